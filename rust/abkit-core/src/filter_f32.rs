//! Alpha-beta filtering of `f32` data in `f32` arithmetic.
//!
//! The default kernels filter `f32` data in `f64` arithmetic and round each
//! output once (the results are the `f64` results rounded). That keeps AVX2
//! CPUs compute bound on `f32` data (four `f64` slots per register, widening
//! and narrowing conversions: 0.3-0.5 of the `f32` memory ceiling;
//! docs/benchmarks.md, sessions 21-23). This module runs the same step in
//! `f32` arithmetic, eight slots per AVX2 register, which the memory keeps
//! up with.
//!
//! The step is `ab_step`'s in `f32` (`x_p = x + T v`,
//! `x' = (1 - alpha) x_p + alpha z`, `v' = (v + g2 z) - g2 x_p`, fused
//! multiply-adds where the CPU has them, a NaN `z` coasting), with the
//! constants `T`, `alpha`, `1 - alpha` and `g2 = beta / T` each computed in
//! `f64` and rounded once to `f32`. The start-up is [`super::run_track`]'s
//! (first valid sample; two-point velocity `(z2 - z1) / (gap T)`) in `f32`.
//! The state carried between calls holds `f32` values (exact in the `f64`
//! [`TrackState`]), so a track run in chunks is bit-identical to one call,
//! and every path (scalar loop, AVX2 rows) runs the same operations in the
//! same order: results are bit-identical whatever the thread count, the
//! batch a track is in or the chunking. The one exception is the default
//! kernels' too: a long track in a group of fewer than [`LANES`] tracks is
//! split into segments ([`split_fma`]), within `f32` rounding of the
//! unsplit run.
//!
//! Accuracy: each step rounds to `f32`, so the estimates drift from the
//! `f64`-arithmetic ones by about `0.3 / alpha` `f32` epsilons of the
//! array's scale (`bench/f32_arith_accuracy.py`, docs/benchmarks.md
//! session 22), against 0.5 ulp for the default kernels.
//!
//! Rows (`x86_64` with AVX2 and FMA): groups of [`LANES`] = 16 contiguous
//! rows in two 8-slot registers (`avx2::rows16`), blocks of 16 steps:
//! per register, two 8 x 8 transposes of the rows' `z` into a column stage,
//! the steps of both registers interleaved (two independent dependency
//! chains), then the outputs' columns transposed back into rows. Outputs
//! too big for the caches are written with non-temporal stores, each lane
//! first stepping to a sample whose `x` line starts a cache line (heads and
//! tails as vector steps of all lanes, each lane masked to its range).
//!
//! Ragged batches ([`filter_ab_f32_tracks`], the Arrow list layout without
//! timestamps): each track as it would run alone; the running tracks that
//! are not split go through the same row lanes, 16 tracks of similar
//! lengths at a time.
//!
//! Short contiguous rows (at most 768 samples) run straight from the batch
//! ([`short_batch`]: no per-track jobs; with streamed outputs through
//! stages of 16 rows drained as whole lines; the next group's rows
//! prefetched by the lanes): 100,000 x 100 went from 1.85 to 0.9 ns per
//! sample on an AVX-512 Xeon (docs/benchmarks.md, session 24).

use super::{Init, Job, Measurements, TrackOut, TrackState};
use crate::Result;

/// Tracks per group of the row kernel (two registers of eight slots).
pub const LANES: usize = 16;

// A split track's segments are the row kernel's lanes (the plan,
// `super::split_seg_len`, divides a track into `SPLIT_SEGMENTS`).
const _: () = assert!(LANES == super::SPLIT_SEGMENTS);

/// Steps per block of the row kernel (one 64-byte line of `f32` per lane).
const BLOCK: usize = 16;

/// Rows with fewer running samples than this run all their steps in the
/// column steps (no whole block). (64 until session 24, when the shorter
/// rows still ran scalar; with the column steps as the alternative, rows
/// of 50 from memory 2.4 -> 1.2 ns per sample with one block.)
const MIN_VECTOR_SAMPLES: usize = BLOCK;

/// Constants of one alpha-beta filter in `f32`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct C32 {
    pub(crate) t: f32,
    pub(crate) alpha: f32,
    pub(crate) c1: f32,
    pub(crate) g2: f32,
}

impl C32 {
    /// Each constant computed in `f64` and rounded once.
    pub(crate) fn new(alpha: f64, beta: f64, t: f64) -> Self {
        C32 {
            t: t as f32,
            alpha: alpha as f32,
            c1: (1.0 - alpha) as f32,
            g2: (beta / t) as f32,
        }
    }
}

#[inline(always)]
fn madd<const FMA: bool>(a: f32, b: f32, c: f32) -> f32 {
    if FMA {
        a.mul_add(b, c)
    } else {
        a * b + c
    }
}

/// One alpha-beta step in `f32` (the operations of `ab_step`):
/// returns `(x', v', residual)`; a NaN `z` coasts.
#[inline(always)]
pub(crate) fn step<const FMA: bool>(c: &C32, x: f32, v: f32, z: f32) -> (f32, f32, f32) {
    let xp = madd::<FMA>(c.t, v, x);
    let e = z - xp;
    let valid = !z.is_nan();
    let zz = if valid { z } else { 0.0 };
    let c1 = if valid { c.c1 } else { 1.0 };
    let g = if valid { c.g2 } else { 0.0 };
    let w = madd::<FMA>(g, zz, v);
    (madd::<FMA>(c1, xp, c.alpha * zz), madd::<FMA>(-g, xp, w), e)
}

/// Start-up of one track over its first samples (the logic of
/// [`super::run_track`] for alpha-beta, in `f32`): returns the number of
/// samples consumed; the track is running (`st.phase == 2`) from there
/// unless all `n` were consumed.
fn start(
    c: &C32,
    init: Init,
    st: &mut TrackState,
    n: usize,
    z: &impl Fn(usize) -> f32,
    o: &mut TrackOut<'_, f32, 2>,
) -> usize {
    let [xs, vs] = &mut o.states;
    let mut x0 = st.x[0] as f32;
    let mut k = 0;
    while st.phase < 2.0 && k < n {
        let zk = z(k);
        if let Some(r) = o.resid.as_deref_mut() {
            r[k] = f32::NAN;
        }
        let valid = !zk.is_nan();
        let (ox, ov) = match (st.phase == 0.0, valid) {
            (true, false) => (f32::NAN, f32::NAN),
            (true, true) => {
                x0 = zk;
                st.x[1] = 0.0;
                if init == Init::First {
                    st.phase = 2.0;
                    (zk, 0.0)
                } else {
                    st.phase = 1.0;
                    st.since = 0.0;
                    (zk, f32::NAN)
                }
            }
            (false, false) => {
                st.since += 1.0;
                (x0, f32::NAN)
            }
            (false, true) => {
                let gap = (st.since + 1.0) as f32;
                let v = (zk - x0) / (gap * c.t);
                x0 = zk;
                st.x[1] = v as f64;
                st.phase = 2.0;
                st.since = 0.0;
                (zk, v)
            }
        };
        xs[k] = ox;
        vs[k] = ov;
        st.x[0] = x0 as f64;
        k += 1;
    }
    k
}

/// Steady-state loop of one track over samples `k0..n`.
#[inline(always)]
fn run_loop<const FMA: bool>(
    c: &C32,
    st: &mut TrackState,
    k0: usize,
    n: usize,
    z: impl Fn(usize) -> f32,
    o: &mut TrackOut<'_, f32, 2>,
) {
    let (mut x, mut v) = (st.x[0] as f32, st.x[1] as f32);
    let [xs, vs] = &mut o.states;
    let (xs, vs) = (&mut xs[..n], &mut vs[..n]);
    match o.resid.as_deref_mut() {
        None => {
            for k in k0..n {
                let (x1, v1, _) = step::<FMA>(c, x, v, z(k));
                (x, v) = (x1, v1);
                xs[k] = x;
                vs[k] = v;
            }
        }
        Some(r) => {
            let r = &mut r[..n];
            for k in k0..n {
                let (x1, v1, e) = step::<FMA>(c, x, v, z(k));
                (x, v) = (x1, v1);
                xs[k] = x;
                vs[k] = v;
                r[k] = e;
            }
        }
    }
    st.x[0] = x as f64;
    st.x[1] = v as f64;
}

/// Alpha-beta filtering of a group of up to [`LANES`] tracks.
#[inline(always)]
fn group<const FMA: bool>(
    params: &[(f64, f64, f64)],
    init: Init,
    z: &Measurements<'_, f32>,
    jobs: &mut [Job<'_, f32, 2>],
    nt: bool,
) {
    let n = z.n_samples;
    let konst = |i: usize| {
        let (a, b, t) = params[if params.len() == 1 { 0 } else { i }];
        C32::new(a, b, t)
    };
    let zrow = |i: usize| z.row(i);
    let zat = |i: usize| move |k: usize| z.at(i, k, 0) as f32;
    let mut k0 = [0usize; LANES];
    for (l, (i, st, o)) in jobs.iter_mut().enumerate() {
        let c = konst(*i);
        let len = match zrow(*i) {
            Some(row) => start(&c, init, st, n, &|k| row[k], o),
            None => start(&c, init, st, n, &zat(*i), o),
        };
        if l < LANES {
            k0[l] = len;
        }
    }
    #[cfg(target_arch = "x86_64")]
    if FMA
        && jobs.len() == LANES
        && super::simd::avx2_available()
        && jobs.iter().enumerate().all(|(l, (i, st, o))| {
            st.phase == 2.0
                && o.resid.is_none()
                && zrow(*i).is_some()
                && n >= k0[l] + MIN_VECTOR_SAMPLES
        })
    {
        // SAFETY: `avx2_available()` checked AVX2 and FMA on this CPU.
        unsafe { rows_fma(&konst, &k0, n, z, jobs, nt) };
        return;
    }
    let few = jobs.len() < LANES;
    for (l, (i, st, o)) in jobs.iter_mut().enumerate() {
        if st.phase < 2.0 {
            continue;
        }
        let c = konst(*i);
        let from = if l < LANES { k0[l] } else { 0 };
        // A long track in a group too small for the row lanes: split it.
        #[cfg(target_arch = "x86_64")]
        if FMA && few && o.resid.is_none() && super::simd::avx2_available() {
            if let Some(row) = zrow(*i) {
                let (a, b, _) = params[if params.len() == 1 { 0 } else { *i }];
                if let Some(ls) = super::split_seg_len(a, b, n - from) {
                    let nt = super::streamed::<f32>(2 * n * 4, true);
                    // SAFETY: AVX2 and FMA checked; the row and outputs have
                    // n >= from + LANES * ls samples (the plan's segments).
                    unsafe { split_fma(&c, st, from, ls, row, o, nt) };
                    continue;
                }
            }
        }
        match zrow(*i) {
            Some(row) => run_loop::<FMA>(&c, st, from, n, |k| row[k], o),
            None => run_loop::<FMA>(&c, st, from, n, zat(*i), o),
        }
    }
}

/// The vector rows of a full group (see [`lanes_fma`]), the states taken
/// from and returned to the jobs.
///
/// # Safety
/// AVX2 and FMA are available; every job is running, has a contiguous `z`
/// row and no residuals, and `n >= k0[l] + MIN_VECTOR_SAMPLES`.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn rows_fma(
    konst: &impl Fn(usize) -> C32,
    k0: &[usize; LANES],
    n: usize,
    z: &Measurements<'_, f32>,
    jobs: &mut [Job<'_, f32, 2>],
    nt: bool,
) {
    let mut lanes: Vec<LaneJob<'_>> = jobs
        .iter_mut()
        .take(LANES)
        .enumerate()
        .map(|(l, (i, st, o))| {
            let [a, b] = &mut o.states;
            LaneJob {
                i: *i,
                k0: k0[l],
                st,
                row: z.row(*i).unwrap_or(&[]),
                x: &mut a[..n],
                v: &mut b[..n],
            }
        })
        .collect();
    // Rows up to NEXT_ROWS_MAX samples: the next group's rows (LANES rows
    // further on where the rows are evenly spaced; a prefetch past the batch
    // is harmless) fetched block by block at the offsets the lanes read.
    let next = if z.s_track > 0 && z.s_sample == 1 && n <= NEXT_ROWS_MAX {
        Next::Dist(LANES * z.s_track as usize)
    } else {
        Next::None
    };
    // SAFETY: forwarded (AVX2 and FMA).
    unsafe { lane_group(konst, &mut lanes, nt, next) };
}

/// Longest rows of a batch whose next group's rows the row lanes prefetch
/// (`rows_fma`); longer rows have the hardware prefetcher going long enough.
/// float32 arithmetic, 10^7 samples from memory, ns per sample, without ->
/// with: rows of 1,500 0.73-0.96 -> 0.59-0.64, 2,500 0.78 -> 0.56-0.61;
/// rows of 5,000 0.52 -> 0.56-0.60 and 10,000 0.50-0.54 -> 0.56-0.58 were
/// slower with it (docs/benchmarks.md, session 25).
const NEXT_ROWS_MAX: usize = 4096;

/// The rows [`lanes_fma`] prefetches block by block (at each block's
/// offset from the lanes' vector starts): none, every lane's row a fixed
/// distance further on (the next group of a batch of evenly spaced rows),
/// or given rows (the next group of a ragged batch, from their steady
/// starts).
#[derive(Clone, Copy)]
enum Next<'n> {
    None,
    Dist(usize),
    Rows(&'n [*const f32; LANES]),
}

/// [`LANES`] lanes, lane `l` stepping its states `x[l]`, `v[l]` over the
/// samples `k0[l]..` of its row `z[l]`, writing `xs[l]`, `vs[l]` (rows of a
/// batch, tracks of a ragged batch, or segments of one split track): each
/// lane steps to its vector start (with streamed outputs, a sample whose
/// `x` output starts a cache line; the `v` rows are streamed too where every
/// lane's `v` row lies at its `x` row's line offset, else stored with
/// ordinary stores, their lines fetched for ownership ahead: a ragged batch
/// of 10^7 samples whose `v` row starts 16 bytes into a line, 1.65 -> 0.74
/// ns per sample against dropping streaming for both; docs/benchmarks.md,
/// session 25), the lanes run whole blocks together, then each
/// its tail (heads and tails in [`avx2::column_steps`]: on rows of 100,
/// 2.0 -> 1.8 ns per sample against the lanes stepped one by one). A lane
/// whose row is shorter than `k0[l] + MIN_VECTOR_SAMPLES` makes every lane
/// run the column steps only (rows of 50: 3.4 -> 2.5 ns per sample against
/// the scalar steps, when the minimum was 64); outputs shorter than
/// `z[l]`, the scalar steps (same
/// results either way). Each block prefetches the `z` rows `next` names at
/// the block's offset (the next group's rows: [`Next`]).
///
/// # Safety
/// AVX2 and FMA are available.
#[cfg(target_arch = "x86_64")]
#[allow(clippy::too_many_arguments)]
#[target_feature(enable = "avx2,fma")]
unsafe fn lanes_fma(
    c: &[C32; LANES],
    x: &mut [f32; LANES],
    v: &mut [f32; LANES],
    k0: &[usize; LANES],
    z: [&[f32]; LANES],
    mut xs: [&mut [f32]; LANES],
    mut vs: [&mut [f32]; LANES],
    nt: bool,
    next: Next<'_>,
) {
    let len: [usize; LANES] = std::array::from_fn(|l| z[l].len());
    let fits =
        (0..LANES).all(|l| k0[l] <= len[l] && xs[l].len() >= len[l] && vs[l].len() >= len[l]);
    if !fits {
        steps(c, x, v, *k0, &len, &z, &mut xs, &mut vs);
        return;
    }
    let zr: [*const f32; LANES] = std::array::from_fn(|l| z[l].as_ptr());
    let xr: [*mut f32; LANES] = std::array::from_fn(|l| xs[l].as_mut_ptr());
    let vr: [*mut f32; LANES] = std::array::from_fn(|l| vs[l].as_mut_ptr());
    if (0..LANES).any(|l| len[l] < k0[l] + MIN_VECTOR_SAMPLES) {
        // Short rows: every step in the column steps (SAFETY: AVX2 and
        // FMA; lane l steps k0[l]..len[l], inside its rows, checked above).
        unsafe { avx2::column_steps(c, x, v, k0, &len, &zr, &xr, &vr) };
        return;
    }
    // Every lane's `x` row is streamed from a line-aligned sample; the `v`
    // rows only if they lie at the same line offsets as the `x` rows (else
    // ordinary stores for `v`).
    let nt_v = nt
        && (0..LANES).all(|l| {
            (vs[l].as_ptr() as usize)
                .wrapping_sub(xs[l].as_ptr() as usize)
                .is_multiple_of(64)
        });
    let mut p = *k0;
    if nt {
        for l in 0..LANES {
            let x0 = xs[l].as_ptr() as usize;
            while !(x0 + 4 * p[l]).is_multiple_of(64) {
                p[l] += 1;
            }
        }
    }
    // SAFETY (the three kernels below): AVX2 and FMA (this function's
    // features); lane l steps k0[l] <= p[l] <= p[l] + BLOCK * blocks <=
    // len[l], inside its rows, the outputs distinct rows; `nt` only with
    // `x` lines aligned at every lane's p[l] (stepped above) and `v` at the
    // same line offset.
    // The heads.
    unsafe { avx2::column_steps(c, x, v, k0, &p, &zr, &xr, &vr) };
    let blocks = (0..LANES)
        .map(|l| (len[l] - p[l]) / BLOCK)
        .min()
        .unwrap_or(0);
    let at = |q: &[*mut f32; LANES]| -> [*mut f32; LANES] {
        std::array::from_fn(|l| q[l].wrapping_add(p[l]))
    };
    let zp: [*const f32; LANES] = std::array::from_fn(|l| zr[l].wrapping_add(p[l]));
    let pf: Option<[*const f32; LANES]> = match next {
        Next::None => None,
        Next::Dist(d) => Some(std::array::from_fn(|l| zp[l].wrapping_add(d))),
        Next::Rows(r) => Some(*r),
    };
    unsafe {
        avx2::rows16(
            c,
            x,
            v,
            &zp,
            &at(&xr),
            &at(&vr),
            blocks,
            [nt, nt_v],
            pf.as_ref(),
        )
    };
    // The tails.
    let from: [usize; LANES] = std::array::from_fn(|l| p[l] + BLOCK * blocks);
    unsafe { avx2::column_steps(c, x, v, &from, &len, &zr, &xr, &vr) };
}

/// Scalar steps of [`LANES`] lanes, lane `l` over samples `from[l]..to[l]`,
/// the lanes interleaved step by step (the operations of [`run_loop`] per
/// lane).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn steps(
    c: &[C32; LANES],
    x: &mut [f32; LANES],
    v: &mut [f32; LANES],
    from: [usize; LANES],
    to: &[usize; LANES],
    z: &[&[f32]; LANES],
    xs: &mut [&mut [f32]; LANES],
    vs: &mut [&mut [f32]; LANES],
) {
    let most = (0..LANES)
        .map(|l| to[l].saturating_sub(from[l]))
        .max()
        .unwrap_or(0);
    for s in 0..most {
        for l in 0..LANES {
            let k = from[l] + s;
            if k < to[l] {
                let (x1, v1, _) = step::<true>(&c[l], x[l], v[l], z[l][k]);
                x[l] = x1;
                v[l] = v1;
                xs[l][k] = x1;
                vs[l][k] = v1;
            }
        }
    }
}

/// One long running track split into [`LANES`] segments of `ls` samples
/// from `k0` (the default kernels' split, `super::ab_split`, in `f32`):
/// pass 1 runs the segments in the vector lanes, segment 0 from the true
/// state, the others from a guess (position from the sample before the
/// segment, velocity zero); pass 2, in order, propagates each segment's
/// start-state error through the loop and adds it to the outputs until it
/// is below 2^-30 of the estimate (1/128 of a float32 epsilon), giving
/// each segment's true end state. The result agrees with the unsplit run
/// within float32 rounding (both within the documented drift of the float64
/// result), not bit for bit; the segmentation depends only on the length.
/// It runs where the AVX2 lanes do (elsewhere the track runs unsplit: the
/// same results within that rounding).
///
/// # Safety
/// AVX2 and FMA are available; `row` and the outputs have `n >= k0 +
/// LANES * ls` samples.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn split_fma(
    c: &C32,
    st: &mut TrackState,
    k0: usize,
    ls: usize,
    row: &[f32],
    o: &mut TrackOut<'_, f32, 2>,
    nt: bool,
) {
    let n = row.len();
    let body_end = k0 + LANES * ls;
    let mut x0 = [0f32; LANES];
    let mut v0 = [0f32; LANES];
    x0[0] = st.x[0] as f32;
    v0[0] = st.x[1] as f32;
    for j in 1..LANES {
        let prev = row[k0 + j * ls - 1];
        x0[j] = if prev.is_nan() { 0.0 } else { prev };
    }
    let (mut ex, mut ev) = (x0, v0);
    {
        let [a, b] = &mut o.states;
        let mut xc = a[k0..body_end].chunks_exact_mut(ls);
        let mut vc = b[k0..body_end].chunks_exact_mut(ls);
        let xs: [&mut [f32]; LANES] = std::array::from_fn(|_| xc.next().unwrap_or_default());
        let vs: [&mut [f32]; LANES] = std::array::from_fn(|_| vc.next().unwrap_or_default());
        let zs: [&[f32]; LANES] = std::array::from_fn(|j| &row[k0 + j * ls..k0 + (j + 1) * ls]);
        // SAFETY: forwarded (AVX2 and FMA).
        unsafe {
            lanes_fma(
                &[*c; LANES],
                &mut ex,
                &mut ev,
                &[0; LANES],
                zs,
                xs,
                vs,
                nt,
                Next::None,
            )
        };
    }
    // Pass 2: corrections, in order.
    let tiny = 2f32.powi(-30);
    let (mut true_x, mut true_v) = (ex[0], ev[0]);
    let [xo, vo] = &mut o.states;
    for j in 1..LANES {
        let (mut dx, mut dv) = (true_x - x0[j], true_v - v0[j]);
        let a = k0 + j * ls;
        let mut k = a;
        while k < a + ls && (dx != 0.0 || dv != 0.0) {
            // delta' = A delta (updated sample) or Phi delta (missed sample)
            let dp = c.t.mul_add(dv, dx);
            if row[k].is_nan() {
                dx = dp;
            } else {
                dx = c.c1 * dp;
                dv = (-c.g2).mul_add(dp, dv);
            }
            let xn = xo[k] + dx;
            let vn = vo[k] + dv;
            xo[k] = xn;
            vo[k] = vn;
            if dx.abs() + (dv * c.t).abs() <= tiny * (xn.abs() + (vn * c.t).abs()) {
                dx = 0.0;
                dv = 0.0;
            }
            k += 1;
        }
        true_x = ex[j] + dx;
        true_v = ev[j] + dv;
    }
    st.x[0] = true_x as f64;
    st.x[1] = true_v as f64;
    // The few samples after the last full segment.
    run_loop::<true>(c, st, body_end, n, |k| row[k], o);
}

/// Longest rows of [`short_batch`] (its stages: two of 16 rows per output,
/// 192 KiB at most). Against the per-track groups, from memory on an
/// AVX-512 Xeon: rows of 300 2.0 -> 0.93 ns per sample, 500 1.0-1.1 ->
/// 0.85, 800 0.94 -> 0.85; rows of 1,000 0.67 -> 0.79 (slower: left to
/// the groups; docs/benchmarks.md, session 24).
#[cfg(target_arch = "x86_64")]
const SHORT_MAX: usize = 768;

/// Short contiguous rows (at most [`SHORT_MAX`] samples, no residuals, a
/// CPU with AVX2 and FMA), [`LANES`] rows at a time straight from the
/// batch: each row's start-up, then the row lanes ([`lanes_fma`]) from each
/// row's first running sample. Without the per-track jobs of
/// [`super::run_batch`] (on rows of 100 their bookkeeping cost more than
/// the lanes). With streamed outputs the lanes write a stage of 16 rows per
/// output (in the caches; 16 rows are one contiguous region of the
/// outputs), which goes out as whole lines streamed past the caches
/// (`super::avx2::Drain`) after the lanes filled the other stage. The lanes
/// prefetch the next group's rows block by block, at the offsets they read
/// (rows of 100 from memory 1.03 -> 0.90 ns per sample against fetching the
/// whole group up front, which waited for free line-fill buffers). Rows
/// left over (fewer than [`LANES`] at the end of a chunk) run the scalar
/// loop.
/// The same operations as [`group`]: bit-identical to every other path.
/// `None` when it does not apply.
#[cfg(target_arch = "x86_64")]
#[allow(clippy::too_many_arguments)]
fn short_batch(
    params: &[(f64, f64, f64)],
    init: Init,
    z: &Measurements<'_, f32>,
    states: &mut [TrackState],
    out: &mut [f32],
    parallel: bool,
    nt: bool,
) -> Option<Result<()>> {
    let (n_tracks, n) = (z.n_tracks, z.n_samples);
    let total = n_tracks.checked_mul(n)?;
    if !(super::simd::avx2_available() && super::uses_fma())
        || z.m != 1
        || n == 0
        || n > SHORT_MAX
        || z.s_sample != 1
        || !(z.s_track == n as isize || n_tracks == 1)
        || states.len() != n_tracks
        || crate::planes::stride::<f32>(out.len(), 2, total, n).is_none()
    {
        return None;
    }
    let zs = z.data.get(z.base..z.base.checked_add(total)?)?;
    let (xs, vs) = crate::planes::split2(out, 2, total, n)?;
    // Chunks of whole tracks (the unit of parallel work), in whole groups.
    let per = super::row_chunk_tracks(n_tracks, n, parallel, LANES);
    let run = |j0: usize, st: &mut [TrackState], xs: &mut [f32], vs: &mut [f32]| {
        let zc = &zs[j0 * n..(j0 + st.len()) * n];
        // SAFETY: AVX2 and FMA (checked above); the chunk's rows and
        // outputs hold st.len() rows of n samples.
        unsafe { short_rows(params, j0, init, n, zc, st, xs, vs, nt) };
        Ok(())
    };
    Some(super::run_row_chunks(states, xs, vs, n, per, run))
}

/// One chunk of [`short_batch`]: tracks `j0..j0 + st.len()`, rows of `n`
/// samples back to back in `z`, `xs`, `vs`.
///
/// # Safety
/// AVX2 and FMA are available; `z`, `xs` and `vs`
/// hold `st.len()` rows of `n <= SHORT_MAX` samples.
#[cfg(target_arch = "x86_64")]
#[allow(clippy::too_many_arguments)]
#[target_feature(enable = "avx2,fma")]
unsafe fn short_rows(
    params: &[(f64, f64, f64)],
    j0: usize,
    init: Init,
    n: usize,
    z: &[f32],
    st: &mut [TrackState],
    xs: &mut [f32],
    vs: &mut [f32],
    nt: bool,
) {
    use super::avx2::Drain;
    let konst = |i: usize| {
        let (a, b, t) = params[if params.len() == 1 { 0 } else { i }];
        C32::new(a, b, t)
    };
    let seg = LANES * n;
    // Two stages of (x, v), each LANES rows.
    let mut stage = if nt { vec![0f32; 4 * seg] } else { Vec::new() };
    let mut drains: [Option<Drain<f32>>; 2] = [None, None];
    let mut cur = 0;
    let cn = st.len();
    let mut g0 = 0;
    while g0 < cn {
        let gl = (cn - g0).min(LANES);
        // The next group's rows (by the lanes) and states, a group ahead:
        // sixteen short rows defeat the hardware prefetcher.
        let ahead = if g0 + 2 * LANES <= cn { seg } else { 0 };
        if ahead > 0 {
            let sn = st.as_ptr().wrapping_add(g0 + LANES) as *const u8;
            for q in (0..LANES * std::mem::size_of::<TrackState>()).step_by(64) {
                super::prefetch(sn.wrapping_add(q));
            }
        }
        let rows = g0 * n..(g0 + gl) * n;
        let zg = &z[rows.clone()];
        let sts = &mut st[g0..g0 + gl];
        let (xd, vd): (&mut [f32], &mut [f32]) = if nt {
            let (a, b) = stage[2 * cur * seg..(2 * cur + 2) * seg].split_at_mut(seg);
            (&mut a[..gl * n], &mut b[..gl * n])
        } else {
            (&mut xs[rows.clone()], &mut vs[rows.clone()])
        };
        let mut c = [C32::new(0.5, 0.1, 1.0); LANES];
        let mut k0 = [n; LANES];
        let mut x = [0f32; LANES];
        let mut v = [0f32; LANES];
        {
            let mut xr = xd.chunks_exact_mut(n);
            let mut vr = vd.chunks_exact_mut(n);
            for (l, (s, zr)) in sts.iter_mut().zip(zg.chunks_exact(n)).enumerate() {
                c[l] = konst(j0 + g0 + l);
                let mut o = TrackOut {
                    states: [xr.next().unwrap_or_default(), vr.next().unwrap_or_default()],
                    resid: None,
                };
                k0[l] = start(&c[l], init, s, n, &|k| zr[k], &mut o);
                if gl < LANES && s.phase == 2.0 {
                    run_loop::<true>(&c[l], s, k0[l], n, |k| zr[k], &mut o);
                }
                x[l] = s.x[0] as f32;
                v[l] = s.x[1] as f32;
            }
        }
        if gl == LANES {
            let mut zr = zg.chunks_exact(n);
            let mut xr = xd.chunks_exact_mut(n);
            let mut vr = vd.chunks_exact_mut(n);
            let zl: [&[f32]; LANES] = std::array::from_fn(|_| zr.next().unwrap_or_default());
            let xl: [&mut [f32]; LANES] = std::array::from_fn(|_| xr.next().unwrap_or_default());
            let vl: [&mut [f32]; LANES] = std::array::from_fn(|_| vr.next().unwrap_or_default());
            // A row not running after its start-up consumed all n samples
            // (k0 = n): its lane takes no steps. SAFETY: forwarded.
            let next = if ahead > 0 {
                Next::Dist(ahead)
            } else {
                Next::None
            };
            // SAFETY: forwarded.
            unsafe { lanes_fma(&c, &mut x, &mut v, &k0, zl, xl, vl, false, next) };
            for (l, s) in sts.iter_mut().enumerate() {
                if s.phase == 2.0 {
                    s.x[0] = x[l] as f64;
                    s.x[1] = v[l] as f64;
                }
            }
        }
        if nt {
            let src = stage[2 * cur * seg..].as_ptr();
            // SAFETY: AVX2 (this function's features); the stage `cur` is
            // not written again until its drain finished (the next call of
            // `follow` on the same slot finishes it, before the stage is
            // reused two groups later); the outputs are not otherwise
            // accessed meanwhile.
            unsafe {
                let [dx, dv] = &mut drains;
                let nx = Drain::follow(dx, &mut xs[rows.clone()], src);
                let nv = Drain::follow(dv, &mut vs[rows], src.add(seg));
                drains = [Some(nx), Some(nv)];
            }
            cur ^= 1;
        }
        g0 += gl;
    }
    if nt {
        // SAFETY: AVX2.
        unsafe {
            for d in drains.iter_mut().flatten() {
                d.finish();
            }
        }
        super::store_fence();
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "fma")]
fn group_fma(
    params: &[(f64, f64, f64)],
    init: Init,
    z: &Measurements<'_, f32>,
    jobs: &mut [Job<'_, f32, 2>],
    nt: bool,
) {
    group::<true>(params, init, z, jobs, nt)
}

fn group_dispatch(
    params: &[(f64, f64, f64)],
    init: Init,
    z: &Measurements<'_, f32>,
    jobs: &mut [Job<'_, f32, 2>],
    nt: bool,
) {
    #[cfg(target_arch = "x86_64")]
    {
        if super::uses_fma() {
            // SAFETY: the CPU supports FMA (checked at run time by `uses_fma`).
            unsafe { group_fma(params, init, z, jobs, nt) };
            return;
        }
        group::<false>(params, init, z, jobs, nt)
    }
    #[cfg(target_arch = "aarch64")]
    {
        group::<true>(params, init, z, jobs, nt)
    }
    #[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
    {
        group::<false>(params, init, z, jobs, nt)
    }
}

/// The constants must be float32 numbers (a period beyond float32's range
/// would round to infinity or zero: silently meaningless output).
fn check_f32(params: &[(f64, f64, f64)]) -> Result<()> {
    for &(a, b, t) in params {
        let c = C32::new(a, b, t);
        if !(c.t.is_finite() && c.t > 0.0) {
            return Err(crate::Error::domain("T", "finite and > 0 in float32", t));
        }
        for (name, v, w) in [("alpha", a, c.alpha), ("beta / T", b / t, c.g2)] {
            if !(w.is_finite() && c.c1.is_finite()) {
                return Err(crate::Error::domain(name, "finite in float32", v));
            }
        }
    }
    Ok(())
}

/// Filter a batch of `f32` measurements with alpha-beta filters in `f32`
/// arithmetic (`params[i] = (alpha, beta, T)`, one for all tracks or one
/// per track). Same arguments and layout as [`super::filter_ab`] (no
/// smoother).
pub fn filter_ab_f32(
    params: &[(f64, f64, f64)],
    init: Init,
    z: &Measurements<'_, f32>,
    states: &mut [TrackState],
    out: &mut [f32],
    resid: Option<&mut [f32]>,
    parallel: bool,
) -> Result<()> {
    super::check_ab(params, z)?;
    check_f32(params)?;
    let nt = super::streamed::<f32>(2 * z.n_tracks * z.n_samples * 4, true);
    #[cfg(target_arch = "x86_64")]
    if resid.is_none() {
        if let Some(r) = short_batch(params, init, z, states, out, parallel, nt) {
            return r;
        }
    }
    super::run_batch::<f32, 2>(
        z.n_tracks,
        z.n_samples,
        1,
        states,
        out,
        resid,
        parallel,
        LANES,
        |jobs| group_dispatch(params, init, z, jobs, nt),
    )
}

/// Samples of a block of consecutive tracks of [`filter_ab_f32_tracks`]
/// (at least; the unit of parallel work of the start-ups, splits and
/// scalar tracks).
/// (Small in the unit tests, so that they run many blocks.)
const TRACKS_BLOCK_SAMPLES: usize = if cfg!(test) { 4096 } else { 1 << 20 };

/// A ragged batch of `f32` tracks in `f32` arithmetic (the Arrow list
/// layout of [`crate::ragged`], no timestamps): track `i` is flat samples
/// `offsets[i]..offsets[i + 1]` of `z`, its outputs the same samples of the
/// rows `x = out[..N]`, `v = out[N..]` (and of `resid`). Each track gives
/// the bits of that track alone through [`filter_ab_f32`] (start-up, then
/// a long running track split as there, otherwise the steady loop), so the
/// result does not depend on the other tracks, the blocking or the thread
/// count. Tracks in blocks of consecutive tracks (about
/// [`TRACKS_BLOCK_SAMPLES`] samples) on rayon's pool: start-ups, splits,
/// and (with residuals, strided `z` or no AVX2) the scalar loop; then the
/// running tracks of up to [`PHASE_TRACKS`] tracks at a time that are not
/// split, sorted by length, go through the AVX2 row lanes ([`lanes_fma`],
/// bit-identical to the loop) [`LANES`] at a time ([`lane_phase`]).
#[allow(clippy::too_many_arguments)]
pub fn filter_ab_f32_tracks<'a>(
    params: &[(f64, f64, f64)],
    init: Init,
    offsets: &[i64],
    z: &crate::ragged::Samples<'a, f32>,
    states: &'a mut [TrackState],
    out: &'a mut [f32],
    resid: Option<&'a mut [f32]>,
    parallel: bool,
) -> Result<()> {
    use crate::Error;
    use rayon::prelude::*;
    let n_total = z.len();
    if z.m != 1 {
        return Err(Error::Shape(format!(
            "alpha-beta needs scalar measurements, got {}",
            z.m
        )));
    }
    z.validate("measurement")?;
    let off = crate::ragged::check_offsets(offsets, n_total, z.row_len, z.n_rows)?;
    let n_tracks = off.len() - 1;
    if states.len() != n_tracks {
        return Err(Error::Shape(format!(
            "{} states for {n_tracks} tracks",
            states.len()
        )));
    }
    if !(params.len() == 1 || params.len() == n_tracks) {
        return Err(Error::Shape(format!(
            "{} parameter sets for {n_tracks} tracks",
            params.len()
        )));
    }
    super::check_ab_params(params)?;
    check_f32(params)?;
    if crate::planes::stride::<f32>(out.len(), 2, n_total, 0).is_none()
        || resid.as_ref().is_some_and(|r| r.len() != n_total)
    {
        return Err(Error::Shape(format!(
            "outputs of {} / residuals of {:?} elements for {n_total} samples",
            out.len(),
            resid.as_ref().map(|r| r.len())
        )));
    }
    if n_total == 0 {
        return Ok(());
    }
    let flat = (z.s_sample == 1 && (z.n_rows <= 1 || z.s_row == z.row_len as isize))
        .then(|| z.data.get(z.base..z.base + n_total))
        .flatten();
    let rg = Ragged {
        params,
        init,
        off: &off,
        z,
        flat,
    };
    let nt = super::streamed::<f32>(2 * n_total * 4, true);
    let Some((xs, vs)) = crate::planes::split2(out, 2, n_total, 0) else {
        return Err(Error::Shape("output planes".into()));
    };
    let threads = if parallel {
        rayon::current_num_threads()
    } else {
        1
    };
    let target = (n_total / (4 * threads)).max(TRACKS_BLOCK_SAMPLES);
    let mut blocks: Vec<Block<'a>> = Vec::new();
    let (mut st_rest, mut o_rest) = (states, (xs, vs, resid));
    let mut j0 = 0;
    while j0 < n_tracks {
        let mut j1 = j0 + 1;
        while j1 < n_tracks && off[j1] - off[j0] < target && j1 - j0 < PHASE_TRACKS {
            j1 += 1;
        }
        let (st, rest) = std::mem::take(&mut st_rest).split_at_mut(j1 - j0);
        let out = split_outs(&mut o_rest, off[j1] - off[j0]);
        blocks.push(Block { j0, st, out });
        st_rest = rest;
        j0 = j1;
    }
    let run = |b: Block<'a>| tracks_block_dispatch(&rg, b);
    let konst = |i: usize| rg.konst(i);
    // Phases of consecutive blocks of at most PHASE_TRACKS tracks (bounds
    // the lane jobs held at a time): the blocks, then their lane jobs.
    let mut blocks = blocks.into_iter().peekable();
    while blocks.peek().is_some() {
        let mut phase: Vec<Block<'a>> = Vec::new();
        let mut tracks = 0;
        while let Some(b) =
            blocks.next_if(|b| phase.is_empty() || tracks + b.st.len() <= PHASE_TRACKS)
        {
            tracks += b.st.len();
            phase.push(b);
        }
        let lanes: Vec<Vec<LaneJob<'a>>> = if parallel && phase.len() > 1 {
            phase.into_par_iter().map(run).collect()
        } else {
            phase.into_iter().map(run).collect()
        };
        let mut lanes: Vec<LaneJob<'a>> = lanes.into_iter().flatten().collect();
        #[cfg(target_arch = "x86_64")]
        lane_phase(&konst, &mut lanes, nt, parallel);
        // Lane jobs exist only where the row lanes run.
        debug_assert!(lanes.is_empty() || cfg!(target_arch = "x86_64"));
    }
    Ok(())
}

/// Most tracks of a block of [`filter_ab_f32_tracks`], and of the blocks
/// whose lane jobs it sorts and runs at a time (the jobs take 72 bytes
/// per track: at most 19 MB).
/// (Small in the unit tests, so that they run many phases.)
const PHASE_TRACKS: usize = if cfg!(test) { 48 } else { 1 << 18 };

/// The lane jobs of a phase of [`filter_ab_f32_tracks`]: sorted longest
/// first, so that each group's lanes end close together (their tails in
/// the column steps are short) and the few left over (run by the loop)
/// are the shortest; groups of [`LANES`] in tasks of 16 groups on rayon's
/// pool, each group prefetching the next group's rows.
#[cfg(target_arch = "x86_64")]
fn lane_phase(
    konst: &(impl Fn(usize) -> C32 + Sync),
    lanes: &mut [LaneJob<'_>],
    nt: bool,
    parallel: bool,
) {
    use rayon::prelude::*;
    if lanes.is_empty() {
        return;
    }
    lanes.sort_by_key(|j| std::cmp::Reverse(j.row.len() - j.k0));
    let full = lanes.len() / LANES * LANES;
    let (groups, rest) = lanes.split_at_mut(full);
    let task = |chunk: &mut [LaneJob<'_>]| {
        for g in 0..chunk.len() / LANES {
            // The next group's rows (elsewhere in the batch), from their
            // steady starts, fetched by the lanes block by block.
            let next: Option<[*const f32; LANES]> = chunk
                .get((g + 1) * LANES..(g + 2) * LANES)
                .map(|nx| std::array::from_fn(|l| nx[l].row.as_ptr().wrapping_add(nx[l].k0)));
            let next = next.as_ref().map_or(Next::None, Next::Rows);
            let grp = &mut chunk[g * LANES..(g + 1) * LANES];
            // SAFETY: lane jobs exist only where AVX2 and FMA are available
            // (`tracks_block`).
            unsafe { lane_group(konst, grp, nt, next) };
        }
        super::store_fence();
    };
    if parallel && groups.len() > 16 * LANES {
        groups.par_chunks_mut(16 * LANES).for_each(task);
    } else {
        task(groups);
    }
    for j in rest {
        // SAFETY: as above.
        unsafe { lane_loop(&konst(j.i), j) };
    }
}

/// A running track for the vector lanes (of a batch's group, `rows_fma`, or
/// left by [`tracks_block`] of a ragged batch): track `i`, its steady state
/// from sample `k0` of `row`, its outputs `x`, `v` (the whole track).
struct LaneJob<'a> {
    i: usize,
    k0: usize,
    st: &'a mut TrackState,
    row: &'a [f32],
    x: &'a mut [f32],
    v: &'a mut [f32],
}

/// [`LANES`] lane jobs through [`lanes_fma`] (their states taken from and
/// returned to the jobs), prefetching the rows `next` (the next group's)
/// as it goes.
///
/// # Safety
/// AVX2 and FMA are available.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn lane_group(
    konst: &impl Fn(usize) -> C32,
    grp: &mut [LaneJob<'_>],
    nt: bool,
    next: Next<'_>,
) {
    let mut c = [C32::new(0.5, 0.1, 1.0); LANES];
    let mut x = [0f32; LANES];
    let mut v = [0f32; LANES];
    let mut k0 = [0usize; LANES];
    let mut rows: [&[f32]; LANES] = [&[]; LANES];
    let mut xl: [&mut [f32]; LANES] = std::array::from_fn(|_| -> &mut [f32] { &mut [] });
    let mut vl: [&mut [f32]; LANES] = std::array::from_fn(|_| -> &mut [f32] { &mut [] });
    for (l, j) in grp.iter_mut().enumerate().take(LANES) {
        c[l] = konst(j.i);
        x[l] = j.st.x[0] as f32;
        v[l] = j.st.x[1] as f32;
        k0[l] = j.k0;
        rows[l] = j.row;
        xl[l] = std::mem::take(&mut j.x);
        vl[l] = std::mem::take(&mut j.v);
    }
    // SAFETY: forwarded (AVX2 and FMA).
    unsafe { lanes_fma(&c, &mut x, &mut v, &k0, rows, xl, vl, nt, next) };
    for (l, j) in grp.iter_mut().enumerate().take(LANES) {
        j.st.x[0] = x[l] as f64;
        j.st.x[1] = v[l] as f64;
    }
}

/// One lane job in the scalar loop.
///
/// # Safety
/// FMA is available.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "fma")]
unsafe fn lane_loop(c: &C32, j: &mut LaneJob<'_>) {
    let row = j.row;
    let mut o = TrackOut {
        states: [std::mem::take(&mut j.x), std::mem::take(&mut j.v)],
        resid: None,
    };
    run_loop::<true>(c, j.st, j.k0, row.len(), |k| row[k], &mut o);
}

/// The outputs `(x, v, residuals)` of consecutive samples of a ragged batch.
type Outs<'a> = (&'a mut [f32], &'a mut [f32], Option<&'a mut [f32]>);

/// The first `len` samples of `rest` split off it.
fn split_outs<'a>(rest: &mut Outs<'a>, len: usize) -> Outs<'a> {
    let (x, xr) = std::mem::take(&mut rest.0).split_at_mut(len);
    let (v, vr) = std::mem::take(&mut rest.1).split_at_mut(len);
    let (r, rr) = match rest.2.take() {
        Some(r) => {
            let (a, b) = r.split_at_mut(len);
            (Some(a), Some(b))
        }
        None => (None, None),
    };
    *rest = (xr, vr, rr);
    (x, v, r)
}

/// What every block of one [`filter_ab_f32_tracks`] call reads.
struct Ragged<'c, 'a> {
    params: &'c [(f64, f64, f64)],
    init: Init,
    /// Track offsets (flat sample indices, one more than tracks).
    off: &'c [usize],
    /// The measurements, any strides.
    z: &'c crate::ragged::Samples<'a, f32>,
    /// The flat samples as one slice where they are contiguous.
    flat: Option<&'a [f32]>,
}

impl Ragged<'_, '_> {
    /// Track `i`'s `(alpha, beta, T)`.
    fn params(&self, i: usize) -> (f64, f64, f64) {
        self.params[if self.params.len() == 1 { 0 } else { i }]
    }

    /// Track `i`'s constants.
    fn konst(&self, i: usize) -> C32 {
        let (a, b, t) = self.params(i);
        C32::new(a, b, t)
    }

    /// Flat sample `g`.
    #[inline(always)]
    fn at(&self, g: usize) -> f32 {
        self.z.data[self.z.addr(g) as usize]
    }
}

/// Consecutive tracks `j0..j0 + st.len()` of a ragged batch: their states
/// and their samples of the outputs.
struct Block<'a> {
    j0: usize,
    st: &'a mut [TrackState],
    out: Outs<'a>,
}

fn tracks_block_dispatch<'a>(r: &Ragged<'_, 'a>, b: Block<'a>) -> Vec<LaneJob<'a>> {
    #[cfg(target_arch = "x86_64")]
    {
        if super::uses_fma() {
            // SAFETY: the CPU supports FMA (checked at run time by `uses_fma`).
            return unsafe { tracks_block_fma(r, b) };
        }
        tracks_block::<false>(r, b)
    }
    #[cfg(target_arch = "aarch64")]
    {
        tracks_block::<true>(r, b)
    }
    #[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
    {
        tracks_block::<false>(r, b)
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "fma")]
fn tracks_block_fma<'a>(r: &Ragged<'_, 'a>, b: Block<'a>) -> Vec<LaneJob<'a>> {
    tracks_block::<true>(r, b)
}

/// One block of [`filter_ab_f32_tracks`]. Each track as [`group`] runs a
/// group of one: the start-up, then (with FMA, AVX2, no residuals and a
/// contiguous row) the split of a long run, else the loop; the loop's
/// tracks are returned for the vector lanes (the same operations) where
/// they run, else run here.
#[inline(always)]
fn tracks_block<'a, const FMA: bool>(r: &Ragged<'_, 'a>, b: Block<'a>) -> Vec<LaneJob<'a>> {
    let Block { j0, st, out } = b;
    let init = r.init;
    let mut lanes: Vec<LaneJob<'a>> = Vec::new();
    #[cfg(target_arch = "x86_64")]
    let vector = FMA && super::simd::avx2_available() && out.2.is_none() && r.flat.is_some();
    #[cfg(not(target_arch = "x86_64"))]
    let vector = false;
    // Each track's output slices, split off the block's as it goes.
    let mut o_rest = out;
    for (j, s) in st.iter_mut().enumerate() {
        let i = j0 + j;
        let (g0, len) = (r.off[i], r.off[i + 1] - r.off[i]);
        let (x, v, res) = split_outs(&mut o_rest, len);
        let c = r.konst(i);
        let mut o = TrackOut {
            states: [x, v],
            resid: res,
        };
        let row = r.flat.map(|f| &f[g0..g0 + len]);
        let k0 = match row {
            Some(z) => start(&c, init, s, len, &|k| z[k], &mut o),
            None => start(&c, init, s, len, &|k| r.at(g0 + k), &mut o),
        };
        if s.phase < 2.0 || k0 >= len {
            continue;
        }
        #[cfg(target_arch = "x86_64")]
        if vector {
            if let Some(z) = row {
                let (a, b, _) = r.params(i);
                if let Some(ls) = super::split_seg_len(a, b, len - k0) {
                    let nt1 = super::streamed::<f32>(2 * len * 4, true);
                    // SAFETY: AVX2 and FMA (`vector`); the row and outputs
                    // have len >= k0 + LANES * ls samples (the plan's
                    // segments).
                    unsafe { split_fma(&c, s, k0, ls, z, &mut o, nt1) };
                } else {
                    let [x, v] = o.states;
                    lanes.push(LaneJob {
                        i,
                        k0,
                        st: s,
                        row: z,
                        x,
                        v,
                    });
                }
                continue;
            }
        }
        match row {
            Some(z) => run_loop::<FMA>(&c, s, k0, len, |k| z[k], &mut o),
            None => run_loop::<FMA>(&c, s, k0, len, |k| r.at(g0 + k), &mut o),
        }
    }
    // The split's streamed stores, before the outputs are read.
    super::store_fence();
    lanes
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::{BLOCK, C32, LANES};
    use std::arch::x86_64::*;

    /// In-place transpose of the 8 x 8 matrix whose rows are `r`.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn tr8(r: &mut [__m256; 8]) {
        let t0 = _mm256_unpacklo_ps(r[0], r[1]);
        let t1 = _mm256_unpackhi_ps(r[0], r[1]);
        let t2 = _mm256_unpacklo_ps(r[2], r[3]);
        let t3 = _mm256_unpackhi_ps(r[2], r[3]);
        let t4 = _mm256_unpacklo_ps(r[4], r[5]);
        let t5 = _mm256_unpackhi_ps(r[4], r[5]);
        let t6 = _mm256_unpacklo_ps(r[6], r[7]);
        let t7 = _mm256_unpackhi_ps(r[6], r[7]);
        let s0 = _mm256_shuffle_ps::<0x44>(t0, t2);
        let s1 = _mm256_shuffle_ps::<0xEE>(t0, t2);
        let s2 = _mm256_shuffle_ps::<0x44>(t1, t3);
        let s3 = _mm256_shuffle_ps::<0xEE>(t1, t3);
        let s4 = _mm256_shuffle_ps::<0x44>(t4, t6);
        let s5 = _mm256_shuffle_ps::<0xEE>(t4, t6);
        let s6 = _mm256_shuffle_ps::<0x44>(t5, t7);
        let s7 = _mm256_shuffle_ps::<0xEE>(t5, t7);
        r[0] = _mm256_permute2f128_ps::<0x20>(s0, s4);
        r[1] = _mm256_permute2f128_ps::<0x20>(s1, s5);
        r[2] = _mm256_permute2f128_ps::<0x20>(s2, s6);
        r[3] = _mm256_permute2f128_ps::<0x20>(s3, s7);
        r[4] = _mm256_permute2f128_ps::<0x31>(s0, s4);
        r[5] = _mm256_permute2f128_ps::<0x31>(s1, s5);
        r[6] = _mm256_permute2f128_ps::<0x31>(s2, s6);
        r[7] = _mm256_permute2f128_ps::<0x31>(s3, s7);
    }

    /// The 16 values of `a` in two registers (lanes 0..8 and 8..16).
    #[inline]
    #[target_feature(enable = "avx2")]
    fn load16(a: &[f32; LANES]) -> [__m256; 2] {
        // SAFETY: `a` holds 16 f32.
        unsafe {
            [
                _mm256_loadu_ps(a.as_ptr()),
                _mm256_loadu_ps(a.as_ptr().add(8)),
            ]
        }
    }

    /// [`load16`]'s inverse.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn store16(a: &mut [f32; LANES], r: [__m256; 2]) {
        // SAFETY: `a` holds 16 f32.
        unsafe {
            _mm256_storeu_ps(a.as_mut_ptr(), r[0]);
            _mm256_storeu_ps(a.as_mut_ptr().add(8), r[1]);
        }
    }

    /// One register's constants.
    #[derive(Clone, Copy)]
    struct K {
        t: __m256,
        alpha: __m256,
        c1: __m256,
        g2: __m256,
    }

    /// A step without missed samples: [`super::step`]'s operations with
    /// `valid` true in every slot.
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    fn clean(k: &K, x: &mut __m256, v: &mut __m256, z: __m256) {
        let xp = _mm256_fmadd_ps(k.t, *v, *x);
        let w = _mm256_fmadd_ps(k.g2, z, *v);
        *x = _mm256_fmadd_ps(k.c1, xp, _mm256_mul_ps(k.alpha, z));
        // -(g2 xp) + w rounded once: the scalar fma(-g2, xp, w).
        *v = _mm256_fnmadd_ps(k.g2, xp, w);
    }

    /// A step where some `z` may be NaN: [`super::step`]'s selects.
    #[inline]
    #[target_feature(enable = "avx2,fma")]
    fn masked(k: &K, one: __m256, x: &mut __m256, v: &mut __m256, z: __m256) {
        let xp = _mm256_fmadd_ps(k.t, *v, *x);
        let ok = _mm256_cmp_ps::<_CMP_ORD_Q>(z, z);
        let zz = _mm256_and_ps(z, ok);
        let c1 = _mm256_blendv_ps(one, k.c1, ok);
        let g = _mm256_and_ps(k.g2, ok);
        let w = _mm256_fmadd_ps(g, zz, *v);
        *x = _mm256_fmadd_ps(c1, xp, _mm256_mul_ps(k.alpha, zz));
        *v = _mm256_fnmadd_ps(g, xp, w);
    }

    /// Steps of the [`LANES`] lanes, lane `l` over samples `from[l]..to[l]`
    /// of its rows `z[l]`, `xo[l]`, `vo[l]`, in vector form: step `s`
    /// updates the lanes with `from[l] + s < to[l]` ([`masked`]: the
    /// scalar step's operations, a NaN coasting) and keeps the others'
    /// states (a blend), so every lane gets exactly its scalar steps. The
    /// heads and tails of [`super::lanes_fma`].
    ///
    /// # Safety
    /// AVX2 and FMA are available; `z[l]`, `xo[l]` and `vo[l]` are valid for
    /// `to[l]` elements (outputs distinct from each other and the inputs);
    /// `from[l] <= to[l]`.
    #[allow(clippy::too_many_arguments)]
    #[target_feature(enable = "avx2,fma")]
    pub(super) unsafe fn column_steps(
        c: &[C32; LANES],
        x: &mut [f32; LANES],
        v: &mut [f32; LANES],
        from: &[usize; LANES],
        to: &[usize; LANES],
        z: &[*const f32; LANES],
        xo: &[*mut f32; LANES],
        vo: &[*mut f32; LANES],
    ) {
        let most = (0..LANES)
            .map(|l| to[l].saturating_sub(from[l]))
            .max()
            .unwrap_or(0);
        if most == 0 {
            return;
        }
        let k0 = konsts(c, 0);
        let k1 = konsts(c, 1);
        let one = _mm256_set1_ps(1.0);
        let [mut x0, mut x1] = load16(x);
        let [mut v0, mut v1] = load16(v);
        let mut zc = [0f32; LANES];
        let mut act = [0f32; LANES];
        let mut ox = [0f32; LANES];
        let mut ov = [0f32; LANES];
        for s in 0..most {
            for l in 0..LANES {
                let k = from[l] + s;
                let on = k < to[l];
                // SAFETY: k < to[l] (the caller's contract).
                zc[l] = if on { unsafe { *z[l].add(k) } } else { 0.0 };
                // All bits set: the lane steps (blendv reads the sign).
                act[l] = f32::from_bits(if on { u32::MAX } else { 0 });
            }
            let [za, zb] = load16(&zc);
            let [ma, mb] = load16(&act);
            let (mut xa, mut va, mut xb, mut vb) = (x0, v0, x1, v1);
            masked(&k0, one, &mut xa, &mut va, za);
            masked(&k1, one, &mut xb, &mut vb, zb);
            x0 = _mm256_blendv_ps(x0, xa, ma);
            v0 = _mm256_blendv_ps(v0, va, ma);
            x1 = _mm256_blendv_ps(x1, xb, mb);
            v1 = _mm256_blendv_ps(v1, vb, mb);
            store16(&mut ox, [x0, x1]);
            store16(&mut ov, [v0, v1]);
            for l in 0..LANES {
                let k = from[l] + s;
                if k < to[l] {
                    // SAFETY: k < to[l] (the caller's contract).
                    unsafe {
                        *xo[l].add(k) = ox[l];
                        *vo[l].add(k) = ov[l];
                    }
                }
            }
        }
        store16(x, [x0, x1]);
        store16(v, [v0, v1]);
    }

    /// Register `g`'s constants (lanes `8 g .. 8 g + 8`).
    #[inline]
    #[target_feature(enable = "avx2")]
    fn konsts(c: &[C32; LANES], g: usize) -> K {
        let gather = |f: &dyn Fn(&C32) -> f32| {
            let a: [f32; 8] = std::array::from_fn(|l| f(&c[8 * g + l]));
            // SAFETY: `a` holds 8 f32.
            unsafe { _mm256_loadu_ps(a.as_ptr()) }
        };
        K {
            t: gather(&|c| c.t),
            alpha: gather(&|c| c.alpha),
            c1: gather(&|c| c.c1),
            g2: gather(&|c| c.g2),
        }
    }

    /// Samples ahead at which [`rows16`] fetches the lines of `v` rows
    /// stored with ordinary stores in a streamed batch.
    const V_AHEAD: usize = 4 * BLOCK;

    /// `blocks` blocks of [`BLOCK`] steps of the [`LANES`] tracks whose
    /// states are `x`, `v` (updated), reading `z[l]` and writing `xo[l]`,
    /// `vo[l]` (`BLOCK * blocks` samples from each pointer); with `pf`,
    /// prefetching the rows `pf[l]` at each block's offset (the next
    /// group's rows).
    ///
    /// # Safety
    /// AVX2 and FMA are available; every pointer is valid for
    /// `BLOCK * blocks` elements, outputs not overlapping each other or the
    /// inputs; with `nt[0]` (streamed `x` rows) every `xo[l]`, with `nt[1]`
    /// (streamed `v` rows) every `vo[l]` is 64-byte aligned.
    #[allow(clippy::too_many_arguments)]
    // Not inlined into its two callers' shared `lanes_fma`: inlined there,
    // 16 rows of 2,100 ran 1.03-1.08 ns per sample against 0.84-0.91
    // (AMD EPYC, session 23).
    #[inline(never)]
    #[target_feature(enable = "avx2,fma")]
    pub(super) unsafe fn rows16(
        c: &[C32; LANES],
        x: &mut [f32; LANES],
        v: &mut [f32; LANES],
        z: &[*const f32; LANES],
        xo: &[*mut f32; LANES],
        vo: &[*mut f32; LANES],
        blocks: usize,
        nt: [bool; 2],
        pf: Option<&[*const f32; LANES]>,
    ) {
        let (k0, k1) = (konsts(c, 0), konsts(c, 1));
        let one = _mm256_set1_ps(1.0);
        let [mut x0, mut x1] = load16(x);
        let [mut v0, mut v1] = load16(v);
        // Column stages: [register][step] -> the 8 slots.
        let mut sz = [[_mm256_setzero_ps(); BLOCK]; 2];
        let mut sx = [[_mm256_setzero_ps(); BLOCK]; 2];
        let mut sv = [[_mm256_setzero_ps(); BLOCK]; 2];
        for b in 0..blocks {
            let off = b * BLOCK;
            if let Some(pf) = pf {
                for zl in pf {
                    crate::filter::prefetch(zl.wrapping_add(off));
                }
            }
            if nt[0] && !nt[1] {
                // `v` rows stored with ordinary stores in a streamed batch:
                // their lines fetched for ownership a few blocks ahead.
                for vl in vo {
                    _mm_prefetch::<_MM_HINT_ET0>(vl.wrapping_add(off + V_AHEAD) as *const i8);
                }
            }
            // z rows -> columns; any NaN in the block?
            let mut nan = _mm256_setzero_ps();
            for g in 0..2 {
                for h in 0..2 {
                    // SAFETY: off + 8 h + 8 <= BLOCK * blocks.
                    let mut r: [__m256; 8] = std::array::from_fn(|l| unsafe {
                        _mm256_loadu_ps(z[8 * g + l].add(off + 8 * h))
                    });
                    for q in 0..4 {
                        let u = _mm256_cmp_ps::<_CMP_UNORD_Q>(r[2 * q], r[2 * q + 1]);
                        nan = _mm256_or_ps(nan, u);
                    }
                    tr8(&mut r);
                    sz[g][8 * h..8 * h + 8].copy_from_slice(&r);
                }
            }
            if _mm256_movemask_ps(nan) == 0 {
                for j in 0..BLOCK {
                    clean(&k0, &mut x0, &mut v0, sz[0][j]);
                    clean(&k1, &mut x1, &mut v1, sz[1][j]);
                    sx[0][j] = x0;
                    sv[0][j] = v0;
                    sx[1][j] = x1;
                    sv[1][j] = v1;
                }
            } else {
                for j in 0..BLOCK {
                    masked(&k0, one, &mut x0, &mut v0, sz[0][j]);
                    masked(&k1, one, &mut x1, &mut v1, sz[1][j]);
                    sx[0][j] = x0;
                    sv[0][j] = v0;
                    sx[1][j] = x1;
                    sv[1][j] = v1;
                }
            }
            // Columns -> rows, stored a whole line (both halves) at a time:
            // streamed lines written in pieces are much slower.
            for g in 0..2 {
                for (s, dst, nt) in [(&sx[g], xo, nt[0]), (&sv[g], vo, nt[1])] {
                    let mut lo: [__m256; 8] = std::array::from_fn(|j| s[j]);
                    let mut hi: [__m256; 8] = std::array::from_fn(|j| s[8 + j]);
                    tr8(&mut lo);
                    tr8(&mut hi);
                    for l in 0..8 {
                        // SAFETY: off + BLOCK <= BLOCK * blocks; with nt
                        // the row is 64-byte aligned, so is off.
                        unsafe {
                            let p = dst[8 * g + l].add(off);
                            if nt {
                                _mm256_stream_ps(p, lo[l]);
                                _mm256_stream_ps(p.add(8), hi[l]);
                            } else {
                                _mm256_storeu_ps(p, lo[l]);
                                _mm256_storeu_ps(p.add(8), hi[l]);
                            }
                        }
                    }
                }
            }
        }
        store16(x, [x0, x1]);
        store16(v, [v0, v1]);
    }
}

#[cfg(test)]
#[path = "tests/f32arith.rs"]
mod tests;
