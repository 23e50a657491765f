//! AVX2 (+FMA) alpha-beta lanes for CPUs without AVX-512: the eight tracks
//! of an [`AB_LANES`] group in two 4-slot `f64` registers (lanes 0-3 and
//! 4-7).
//!
//! Per block (one 64-byte cache line of output per lane: 8 `f64` or 16
//! `f32` samples) the first group of four lanes runs all its steps, then the
//! second. Per quarter of four steps: four row loads (`f32` widened), a
//! 4 x 4 transpose, four vector steps, two 4 x 4 transposes back and eight
//! 4-sample row stores (`x`, `v`; `f32` narrowed). Few values are live at a
//! time, so the states stay in registers (an earlier version kept a whole
//! block of both groups in flight and spilled the states to the stack: the
//! store-to-load round trip sat on the dependency chain; 8 rows of 2,100
//! samples in L2 on Zen 3: 1.02 -> 0.81 ns per sample in `f32`, 0.89-1.04
//! -> 0.73 in `f64`). Interleaving the two groups per quarter or per step
//! ran as fast on such rows and slower on rows whose addresses alias (a
//! multiple of 4 KiB apart). A quarter
//! whose `z` has no NaN runs [`step_clean`] (the same operations without the
//! compare and selects). For outputs too big for the caches the block's
//! rows are staged in a small buffer and streamed out whole lines at a time
//! (the group's `x` lines, then its `v` lines): lines written in pieces by
//! streamed stores ran about six times slower. The arithmetic of each slot
//! is exactly the scalar [`ab_step`] with FMA (the same fused operations in
//! the same order), so results are bit-identical to the scalar lanes and to
//! the AVX-512 lanes.
//!
//! As in the AVX-512 lanes, every lane first steps (scalar) to a sample
//! whose `x` output starts a cache line, so the stores are aligned and, for
//! outputs too big for the caches, non-temporal. `f32` rows are transposed
//! as `f32` (in-lane shuffles) and widened after; outputs are narrowed per
//! step and transposed as `f32` (the same values either way).
//!
//! Short rows ([`ab_short_rows`]) run eight consecutive rows in the same
//! two groups, the outputs either written directly or, when streamed,
//! staged and written out whole lines at a time while the lanes fill the
//! other stage.

use std::arch::x86_64::*;

use super::simd::{fits, is_f64};
use super::{
    ab_loop, ab_start, ab_step, prefetch, AbConst, Init, IoFloat, TrackOut, TrackState, AB_LANES,
};
use crate::Result;

/// Slots per register.
const V: usize = 4;

/// Four consecutive samples at `p`, widened to `f64`.
///
/// # Safety
/// `T` is `f64` or `f32`, `p..p+4` is readable, AVX is available.
#[inline]
#[target_feature(enable = "avx2")]
unsafe fn load4<T: 'static>(p: *const T) -> __m256d {
    // SAFETY: forwarded from the caller.
    unsafe {
        if is_f64::<T>() {
            _mm256_loadu_pd(p as *const f64)
        } else {
            _mm256_cvtps_pd(_mm_loadu_ps(p as *const f32))
        }
    }
}

/// In-place transpose of the 4 x 4 matrix whose rows are `r`.
#[inline]
#[target_feature(enable = "avx2")]
fn transpose4(r: &mut [__m256d; V]) {
    let t0 = _mm256_unpacklo_pd(r[0], r[1]);
    let t1 = _mm256_unpackhi_pd(r[0], r[1]);
    let t2 = _mm256_unpacklo_pd(r[2], r[3]);
    let t3 = _mm256_unpackhi_pd(r[2], r[3]);
    r[0] = _mm256_permute2f128_pd::<0x20>(t0, t2);
    r[1] = _mm256_permute2f128_pd::<0x20>(t1, t3);
    r[2] = _mm256_permute2f128_pd::<0x31>(t0, t2);
    r[3] = _mm256_permute2f128_pd::<0x31>(t1, t3);
}

/// In-place transpose of the 4 x 4 `f32` matrix whose rows are `r`
/// (in-lane shuffles only).
#[inline]
#[target_feature(enable = "avx2")]
fn transpose4_ps(r: &mut [__m128; V]) {
    let t0 = _mm_unpacklo_ps(r[0], r[1]);
    let t1 = _mm_unpacklo_ps(r[2], r[3]);
    let t2 = _mm_unpackhi_ps(r[0], r[1]);
    let t3 = _mm_unpackhi_ps(r[2], r[3]);
    r[0] = _mm_movelh_ps(t0, t1);
    r[1] = _mm_movehl_ps(t1, t0);
    r[2] = _mm_movelh_ps(t2, t3);
    r[3] = _mm_movehl_ps(t3, t2);
}

/// Per-slot constants of four lanes.
#[derive(Clone, Copy)]
pub(super) struct Consts {
    pub(super) t: __m256d,
    pub(super) alpha: __m256d,
    pub(super) oma: __m256d,
    pub(super) g2: __m256d,
}

/// One vector step of four lanes: exactly `ab_step::<true>` per slot
/// (`x_p = fma(t, v, x)`, `w = fma(g, zz, v)`, `x' = fma(c1, x_p, alpha zz)`,
/// `v' = fma(-g, x_p, w)`, with `(zz, c1, g) = (0, 1, 0)` for a NaN `z`).
#[inline]
#[target_feature(enable = "avx2,fma")]
fn step(c: &Consts, one: __m256d, x: &mut __m256d, v: &mut __m256d, z: __m256d) {
    let xp = _mm256_fmadd_pd(c.t, *v, *x);
    let valid = _mm256_cmp_pd::<_CMP_ORD_Q>(z, z);
    let zz = _mm256_and_pd(valid, z);
    let c1 = _mm256_blendv_pd(one, c.oma, valid);
    let g = _mm256_and_pd(valid, c.g2);
    let w = _mm256_fmadd_pd(g, zz, *v);
    *x = _mm256_fmadd_pd(c1, xp, _mm256_mul_pd(c.alpha, zz));
    *v = _mm256_fnmadd_pd(g, xp, w);
}

/// [`step`] for four `z` known not to be NaN: the same operations on the
/// same operands (`zz = z`, `c1 = 1 - alpha`, `g = g2`), so the same bits,
/// without the compare and the three selects.
#[inline]
#[target_feature(enable = "avx2,fma")]
pub(super) fn step_clean(c: &Consts, x: &mut __m256d, v: &mut __m256d, z: __m256d) {
    let xp = _mm256_fmadd_pd(c.t, *v, *x);
    let w = _mm256_fmadd_pd(c.g2, z, *v);
    *x = _mm256_fmadd_pd(c.oma, xp, _mm256_mul_pd(c.alpha, z));
    *v = _mm256_fnmadd_pd(c.g2, xp, w);
}

/// The eight lanes over samples `k0..n` (see the module docs): the same
/// contract as the scalar `ab_lanes` and `simd::ab_lanes8`, with
/// non-temporal stores if `nt`.
///
/// # Safety
/// The CPU supports AVX2 and FMA (`simd::avx2_available`).
#[allow(clippy::too_many_arguments)]
#[target_feature(enable = "avx2,fma")]
pub(super) unsafe fn ab_lanes8<T: IoFloat>(
    c: &[AbConst; AB_LANES],
    x_out: &mut [f64; AB_LANES],
    v_out: &mut [f64; AB_LANES],
    k0: usize,
    n: usize,
    z: [&[T]; AB_LANES],
    xs: [&mut [T]; AB_LANES],
    vs: [&mut [T]; AB_LANES],
    ahead: Option<(usize, usize)>,
    nt: bool,
) {
    // SAFETY: forwarded.
    unsafe { ab_lanes8_body(c, x_out, v_out, k0, n, z, xs, vs, ahead, nt) }
}

/// [`ab_lanes8`] compiled with AVX-512VL too (32 registers; the same
/// operations, so the same bits): the `f64` row lanes on an AMD Zen 4
/// (`filter::rows_zen4`).
///
/// # Safety
/// The CPU supports AVX2, FMA, AVX-512F and AVX-512VL.
#[allow(clippy::too_many_arguments)]
#[target_feature(enable = "avx2,fma,avx512f,avx512vl")]
pub(super) unsafe fn ab_lanes8_zen4<T: IoFloat>(
    c: &[AbConst; AB_LANES],
    x_out: &mut [f64; AB_LANES],
    v_out: &mut [f64; AB_LANES],
    k0: usize,
    n: usize,
    z: [&[T]; AB_LANES],
    xs: [&mut [T]; AB_LANES],
    vs: [&mut [T]; AB_LANES],
    ahead: Option<(usize, usize)>,
    nt: bool,
) {
    // SAFETY: forwarded.
    unsafe { ab_lanes8_body(c, x_out, v_out, k0, n, z, xs, vs, ahead, nt) }
}

#[allow(clippy::too_many_arguments)]
#[inline(always)]
unsafe fn ab_lanes8_body<T: IoFloat>(
    c: &[AbConst; AB_LANES],
    x_out: &mut [f64; AB_LANES],
    v_out: &mut [f64; AB_LANES],
    k0: usize,
    n: usize,
    z: [&[T]; AB_LANES],
    xs: [&mut [T]; AB_LANES],
    vs: [&mut [T]; AB_LANES],
    ahead: Option<(usize, usize)>,
    nt: bool,
) {
    if !fits::<T>(k0, n)
        || z.iter().any(|r| r.len() < n)
        || xs.iter().chain(vs.iter()).any(|r| r.len() < n)
    {
        super::ab_lanes::<T, true>(c, x_out, v_out, k0, n, z, xs, vs, ahead);
        return;
    }
    let size = std::mem::size_of::<T>();
    let z = z.map(|s| &s[..n]);
    let mut xs = xs.map(|s| &mut s[..n]);
    let mut vs = vs.map(|s| &mut s[..n]);
    let (mut x, mut v) = (*x_out, *v_out);
    // Whole cache lines per lane and block: 8 f64 or 16 f32 samples.
    let bytes = 64;
    let sb = bytes / size;
    // Heads: each lane steps to its first sample with a line-aligned x
    // output (slices are aligned to their element size, so the misalignment
    // is a whole number of elements).
    let mut k = [k0; AB_LANES];
    for l in 0..AB_LANES {
        let addr = xs[l].as_ptr() as usize + k0 * size;
        k[l] = k0 + ((bytes - addr % bytes) % bytes) / size;
    }
    scalar_steps(c, &mut x, &mut v, &z, &mut xs, &mut vs, [k0; AB_LANES], k);
    // Rows are streamed only as whole lines (x rows are line-aligned by the
    // head; v rows only if line-aligned too: a v row half a line off x was
    // streamed in half lines, 2.5 x slower than ordinary stores, e.g.
    // 33,333 x 300 float64 5.0-5.8 -> 2.5-3.6 ns per sample).
    let aligned = |p: *const T, at: usize| (p as usize + at * size).is_multiple_of(64);
    let x_nt: [bool; AB_LANES] = std::array::from_fn(|l| nt && aligned(xs[l].as_ptr(), k[l]));
    let v_nt: [bool; AB_LANES] = std::array::from_fn(|l| nt && aligned(vs[l].as_ptr(), k[l]));
    let blocks = k.iter().map(|&kl| (n - kl) / sb).min().unwrap_or(0);
    let cs = [consts(c, 0), consts(c, 1)];
    let one = _mm256_set1_pd(1.0);
    // SAFETY (loads): x, v are plain arrays of 8 f64.
    let mut xv = unsafe {
        [
            _mm256_loadu_pd(x.as_ptr()),
            _mm256_loadu_pd(x.as_ptr().add(V)),
        ]
    };
    let mut vv = unsafe {
        [
            _mm256_loadu_pd(v.as_ptr()),
            _mm256_loadu_pd(v.as_ptr().add(V)),
        ]
    };
    let ctx = Body {
        z: &z,
        k: &k,
        stream: std::array::from_fn(|g| {
            std::array::from_fn(|i| {
                if i < V {
                    x_nt[V * g + i]
                } else {
                    v_nt[V * g + i - V]
                }
            })
        }),
        ahead,
        blocks,
        sb,
    };
    // SAFETY: this function is compiled with AVX2 and FMA; blocks * sb
    // samples from k[l] fit every lane; a row is streamed only if aligned.
    unsafe {
        if nt {
            body::<T, true>(&ctx, &cs, one, &mut xv, &mut vv, &mut xs, &mut vs);
            _mm_sfence();
        } else {
            body::<T, false>(&ctx, &cs, one, &mut xv, &mut vv, &mut xs, &mut vs);
        }
    }
    // SAFETY: x, v are plain arrays of 8 f64.
    unsafe {
        _mm256_storeu_pd(x.as_mut_ptr(), xv[0]);
        _mm256_storeu_pd(x.as_mut_ptr().add(V), xv[1]);
        _mm256_storeu_pd(v.as_mut_ptr(), vv[0]);
        _mm256_storeu_pd(v.as_mut_ptr().add(V), vv[1]);
    }
    // Tails.
    let start: [usize; AB_LANES] = std::array::from_fn(|l| k[l] + blocks * sb);
    scalar_steps(
        c,
        &mut x,
        &mut v,
        &z,
        &mut xs,
        &mut vs,
        start,
        [n; AB_LANES],
    );
    *x_out = x;
    *v_out = v;
}

/// Loop-invariant inputs of [`body`].
struct Body<'a, 'b, T> {
    z: &'a [&'b [T]; AB_LANES],
    k: &'a [usize; AB_LANES],
    /// Per group of four lanes, whether row `i` (`x` rows, then `v` rows)
    /// is streamed (if `NT`).
    stream: [[bool; 2 * V]; 2],
    ahead: Option<(usize, usize)>,
    blocks: usize,
    sb: usize,
}

/// Store the four samples `a` of one lane at `p` (32 bytes of `f64`, or 16
/// bytes of `f32` narrowed with round to nearest).
///
/// # Safety
/// `T` is `f64` or `f32`, the four elements at `p` are writable; AVX is
/// available.
#[inline(always)]
unsafe fn store4<T: 'static>(p: *mut T, a: __m256d) {
    // SAFETY: forwarded from the caller.
    unsafe {
        if is_f64::<T>() {
            _mm256_storeu_pd(p as *mut f64, a)
        } else {
            _mm_storeu_ps(p as *mut f32, _mm256_cvtpd_ps(a))
        }
    }
}

/// One block of four lanes: where each lane's block starts (`z` samples,
/// `x` and `v` outputs) and whether its `x` / `v` line is streamed.
pub(super) struct Rows<T> {
    pub(super) z: [*const T; V],
    pub(super) x: [*mut T; V],
    pub(super) v: [*mut T; V],
    /// `x` rows, then `v` rows.
    pub(super) stream: [bool; 2 * V],
}

/// One block (`sb` samples: one 64-byte line of output) of four lanes, a
/// quarter (four steps) at a time: four row loads (`f32` widened), a 4 x 4
/// transpose, four vector steps ([`step_clean`] if the quarter has no NaN
/// `z`, else [`step`]), two transposes back and eight 4-sample row stores;
/// few values are live, so the states stay in registers. If `NT`, the rows
/// go through `stage` and out whole lines at a time (`x` lines, then `v`
/// lines; streamed where `rows.stream` says so).
///
/// # Safety
/// Called only from functions compiled with AVX2 and FMA (always inlined);
/// `sb` is 8 (`f64`) or 16 (`f32`) if `NT`, else a multiple of 4 up to
/// 16; each lane has `sb` readable `z` and `sb` writable `x` and `v`
/// elements at its pointers; a streamed line is 32-byte aligned.
#[inline(always)]
pub(super) unsafe fn group_block<T: IoFloat, const NT: bool>(
    c: &Consts,
    one: __m256d,
    x: &mut __m256d,
    v: &mut __m256d,
    rows: &Rows<T>,
    sb: usize,
    stage: &mut [[T; 16]; 2 * V],
) {
    // SAFETY: forwarded from the caller.
    unsafe { group_block_ev::<T, NT>(c, one, x, v, rows, sb, stage, None) }
}

/// The track starts and final-state captures of one block of the flat
/// kernel's four slots ([`group_block_ev`]): bit `p` of `steps` if a slot
/// starts a track at block step `p`, with `s0[p]` (bit `l`: slot `l` at its
/// track's first sample) and `s1[p]` (at its second, two-point start), both
/// cleared when used; `v0` the velocity at a first sample (`Init::First`:
/// `v0 + signed * z`; two-point: NaN), as `filter_flat_vec::compute`; bit
/// `p` of `caps`: the states after step `p` are wanted (`capx[p]`,
/// `capv[p]`, slot `l` in lane `l`).
pub(super) struct BlockStarts<'a> {
    pub(super) steps: u32,
    pub(super) s0: &'a mut [u32; 16],
    pub(super) s1: &'a mut [u32; 16],
    pub(super) v0: __m256d,
    pub(super) signed: Option<__m256d>,
    pub(super) caps: u32,
    pub(super) capx: &'a mut [__m256d; 16],
    pub(super) capv: &'a mut [__m256d; 16],
}

/// The lanes whose bit is set in `bits` (all ones there).
#[inline]
#[target_feature(enable = "avx2,fma")]
fn mask4(bits: u32) -> __m256d {
    let b = _mm256_set_epi64x(8, 4, 2, 1);
    let m = _mm256_and_si256(_mm256_set1_epi64x(bits as i64), b);
    _mm256_castsi256_pd(_mm256_cmpeq_epi64(m, b))
}

/// Block step `p`'s track starts after the step from `x0` on sample `z`:
/// at a first sample `x = z`, `v = v0`, at a second `x = z`,
/// `v = (z - x0) / T` (the operations of `filter_flat_vec::compute`).
#[inline]
#[target_feature(enable = "avx2,fma")]
fn start_blend(
    e: &mut BlockStarts<'_>,
    c: &Consts,
    x: &mut __m256d,
    v: &mut __m256d,
    x0: __m256d,
    z: __m256d,
    p: usize,
) {
    let (b0, b1) = (std::mem::take(&mut e.s0[p]), std::mem::take(&mut e.s1[p]));
    let vel = _mm256_div_pd(_mm256_sub_pd(z, x0), c.t);
    *x = _mm256_blendv_pd(*x, z, mask4(b0 | b1));
    *v = _mm256_blendv_pd(*v, vel, mask4(b1));
    let v0 = match e.signed {
        Some(zs) => _mm256_add_pd(e.v0, _mm256_mul_pd(zs, z)),
        None => e.v0,
    };
    *v = _mm256_blendv_pd(*v, v0, mask4(b0));
}

/// [`group_block`] with the starts and captures of `ev` (if any).
///
/// # Safety
/// As [`group_block`].
#[allow(unused_unsafe, clippy::too_many_arguments)]
#[inline(always)]
pub(super) unsafe fn group_block_ev<T: IoFloat, const NT: bool>(
    c: &Consts,
    one: __m256d,
    x: &mut __m256d,
    v: &mut __m256d,
    rows: &Rows<T>,
    sb: usize,
    stage: &mut [[T; 16]; 2 * V],
    mut ev: Option<&mut BlockStarts<'_>>,
) {
    // SAFETY: the caller has AVX2 and FMA; every access is inside a lane's
    // sb elements (q V + V <= sb) or inside `stage` (sb <= 16).
    unsafe {
        let zero = _mm256_setzero_pd();
        for q in 0..sb / V {
            let at = q * V;
            // unord(a, b) is set where a or b is NaN.
            let (r, any_nan) = if is_f64::<T>() {
                let mut r: [__m256d; V] =
                    std::array::from_fn(|i| unsafe { load4(rows.z[i].add(at)) });
                let nan = _mm256_or_pd(
                    _mm256_cmp_pd::<_CMP_UNORD_Q>(r[0], r[1]),
                    _mm256_cmp_pd::<_CMP_UNORD_Q>(r[2], r[3]),
                );
                transpose4(&mut r);
                (r, _mm256_movemask_pd(nan) != 0)
            } else {
                // f32: transposed as f32 (in-lane shuffles), then widened
                // (exact), so the steps see the same values.
                let mut r: [__m128; V] = std::array::from_fn(|i| unsafe {
                    _mm_loadu_ps(rows.z[i].add(at) as *const f32)
                });
                let nan = _mm_or_ps(_mm_cmpunord_ps(r[0], r[1]), _mm_cmpunord_ps(r[2], r[3]));
                transpose4_ps(&mut r);
                (r.map(|v| _mm256_cvtps_pd(v)), _mm_movemask_ps(nan) != 0)
            };
            let mut xo = [zero; V];
            let mut vo = [zero; V];
            if !any_nan {
                for j in 0..V {
                    let x0 = *x;
                    step_clean(c, x, v, r[j]);
                    if let Some(e) = ev.as_deref_mut() {
                        if e.steps & (1 << (at + j)) != 0 {
                            start_blend(e, c, x, v, x0, r[j], at + j);
                        }
                    }
                    xo[j] = *x;
                    vo[j] = *v;
                }
            } else {
                for j in 0..V {
                    let x0 = *x;
                    step(c, one, x, v, r[j]);
                    if let Some(e) = ev.as_deref_mut() {
                        if e.steps & (1 << (at + j)) != 0 {
                            start_blend(e, c, x, v, x0, r[j], at + j);
                        }
                    }
                    xo[j] = *x;
                    vo[j] = *v;
                }
            }
            if let Some(e) = ev.as_deref_mut() {
                if (e.caps >> at) & 0xf != 0 {
                    e.capx[at..at + V].copy_from_slice(&xo);
                    e.capv[at..at + V].copy_from_slice(&vo);
                }
            }
            if is_f64::<T>() {
                transpose4(&mut xo);
                transpose4(&mut vo);
                for i in 0..V {
                    if NT {
                        store4::<T>(stage[i].as_mut_ptr().add(at), xo[i]);
                        store4::<T>(stage[V + i].as_mut_ptr().add(at), vo[i]);
                    } else {
                        store4::<T>(rows.x[i].add(at), xo[i]);
                        store4::<T>(rows.v[i].add(at), vo[i]);
                    }
                }
            } else {
                // f32: narrowed per step (round to nearest, as a narrowing
                // after the transpose would), transposed as f32.
                let mut xq = xo.map(|v| _mm256_cvtpd_ps(v));
                let mut vq = vo.map(|v| _mm256_cvtpd_ps(v));
                transpose4_ps(&mut xq);
                transpose4_ps(&mut vq);
                for i in 0..V {
                    let (px, pv) = if NT {
                        (
                            stage[i].as_mut_ptr().add(at),
                            stage[V + i].as_mut_ptr().add(at),
                        )
                    } else {
                        (rows.x[i].add(at), rows.v[i].add(at))
                    };
                    _mm_storeu_ps(px as *mut f32, xq[i]);
                    _mm_storeu_ps(pv as *mut f32, vq[i]);
                }
            }
        }
        if NT {
            // Whole lines, each by two consecutive stores.
            for i in 0..2 * V {
                let dst = if i < V { rows.x[i] } else { rows.v[i - V] };
                copy_line(dst, stage[i].as_ptr(), rows.stream[i]);
            }
        }
    }
}

/// Copy the 64-byte line at `src` to `dst` (two 32-byte stores, streamed
/// past the caches if `nt`).
///
/// # Safety
/// `src` has 64 readable bytes, `dst` 64 writable bytes, aligned to 32 if
/// `nt`; AVX is available.
#[inline(always)]
unsafe fn copy_line<T>(dst: *mut T, src: *const T, nt: bool) {
    // SAFETY: forwarded from the caller.
    unsafe {
        let (s, d) = (src as *const __m256i, dst as *mut __m256i);
        let (a, b) = (_mm256_loadu_si256(s), _mm256_loadu_si256(s.add(1)));
        if nt {
            _mm256_stream_si256(d, a);
            _mm256_stream_si256(d.add(1), b);
        } else {
            _mm256_storeu_si256(d, a);
            _mm256_storeu_si256(d.add(1), b);
        }
    }
}

/// The vector blocks of the eight lanes: per block (one cache line of
/// output per lane) the first group of four lanes runs all its steps, then
/// the second; per quarter of four steps, four row loads, a transpose, four
/// vector steps, two transposes back and eight 4-sample row stores (`x`
/// and `v`), so that few values are live at a time and the states stay in
/// registers. A quarter whose `z` has no NaN runs [`step_clean`], else
/// [`step`]. If `NT`, the block's rows go through `stage` and out whole
/// lines at a time, streamed where `ctx.stream` says so.
///
/// # Safety
/// Called only from functions compiled with AVX2 and FMA. Always inlined
/// into them: as an `#[inline]` target-feature function it was inlined only
/// while it had a single caller (a second caller made LLVM keep it out of
/// line and the row lanes lost 45 %; docs/benchmarks.md, "Ragged without
/// t: long tracks in the row lanes, tried"). `blocks * sb` samples from
/// `k[l]` exist in every lane's `z`, `xs` and `vs`; a streamed row is
/// 32-byte aligned at `k[l]`.
#[allow(clippy::too_many_arguments)]
// (the inner `unsafe` blocks keep their SAFETY notes inside the outer one)
#[allow(unused_unsafe)]
#[inline(always)]
unsafe fn body<T: IoFloat, const NT: bool>(
    ctx: &Body<'_, '_, T>,
    cs: &[Consts; 2],
    one: __m256d,
    xv: &mut [__m256d; 2],
    vv: &mut [__m256d; 2],
    xs: &mut [&mut [T]; AB_LANES],
    vs: &mut [&mut [T]; AB_LANES],
) {
    // SAFETY: the caller has AVX2 and FMA (see above); every pointer below
    // stays inside its lane's slice: at + V <= k[l] + blocks * sb <= n.
    unsafe {
        let Body {
            z,
            k,
            stream,
            ahead,
            blocks,
            sb,
        } = *ctx;
        // Each group's rows at its lanes' first vector sample.
        let groups: [Rows<T>; 2] = std::array::from_fn(|g| Rows {
            z: std::array::from_fn(|i| z[V * g + i].as_ptr().add(k[V * g + i])),
            x: std::array::from_fn(|i| xs[V * g + i].as_mut_ptr().add(k[V * g + i])),
            v: std::array::from_fn(|i| vs[V * g + i].as_mut_ptr().add(k[V * g + i])),
            stream: stream[g],
        });
        // With streamed stores: a group's block of outputs (one line per
        // lane, x then v), written out whole lines at a time (lines written
        // in pieces by streamed stores are many times slower).
        let mut stage = [[T::from_f64(0.0); 16]; 2 * V];
        // Local copies of the states (kept in registers).
        let (mut xl, mut vl) = (*xv, *vv);
        for b in 0..blocks {
            let base = b * sb;
            if let Some((dz, dout)) = ahead {
                for rows in &groups {
                    for i in 0..V {
                        prefetch(rows.z[i].wrapping_add(dz + base));
                        if !NT {
                            prefetch(rows.x[i].wrapping_add(dout + base));
                            prefetch(rows.v[i].wrapping_add(dout + base));
                        }
                    }
                }
            }
            for (g, rows) in groups.iter().enumerate() {
                let block = Rows {
                    z: rows.z.map(|p| p.wrapping_add(base)),
                    x: rows.x.map(|p| p.wrapping_add(base)),
                    v: rows.v.map(|p| p.wrapping_add(base)),
                    stream: rows.stream,
                };
                group_block::<T, NT>(&cs[g], one, &mut xl[g], &mut vl[g], &block, sb, &mut stage);
            }
        }
        *xv = xl;
        *vv = vl;
    }
}

/// Scalar steps of every lane `l` over samples `from[l]..to[l]`, the lanes
/// interleaved (step `s` of every lane, then step `s + 1`).
#[allow(clippy::too_many_arguments)]
#[inline]
#[target_feature(enable = "fma")]
fn scalar_steps<T: IoFloat>(
    c: &[AbConst; AB_LANES],
    x: &mut [f64; AB_LANES],
    v: &mut [f64; AB_LANES],
    z: &[&[T]; AB_LANES],
    xs: &mut [&mut [T]; AB_LANES],
    vs: &mut [&mut [T]; AB_LANES],
    from: [usize; AB_LANES],
    to: [usize; AB_LANES],
) {
    let most = (0..AB_LANES)
        .map(|l| to[l].saturating_sub(from[l]))
        .max()
        .unwrap_or(0);
    for s in 0..most {
        for l in 0..AB_LANES {
            let kk = from[l] + s;
            if kk < to[l] {
                let (x1, v1, _) = ab_step::<true>(&c[l], x[l], v[l], z[l][kk].to_f64());
                x[l] = x1;
                v[l] = v1;
                xs[l][kk] = T::from_f64(x1);
                vs[l][kk] = T::from_f64(v1);
            }
        }
    }
}

/// Scalar steps `from..n` of the eight rows of `n` samples back to back in
/// `z`, `xs`, `vs` (row `l` in lane `l`), the rows interleaved (step `s`
/// of every row, then step `s + 1`): [`scalar_steps`] for the short-row
/// lanes' last steps, without per-row slices.
#[allow(clippy::too_many_arguments)]
#[inline]
#[target_feature(enable = "fma")]
fn row_tails<T: IoFloat>(
    c: &[AbConst; AB_LANES],
    x: &mut [f64; AB_LANES],
    v: &mut [f64; AB_LANES],
    z: &[T],
    xs: &mut [T],
    vs: &mut [T],
    n: usize,
    from: usize,
) {
    for kk in from..n {
        for l in 0..AB_LANES {
            let i = l * n + kk;
            let (x1, v1, _) = ab_step::<true>(&c[l], x[l], v[l], z[i].to_f64());
            x[l] = x1;
            v[l] = v1;
            xs[i] = T::from_f64(x1);
            vs[i] = T::from_f64(v1);
        }
    }
}

/// Short contiguous rows (`z`, `xs`, `vs`: `states.len()` rows of `n`
/// samples back to back; row `j` has the gains `params(j)`), eight rows at
/// a time: each row's start-up (`ab_start`) and steps to a common first
/// running sample, then the eight lanes a block (two quarters) of each
/// group at a time as in [`body`], the last steps scalar. Unless `nt` the
/// lanes write the outputs directly; with `nt` they write a stage of eight
/// rows per component (in the caches), which goes out while the lanes fill
/// the other stage, whole lines streamed past the caches: eight rows of
/// outputs are one contiguous region, so there are no scalar heads to
/// line-aligned outputs and partial lines only at the ends of a call.
/// Rows left over (fewer than eight) and groups with a row that does not
/// run take the scalar loop (through the stage too, when streamed). Every step is `ab_step::<true>`
/// (bit-identical to the scalar lanes and to the flat kernel).
///
/// In the caches this runs 1.3-1.5x faster than the flat kernel (two
/// groups of four lanes overlap their dependency chains; the flat kernel
/// has one); from memory it was slower in `f64` (the streamed outputs cost
/// it about 1 ns per sample more than the flat kernel's, not understood)
/// and faster in `f32` with streamed outputs (docs/benchmarks.md, "Short
/// rows in two groups of lanes"), so `filter_ab` runs it only there.
///
/// # Safety
/// The CPU supports AVX2 and FMA; `T` is `f32` or `f64`.
#[allow(clippy::too_many_arguments)]
#[target_feature(enable = "avx2,fma")]
pub(super) unsafe fn ab_short_rows<T: IoFloat>(
    params: &[(f64, f64, f64)],
    init: Init,
    n: usize,
    z: &[T],
    xs: &mut [T],
    vs: &mut [T],
    states: &mut [TrackState],
    nt: bool,
) -> Result<()> {
    let cn = states.len();
    let total = cn
        .checked_mul(n)
        .ok_or_else(|| crate::Error::Shape("short rows: size overflow".into()))?;
    if z.len() < total || xs.len() < total || vs.len() < total {
        return Err(crate::Error::Shape(
            "short rows: buffers do not match the rows".into(),
        ));
    }
    const L: usize = AB_LANES;
    // One (alpha, beta, T) for all rows, or one per row.
    let shared = params.len() == 1;
    if !shared && params.len() < cn {
        return Err(crate::Error::Shape(
            "short rows: fewer gains than rows".into(),
        ));
    }
    let Some(&(a0, b0, t0)) = params.first() else {
        return if cn == 0 {
            Ok(())
        } else {
            Err(crate::Error::Shape("short rows: no gains".into()))
        };
    };
    let c_shared = AbConst::new(a0, b0, t0);
    // Streamed outputs: two stages of eight rows per component; while the
    // lanes fill one, the other drains to the outputs a few lines per block
    // (spread over the computation rather than one burst per group).
    let seg = L * n;
    let mut stage = vec![T::from_f64(0.0); if nt { 4 * seg } else { 0 }];
    let sp = stage.as_mut_ptr();
    let (xp, vp) = (xs.as_mut_ptr(), vs.as_mut_ptr());
    let mut cur = 0;
    let mut drains: [Option<Drain<T>>; 2] = [None, None];
    let one = _mm256_set1_pd(1.0);
    let mut dummy = [[T::from_f64(0.0); 16]; 2 * V];
    let mut j0 = 0;
    while j0 < cn {
        let rows = (cn - j0).min(L);
        let zb = &z[j0 * n..(j0 + rows) * n];
        // SAFETY: (j0 + rows) n <= total <= xs.len(), vs.len(); the blocks
        // are disjoint and every access to xs and vs goes through xp, vp
        // (a drain writes the previous block's while this one runs).
        let (ox, ov) = unsafe {
            (
                std::slice::from_raw_parts_mut(xp.add(j0 * n), rows * n),
                std::slice::from_raw_parts_mut(vp.add(j0 * n), rows * n),
            )
        };
        let sts = &mut states[j0..j0 + rows];
        // Streamed: through the stage; else straight into the outputs.
        let (dx, dv): (&mut [T], &mut [T]) = if nt {
            // SAFETY: stage `cur` (x: segment 2 cur, v: 2 cur + 1) is
            // inside `stage` and disjoint from the draining one; all
            // accesses go through `sp`.
            unsafe {
                (
                    std::slice::from_raw_parts_mut(sp.add(2 * cur * seg), rows * n),
                    std::slice::from_raw_parts_mut(sp.add((2 * cur + 1) * seg), rows * n),
                )
            }
        } else {
            (&mut *ox, &mut *ov)
        };
        let par = |l: usize| params[if shared { 0 } else { j0 + l }];
        let c: [AbConst; L] = if shared {
            [c_shared; L]
        } else {
            std::array::from_fn(|l| {
                let (a, b, t) = par(l.min(rows - 1));
                AbConst::new(a, b, t)
            })
        };
        let mut k0 = [0usize; L];
        for (l, st) in sts.iter_mut().enumerate() {
            let zr = &zb[l * n..(l + 1) * n];
            let (a, b, t) = par(l);
            let mut o = TrackOut {
                states: [&mut dx[l * n..(l + 1) * n], &mut dv[l * n..(l + 1) * n]],
                resid: None,
            };
            k0[l] = ab_start::<T>(a, b, t, init, st, n, &|k| zr[k].to_f64(), &mut o);
        }
        // Left-over rows (fewer than eight) run alone, like a group with a
        // row that does not run.
        let running = rows == L && sts.iter().all(|s| s.phase >= 2.0);
        let kmax = if running {
            k0.iter().copied().max().unwrap_or(n)
        } else {
            n
        };
        let nq = (n - kmax) / V;
        if nq < 2 {
            // Scalar rows (left-over rows, a row that does not run, or too
            // few samples).
            for (l, st) in sts.iter_mut().enumerate() {
                if st.phase < 2.0 {
                    continue;
                }
                let zr = &zb[l * n..(l + 1) * n];
                let mut o = TrackOut {
                    states: [&mut dx[l * n..(l + 1) * n], &mut dv[l * n..(l + 1) * n]],
                    resid: None,
                };
                ab_loop::<T, true>(&c[l], st, k0[l], n, |k| zr[k].to_f64(), &mut o);
            }
        } else {
            let mut x = [0.0; L];
            let mut v = [0.0; L];
            for (l, st) in sts.iter_mut().enumerate() {
                let zr = &zb[l * n..(l + 1) * n];
                let mut o = TrackOut {
                    states: [&mut dx[l * n..(l + 1) * n], &mut dv[l * n..(l + 1) * n]],
                    resid: None,
                };
                ab_loop::<T, true>(&c[l], st, k0[l], kmax, |k| zr[k].to_f64(), &mut o);
                x[l] = st.x[0];
                v[l] = st.x[1];
            }
            let cs = [consts(&c, 0), consts(&c, 1)];
            // SAFETY: x, v are plain arrays of 8 f64.
            let (mut xv, mut vv) = unsafe {
                (
                    [
                        _mm256_loadu_pd(x.as_ptr()),
                        _mm256_loadu_pd(x.as_ptr().add(V)),
                    ],
                    [
                        _mm256_loadu_pd(v.as_ptr()),
                        _mm256_loadu_pd(v.as_ptr().add(V)),
                    ],
                )
            };
            let groups: [Rows<T>; 2] = std::array::from_fn(|g| Rows {
                z: std::array::from_fn(|i| zb[(V * g + i) * n + kmax..].as_ptr()),
                x: std::array::from_fn(|i| dx[(V * g + i) * n + kmax..].as_mut_ptr()),
                v: std::array::from_fn(|i| dv[(V * g + i) * n + kmax..].as_mut_ptr()),
                stream: [false; 2 * V],
            });
            // The next eight rows' z, fetched a group ahead in the order the
            // lanes read them (each row at the same offset as this block's
            // lanes): eight short rows defeat the hardware prefetcher.
            let ahead = (j0 + 2 * L) * n <= z.len();
            let next = zb.as_ptr().wrapping_add(L * n + kmax);
            let blocks = nq / 2;
            let drain_per = drains
                .iter()
                .map(|d| {
                    d.as_ref()
                        .map_or(0, |d| d.lines_left().div_ceil(blocks.max(1)))
                })
                .max()
                .unwrap_or(0);
            for q in (0..nq).step_by(2) {
                let base = q * V;
                let sb = if q + 1 < nq { 2 * V } else { V };
                if ahead && q == 0 {
                    // The next rows' states and first samples (the start-ups
                    // read them first).
                    let sn = sts.as_ptr().wrapping_add(L) as *const u8;
                    for p in (0..L * std::mem::size_of::<TrackState>()).step_by(64) {
                        prefetch(sn.wrapping_add(p));
                    }
                    for r in 0..L {
                        prefetch(next.wrapping_add(r * n).wrapping_sub(kmax));
                    }
                }
                if ahead {
                    for r in 0..L {
                        prefetch(next.wrapping_add(r * n + base + 2 * V));
                        if q + 2 >= nq {
                            prefetch(next.wrapping_add(r * n + n - 1 - kmax));
                        }
                    }
                }
                for (g, rows) in groups.iter().enumerate() {
                    let block = Rows {
                        z: rows.z.map(|p| p.wrapping_add(base)),
                        x: rows.x.map(|p| p.wrapping_add(base)),
                        v: rows.v.map(|p| p.wrapping_add(base)),
                        stream: rows.stream,
                    };
                    // SAFETY: base + sb <= nq V <= n - kmax samples from
                    // kmax in every row of zb, dx and dv; not streamed.
                    unsafe {
                        group_block::<T, false>(
                            &cs[g], one, &mut xv[g], &mut vv[g], &block, sb, &mut dummy,
                        )
                    };
                }
                for d in drains.iter_mut().flatten() {
                    // SAFETY: the CPU has AVX2 (caller).
                    unsafe { d.lines(drain_per) };
                }
            }
            // SAFETY: x, v are plain arrays of 8 f64.
            unsafe {
                _mm256_storeu_pd(x.as_mut_ptr(), xv[0]);
                _mm256_storeu_pd(x.as_mut_ptr().add(V), xv[1]);
                _mm256_storeu_pd(v.as_mut_ptr(), vv[0]);
                _mm256_storeu_pd(v.as_mut_ptr().add(V), vv[1]);
            }
            // The last steps (fewer than four), if any.
            let from = kmax + nq * V;
            if from < n {
                row_tails(&c, &mut x, &mut v, zb, dx, dv, n, from);
            }
            for (l, st) in sts.iter_mut().enumerate() {
                st.x[0] = x[l];
                st.x[1] = v[l];
            }
        }
        if nt {
            // SAFETY: the CPU has AVX2 (caller); the drained stage is the
            // other one; stage `cur` is not written until it has drained.
            unsafe {
                let [dxo, dvo] = &mut drains;
                drains = [
                    Some(Drain::follow(dxo, ox, sp.add(2 * cur * seg))),
                    Some(Drain::follow(dvo, ov, sp.add((2 * cur + 1) * seg))),
                ];
            }
            cur ^= 1;
        }
        j0 += L;
    }
    if nt {
        // SAFETY: the CPU has AVX2 (caller).
        unsafe {
            for d in drains.iter_mut().flatten() {
                d.finish();
            }
        }
        _mm_sfence();
    }
    drop(stage);
    Ok(())
}

/// Group `g`'s constants (lanes `4 g .. 4 g + 4` of `c`).
#[inline]
#[target_feature(enable = "avx2")]
fn consts(c: &[AbConst; AB_LANES], g: usize) -> Consts {
    let lane = |f: fn(&AbConst) -> f64| {
        _mm256_set_pd(
            f(&c[4 * g + 3]),
            f(&c[4 * g + 2]),
            f(&c[4 * g + 1]),
            f(&c[4 * g]),
        )
    };
    Consts {
        t: lane(|c| c.t),
        alpha: lane(|c| c.alpha),
        oma: lane(|c| c.one_minus_alpha),
        g2: lane(|c| c.g2),
    }
}

/// A stage on its way to the outputs: the whole 64-byte lines streamed
/// past the caches a few at a time ([`Drain::lines`]). The partial line at
/// the start is completed with the previous drain's partial line at its end
/// when the two are contiguous (consecutive row groups) and streamed whole;
/// otherwise, and at the end of a call ([`Drain::finish`]), partial lines
/// get plain stores (a plain store to a line not in the caches waits for
/// the line to be read, and the stores behind it wait too).
pub(super) struct Drain<T> {
    dst: *mut T,
    src: *const T,
    /// Next line (elements from `dst`), end of the whole lines.
    at: usize,
    end: usize,
    /// The elements after `end` (fewer than a line), not yet stored.
    tail: [T; 16],
    tail_len: usize,
}

impl<T: IoFloat> Drain<T> {
    /// Start copying `dst.len()` elements from `src` to `dst`, after
    /// finishing `prev` (whose pending partial line is joined with this
    /// one's first one if they meet).
    ///
    /// # Safety
    /// AVX is available; `src` has `dst.len()` readable elements, not
    /// written (and `dst` not accessed otherwise) until the drain is
    /// finished; `prev`'s contract holds.
    #[inline]
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn follow(prev: &mut Option<Self>, dst: &mut [T], src: *const T) -> Self {
        let len = dst.len();
        let es = std::mem::size_of::<T>().max(1);
        let line = 64 / es;
        // SAFETY: forwarded from the caller.
        let src_s = unsafe { std::slice::from_raw_parts(src, len) };
        let head = (((64 - (dst.as_ptr() as usize) % 64) % 64) / es).min(len);
        let end = head + (len - head) / line * line;
        let mut joined = false;
        if let Some(p) = prev.as_mut() {
            // SAFETY: forwarded from the caller.
            unsafe { p.lines(usize::MAX) };
            // SAFETY (pointer only): one past p's last element.
            let p_end = p.dst.wrapping_add(p.end + p.tail_len);
            if head > 0 && p.tail_len + head == line && p_end == dst.as_mut_ptr() {
                let mut buf = p.tail;
                buf[p.tail_len..line].copy_from_slice(&src_s[..head]);
                // SAFETY: p.dst + p.end is line-aligned, and the line is
                // p's tail followed by this head.
                unsafe { copy_line(p.dst.add(p.end), buf.as_ptr(), true) };
                p.tail_len = 0;
                joined = true;
            }
            // SAFETY: forwarded from the caller.
            unsafe { p.finish() };
        }
        if !joined {
            dst[..head].copy_from_slice(&src_s[..head]);
        }
        let mut tail = [T::from_f64(0.0); 16];
        tail[..len - end].copy_from_slice(&src_s[end..]);
        Drain {
            dst: dst.as_mut_ptr(),
            src,
            at: head,
            end,
            tail,
            tail_len: len - end,
        }
    }

    /// Stream the remaining lines and store the pending partial line.
    ///
    /// # Safety
    /// AVX is available; the contract of [`Drain::follow`].
    #[inline]
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn finish(&mut self) {
        // SAFETY: forwarded from the caller; the tail's elements are
        // `end..end + tail_len` of dst.
        unsafe {
            self.lines(usize::MAX);
            std::ptr::copy_nonoverlapping(
                self.tail.as_ptr(),
                self.dst.add(self.end),
                self.tail_len,
            );
        }
        self.tail_len = 0;
    }

    pub(super) fn lines_left(&self) -> usize {
        (self.end - self.at) * std::mem::size_of::<T>() / 64
    }

    /// Stream up to `k` more lines.
    ///
    /// # Safety
    /// AVX is available.
    #[inline]
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn lines(&mut self, k: usize) {
        let step = 64 / std::mem::size_of::<T>().max(1);
        for _ in 0..k {
            if self.at >= self.end {
                break;
            }
            // SAFETY: at + step <= end elements of both (`new`); dst + at is
            // 64-byte aligned (after the head).
            unsafe { copy_line(self.dst.add(self.at), self.src.add(self.at), true) };
            self.at += step;
        }
    }
}
