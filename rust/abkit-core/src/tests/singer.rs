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

/// Found by fuzzing (fuzz/regressions/designs/singer_tiny_noise_negative_position):
/// theta = 0.757 with q T^5 / sigma_pos^2 and sigma_vel T / sigma_pos at
/// 9.7e-72. The numeric solver's prediction covariance had a position
/// variance of -4.7e-50 (the other variances 3e-72 and 6e-72): not rounding
/// but a wrong solution, returned as a steady state. Every method now gives
/// an error or a covariance whose variances are non-negative to 1e-7 of
/// max |P|.
#[test]
fn tiny_noise_gives_an_error_not_a_negative_variance() {
    let (theta, qn, rv) = (
        0.7566061019897461,
        9.730415952684516e-72,
        9.730415951366742e-72,
    );
    for method in [Method::Numeric, Method::ClosedForm, Method::Auto] {
        match steady_state(theta, qn, rv, method) {
            Ok(s) => {
                let p = s.p_pred;
                let scale = p.iter().fold(0.0f64, |m, v| m.max(v.abs()));
                for i in 0..3 {
                    assert!(p[(i, i)] >= -1e-7 * scale, "{method:?}: {p}");
                }
            }
            Err(e) => assert!(matches!(e, Error::NoSolution(_)), "{method:?}: {e}"),
        }
    }
}
