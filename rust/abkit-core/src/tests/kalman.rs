//! Unit tests of `kalman` (a child module of it, so private items are in reach).

use super::*;

#[test]
fn browns_examples() {
    // Random constant: P0 = 4, R = 0.25, Q = 0 -> K0 = 16/17.
    let m = Model::<1, 1> {
        phi: [[1.0]],
        h: [[1.0]],
        q: [[0.0]],
        r: [[0.25]],
    };
    let (k, _, _) = gain_sequence(&m, &[[4.0]], 3).unwrap();
    assert!((k[0][0][0] - 16.0 / 17.0).abs() < 1e-15);
    // Wiener process: P0 = 0, Q = 1, R = 0.25 -> K0 = 0, K1 = 4/5.
    let m = Model::<1, 1> {
        phi: [[1.0]],
        h: [[1.0]],
        q: [[1.0]],
        r: [[0.25]],
    };
    let (k, _, _) = gain_sequence(&m, &[[0.0]], 3).unwrap();
    assert_eq!(k[0][0][0], 0.0);
    assert!((k[1][0][0] - 0.8).abs() < 1e-15);
}

#[test]
fn non_spd_innovation_is_an_error() {
    let m = Model::<1, 1> {
        phi: [[1.0]],
        h: [[1.0]],
        q: [[0.0]],
        r: [[0.0]],
    };
    assert!(update(&m, &[[0.0]]).is_err());
}
