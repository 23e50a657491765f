//! Batched fixed-gain filtering kernels.
//!
//! A fixed-gain filter with state transition `Phi` (n x n), measurement
//! matrix `H` (m x n) and filter-form gain `K` (n x m) runs, for each sample,
//!
//! ```text
//! x_p = Phi x            (predict)
//! e   = z - H x_p        (residual)
//! x   = x_p + K e        (update; skipped when z has a NaN component)
//! ```
//!
//! Tracks are independent; the batch driver runs them on rayon's global pool
//! (or serially), and the result of a track never depends on how tracks are
//! distributed, so output is bit-identical for any thread count. Arithmetic
//! is in `f64` whatever the input precision; the state carried between
//! chunks is `f64` too, so a track run in chunks is bit-identical to one call.
//!
//! Start-up (`Init`): before a track's first valid sample the estimates are
//! NaN. `Init::First` sets the state from the first valid measurement through
//! the pseudo-inverse of `H` (zero rates). `Init::TwoPoint` (kinematic filters:
//! state `[position, velocity, ...]`, scalar position measurement) sets the
//! position from the first valid sample, holds it (velocity NaN) until the
//! second valid sample, then sets position and the velocity from the two
//! (`(z2 - z1) / (gap * T)`) and starts filtering at the next sample.
//! `Init::Given` starts from a state supplied for "just before sample 0".

#![allow(clippy::needless_range_loop, clippy::too_many_arguments)]

use crate::{Error, Result};
use rayon::prelude::*;

/// Largest state dimension of the general kernel.
pub const MAX_STATES: usize = 6;
/// Largest measurement dimension of the general kernel.
pub const MAX_MEAS: usize = 2;

/// Input/output element type: the kernels read and write `f32` or `f64` and
/// compute in `f64`.
pub trait IoFloat: Copy + Send + Sync + 'static {
    /// Widen to `f64` (exact).
    fn to_f64(self) -> f64;
    /// Narrow from `f64` (round to nearest).
    fn from_f64(x: f64) -> Self;
}

impl IoFloat for f64 {
    #[inline(always)]
    fn to_f64(self) -> f64 {
        self
    }
    #[inline(always)]
    fn from_f64(x: f64) -> Self {
        x
    }
}

impl IoFloat for f32 {
    #[inline(always)]
    fn to_f64(self) -> f64 {
        self as f64
    }
    #[inline(always)]
    fn from_f64(x: f64) -> Self {
        x as f32
    }
}

/// Per-track filter state carried between calls (streaming).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackState {
    /// State estimate (first `n` entries used).
    pub x: [f64; MAX_STATES],
    /// 0: no valid sample yet; 1: one valid sample held (two-point start);
    /// 2: running.
    pub phase: u8,
    /// In phase 1, samples since the held valid sample.
    pub since: u64,
}

impl Default for TrackState {
    fn default() -> Self {
        TrackState {
            x: [0.0; MAX_STATES],
            phase: 0,
            since: 0,
        }
    }
}

/// How a track starts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Init {
    /// State from the first valid measurement (pseudo-inverse of `H`), zero rates.
    First,
    /// Position from the first valid sample, velocity from the first two.
    TwoPoint,
}

/// A fixed-gain filter of state dimension `N` and measurement dimension `M`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gains<const N: usize, const M: usize> {
    /// State transition.
    pub phi: [[f64; N]; N],
    /// Measurement matrix.
    pub h: [[f64; N]; M],
    /// Filter-form gain.
    pub k: [[f64; M]; N],
    /// Pseudo-inverse of `H` (n x m), used by `Init::First`.
    pub h_pinv: [[f64; M]; N],
    /// Sampling period, used by `Init::TwoPoint` for the velocity.
    pub t: f64,
}

/// Measurements of a batch: element `(track i, sample k, component j)` is
/// `data[base + i*s_track + k*s_sample + j*s_comp]` (strides in elements,
/// any sign).
#[derive(Debug, Clone, Copy)]
pub struct Measurements<'a, T> {
    /// Backing memory.
    pub data: &'a [T],
    /// Offset of element (0, 0, 0).
    pub base: usize,
    /// Stride between tracks.
    pub s_track: isize,
    /// Stride between samples.
    pub s_sample: isize,
    /// Stride between components.
    pub s_comp: isize,
    /// Number of tracks.
    pub n_tracks: usize,
    /// Samples per track.
    pub n_samples: usize,
    /// Measurement components.
    pub m: usize,
}

impl<'a, T: IoFloat> Measurements<'a, T> {
    /// C-contiguous `(n_tracks, n_samples, m)` data.
    pub fn contiguous(data: &'a [T], n_tracks: usize, n_samples: usize, m: usize) -> Result<Self> {
        if data.len() != n_tracks * n_samples * m {
            return Err(Error::Shape(format!(
                "measurement buffer of {} elements for {n_tracks} x {n_samples} x {m}",
                data.len()
            )));
        }
        Ok(Measurements {
            data,
            base: 0,
            s_track: (n_samples * m) as isize,
            s_sample: m as isize,
            s_comp: 1,
            n_tracks,
            n_samples,
            m,
        })
    }

    /// Check that every element lies inside `data`.
    pub fn validate(&self) -> Result<()> {
        let ext = |n: usize, s: isize| -> (isize, isize) {
            if n == 0 {
                return (0, 0);
            }
            let span = (n as isize - 1) * s;
            (span.min(0), span.max(0))
        };
        if self.n_tracks == 0 || self.n_samples == 0 || self.m == 0 {
            return Ok(());
        }
        let parts = [
            ext(self.n_tracks, self.s_track),
            ext(self.n_samples, self.s_sample),
            ext(self.m, self.s_comp),
        ];
        let lo: isize = self.base as isize + parts.iter().map(|p| p.0).sum::<isize>();
        let hi: isize = self.base as isize + parts.iter().map(|p| p.1).sum::<isize>();
        if lo < 0 || hi >= self.data.len() as isize {
            return Err(Error::Shape(
                "measurement strides reach outside the buffer".into(),
            ));
        }
        Ok(())
    }

    /// Row `i` as a contiguous slice when samples of a scalar measurement are
    /// adjacent in memory.
    #[inline]
    fn row(&self, i: usize) -> Option<&'a [T]> {
        if self.m == 1 && self.s_sample == 1 {
            let start = (self.base as isize + i as isize * self.s_track) as usize;
            self.data.get(start..start + self.n_samples)
        } else {
            None
        }
    }

    #[inline(always)]
    fn at(&self, i: usize, k: usize, j: usize) -> f64 {
        let off = self.base as isize
            + i as isize * self.s_track
            + k as isize * self.s_sample
            + j as isize * self.s_comp;
        self.data[off as usize].to_f64()
    }
}

/// Output buffers of one track: `states[c]` is component `c` (length
/// `n_samples`), `resid` the residuals (`n_samples * m`, sample-major).
pub struct TrackOut<'a, T, const N: usize> {
    /// Estimate components.
    pub states: [&'a mut [T]; N],
    /// Residuals, if requested.
    pub resid: Option<&'a mut [T]>,
}

/// Run one track of a general fixed-gain filter.
///
/// `z(k)` returns sample `k` (`M` components, in `f64`).
pub fn run_track<T: IoFloat, const N: usize, const M: usize>(
    g: &Gains<N, M>,
    init: Init,
    st: &mut TrackState,
    n: usize,
    z: impl Fn(usize) -> [f64; M],
    out: &mut TrackOut<'_, T, N>,
) {
    let nan = T::from_f64(f64::NAN);
    let mut x: [f64; N] = std::array::from_fn(|i| st.x[i]);
    let mut k0 = 0;
    // Start-up: until the track is running.
    while st.phase < 2 && k0 < n {
        let zk = z(k0);
        let valid = zk.iter().all(|v| !v.is_nan());
        if let Some(r) = out.resid.as_deref_mut() {
            for j in 0..M {
                r[k0 * M + j] = nan;
            }
        }
        match (st.phase, valid) {
            (0, false) => {
                for c in 0..N {
                    out.states[c][k0] = nan;
                }
            }
            (0, true) => {
                for (i, xi) in x.iter_mut().enumerate() {
                    *xi = (0..M).map(|j| g.h_pinv[i][j] * zk[j]).sum();
                }
                if init == Init::First {
                    st.phase = 2;
                    for c in 0..N {
                        out.states[c][k0] = T::from_f64(x[c]);
                    }
                } else {
                    st.phase = 1;
                    st.since = 0;
                    out.states[0][k0] = T::from_f64(x[0]);
                    for c in 1..N {
                        out.states[c][k0] = nan;
                    }
                }
            }
            (_, false) => {
                // phase 1, missed sample: hold the first position.
                st.since += 1;
                out.states[0][k0] = T::from_f64(x[0]);
                for c in 1..N {
                    out.states[c][k0] = nan;
                }
            }
            (_, true) => {
                // phase 1, second valid sample: two-point start.
                let gap = (st.since + 1) as f64;
                let p1 = x[0];
                let p2 = zk[0];
                x = [0.0; N];
                x[0] = p2;
                if N > 1 {
                    x[1] = (p2 - p1) / (gap * g.t);
                }
                st.phase = 2;
                st.since = 0;
                for c in 0..N {
                    out.states[c][k0] = T::from_f64(x[c]);
                }
            }
        }
        k0 += 1;
    }
    // Steady state.
    for k in k0..n {
        let zk = z(k);
        let mut xp = [0.0; N];
        for (i, xpi) in xp.iter_mut().enumerate() {
            let mut s = 0.0;
            for (j, xj) in x.iter().enumerate() {
                s += g.phi[i][j] * xj;
            }
            *xpi = s;
        }
        let mut e = [0.0; M];
        let mut valid = true;
        for j in 0..M {
            let mut hx = 0.0;
            for (i, xpi) in xp.iter().enumerate() {
                hx += g.h[j][i] * xpi;
            }
            e[j] = zk[j] - hx;
            valid &= !e[j].is_nan();
        }
        if valid {
            for i in 0..N {
                let mut s = xp[i];
                for j in 0..M {
                    s += g.k[i][j] * e[j];
                }
                x[i] = s;
            }
        } else {
            x = xp;
        }
        for c in 0..N {
            out.states[c][k] = T::from_f64(x[c]);
        }
        if let Some(r) = out.resid.as_deref_mut() {
            for j in 0..M {
                r[k * M + j] = if valid { T::from_f64(e[j]) } else { nan };
            }
        }
    }
    st.x[..N].copy_from_slice(&x);
}

/// Alpha-beta specialisation (`N = 2`, `M = 1`, `Phi = [[1, T], [0, 1]]`,
/// `K = [alpha, beta / T]`): the update is arranged so that the per-sample
/// dependency chain is two fused multiply-adds,
/// `x' = (1 - alpha)(x + T v) + alpha z`, `v' = v + g2 (z - (x + T v))`.
pub fn run_track_ab<T: IoFloat>(
    alpha: f64,
    beta: f64,
    t: f64,
    init: Init,
    st: &mut TrackState,
    z: &[T],
    out: &mut TrackOut<'_, T, 2>,
) {
    let g = Gains::<2, 1> {
        phi: [[1.0, t], [0.0, 1.0]],
        h: [[1.0, 0.0]],
        k: [[alpha], [beta / t]],
        h_pinv: [[1.0], [0.0]],
        t,
    };
    let n = z.len();
    // Start-up with the general code, then the fast loop from where it stopped.
    let k0 = startup_len(init, st, z);
    if k0 > 0 {
        let (s0, s1) = {
            let [a, b] = &mut out.states;
            (&mut a[..k0], &mut b[..k0])
        };
        let mut head = TrackOut {
            states: [s0, s1],
            resid: out.resid.as_deref_mut().map(|r| &mut r[..k0]),
        };
        run_track(&g, init, st, k0, |k| [z[k].to_f64()], &mut head);
    }
    if st.phase < 2 {
        return;
    }
    let (one_m_a, g2) = (1.0 - alpha, beta / t);
    let (mut x, mut v) = (st.x[0], st.x[1]);
    let [xs, vs] = &mut out.states;
    let (xs, vs) = (&mut xs[k0..n], &mut vs[k0..n]);
    let zs = &z[k0..n];
    match out.resid.as_deref_mut() {
        None => {
            for ((zk, xo), vo) in zs.iter().zip(xs.iter_mut()).zip(vs.iter_mut()) {
                let zk = zk.to_f64();
                let xp = t.mul_add(v, x);
                let e = zk - xp;
                if e.is_nan() {
                    x = xp;
                } else {
                    x = one_m_a.mul_add(xp, alpha * zk);
                    v = g2.mul_add(e, v);
                }
                *xo = T::from_f64(x);
                *vo = T::from_f64(v);
            }
        }
        Some(r) => {
            let r = &mut r[k0..n];
            for (((zk, xo), vo), ro) in zs.iter().zip(xs.iter_mut()).zip(vs.iter_mut()).zip(r) {
                let zk = zk.to_f64();
                let xp = t.mul_add(v, x);
                let e = zk - xp;
                if e.is_nan() {
                    x = xp;
                } else {
                    x = one_m_a.mul_add(xp, alpha * zk);
                    v = g2.mul_add(e, v);
                }
                *xo = T::from_f64(x);
                *vo = T::from_f64(v);
                *ro = T::from_f64(e);
            }
        }
    }
    st.x[0] = x;
    st.x[1] = v;
}

/// Number of leading samples of `z` consumed by the start-up phase (a
/// dry run of the phase logic; the state is not changed).
fn startup_len<T: IoFloat>(init: Init, st: &TrackState, z: &[T]) -> usize {
    let mut phase = st.phase;
    let mut k = 0;
    while phase < 2 && k < z.len() {
        if !z[k].to_f64().is_nan() {
            phase = if phase == 0 && init == Init::TwoPoint {
                1
            } else {
                2
            };
        }
        k += 1;
    }
    k
}

/// Run many tracks in parallel (rayon's global pool) or serially.
///
/// `track(i, state, out)` filters track `i`. `states` holds the per-track
/// state (updated in place); `out` is the estimate buffer `(N, n_tracks,
/// n_samples)` component-major; `resid` the optional residual buffer
/// `(n_tracks, n_samples, m)`.
pub fn run_batch<T: IoFloat, const N: usize>(
    n_tracks: usize,
    n_samples: usize,
    m: usize,
    states: &mut [TrackState],
    out: &mut [T],
    resid: Option<&mut [T]>,
    parallel: bool,
    track: impl Fn(usize, &mut TrackState, &mut TrackOut<'_, T, N>) + Sync + Send,
) -> Result<()> {
    let per = n_tracks * n_samples;
    if states.len() != n_tracks || out.len() != N * per {
        return Err(Error::Shape(format!(
            "state of {} tracks / output of {} elements for {N} x {n_tracks} x {n_samples}",
            states.len(),
            out.len()
        )));
    }
    if let Some(r) = &resid {
        if r.len() != per * m {
            return Err(Error::Shape("residual buffer has the wrong size".into()));
        }
    }
    if per == 0 {
        return Ok(());
    }
    // Per-track views: N component rows + residual row.
    let mut comps: Vec<std::slice::ChunksExactMut<'_, T>> = out
        .chunks_exact_mut(per)
        .map(|c| c.chunks_exact_mut(n_samples))
        .collect();
    let mut resid_rows = resid.map(|r| r.chunks_exact_mut(n_samples * m));
    let mut jobs: Vec<(usize, &mut TrackState, TrackOut<'_, T, N>)> = Vec::with_capacity(n_tracks);
    for (i, st) in states.iter_mut().enumerate() {
        let mut rows: Vec<&mut [T]> = Vec::with_capacity(N);
        for c in comps.iter_mut() {
            rows.push(c.next().ok_or_else(|| Error::Shape("output rows".into()))?);
        }
        let states_arr: [&mut [T]; N] = rows
            .try_into()
            .map_err(|_| Error::Shape("output components".into()))?;
        let r = match resid_rows.as_mut() {
            Some(it) => Some(
                it.next()
                    .ok_or_else(|| Error::Shape("residual rows".into()))?,
            ),
            None => None,
        };
        jobs.push((
            i,
            st,
            TrackOut {
                states: states_arr,
                resid: r,
            },
        ));
    }
    if parallel && n_tracks > 1 {
        jobs.into_par_iter()
            .with_min_len(1.max(16_384 / n_samples.max(1)))
            .for_each(|(i, st, mut o)| track(i, st, &mut o));
    } else {
        for (i, st, mut o) in jobs {
            track(i, st, &mut o);
        }
    }
    Ok(())
}

/// Optional smoothing after filtering: backward gains `A` (one per parameter
/// set) and the lag (`None`: fixed interval). See [`crate::smooth`].
#[derive(Debug, Clone, Copy)]
pub struct Smoother<'a, const N: usize> {
    /// Backward gains `A = P_filt Phi^T P_pred^-1`.
    pub a: &'a [[[f64; N]; N]],
    /// Fixed lag, or `None` for the fixed-interval smoother.
    pub lag: Option<usize>,
}

/// Filter a batch with a general fixed-gain filter: one `Gains` for all
/// tracks (`gains.len() == 1`) or one per track; optionally smooth each track
/// right after filtering it (while it is in cache).
pub fn filter_general<T: IoFloat, const N: usize, const M: usize>(
    gains: &[Gains<N, M>],
    init: Init,
    z: &Measurements<'_, T>,
    states: &mut [TrackState],
    out: &mut [T],
    resid: Option<&mut [T]>,
    parallel: bool,
    smoother: Option<Smoother<'_, N>>,
) -> Result<()> {
    check_params(gains.len(), z)?;
    if let Some(sm) = &smoother {
        check_params(sm.a.len(), z)?;
    }
    if z.m != M {
        return Err(Error::Shape(format!(
            "measurement dimension {} != {M}",
            z.m
        )));
    }
    z.validate()?;
    run_batch::<T, N>(
        z.n_tracks,
        z.n_samples,
        M,
        states,
        out,
        resid,
        parallel,
        |i, st, o| {
            let g = &gains[if gains.len() == 1 { 0 } else { i }];
            match z.row(i) {
                Some(row) => run_track(
                    g,
                    init,
                    st,
                    z.n_samples,
                    |k| {
                        let mut a = [0.0; M];
                        a[0] = row[k].to_f64();
                        a
                    },
                    o,
                ),
                None => run_track(
                    g,
                    init,
                    st,
                    z.n_samples,
                    |k| std::array::from_fn(|j| z.at(i, k, j)),
                    o,
                ),
            }
            if let Some(sm) = &smoother {
                let a = &sm.a[if sm.a.len() == 1 { 0 } else { i }];
                crate::smooth::smooth_track(&g.phi, a, sm.lag, &mut o.states);
            }
        },
    )
}

/// Filter a batch with alpha-beta filters (`params[i] = (alpha, beta, T)`,
/// one for all tracks or one per track).
pub fn filter_ab<T: IoFloat>(
    params: &[(f64, f64, f64)],
    init: Init,
    z: &Measurements<'_, T>,
    states: &mut [TrackState],
    out: &mut [T],
    resid: Option<&mut [T]>,
    parallel: bool,
    smoother: Option<Smoother<'_, 2>>,
) -> Result<()> {
    check_params(params.len(), z)?;
    if let Some(sm) = &smoother {
        check_params(sm.a.len(), z)?;
    }
    if z.m != 1 {
        return Err(Error::Shape(format!(
            "alpha-beta needs scalar measurements, got {}",
            z.m
        )));
    }
    z.validate()?;
    run_batch::<T, 2>(
        z.n_tracks,
        z.n_samples,
        1,
        states,
        out,
        resid,
        parallel,
        |i, st, o| {
            let (a, b, t) = params[if params.len() == 1 { 0 } else { i }];
            match z.row(i) {
                Some(row) => run_track_ab(a, b, t, init, st, row, o),
                None => {
                    let g = Gains::<2, 1> {
                        phi: [[1.0, t], [0.0, 1.0]],
                        h: [[1.0, 0.0]],
                        k: [[a], [b / t]],
                        h_pinv: [[1.0], [0.0]],
                        t,
                    };
                    run_track(&g, init, st, z.n_samples, |k| [z.at(i, k, 0)], o)
                }
            }
            if let Some(sm) = &smoother {
                let a = &sm.a[if sm.a.len() == 1 { 0 } else { i }];
                crate::smooth::smooth_track(&[[1.0, t], [0.0, 1.0]], a, sm.lag, &mut o.states);
            }
        },
    )
}

fn check_params<T>(n_params: usize, z: &Measurements<'_, T>) -> Result<()> {
    if n_params == 1 || n_params == z.n_tracks {
        Ok(())
    } else {
        Err(Error::Shape(format!(
            "{n_params} parameter sets for {} tracks (need 1 or one per track)",
            z.n_tracks
        )))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn reference_ab(alpha: f64, beta: f64, t: f64, z: &[f64]) -> (Vec<f64>, Vec<f64>) {
        // Plain two-point alpha-beta, written independently.
        let n = z.len();
        let (mut xs, mut vs) = (vec![f64::NAN; n], vec![f64::NAN; n]);
        let valid: Vec<usize> = (0..n).filter(|&k| !z[k].is_nan()).collect();
        if valid.is_empty() {
            return (xs, vs);
        }
        let k1 = valid[0];
        for k in k1..n {
            xs[k] = z[k1];
        }
        if valid.len() < 2 {
            return (xs, vs);
        }
        let k2 = valid[1];
        let (mut x, mut v) = (z[k2], (z[k2] - z[k1]) / ((k2 - k1) as f64 * t));
        xs[k2] = x;
        vs[k2] = v;
        for k in k2 + 1..n {
            let xp = x + t * v;
            if z[k].is_nan() {
                x = xp;
            } else {
                let e = z[k] - xp;
                x = xp + alpha * e;
                v += beta / t * e;
            }
            xs[k] = x;
            vs[k] = v;
        }
        (xs, vs)
    }

    fn close(a: f64, b: f64) -> bool {
        (a.is_nan() && b.is_nan()) || (a - b).abs() <= 1e-12 * (1.0 + b.abs())
    }

    #[test]
    fn ab_matches_reference_with_nans_and_chunks() {
        let n = 500;
        let mut z: Vec<f64> = (0..n)
            .map(|k| 0.3 * k as f64 + ((k * 7919) % 13) as f64 * 0.1)
            .collect();
        for k in [0usize, 3, 4, 100, 101, 102, 499] {
            z[k] = f64::NAN;
        }
        let (a, b, t) = (0.5, 0.2, 0.1);
        let (rx, rv) = reference_ab(a, b, t, &z);
        for split in [n, 1, 2, 3, 250] {
            let mut st = [TrackState::default()];
            let mut out = vec![0.0; 2 * n];
            {
                let (o1, o2) = out.split_at_mut(n);
                let meas1 = Measurements::contiguous(&z[..split], 1, split, 1).unwrap();
                let mut buf = vec![0.0; 2 * split];
                filter_ab(
                    &[(a, b, t)],
                    Init::TwoPoint,
                    &meas1,
                    &mut st,
                    &mut buf,
                    None,
                    false,
                    None,
                )
                .unwrap();
                o1[..split].copy_from_slice(&buf[..split]);
                o2[..split].copy_from_slice(&buf[split..]);
                if split < n {
                    let rest = n - split;
                    let meas2 = Measurements::contiguous(&z[split..], 1, rest, 1).unwrap();
                    let mut buf = vec![0.0; 2 * rest];
                    filter_ab(
                        &[(a, b, t)],
                        Init::TwoPoint,
                        &meas2,
                        &mut st,
                        &mut buf,
                        None,
                        false,
                        None,
                    )
                    .unwrap();
                    o1[split..].copy_from_slice(&buf[..rest]);
                    o2[split..].copy_from_slice(&buf[rest..]);
                }
            }
            for k in 0..n {
                assert!(
                    close(out[k], rx[k]),
                    "split {split} x[{k}] {} vs {}",
                    out[k],
                    rx[k]
                );
                assert!(
                    close(out[n + k], rv[k]),
                    "split {split} v[{k}] {} vs {}",
                    out[n + k],
                    rv[k]
                );
            }
        }
    }

    #[test]
    fn general_kernel_equals_ab_kernel() {
        let n = 300;
        let z: Vec<f64> = (0..n).map(|k| (k as f64 * 0.37).sin() * 10.0).collect();
        let (a, b, t) = (0.4, 0.1, 0.5);
        let g = Gains::<2, 1> {
            phi: [[1.0, t], [0.0, 1.0]],
            h: [[1.0, 0.0]],
            k: [[a], [b / t]],
            h_pinv: [[1.0], [0.0]],
            t,
        };
        let meas = Measurements::contiguous(&z, 1, n, 1).unwrap();
        let mut s1 = [TrackState::default()];
        let mut s2 = [TrackState::default()];
        let mut o1 = vec![0.0; 2 * n];
        let mut o2 = vec![0.0; 2 * n];
        filter_ab(
            &[(a, b, t)],
            Init::First,
            &meas,
            &mut s1,
            &mut o1,
            None,
            false,
            None,
        )
        .unwrap();
        filter_general(
            &[g],
            Init::First,
            &meas,
            &mut s2,
            &mut o2,
            None,
            false,
            None,
        )
        .unwrap();
        for k in 0..2 * n {
            assert!(close(o1[k], o2[k]), "{k}: {} {}", o1[k], o2[k]);
        }
    }

    #[test]
    fn bad_strides_and_param_counts_are_errors() {
        let z = [1.0f64; 10];
        let m = Measurements {
            data: &z,
            base: 0,
            s_track: 5,
            s_sample: 1,
            s_comp: 1,
            n_tracks: 3,
            n_samples: 5,
            m: 1,
        };
        assert!(m.validate().is_err());
        let meas = Measurements::contiguous(&z, 2, 5, 1).unwrap();
        let mut st = [TrackState::default(); 2];
        let mut out = vec![0.0; 20];
        assert!(filter_ab(
            &[(0.5, 0.1, 1.0); 3],
            Init::First,
            &meas,
            &mut st,
            &mut out,
            None,
            false,
            None
        )
        .is_err());
    }
}
