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
//! (The opt-in [`f32arith`] runs alpha-beta on `f32` data in `f32`
//! arithmetic, with the same guarantees among its own paths.)
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

#[cfg(target_arch = "x86_64")]
#[path = "filter_avx2.rs"]
mod avx2;
#[path = "filter_f32.rs"]
pub mod f32arith;
#[cfg(target_arch = "x86_64")]
#[path = "filter_flat.rs"]
mod flat;
#[cfg(target_arch = "x86_64")]
#[path = "filter_flat_vec.rs"]
mod flatv;
#[cfg(target_arch = "x86_64")]
#[path = "filter_rows16.rs"]
mod rows16;
#[cfg(target_arch = "x86_64")]
#[path = "filter_simd.rs"]
mod simd;

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

/// `f64`s in a [`TrackState`]: the state, the phase, the gap counter and
/// the two timestamps of the irregular-time kernels ([`crate::ragged`]).
pub const STATE_WIDTH: usize = MAX_STATES + 4;

/// Per-track filter state carried between calls (streaming). `repr(C)`:
/// exactly [`STATE_WIDTH`] `f64`s, so a `(n_tracks, STATE_WIDTH)` `f64`
/// array is a `[TrackState]` (see [`states_from_f64`]).
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C)]
pub struct TrackState {
    /// State estimate (first `n` entries used).
    pub x: [f64; MAX_STATES],
    /// 0: no valid sample yet; 1: one valid sample held (two-point start);
    /// 2: running. (Stored as `f64` so that a state is exactly
    /// [`STATE_WIDTH`] `f64`s, the layout of the Python `FilterState`.)
    pub phase: f64,
    /// In phase 1, samples since the held valid sample.
    pub since: f64,
    /// Timestamp of the last (kept) sample, NaN when none is known (only the
    /// irregular-time kernels of [`crate::ragged`] read or write it).
    pub t_last: f64,
    /// In phase 1 with timestamps, the timestamp of the held valid sample
    /// (NaN when unknown: the velocity then uses `since` and `T`).
    pub t_held: f64,
}

impl Default for TrackState {
    fn default() -> Self {
        TrackState {
            x: [0.0; MAX_STATES],
            phase: 0.0,
            since: 0.0,
            t_last: f64::NAN,
            t_held: f64::NAN,
        }
    }
}

const _: () = assert!(
    std::mem::size_of::<TrackState>() == STATE_WIDTH * std::mem::size_of::<f64>()
        && std::mem::align_of::<TrackState>() == std::mem::align_of::<f64>()
);

/// View a `(n_tracks, STATE_WIDTH)` `f64` buffer as per-track states, in
/// place (no copy). Errors if the length is not a multiple of `STATE_WIDTH`.
pub fn states_from_f64(packed: &mut [f64]) -> Result<&mut [TrackState]> {
    if !packed.len().is_multiple_of(STATE_WIDTH) {
        return Err(Error::Shape(format!(
            "state buffer of {} f64 is not a multiple of {STATE_WIDTH}",
            packed.len()
        )));
    }
    let n = packed.len() / STATE_WIDTH;
    // SAFETY: TrackState is repr(C) and made of exactly STATE_WIDTH f64
    // fields (size and alignment asserted above), every bit pattern is a
    // valid f64, and the returned slice reborrows `packed` exclusively.
    Ok(unsafe { std::slice::from_raw_parts_mut(packed.as_mut_ptr().cast::<TrackState>(), n) })
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

    /// Check that every element lies inside `data` (with checked
    /// arithmetic: absurd strides or counts are an error, not an overflow).
    pub fn validate(&self) -> Result<()> {
        if self.n_tracks == 0 || self.n_samples == 0 || self.m == 0 {
            return Ok(());
        }
        let overflow =
            || Error::Shape("measurement strides or counts overflow the address range".into());
        let ext = |n: usize, s: isize| -> Option<(isize, isize)> {
            let span = isize::try_from(n - 1).ok()?.checked_mul(s)?;
            Some((span.min(0), span.max(0)))
        };
        let parts = [
            ext(self.n_tracks, self.s_track).ok_or_else(overflow)?,
            ext(self.n_samples, self.s_sample).ok_or_else(overflow)?,
            ext(self.m, self.s_comp).ok_or_else(overflow)?,
        ];
        let base = isize::try_from(self.base).map_err(|_| overflow())?;
        let (mut lo, mut hi) = (base, base);
        for (a, b) in parts {
            lo = lo.checked_add(a).ok_or_else(overflow)?;
            hi = hi.checked_add(b).ok_or_else(overflow)?;
        }
        if lo < 0 || hi >= self.data.len() as isize {
            return Err(Error::Shape(
                "measurement strides reach outside the buffer".into(),
            ));
        }
        Ok(())
    }

    /// Row `i` as a contiguous slice (sample-major, `n_samples * m`
    /// elements) when the track's measurements are adjacent in memory.
    #[inline]
    pub(crate) fn row(&self, i: usize) -> Option<&'a [T]> {
        if self.s_sample == self.m as isize && (self.m == 1 || self.s_comp == 1) {
            let start = (self.base as isize + i as isize * self.s_track) as usize;
            self.data.get(start..start + self.n_samples * self.m)
        } else {
            None
        }
    }

    #[inline(always)]
    pub(crate) fn at(&self, i: usize, k: usize, j: usize) -> f64 {
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
    while st.phase < 2.0 && k0 < n {
        let zk = z(k0);
        let valid = zk.iter().all(|v| !v.is_nan());
        if let Some(r) = out.resid.as_deref_mut() {
            for j in 0..M {
                r[k0 * M + j] = nan;
            }
        }
        match (st.phase as u8, valid) {
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
                    st.phase = 2.0;
                    for c in 0..N {
                        out.states[c][k0] = T::from_f64(x[c]);
                    }
                } else {
                    st.phase = 1.0;
                    st.since = 0.0;
                    out.states[0][k0] = T::from_f64(x[0]);
                    for c in 1..N {
                        out.states[c][k0] = nan;
                    }
                }
            }
            (_, false) => {
                // phase 1, missed sample: hold the first position.
                st.since += 1.0;
                out.states[0][k0] = T::from_f64(x[0]);
                for c in 1..N {
                    out.states[c][k0] = nan;
                }
            }
            (_, true) => {
                // phase 1, second valid sample: two-point start.
                let gap = st.since + 1.0;
                let p1 = x[0];
                let p2 = zk[0];
                x = [0.0; N];
                x[0] = p2;
                if N > 1 {
                    x[1] = (p2 - p1) / (gap * g.t);
                }
                st.phase = 2.0;
                st.since = 0.0;
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

/// Whether the fused multiply-add kernels are used on this machine (decided
/// once per process, so results never depend on anything but the data).
pub fn uses_fma() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        static FMA: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
        *FMA.get_or_init(|| std::is_x86_feature_detected!("fma"))
    }
    #[cfg(target_arch = "aarch64")]
    {
        true
    }
    #[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
    {
        false
    }
}

#[inline(always)]
pub(crate) fn madd<const FMA: bool>(a: f64, b: f64, c: f64) -> f64 {
    if FMA {
        a.mul_add(b, c)
    } else {
        a * b + c
    }
}

/// Constants of one alpha-beta filter.
#[derive(Debug, Clone, Copy)]
struct AbConst {
    t: f64,
    alpha: f64,
    one_minus_alpha: f64,
    g2: f64,
}

impl AbConst {
    fn new(alpha: f64, beta: f64, t: f64) -> Self {
        AbConst {
            t,
            alpha,
            one_minus_alpha: 1.0 - alpha,
            g2: beta / t,
        }
    }
}

/// One alpha-beta step. The update is arranged so that the loop-carried
/// dependency chain is two multiply-adds for both state components:
/// `x_p = x + T v`, `x' = (1 - alpha) x_p + alpha z`,
/// `v' = (v + g2 z) - g2 x_p` (the terms with `z` are off the chain).
/// Returns `(x', v', residual)`; a NaN `z` coasts.
#[inline(always)]
fn ab_step<const FMA: bool>(c: &AbConst, x: f64, v: f64, z: f64) -> (f64, f64, f64) {
    let xp = madd::<FMA>(c.t, v, x);
    let e = z - xp;
    // A missed sample (NaN) becomes coefficients (1, 0) and gain 0, selected
    // from z alone, so no compare or blend sits on the dependency chain:
    // x' = 1 * x_p + 0 = x_p, v' = v - 0 * x_p = v.
    let valid = !z.is_nan();
    let zz = if valid { z } else { 0.0 };
    let c1 = if valid { c.one_minus_alpha } else { 1.0 };
    let g = if valid { c.g2 } else { 0.0 };
    let w = madd::<FMA>(g, zz, v);
    (madd::<FMA>(c1, xp, c.alpha * zz), madd::<FMA>(-g, xp, w), e)
}

/// Steady-state alpha-beta loop of one track over samples `k0..n`.
#[inline(always)]
fn ab_loop<T: IoFloat, const FMA: bool>(
    c: &AbConst,
    st: &mut TrackState,
    k0: usize,
    n: usize,
    z: impl Fn(usize) -> f64,
    out: &mut TrackOut<'_, T, 2>,
) {
    let (mut x, mut v) = (st.x[0], st.x[1]);
    let [xs, vs] = &mut out.states;
    let (xs, vs) = (&mut xs[..n], &mut vs[..n]);
    match out.resid.as_deref_mut() {
        None => {
            for k in k0..n {
                let (x1, v1, _) = ab_step::<FMA>(c, x, v, z(k));
                x = x1;
                v = v1;
                xs[k] = T::from_f64(x);
                vs[k] = T::from_f64(v);
            }
        }
        Some(r) => {
            let r = &mut r[..n];
            for k in k0..n {
                let (x1, v1, e) = ab_step::<FMA>(c, x, v, z(k));
                x = x1;
                v = v1;
                xs[k] = T::from_f64(x);
                vs[k] = T::from_f64(v);
                r[k] = T::from_f64(e);
            }
        }
    }
    st.x[0] = x;
    st.x[1] = v;
}

/// Lanes of the interleaved alpha-beta kernel.
pub const AB_LANES: usize = 8;

/// `AB_LANES` running tracks at once (contiguous rows, no residuals): the
/// tracks' dependency chains overlap, so throughput is bounded by memory,
/// not by the latency of one track's recursion. Same arithmetic per track as
/// [`ab_loop`], so results are bit-identical to running the tracks alone.
#[inline(always)]
fn ab_lanes<T: IoFloat, const FMA: bool>(
    c: &[AbConst; AB_LANES],
    x_out: &mut [f64; AB_LANES],
    v_out: &mut [f64; AB_LANES],
    k0: usize,
    n: usize,
    z: [&[T]; AB_LANES],
    xs: [&mut [T]; AB_LANES],
    vs: [&mut [T]; AB_LANES],
    ahead: Option<(usize, usize)>,
) {
    let z = z.map(|s| &s[..n]);
    let xs = xs.map(|s| &mut s[..n]);
    let vs = vs.map(|s| &mut s[..n]);
    let line = (64 / std::mem::size_of::<T>()).max(1);
    // Work on local copies: the caller's arrays may share a cache line with
    // another thread's (false sharing when segments run in parallel).
    let (mut xl, mut vl) = (*x_out, *v_out);
    let (x, v) = (&mut xl, &mut vl);
    for k in k0..n {
        if let Some((dz, dout)) = ahead {
            if k % line == 0 {
                for l in 0..AB_LANES {
                    prefetch(z[l].as_ptr().wrapping_add(dz + k));
                    prefetch(xs[l].as_ptr().wrapping_add(dout + k));
                    prefetch(vs[l].as_ptr().wrapping_add(dout + k));
                }
            }
        }
        for l in 0..AB_LANES {
            let (x1, v1, _) = ab_step::<FMA>(&c[l], x[l], v[l], z[l][k].to_f64());
            x[l] = x1;
            v[l] = v1;
            xs[l][k] = T::from_f64(x1);
            vs[l][k] = T::from_f64(v1);
        }
    }
    *x_out = xl;
    *v_out = vl;
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "fma")]
fn ab_lanes_fma<T: IoFloat>(
    c: &[AbConst; AB_LANES],
    x: &mut [f64; AB_LANES],
    v: &mut [f64; AB_LANES],
    n: usize,
    z: [&[T]; AB_LANES],
    xs: [&mut [T]; AB_LANES],
    vs: [&mut [T]; AB_LANES],
) {
    ab_lanes::<T, true>(c, x, v, 0, n, z, xs, vs, None)
}

/// [`ab_lanes`] from a context that may not have the FMA target feature
/// (a closure run by rayon): `FMA` is true only when [`uses_fma`] said so.
/// Takes the vector lanes where the CPU has them (bit-identical results).
#[allow(clippy::too_many_arguments)]
fn ab_lanes_entry<T: IoFloat, const FMA: bool>(
    c: &[AbConst; AB_LANES],
    x: &mut [f64; AB_LANES],
    v: &mut [f64; AB_LANES],
    n: usize,
    z: [&[T]; AB_LANES],
    xs: [&mut [T]; AB_LANES],
    vs: [&mut [T]; AB_LANES],
    nt: bool,
) {
    #[cfg(target_arch = "x86_64")]
    {
        if FMA && rows_zen4::<T>() && simd::fits::<T>(0, n) {
            // SAFETY: `rows_zen4` checked AVX2, FMA, AVX-512F and -VL.
            unsafe { avx2::ab_lanes8_zen4(c, x, v, 0, n, z, xs, vs, None, nt) };
            return;
        }
        if FMA && simd::available() && simd::fits::<T>(0, n) {
            // SAFETY: `available()` checked AVX-512F and FMA on this CPU.
            unsafe { simd::ab_lanes8(c, x, v, 0, n, z, xs, vs, None, nt) };
            return;
        }
        if FMA && simd::avx2_available() && simd::fits::<T>(0, n) {
            // SAFETY: `avx2_available()` checked AVX2 and FMA on this CPU.
            unsafe { avx2::ab_lanes8(c, x, v, 0, n, z, xs, vs, None, nt) };
            return;
        }
        if FMA {
            // SAFETY: FMA = true is only instantiated after `uses_fma()`
            // confirmed the CPU supports FMA.
            unsafe { ab_lanes_fma(c, x, v, n, z, xs, vs) };
            return;
        }
    }
    let _ = nt;
    ab_lanes::<T, FMA>(c, x, v, 0, n, z, xs, vs, None)
}

/// Whether outputs of `bytes` bytes are written with non-temporal stores by
/// the vector lanes (which write whole 64-byte lines): only outputs much
/// bigger than the caches. `f32` too if `lines_f32` (the kernel writes
/// whole lines of `f32` as well).
pub(crate) fn streamed<T: 'static>(bytes: usize, lines_f32: bool) -> bool {
    let f64_ = std::any::TypeId::of::<T>() == std::any::TypeId::of::<f64>();
    (f64_ || lines_f32) && bytes >= NT_MIN_BYTES
}

/// Hint the CPU to fetch the cache line at `p` (no effect on memory, never
/// faults, any address allowed).
#[inline(always)]
fn prefetch<T>(p: *const T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch is only a hint; it does not access memory
    // architecturally and cannot fault, whatever the address.
    unsafe {
        std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(p as *const i8)
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = p;
}

/// Orders this thread's streamed (non-temporal) stores before its later
/// stores (`sfence`): streamed stores are weakly ordered, so a task that made
/// them fences before its outputs are read, by the thread that waits for the
/// task (rayon's completion signal is an ordinary store) or by later code of
/// its own. The general lanes leave this to their callers, once per task:
/// a fence per group of four tracks waited for the write-combining buffers
/// every 400 samples on 100,000 x 100 (4 % of the time; docs/benchmarks.md,
/// session 22).
#[inline]
fn store_fence() {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: `sfence` is part of SSE, which every x86_64 CPU has; it only
    // orders stores.
    unsafe {
        std::arch::x86_64::_mm_sfence()
    };
}

/// Outputs of at least this many bytes are written with non-temporal
/// (cache-bypassing) stores by the vector lanes. (64 MiB until 2026-12-02:
/// on Zen 3 the row lanes' ordinary stores ran 3-4 x slower than streamed
/// ones once the outputs outgrew the caches, e.g. 1,000 x 1,000 float64
/// 3.1-3.4 -> 0.9 ns per sample, 20,000 x 100 4.0 -> 1.8-2.3;
/// docs/benchmarks.md, session 10.)
pub(crate) const NT_MIN_BYTES: usize = 8 << 20;

/// Rows at least this long run in the vector lanes (on shorter rows the
/// scalar heads and tails cost more than the vector loop saves).
const SIMD_MIN_SAMPLES: usize = 256;

/// On AVX-512 CPUs, contiguous rows shorter than this (`[f32, f64]`) run
/// in the flat kernel rather than the row lanes (from `SIMD_MIN_SAMPLES`
/// up; shorter ones as before). On an Intel Xeon, 10^7 samples from memory,
/// ns per sample, row lanes -> flat kernel (two runs): `f64` rows of 256
/// 2.0 -> 1.3-1.4, 300 2.5-2.6 -> 1.3-1.4, 400 1.5-1.6 -> 1.3, 500 1.4 ->
/// 1.1 (600 1.13-1.15 -> 1.17-1.28: not taken); `f32` 256 1.4-1.5 ->
/// 0.75-0.84, 300 2.2-2.4 -> 0.73-0.80, 400 0.82-1.0 -> 0.59-0.62, 600
/// 0.73-0.80 -> 0.58-0.62, 1,000 0.67-0.77 -> 0.63-0.67, 2,000 0.56 ->
/// 0.51, 3,000 0.63-0.73 -> 0.60-0.70 (10,000 the same; docs/benchmarks.md,
/// session 24).
#[cfg(target_arch = "x86_64")]
const FLAT_AVX512_MAX_SAMPLES: [usize; 2] = [4096, 512];

/// Rows at least this long run in the row lanes rather than the flat
/// kernel of `kind` (see [`FLAT_AVX512_MAX_SAMPLES`]).
#[cfg(target_arch = "x86_64")]
fn flat_max_samples<T: 'static>(kind: FlatKernel) -> usize {
    match kind {
        FlatKernel::Avx2 => SIMD_MIN_SAMPLES,
        FlatKernel::Avx512 | FlatKernel::Avx512Generic => {
            FLAT_AVX512_MAX_SAMPLES[usize::from(simd::is_f64::<T>())]
        }
    }
}

/// Tracks at most this long get software prefetching of the next group of
/// tracks (the hardware prefetcher does not ramp up on short rows).
const PREFETCH_MAX_SAMPLES: usize = 4096;

/// Number of segments of a split single track (fixed, so results never
/// depend on the thread count): two groups of `AB_LANES`.
pub const SPLIT_SEGMENTS: usize = 2 * AB_LANES;
/// Shortest steady-state run that is split.
pub const SPLIT_MIN_SAMPLES: usize = 1 << 16;

/// How a long alpha-beta track is split (see [`ab_split`]).
#[derive(Debug, Clone, Copy)]
struct SplitPlan {
    seg_len: usize,
}

impl SplitPlan {
    /// A plan when splitting pays: a long run and a fast-decaying loop
    /// (the correction pass then touches a small part of each segment).
    fn new(alpha: f64, beta: f64, len: usize) -> Option<Self> {
        if len < SPLIT_MIN_SAMPLES || !jury_ok(alpha, beta) {
            return None;
        }
        let rho = ab_spectral_radius(alpha, beta);
        if rho.is_nan() || rho >= 1.0 {
            return None;
        }
        // Samples until a correction shrinks by 2^-60.
        let decay = if rho <= 0.0 {
            1.0
        } else {
            (-60.0 * std::f64::consts::LN_2) / rho.ln()
        };
        let seg_len = len / SPLIT_SEGMENTS;
        (decay.is_finite() && 8.0 * decay <= seg_len as f64).then_some(SplitPlan { seg_len })
    }
}

/// Segment length of a split alpha-beta track of `len` samples
/// ([`SplitPlan`]: at least [`SPLIT_MIN_SAMPLES`] and a fast-decaying loop),
/// `None` when it is not split.
pub(crate) fn split_seg_len(alpha: f64, beta: f64, len: usize) -> Option<usize> {
    SplitPlan::new(alpha, beta, len).map(|p| p.seg_len)
}

fn jury_ok(alpha: f64, beta: f64) -> bool {
    alpha > 0.0 && beta > 0.0 && 2.0 * alpha + beta < 4.0
}

/// Spectral radius of the alpha-beta loop, the largest root magnitude of
/// `z^2 - (2 - alpha - beta) z + (1 - alpha)`.
fn ab_spectral_radius(alpha: f64, beta: f64) -> f64 {
    let tr = 2.0 - alpha - beta;
    let det = 1.0 - alpha;
    let disc = tr * tr - 4.0 * det;
    if disc < 0.0 {
        det.abs().sqrt()
    } else {
        let sq = disc.sqrt();
        ((tr + sq) * 0.5).abs().max(((tr - sq) * 0.5).abs())
    }
}

/// Alpha-beta filtering of one long track in segments (the filter is
/// linear, so a segment started from a guessed state differs from the true
/// run by the state difference propagated through the loop, which decays).
///
/// Pass 1 runs all `SPLIT_SEGMENTS` segments interleaved (and, with
/// `parallel`, the two lane groups on two threads): segment 0 from the true
/// state, the others from a guess (position from the sample before the
/// segment, velocity zero). Pass 2, in order, propagates each segment's
/// start-state error `delta` through the loop (`A` for an updated sample,
/// `Phi` for a missed one), adds it to the outputs until it is below 2^-60
/// of the estimate, and so obtains each segment's true end state. The
/// result equals the unsplit run to rounding (about 1e-15 relative); the
/// segmentation depends only on the track length.
#[inline(always)]
fn ab_split<T: IoFloat, const FMA: bool>(
    c: &AbConst,
    st: &mut TrackState,
    k0: usize,
    row: &[T],
    out: &mut TrackOut<'_, T, 2>,
    plan: SplitPlan,
    parallel: bool,
) {
    let n = row.len();
    let ls = plan.seg_len;
    let body_end = k0 + SPLIT_SEGMENTS * ls;
    // Starting states: true for segment 0, guessed for the others.
    let mut x0 = [0.0; SPLIT_SEGMENTS];
    let mut v0 = [0.0; SPLIT_SEGMENTS];
    x0[0] = st.x[0];
    v0[0] = st.x[1];
    for j in 1..SPLIT_SEGMENTS {
        let prev = row[k0 + j * ls - 1].to_f64();
        x0[j] = if prev.is_nan() { 0.0 } else { prev };
    }
    let (xs, vs) = {
        let [a, b] = &mut out.states;
        (&mut a[k0..body_end], &mut b[k0..body_end])
    };
    let zs = &row[k0..body_end];
    let mut ends_x = [0.0; SPLIT_SEGMENTS];
    let mut ends_v = [0.0; SPLIT_SEGMENTS];
    {
        let mut xc = xs.chunks_exact_mut(ls);
        let mut vc = vs.chunks_exact_mut(ls);
        let mut zc = zs.chunks_exact(ls);
        type Lanes<'s, T> = (
            [&'s mut [T]; AB_LANES],
            [&'s mut [T]; AB_LANES],
            [&'s [T]; AB_LANES],
        );
        let mut lane_group = || -> Lanes<'_, T> {
            (
                std::array::from_fn(|_| xc.next().unwrap_or_default()),
                std::array::from_fn(|_| vc.next().unwrap_or_default()),
                std::array::from_fn(|_| zc.next().unwrap_or_default()),
            )
        };
        let (xa, va, za) = lane_group();
        let (xb, vb, zb) = lane_group();
        let cs = [*c; AB_LANES];
        let mut xa0: [f64; AB_LANES] = std::array::from_fn(|l| x0[l]);
        let mut va0: [f64; AB_LANES] = std::array::from_fn(|l| v0[l]);
        let mut xb0: [f64; AB_LANES] = std::array::from_fn(|l| x0[AB_LANES + l]);
        let mut vb0: [f64; AB_LANES] = std::array::from_fn(|l| v0[AB_LANES + l]);
        // Closures are separate functions that do not inherit the caller's
        // target features: enter the FMA code explicitly.
        let nt = streamed::<T>(2 * n * std::mem::size_of::<T>(), true);
        let run_a = || ab_lanes_entry::<T, FMA>(&cs, &mut xa0, &mut va0, ls, za, xa, va, nt);
        let run_b = || ab_lanes_entry::<T, FMA>(&cs, &mut xb0, &mut vb0, ls, zb, xb, vb, nt);
        if parallel {
            rayon::join(run_a, run_b);
        } else {
            run_a();
            run_b();
        }
        ends_x[..AB_LANES].copy_from_slice(&xa0);
        ends_x[AB_LANES..].copy_from_slice(&xb0);
        ends_v[..AB_LANES].copy_from_slice(&va0);
        ends_v[AB_LANES..].copy_from_slice(&vb0);
    }
    // Pass 2: corrections, in order.
    let (t, oma, g2) = (c.t, c.one_minus_alpha, c.g2);
    let (mut true_x, mut true_v) = (ends_x[0], ends_v[0]);
    let tiny = 2f64.powi(-60);
    for j in 1..SPLIT_SEGMENTS {
        let (mut dx, mut dv) = (true_x - x0[j], true_v - v0[j]);
        let a = k0 + j * ls;
        let mut k = a;
        while k < a + ls && (dx != 0.0 || dv != 0.0) {
            // delta' = A delta (updated sample) or Phi delta (missed sample)
            let dp = madd::<FMA>(t, dv, dx);
            if row[k].to_f64().is_nan() {
                dx = dp;
            } else {
                dx = oma * dp;
                dv = madd::<FMA>(-g2, dp, dv);
            }
            let [xo, vo] = &mut out.states;
            let xn = xo[k].to_f64() + dx;
            let vn = vo[k].to_f64() + dv;
            xo[k] = T::from_f64(xn);
            vo[k] = T::from_f64(vn);
            let scale = xn.abs() + (vn * t).abs();
            if dx.abs() + (dv * t).abs() <= tiny * scale {
                dx = 0.0;
                dv = 0.0;
            }
            k += 1;
        }
        true_x = ends_x[j] + dx;
        true_v = ends_v[j] + dv;
    }
    st.x[0] = true_x;
    st.x[1] = true_v;
    // The few samples after the last full segment.
    ab_loop::<T, FMA>(c, st, body_end, n, |k| row[k].to_f64(), out);
}

/// Start-up of one alpha-beta track (`params (a, b, t)`): the samples
/// before it is running, from the state `st`. Returns the number of samples
/// consumed (all `n` if it never runs); the track runs from there with
/// `st.x` when `st.phase == 2`.
#[inline(always)]
fn ab_start<T: IoFloat>(
    a: f64,
    b: f64,
    t: f64,
    init: Init,
    st: &mut TrackState,
    n: usize,
    zf: &impl Fn(usize) -> f64,
    o: &mut TrackOut<'_, T, 2>,
) -> usize {
    // Fast path of the usual start: two valid samples first (same
    // arithmetic as the general start-up code).
    if st.phase == 0.0 && n >= 2 {
        let (z0, z1) = (zf(0), zf(1));
        if !z0.is_nan() && !z1.is_nan() {
            let [s0, s1] = &mut o.states;
            let len = match init {
                Init::TwoPoint => {
                    st.x[0] = z1;
                    st.x[1] = (z1 - z0) / (1.0 * t);
                    s0[0] = T::from_f64(z0);
                    s1[0] = T::from_f64(f64::NAN);
                    s0[1] = T::from_f64(st.x[0]);
                    s1[1] = T::from_f64(st.x[1]);
                    if let Some(r) = o.resid.as_deref_mut() {
                        r[0] = T::from_f64(f64::NAN);
                        r[1] = T::from_f64(f64::NAN);
                    }
                    2
                }
                Init::First => {
                    st.x[0] = z0;
                    st.x[1] = 0.0;
                    s0[0] = T::from_f64(z0);
                    s1[0] = T::from_f64(0.0);
                    if let Some(r) = o.resid.as_deref_mut() {
                        r[0] = T::from_f64(f64::NAN);
                    }
                    1
                }
            };
            st.phase = 2.0;
            st.since = 0.0;
            return len;
        }
    }
    let len = startup_len(init, st, n, zf);
    if len > 0 {
        let gains = Gains::<2, 1> {
            phi: [[1.0, t], [0.0, 1.0]],
            h: [[1.0, 0.0]],
            k: [[a], [b / t]],
            h_pinv: [[1.0], [0.0]],
            t,
        };
        let [s0, s1] = &mut o.states;
        let mut head = TrackOut {
            states: [&mut s0[..len], &mut s1[..len]],
            resid: o.resid.as_deref_mut().map(|r| &mut r[..len]),
        };
        run_track(&gains, init, st, len, |k| [zf(k)], &mut head);
    }
    len
}

type Job<'a, T, const N: usize> = (usize, &'a mut TrackState, TrackOut<'a, T, N>);

/// Alpha-beta filtering of a group of tracks (the unit of parallel work).
#[inline(always)]
fn ab_group<T: IoFloat, const FMA: bool>(
    params: &[(f64, f64, f64)],
    init: Init,
    z: &Measurements<'_, T>,
    group: &mut [Job<'_, T, 2>],
    parallel: bool,
) {
    let n = z.n_samples;
    let konst = |i: usize| {
        let (a, b, t) = params[if params.len() == 1 { 0 } else { i }];
        (AbConst::new(a, b, t), a, b, t)
    };
    // Start-up of every track with the general code.
    let mut k0 = [0usize; AB_LANES];
    let lanes_ok = group.len() == AB_LANES;
    for (g, (i, st, o)) in group.iter_mut().enumerate() {
        let (_, a, b, t) = konst(*i);
        let len = ab_start::<T>(a, b, t, init, st, n, &|k: usize| z.at(*i, k, 0), o);
        if g < AB_LANES {
            k0[g] = len;
        }
    }
    let group_len = group.len();
    let lanes_ok = lanes_ok
        && group
            .iter()
            .all(|(i, st, o)| st.phase == 2.0 && o.resid.is_none() && z.row(*i).is_some());
    if !lanes_ok {
        for (idx, (i, st, o)) in group.iter_mut().enumerate() {
            if st.phase < 2.0 {
                continue;
            }
            let (c, a, b, _) = konst(*i);
            let start = if idx < AB_LANES { k0[idx] } else { 0 };
            match z.row(*i) {
                Some(row) => {
                    if o.resid.is_none() && group_len < AB_LANES {
                        if let Some(plan) = SplitPlan::new(a, b, n - start) {
                            ab_split::<T, FMA>(&c, st, start, row, o, plan, parallel);
                            continue;
                        }
                    }
                    ab_loop::<T, FMA>(&c, st, start, n, |k| row[k].to_f64(), o)
                }
                None => ab_loop::<T, FMA>(&c, st, start, n, |k| z.at(*i, k, 0), o),
            }
        }
        return;
    }
    // Bring every track to a common start, then run the lanes.
    let kmax = k0.iter().copied().max().unwrap_or(0);
    let mut c = [AbConst::new(0.5, 0.1, 1.0); AB_LANES];
    let mut x = [0.0; AB_LANES];
    let mut v = [0.0; AB_LANES];
    let mut rows: [&[T]; AB_LANES] = [&[]; AB_LANES];
    for (l, (i, st, o)) in group.iter_mut().enumerate() {
        c[l] = konst(*i).0;
        let row = z.row(*i).unwrap_or(&[]);
        rows[l] = row;
        ab_loop::<T, FMA>(&c[l], st, k0[l], kmax, |k| row[k].to_f64(), o);
        x[l] = st.x[0];
        v[l] = st.x[1];
    }
    // Output rows of the lanes, without allocating (the group is full here).
    let mut xs: [&mut [T]; AB_LANES] = std::array::from_fn(|_| -> &mut [T] { &mut [] });
    let mut vs: [&mut [T]; AB_LANES] = std::array::from_fn(|_| -> &mut [T] { &mut [] });
    for (l, (_, _, o)) in group.iter_mut().enumerate().take(AB_LANES) {
        let [a, b] = &mut o.states;
        xs[l] = &mut **a;
        vs[l] = &mut **b;
    }
    let ahead = (n <= PREFETCH_MAX_SAMPLES && z.s_track > 0)
        .then(|| (AB_LANES * z.s_track as usize, AB_LANES * n));
    #[cfg(target_arch = "x86_64")]
    if FMA
        && n >= SIMD_MIN_SAMPLES
        && simd::fits::<T>(kmax, n)
        && (simd::available() || simd::avx2_available())
    {
        let nt = streamed::<T>(2 * z.n_tracks * n * std::mem::size_of::<T>(), true);
        if rows_zen4::<T>() {
            // SAFETY: `rows_zen4` checked AVX2, FMA, AVX-512F and -VL.
            unsafe { avx2::ab_lanes8_zen4(&c, &mut x, &mut v, kmax, n, rows, xs, vs, ahead, nt) };
        } else if simd::available() {
            // SAFETY: `available()` checked AVX-512F and FMA on this CPU.
            unsafe { simd::ab_lanes8(&c, &mut x, &mut v, kmax, n, rows, xs, vs, ahead, nt) };
        } else {
            // SAFETY: `avx2_available()` checked AVX2 and FMA on this CPU.
            unsafe { avx2::ab_lanes8(&c, &mut x, &mut v, kmax, n, rows, xs, vs, ahead, nt) };
        }
        for (l, (_, st, _)) in group.iter_mut().enumerate() {
            st.x[0] = x[l];
            st.x[1] = v[l];
        }
        return;
    }
    ab_lanes::<T, FMA>(&c, &mut x, &mut v, kmax, n, rows, xs, vs, ahead);
    for (l, (_, st, _)) in group.iter_mut().enumerate() {
        st.x[0] = x[l];
        st.x[1] = v[l];
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "fma")]
fn ab_group_fma<T: IoFloat>(
    params: &[(f64, f64, f64)],
    init: Init,
    z: &Measurements<'_, T>,
    group: &mut [Job<'_, T, 2>],
    parallel: bool,
) {
    ab_group::<T, true>(params, init, z, group, parallel)
}

fn ab_group_dispatch<T: IoFloat>(
    params: &[(f64, f64, f64)],
    init: Init,
    z: &Measurements<'_, T>,
    group: &mut [Job<'_, T, 2>],
    parallel: bool,
) {
    #[cfg(target_arch = "x86_64")]
    {
        if uses_fma() {
            // SAFETY: the CPU supports FMA (checked at run time by `uses_fma`).
            unsafe { ab_group_fma(params, init, z, group, parallel) };
            return;
        }
        ab_group::<T, false>(params, init, z, group, parallel)
    }
    #[cfg(target_arch = "aarch64")]
    {
        ab_group::<T, true>(params, init, z, group, parallel)
    }
    #[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
    {
        ab_group::<T, false>(params, init, z, group, parallel)
    }
}

/// Number of leading samples consumed by the start-up phase (a dry run of
/// the phase logic; the state is not changed).
fn startup_len(init: Init, st: &TrackState, n: usize, z: &impl Fn(usize) -> f64) -> usize {
    let mut phase = st.phase;
    let mut k = 0;
    while phase < 2.0 && k < n {
        if !z(k).is_nan() {
            phase = if phase == 0.0 && init == Init::TwoPoint {
                1.0
            } else {
                2.0
            };
        }
        k += 1;
    }
    k
}

/// Run many tracks in parallel (rayon's global pool) or serially, in groups
/// of up to `group_size` consecutive tracks.
///
/// `group(jobs)` filters the tracks of one group. `states` holds the
/// per-track state (updated in place); `out` is the estimate buffer `(N,
/// n_tracks, n_samples)` component-major; `resid` the optional residual
/// buffer `(n_tracks, n_samples, m)`.
pub fn run_batch<T: IoFloat, const N: usize>(
    n_tracks: usize,
    n_samples: usize,
    m: usize,
    states: &mut [TrackState],
    out: &mut [T],
    resid: Option<&mut [T]>,
    parallel: bool,
    group_size: usize,
    group: impl Fn(&mut [Job<'_, T, N>]) + Sync + Send,
) -> Result<()> {
    run_batch_cols(
        n_tracks, n_samples, m, 0, states, out, resid, parallel, group_size, group,
    )
}

/// [`run_batch`] over the samples `col0..n_samples` only: the jobs' output
/// rows start at sample `col0` of the `(N, n_tracks, n_samples)` buffer.
pub fn run_batch_cols<T: IoFloat, const N: usize>(
    n_tracks: usize,
    n_samples: usize,
    m: usize,
    col0: usize,
    states: &mut [TrackState],
    out: &mut [T],
    resid: Option<&mut [T]>,
    parallel: bool,
    group_size: usize,
    group: impl Fn(&mut [Job<'_, T, N>]) + Sync + Send,
) -> Result<()> {
    if col0 > n_samples {
        return Err(Error::Shape(format!(
            "first column {col0} > {n_samples} samples"
        )));
    }
    let per = n_tracks * n_samples;
    let out_len = out.len();
    let planes = crate::planes::split(out, N, per, n_samples);
    let Some(planes) = planes.filter(|_| states.len() == n_tracks) else {
        return Err(Error::Shape(format!(
            "state of {} tracks / output of {out_len} elements for {N} x {n_tracks} x {n_samples}",
            states.len(),
        )));
    };
    if let Some(r) = &resid {
        if r.len() != per * m {
            return Err(Error::Shape("residual buffer has the wrong size".into()));
        }
    }
    if per == 0 {
        return Ok(());
    }
    let mut comps: Vec<std::slice::ChunksExactMut<'_, T>> = planes
        .into_iter()
        .map(|c| c.chunks_exact_mut(n_samples))
        .collect();
    let mut resid_rows = resid.map(|r| r.chunks_exact_mut(n_samples * m));
    let gs = group_size.max(1);
    // Tracks are handed out in blocks, so the per-track bookkeeping stays
    // bounded (a few hundred KiB) however many tracks there are.
    let block = gs * (16_384 / gs).max(1);
    let mut jobs: Vec<Job<'_, T, N>> = Vec::with_capacity(block.min(n_tracks));
    let mut st_iter = states.iter_mut().enumerate();
    loop {
        jobs.clear();
        for (i, st) in st_iter.by_ref().take(block) {
            let mut missing = false;
            let states_arr: [&mut [T]; N] =
                std::array::from_fn(|c| match comps.get_mut(c).and_then(|it| it.next()) {
                    Some(row) => &mut row[col0..],
                    None => {
                        missing = true;
                        &mut []
                    }
                });
            if missing {
                return Err(Error::Shape("output rows".into()));
            }
            let r = match resid_rows.as_mut() {
                Some(it) => Some(
                    &mut it
                        .next()
                        .ok_or_else(|| Error::Shape("residual rows".into()))?[col0 * m..],
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
        if jobs.is_empty() {
            break;
        }
        // A task: its groups, then one fence for its streamed stores.
        let task = |t: &mut [Job<'_, T, N>]| {
            for g in t.chunks_mut(gs) {
                group(g);
            }
            store_fence();
        };
        if parallel && jobs.len() > gs {
            // Enough groups per task that scheduling overhead stays small.
            let min_groups = 1.max(65_536 / (gs * n_samples).max(1));
            jobs.par_chunks_mut(gs * min_groups).for_each(task);
        } else {
            task(&mut jobs);
        }
    }
    Ok(())
}

/// Constants of one general fixed-gain filter in the form used by the
/// steady-state loop: `x' = A x + K z` (`A = (I - K H) Phi`) for a valid
/// sample, `x' = Phi x` for a missed one; residual `z - (H Phi) x`.
#[derive(Debug, Clone, Copy)]
struct GenConst<const N: usize, const M: usize> {
    a: [[f64; N]; N],
    phi: [[f64; N]; N],
    k: [[f64; M]; N],
    hphi: [[f64; N]; M],
}

impl<const N: usize, const M: usize> GenConst<N, M> {
    fn new(g: &Gains<N, M>) -> Self {
        let hphi: [[f64; N]; M] = std::array::from_fn(|j| {
            std::array::from_fn(|c| (0..N).map(|i| g.h[j][i] * g.phi[i][c]).sum())
        });
        let a: [[f64; N]; N] = std::array::from_fn(|i| {
            std::array::from_fn(|c| {
                g.phi[i][c] - (0..M).map(|j| g.k[i][j] * hphi[j][c]).sum::<f64>()
            })
        });
        GenConst {
            a,
            phi: g.phi,
            k: g.k,
            hphi,
        }
    }
}

/// One step of the general kernel (see [`GenConst`]).
#[inline(always)]
fn gen_step<const N: usize, const M: usize, const FMA: bool>(
    c: &GenConst<N, M>,
    x: &[f64; N],
    z: &[f64; M],
) -> [f64; N] {
    if z.iter().all(|v| !v.is_nan()) {
        std::array::from_fn(|i| {
            let mut s = c.k[i][0] * z[0];
            for j in 1..M {
                s = madd::<FMA>(c.k[i][j], z[j], s);
            }
            for j in 0..N {
                s = madd::<FMA>(c.a[i][j], x[j], s);
            }
            s
        })
    } else {
        std::array::from_fn(|i| {
            let mut s = 0.0;
            for j in 0..N {
                s = madd::<FMA>(c.phi[i][j], x[j], s);
            }
            s
        })
    }
}

#[inline(always)]
fn gen_resid<const N: usize, const M: usize, const FMA: bool>(
    c: &GenConst<N, M>,
    x: &[f64; N],
    z: &[f64; M],
) -> [f64; M] {
    let valid = z.iter().all(|v| !v.is_nan());
    std::array::from_fn(|j| {
        if !valid {
            return f64::NAN;
        }
        let mut s = 0.0;
        for i in 0..N {
            s = madd::<FMA>(c.hphi[j][i], x[i], s);
        }
        z[j] - s
    })
}

/// Steady-state loop of one track of the general kernel over `k0..n`.
#[inline(always)]
fn gen_loop<T: IoFloat, const N: usize, const M: usize, const FMA: bool>(
    c: &GenConst<N, M>,
    st: &mut TrackState,
    k0: usize,
    n: usize,
    z: impl Fn(usize) -> [f64; M],
    out: &mut TrackOut<'_, T, N>,
) {
    let mut x: [f64; N] = std::array::from_fn(|i| st.x[i]);
    for k in k0..n {
        let zk = z(k);
        if let Some(r) = out.resid.as_deref_mut() {
            let e = gen_resid::<N, M, FMA>(c, &x, &zk);
            for j in 0..M {
                r[k * M + j] = T::from_f64(e[j]);
            }
        }
        x = gen_step::<N, M, FMA>(c, &x, &zk);
        for i in 0..N {
            out.states[i][k] = T::from_f64(x[i]);
        }
    }
    st.x[..N].copy_from_slice(&x);
}

/// Lanes of the interleaved general kernel.
pub const GEN_LANES: usize = 4;

/// Largest group of the general kernel: eight tracks with the AVX-512 lanes.
const GEN_GROUP_MAX: usize = 2 * GEN_LANES;

/// Tracks per group of the general kernel for rows of `n` samples (outputs
/// streamed if `nt`): eight where the AVX-512 lanes run (one or two
/// measurement components; by default `f64` rows long enough, see
/// `simd::gen8_enabled`), else `GEN_LANES`. A group of eight that cannot run
/// as one vector group runs as two groups of `GEN_LANES`, so every track
/// takes the same path (and gives the same bits) whatever the group size.
fn gen_group_size<T: 'static, const M: usize>(n: usize, nt: bool) -> usize {
    #[cfg(target_arch = "x86_64")]
    if uses_fma() && simd::gen8_enabled::<T>(n, nt) && simd::gen_fits::<T>(M) {
        return GEN_GROUP_MAX;
    }
    let _ = (n, nt);
    GEN_LANES
}

/// Whether the general kernel streams the outputs of `n_tracks` rows of `n`
/// samples with `N` states (saturating: called before the shapes are
/// validated).
fn gen_streamed<T: 'static, const N: usize>(n_tracks: usize, n: usize) -> bool {
    let bytes = N
        .saturating_mul(n_tracks)
        .saturating_mul(n)
        .saturating_mul(std::mem::size_of::<T>());
    streamed::<T>(bytes, true)
}

/// General fixed-gain filtering of a group of tracks: start-up per track,
/// then (for a full group of running tracks with contiguous rows and no
/// residuals) `GEN_LANES` tracks interleaved; same arithmetic per track in
/// every path.
#[inline(always)]
fn gen_group<T: IoFloat, const N: usize, const M: usize, const FMA: bool>(
    gains: &[Gains<N, M>],
    consts: &[GenConst<N, M>],
    init: Init,
    z: &Measurements<'_, T>,
    group: &mut [Job<'_, T, N>],
    parallel: bool,
) {
    let n = z.n_samples;
    let pick = |i: usize| if gains.len() == 1 { 0 } else { i };
    let mut k0 = [0usize; GEN_GROUP_MAX];
    for (g, (i, st, o)) in group.iter_mut().enumerate() {
        let i = *i;
        let zf = |k: usize| -> [f64; M] { std::array::from_fn(|j| z.at(i, k, j)) };
        let len = startup_len(init, st, n, &|k| {
            if zf(k).iter().any(|v| v.is_nan()) {
                f64::NAN
            } else {
                0.0
            }
        });
        if len > 0 {
            let mut head = TrackOut {
                states: std::array::from_fn(|_| -> &mut [T] { &mut [] }),
                resid: None,
            };
            for (h, s) in head.states.iter_mut().zip(o.states.iter_mut()) {
                *h = &mut s[..len];
            }
            head.resid = o.resid.as_deref_mut().map(|r| &mut r[..len * M]);
            run_track(&gains[pick(i)], init, st, len, zf, &mut head);
        }
        if g < GEN_GROUP_MAX {
            k0[g] = len;
        }
    }
    #[cfg(target_arch = "x86_64")]
    if FMA
        && group.len() == simd::GEN_LANES8
        && gen_group_size::<T, M>(n, gen_streamed::<T, N>(z.n_tracks, n)) == simd::GEN_LANES8
        && group
            .iter()
            .all(|(i, st, o)| st.phase == 2.0 && o.resid.is_none() && z.row(*i).is_some())
    {
        const L: usize = simd::GEN_LANES8;
        let kmax = k0[..L].iter().copied().max().unwrap_or(0);
        let mut rows: [&[T]; L] = [&[]; L];
        let mut cs: [&GenConst<N, M>; L] = [&consts[0]; L];
        for (l, (i, st, o)) in group.iter_mut().enumerate() {
            let row = z.row(*i).unwrap_or(&[]);
            rows[l] = &row[..(n * M).min(row.len())];
            cs[l] = &consts[pick(*i)];
            gen_loop::<T, N, M, FMA>(
                cs[l],
                st,
                k0[l],
                kmax,
                |k| std::array::from_fn(|j| row[k * M + j].to_f64()),
                o,
            );
        }
        if rows.iter().any(|r| r.len() != n * M) {
            return;
        }
        let mut xs: [[f64; N]; L] = [[0.0; N]; L];
        for (l, (_, st, _)) in group.iter().enumerate() {
            xs[l] = std::array::from_fn(|i| st.x[i]);
        }
        let ahead =
            (n <= PREFETCH_MAX_SAMPLES && z.s_track > 0).then(|| (L * z.s_track as usize, L * n));
        let nt = gen_streamed::<T, N>(z.n_tracks, n);
        // SAFETY: `gen_group_size` said 8 only if `simd::gen8_enabled` checked
        // AVX-512F and FMA on this CPU.
        unsafe { simd::gen_lanes8::<T, N, M>(&cs, &mut xs, kmax, n, &rows, group, ahead, nt) };
        for (l, (_, st, _)) in group.iter_mut().enumerate() {
            st.x[..N].copy_from_slice(&xs[l]);
        }
        return;
    }
    // Otherwise in groups of `GEN_LANES` (the same tracks take the same
    // paths whatever the group size).
    for (grp, k0) in group.chunks_mut(GEN_LANES).zip(k0.chunks(GEN_LANES)) {
        gen_rest::<T, N, M, FMA>(gains, consts, z, grp, k0, parallel);
    }
}

/// [`gen_group`] after the start-up, for at most `GEN_LANES` tracks whose
/// steady state starts at `k0[l]`.
#[inline(always)]
fn gen_rest<T: IoFloat, const N: usize, const M: usize, const FMA: bool>(
    gains: &[Gains<N, M>],
    consts: &[GenConst<N, M>],
    z: &Measurements<'_, T>,
    group: &mut [Job<'_, T, N>],
    k0: &[usize],
    parallel: bool,
) {
    let n = z.n_samples;
    let pick = |i: usize| if gains.len() == 1 { 0 } else { i };
    let group_len = group.len();
    let lanes_ok = group.len() == GEN_LANES
        && group
            .iter()
            .all(|(i, st, o)| st.phase == 2.0 && o.resid.is_none() && z.row(*i).is_some());
    if !lanes_ok {
        for (idx, (i, st, o)) in group.iter_mut().enumerate() {
            if st.phase < 2.0 {
                continue;
            }
            let i = *i;
            let c = &consts[pick(i)];
            let start = k0.get(idx).copied().unwrap_or(0);
            if let (Some(row), true) = (z.row(i), o.resid.is_none() && group_len < GEN_LANES) {
                if let Some(seg_len) = gen_split_plan(c, gains[pick(i)].t, n - start) {
                    let row = &row[..(n * M).min(row.len())];
                    if row.len() == n * M {
                        gen_split::<T, N, M, FMA>(
                            &gains[pick(i)],
                            c,
                            st,
                            start,
                            row,
                            o,
                            seg_len,
                            parallel,
                        );
                        continue;
                    }
                }
            }
            match z.row(i) {
                Some(row) => gen_loop::<T, N, M, FMA>(
                    c,
                    st,
                    start,
                    n,
                    |k| std::array::from_fn(|j| row[k * M + j].to_f64()),
                    o,
                ),
                None => gen_loop::<T, N, M, FMA>(
                    c,
                    st,
                    start,
                    n,
                    |k| std::array::from_fn(|j| z.at(i, k, j)),
                    o,
                ),
            }
        }
        return;
    }
    let kmax = k0.iter().copied().max().unwrap_or(0);
    let mut rows: [&[T]; GEN_LANES] = [&[]; GEN_LANES];
    let mut cs: [&GenConst<N, M>; GEN_LANES] = [&consts[0]; GEN_LANES];
    for (l, (i, st, o)) in group.iter_mut().enumerate() {
        let row = z.row(*i).unwrap_or(&[]);
        rows[l] = row;
        cs[l] = &consts[pick(*i)];
        gen_loop::<T, N, M, FMA>(
            cs[l],
            st,
            k0.get(l).copied().unwrap_or(0),
            kmax,
            |k| std::array::from_fn(|j| row[k * M + j].to_f64()),
            o,
        );
    }
    let rows = rows.map(|r| &r[..(n * M).min(r.len())]);
    if rows.iter().any(|r| r.len() != n * M) {
        return;
    }
    let mut xs: [[f64; N]; GEN_LANES] = [[0.0; N]; GEN_LANES];
    for (l, (_, st, _)) in group.iter().enumerate() {
        xs[l] = std::array::from_fn(|i| st.x[i]);
    }
    let ahead = (n <= PREFETCH_MAX_SAMPLES && z.s_track > 0)
        .then(|| (GEN_LANES * z.s_track as usize, GEN_LANES * n));
    // Whole lines of f32 too (see `simd::gen_lanes4`).
    let nt = streamed::<T>(N * z.n_tracks * n * std::mem::size_of::<T>(), true);
    let cs: [&GenConst<N, M>; GEN_LANES] = cs;
    gen_lanes_entry::<T, N, M, FMA>(cs, &mut xs, kmax, n, rows, group, ahead, nt);
    for (l, (_, st, _)) in group.iter_mut().enumerate() {
        st.x[..N].copy_from_slice(&xs[l]);
    }
}

/// The `GEN_LANES` general lanes over samples `k0..n` (scalar): `rows[l]`
/// holds lane `l`'s measurements (`n * M` values), `group[l]` its outputs,
/// `xs[l]` its state (updated).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn gen_lanes_scalar<T: IoFloat, const N: usize, const M: usize, const FMA: bool>(
    cs: [&GenConst<N, M>; GEN_LANES],
    xs: &mut [[f64; N]; GEN_LANES],
    k0: usize,
    n: usize,
    rows: [&[T]; GEN_LANES],
    group: &mut [Job<'_, T, N>],
    ahead: Option<(usize, usize)>,
) {
    if group.len() < GEN_LANES || rows.iter().any(|r| r.len() < n * M) {
        return;
    }
    let line = (64 / std::mem::size_of::<T>()).max(1);
    for k in k0..n {
        if let Some((dz, dout)) = ahead {
            if k % line == 0 {
                for l in 0..GEN_LANES {
                    prefetch(rows[l].as_ptr().wrapping_add(dz + k * M));
                    for i in 0..N {
                        prefetch(group[l].2.states[i].as_ptr().wrapping_add(dout + k));
                    }
                }
            }
        }
        for l in 0..GEN_LANES {
            let zk: [f64; M] = std::array::from_fn(|j| rows[l][k * M + j].to_f64());
            xs[l] = gen_step::<N, M, FMA>(cs[l], &xs[l], &zk);
            let o = &mut group[l].2;
            for i in 0..N {
                o.states[i][k] = T::from_f64(xs[l][i]);
            }
        }
    }
}

#[allow(clippy::too_many_arguments)]
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "fma")]
fn gen_lanes_scalar_fma<T: IoFloat, const N: usize, const M: usize>(
    cs: [&GenConst<N, M>; GEN_LANES],
    xs: &mut [[f64; N]; GEN_LANES],
    k0: usize,
    n: usize,
    rows: [&[T]; GEN_LANES],
    group: &mut [Job<'_, T, N>],
    ahead: Option<(usize, usize)>,
) {
    gen_lanes_scalar::<T, N, M, true>(cs, xs, k0, n, rows, group, ahead)
}

/// The general lanes from any context (also a closure run by rayon, which
/// does not inherit target features): the vector lanes where the CPU has
/// them, else the scalar lanes (with FMA if `FMA`, which is only true when
/// [`uses_fma`] said so). Bit-identical either way.
#[allow(clippy::too_many_arguments)]
fn gen_lanes_entry<T: IoFloat, const N: usize, const M: usize, const FMA: bool>(
    cs: [&GenConst<N, M>; GEN_LANES],
    xs: &mut [[f64; N]; GEN_LANES],
    k0: usize,
    n: usize,
    rows: [&[T]; GEN_LANES],
    group: &mut [Job<'_, T, N>],
    ahead: Option<(usize, usize)>,
    nt: bool,
) {
    #[cfg(target_arch = "x86_64")]
    {
        if FMA && n >= k0 + 64 && simd::avx2_available() && simd::gen_fits::<T>(M) {
            if simd::gen_zen4::<T>() {
                // SAFETY: `gen_zen4` (`zen4_forms`) checked AVX2, FMA,
                // AVX-512F and -VL.
                unsafe { simd::gen_lanes4_zen4::<T, N, M>(cs, xs, k0, n, rows, group, ahead, nt) };
                return;
            }
            // SAFETY: `avx2_available()` checked AVX2 and FMA on this CPU.
            unsafe { simd::gen_lanes4::<T, N, M>(cs, xs, k0, n, rows, group, ahead, nt) };
            return;
        }
        if FMA {
            // SAFETY: FMA = true only after `uses_fma()` confirmed FMA.
            unsafe { gen_lanes_scalar_fma::<T, N, M>(cs, xs, k0, n, rows, group, ahead) };
            return;
        }
    }
    let _ = nt;
    gen_lanes_scalar::<T, N, M, FMA>(cs, xs, k0, n, rows, group, ahead)
}

/// Segments of a split single general track (fixed: results never depend
/// on the thread count): four groups of `GEN_LANES`.
pub const GEN_SPLIT_SEGMENTS: usize = 4 * GEN_LANES;

/// Segment length when splitting a general track of `len` steady-state
/// samples pays: a long run and a loop `A = (I - K H) Phi` whose transients
/// shrink by 2^-60 within 1/8 of a segment (checked on `||A^p||_inf` by
/// repeated squaring).
fn gen_split_plan<const N: usize, const M: usize>(
    c: &GenConst<N, M>,
    t: f64,
    len: usize,
) -> Option<usize> {
    if len < SPLIT_MIN_SAMPLES || !(t.is_finite() && t > 0.0) {
        return None;
    }
    let seg_len = len / GEN_SPLIT_SEGMENTS;
    let mut p = c.a;
    let mut steps = 1usize;
    let norm = |m: &[[f64; N]; N]| -> f64 {
        // weighted by the kinematic scales t^i so that rates count like positions
        (0..N)
            .map(|i| {
                (0..N)
                    .map(|j| (m[i][j] * t.powi(i as i32 - j as i32)).abs())
                    .sum::<f64>()
            })
            .fold(0.0, f64::max)
    };
    while 2 * steps <= seg_len / 8 {
        let q: [[f64; N]; N] = std::array::from_fn(|i| {
            std::array::from_fn(|j| (0..N).map(|k| p[i][k] * p[k][j]).sum())
        });
        p = q;
        steps *= 2;
        let nm = norm(&p);
        if nm <= 2f64.powi(-60) {
            return Some(seg_len);
        }
        if !nm.is_finite() {
            return None;
        }
    }
    None
}

/// A single long general track split into [`GEN_SPLIT_SEGMENTS`] segments
/// (the general counterpart of [`ab_split`]): the segments run as lanes
/// (and on two threads when allowed) from a guessed start state (`pinv(H) z`
/// of the sample before the segment, or zero), then, in order, each
/// segment's start-state error `delta` is propagated through the loop (`A`
/// for an updated sample, `Phi` for a missed one) and added to its outputs
/// until it is below 2^-60 of the estimate (components weighted by `T^i`).
/// The filter is linear, so this is the unsplit recursion to rounding.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn gen_split<T: IoFloat, const N: usize, const M: usize, const FMA: bool>(
    g: &Gains<N, M>,
    c: &GenConst<N, M>,
    st: &mut TrackState,
    k0: usize,
    row: &[T],
    out: &mut TrackOut<'_, T, N>,
    ls: usize,
    parallel: bool,
) {
    const S: usize = GEN_SPLIT_SEGMENTS;
    let n = row.len() / M;
    let body_end = k0 + S * ls;
    let zat = |k: usize| -> [f64; M] { std::array::from_fn(|j| row[k * M + j].to_f64()) };
    let mut x0 = [[0.0; N]; S];
    x0[0] = std::array::from_fn(|i| st.x[i]);
    for (j, x0j) in x0.iter_mut().enumerate().skip(1) {
        let zp = zat(k0 + j * ls - 1);
        if zp.iter().all(|v| !v.is_nan()) {
            *x0j = std::array::from_fn(|i| (0..M).map(|m| g.h_pinv[i][m] * zp[m]).sum());
        }
    }
    let mut dummy = [TrackState::default(); S];
    let mut ends = x0;
    {
        let mut chunks: Vec<std::slice::ChunksExactMut<'_, T>> = out
            .states
            .iter_mut()
            .map(|s| s[k0..body_end].chunks_exact_mut(ls))
            .collect();
        let mut jobs: Vec<Job<'_, T, N>> = Vec::with_capacity(S);
        for (j, d) in dummy.iter_mut().enumerate() {
            let states: [&mut [T]; N] =
                std::array::from_fn(|i| chunks[i].next().unwrap_or_default());
            jobs.push((
                j,
                d,
                TrackOut {
                    states,
                    resid: None,
                },
            ));
        }
        let zrows: [&[T]; S] =
            std::array::from_fn(|j| &row[(k0 + j * ls) * M..(k0 + (j + 1) * ls) * M]);
        // Groups of 8 segments on the AVX-512 lanes where the CPU has them
        // (16 segments either way: the same bits).
        let nt = gen_streamed::<T, N>(1, n);
        let gl = if FMA {
            gen_group_size::<T, M>(ls, nt)
        } else {
            GEN_LANES
        };
        type Seg<'s, 'j, T, const N: usize> =
            (usize, (&'s mut [Job<'j, T, N>], &'s mut [[f64; N]]));
        let run = |(gi, (grp, xs)): Seg<'_, '_, T, N>| {
            #[cfg(target_arch = "x86_64")]
            if gl == simd::GEN_LANES8 {
                const L: usize = simd::GEN_LANES8;
                let rows: [&[T]; L] = std::array::from_fn(|l| zrows[gi * L + l]);
                // SAFETY: `gen_group_size` said 8 only if `simd::gen8_enabled`
                // checked AVX-512F and FMA on this CPU.
                unsafe { simd::gen_lanes8::<T, N, M>(&[c; L], xs, 0, ls, &rows, grp, None, nt) };
                store_fence();
                return;
            }
            let rows: [&[T]; GEN_LANES] = std::array::from_fn(|l| zrows[gi * GEN_LANES + l]);
            let mut xl: [[f64; N]; GEN_LANES] = std::array::from_fn(|l| xs[l]);
            gen_lanes_entry::<T, N, M, FMA>([c; GEN_LANES], &mut xl, 0, ls, rows, grp, None, nt);
            xs.copy_from_slice(&xl);
            store_fence();
        };
        if parallel {
            jobs.par_chunks_mut(gl)
                .zip(ends.par_chunks_mut(gl))
                .enumerate()
                .for_each(run);
        } else {
            jobs.chunks_mut(gl)
                .zip(ends.chunks_mut(gl))
                .enumerate()
                .for_each(run);
        }
    }
    // Pass 2: corrections, in order.
    let tiny = 2f64.powi(-60);
    let w: [f64; N] = std::array::from_fn(|i| g.t.powi(i as i32));
    let mut truth = ends[0];
    for j in 1..S {
        let mut d: [f64; N] = std::array::from_fn(|i| truth[i] - x0[j][i]);
        let a = k0 + j * ls;
        let mut k = a;
        while k < a + ls && d.iter().any(|&v| v != 0.0) {
            let m = if zat(k).iter().all(|v| !v.is_nan()) {
                &c.a
            } else {
                &c.phi
            };
            d = std::array::from_fn(|i| {
                let mut s = 0.0;
                for (jj, dj) in d.iter().enumerate() {
                    s = madd::<FMA>(m[i][jj], *dj, s);
                }
                s
            });
            let (mut err, mut scale) = (0.0, 0.0);
            for i in 0..N {
                let xn = out.states[i][k].to_f64() + d[i];
                out.states[i][k] = T::from_f64(xn);
                err += (d[i] * w[i]).abs();
                scale += (xn * w[i]).abs();
            }
            if err <= tiny * scale {
                d = [0.0; N];
            }
            k += 1;
        }
        truth = std::array::from_fn(|i| ends[j][i] + d[i]);
    }
    st.x[..N].copy_from_slice(&truth);
    // The few samples after the last full segment.
    gen_loop::<T, N, M, FMA>(c, st, body_end, n, zat, out);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "fma")]
fn gen_group_fma<T: IoFloat, const N: usize, const M: usize>(
    gains: &[Gains<N, M>],
    consts: &[GenConst<N, M>],
    init: Init,
    z: &Measurements<'_, T>,
    group: &mut [Job<'_, T, N>],
    parallel: bool,
) {
    gen_group::<T, N, M, true>(gains, consts, init, z, group, parallel)
}

fn gen_group_dispatch<T: IoFloat, const N: usize, const M: usize>(
    gains: &[Gains<N, M>],
    consts: &[GenConst<N, M>],
    init: Init,
    z: &Measurements<'_, T>,
    group: &mut [Job<'_, T, N>],
    parallel: bool,
) {
    #[cfg(target_arch = "x86_64")]
    {
        if uses_fma() {
            // SAFETY: the CPU supports FMA (checked at run time by `uses_fma`).
            unsafe { gen_group_fma(gains, consts, init, z, group, parallel) };
            return;
        }
        gen_group::<T, N, M, false>(gains, consts, init, z, group, parallel)
    }
    #[cfg(target_arch = "aarch64")]
    {
        gen_group::<T, N, M, true>(gains, consts, init, z, group, parallel)
    }
    #[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
    {
        gen_group::<T, N, M, false>(gains, consts, init, z, group, parallel)
    }
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
    general_cols(
        gains,
        init,
        z,
        z.n_samples,
        0,
        states,
        out,
        resid,
        parallel,
        smoother,
    )
}

/// The general kernel over a column block: `z` views samples
/// `col0..n_full` of the batch, whose output buffer is `(N, n_tracks,
/// n_full)`. Used to continue a time-varying filter with its limiting gain.
pub fn general_cols<T: IoFloat, const N: usize, const M: usize>(
    gains: &[Gains<N, M>],
    init: Init,
    z: &Measurements<'_, T>,
    n_full: usize,
    col0: usize,
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
            "measurements have {} components, the filter {M}",
            z.m
        )));
    }
    z.validate()?;
    if col0 + z.n_samples != n_full {
        return Err(Error::Shape(
            "column block does not end at the last sample".into(),
        ));
    }
    for g in gains {
        let all = g
            .phi
            .iter()
            .flatten()
            .chain(g.h.iter().flatten())
            .chain(g.k.iter().flatten());
        if let Some(v) = all.copied().find(|v| !v.is_finite()) {
            return Err(Error::domain("Phi, H, K", "finite", v));
        }
        if !(g.t.is_finite() && g.t > 0.0) {
            return Err(Error::domain("T", "finite and > 0", g.t));
        }
    }
    let consts: Vec<GenConst<N, M>> = gains.iter().map(GenConst::new).collect();
    run_batch_cols::<T, N>(
        z.n_tracks,
        n_full,
        M,
        col0,
        states,
        out,
        resid,
        parallel,
        gen_group_size::<T, M>(z.n_samples, gen_streamed::<T, N>(z.n_tracks, z.n_samples)),
        |group| {
            gen_group_dispatch(gains, &consts, init, z, group, parallel);
            if let Some(sm) = &smoother {
                // The smoother reads the filtered rows (streamed stores).
                store_fence();
                for (i, _, o) in group.iter_mut() {
                    let g = &gains[if gains.len() == 1 { 0 } else { *i }];
                    let a = &sm.a[if sm.a.len() == 1 { 0 } else { *i }];
                    crate::smooth::smooth_track(&g.phi, a, sm.lag, &mut o.states);
                }
            }
        },
    )
}

/// Filter a batch with alpha-beta filters (`params[i] = (alpha, beta, T)`,
/// one for all tracks or one per track), optionally smoothing each track.
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
    check_ab(params, z)?;
    if let Some(sm) = &smoother {
        check_params(sm.a.len(), z)?;
    }
    #[cfg(target_arch = "x86_64")]
    if resid.is_none() {
        if let Some(r) = ab_flat_batch(params, init, z, states, out, parallel, smoother.as_ref()) {
            return r;
        }
    }
    run_batch::<T, 2>(
        z.n_tracks,
        z.n_samples,
        1,
        states,
        out,
        resid,
        parallel,
        AB_LANES,
        |group| {
            ab_group_dispatch(params, init, z, group, parallel);
            if let Some(sm) = &smoother {
                for (i, _, o) in group.iter_mut() {
                    let j = if params.len() == 1 { 0 } else { *i };
                    let t = params[j].2;
                    let a = &sm.a[if sm.a.len() == 1 { 0 } else { *i }];
                    crate::smooth::smooth_track(&[[1.0, t], [0.0, 1.0]], a, sm.lag, &mut o.states);
                }
            }
        },
    )
}

/// Alpha-beta parameters `(alpha, beta, T)`: the core is callable
/// directly, and NaN/Inf gains or a non-positive period would give silently
/// meaningless (and chunking-dependent) output.
pub(crate) fn check_ab_params(params: &[(f64, f64, f64)]) -> Result<()> {
    for &(a, b, t) in params {
        for (name, v) in [("alpha", a), ("beta", b)] {
            if !v.is_finite() {
                return Err(Error::domain(name, "finite", v));
            }
        }
        if !(t.is_finite() && t > 0.0) {
            return Err(Error::domain("T", "finite and > 0", t));
        }
    }
    Ok(())
}

/// Checks of [`filter_ab`]'s (and [`f32arith::filter_ab_f32`]'s) arguments.
fn check_ab<T: IoFloat>(params: &[(f64, f64, f64)], z: &Measurements<'_, T>) -> Result<()> {
    check_params(params.len(), z)?;
    check_ab_params(params)?;
    if z.m != 1 {
        return Err(Error::Shape(format!(
            "alpha-beta needs scalar measurements, got {}",
            z.m
        )));
    }
    z.validate()
}

/// Short contiguous rows (fewer than [`SIMD_MIN_SAMPLES`] samples, on
/// AVX-512 CPUs [`FLAT_AVX512_MAX_SAMPLES`]; no residuals), and on AVX2
/// streamed rows a multiple of 2 KiB long
/// ([`aliased_rows`]), through the flat vector kernel ([`flat`]): the rows
/// are one flat sequence of tracks. `None` when it does not apply (the row kernels
/// run instead). Bit-identical to them.
#[cfg(target_arch = "x86_64")]
fn ab_flat_batch<T: IoFloat>(
    params: &[(f64, f64, f64)],
    init: Init,
    z: &Measurements<'_, T>,
    states: &mut [TrackState],
    out: &mut [T],
    parallel: bool,
    smoother: Option<&Smoother<'_, 2>>,
) -> Option<Result<()>> {
    let (nt_, n) = (z.n_tracks, z.n_samples);
    let total = nt_.checked_mul(n)?;
    let rows_ok = z.s_sample == 1 && (z.s_track == n as isize || nt_ == 1);
    let cpu_kind = flat_kernel()?;
    let nt = streamed::<T>(2 * total * std::mem::size_of::<T>(), true);
    // The flat kernel of the rows: on an AMD Zen 4, batches beyond the L3
    // take the AVX2 instance in `f64` as ragged batches do
    // ([`tracks_flat_kernel`]), with its row lengths and its routing of
    // aliased rows ([`ZEN4_ROWS_AVX2_MIN_BYTES`]).
    let kind = if total
        .checked_mul(3 * std::mem::size_of::<T>())
        .is_some_and(|b| b >= ZEN4_ROWS_AVX2_MIN_BYTES)
    {
        tracks_flat_kernel::<T>(cpu_kind)
    } else {
        cpu_kind
    };
    if !simd::fits::<T>(0, 32)
        || z.m != 1
        || n == 0
        || (n >= flat_max_samples::<T>(kind)
            && !(kind == FlatKernel::Avx2 && nt && aliased_rows::<T>(n)))
        || !rows_ok
        || states.len() != nt_
        || crate::planes::stride::<T>(out.len(), 2, total, n).is_none()
    {
        return None;
    }
    let zs = z.data.get(z.base..z.base.checked_add(total)?)?;
    // The AVX2 short-row lanes where they were measured faster than the flat
    // kernel (`avx2::ab_short_rows`): z and outputs within the caches, short
    // rows in memory (SHORT_ROWS_MEM_MAX), or f32 with streamed outputs. Also
    // on AVX-512 CPUs (which have AVX2), except f64 rows longer than
    // SHORT_ROWS_AVX512_F64_MAX (docs/benchmarks.md, session 12).
    let f64_ = simd::is_f64::<T>();
    let lanes_cpu = match cpu_kind {
        FlatKernel::Avx2 => true,
        FlatKernel::Avx512 => simd::avx2_available() && !(f64_ && n > SHORT_ROWS_AVX512_F64_MAX),
        FlatKernel::Avx512Generic => false,
    };
    let rows8 = lanes_cpu
        && n < SIMD_MIN_SAMPLES
        && !short_rows_flat()
        && (3 * total * std::mem::size_of::<T>() <= SHORT_ROWS_CACHED_BYTES
            || n <= SHORT_ROWS_MEM_MAX[usize::from(f64_)]
            || (nt && !f64_)
            || (nt && cpu_kind == FlatKernel::Avx2 && page_rows::<T>(n)));
    let rows16 = match rows16_switch() {
        Some(on) => {
            on && cpu_kind == FlatKernel::Avx512 && simd::avx2_available() && n < SIMD_MIN_SAMPLES
        }
        None => false,
    };
    let (xs, vs) = crate::planes::split2(out, 2, total, n)?;
    // Results do not depend on the chunking.
    let per = row_chunk_tracks(nt_, n, parallel, 1);
    let shared = params.len() == 1;
    let run = |j0: usize, st: &mut [TrackState], xs: &mut [T], vs: &mut [T]| -> Result<()> {
        let cn = st.len();
        let p = |j: usize| params[if shared { 0 } else { j0 + j }];
        let konst = |j: usize| {
            let (a, b, t) = p(j);
            AbConst::new(a, b, t)
        };
        let mut start = |j: usize, st: &mut TrackState, zr: &[T], xr: &mut [T], vr: &mut [T]| {
            let (a, b, t) = p(j);
            let mut o = TrackOut {
                states: [xr, vr],
                resid: None,
            };
            Ok(ab_start::<T>(
                a,
                b,
                t,
                init,
                st,
                zr.len(),
                &|k| zr[k].to_f64(),
                &mut o,
            ))
        };
        let zc = &zs[j0 * n..(j0 + cn) * n];
        let pr = if shared {
            &params[..1]
        } else {
            &params[j0..j0 + cn]
        };
        if rows16 {
            // SAFETY: `cpu_kind` is Avx512 (AVX-512F and FMA checked by
            // `flat_kernel()`) and `avx2_available()`; T is f32 or f64.
            unsafe { rows16::ab_rows16(pr, init, n, zc, xs, vs, st, nt)? };
        } else if rows8 {
            // SAFETY: `lanes_cpu`: AVX2 and FMA (`flat_kernel()` checked
            // them for the AVX2 kind, `avx2_available()` on AVX-512 CPUs);
            // T is f32 or f64 (`fits`).
            unsafe { avx2::ab_short_rows(pr, init, n, zc, xs, vs, st, nt)? };
        } else {
            // The rows' offsets: only the flat kernel takes them (800 KB
            // on 100,000 rows, not made for the short-row lanes).
            let off: Vec<usize> = (0..=cn).map(|j| j * n).collect();
            // SAFETY: `flat_kernel()` checked the CPU features of `kind`; T
            // is f32 or f64 (`fits`).
            unsafe {
                run_flat(
                    kind,
                    &konst,
                    shared,
                    &mut start,
                    &off,
                    zc,
                    xs,
                    vs,
                    st,
                    nt,
                    None,
                    Some(flat::VecStart::Rows(init)),
                )?
            };
        }
        if let Some(sm) = smoother {
            for j in 0..cn {
                let i = j0 + j;
                let t = p(j).2;
                let a = &sm.a[if sm.a.len() == 1 { 0 } else { i }];
                let (x, v) = (&mut xs[j * n..(j + 1) * n], &mut vs[j * n..(j + 1) * n]);
                crate::smooth::smooth_track(&[[1.0, t], [0.0, 1.0]], a, sm.lag, &mut [x, v]);
            }
        }
        Ok(())
    };
    Some(run_row_chunks(states, xs, vs, n, per, run))
}

/// Bytes of `z` and outputs from which rectangular `f64` batches on an
/// AMD Zen 4 take the AVX2 flat kernel's routing ([`tracks_flat_kernel`]:
/// rows shorter than `SIMD_MIN_SAMPLES` and aliased rows
/// ([`aliased_rows`]) with streamed outputs in the AVX2 flat kernel, the
/// other rows in the row lanes) rather than the AVX-512 one (rows shorter
/// than 512 in the hand-written AVX-512 flat kernel, aliased rows in the
/// row lanes). Measured on a Zen 4 EPYC guest (32 MiB L3), from Python,
/// `f64`, ns per sample, three alternated processes, AVX-512 routing ->
/// AVX2 (docs/benchmarks.md, session 34): 10^7 samples, rows of 100
/// 1.19-1.23 -> 1.04-1.06, 200 1.03-1.06 -> 0.88-0.91, 400 0.98-1.00 ->
/// 0.85, 256 1.36-1.37 -> 0.86-0.90, 512 1.45-1.47 -> 0.81-0.84, 1,024
/// 1.27-1.34 -> 0.79-0.81, 4,096 1.16-1.21 -> 0.77, 1,000 and 10,000 the
/// same kernel; 2-4 x 10^6 samples rows of 100-400 12-21 % faster, 1.4 x
/// 10^6 5-13 %; but at 10^6 (24 MB, within the L3) rows of 100 and 200
/// the same or slower, and at 6 x 10^5 rows of 100 and 200 1.18 / 1.04 ->
/// 1.60-1.66 / 1.47-1.50.
#[cfg(target_arch = "x86_64")]
const ZEN4_ROWS_AVX2_MIN_BYTES: usize = 32 << 20;

/// Tracks per chunk (the unit of parallel work) of a batch of `n_tracks`
/// rows of `n` samples: all of them unless `parallel` with several threads
/// in rayon's pool, then about four chunks per thread of at least 2^18
/// samples each, rounded up to a multiple of `group` tracks.
fn row_chunk_tracks(n_tracks: usize, n: usize, parallel: bool, group: usize) -> usize {
    let threads = if parallel {
        rayon::current_num_threads()
    } else {
        1
    };
    if threads > 1 {
        n_tracks
            .div_ceil(4 * threads)
            .max((1usize << 18).div_ceil(n.max(1)))
            .next_multiple_of(group.max(1))
    } else {
        n_tracks
    }
    .max(1)
}

/// `run(j0, states, xs, vs)` on chunks of `per` whole tracks `j0..` (rows
/// of `n` samples back to back in `xs` and `vs`), on rayon's pool when
/// there are several chunks; the first error in track order.
fn run_row_chunks<T: Send>(
    states: &mut [TrackState],
    xs: &mut [T],
    vs: &mut [T],
    n: usize,
    per: usize,
    run: impl Fn(usize, &mut [TrackState], &mut [T], &mut [T]) -> Result<()> + Sync,
) -> Result<()> {
    let n_tracks = states.len();
    let mut jobs = Vec::with_capacity(n_tracks.div_ceil(per.max(1)));
    let (mut st_rest, mut x_rest, mut v_rest) = (states, xs, vs);
    let mut j0 = 0;
    while j0 < n_tracks {
        let cn = per.max(1).min(n_tracks - j0);
        let (a, b) = std::mem::take(&mut st_rest).split_at_mut(cn);
        let (xa, xb) = std::mem::take(&mut x_rest).split_at_mut(cn * n);
        let (va, vb) = std::mem::take(&mut v_rest).split_at_mut(cn * n);
        jobs.push((j0, a, xa, va));
        (st_rest, x_rest, v_rest) = (b, xb, vb);
        j0 += cn;
    }
    let res: Vec<Result<()>> = if jobs.len() > 1 {
        jobs.into_par_iter()
            .map(|(j0, st, x, v)| run(j0, st, x, v))
            .collect()
    } else {
        jobs.into_iter()
            .map(|(j0, st, x, v)| run(j0, st, x, v))
            .collect()
    };
    res.into_iter().collect()
}

/// Rows of `n` samples a multiple of 2 KiB long (`f64`: `n` a multiple
/// of 256; `f32`: of 512): in the AVX2 row lanes the eight lanes' rows and
/// both outputs then sit at one or two offsets modulo 4 KiB, and streamed
/// stores to addresses that agree modulo 4 KiB run several times slower
/// (docs/benchmarks.md, "Power-of-two row lengths"). With streamed
/// outputs such rows run in the flat kernel instead, whose slots walk
/// separate regions of the batch. Measured on an AMD EPYC (Zen 3), 10^7
/// samples, ns per sample, row lanes -> flat kernel: `f64` 512 samples
/// 6.2-6.3 -> 2.5-2.6, 768: 5.7 -> 2.3-2.9, 1,024: 5.2-6.2 -> 1.8-2.4,
/// 1,280: 5.4-5.6 -> 2.5-2.7, 2,048: 5.1-5.6 -> 2.0-2.3, 4,096: 5.4-5.5
/// -> 2.0-2.3; `f32` 512: 2.7-3.8 -> 1.8-2.1, 1,024: 3.3-4.0 -> 1.5-1.9,
/// 2,048: 3.1-4.0 -> 1.9-2.0, 4,096: 3.5-4.0 -> 1.3-1.7. (Rows of 1,000
/// `f64`: 1.3-1.8 in either.)
#[cfg(target_arch = "x86_64")]
fn aliased_rows<T>(n: usize) -> bool {
    n.checked_mul(std::mem::size_of::<T>())
        .is_some_and(|b| b.is_multiple_of(2048))
}

/// Whether rows of `n` samples of `T` are a whole fraction of 4 KiB (`f64`
/// rows of 128, say): then every region of the flat kernel starts at the
/// same offset modulo 4 KiB, so its slots' streams all agree modulo 4 KiB
/// and no choice of region can spread them. With streamed outputs such
/// rows run in the AVX2 short-row lanes on AVX2-only CPUs. Measured on an
/// AMD EPYC (Zen 3), 10^7 `f64` samples in rows of 128, ns per sample,
/// flat kernel -> short-row lanes: `rowbench` 2.2-3.0 -> 1.32-1.33; from
/// Python with `abkit.empty_states` outputs 5.3-6.1 -> 1.5-1.85, with
/// `np.empty` 2.2-2.8 -> 1.6-2.1 (docs/benchmarks.md, session 38).
#[cfg(target_arch = "x86_64")]
fn page_rows<T>(n: usize) -> bool {
    let b = n.saturating_mul(std::mem::size_of::<T>());
    b > 0 && 4096 % b == 0
}

/// Most bytes of `z` and outputs for which short rows run in the AVX2
/// short-row lanes rather than the flat kernel (measured on an AMD EPYC,
/// Zen 3, 32 MiB L3: 9.6 MB faster in both precisions, 12 MB faster in
/// `f32`, 19 MB slower in `f64`).
#[cfg(target_arch = "x86_64")]
const SHORT_ROWS_CACHED_BYTES: usize = 12 << 20;

/// Longest rows (samples; `[f32, f64]`) that run in the AVX2 short-row
/// lanes whatever the size of the batch: there the flat kernel spends most
/// blocks on track boundaries. Measured on an AMD EPYC (Zen 3), 100,000
/// rows in memory, ns per sample, flat kernel -> short-row lanes: `f64` 8
/// samples 4.8 -> 2.3, 16: 3.5 -> 1.7, 32: 2.4 -> 1.9, 48: 1.95 -> 1.79,
/// 64: 2.06 -> 1.68, 80: 1.75 -> 1.57, 100: 1.41 -> 1.59; `f32` 16: 3.1 ->
/// 1.7, 48: 2.0 -> 1.3, 64: 1.71 -> 1.24, 80: 1.37 -> 1.52.
#[cfg(target_arch = "x86_64")]
const SHORT_ROWS_MEM_MAX: [usize; 2] = [64, 80];

/// On AVX-512 CPUs, f64 rows longer than this stay in the AVX-512 flat
/// kernel: on an Intel Xeon (AVX-512) the short-row lanes were faster for
/// f64 rows of 5-100 samples and slower for rows of 200 within the caches
/// (docs/benchmarks.md, "Run of 2026-12-02 on an Intel Xeon with AVX-512").
#[cfg(target_arch = "x86_64")]
const SHORT_ROWS_AVX512_F64_MAX: usize = 128;

/// `ABKIT_ROWS16`: `1` short rows run in the sixteen-row AVX-512 lanes,
/// `0` not (unset: the default). Read once.
#[cfg(target_arch = "x86_64")]
fn rows16_switch() -> Option<bool> {
    static F: std::sync::OnceLock<Option<bool>> = std::sync::OnceLock::new();
    *F.get_or_init(|| std::env::var_os("ABKIT_ROWS16").map(|v| v != "0"))
}

/// `ABKIT_SHORT_ROWS_FLAT` set to anything but `0`: short rows always run
/// in the flat kernel (for tests and comparisons). Read once.
#[cfg(target_arch = "x86_64")]
fn short_rows_flat() -> bool {
    static F: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *F.get_or_init(|| std::env::var_os("ABKIT_SHORT_ROWS_FLAT").is_some_and(|v| v != "0"))
}

/// Start-up callback of [`ab_tracks_flat`] (see `flat::Start`).
#[cfg(target_arch = "x86_64")]
pub(crate) use flat::Start as FlatStart;

/// Fresh tracks started in [`ab_tracks_flat`]'s vector steps (see
/// `flat::VecStart`).
#[cfg(target_arch = "x86_64")]
pub(crate) use flat::VecStart as FlatVecStart;

/// For [`crate::ragged`]: alpha-beta over the back-to-back tracks
/// `off[j]..off[j+1]` of the flat `z`, `xs`, `vs` with the flat vector
/// kernel, gains `(T, alpha, g = beta / T)` per track (or one for all).
/// `None` where no flat kernel runs (no AVX2 or AVX-512 with FMA, another
/// `T`, `ABKIT_DISABLE_SIMD`).
///
/// Tracks that `run` would split when filtered alone (a steady-state run
/// of at least [`SPLIT_MIN_SAMPLES`] with a fast-decaying loop,
/// [`SplitPlan`]) are split the same way here ([`ab_split`], two passes,
/// `parallel`: the lane groups on two threads), so a long track in a
/// ragged batch gets the same results as alone and the same speed: in the
/// flat kernel a few long tracks would leave most of its slots idle (one
/// track of 10^7 samples: 12.7 ns per sample against 1.6 split; Intel
/// Xeon, session 14).
#[cfg(target_arch = "x86_64")]
#[allow(clippy::too_many_arguments)]
pub(crate) fn ab_tracks_flat<T: IoFloat>(
    gains: &[(f64, f64, f64)],
    start: &mut FlatStart<'_, T>,
    off: &[usize],
    z: &[T],
    xs: &mut [T],
    vs: &mut [T],
    states: &mut [TrackState],
    parallel: bool,
    vstart: Option<FlatVecStart>,
) -> Option<Result<()>> {
    let kind = tracks_flat_kernel::<T>(flat_kernel()?);
    if !simd::fits::<T>(0, 32) || gains.is_empty() {
        return None;
    }
    let total = off.last().copied().unwrap_or(0);
    let nt = streamed::<T>(2 * total * std::mem::size_of::<T>(), true);
    let shared = gains.len() == 1;
    let konst = |j: usize| {
        let (t, a, g) = gains[if shared { 0 } else { j }];
        AbConst {
            t,
            alpha: a,
            one_minus_alpha: 1.0 - a,
            g2: g,
        }
    };
    let n_tracks = off.len().saturating_sub(1);
    // (alpha, beta) of track j, for the split decision.
    let ab = |j: usize| {
        let (t, a, g) = gains[if shared { 0 } else { j }];
        (a, g * t)
    };
    let split: Vec<bool> = (0..n_tracks)
        .map(|j| {
            let (a, b) = ab(j);
            SplitPlan::new(a, b, off[j + 1].saturating_sub(off[j])).is_some()
        })
        .collect();
    let any_split = split.iter().any(|&s| s);
    // SAFETY: `flat_kernel()` checked the CPU features of `kind` (and
    // `tracks_flat_kernel` those of the AVX2 kind it may give instead:
    // `avx2_available()`); T is f32 or f64 (`fits`).
    let r = unsafe {
        run_flat(
            kind,
            &konst,
            shared,
            start,
            off,
            z,
            xs,
            vs,
            states,
            nt,
            any_split.then_some(&split[..]),
            vstart,
        )
    };
    if r.is_err() || !any_split {
        return Some(r);
    }
    for j in (0..n_tracks).filter(|&j| split[j]) {
        let (a, e) = (off[j], off[j + 1]);
        let (Some(zr), Some(xr), Some(vr), Some(st)) = (
            z.get(a..e),
            xs.get_mut(a..e),
            vs.get_mut(a..e),
            states.get_mut(j),
        ) else {
            return Some(Err(crate::Error::Shape(
                "flat alpha-beta: buffers do not match the offsets".into(),
            )));
        };
        let k0 = if st.phase >= 2.0 {
            0
        } else {
            match start(j, st, zr, xr, vr) {
                Ok(k) => k.min(e - a),
                Err(err) => return Some(Err(err)),
            }
        };
        if st.phase < 2.0 || k0 >= e - a {
            continue;
        }
        let (alpha, beta) = ab(j);
        let plan = SplitPlan::new(alpha, beta, e - a - k0);
        // SAFETY: the flat kernels need FMA (`flat_kernel()` checked it).
        unsafe { ab_track_fma(&konst(j), st, k0, zr, xr, vr, plan, parallel) };
    }
    Some(Ok(()))
}

/// One track from sample `k0` (running from `st`) with FMA: split by
/// `plan`, or in one piece.
///
/// # Safety
/// The CPU supports FMA.
#[cfg(target_arch = "x86_64")]
#[allow(clippy::too_many_arguments)]
#[target_feature(enable = "fma")]
unsafe fn ab_track_fma<T: IoFloat>(
    c: &AbConst,
    st: &mut TrackState,
    k0: usize,
    row: &[T],
    xs: &mut [T],
    vs: &mut [T],
    plan: Option<SplitPlan>,
    parallel: bool,
) {
    let mut o = TrackOut {
        states: [xs, vs],
        resid: None,
    };
    match plan {
        Some(plan) => ab_split::<T, true>(c, st, k0, row, &mut o, plan, parallel),
        None => ab_loop::<T, true>(c, st, k0, row.len(), |k| row[k].to_f64(), &mut o),
    }
}

/// The flat kernel of [`ab_tracks_flat`] (ragged batches) given the CPU's
/// flat kernel `kind`: on an AMD Zen 4 (family 19h with AVX-512) `f64`
/// tracks run in the AVX2 instance instead of the hand-written AVX-512
/// kernel (4 slots and 8 output streams instead of 8 and 16): there it was
/// faster on every ragged mix measured, `ragbench`, 10^7 samples from
/// memory, ns per sample, AVX-512 -> AVX2 (minimum of 5 alternated runs):
/// lengths 10..10,000 1.07 -> 0.92, 10..300 2.34 -> 1.65, 1,000..10,000
/// 1.01 -> 0.93, all 300 1.04 -> 0.94, all 100 1.27 -> 1.17; from Python
/// (`bench/bench_tracks.py`) ragged 10..10,000 893 -> 1,005 Msamples/s,
/// while `f32` lost 3-5 % and so keeps the AVX-512 kernel (rectangular
/// short rows kept it too in session 30, where the AVX2 kind was as fast
/// or slower; since session 34 rectangular `f64` batches beyond the L3
/// take the AVX2 kind, [`ZEN4_ROWS_AVX2_MIN_BYTES`]; docs/benchmarks.md).
/// `ABKIT_FLAT_AVX2=0` keeps the AVX-512 kernel here as well (tests and
/// comparisons); `ABKIT_FLAT_AVX2=1` gave the AVX2 kind already. The same
/// bits either way.
#[cfg(target_arch = "x86_64")]
fn tracks_flat_kernel<T: 'static>(kind: FlatKernel) -> FlatKernel {
    static ZEN4: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    let zen4 = *ZEN4.get_or_init(|| {
        let forced_off = std::env::var_os("ABKIT_FLAT_AVX2").is_some_and(|v| v == "0");
        !forced_off && amd_family() == Some(0x19) && simd::avx2_available()
    });
    if kind == FlatKernel::Avx512 && zen4 && simd::is_f64::<T>() {
        FlatKernel::Avx2
    } else {
        kind
    }
}

/// Whether the AVX2 kernels that run on an AMD Zen 4 take their Zen 4
/// forms: AMD family 19h with AVX2, FMA, AVX-512F and AVX-512VL, unless the
/// environment variable `ABKIT_ZEN4` is `0` (read once). The forms compile
/// the same kernels with AVX-512VL, so that they have 32 vector registers
/// instead of 16 (fewer spills; the same operations and so the same bits):
/// the AVX2 flat kernel of ragged `f64` batches ([`tracks_flat_kernel`],
/// `flatv::ab_flat_avx2`), the AVX2 row lanes, which then also take `f64`
/// rows from the AVX-512 ones ([`rows_zen4`]), and the irregular-timestamp lanes
/// ([`crate::ragged_simd::zen4`], which also store and prefetch
/// differently there), and the 4-lane general kernel of `f64`, which then
/// also takes `f64` rows from the 8 AVX-512 general lanes
/// (`simd::gen_lanes4_zen4`, `simd::gen8_enabled`). Measured on a Zen 4 EPYC
/// guest, docs/benchmarks.md, sessions 31 and 35.
#[cfg(target_arch = "x86_64")]
pub(crate) fn zen4_forms() -> bool {
    static Z: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *Z.get_or_init(|| {
        std::env::var_os("ABKIT_ZEN4").is_none_or(|v| v != "0")
            && amd_family() == Some(0x19)
            && is_x86_feature_detected!("avx2")
            && is_x86_feature_detected!("fma")
            && is_x86_feature_detected!("avx512f")
            && is_x86_feature_detected!("avx512vl")
    })
}

/// Whether the alpha-beta row lanes of `T` run in the AVX2 kernel's Zen 4
/// form ([`zen4_forms`]; `f64` only) instead of the AVX-512 lanes: on the
/// Zen 4 EPYC guest (`rowbench`, ns per sample, minimum / median of 5
/// alternated runs) `f64` 1,000 x 10,000 0.642 / 0.672 -> 0.611 / 0.623 and
/// one track of 10^7 (split into segments) 0.690 / 0.720 -> 0.639 / 0.644,
/// while `f32` was slower that way (0.55 -> 0.75; docs/benchmarks.md,
/// session 31). The same bits either way.
#[cfg(target_arch = "x86_64")]
fn rows_zen4<T: 'static>() -> bool {
    simd::is_f64::<T>() && zen4_forms()
}

/// The CPU family (base + extended, as `lscpu` prints it) of an AMD CPU,
/// `None` on other vendors.
#[cfg(target_arch = "x86_64")]
pub(crate) fn amd_family() -> Option<u32> {
    use std::arch::x86_64::__cpuid;
    #[allow(unused_unsafe)]
    // SAFETY: CPUID leaves 0 and 1 exist on every x86_64 CPU.
    let (l0, l1) = unsafe { (__cpuid(0), __cpuid(1)) };
    let amd = (l0.ebx, l0.edx, l0.ecx) == (0x6874_7541, 0x6974_6e65, 0x444d_4163);
    let base = (l1.eax >> 8) & 0xf;
    let ext = (l1.eax >> 20) & 0xff;
    amd.then_some(if base == 0xf { base + ext } else { base })
}

/// The flat kernels (see [`flat`] and [`flatv`]).
#[cfg(target_arch = "x86_64")]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum FlatKernel {
    /// AVX-512F + FMA, [`flat::ab_flat`] (the default on AVX-512 CPUs).
    Avx512,
    /// AVX-512F + FMA, the generic kernel ([`flatv::ab_flat_avx512`]):
    /// opt-in with `ABKIT_FLAT_AVX512` set to anything but `0`.
    Avx512Generic,
    /// AVX2 + FMA, the generic kernel ([`flatv::ab_flat_avx2`]).
    Avx2,
}

/// The flat kernel of this CPU, `None` without one (or with
/// `ABKIT_DISABLE_SIMD`); `ABKIT_FLAT_AVX2` set to anything but `0` takes
/// the AVX2 kernel on AVX-512 CPUs too (for tests and comparisons: the
/// flat paths of an AVX2-only CPU). Checked once.
#[cfg(target_arch = "x86_64")]
fn flat_kernel() -> Option<FlatKernel> {
    static K: std::sync::OnceLock<Option<FlatKernel>> = std::sync::OnceLock::new();
    *K.get_or_init(|| {
        let on = |k: &str| std::env::var_os(k).is_some_and(|v| v != "0");
        let opt_in = on("ABKIT_FLAT_AVX512");
        if !uses_fma() {
            None
        } else if simd::available() && !on("ABKIT_FLAT_AVX2") {
            Some(if opt_in {
                FlatKernel::Avx512Generic
            } else {
                FlatKernel::Avx512
            })
        } else if simd::avx2_available() {
            Some(FlatKernel::Avx2)
        } else {
            None
        }
    })
}

/// Run the flat kernel `kind` (the contract of [`flat::ab_flat`]).
///
/// # Safety
/// The CPU has the features of `kind` (as returned by [`flat_kernel`]);
/// `T` is `f32` or `f64`.
#[cfg(target_arch = "x86_64")]
#[allow(clippy::too_many_arguments)]
unsafe fn run_flat<T: IoFloat>(
    kind: FlatKernel,
    konst: &dyn Fn(usize) -> AbConst,
    shared: bool,
    start: &mut FlatStart<'_, T>,
    off: &[usize],
    z: &[T],
    xs: &mut [T],
    vs: &mut [T],
    states: &mut [TrackState],
    nt: bool,
    skip: Option<&[bool]>,
    vstart: Option<flat::VecStart>,
) -> Result<()> {
    // SAFETY: forwarded from the caller.
    unsafe {
        match kind {
            FlatKernel::Avx512 => flat::ab_flat(
                konst, shared, start, off, z, xs, vs, states, nt, skip, vstart,
            ),
            FlatKernel::Avx512Generic => flatv::ab_flat_avx512(
                konst, shared, start, off, z, xs, vs, states, nt, skip, vstart,
            ),
            FlatKernel::Avx2 => flatv::ab_flat_avx2(
                konst, shared, start, off, z, xs, vs, states, nt, skip, vstart,
            ),
        }
    }
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
#[path = "tests/filter.rs"]
mod tests;
