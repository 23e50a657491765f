//! The discrete Kalman filter recursion (Brown's "guided tour", paper 002,
//! Fig. 5): gain, update, covariance update, project ahead.
//!
//! ```text
//! K_k  = P_k^- H^T (H P_k^- H^T + R)^-1
//! x_k  = x_k^- + K_k (z_k - H x_k^-)
//! P_k  = (I - K_k H) P_k^- (I - K_k H)^T + K_k R K_k^T      (Joseph form)
//! x_{k+1}^- = Phi x_k,   P_{k+1}^- = Phi P_k Phi^T + Q
//! ```
//!
//! A missed sample (NaN) skips the gain and update: `P_k = P_k^-`.
//! When every track shares the model and has no missed samples the gain
//! sequence does not depend on the data: it is computed once, block by
//! block, and applied to all tracks; once it has converged (to the last
//! bit) the rest runs with the fixed limiting gain. Tracks with missed
//! samples run their own covariance recursion.
#![allow(clippy::needless_range_loop)]

use crate::filter::{IoFloat, Measurements, TrackOut};
use crate::{Error, Result};
use rayon::prelude::*;

type Mat<const R: usize, const C: usize> = [[f64; C]; R];

/// A linear Gaussian model: `x' = Phi x + w` (`cov w = Q`), `z = H x + v`
/// (`cov v = R`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Model<const N: usize, const M: usize> {
    /// State transition.
    pub phi: Mat<N, N>,
    /// Measurement matrix.
    pub h: Mat<M, N>,
    /// Process noise covariance.
    pub q: Mat<N, N>,
    /// Measurement noise covariance.
    pub r: Mat<M, M>,
}

fn mul<const A: usize, const B: usize, const C: usize>(x: &Mat<A, B>, y: &Mat<B, C>) -> Mat<A, C> {
    std::array::from_fn(|i| std::array::from_fn(|j| (0..B).map(|k| x[i][k] * y[k][j]).sum()))
}

fn tr<const A: usize, const B: usize>(x: &Mat<A, B>) -> Mat<B, A> {
    std::array::from_fn(|i| std::array::from_fn(|j| x[j][i]))
}

fn sym<const N: usize>(x: &Mat<N, N>) -> Mat<N, N> {
    std::array::from_fn(|i| std::array::from_fn(|j| 0.5 * (x[i][j] + x[j][i])))
}

/// Inverse of a symmetric positive-definite 1x1 or 2x2 matrix.
fn inv_spd<const M: usize>(s: &Mat<M, M>) -> Option<Mat<M, M>> {
    match M {
        1 => {
            let d = s[0][0];
            (d > 0.0 && d.is_finite())
                .then(|| std::array::from_fn(|_| std::array::from_fn(|_| 1.0 / d)))
        }
        2 => {
            let det = s[0][0] * s[1][1] - s[0][1] * s[1][0];
            if !(det > 0.0 && s[0][0] > 0.0 && det.is_finite()) {
                return None;
            }
            let inv = [
                [s[1][1] / det, -s[0][1] / det],
                [-s[1][0] / det, s[0][0] / det],
            ];
            Some(std::array::from_fn(|i| std::array::from_fn(|j| inv[i][j])))
        }
        _ => None,
    }
}

/// One gain/update: from the prior covariance to `(K, P_post)`.
pub fn update<const N: usize, const M: usize>(
    m: &Model<N, M>,
    p_prior: &Mat<N, N>,
) -> Result<(Mat<N, M>, Mat<N, N>)> {
    let ht = tr(&m.h);
    let pht = mul(p_prior, &ht);
    let hpht = mul(&m.h, &pht);
    let s: Mat<M, M> = std::array::from_fn(|i| std::array::from_fn(|j| hpht[i][j] + m.r[i][j]));
    if let Some(v) = s.iter().flatten().find(|v| !v.is_finite()) {
        // finite model matrices whose covariance recursion overflowed
        return Err(Error::domain(
            "F, H, Q, P0",
            "of a scale at which the covariance recursion stays within float64 (it overflowed)",
            *v,
        ));
    }
    let sinv = inv_spd(&s).ok_or_else(|| {
        Error::domain(
            "R",
            "such that the innovation covariance H P H^T + R is positive definite",
            f64::NAN,
        )
    })?;
    let k = mul(&pht, &sinv);
    let kh = mul(&k, &m.h);
    let ikh: Mat<N, N> =
        std::array::from_fn(|i| std::array::from_fn(|j| if i == j { 1.0 } else { 0.0 } - kh[i][j]));
    let a = mul(&mul(&ikh, p_prior), &tr(&ikh));
    let krk = mul(&mul(&k, &m.r), &tr(&k));
    let p: Mat<N, N> = std::array::from_fn(|i| std::array::from_fn(|j| a[i][j] + krk[i][j]));
    Ok((k, sym(&p)))
}

/// Project ahead: `Phi P Phi^T + Q`.
pub fn project<const N: usize, const M: usize>(m: &Model<N, M>, p: &Mat<N, N>) -> Mat<N, N> {
    let a = mul(&mul(&m.phi, p), &tr(&m.phi));
    sym(&std::array::from_fn(|i| {
        std::array::from_fn(|j| a[i][j] + m.q[i][j])
    }))
}

/// Gains and covariances of the first `n` steps from the prior `p0`:
/// `k[s]`, `p_prior[s]`, `p_post[s]` for `s < n`.
pub fn gain_sequence<const N: usize, const M: usize>(
    m: &Model<N, M>,
    p0: &Mat<N, N>,
    n: usize,
) -> Result<(Vec<Mat<N, M>>, Vec<Mat<N, N>>, Vec<Mat<N, N>>)> {
    let (mut ks, mut pri, mut post) = (
        Vec::with_capacity(n),
        Vec::with_capacity(n),
        Vec::with_capacity(n),
    );
    let mut p = *p0;
    for _ in 0..n {
        let (k, pp) = update(m, &p)?;
        ks.push(k);
        pri.push(p);
        post.push(pp);
        p = project(m, &pp);
    }
    Ok((ks, pri, post))
}

#[inline(always)]
fn step<const N: usize, const M: usize>(
    phi: &Mat<N, N>,
    h: &Mat<M, N>,
    k: Option<&Mat<N, M>>,
    x_prior: &[f64; N],
    z: &[f64; M],
) -> ([f64; N], [f64; M]) {
    let valid = z.iter().all(|v| !v.is_nan());
    let e: [f64; M] = std::array::from_fn(|j| {
        if valid {
            z[j] - (0..N).map(|i| h[j][i] * x_prior[i]).sum::<f64>()
        } else {
            f64::NAN
        }
    });
    let x = match (valid, k) {
        (true, Some(k)) => {
            std::array::from_fn(|i| x_prior[i] + (0..M).map(|j| k[i][j] * e[j]).sum::<f64>())
        }
        _ => *x_prior,
    };
    let _ = phi;
    (x, e)
}

fn predict<const N: usize>(phi: &Mat<N, N>, x: &[f64; N]) -> [f64; N] {
    std::array::from_fn(|i| (0..N).map(|j| phi[i][j] * x[j]).sum())
}

#[allow(clippy::too_many_arguments)]
/// Run the Kalman filter over a batch: prior `x0` (one for all tracks or one
/// per track), prior covariance `p0`. `out` is `(N, n_tracks, n_samples)`,
/// `resid` `(n_tracks, n_samples, M)`, `p_final` receives each track's last
/// filtered covariance (`n_tracks * N * N`).
pub fn run_batch<T: IoFloat, const N: usize, const M: usize>(
    m: &Model<N, M>,
    x0: &[[f64; N]],
    p0: &Mat<N, N>,
    z: &Measurements<'_, T>,
    out: &mut [T],
    resid: Option<&mut [T]>,
    p_final: &mut [f64],
    parallel: bool,
) -> Result<()> {
    let (nt, n) = (z.n_tracks, z.n_samples);
    if z.m != M || !(x0.len() == 1 || x0.len() == nt) || p_final.len() != nt * N * N {
        return Err(Error::Shape("Kalman batch: inconsistent sizes".into()));
    }
    z.validate()?;
    let mut states = vec![crate::filter::TrackState::default(); nt];
    // Shared gain sequence until it converges (bitwise), then fixed.
    let mut gains: Vec<Mat<N, M>> = Vec::new();
    let mut posts: Vec<Mat<N, N>> = Vec::new();
    let mut p = *p0;
    for _ in 0..n {
        let (k, pp) = update(m, &p)?;
        let converged =
            gains.last().is_some_and(|last| *last == k) && posts.last().is_some_and(|l| *l == pp);
        gains.push(k);
        posts.push(pp);
        if converged {
            break;
        }
        p = project(m, &pp);
    }
    let n_shared = gains.len();
    // The shared gains converged before the end: the rest is fixed-gain
    // filtering with the limiting gain, run by the batch engine's kernel.
    let k_end = if n_shared < n { n_shared } else { n };
    // Which tracks miss samples (they need their own covariance recursion).
    let scan = |i: usize| match z.row(i) {
        Some(r) => r.iter().any(|v| v.to_f64().is_nan()),
        None => (0..n).any(|k| (0..M).any(|j| z.at(i, k, j).is_nan())),
    };
    let nan_rows: Vec<bool> = if parallel {
        (0..nt).into_par_iter().map(scan).collect()
    } else {
        (0..nt).map(scan).collect()
    };
    let has_nan = |i: usize| nan_rows[i];
    let own_recursion = |i: usize, o: &mut TrackOut<'_, T, N>| {
        let zk = |k: usize| -> [f64; M] { std::array::from_fn(|j| z.at(i, k, j)) };
        let mut x = x0[if x0.len() == 1 { 0 } else { i }];
        let mut p = *p0;
        for k in 0..n {
            if k > 0 {
                x = predict(&m.phi, &x);
                p = project(m, &p);
            }
            let z_k = zk(k);
            if z_k.iter().all(|v| !v.is_nan()) {
                // The shared model already passed the SPD check at least
                // once; a failure here leaves the prior.
                if let Ok((g, pp)) = update(m, &p) {
                    let (xn, e) = step(&m.phi, &m.h, Some(&g), &x, &z_k);
                    x = xn;
                    p = pp;
                    write(o, k, &x, &e);
                    continue;
                }
            }
            let (xn, e) = step(&m.phi, &m.h, None, &x, &z_k);
            x = xn;
            write(o, k, &x, &e);
        }
    };
    let mut resid = resid;
    crate::filter::run_batch::<T, N>(
        nt,
        n,
        M,
        &mut states,
        out,
        resid.as_deref_mut(),
        parallel,
        1,
        |group| {
            for (i, st, o) in group.iter_mut() {
                let i = *i;
                if has_nan(i) {
                    own_recursion(i, o);
                    continue;
                }
                let zk = |k: usize| -> [f64; M] { std::array::from_fn(|j| z.at(i, k, j)) };
                let mut x = x0[if x0.len() == 1 { 0 } else { i }];
                for k in 0..k_end {
                    if k > 0 {
                        x = predict(&m.phi, &x);
                    }
                    let (xn, e) = step(&m.phi, &m.h, Some(&gains[k]), &x, &zk(k));
                    x = xn;
                    write(o, k, &x, &e);
                }
                st.x[..N].copy_from_slice(&x);
                st.phase = 2.0;
            }
        },
    )?;
    if k_end < n {
        let g_inf = crate::filter::Gains::<N, M> {
            phi: m.phi,
            h: m.h,
            k: gains[n_shared - 1],
            h_pinv: [[0.0; M]; N],
            t: 1.0,
        };
        let tail = Measurements {
            base: (z.base as isize + k_end as isize * z.s_sample) as usize,
            n_samples: n - k_end,
            ..*z
        };
        crate::filter::general_cols(
            &[g_inf],
            crate::filter::Init::First,
            &tail,
            n,
            k_end,
            &mut states,
            out,
            resid.as_deref_mut(),
            parallel,
            None,
        )?;
        // Tracks with missed samples ran their own recursion above; the
        // fixed-gain tail overwrote them, so run them again.
        if (0..nt).any(has_nan) {
            crate::filter::run_batch::<T, N>(
                nt,
                n,
                M,
                &mut states,
                out,
                resid,
                parallel,
                1,
                |group| {
                    for (i, _, o) in group.iter_mut() {
                        if has_nan(*i) {
                            own_recursion(*i, o);
                        }
                    }
                },
            )?;
        }
    }
    // Final covariances: shared tracks end on the shared sequence; tracks
    // with missed samples are recomputed (cheap, N x N per sample).
    let final_cov = |i: usize| {
        let zk = |k: usize| -> bool { (0..M).any(|j| z.at(i, k, j).is_nan()) };
        if n == 0 {
            return *p0;
        }
        if !(0..n).any(zk) {
            return posts[(n - 1).min(n_shared - 1)];
        }
        let mut p = *p0;
        for k in 0..n {
            if k > 0 {
                p = project(m, &p);
            }
            if !zk(k) {
                if let Ok((_, pp)) = update(m, &p) {
                    p = pp;
                }
            }
        }
        p
    };
    let finals: Vec<Mat<N, N>> = if parallel {
        (0..nt).into_par_iter().map(final_cov).collect()
    } else {
        (0..nt).map(final_cov).collect()
    };
    for (dst, p) in p_final.chunks_exact_mut(N * N).zip(&finals) {
        for r in 0..N {
            dst[r * N..(r + 1) * N].copy_from_slice(&p[r]);
        }
    }
    Ok(())
}

#[inline(always)]
fn write<T: IoFloat, const N: usize, const M: usize>(
    o: &mut TrackOut<'_, T, N>,
    k: usize,
    x: &[f64; N],
    e: &[f64; M],
) {
    for c in 0..N {
        o.states[c][k] = T::from_f64(x[c]);
    }
    if let Some(r) = o.resid.as_deref_mut() {
        for j in 0..M {
            r[k * M + j] = T::from_f64(e[j]);
        }
    }
}

#[cfg(test)]
#[path = "tests/kalman.rs"]
mod tests;
