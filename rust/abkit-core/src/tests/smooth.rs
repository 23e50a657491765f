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

#[test]
fn time_varying_smoother_skips_nan_and_breaks_at_gaps() {
    // Hand recursion with A(dt) = dt * I (a toy gain) and Phi(dt) = [[1, dt], [0, 1]].
    let t = [0.0, 1.0, 2.0, 3.5, 10.0, 11.0];
    let mut x0 = vec![1.0, 2.0, f64::NAN, 4.0, 5.0, 7.0];
    let mut x1 = vec![0.1, 0.2, 0.3, 0.4, 0.5, 0.6];
    let xf0 = x0.clone();
    let xf1 = x1.clone();
    let tf = |k: usize| t[k];
    let mut gain = |dt: f64, _j: usize| -> crate::Result<PhiAndGain<2>> {
        Ok(([[1.0, dt], [0.0, 1.0]], [[0.1 * dt, 0.0], [0.0, 0.1 * dt]]))
    };
    {
        let mut st: [&mut [f64]; 2] = [&mut x0, &mut x1];
        smooth_track_tv(&tf, 5.0, None, &mut st, &mut gain).unwrap();
    }
    // sample 5 and 4: 4 -> 5 over dt = 1; 3 -> 4 is a gap (6.5 > 5): sample 3 stays filtered.
    let back = |xf: [f64; 2], xn: [f64; 2], dt: f64| -> [f64; 2] {
        let p = [xf[0] + dt * xf[1], xf[1]];
        [
            xf[0] + 0.1 * dt * (xn[0] - p[0]),
            xf[1] + 0.1 * dt * (xn[1] - p[1]),
        ]
    };
    let s5 = [xf0[5], xf1[5]];
    let s4 = back([xf0[4], xf1[4]], s5, 1.0);
    assert_eq!([x0[4], x1[4]], s4);
    assert_eq!([x0[3], x1[3]], [xf0[3], xf1[3]]);
    // sample 2 is NaN: skipped, 1 -> 3 over dt = 2.5.
    assert!(x0[2].is_nan() && x1[2] == xf1[2]);
    let s1 = back([xf0[1], xf1[1]], [xf0[3], xf1[3]], 2.5);
    assert_eq!([x0[1], x1[1]], s1);
    let s0 = back([xf0[0], xf1[0]], s1, 1.0);
    assert_eq!([x0[0], x1[0]], s0);
}
