//! Unit tests of `abg` (a child module of it, so private items are in reach).

use super::*;

#[test]
fn tracking_index_matches_riccati() {
    for lam in [1e-6, 0.01, 0.5, 1.0, 3.0, 100.0] {
        let cf = from_tracking_index(lam).unwrap();
        let f = DMatrix::from_row_slice(3, 3, &[1.0, 1.0, 0.5, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0]);
        let hm = DMatrix::from_row_slice(1, 3, &[1.0, 0.0, 0.0]);
        let s = (lam * lam).max(1.0);
        let q = DMatrix::from_diagonal(&nalgebra::DVector::from_vec(vec![0.0, 0.0, lam * lam / s]));
        let r = DMatrix::from_element(1, 1, 1.0 / s);
        let k = kalman_steady_state(&f, &hm, &q, &r).unwrap().k_filt;
        for i in 0..3 {
            assert!((k[(i, 0)] - cf[i]).abs() <= 1e-7 * cf[i].abs(), "{lam} {i}");
        }
    }
}

#[test]
fn round_trip() {
    let g = from_noise(0.3, 0.2, 0.1, 1.0, 0.7).unwrap();
    let q = noise_ratios(g[0], g[1], g[2], 0.7).unwrap();
    assert!((q[0] - 0.3).abs() < 1e-10 && (q[1] - 0.2).abs() < 1e-10 && (q[2] - 0.1).abs() < 1e-10);
    assert!(matches!(
        from_noise(1.0, 1.0, 0.0, 1.0, 1.0),
        Err(Error::NoSolution(_))
    ));
}
