//! Unit tests of `singer` (a child module of it, so private items are in reach).

use super::*;

#[test]
fn g_limits() {
    let g = singer_g(0.0);
    let want = [1.0 / 20.0, 1.0 / 8.0, 1.0 / 6.0, 1.0 / 3.0, 0.5, 1.0];
    for (a, b) in g.iter().zip(want) {
        assert!((a - b).abs() < 1e-15);
    }
    // Continuity at the switch theta = 2.
    let (a, b) = (singer_g(2.0), singer_g(2.0 + 1e-12));
    for (x, y) in a.iter().zip(b) {
        assert!((x - y).abs() < 1e-12 * x.abs());
    }
}

#[test]
fn numeric_steady_state_is_a_riccati_fixed_point() {
    for &(theta, qn, rv) in &[
        (0.1, 1e-3, 0.5),
        (1.0, 1.0, f64::INFINITY),
        (0.0, 1e-2, 1.0),
    ] {
        let s = steady_state_numeric(theta, qn, rv).unwrap();
        let (h, r) = measurement(rv);
        let p = to_d(&s.p_pred);
        let phi = to_d(&s.phi);
        let sinv = (&h * &p * h.transpose() + &r).try_inverse().unwrap();
        let next = &phi * (&p - &p * h.transpose() * sinv * &h * &p) * phi.transpose() + to_d(&s.q);
        assert!((next - &p).amax() < 1e-12 * p.amax());
    }
}
