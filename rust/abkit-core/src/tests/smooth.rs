//! Unit tests of `smooth` (a child module of it, so private items are in reach).

use super::*;

#[test]
fn fixed_lag_with_long_lag_equals_fixed_interval() {
    let n = 50;
    let phi = [[1.0, 1.0], [0.0, 1.0]];
    let a = [[0.6, 0.3], [-0.1, 0.8]];
    let x: Vec<f64> = (0..n).map(|k| (k as f64 * 0.3).sin()).collect();
    let v: Vec<f64> = (0..n).map(|k| (k as f64 * 0.2).cos()).collect();
    let (mut x1, mut v1) = (x.clone(), v.clone());
    let (mut x2, mut v2) = (x.clone(), v.clone());
    smooth_track(&phi, &a, None, &mut [&mut x1[..], &mut v1[..]]);
    smooth_track(&phi, &a, Some(n), &mut [&mut x2[..], &mut v2[..]]);
    for k in 0..n {
        assert!((x1[k] - x2[k]).abs() < 1e-12 && (v1[k] - v2[k]).abs() < 1e-12);
    }
    // lag 0 is the filter itself
    let (mut x3, mut v3) = (x.clone(), v.clone());
    smooth_track(&phi, &a, Some(0), &mut [&mut x3[..], &mut v3[..]]);
    assert_eq!(x3, x);
    assert_eq!(v3, v);
}
