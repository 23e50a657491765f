//! Steady-state smoothing of filtered tracks.
//!
//! Fixed-interval (Rauch-Tung-Striebel) smoother with the constant backward
//! gain `A = P_filt Phi^T P_pred^-1` (paper 001, eq (22)):
//!
//! ```text
//! x_s[n-1] = x_f[n-1]
//! x_s[k]   = x_f[k] + A (x_s[k+1] - Phi x_f[k])
//! ```
//!
//! and the fixed-lag variant `x_s[k] = x_{k | k+L}`, the same recursion run
//! backwards over the window `k..=min(k+L, n-1)` from `x_f[k+L]`.
//!
//! Samples whose filtered estimate has a NaN component (before a track has
//! started, or the position-only first sample of a two-point start) are left
//! as filtered, and the backward recursion restarts after them.
#![allow(clippy::needless_range_loop)]

use crate::filter::IoFloat;

#[inline(always)]
fn load<T: IoFloat, const N: usize>(s: &[&mut [T]; N], k: usize) -> [f64; N] {
    std::array::from_fn(|c| s[c][k].to_f64())
}

#[inline(always)]
fn step<const N: usize>(
    phi: &[[f64; N]; N],
    a: &[[f64; N]; N],
    xf: &[f64; N],
    xs_next: &[f64; N],
) -> [f64; N] {
    let mut d = [0.0; N];
    for i in 0..N {
        let mut p = 0.0;
        for j in 0..N {
            p += phi[i][j] * xf[j];
        }
        d[i] = xs_next[i] - p;
    }
    std::array::from_fn(|i| {
        let mut s = xf[i];
        for j in 0..N {
            s += a[i][j] * d[j];
        }
        s
    })
}

fn has_nan<const N: usize>(x: &[f64; N]) -> bool {
    x.iter().any(|v| v.is_nan())
}

/// Smooth one track in place: `states[c]` holds component `c` of the
/// filtered estimates on entry and of the smoothed ones on return.
pub fn smooth_track<T: IoFloat, const N: usize>(
    phi: &[[f64; N]; N],
    a: &[[f64; N]; N],
    lag: Option<usize>,
    states: &mut [&mut [T]; N],
) {
    let n = states.first().map_or(0, |s| s.len());
    if n == 0 {
        return;
    }
    match lag {
        None => {
            let mut next: Option<[f64; N]> = None;
            for k in (0..n).rev() {
                let xf = load(states, k);
                if has_nan(&xf) {
                    next = None;
                    continue;
                }
                let xs = match next {
                    None => xf,
                    Some(xn) => step(phi, a, &xf, &xn),
                };
                for c in 0..N {
                    states[c][k] = T::from_f64(xs[c]);
                }
                next = Some(xs);
            }
        }
        Some(lag) => {
            // Increasing k: x_f[k..] is still intact when x_s[k] is written.
            for k in 0..n {
                let xf_k = load(states, k);
                if has_nan(&xf_k) {
                    continue;
                }
                let end = (k + lag).min(n - 1);
                let mut s = load(states, end);
                if has_nan(&s) {
                    continue;
                }
                let mut j = end;
                while j > k {
                    let xf = load(states, j - 1);
                    s = step(phi, a, &xf, &s);
                    j -= 1;
                }
                for c in 0..N {
                    states[c][k] = T::from_f64(s[c]);
                }
            }
        }
    }
}

#[cfg(test)]
#[path = "tests/smooth.rs"]
mod tests;
