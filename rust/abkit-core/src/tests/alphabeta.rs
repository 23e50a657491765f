//! Unit tests of `alphabeta` (a child module of it, so private items are in reach).

use super::*;

fn rel(a: f64, b: f64) -> f64 {
    ((a - b) / b).abs()
}

/// Brute-force Riccati iteration on the normalised model (an independent
/// check of the closed forms).
fn riccati(r: f64) -> ([f64; 3], [f64; 3]) {
    // predicted covariance M, filtered P
    let (mut m11, mut m12, mut m22) = (1e3, 0.0, 1e3);
    let mut p = [0.0; 3];
    for _ in 0..200_000 {
        let s = m11 + 1.0;
        let (k1, k2) = (m11 / s, m12 / s);
        let p11 = m11 - k1 * m11;
        let p12 = m12 - k1 * m12;
        let p22 = m22 - k2 * m12;
        p = [p11, p12, p22];
        let n11 = p11 + 2.0 * p12 + p22 + r;
        let n12 = p12 + p22 + 2.0 * r;
        let n22 = p22 + 4.0 * r;
        let done = rel(n11, m11) < 1e-15 && rel(n22, m22) < 1e-15;
        m11 = n11;
        m12 = n12;
        m22 = n22;
        if done {
            break;
        }
    }
    (p, [m11, m12, m22])
}

#[test]
fn kalman_closed_form_matches_riccati_iteration() {
    for &r in &[1e-4, 1e-2, 0.1, 1.0, 10.0, 1e3] {
        let ab = AlphaBeta::from_snr(r).unwrap();
        let (p, m) = riccati(r);
        for i in 0..3 {
            assert!(rel(ab.covariance.filtered[i], p[i]) < 1e-9, "r={r} P[{i}]");
            assert!(rel(ab.covariance.predicted[i], m[i]) < 1e-9, "r={r} M[{i}]");
        }
        assert!(rel(ab.alpha, p[0]) < 1e-9 && rel(ab.beta, p[1]) < 1e-9);
        assert!(ab.kalman_optimal && ab.stable && ab.valid);
        assert!(rel(ab.damping, KALMAN_DAMPING) < 1e-15);
    }
}

#[test]
fn lyapunov_form_agrees_with_kalman_form() {
    for &r in &[1e-6, 1e-3, 0.5, 20.0, 1e4] {
        let k = AlphaBeta::from_snr(r).unwrap();
        let a = AlphaBeta::analyze(k.alpha, k.beta).unwrap();
        assert!(a.kalman_optimal, "r={r}");
        for i in 0..3 {
            let tol = 1e-10 * (1.0 + r.sqrt());
            assert!(rel(a.covariance.filtered[i], k.covariance.filtered[i]) < tol);
            assert!(rel(a.covariance.predicted[i], k.covariance.predicted[i]) < tol);
        }
    }
}

#[test]
fn constructors_agree() {
    let a = AlphaBeta::from_snr(0.01).unwrap();
    let b = AlphaBeta::from_tracking_index(0.2).unwrap();
    let c = AlphaBeta::from_tracking_error(a.alpha).unwrap();
    let d = AlphaBeta::from_bandwidth(a.bandwidth_t, KALMAN_DAMPING).unwrap();
    let e = AlphaBeta::from_natural_frequency(a.omega_n_t / 0.1, 0.1, KALMAN_DAMPING).unwrap();
    let f = AlphaBeta::from_noise(3.2, 32.0, 2f64.sqrt()).unwrap();
    for x in [&b, &c, &d, &e, &f] {
        assert!(rel(x.alpha, a.alpha) < 1e-12, "{} vs {}", x.alpha, a.alpha);
        assert!(rel(x.beta, a.beta) < 1e-12);
    }
}

#[test]
fn bad_input_is_an_error() {
    assert!(AlphaBeta::from_snr(0.0).is_err());
    assert!(AlphaBeta::from_snr(f64::NAN).is_err());
    assert!(AlphaBeta::from_snr(f64::INFINITY).is_err());
    assert!(AlphaBeta::from_tracking_error(1.0).is_err());
    assert!(AlphaBeta::from_bandwidth(0.3, KALMAN_DAMPING).is_err());
    assert!(AlphaBeta::from_natural_frequency(20.0, 0.1, KALMAN_DAMPING).is_err());
    assert!(AlphaBeta::from_noise(1e-300, 1e300, 1e-100).is_err());
    assert!(AlphaBeta::analyze(-0.1, 0.1).is_err());
}

#[test]
fn unstable_gains_are_reported() {
    let a = AlphaBeta::analyze(0.5, 3.5).unwrap();
    assert!(!a.stable && !a.valid);
    assert!(a.covariance.filtered[0].is_infinite());
    let mod_max = a
        .poles
        .iter()
        .map(|(re, im)| re.hypot(*im))
        .fold(0.0, f64::max);
    assert!(mod_max > 1.0);
}

proptest::proptest! {
    #[test]
    fn bandwidth_round_trip(bnt in 1e-9f64..0.2499, damping in 0.05f64..3.0) {
        if let Ok(x) = invert_bandwidth(bnt, damping) {
            let back = bandwidth_t_from_x(x, damping);
            proptest::prop_assert!(rel(back, bnt) < 1e-13);
            proptest::prop_assert!(x > 0.0 && x < max_omega_n_t(damping));
        }
    }

    #[test]
    fn kalman_designs_are_stable_and_consistent(logr in -12.0f64..12.0) {
        let r = 10f64.powf(logr);
        let ab = AlphaBeta::from_snr(r).unwrap();
        proptest::prop_assert!(ab.stable && ab.kalman_optimal);
        proptest::prop_assert!(ab.alpha > 0.0 && ab.alpha < 1.0 && ab.beta > 0.0 && ab.beta < 2.0);
        // eq (9), second line: p12 / (1 - p11) = p12 + p22 + 2 r  (relative to the larger side)
        let [p11, p12, p22] = ab.covariance.filtered;
        let lhs = p12 / ab.one_minus_alpha;
        let rhs = p12 + p22 + 2.0 * r;
        proptest::prop_assert!(rel(lhs, rhs) < 1e-12);
        let _ = p11;
    }
}
