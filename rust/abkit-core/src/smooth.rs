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

/// `(Phi(dt), A(dt))` of one backward step.
pub type PhiAndGain<const N: usize> = ([[f64; N]; N], [[f64; N]; N]);

/// Smooth one track with timestamps in place: the backward step from
/// sample `k` to the next kept sample `j` (the next one whose estimate has
/// no NaN) uses `gain(t_j - t_k, j) = (Phi, A)` for that interval. Samples with
/// a NaN component (dropped duplicates, start-up) are left as they are and
/// skipped; the recursion restarts where the interval exceeds `max_gap` (a
/// filter restart). `lag`: as in [`smooth_track`], counted in samples.
pub fn smooth_track_tv<T: IoFloat, const N: usize>(
    t: &dyn Fn(usize) -> f64,
    max_gap: f64,
    lag: Option<usize>,
    states: &mut [&mut [T]; N],
    gain: &mut dyn FnMut(f64, usize) -> crate::Result<PhiAndGain<N>>,
) -> crate::Result<()> {
    let n = states.first().map_or(0, |s| s.len());
    match lag {
        None => {
            let mut next: Option<([f64; N], f64, usize)> = None;
            for k in (0..n).rev() {
                let xf = load(states, k);
                if has_nan(&xf) {
                    continue;
                }
                let tk = t(k);
                let xs = match next {
                    Some((xn, tn, jn)) if tn - tk <= max_gap => {
                        let (phi, a) = gain(tn - tk, jn)?;
                        step(&phi, &a, &xf, &xn)
                    }
                    _ => xf,
                };
                for c in 0..N {
                    states[c][k] = T::from_f64(xs[c]);
                }
                next = Some((xs, tk, k));
            }
        }
        Some(lag) => {
            // Increasing k: x_f[k..] is still intact when x_s[k] is written.
            let mut chain: Vec<usize> = Vec::with_capacity(lag + 1);
            for k in 0..n {
                let xf_k = load(states, k);
                if has_nan(&xf_k) {
                    continue;
                }
                chain.clear();
                chain.push(k);
                let end = (k + lag).min(n - 1);
                let mut last_t = t(k);
                for j in k + 1..=end {
                    if has_nan(&load(states, j)) {
                        continue;
                    }
                    let tj = t(j);
                    if tj - last_t > max_gap {
                        break;
                    }
                    chain.push(j);
                    last_t = tj;
                }
                let Some(&jl) = chain.last() else { continue };
                let mut s = load(states, jl);
                for w in chain.windows(2).rev() {
                    let (i, j) = (w[0], w[1]);
                    let (phi, a) = gain(t(j) - t(i), j)?;
                    s = step(&phi, &a, &load(states, i), &s);
                }
                for c in 0..N {
                    states[c][k] = T::from_f64(s[c]);
                }
            }
        }
    }
    Ok(())
}

#[cfg(test)]
#[path = "tests/smooth.rs"]
mod tests;
