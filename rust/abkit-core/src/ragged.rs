//! Ragged batches of tracks with optional per-sample timestamps.
//!
//! # Layout
//! The samples of all tracks are one flat sequence of `N` samples; track `i`
//! is samples `offsets[i]..offsets[i+1]` (the Arrow list layout). Outputs
//! use the same flat layout: estimates `(n, N)` component-major, residuals
//! `(N, m)`. A rectangular batch `(n_tracks, n_samples)` is the special case
//! `offsets[i] = i n_samples` ([`Samples`] addresses both without a copy).
//!
//! # Semantics (per track)
//! The state always sits at the time of the last kept sample. With
//! timestamps, sample `k` at `t_k`:
//!
//! 1. `t_k` must be finite, and after the last kept timestamp: otherwise an
//!    [`Error::Data`] (track, sample), or with `drop_duplicates` the sample
//!    is dropped (estimates and residual NaN, state untouched, counted).
//! 2. `dt = t_k - t_last`; if `dt > max_gap` a started track restarts (phase
//!    0, counted) and sample `k` starts it again by the `init` rule.
//! 3. Start-up as in [`crate::filter`]: the two-point velocity is
//!    `(z2 - z1) / (t2 - t1)`.
//! 4. Running: `x_p = Phi(dt) x`, `e = z - H x_p`, `x = x_p + K(dt) e`
//!    (coast `x = x_p` on a NaN measurement) with the step model of the
//!    [`GainLaw`].
//!
//! Without timestamps every step is the nominal period (`dt = T`) and the
//! two-point velocity uses the sample count, as in [`crate::filter`]. A
//! running state without a known last time (an explicit initial state, or
//! a state from a call without timestamps) is taken to be one nominal
//! period before its next sample.
//!
//! Tracks are processed in blocks of consecutive tracks (about
//! [`BLOCK_SAMPLES`] samples each) on rayon's pool; each block gets
//! disjoint sub-slices of the outputs, nothing is padded or copied. The
//! result of a track never depends on the blocking, so results are
//! bit-identical for any thread count and equal to running each track alone.
//!
//! Alpha-beta laws with timestamps run their plain running steps in the
//! vector lanes of [`crate::ragged_simd`] where the CPU has them (the same
//! arithmetic per track, bit-identical to the scalar lanes).
#![allow(clippy::needless_range_loop, clippy::too_many_arguments)]

use crate::filter::{Init, IoFloat, TrackOut, TrackState};
use crate::irregular::{GainLaw, Kin3Backward, Kin3Cache, Step};
use crate::{Error, Result};
use rayon::prelude::*;

/// Target samples per block of tracks.
pub const BLOCK_SAMPLES: usize = 32_768;
/// Target samples per block of tracks when the vector lanes run.
pub const VECTOR_BLOCK_SAMPLES: usize = 262_144;
/// Largest number of tracks per block.
pub const BLOCK_TRACKS: usize = 4_096;

/// Samples (or timestamps, `m = 1`) in rows: flat sample `g` is in row
/// `g / row_len` at position `g % row_len`; element `(g, j)` is
/// `data[base + row * s_row + pos * s_sample + j * s_comp]` (strides in
/// elements, any sign). A flat array is one row of all samples; a
/// rectangular `(n_tracks, n_samples)` array has `row_len = n_samples`.
#[derive(Debug, Clone, Copy)]
pub struct Samples<'a, T> {
    /// Backing memory.
    pub data: &'a [T],
    /// Offset of element `(0, 0)`.
    pub base: usize,
    /// Stride between rows.
    pub s_row: isize,
    /// Stride between samples of a row.
    pub s_sample: isize,
    /// Stride between components.
    pub s_comp: isize,
    /// Samples per row.
    pub row_len: usize,
    /// Number of rows.
    pub n_rows: usize,
    /// Components per sample.
    pub m: usize,
}

impl<'a, T: Copy> Samples<'a, T> {
    /// A contiguous flat `(n, m)` array.
    pub fn flat(data: &'a [T], m: usize) -> Result<Self> {
        if m == 0 || !data.len().is_multiple_of(m) {
            return Err(Error::Shape(format!(
                "buffer of {} elements is not a multiple of m = {m}",
                data.len()
            )));
        }
        Ok(Samples {
            data,
            base: 0,
            s_row: 0,
            s_sample: m as isize,
            s_comp: 1,
            row_len: data.len() / m,
            n_rows: 1,
            m,
        })
    }

    /// Total number of samples.
    pub fn len(&self) -> usize {
        self.row_len * self.n_rows
    }

    /// Whether there are no samples.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Address of flat sample `g`, component 0 (an empty layout, e.g. rows
    /// of no samples, has only `g = 0`: its base).
    #[inline]
    pub(crate) fn addr(&self, g: usize) -> isize {
        let (r, p) = if self.n_rows <= 1 || self.row_len == 0 {
            (0, g)
        } else {
            (g / self.row_len, g % self.row_len)
        };
        self.base as isize + r as isize * self.s_row + p as isize * self.s_sample
    }

    /// Check that every element lies inside `data`.
    pub(crate) fn validate(&self, what: &str) -> Result<()> {
        if self.is_empty() {
            return Ok(());
        }
        let ext = |n: usize, s: isize| {
            let span = (n as isize - 1) * s;
            (span.min(0), span.max(0))
        };
        let parts = [
            ext(self.n_rows, self.s_row),
            ext(self.row_len, self.s_sample),
            ext(self.m, self.s_comp),
        ];
        let lo = self.base as isize + parts.iter().map(|p| p.0).sum::<isize>();
        let hi = self.base as isize + parts.iter().map(|p| p.1).sum::<isize>();
        if lo < 0 || hi >= self.data.len() as isize {
            return Err(Error::Shape(format!(
                "{what} strides reach outside the buffer"
            )));
        }
        Ok(())
    }
}

/// Options of the track kernel.
#[derive(Debug, Clone, Copy)]
pub struct Options {
    /// Start-up rule.
    pub init: Init,
    /// Nominal period: the step without timestamps, and the two-point
    /// divisor `gap * T` when no held timestamp is known.
    pub t_nominal: f64,
    /// Restart a track after a step longer than this (timestamps only).
    pub max_gap: Option<f64>,
    /// Drop samples whose timestamp is not after the last kept one
    /// (otherwise an error).
    pub drop_duplicates: bool,
}

/// The filter of the track kernel: a gain law (one for all tracks or one
/// per track) and the measurement model.
#[derive(Debug, Clone)]
pub struct TrackFilter<'a, L, const N: usize, const M: usize> {
    /// Gain laws, `1` or `n_tracks`.
    pub laws: &'a [L],
    /// Measurement matrix.
    pub h: [[f64; N]; M],
    /// Pseudo-inverse of `H`, for `Init::First`.
    pub h_pinv: [[f64; M]; N],
}

/// Per-track counts: `[n_dropped, n_restarts]`.
pub type Counts = [i64; 2];

/// What to do with each track after filtering it (e.g. smoothing): called
/// with the track index, its estimates and its timestamps (if any).
pub trait PostTrack<T, const N: usize>: Sync {
    /// Process one filtered track in place.
    fn post(
        &self,
        track: usize,
        states: &mut [&mut [T]; N],
        t: Option<&dyn Fn(usize) -> f64>,
        max_gap: Option<f64>,
    ) -> Result<()>;

    /// Whether [`PostTrack::post`] does nothing ([`NoPost`]).
    fn is_none(&self) -> bool {
        false
    }
}

/// No post-processing.
#[derive(Debug, Clone, Copy)]
pub struct NoPost;

impl<T, const N: usize> PostTrack<T, N> for NoPost {
    fn is_none(&self) -> bool {
        true
    }

    fn post(
        &self,
        _: usize,
        _: &mut [&mut [T]; N],
        _: Option<&dyn Fn(usize) -> f64>,
        _: Option<f64>,
    ) -> Result<()> {
        Ok(())
    }
}

/// Steady-state smoothing with constant backward gains (no timestamps):
/// [`crate::smooth::smooth_track`] with `phi[p]`, `a[p]` of the track's
/// parameter set `p`.
#[derive(Debug, Clone)]
pub struct ConstSmooth<'a, const N: usize> {
    /// Transitions, 1 or one per track.
    pub phi: &'a [[[f64; N]; N]],
    /// Backward gains, 1 or one per track.
    pub a: &'a [[[f64; N]; N]],
    /// Fixed lag, or `None` for fixed interval.
    pub lag: Option<usize>,
}

impl<T: IoFloat, const N: usize> PostTrack<T, N> for ConstSmooth<'_, N> {
    fn post(
        &self,
        track: usize,
        states: &mut [&mut [T]; N],
        _: Option<&dyn Fn(usize) -> f64>,
        _: Option<f64>,
    ) -> Result<()> {
        let p = |len: usize| if len == 1 { 0 } else { track };
        let (Some(phi), Some(a)) = (self.phi.get(p(self.phi.len())), self.a.get(p(self.a.len())))
        else {
            return Err(Error::Shape(
                "smoother gains do not match the tracks".into(),
            ));
        };
        crate::smooth::smooth_track(phi, a, self.lag, states);
        Ok(())
    }
}

/// Alpha-beta smoothing: constant gains without timestamps, the per-dt
/// backward gain of [`AbBackward`] with them.
#[derive(Debug, Clone)]
pub struct AbSmooth<'a> {
    /// Backward gains, 1 or one per track.
    pub back: &'a [crate::irregular::AbBackward],
    /// Nominal period (steps without timestamps).
    pub t_nominal: f64,
    /// Fixed lag, or `None` for fixed interval.
    pub lag: Option<usize>,
}

impl<T: IoFloat> PostTrack<T, 2> for AbSmooth<'_> {
    fn post(
        &self,
        track: usize,
        states: &mut [&mut [T]; 2],
        t: Option<&dyn Fn(usize) -> f64>,
        max_gap: Option<f64>,
    ) -> Result<()> {
        let Some(b) = self.back.get(if self.back.len() == 1 { 0 } else { track }) else {
            return Err(Error::Shape(
                "smoother gains do not match the tracks".into(),
            ));
        };
        match t {
            None => {
                let (phi, a) = b.at(self.t_nominal);
                crate::smooth::smooth_track(&phi, &a, self.lag, states);
                Ok(())
            }
            Some(t) => crate::smooth::smooth_track_tv(
                t,
                max_gap.unwrap_or(f64::INFINITY),
                self.lag,
                states,
                &mut |dt, _| {
                    let (phi, a) = b.at(dt);
                    if phi.iter().chain(a.iter()).flatten().all(|v| v.is_finite()) {
                        Ok((phi, a))
                    } else {
                        Err(Error::Domain {
                            name: "t",
                            expected: format!(
                                "steps dt at which the smoother's backward gain is representable in float64 \
                                 (track {track}); rescale t"
                            ),
                            value: dt,
                        })
                    }
                },
            ),
        }
    }
}

/// Smoothing of the 3-state kinematic filters (alpha-beta-gamma, Singer):
/// with timestamps the per-dt backward gain of [`Kin3Backward`] (cached per
/// track for the last distinct steps), at the nominal period without.
#[derive(Debug, Clone)]
pub struct Kin3Smooth<'a> {
    /// Backward gains, 1 or one per track.
    pub back: &'a [Kin3Backward],
    /// Nominal period (steps without timestamps).
    pub t_nominal: f64,
    /// Fixed lag, or `None` for fixed interval.
    pub lag: Option<usize>,
}

impl<T: IoFloat> PostTrack<T, 3> for Kin3Smooth<'_> {
    fn post(
        &self,
        track: usize,
        states: &mut [&mut [T]; 3],
        t: Option<&dyn Fn(usize) -> f64>,
        max_gap: Option<f64>,
    ) -> Result<()> {
        let Some(b) = self.back.get(if self.back.len() == 1 { 0 } else { track }) else {
            return Err(Error::Shape(
                "smoother gains do not match the tracks".into(),
            ));
        };
        let fail = |sample: usize, dt: f64, e: Error| Error::Data {
            track,
            sample,
            msg: format!("smoothing: no backward gain for the step dt={dt}: {e}"),
        };
        match t {
            None => {
                let (phi, a) = b
                    .at(self.t_nominal)
                    .map_err(|e| fail(0, self.t_nominal, e))?;
                crate::smooth::smooth_track(&phi, &a, self.lag, states);
                Ok(())
            }
            Some(t) => {
                let mut cache = Kin3Cache::default();
                crate::smooth::smooth_track_tv(
                    t,
                    max_gap.unwrap_or(f64::INFINITY),
                    self.lag,
                    states,
                    &mut |dt, j| cache.get(b, dt).map_err(|e| fail(j, dt, e)),
                )
            }
        }
    }
}

/// Check offsets: `n_tracks + 1` entries, starting at 0, non-decreasing,
/// ending at `n_total`; and (for rows of a rectangular array) no track
/// crossing a row. Returns them as `usize`.
pub fn check_offsets(
    offsets: &[i64],
    n_total: usize,
    row_len: usize,
    n_rows: usize,
) -> Result<Vec<usize>> {
    let Some(&first) = offsets.first() else {
        return Err(Error::Shape("offsets must have at least one entry".into()));
    };
    if first != 0 {
        return Err(Error::Shape(format!("offsets[0] must be 0, got {first}")));
    }
    let mut out = Vec::with_capacity(offsets.len());
    let mut prev = 0i64;
    for (i, &o) in offsets.iter().enumerate() {
        if o < prev {
            return Err(Error::Shape(format!(
                "offsets must be non-decreasing: offsets[{i}] = {o} < offsets[{}] = {prev}",
                i - 1
            )));
        }
        prev = o;
        out.push(o as usize);
    }
    if prev as usize != n_total || prev < 0 {
        return Err(Error::Shape(format!(
            "offsets[-1] must be the number of samples {n_total}, got {prev}"
        )));
    }
    if n_rows > 1 {
        for (i, w) in out.windows(2).enumerate() {
            if w[1] > w[0] && (w[0] / row_len != (w[1] - 1) / row_len) {
                return Err(Error::Shape(format!(
                    "track {i} crosses a row of the measurement array"
                )));
            }
        }
    }
    Ok(out)
}

struct Block<'a, T, const N: usize> {
    i0: usize,
    s0: usize,
    comps: [&'a mut [T]; N],
    resid: Option<&'a mut [T]>,
    states: &'a mut [TrackState],
    counts: &'a mut [Counts],
}

/// Split `[0, n_tracks)` into blocks of consecutive tracks.
/// Blocks hold about `samples` samples and at least `min_tracks` tracks
/// (when there are that many) so that the vector lanes fill.
fn plan_blocks(offsets: &[usize], samples: usize, min_tracks: usize) -> Vec<(usize, usize)> {
    let n_tracks = offsets.len() - 1;
    let mut blocks = Vec::new();
    let mut i0 = 0;
    while i0 < n_tracks {
        let mut i1 = i0 + 1;
        while i1 < n_tracks
            && i1 - i0 < BLOCK_TRACKS
            && (offsets[i1] - offsets[i0] < samples || i1 - i0 < min_tracks)
        {
            i1 += 1;
        }
        blocks.push((i0, i1));
        i0 = i1;
    }
    blocks
}

/// Filter ragged tracks (see the module docs).
///
/// `out` is `(N, n_total)` component-major, `resid` `(n_total, M)`,
/// `states` and `counts` one per track.
pub fn filter_tracks<
    T: IoFloat,
    L: GainLaw<N, M>,
    P: PostTrack<T, N>,
    const N: usize,
    const M: usize,
>(
    filt: &TrackFilter<'_, L, N, M>,
    opts: &Options,
    offsets: &[i64],
    z: &Samples<'_, T>,
    t: Option<&Samples<'_, f64>>,
    states: &mut [TrackState],
    out: &mut [T],
    resid: Option<&mut [T]>,
    counts: &mut [Counts],
    parallel: bool,
    post: &P,
) -> Result<()> {
    let n_total = z.len();
    if z.m != M {
        return Err(Error::Shape(format!(
            "measurements have {} components, the filter {M}",
            z.m
        )));
    }
    z.validate("measurement")?;
    let off = check_offsets(offsets, n_total, z.row_len, z.n_rows)?;
    let n_tracks = off.len() - 1;
    if let Some(t) = t {
        if t.len() != n_total || t.row_len != z.row_len {
            return Err(Error::Shape(format!(
                "t has {} samples in rows of {}, z {n_total} in rows of {}",
                t.len(),
                t.row_len,
                z.row_len
            )));
        }
        t.validate("timestamp")?;
    }
    if filt.laws.len() != 1 && filt.laws.len() != n_tracks {
        return Err(Error::Shape(format!(
            "{} parameter sets for {n_tracks} tracks (need 1 or one per track)",
            filt.laws.len()
        )));
    }
    if states.len() != n_tracks || counts.len() != n_tracks {
        return Err(Error::Shape(
            "state or count buffers do not match the tracks".into(),
        ));
    }
    if crate::planes::stride::<T>(out.len(), N, n_total, 0).is_none() {
        return Err(Error::Shape("output buffer has the wrong size".into()));
    }
    if let Some(r) = &resid {
        if r.len() != M * n_total {
            return Err(Error::Shape("residual buffer has the wrong size".into()));
        }
    }
    if !(opts.t_nominal.is_finite() && opts.t_nominal > 0.0) {
        return Err(Error::domain("T", "finite and > 0", opts.t_nominal));
    }
    if let Some(g) = opts.max_gap {
        if g.is_nan() || g <= 0.0 {
            return Err(Error::domain("max_gap", "> 0", g));
        }
    }
    if n_tracks == 0 {
        return Ok(());
    }
    #[cfg(target_arch = "x86_64")]
    if let (Some(tt), None) = (t, &resid) {
        if let Some(r) = crate::ragged_split::split_timed(
            filt, opts, &off, z, tt, states, out, counts, parallel, post,
        ) {
            return r;
        }
    }
    run_tracks(
        filt, opts, &off, z, t, states, out, resid, counts, parallel, post,
    )
}

/// [`filter_tracks`] after its checks (`off`: the validated offsets).
#[allow(clippy::too_many_arguments)]
pub(crate) fn run_tracks<
    T: IoFloat,
    L: GainLaw<N, M>,
    P: PostTrack<T, N>,
    const N: usize,
    const M: usize,
>(
    filt: &TrackFilter<'_, L, N, M>,
    opts: &Options,
    off: &[usize],
    z: &Samples<'_, T>,
    t: Option<&Samples<'_, f64>>,
    states: &mut [TrackState],
    out: &mut [T],
    resid: Option<&mut [T]>,
    counts: &mut [Counts],
    parallel: bool,
    post: &P,
) -> Result<()> {
    let n_total = z.len();
    #[cfg(target_arch = "x86_64")]
    if t.is_none() && resid.is_none() && N == 2 && M == 1 {
        if let Some(r) = flat_tracks(filt, opts, off, z, states, out, counts, parallel, post) {
            return r;
        }
    }
    // Split the outputs into per-block slices.
    // With the vector lanes: blocks of at least two tracks per lane (the
    // lanes fill), and bigger (the lanes of a block's last tracks run
    // partly idle).
    #[cfg(target_arch = "x86_64")]
    let vector = t.is_some() && N == 2 && M == 1 && crate::ragged_simd::width() > 0;
    #[cfg(not(target_arch = "x86_64"))]
    let vector = false;
    let plan = if vector {
        #[cfg(target_arch = "x86_64")]
        let w = crate::ragged_simd::width();
        #[cfg(not(target_arch = "x86_64"))]
        let w = 1;
        plan_blocks(off, VECTOR_BLOCK_SAMPLES, 2 * w)
    } else {
        plan_blocks(off, BLOCK_SAMPLES, 1)
    };
    let Some(mut rows) = crate::planes::split(out, N, n_total, 0) else {
        return Err(Error::Shape("output buffer has the wrong size".into()));
    };
    let mut resid_rest = resid;
    let mut st_rest = states;
    let mut ct_rest = counts;
    let mut blocks: Vec<Block<'_, T, N>> = Vec::with_capacity(plan.len());
    for &(i0, i1) in &plan {
        let len = off[i1] - off[i0];
        let mut comps: [&mut [T]; N] = std::array::from_fn(|_| -> &mut [T] { &mut [] });
        for (c, row) in rows.iter_mut().enumerate() {
            let (a, b) = std::mem::take(row).split_at_mut(len);
            comps[c] = a;
            *row = b;
        }
        let r = match resid_rest.take() {
            Some(r) => {
                let (a, b) = r.split_at_mut(len * M);
                resid_rest = Some(b);
                Some(a)
            }
            None => None,
        };
        let (s, s_rest) = std::mem::take(&mut st_rest).split_at_mut(i1 - i0);
        st_rest = s_rest;
        let (c, c_rest) = std::mem::take(&mut ct_rest).split_at_mut(i1 - i0);
        ct_rest = c_rest;
        blocks.push(Block {
            i0,
            s0: off[i0],
            comps,
            resid: r,
            states: s,
            counts: c,
        });
    }
    let run = |b: &mut Block<'_, T, N>| run_block_dispatch(filt, opts, off, z, t, b, post);
    let results: Vec<Result<()>> = if parallel && blocks.len() > 1 {
        blocks.par_iter_mut().map(run).collect()
    } else {
        blocks.iter_mut().map(run).collect()
    };
    results.into_iter().collect()
}

/// Alpha-beta without timestamps on contiguous samples: the flat vector
/// kernel of [`crate::filter`] (slots walking runs of back-to-back tracks),
/// with this module's start-up ([`track_tv`] until the track runs) and
/// post-processing. The same arithmetic per track as [`run_block_lanes`]
/// (bit-identical). `None` where it does not apply.
#[cfg(target_arch = "x86_64")]
fn flat_tracks<T: IoFloat, L: GainLaw<N, M>, P: PostTrack<T, N>, const N: usize, const M: usize>(
    filt: &TrackFilter<'_, L, N, M>,
    opts: &Options,
    off: &[usize],
    z: &Samples<'_, T>,
    states: &mut [TrackState],
    out: &mut [T],
    counts: &mut [Counts],
    parallel: bool,
    post: &P,
) -> Option<Result<()>> {
    let n_total = z.len();
    let contiguous = z.s_sample == 1 && (z.n_rows <= 1 || z.s_row == z.row_len as isize);
    if N != 2 || M != 1 || z.m != 1 || !contiguous || n_total == 0 {
        return None;
    }
    let zs = z.data.get(z.base..z.base.checked_add(n_total)?)?;
    let mut gains = Vec::with_capacity(filt.laws.len());
    for law in filt.laws {
        let (a, g) = law.clone().ab_gains(opts.t_nominal)?;
        if !(a.is_finite() && g.is_finite()) {
            return None;
        }
        gains.push((opts.t_nominal, a, g));
    }
    let n_tracks = states.len();
    let (xs, vs) = crate::planes::split2(out, N, n_total, 0)?;
    // Chunks of whole tracks (the unit of parallel work); results do not
    // depend on the chunking.
    let threads = if parallel {
        rayon::current_num_threads()
    } else {
        1
    };
    let target = if threads > 1 {
        (n_total / (4 * threads)).max(1 << 18)
    } else {
        n_total
    };
    type Chunk<'c, T> = (
        usize,
        usize,
        &'c mut [TrackState],
        &'c mut [Counts],
        &'c mut [T],
        &'c mut [T],
    );
    let mut chunks: Vec<Chunk<'_, T>> = Vec::new();
    let (mut st_rest, mut ct_rest, mut x_rest, mut v_rest) = (states, counts, xs, vs);
    let mut j0 = 0;
    while j0 < n_tracks {
        let mut j1 = j0 + 1;
        while j1 < n_tracks && off[j1] - off[j0] < target {
            j1 += 1;
        }
        let len = off[j1] - off[j0];
        let (a, b) = std::mem::take(&mut st_rest).split_at_mut(j1 - j0);
        let (ca, cb) = std::mem::take(&mut ct_rest).split_at_mut(j1 - j0);
        let (xa, xb) = std::mem::take(&mut x_rest).split_at_mut(len);
        let (va, vb) = std::mem::take(&mut v_rest).split_at_mut(len);
        chunks.push((j0, j1, a, ca, xa, va));
        (st_rest, ct_rest, x_rest, v_rest) = (b, cb, xb, vb);
        j0 = j1;
    }
    // A long track split alone (`ab_tracks_flat`) takes both threads when
    // its chunk is the only one.
    let split_par = parallel && chunks.len() == 1;
    let run = |(j0, j1, st, ct, xs, vs): Chunk<'_, T>| -> Option<Result<()>> {
        let base = off[j0];
        let loc: Vec<usize> = off[j0..=j1].iter().map(|&o| o - base).collect();
        let g = if gains.len() == 1 {
            &gains[..]
        } else {
            &gains[j0..j1]
        };
        let mut start = |j: usize, s: &mut TrackState, zr: &[T], xr: &mut [T], vr: &mut [T]| {
            let i = j0 + j;
            let mut law = filt.laws[if filt.laws.len() == 1 { 0 } else { i }].clone();
            let mut it = [xr, vr].into_iter();
            let comps: [&mut [T]; N] = std::array::from_fn(|_| it.next().unwrap_or_default());
            let mut o = TrackOut {
                states: comps,
                resid: None,
            };
            let zf = |k: usize| -> [f64; M] { std::array::from_fn(|_| zr[k].to_f64()) };
            track_tv::<T, L, N, M, true>(
                &mut law,
                &filt.h,
                &filt.h_pinv,
                opts,
                s,
                zr.len(),
                zf,
                None::<&fn(usize) -> f64>,
                &mut o,
                &mut ct[j],
                i,
                0,
                true,
            )
        };
        let zc = &zs[base..off[j1]];
        // Fresh tracks whose first samples are valid start in the kernel's
        // vector steps, with `track_tv`'s arithmetic.
        let vs0 = Some(crate::filter::FlatVecStart::Tracks(opts.init));
        let r = crate::filter::ab_tracks_flat(g, &mut start, &loc, zc, xs, vs, st, split_par, vs0)?;
        Some(r.and_then(|()| {
            for j in 0..j1 - j0 {
                let (a, e) = (loc[j], loc[j + 1]);
                let mut it = [&mut xs[a..e], &mut vs[a..e]].into_iter();
                let mut comps: [&mut [T]; N] =
                    std::array::from_fn(|_| it.next().unwrap_or_default());
                post.post(j0 + j, &mut comps, None, None)?;
            }
            Ok(())
        }))
    };
    let res: Vec<Option<Result<()>>> = if parallel && chunks.len() > 1 {
        chunks.into_par_iter().map(run).collect()
    } else {
        chunks.into_iter().map(run).collect()
    };
    // `None` from a chunk: the kernel is not available (then for none).
    res.into_iter()
        .collect::<Option<Vec<_>>>()
        .map(|v| v.into_iter().collect())
}

fn run_block_dispatch<
    T: IoFloat,
    L: GainLaw<N, M>,
    P: PostTrack<T, N>,
    const N: usize,
    const M: usize,
>(
    filt: &TrackFilter<'_, L, N, M>,
    opts: &Options,
    off: &[usize],
    z: &Samples<'_, T>,
    t: Option<&Samples<'_, f64>>,
    b: &mut Block<'_, T, N>,
    post: &P,
) -> Result<()> {
    #[cfg(target_arch = "x86_64")]
    {
        if crate::filter::uses_fma() {
            // SAFETY: the CPU supports FMA (checked at run time by `uses_fma`).
            return unsafe { run_block_fma(filt, opts, off, z, t, b, post) };
        }
        run_block::<T, L, P, N, M, false>(filt, opts, off, z, t, b, post)
    }
    #[cfg(target_arch = "aarch64")]
    {
        run_block::<T, L, P, N, M, true>(filt, opts, off, z, t, b, post)
    }
    #[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
    {
        run_block::<T, L, P, N, M, false>(filt, opts, off, z, t, b, post)
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "fma")]
fn run_block_fma<
    T: IoFloat,
    L: GainLaw<N, M>,
    P: PostTrack<T, N>,
    const N: usize,
    const M: usize,
>(
    filt: &TrackFilter<'_, L, N, M>,
    opts: &Options,
    off: &[usize],
    z: &Samples<'_, T>,
    t: Option<&Samples<'_, f64>>,
    b: &mut Block<'_, T, N>,
    post: &P,
) -> Result<()> {
    run_block::<T, L, P, N, M, true>(filt, opts, off, z, t, b, post)
}

#[inline(always)]
fn run_block<
    T: IoFloat,
    L: GainLaw<N, M>,
    P: PostTrack<T, N>,
    const N: usize,
    const M: usize,
    const FMA: bool,
>(
    filt: &TrackFilter<'_, L, N, M>,
    opts: &Options,
    off: &[usize],
    z: &Samples<'_, T>,
    t: Option<&Samples<'_, f64>>,
    b: &mut Block<'_, T, N>,
    post: &P,
) -> Result<()> {
    if N == 2 && M == 1 && filt.laws[0].clone().ab_gains(opts.t_nominal).is_some() {
        return run_block_lanes::<T, L, P, N, M, FMA>(filt, opts, off, z, t, b, post);
    }
    let mut shared: Option<L> = None;
    for j in 0..b.states.len() {
        let i = b.i0 + j;
        let (a, e) = (off[i] - b.s0, off[i + 1] - b.s0);
        let n = e - a;
        let mut own;
        let law: &mut L = if filt.laws.len() == 1 {
            shared.get_or_insert_with(|| filt.laws[0].clone())
        } else {
            own = filt.laws[i].clone();
            &mut own
        };
        let mut o = TrackOut {
            states: b.comps.each_mut().map(|s| &mut s[a..e]),
            resid: b.resid.as_deref_mut().map(|r| &mut r[a * M..e * M]),
        };
        let zb = z.addr(off[i]);
        let zf = |k: usize| -> [f64; M] {
            std::array::from_fn(|c| {
                z.data[(zb + k as isize * z.s_sample + c as isize * z.s_comp) as usize].to_f64()
            })
        };
        let st = &mut b.states[j];
        let ct = &mut b.counts[j];
        match t {
            Some(ts) => {
                let tb = ts.addr(off[i]);
                let tf = |k: usize| -> f64 { ts.data[(tb + k as isize * ts.s_sample) as usize] };
                track_tv::<T, L, N, M, FMA>(
                    law,
                    &filt.h,
                    &filt.h_pinv,
                    opts,
                    st,
                    n,
                    zf,
                    Some(&tf),
                    &mut o,
                    ct,
                    i,
                    0,
                    false,
                )?;
                post.post(i, &mut o.states, Some(&tf), opts.max_gap)?;
            }
            None => {
                track_tv::<T, L, N, M, FMA>(
                    law,
                    &filt.h,
                    &filt.h_pinv,
                    opts,
                    st,
                    n,
                    zf,
                    None::<&fn(usize) -> f64>,
                    &mut o,
                    ct,
                    i,
                    0,
                    false,
                )?;
                post.post(i, &mut o.states, None, None)?;
            }
        }
    }
    Ok(())
}

/// Lanes of the interleaved (scalar) alpha-beta driver.
pub const AB_TRACK_LANES: usize = 4;

/// Most lanes of the driver (the vector lanes of [`crate::ragged_simd`]).
const MAX_TRACK_LANES: usize = 8;

/// Lanes of the vector kernel for this call (0: the scalar lanes run):
/// alpha-beta laws it knows, timestamps, stride-1 measurements and
/// timestamps, `f32`/`f64` samples, FMA arithmetic, a CPU with the vector
/// units (and `ABKIT_DISABLE_SIMD` unset).
fn vector_width<T: IoFloat, L: GainLaw<N, M>, const N: usize, const M: usize, const FMA: bool>(
    law: &L,
    z: &Samples<'_, T>,
    t: Option<&Samples<'_, f64>>,
) -> usize {
    #[cfg(target_arch = "x86_64")]
    {
        let Some(ts) = t else { return 0 };
        if !(FMA
            && N == 2
            && M == 1
            && z.s_sample == 1
            && ts.s_sample == 1
            && law.ab_law().is_some()
            && crate::ragged_simd::handles::<T>())
        {
            return 0;
        }
        crate::ragged_simd::width().min(MAX_TRACK_LANES)
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let _ = (law, z, t);
        0
    }
}

/// Samples per call of the vector kernel while idle lanes walk [`Pad`].
#[cfg(target_arch = "x86_64")]
const PAD_STEPS: usize = 256;

/// Shortest stretch of vector steps whose outputs are streamed
/// (`ragged_simd::run`).
#[cfg(target_arch = "x86_64")]
const NT_MIN_STEPS: usize = 2048;

/// Scratch tracks of the idle vector lanes: measurements 0 at times
/// `h, 2h, ...` (`h` a power of 2 within `max_gap`, so every step is a
/// plain one), outputs discarded.
#[cfg(target_arch = "x86_64")]
struct Pad<T> {
    z: Vec<T>,
    t: Vec<f64>,
    out: Vec<T>,
}

#[cfg(target_arch = "x86_64")]
impl<T> Default for Pad<T> {
    fn default() -> Self {
        Pad {
            z: Vec::new(),
            t: Vec::new(),
            out: Vec::new(),
        }
    }
}

/// Up to `steps` steps of every lane in the vector kernel (whole blocks of
/// plain steps; see [`crate::ragged_simd::run`]), with scratch tracks in
/// the lanes no track occupies; returns the steps done.
#[cfg(target_arch = "x86_64")]
fn vector_steps<T: IoFloat, L: GainLaw<N, M>, const N: usize, const M: usize>(
    lanes: &mut [Lane<'_, T, L, N>],
    xv: &mut [(f64, f64); MAX_TRACK_LANES],
    z: &Samples<'_, T>,
    ts: &Samples<'_, f64>,
    steps: usize,
    max_gap: f64,
    pad: &mut Pad<T>,
) -> usize {
    use crate::ragged_simd::{run, width, VLane};
    // Outputs too big for the caches: whole lines streamed (`run`).
    let bytes = z.data.len().saturating_mul(2 * std::mem::size_of::<T>());
    let nt = crate::filter::streamed::<T>(bytes, false);
    let w = width();
    if lanes.is_empty() || lanes.len() > w {
        return 0;
    }
    let n_pad = w - lanes.len();
    let Some(law0) = lanes[0].law.ab_law() else {
        return 0;
    };
    if n_pad > 0 && pad.z.is_empty() {
        // h: the largest power of 2 <= min(1, max_gap) (exact times k h).
        let mut h = 1.0f64;
        while h > max_gap && h > f64::MIN_POSITIVE {
            h *= 0.5;
        }
        pad.z = vec![T::from_f64(0.0); PAD_STEPS];
        pad.t = (1..=PAD_STEPS).map(|k| k as f64 * h).collect();
        pad.out = vec![T::from_f64(0.0); 3 * (MAX_TRACK_LANES - 1) * PAD_STEPS];
    }
    let resid = lanes[0].out.resid.is_some();
    let mut done = 0;
    while done < steps {
        let chunk = if n_pad > 0 {
            (steps - done).min(PAD_STEPS)
        } else {
            steps - done
        };
        let mut vl: Vec<VLane<'_, T>> = Vec::with_capacity(w);
        for (l, &(x, v)) in lanes.iter_mut().zip(xv.iter()) {
            let k = l.k;
            let (Ok(zb), Ok(tb)) = (usize::try_from(l.zb), usize::try_from(l.tb)) else {
                return done;
            };
            let Some(law) = l.law.ab_law() else {
                return done;
            };
            let (Some(zs), Some(tt)) = (
                z.data.get(zb + k..zb + k + chunk),
                ts.data.get(tb + k..tb + k + chunk),
            ) else {
                return done;
            };
            let (s0, s1) = l.out.states.split_at_mut(1);
            let (Some(xs), Some(vs)) = (
                s0.first_mut().and_then(|s| s.get_mut(k..k + chunk)),
                s1.first_mut().and_then(|s| s.get_mut(k..k + chunk)),
            ) else {
                return done;
            };
            let rs = match l.out.resid.as_deref_mut() {
                Some(r) => match r.get_mut(k..k + chunk) {
                    Some(r) => Some(r),
                    None => return done,
                },
                None => None,
            };
            vl.push(VLane {
                z: zs,
                t: tt,
                xs,
                vs,
                rs,
                x,
                v,
                t_last: l.t_last,
                law,
            });
        }
        let mut outs = pad.out.chunks_exact_mut(PAD_STEPS);
        for _ in 0..n_pad {
            let (Some(xs), Some(vs), Some(rs)) = (outs.next(), outs.next(), outs.next()) else {
                return done;
            };
            vl.push(VLane {
                z: &pad.z[..chunk],
                t: &pad.t[..chunk],
                xs,
                vs,
                rs: if resid { Some(rs) } else { None },
                x: 0.0,
                v: 0.0,
                t_last: 0.0,
                law: law0,
            });
        }
        // Streamed only over long stretches: each call stores the part
        // lines at its ends with ordinary stores and fences (ragged fixed
        // gains, lengths 10..10,000, every stretch streamed: 443-450
        // Msamples/s, against 470-523 without; docs/benchmarks.md,
        // session 27).
        let d = run(&mut vl, chunk, max_gap, nt && chunk >= NT_MIN_STEPS);
        let mut res = [(0.0, 0.0, 0.0); MAX_TRACK_LANES];
        for (r, q) in res.iter_mut().zip(vl.iter()) {
            *r = (q.x, q.v, q.t_last);
        }
        drop(vl);
        if d > 0 {
            for ((l, xv), (x, v, tl)) in lanes.iter_mut().zip(xv.iter_mut()).zip(res) {
                l.k += d;
                l.t_last = tl;
                *xv = (x, v);
            }
        }
        done += d;
        if d < chunk {
            break;
        }
    }
    done
}

/// A running alpha-beta track in a lane of [`run_block_lanes`].
struct Lane<'a, T, L, const N: usize> {
    j: usize,
    k: usize,
    n: usize,
    zb: isize,
    tb: isize,
    x: f64,
    v: f64,
    t_last: f64,
    dt: f64,
    a: f64,
    g: f64,
    law: L,
    out: TrackOut<'a, T, N>,
    broken: bool,
}

/// One fast step of a lane; `false` (lane marked broken, nothing written)
/// when the sample needs the general code (bad, duplicate or gap step).
#[inline(always)]
fn lane_step<T: IoFloat, L: GainLaw<N, M>, const N: usize, const M: usize, const FMA: bool>(
    l: &mut Lane<'_, T, L, N>,
    xv: &mut (f64, f64),
    z: &Samples<'_, T>,
    t: Option<&Samples<'_, f64>>,
    max_gap: f64,
    t_nominal: f64,
) -> bool {
    let k = l.k;
    let dt = match t {
        Some(ts) => {
            let tk = ts.data[(l.tb + k as isize * ts.s_sample) as usize];
            let dt = tk - l.t_last;
            if !(dt > 0.0 && dt <= max_gap && dt < f64::INFINITY) {
                l.broken = true;
                return false;
            }
            l.t_last = tk;
            dt
        }
        None => t_nominal,
    };
    if dt != l.dt {
        let Some((a, g)) = l.law.ab_gains(dt) else {
            l.broken = true;
            return false;
        };
        (l.dt, l.a, l.g) = (dt, a, g);
    }
    let zk = z.data[(l.zb + k as isize * z.s_sample) as usize].to_f64();
    let (x1, v1, e) = ab_update::<FMA>(xv.0, xv.1, dt, l.a, l.g, zk);
    *xv = (x1, v1);
    let (s0, s1) = l.out.states.split_at_mut(1);
    s0[0][k] = T::from_f64(x1);
    s1[0][k] = T::from_f64(v1);
    if let Some(r) = l.out.resid.as_deref_mut() {
        r[k] = T::from_f64(e);
    }
    l.k = k + 1;
    true
}

/// Alpha-beta laws: start-up and every irregular sample through
/// [`track_tv`], the running stretches of up to [`AB_TRACK_LANES`] tracks
/// interleaved (independent dependency chains), with the same arithmetic
/// per track as [`track_tv`]'s fast path, so the result of a track does not
/// depend on its lane or neighbours.
fn run_block_lanes<
    T: IoFloat,
    L: GainLaw<N, M>,
    P: PostTrack<T, N>,
    const N: usize,
    const M: usize,
    const FMA: bool,
>(
    filt: &TrackFilter<'_, L, N, M>,
    opts: &Options,
    off: &[usize],
    z: &Samples<'_, T>,
    t: Option<&Samples<'_, f64>>,
    b: &mut Block<'_, T, N>,
    post: &P,
) -> Result<()> {
    let max_gap = opts.max_gap.unwrap_or(f64::INFINITY);
    let Block {
        i0,
        comps,
        resid,
        states,
        counts,
        ..
    } = b;
    let i0 = *i0;
    let n_block = states.len();
    let mut rest: [&mut [T]; N] = comps.each_mut().map(std::mem::take);
    let mut rest_r: Option<&mut [T]> = resid.as_deref_mut();
    // Vector lanes (0: none): alpha-beta laws they know, with timestamps,
    // stride-1 samples and FMA (their arithmetic is the FMA form).
    let vw = vector_width::<T, L, N, M, FMA>(&filt.laws[0], z, t);
    let n_lanes = if vw > 0 { vw } else { AB_TRACK_LANES };
    let mut lanes: Vec<Lane<'_, T, L, N>> = Vec::with_capacity(n_lanes);
    // Scratch tracks for the idle vector lanes (while fewer tracks than
    // lanes are left in the block).
    #[cfg(target_arch = "x86_64")]
    let mut pad = Pad::<T>::default();
    let mut next_j = 0;
    // Run the general code on track j from sample k0 until it is running
    // again (Some(lane state)) or done (None, post-processed).
    macro_rules! general {
        ($j:expr, $k0:expr, $law:expr, $out:expr) => {{
            let j = $j;
            let i = i0 + j;
            let n = off[i + 1] - off[i];
            let zb = z.addr(off[i]);
            let zf = |k: usize| -> [f64; M] {
                std::array::from_fn(|c| {
                    z.data[(zb + k as isize * z.s_sample + c as isize * z.s_comp) as usize].to_f64()
                })
            };
            let kk = match t {
                Some(ts) => {
                    let tb = ts.addr(off[i]);
                    let tf =
                        |k: usize| -> f64 { ts.data[(tb + k as isize * ts.s_sample) as usize] };
                    let kk = track_tv::<T, L, N, M, FMA>(
                        $law,
                        &filt.h,
                        &filt.h_pinv,
                        opts,
                        &mut states[j],
                        n,
                        zf,
                        Some(&tf),
                        $out,
                        &mut counts[j],
                        i,
                        $k0,
                        true,
                    )?;
                    if kk >= n {
                        post.post(i, &mut $out.states, Some(&tf), opts.max_gap)?;
                    }
                    kk
                }
                None => {
                    let kk = track_tv::<T, L, N, M, FMA>(
                        $law,
                        &filt.h,
                        &filt.h_pinv,
                        opts,
                        &mut states[j],
                        n,
                        zf,
                        None::<&fn(usize) -> f64>,
                        $out,
                        &mut counts[j],
                        i,
                        $k0,
                        true,
                    )?;
                    if kk >= n {
                        post.post(i, &mut $out.states, None, None)?;
                    }
                    kk
                }
            };
            kk
        }};
    }
    loop {
        // Fill the lanes with the next tracks (in order: their output
        // slices are peeled off the front of the block's buffers).
        while lanes.len() < n_lanes && next_j < n_block {
            let j = next_j;
            next_j += 1;
            let i = i0 + j;
            let n = off[i + 1] - off[i];
            let states_j: [&mut [T]; N] = std::array::from_fn(|c| {
                let r = std::mem::take(&mut rest[c]);
                let (a, bb) = r.split_at_mut(n.min(r.len()));
                rest[c] = bb;
                a
            });
            let resid_j = match rest_r.take() {
                Some(r) => {
                    let (a, bb) = r.split_at_mut((n * M).min(r.len()));
                    rest_r = Some(bb);
                    Some(a)
                }
                None => None,
            };
            let mut out = TrackOut {
                states: states_j,
                resid: resid_j,
            };
            let mut law = filt.laws[if filt.laws.len() == 1 { 0 } else { i }].clone();
            // A running track (continued with state=, or a segment of a
            // split track) goes to the lanes at once: the general code
            // would run all of it in its scalar loop. The lanes hand any
            // sample that is not a plain step back to the general code.
            let kk = if states[j].phase >= 2.0 && n > 0 {
                0
            } else {
                general!(j, 0, &mut law, &mut out)
            };
            if kk < n {
                let st = &states[j];
                lanes.push(Lane {
                    j,
                    k: kk,
                    n,
                    zb: z.addr(off[i]),
                    tb: t.map_or(0, |ts| ts.addr(off[i])),
                    x: st.x[0],
                    v: st.x[1],
                    t_last: st.t_last,
                    dt: f64::NAN,
                    a: 0.0,
                    g: 0.0,
                    law,
                    out,
                    broken: false,
                });
            }
        }
        if lanes.is_empty() {
            break;
        }
        if lanes.len() == n_lanes || vw > 0 {
            let steps = lanes.iter().map(|l| l.n - l.k).min().unwrap_or(0);
            // The chains' state in locals (registers), not in the lanes.
            let mut xv: [(f64, f64); MAX_TRACK_LANES] =
                std::array::from_fn(|q| lanes.get(q).map_or((0.0, 0.0), |l| (l.x, l.v)));
            let mut done = 0;
            'outer: while done < steps {
                if vw > 0 {
                    // Whole blocks of plain steps in the vector lanes.
                    #[cfg(target_arch = "x86_64")]
                    if let Some(ts) = t {
                        done += vector_steps(
                            &mut lanes,
                            &mut xv,
                            z,
                            ts,
                            steps - done,
                            max_gap,
                            &mut pad,
                        );
                    }
                    if done >= steps {
                        break;
                    }
                }
                // Scalar steps: the rest (no vector lanes), or up to one
                // block (the one the vector lanes left: it holds a step
                // that stops a lane, or is the tail).
                let lim = if vw > 0 {
                    (steps - done).min(vw)
                } else {
                    steps - done
                };
                for _ in 0..lim {
                    let mut ok = true;
                    for (l, xv) in lanes.iter_mut().zip(xv.iter_mut()) {
                        ok &= lane_step::<T, L, N, M, FMA>(l, xv, z, t, max_gap, opts.t_nominal);
                    }
                    if !ok {
                        break 'outer;
                    }
                    done += 1;
                }
            }
            for (l, xv) in lanes.iter_mut().zip(xv.iter()) {
                (l.x, l.v) = *xv;
            }
        } else {
            for l in lanes.iter_mut() {
                let mut xv = (l.x, l.v);
                while l.k < l.n
                    && lane_step::<T, L, N, M, FMA>(l, &mut xv, z, t, max_gap, opts.t_nominal)
                {
                }
                (l.x, l.v) = xv;
            }
        }
        // Lanes that ended or need the general code.
        let mut idx = 0;
        while idx < lanes.len() {
            let l = &mut lanes[idx];
            if l.k < l.n && !l.broken {
                idx += 1;
                continue;
            }
            let st = &mut states[l.j];
            st.x[0] = l.x;
            st.x[1] = l.v;
            st.t_last = l.t_last;
            if l.k >= l.n {
                // Done: the general code only stores and post-processes.
                let (j, n) = (l.j, l.n);
                let kk = general!(j, n, &mut l.law, &mut l.out);
                debug_assert!(kk >= n);
                lanes.swap_remove(idx);
                continue;
            }
            let (j, k0) = (l.j, l.k);
            let kk = general!(j, k0, &mut l.law, &mut l.out);
            if kk >= l.n {
                lanes.swap_remove(idx);
                continue;
            }
            let st = &states[l.j];
            l.k = kk;
            l.x = st.x[0];
            l.v = st.x[1];
            l.t_last = st.t_last;
            l.broken = false;
            idx += 1;
        }
    }
    Ok(())
}

/// One track of the time-varying kernel (see the module docs).
#[inline(always)]
pub(crate) fn track_tv<
    T: IoFloat,
    L: GainLaw<N, M>,
    const N: usize,
    const M: usize,
    const FMA: bool,
>(
    law: &mut L,
    h: &[[f64; N]; M],
    h_pinv: &[[f64; M]; N],
    opts: &Options,
    st: &mut TrackState,
    n: usize,
    z: impl Fn(usize) -> [f64; M],
    t: Option<&impl Fn(usize) -> f64>,
    out: &mut TrackOut<'_, T, N>,
    counts: &mut Counts,
    track: usize,
    k0: usize,
    lane_mode: bool,
) -> Result<usize> {
    let nan = T::from_f64(f64::NAN);
    let max_gap = opts.max_gap.unwrap_or(f64::INFINITY);
    let mut x: [f64; N] = std::array::from_fn(|i| st.x[i]);
    let mut phase = st.phase;
    // Step model cache for the last dt.
    let mut last_dt = f64::NAN;
    let mut step: Step<N, M> = Step {
        phi: [[0.0; N]; N],
        k: [[0.0; M]; N],
    };
    if t.is_none() {
        step = law
            .step(opts.t_nominal)
            .map_err(|e| data_err(track, 0, e))?;
        last_dt = opts.t_nominal;
    }
    let mut t_last = st.t_last;
    let mut res = Ok(());
    // Alpha-beta fast path state: gains of the last step.
    let is_ab = N == 2 && M == 1 && law.ab_gains(opts.t_nominal).is_some();
    let (mut ab_dt, mut ab_a, mut ab_g) = (f64::NAN, 0.0, 0.0);
    let mut k = k0;
    while k < n {
        if is_ab && phase >= 2.0 {
            if lane_mode && k > k0 {
                // Hand the running track to the lane driver (at `k0` itself
                // the sample that stopped the lane is processed first).
                st.x[..N].copy_from_slice(&x);
                st.phase = phase;
                st.t_last = t_last;
                return Ok(k);
            }
            // Running alpha-beta over samples with valid steps: the update
            // arranged as in the fixed-T kernel (two multiply-adds on the
            // dependency chain); anything else (bad or duplicate timestamp,
            // gap) falls through to the general code for that sample.
            let (mut xx, mut vv) = (x[0], x[1]);
            let (s0, s1) = out.states.split_at_mut(1);
            let (xs, vs) = (&mut s0[0][..n], &mut s1[0][..n]);
            let mut resid = out.resid.as_deref_mut().map(|r| &mut r[..n]);
            while k < n {
                let dt = match t {
                    Some(tf) => {
                        let tk = tf(k);
                        let dt = tk - t_last;
                        if !(dt > 0.0 && dt <= max_gap && dt < f64::INFINITY) {
                            break;
                        }
                        t_last = tk;
                        dt
                    }
                    None => opts.t_nominal,
                };
                if dt != ab_dt {
                    let Some((a, g)) = law
                        .ab_gains(dt)
                        .filter(|(a, g)| a.is_finite() && g.is_finite())
                    else {
                        break;
                    };
                    (ab_dt, ab_a, ab_g) = (dt, a, g);
                }
                let zk = z(k)[0];
                let (x1, v1, e) = ab_update::<FMA>(xx, vv, dt, ab_a, ab_g, zk);
                xx = x1;
                vv = v1;
                xs[k] = T::from_f64(xx);
                vs[k] = T::from_f64(vv);
                if let Some(r) = resid.as_deref_mut() {
                    r[k] = T::from_f64(e);
                }
                k += 1;
            }
            x[0] = xx;
            x[1] = vv;
            if k >= n {
                break;
            }
        }
        let k_now = k;
        k += 1;
        let k = k_now;
        let zk = z(k);
        let valid = zk.iter().all(|v| !v.is_nan());
        let mut dt = opts.t_nominal;
        let mut tk = f64::NAN;
        if let Some(tf) = t {
            tk = tf(k);
            if !tk.is_finite() {
                res = Err(Error::Data {
                    track,
                    sample: k,
                    msg: format!("t={tk} is not finite"),
                });
                break;
            }
            if !t_last.is_nan() {
                if tk <= t_last {
                    if opts.drop_duplicates {
                        counts[0] += 1;
                        for c in 0..N {
                            out.states[c][k] = nan;
                        }
                        if let Some(r) = out.resid.as_deref_mut() {
                            for j in 0..M {
                                r[k * M + j] = nan;
                            }
                        }
                        continue;
                    }
                    res = Err(Error::Data {
                        track,
                        sample: k,
                        msg: format!("t={tk} not after t={t_last} (use on_duplicate='drop' to drop such samples)"),
                    });
                    break;
                }
                dt = tk - t_last;
                if dt > max_gap && phase > 0.0 {
                    phase = 0.0;
                    counts[1] += 1;
                }
            }
            t_last = tk;
        }
        if phase >= 2.0 {
            if dt != last_dt {
                match law.step(dt) {
                    Ok(s) if step_is_finite(&s) => step = s,
                    Ok(_) => {
                        res = Err(Error::Data {
                            track,
                            sample: k,
                            msg: format!(
                                "t: the step dt={dt} gives a transition or gains beyond float64's range (overflow); rescale t"
                            ),
                        });
                        break;
                    }
                    Err(e) => {
                        res = Err(Error::Data {
                            track,
                            sample: k,
                            msg: format!("t: no gains for the step dt={dt}: {e}"),
                        });
                        break;
                    }
                }
                last_dt = dt;
            }
            let mut xp = [0.0; N];
            for i in 0..N {
                let mut s = 0.0;
                for j in 0..N {
                    s += step.phi[i][j] * x[j];
                }
                xp[i] = s;
            }
            let mut e = [0.0; M];
            for j in 0..M {
                let mut hx = 0.0;
                for i in 0..N {
                    hx += h[j][i] * xp[i];
                }
                e[j] = zk[j] - hx;
            }
            if valid {
                for i in 0..N {
                    let mut s = xp[i];
                    for j in 0..M {
                        s += step.k[i][j] * e[j];
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
            continue;
        }
        if let Some(r) = out.resid.as_deref_mut() {
            for j in 0..M {
                r[k * M + j] = nan;
            }
        }
        if phase == 0.0 {
            if !valid {
                for c in 0..N {
                    out.states[c][k] = nan;
                }
                continue;
            }
            for (i, xi) in x.iter_mut().enumerate() {
                *xi = (0..M).map(|j| h_pinv[i][j] * zk[j]).sum();
            }
            if opts.init == Init::First {
                phase = 2.0;
                for c in 0..N {
                    out.states[c][k] = T::from_f64(x[c]);
                }
            } else {
                phase = 1.0;
                st.since = 0.0;
                st.t_held = tk;
                out.states[0][k] = T::from_f64(x[0]);
                for c in 1..N {
                    out.states[c][k] = nan;
                }
            }
            continue;
        }
        // phase 1: holding the first valid position (two-point start).
        if !valid {
            st.since += 1.0;
            out.states[0][k] = T::from_f64(x[0]);
            for c in 1..N {
                out.states[c][k] = nan;
            }
            continue;
        }
        let gap = if t.is_some() && !st.t_held.is_nan() {
            tk - st.t_held
        } else {
            (st.since + 1.0) * opts.t_nominal
        };
        let p1 = x[0];
        let p2 = zk[0];
        x = [0.0; N];
        x[0] = p2;
        if N > 1 {
            x[1] = (p2 - p1) / gap;
        }
        phase = 2.0;
        st.since = 0.0;
        st.t_held = f64::NAN;
        for c in 0..N {
            out.states[c][k] = T::from_f64(x[c]);
        }
    }
    st.x[..N].copy_from_slice(&x);
    st.phase = phase;
    st.t_last = t_last;
    res.map(|()| n)
}

/// One running alpha-beta step over `dt` with gains `(a, g = beta/dt)`,
/// arranged as in the fixed-T kernel (two multiply-adds on the dependency
/// chain); a NaN `z` coasts. Returns `(x', v', residual or NaN)`.
#[inline(always)]
pub(crate) fn ab_update<const FMA: bool>(
    x: f64,
    v: f64,
    dt: f64,
    a: f64,
    g: f64,
    zk: f64,
) -> (f64, f64, f64) {
    let xp = crate::filter::madd::<FMA>(dt, v, x);
    let valid = !zk.is_nan();
    let e = if valid { zk - xp } else { f64::NAN };
    let zz = if valid { zk } else { 0.0 };
    let c1 = if valid { 1.0 - a } else { 1.0 };
    let g = if valid { g } else { 0.0 };
    let w = crate::filter::madd::<FMA>(g, zz, v);
    (
        crate::filter::madd::<FMA>(c1, xp, a * zz),
        crate::filter::madd::<FMA>(-g, xp, w),
        e,
    )
}

fn step_is_finite<const N: usize, const M: usize>(s: &Step<N, M>) -> bool {
    s.phi
        .iter()
        .flatten()
        .chain(s.k.iter().flatten())
        .all(|v| v.is_finite())
}

fn data_err(track: usize, sample: usize, e: Error) -> Error {
    Error::Data {
        track,
        sample,
        msg: format!("no gains for this step: {e}"),
    }
}

#[cfg(test)]
#[path = "tests/ragged.rs"]
mod tests;
