//! Vector lanes. Alpha-beta (AVX-512): the eight tracks of an [`AB_LANES`]
//! group in the eight `f64` slots of one register. The general kernel:
//! eight tracks per register with AVX-512 ([`gen_lanes8`], groups of
//! [`GEN_LANES8`]), else the four tracks of a [`GEN_LANES`] group in an AVX2
//! register ([`gen_lanes4`]; on an AMD Zen 4 `f64` always takes the four
//! lanes, compiled with AVX-512VL: [`gen_lanes4_zen4`], [`gen8_enabled`]).
//!
//! Each lane reads eight consecutive samples of its own track (one vector
//! load), an 8 x 8 transpose turns the eight rows into eight vectors of "the
//! same step of every track", eight vector steps run the recursion, and two
//! more transposes turn the estimates back into rows for eight-wide stores.
//! A block of 64 samples without NaN takes the steps without the masks of
//! missed detections (the same operations on valid samples). The `z` rows
//! are prefetched [`Z_AHEAD`] samples ahead.
//! The arithmetic of each slot is exactly the scalar [`ab_step`] with FMA
//! (the same fused operations in the same order), so results are
//! bit-identical to the scalar kernel: the lanes that run here and the ones
//! that run scalar (heads, tails, other CPUs) agree to the last bit.
//!
//! Every lane first steps (scalar) to a sample whose output address is
//! aligned to a whole vector, so the stores are aligned and, for outputs too
//! big for the caches, non-temporal (whole lines written without being read
//! first). Lanes may therefore be at different samples; they are
//! independent tracks.

use std::any::TypeId;
use std::arch::x86_64::*;

const W: usize = 8;

/// Software prefetch distance of the alpha-beta lanes' `z` rows, in samples
/// (8 lines of f64, 4 of f32): on the AVX-512 Xeon, 1,000 x 10,000 f64 1.8
/// -> 1.6 ns per sample, f32 1.08 -> 0.97 (docs/benchmarks.md, session 13).
/// The AVX-512 general lanes prefetch as far ahead (3-state 1,000 x 10,000
/// f32 2.2-2.4 -> 1.7-1.9; f64 unchanged at 3.4-3.6; session 15).
const Z_AHEAD: usize = 64;

use super::{ab_step, gen_step, prefetch, AbConst, GenConst, IoFloat, Job, AB_LANES, GEN_LANES};

/// Whether the environment variable `ABKIT_DISABLE_SIMD` (set to anything
/// but `0` before the first call) turns the vector lanes off. The scalar
/// lanes give bit-identical results; the switch exists for comparisons and
/// debugging.
fn disabled() -> bool {
    std::env::var_os("ABKIT_DISABLE_SIMD").is_some_and(|v| v != "0")
}

/// Whether this CPU runs the AVX-512 alpha-beta lanes (checked once).
pub(super) fn available() -> bool {
    use std::sync::OnceLock;
    static OK: OnceLock<bool> = OnceLock::new();
    *OK.get_or_init(|| {
        !disabled() && is_x86_feature_detected!("avx512f") && is_x86_feature_detected!("fma")
    })
}

pub(super) fn is_f64<T: 'static>() -> bool {
    TypeId::of::<T>() == TypeId::of::<f64>()
}

fn is_f32<T: 'static>() -> bool {
    TypeId::of::<T>() == TypeId::of::<f32>()
}

/// Eight consecutive samples at `p`, widened to `f64`.
///
/// # Safety
/// `T` is `f64` or `f32`, `p..p+8` is readable, and AVX-512F is available.
#[inline]
#[target_feature(enable = "avx512f")]
pub(super) unsafe fn load8<T: 'static>(p: *const T) -> __m512d {
    // SAFETY: forwarded from the caller (T is f64 or f32, 8 elements readable).
    unsafe {
        if is_f64::<T>() {
            _mm512_loadu_pd(p as *const f64)
        } else {
            _mm512_cvtps_pd(_mm256_loadu_ps(p as *const f32))
        }
    }
}

/// Store one cache line's worth of values at `p`: the 8 values of `a`
/// (`f64`), or the 16 of `a` then `b` narrowed to `f32` (round to nearest);
/// streamed past the caches if `nt`.
///
/// # Safety
/// `T` is `f64` or `f32`, the 64 bytes at `p` are writable and, if `nt`,
/// aligned to 64 bytes; AVX-512F is available.
#[inline]
#[target_feature(enable = "avx512f")]
pub(super) unsafe fn store_line<T: 'static>(p: *mut T, a: __m512d, b: __m512d, nt: bool) {
    // SAFETY: forwarded from the caller.
    unsafe {
        if is_f64::<T>() {
            if nt {
                _mm512_stream_pd(p as *mut f64, a)
            } else {
                _mm512_storeu_pd(p as *mut f64, a)
            }
        } else {
            let lo = _mm256_castps_pd(_mm512_cvtpd_ps(a));
            let hi = _mm256_castps_pd(_mm512_cvtpd_ps(b));
            let line = _mm512_castpd_ps(_mm512_insertf64x4::<1>(_mm512_castpd256_pd512(lo), hi));
            if nt {
                _mm512_stream_ps(p as *mut f32, line)
            } else {
                _mm512_storeu_ps(p as *mut f32, line)
            }
        }
    }
}

/// Whether none of the 64 values of `rows` is NaN: a NaN makes their sum
/// NaN (a NaN from Inf - Inf only gives a false `false`, which sends a block
/// without NaN down the masked steps: the same bits).
#[inline]
#[target_feature(enable = "avx512f")]
pub(super) fn no_nan8(rows: &[__m512d; W]) -> bool {
    let s01 = _mm512_add_pd(rows[0], rows[1]);
    let s23 = _mm512_add_pd(rows[2], rows[3]);
    let s45 = _mm512_add_pd(rows[4], rows[5]);
    let s67 = _mm512_add_pd(rows[6], rows[7]);
    let sum = _mm512_add_pd(_mm512_add_pd(s01, s23), _mm512_add_pd(s45, s67));
    _mm512_cmp_pd_mask::<_CMP_UNORD_Q>(sum, sum) == 0
}

/// Eight alpha-beta vector steps on transposed samples `zt` none of which is
/// NaN, constants `[t, alpha, 1 - alpha, g2]` per slot: the operations of
/// the masked steps with every sample valid (`zz = z`, `c1 = 1 - alpha`,
/// `g = g2`), so the same bits, four operations fewer per step. The
/// estimates after each step go to `xo`, `vo`.
#[inline]
#[target_feature(enable = "avx512f,fma")]
pub(super) fn clean_steps8(
    zt: &[__m512d; W],
    [ct, calpha, coma, cg2]: [__m512d; 4],
    xv: &mut __m512d,
    vv: &mut __m512d,
    xo: &mut [__m512d; W],
    vo: &mut [__m512d; W],
) {
    for j in 0..W {
        // SAFETY: this function has AVX-512F and FMA.
        unsafe { clean_step8([ct, calpha, coma, cg2], xv, vv, zt[j]) };
        xo[j] = *xv;
        vo[j] = *vv;
    }
}

/// One step of [`clean_steps8`] (no sample NaN): the same bits as
/// [`masked_step8`] on valid samples. Also for the flat kernel's event
/// blocks without NaN.
///
/// # Safety
/// Called only from functions compiled with AVX-512F and FMA (always
/// inlined into them).
#[inline(always)]
pub(super) unsafe fn clean_step8(
    [ct, calpha, coma, cg2]: [__m512d; 4],
    xv: &mut __m512d,
    vv: &mut __m512d,
    zj: __m512d,
) {
    // SAFETY: forwarded from the caller (AVX-512F and FMA).
    unsafe {
        let xp = _mm512_fmadd_pd(ct, *vv, *xv);
        let w = _mm512_fmadd_pd(cg2, zj, *vv);
        *xv = _mm512_fmadd_pd(coma, xp, _mm512_mul_pd(calpha, zj));
        *vv = _mm512_fnmadd_pd(cg2, xp, w);
    }
}

/// Eight alpha-beta vector steps on transposed samples `zt` (NaN = missed:
/// the slot coasts), constants `[t, alpha, 1 - alpha, g2]` per slot: the
/// scalar `ab_step` with FMA in every slot. The estimates after each step go
/// to `xo`, `vo`.
#[inline]
#[target_feature(enable = "avx512f,fma")]
pub(super) fn masked_steps8(
    zt: &[__m512d; W],
    c: [__m512d; 4],
    xv: &mut __m512d,
    vv: &mut __m512d,
    xo: &mut [__m512d; W],
    vo: &mut [__m512d; W],
) {
    let one = _mm512_set1_pd(1.0);
    for j in 0..W {
        // SAFETY: this function has AVX-512F and FMA.
        unsafe { masked_step8(c, one, xv, vv, zt[j]) };
        xo[j] = *xv;
        vo[j] = *vv;
    }
}

/// One alpha-beta vector step on the samples `zj` of the eight slots (NaN =
/// missed: the slot coasts), constants `[t, alpha, 1 - alpha, g2]` per slot,
/// `one` = 1 in every slot: the scalar `ab_step` with FMA in every slot.
/// Shared by [`masked_steps8`] and the flat kernel's event blocks.
///
/// # Safety
/// Called only from functions compiled with AVX-512F and FMA (always
/// inlined into them).
#[inline(always)]
pub(super) unsafe fn masked_step8(
    [ct, calpha, coma, cg2]: [__m512d; 4],
    one: __m512d,
    xv: &mut __m512d,
    vv: &mut __m512d,
    zj: __m512d,
) {
    // SAFETY: forwarded from the caller (AVX-512F and FMA).
    unsafe {
        let xp = _mm512_fmadd_pd(ct, *vv, *xv);
        let valid = _mm512_cmp_pd_mask::<_CMP_ORD_Q>(zj, zj);
        let zz = _mm512_maskz_mov_pd(valid, zj);
        let c1 = _mm512_mask_blend_pd(valid, one, coma);
        let g = _mm512_maskz_mov_pd(valid, cg2);
        let w = _mm512_fmadd_pd(g, zz, *vv);
        *xv = _mm512_fmadd_pd(c1, xp, _mm512_mul_pd(calpha, zz));
        *vv = _mm512_fnmadd_pd(g, xp, w);
    }
}

/// Store the 16 `f32` of `v` at `p`, streamed past the caches if `nt`.
///
/// # Safety
/// The 64 bytes at `p` are writable and, if `nt`, aligned to 64 bytes;
/// AVX-512F is available.
#[inline]
#[target_feature(enable = "avx512f")]
pub(super) unsafe fn store_ps(p: *mut f32, v: __m512, nt: bool) {
    // SAFETY: forwarded from the caller.
    unsafe {
        if nt {
            _mm512_stream_ps(p, v)
        } else {
            _mm512_storeu_ps(p, v)
        }
    }
}

/// In-place transpose of the 8 x 8 matrix whose rows are `r`.
#[inline]
#[target_feature(enable = "avx512f")]
pub(super) fn transpose8(r: &mut [__m512d; 8]) {
    // Stage 1: 2 x 2 blocks within 128-bit lanes.
    let t0 = _mm512_unpacklo_pd(r[0], r[1]);
    let t1 = _mm512_unpackhi_pd(r[0], r[1]);
    let t2 = _mm512_unpacklo_pd(r[2], r[3]);
    let t3 = _mm512_unpackhi_pd(r[2], r[3]);
    let t4 = _mm512_unpacklo_pd(r[4], r[5]);
    let t5 = _mm512_unpackhi_pd(r[4], r[5]);
    let t6 = _mm512_unpacklo_pd(r[6], r[7]);
    let t7 = _mm512_unpackhi_pd(r[6], r[7]);
    // Stage 2: 4 x 4 blocks (128-bit pieces of two rows interleaved).
    let lo = _mm512_set_epi64(13, 12, 5, 4, 9, 8, 1, 0);
    let hi = _mm512_set_epi64(15, 14, 7, 6, 11, 10, 3, 2);
    let u0 = _mm512_permutex2var_pd(t0, lo, t2);
    let u2 = _mm512_permutex2var_pd(t0, hi, t2);
    let u1 = _mm512_permutex2var_pd(t1, lo, t3);
    let u3 = _mm512_permutex2var_pd(t1, hi, t3);
    let u4 = _mm512_permutex2var_pd(t4, lo, t6);
    let u6 = _mm512_permutex2var_pd(t4, hi, t6);
    let u5 = _mm512_permutex2var_pd(t5, lo, t7);
    let u7 = _mm512_permutex2var_pd(t5, hi, t7);
    // Stage 3: 256-bit halves.
    r[0] = _mm512_shuffle_f64x2::<0b01_00_01_00>(u0, u4);
    r[4] = _mm512_shuffle_f64x2::<0b11_10_11_10>(u0, u4);
    r[1] = _mm512_shuffle_f64x2::<0b01_00_01_00>(u1, u5);
    r[5] = _mm512_shuffle_f64x2::<0b11_10_11_10>(u1, u5);
    r[2] = _mm512_shuffle_f64x2::<0b01_00_01_00>(u2, u6);
    r[6] = _mm512_shuffle_f64x2::<0b11_10_11_10>(u2, u6);
    r[3] = _mm512_shuffle_f64x2::<0b01_00_01_00>(u3, u7);
    r[7] = _mm512_shuffle_f64x2::<0b11_10_11_10>(u3, u7);
}

/// Eight rows of 16 `f32` samples transposed in `f32`: on return `r[j]`
/// (`j < 4`) holds the eight rows' samples `j` (low 256 bits) and `4 + j`
/// (high), `r[4 + j]` samples `8 + j` and `12 + j` (lane `l` of each half
/// from row `l`). 24 shuffles for 128 values; the transposes of widened
/// `f64` vectors need 48 (docs/benchmarks.md, session 15).
#[inline]
#[target_feature(enable = "avx512f")]
pub(super) fn transpose8x16(r: &mut [__m512; 8]) {
    let pd = _mm512_castps_pd;
    // Stage 1: pairs of rows interleaved within 128-bit lanes.
    let a01 = pd(_mm512_unpacklo_ps(r[0], r[1]));
    let b01 = pd(_mm512_unpackhi_ps(r[0], r[1]));
    let a23 = pd(_mm512_unpacklo_ps(r[2], r[3]));
    let b23 = pd(_mm512_unpackhi_ps(r[2], r[3]));
    let a45 = pd(_mm512_unpacklo_ps(r[4], r[5]));
    let b45 = pd(_mm512_unpackhi_ps(r[4], r[5]));
    let a67 = pd(_mm512_unpacklo_ps(r[6], r[7]));
    let b67 = pd(_mm512_unpackhi_ps(r[6], r[7]));
    // Stage 2: 128-bit lane q of t[j] = rows 0-3 at sample 4 q + j (u: rows 4-7).
    let t = [
        _mm512_unpacklo_pd(a01, a23),
        _mm512_unpackhi_pd(a01, a23),
        _mm512_unpacklo_pd(b01, b23),
        _mm512_unpackhi_pd(b01, b23),
    ];
    let u = [
        _mm512_unpacklo_pd(a45, a67),
        _mm512_unpackhi_pd(a45, a67),
        _mm512_unpacklo_pd(b45, b67),
        _mm512_unpackhi_pd(b45, b67),
    ];
    // Stage 3: [t.0, u.0, t.1, u.1] and [t.2, u.2, t.3, u.3].
    let ip = _mm512_set_epi64(11, 10, 3, 2, 9, 8, 1, 0);
    let iq = _mm512_set_epi64(15, 14, 7, 6, 13, 12, 5, 4);
    for j in 0..4 {
        r[j] = _mm512_castpd_ps(_mm512_permutex2var_pd(t[j], ip, u[j]));
        r[4 + j] = _mm512_castpd_ps(_mm512_permutex2var_pd(t[j], iq, u[j]));
    }
}

/// The inverse of [`transpose8x16`]: from the per-sample layout back to
/// eight rows of 16 samples.
#[inline]
#[target_feature(enable = "avx512f")]
pub(super) fn untranspose8x16(r: &mut [__m512; 8]) {
    let pd = _mm512_castps_pd;
    let it = _mm512_set_epi64(13, 12, 9, 8, 5, 4, 1, 0);
    let iu = _mm512_set_epi64(15, 14, 11, 10, 7, 6, 3, 2);
    let t: [__m512d; 4] =
        std::array::from_fn(|j| _mm512_permutex2var_pd(pd(r[j]), it, pd(r[4 + j])));
    let u: [__m512d; 4] =
        std::array::from_fn(|j| _mm512_permutex2var_pd(pd(r[j]), iu, pd(r[4 + j])));
    let ps = _mm512_castpd_ps;
    let a01 = ps(_mm512_unpacklo_pd(t[0], t[1]));
    let a23 = ps(_mm512_unpackhi_pd(t[0], t[1]));
    let b01 = ps(_mm512_unpacklo_pd(t[2], t[3]));
    let b23 = ps(_mm512_unpackhi_pd(t[2], t[3]));
    let a45 = ps(_mm512_unpacklo_pd(u[0], u[1]));
    let a67 = ps(_mm512_unpackhi_pd(u[0], u[1]));
    let b45 = ps(_mm512_unpacklo_pd(u[2], u[3]));
    let b67 = ps(_mm512_unpackhi_pd(u[2], u[3]));
    r[0] = _mm512_shuffle_ps::<0b10_00_10_00>(a01, b01);
    r[1] = _mm512_shuffle_ps::<0b11_01_11_01>(a01, b01);
    r[2] = _mm512_shuffle_ps::<0b10_00_10_00>(a23, b23);
    r[3] = _mm512_shuffle_ps::<0b11_01_11_01>(a23, b23);
    r[4] = _mm512_shuffle_ps::<0b10_00_10_00>(a45, b45);
    r[5] = _mm512_shuffle_ps::<0b11_01_11_01>(a45, b45);
    r[6] = _mm512_shuffle_ps::<0b10_00_10_00>(a67, b67);
    r[7] = _mm512_shuffle_ps::<0b11_01_11_01>(a67, b67);
}

/// Sample `s` (0..16) of the eight rows transposed by [`transpose8x16`],
/// widened to `f64` (exact).
#[inline]
#[target_feature(enable = "avx512f")]
pub(super) fn widen_step(r: &[__m512; 8], s: usize) -> __m512d {
    let v = r[(s / 8) * 4 + s % 4];
    let half = if (s / 4).is_multiple_of(2) {
        _mm512_castps512_ps256(v)
    } else {
        _mm256_castpd_ps(_mm512_extractf64x4_pd::<1>(_mm512_castps_pd(v)))
    };
    _mm512_cvtps_pd(half)
}

/// The 16 per-sample `f64` vectors `o[s / 8][s % 8]` narrowed to `f32`
/// (round to nearest, as the scalar conversion) in the layout of
/// [`transpose8x16`].
#[inline]
#[target_feature(enable = "avx512f")]
pub(super) fn narrow_steps(o: &[[__m512d; W]; 2]) -> [__m512; 8] {
    let pair = |lo: __m512d, hi: __m512d| {
        let lo = _mm256_castps_pd(_mm512_cvtpd_ps(lo));
        let hi = _mm256_castps_pd(_mm512_cvtpd_ps(hi));
        _mm512_castpd_ps(_mm512_insertf64x4::<1>(_mm512_castpd256_pd512(lo), hi))
    };
    std::array::from_fn(|i| {
        let (h, j) = (i / 4, i % 4);
        pair(o[h][j], o[h][4 + j])
    })
}

/// Whether none of the 128 `f32` values of `rows` is NaN (as [`no_nan8`]).
#[inline]
#[target_feature(enable = "avx512f")]
pub(super) fn no_nan16(rows: &[__m512; W]) -> bool {
    let s01 = _mm512_add_ps(rows[0], rows[1]);
    let s23 = _mm512_add_ps(rows[2], rows[3]);
    let s45 = _mm512_add_ps(rows[4], rows[5]);
    let s67 = _mm512_add_ps(rows[6], rows[7]);
    let sum = _mm512_add_ps(_mm512_add_ps(s01, s23), _mm512_add_ps(s45, s67));
    _mm512_cmp_ps_mask::<_CMP_UNORD_Q>(sum, sum) == 0
}

/// Lane phases (module docs of `flat`, "Slot phases"): lane `l`, whose
/// current line is `line[l]` (its first output's address / 64), starts one
/// block of `sb` samples later where that line's parity is not `l` plus
/// lane 0's, so that neighbouring lanes' lines alternate in parity.
#[inline]
fn alternate_parities<const L: usize>(k: &mut [usize; L], line: &[usize; L], sb: usize) {
    for l in 1..L {
        if (line[l] ^ line[0] ^ l) & 1 != 0 {
            k[l] += sb;
        }
    }
}

/// The eight lanes over samples `k0..n` (see the module docs): the same
/// contract as the scalar `ab_lanes`, with non-temporal stores if `nt`.
/// The caller checks [`fits`] first.
///
/// # Safety
/// The CPU supports AVX-512F and FMA ([`available`]).
#[allow(clippy::too_many_arguments)]
#[target_feature(enable = "avx512f,fma")]
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
    if !fits::<T>(k0, n)
        || z.iter().any(|r| r.len() < n)
        || xs.iter().chain(vs.iter()).any(|r| r.len() < n)
    {
        super::ab_lanes::<T, true>(c, x_out, v_out, k0, n, z, xs, vs, ahead);
        return;
    }
    let z = z.map(|s| &s[..n]);
    let mut xs = xs.map(|s| &mut s[..n]);
    let mut vs = vs.map(|s| &mut s[..n]);
    let (mut x, mut v) = (*x_out, *v_out);
    // Whole cache lines per lane and block: 8 f64 or 16 f32 samples.
    let bytes = 64;
    let sb = bytes / std::mem::size_of::<T>();
    // Heads: each lane steps to its first sample with an aligned x output
    // (the lanes interleaved, so their dependency chains overlap).
    let mut k = [k0; AB_LANES];
    for l in 0..AB_LANES {
        // Slices of f32/f64 are aligned to their element size, so the
        // misalignment is a whole number of elements.
        let addr = xs[l].as_ptr() as usize + k0 * std::mem::size_of::<T>();
        k[l] = k0 + ((bytes - addr % bytes) % bytes) / std::mem::size_of::<T>();
    }
    // Streamed: the lanes' x lines alternate in parity from lane to lane
    // (a lane off the pattern takes one more line of head steps). On the
    // Intel Xeon of docs/benchmarks.md (session 26) streams whose lines
    // all have the same parity ran up to 1.3x slower: rows of 10,000
    // float64 (1,250 lines, every lane on the same parity) 1.19 -> 0.87 ns
    // per sample. `fits` leaves room: k[l] + sb <= k0 + 31 < n.
    if nt {
        let line: [usize; AB_LANES] = std::array::from_fn(|l| {
            (xs[l].as_ptr() as usize + k[l] * std::mem::size_of::<T>()) / 64
        });
        alternate_parities(&mut k, &line, sb);
    }
    scalar_steps(c, &mut x, &mut v, &z, &mut xs, &mut vs, [k0; AB_LANES], k);
    let aligned =
        |p: *const T, at: usize| (p as usize + at * std::mem::size_of::<T>()).is_multiple_of(bytes);
    let x_aligned: [bool; AB_LANES] = std::array::from_fn(|l| aligned(xs[l].as_ptr(), k[l]));
    let v_aligned: [bool; AB_LANES] = std::array::from_fn(|l| aligned(vs[l].as_ptr(), k[l]));
    let blocks = k.iter().map(|&kl| (n - kl) / sb).min().unwrap_or(0);
    // Streamed f64 rows whose v lines are not at x's line offsets: v in
    // whole lines across blocks (`VLines`).
    let mut vl8: [Option<VLines>; AB_LANES] = std::array::from_fn(|l| {
        if nt && is_f64::<T>() && blocks > 0 && !v_aligned[l] {
            VLines::new(vs[l].as_ptr() as usize + k[l] * 8)
        } else {
            None
        }
    });
    let lane = |f: fn(&AbConst) -> f64| {
        _mm512_set_pd(
            f(&c[7]),
            f(&c[6]),
            f(&c[5]),
            f(&c[4]),
            f(&c[3]),
            f(&c[2]),
            f(&c[1]),
            f(&c[0]),
        )
    };
    let ct = lane(|c| c.t);
    let calpha = lane(|c| c.alpha);
    let coma = lane(|c| c.one_minus_alpha);
    let cg2 = lane(|c| c.g2);
    // SAFETY (loads): x, v are plain arrays of 8 f64.
    let mut xv = unsafe { _mm512_loadu_pd(x.as_ptr()) };
    let mut vv = unsafe { _mm512_loadu_pd(v.as_ptr()) };
    let zero = _mm512_setzero_pd();
    let cs = [ct, calpha, coma, cg2];
    // Prefetches for lane `l`'s 8 samples at `at`: the next group's `z` (and,
    // unless streamed, outputs) and, once per block (`first`), this row's
    // `z` Z_AHEAD samples ahead.
    let (zp, xp, vp): (
        [*const T; AB_LANES],
        [*const T; AB_LANES],
        [*const T; AB_LANES],
    ) = (
        std::array::from_fn(|l| z[l].as_ptr()),
        std::array::from_fn(|l| xs[l].as_ptr()),
        std::array::from_fn(|l| vs[l].as_ptr()),
    );
    let fetch = |l: usize, at: usize, first: bool| {
        if let Some((dz, dout)) = ahead {
            prefetch(zp[l].wrapping_add(dz + at));
            if !nt {
                prefetch(xp[l].wrapping_add(dout + at));
                prefetch(vp[l].wrapping_add(dout + at));
            }
        }
        if first {
            prefetch(zp[l].wrapping_add(at + Z_AHEAD));
        }
    };
    for b in 0..blocks {
        let mut xbuf = [[zero; W]; 2];
        let mut vbuf = [[zero; W]; 2];
        if is_f32::<T>() {
            // f32: one line of 16 samples per lane, transposed as f32.
            let mut rows = [_mm512_setzero_ps(); W];
            for l in 0..AB_LANES {
                let at = k[l] + b * sb;
                fetch(l, at, true);
                fetch(l, at + W, false);
                // SAFETY: T is f32 and at + sb <= k[l] + blocks * sb <= n = z[l].len().
                rows[l] = unsafe { _mm512_loadu_ps(z[l].as_ptr().add(at) as *const f32) };
            }
            let clean = no_nan16(&rows);
            transpose8x16(&mut rows);
            for h in 0..2 {
                let zt: [__m512d; W] = std::array::from_fn(|j| widen_step(&rows, h * W + j));
                let (xo, vo) = (&mut xbuf[h], &mut vbuf[h]);
                if clean {
                    clean_steps8(&zt, cs, &mut xv, &mut vv, xo, vo);
                } else {
                    masked_steps8(&zt, cs, &mut xv, &mut vv, xo, vo);
                }
            }
            let mut xl = narrow_steps(&xbuf);
            let mut vl = narrow_steps(&vbuf);
            untranspose8x16(&mut xl);
            untranspose8x16(&mut vl);
            for l in 0..AB_LANES {
                let at = k[l] + b * sb;
                // SAFETY: as for the f64 stores below (T is f32).
                unsafe {
                    store_ps(
                        xs[l].as_mut_ptr().add(at) as *mut f32,
                        xl[l],
                        nt && x_aligned[l],
                    );
                    store_ps(
                        vs[l].as_mut_ptr().add(at) as *mut f32,
                        vl[l],
                        nt && v_aligned[l],
                    );
                }
            }
            continue;
        }
        for h in 0..sb / W {
            let mut rows = [zero; W];
            for l in 0..AB_LANES {
                let at = k[l] + b * sb + h * W;
                fetch(l, at, h == 0);
                // SAFETY: at + W <= k[l] + blocks * sb <= n = z[l].len().
                rows[l] = unsafe { load8(z[l].as_ptr().add(at)) };
            }
            let clean = no_nan8(&rows);
            transpose8(&mut rows);
            let (xo, vo) = (&mut xbuf[h], &mut vbuf[h]);
            if clean {
                clean_steps8(&rows, cs, &mut xv, &mut vv, xo, vo);
            } else {
                masked_steps8(&rows, cs, &mut xv, &mut vv, xo, vo);
            }
            transpose8(xo);
            transpose8(vo);
        }
        // The x lines of all lanes, then their v lines (in lane order, so
        // each stream's parities alternate as the lanes' do).
        for l in 0..AB_LANES {
            let at = k[l] + b * sb;
            // SAFETY: at + sb <= n = xs[l].len(); x stores are line-aligned
            // by the head.
            unsafe {
                store_line(
                    xs[l].as_mut_ptr().add(at),
                    xbuf[0][l],
                    xbuf[1][l],
                    nt && x_aligned[l],
                )
            };
        }
        for l in 0..AB_LANES {
            let at = k[l] + b * sb;
            // SAFETY: at + sb <= n = vs[l].len(); v stores are streamed only
            // if aligned, else (streamed f64) whole lines across blocks.
            unsafe {
                if let Some(vl) = vl8[l].as_mut() {
                    vl.put(vs[l].as_mut_ptr().add(at) as *mut f64, b == 0, vbuf[0][l]);
                } else {
                    store_line(
                        vs[l].as_mut_ptr().add(at),
                        vbuf[0][l],
                        vbuf[1][l],
                        nt && v_aligned[l],
                    );
                }
            }
        }
    }
    for l in 0..AB_LANES {
        if let Some(vl) = vl8[l].as_ref() {
            // SAFETY: the last block's samples, inside vs[l] (blocks > 0).
            unsafe { vl.flush(vs[l].as_mut_ptr().add(k[l] + (blocks - 1) * sb) as *mut f64) };
        }
    }
    if nt {
        _mm_sfence();
    }
    // SAFETY: x, v are plain arrays of 8 f64.
    unsafe {
        _mm512_storeu_pd(x.as_mut_ptr(), xv);
        _mm512_storeu_pd(v.as_mut_ptr(), vv);
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

/// One lane's `f64` `v` row streamed in whole lines when its lines are not
/// at the `x` row's line offsets (the blocks follow `x`'s lines): `v`'s
/// lines begin at block sample `e`, so each line is the last `8 - e`
/// samples of the previous block and the first `e` of the current one (one
/// permute). Ordinary stores of those rows read each line from memory
/// first: 999 x 10,001 `f64` 1.16 ns per sample with them, 0.86-0.92 with
/// these lines (and the row lanes' store order; docs/benchmarks.md,
/// session 26).
pub(super) struct VLines {
    e: usize,
    idx: __m512i,
    prev: __m512d,
}

impl VLines {
    /// For a `v` row whose first block starts at address `addr` (8-byte
    /// aligned; `None` if it is not, or if the row's lines start with the
    /// block).
    #[target_feature(enable = "avx512f")]
    pub(super) fn new(addr: usize) -> Option<VLines> {
        if !addr.is_multiple_of(8) || addr.is_multiple_of(64) {
            return None;
        }
        let e = (64 - addr % 64) / 8;
        Some(VLines {
            e,
            idx: Self::idx(e),
            prev: _mm512_setzero_pd(),
        })
    }

    /// `_mm512_permutex2var_pd` indices that take elements `e..8` of the
    /// first vector, then `0..e` of the second (`0 < e < 8`).
    #[target_feature(enable = "avx512f")]
    pub(super) fn idx(e: usize) -> __m512i {
        let idx: [i64; 8] = std::array::from_fn(|i| (i + e) as i64);
        // SAFETY: eight i64 read from an array of eight.
        unsafe { _mm512_loadu_si512(idx.as_ptr() as *const _) }
    }

    /// The block at `p` (8 samples) has the estimates `cur`: store the line
    /// ending at `p + e` (the first block: only its samples before `e`),
    /// keep the rest.
    ///
    /// # Safety
    /// `p..p + 8` is writable (and, but for the first block, so is
    /// `p - 8..p`); AVX-512F.
    #[inline(always)]
    pub(super) unsafe fn put(&mut self, p: *mut f64, first: bool, cur: __m512d) {
        // SAFETY: forwarded; `p + e - 8` is a line start.
        unsafe {
            if first {
                _mm512_mask_storeu_pd(p, ((1u32 << self.e) - 1) as u8, cur);
            } else {
                let line = _mm512_permutex2var_pd(self.prev, self.idx, cur);
                _mm512_stream_pd(p.add(self.e).sub(8), line);
            }
        }
        self.prev = cur;
    }

    /// The last block (at `p`): store its samples kept back.
    ///
    /// # Safety
    /// `p..p + 8` is writable; AVX-512F.
    #[inline(always)]
    pub(super) unsafe fn flush(&self, p: *mut f64) {
        // SAFETY: forwarded.
        unsafe { _mm512_mask_storeu_pd(p, !((1u32 << self.e) - 1) as u8, self.prev) };
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

/// Whether [`ab_lanes8`] handles `T` and samples `k0..n` (rows long enough
/// for the vector loop to pay).
pub(super) fn fits<T: 'static>(k0: usize, n: usize) -> bool {
    (is_f64::<T>() || is_f32::<T>()) && n >= k0 + 32
}

// ---------------------------------------------------------------------------
// The general kernel: GEN_LANES = 4 tracks in the 4 f64 slots of an AVX2
// register.
// ---------------------------------------------------------------------------

/// Whether this CPU runs the AVX2 general lanes (checked once; the same
/// `ABKIT_DISABLE_SIMD` switch as [`available`]).
pub(super) fn avx2_available() -> bool {
    use std::sync::OnceLock;
    static OK: OnceLock<bool> = OnceLock::new();
    *OK.get_or_init(|| {
        !disabled() && is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma")
    })
}

/// Four consecutive values at `p`, widened to `f64`.
///
/// # Safety
/// `T` is `f64` or `f32`, `p..p+4` is readable, and AVX is available.
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

/// Store four values at `p`, narrowed to `T` (round to nearest); streamed
/// past the caches if `nt`.
///
/// # Safety
/// `T` is `f64` or `f32`, `p..p+4` is writable and, if `nt`, aligned to 4
/// values (32 or 16 bytes); AVX is available.
#[inline]
#[target_feature(enable = "avx2")]
unsafe fn store4<T: 'static>(p: *mut T, v: __m256d, nt: bool) {
    // SAFETY: forwarded from the caller.
    unsafe {
        if is_f64::<T>() {
            if nt {
                _mm256_stream_pd(p as *mut f64, v)
            } else {
                _mm256_storeu_pd(p as *mut f64, v)
            }
        } else {
            let v = _mm256_cvtpd_ps(v);
            if nt {
                _mm_stream_ps(p as *mut f32, v)
            } else {
                _mm_storeu_ps(p as *mut f32, v)
            }
        }
    }
}

/// In-place transpose of the 4 x 4 matrix whose rows are `r`.
#[inline]
#[target_feature(enable = "avx2")]
fn transpose4(r: &mut [__m256d; 4]) {
    let t0 = _mm256_unpacklo_pd(r[0], r[1]);
    let t1 = _mm256_unpackhi_pd(r[0], r[1]);
    let t2 = _mm256_unpacklo_pd(r[2], r[3]);
    let t3 = _mm256_unpackhi_pd(r[2], r[3]);
    r[0] = _mm256_permute2f128_pd::<0x20>(t0, t2);
    r[1] = _mm256_permute2f128_pd::<0x20>(t1, t3);
    r[2] = _mm256_permute2f128_pd::<0x31>(t0, t2);
    r[3] = _mm256_permute2f128_pd::<0x31>(t1, t3);
}

/// Rows shorter than this (after the start) run the general lanes without
/// aligning heads (`f32` always, `f64` unless its outputs are streamed).
const SHORT_F32: usize = 512;

/// The general gains of four lanes in vectors (slot `l`: lane `l`'s).
struct GenMats<const N: usize, const M: usize> {
    a: [[__m256d; N]; N],
    phi: [[__m256d; N]; N],
    k: [[__m256d; M]; N],
}

/// One vector step of four lanes on their measurement vectors `zs`
/// (component `j` of each lane in `zs[j]`): `A x + K z` where every
/// component of a lane's `z` is valid, else the coast `Phi x` (computed only
/// if some lane needs it). Per slot exactly the scalar `gen_step` (the same
/// FMAs in the same order).
#[inline]
#[target_feature(enable = "avx2,fma")]
fn gen_vstep<const N: usize, const M: usize>(
    g: &GenMats<N, M>,
    x: &[__m256d; N],
    zs: &[__m256d; M],
) -> [__m256d; N] {
    let mut valid = _mm256_cmp_pd::<_CMP_ORD_Q>(zs[0], zs[0]);
    for zc in zs.iter().skip(1) {
        valid = _mm256_and_pd(valid, _mm256_cmp_pd::<_CMP_ORD_Q>(*zc, *zc));
    }
    let all_valid = _mm256_movemask_pd(valid) == 0xf;
    std::array::from_fn(|i| {
        let mut u = _mm256_mul_pd(g.k[i][0], zs[0]);
        for j in 1..M {
            u = _mm256_fmadd_pd(g.k[i][j], zs[j], u);
        }
        for j in 0..N {
            u = _mm256_fmadd_pd(g.a[i][j], x[j], u);
        }
        if all_valid {
            return u;
        }
        let mut p = _mm256_setzero_pd();
        for j in 0..N {
            p = _mm256_fmadd_pd(g.phi[i][j], x[j], p);
        }
        _mm256_blendv_pd(p, u, valid)
    })
}

/// Vector steps of the four general lanes, lane `l` over samples
/// `from[l]..to[l]` (its step `s` at sample `from[l] + s`; a lane whose
/// range is done keeps its state): per step the running lanes' `z` gathered
/// into vectors (a done lane's slot gets 0), one [`gen_vstep`], the new
/// state blended in where a lane runs, and each running lane's outputs
/// stored. The heads and tails of the rows around the vector blocks: the
/// same bits as the scalar `gen_step` per lane, in a third of the time of
/// stepping the four lanes one after the other (3-state rows of 100
/// samples; docs/benchmarks.md, session 10).
///
/// # Safety
/// AVX2 and FMA; for every lane
/// `to[l] * M <= rows[l].len()` and `out[l][i]` has `to[l]` writable
/// elements.
#[inline]
#[target_feature(enable = "avx2,fma")]
unsafe fn gen_masked_steps<T: IoFloat, const N: usize, const M: usize>(
    g: &GenMats<N, M>,
    x: &mut [__m256d; N],
    rows: &[&[T]; GEN_LANES],
    out: &[[*mut T; N]; GEN_LANES],
    from: [usize; GEN_LANES],
    to: [usize; GEN_LANES],
) {
    const L: usize = GEN_LANES;
    let most = (0..L)
        .map(|l| to[l].saturating_sub(from[l]))
        .max()
        .unwrap_or(0);
    // SAFETY: every access below is at a running sample k < to[l] of lane
    // l (the caller's bounds); the rest is register and stack work.
    unsafe {
        for s in 0..most {
            let mut zl = [[0.0f64; L]; M];
            let mut run = [0i64; L];
            for l in 0..L {
                let k = from[l] + s;
                if k < to[l] {
                    for (j, zj) in zl.iter_mut().enumerate() {
                        zj[l] = rows[l].get_unchecked(k * M + j).to_f64();
                    }
                    run[l] = -1;
                }
            }
            let zs: [__m256d; M] = std::array::from_fn(|j| _mm256_loadu_pd(zl[j].as_ptr()));
            let xn = gen_vstep(g, x, &zs);
            let runv = _mm256_castsi256_pd(_mm256_loadu_si256(run.as_ptr() as *const __m256i));
            let mut t = [[0.0f64; L]; N];
            for i in 0..N {
                x[i] = _mm256_blendv_pd(x[i], xn[i], runv);
                _mm256_storeu_pd(t[i].as_mut_ptr(), xn[i]);
            }
            for l in 0..L {
                let k = from[l] + s;
                if k < to[l] {
                    for i in 0..N {
                        *out[l][i].add(k) = T::from_f64(t[i][l]);
                    }
                }
            }
        }
    }
}

/// The four general lanes over samples `k0..n`: `rows[l]` holds lane `l`'s
/// measurements (`n * M` values, sample-major), `group[l].2.states[i]` its
/// outputs, `x[l]` its state (updated). Each lane first steps to a sample
/// where its first output row is aligned to a cache line (lanes are
/// independent tracks, so they may be at different samples; these heads,
/// and the tails after the last whole block, run as masked vector steps,
/// [`gen_masked_steps`]); then blocks of one output line (8 `f64` or 16
/// `f32` samples): per 4 samples each lane loads `4 M` consecutive values,
/// 4 x 4 transposes give per-sample vectors across the lanes, the steps run
/// in vectors ([`gen_vstep`]: the update `A x + K z`, and where some lane
/// misses a component also the coast `Phi x`, blended per lane on "every
/// component valid"), and transposes give the rows back, stored as whole
/// lines (non-temporal if `nt`, for aligned rows). Each slot does exactly
/// the scalar `gen_step` arithmetic (same FMAs, same order), so results
/// are bit-identical to the scalar lanes. The streamed stores are not
/// fenced here: the caller runs [`super::store_fence`] before the outputs
/// are read (once per task, not per group of four tracks).
///
/// # Safety
/// The CPU supports AVX2 and FMA ([`avx2_available`]).
#[allow(clippy::too_many_arguments)]
#[target_feature(enable = "avx2,fma")]
pub(super) unsafe fn gen_lanes4<T: IoFloat, const N: usize, const M: usize>(
    cs: [&GenConst<N, M>; GEN_LANES],
    xs: &mut [[f64; N]; GEN_LANES],
    k0: usize,
    n: usize,
    rows: [&[T]; GEN_LANES],
    group: &mut [Job<'_, T, N>],
    ahead: Option<(usize, usize)>,
    nt: bool,
) {
    // SAFETY: forwarded.
    unsafe { gen_lanes4_body::<T, N, M>(cs, xs, k0, n, rows, group, ahead, nt) }
}

/// [`gen_lanes4`] compiled with AVX-512VL too (32 vector registers; the
/// same operations, so the same bits): the `f64` general lanes on an AMD
/// Zen 4 (`filter::zen4_forms`). There (`genbench`, 3-state `f64`, ns per
/// sample, plain -> Zen 4 form) 19,531 x 512 2.00 -> 1.70, 4,882 x 2,048
/// 1.76 -> 1.38, 10,000 x 1,000 1.27 -> 1.12, 1,000 x 10,000 1.15 -> 1.07,
/// rows of 64-200 about equal; `f32` rows of 64-100 (which stay in the 4
/// lanes) were 7-12 % slower in it, so `f32` keeps the plain kernel
/// (docs/benchmarks.md, session 35).
///
/// # Safety
/// The CPU supports AVX2, FMA, AVX-512F and AVX-512VL.
#[allow(clippy::too_many_arguments)]
#[target_feature(enable = "avx2,fma,avx512f,avx512vl")]
pub(super) unsafe fn gen_lanes4_zen4<T: IoFloat, const N: usize, const M: usize>(
    cs: [&GenConst<N, M>; GEN_LANES],
    xs: &mut [[f64; N]; GEN_LANES],
    k0: usize,
    n: usize,
    rows: [&[T]; GEN_LANES],
    group: &mut [Job<'_, T, N>],
    ahead: Option<(usize, usize)>,
    nt: bool,
) {
    // SAFETY: forwarded.
    unsafe { gen_lanes4_body::<T, N, M>(cs, xs, k0, n, rows, group, ahead, nt) }
}

#[allow(clippy::too_many_arguments)]
#[inline(always)]
unsafe fn gen_lanes4_body<T: IoFloat, const N: usize, const M: usize>(
    cs: [&GenConst<N, M>; GEN_LANES],
    xs: &mut [[f64; N]; GEN_LANES],
    k0: usize,
    n: usize,
    rows: [&[T]; GEN_LANES],
    group: &mut [Job<'_, T, N>],
    ahead: Option<(usize, usize)>,
    nt: bool,
) {
    const L: usize = GEN_LANES;
    // Samples per block: one 64-byte line of output per lane and component
    // (8 f64 or 16 f32); `BMAX` sizes the buffers.
    const BMAX: usize = 4 * L;
    let size = std::mem::size_of::<T>();
    let bs = (64 / size).min(BMAX);
    let ok = gen_fits::<T>(M)
        && group.len() == L
        && rows.iter().all(|r| r.len() >= n * M)
        && group
            .iter()
            .all(|j| j.2.states.iter().all(|s| s.len() >= n))
        && n >= k0 + 4 * bs;
    if !ok {
        gen_scalar_steps(cs, xs, &rows, group, [k0; L], [n; L]);
        return;
    }
    // Short rows skip the aligning heads where they buy nothing: in f32
    // (up to 15 steps of a short row cost more than the unaligned stores)
    // and, unless streamed, in f64 (the heads only make streamed stores
    // possible; 3-state rows of 100 samples: 2,000 rows 2.75 -> 2.46,
    // 20,000 rows 3.2-3.4 -> 2.9-3.2 ns per sample on Zen 3, with scalar
    // heads).
    let short = n.saturating_sub(k0) < SHORT_F32;
    let align = !((is_f32::<T>() || !nt) && short);
    let out: [[*mut T; N]; L] =
        std::array::from_fn(|l| std::array::from_fn(|i| group[l].2.states[i].as_mut_ptr()));
    let mut k = [k0; L];
    if align {
        for l in 0..L {
            let addr = out[l][0] as usize + k0 * size;
            k[l] = k0 + ((64 - addr % 64) % 64) / size;
        }
    }
    // One set of gains for the four lanes (the usual case): broadcasts.
    let shared = cs.iter().all(|c| std::ptr::eq(*c, cs[0]));
    let v4 = |f: &dyn Fn(&GenConst<N, M>) -> f64| {
        if shared {
            _mm256_set1_pd(f(cs[0]))
        } else {
            _mm256_set_pd(f(cs[3]), f(cs[2]), f(cs[1]), f(cs[0]))
        }
    };
    let g = GenMats::<N, M> {
        a: std::array::from_fn(|i| std::array::from_fn(|j| v4(&|c| c.a[i][j]))),
        phi: std::array::from_fn(|i| std::array::from_fn(|j| v4(&|c| c.phi[i][j]))),
        k: std::array::from_fn(|i| std::array::from_fn(|j| v4(&|c| c.k[i][j]))),
    };
    let mut x: [__m256d; N] =
        std::array::from_fn(|i| _mm256_set_pd(xs[3][i], xs[2][i], xs[1][i], xs[0][i]));
    let blocks = k
        .iter()
        .map(|&kl| n.saturating_sub(kl) / bs)
        .min()
        .unwrap_or(0);
    // Each lane's tail (after the last whole block): samples from[l]..n.
    let from: [usize; L] = std::array::from_fn(|l| (k[l] + blocks * bs).min(n));
    // Streamed rows: the lines that the start-up, heads and tails write with
    // ordinary stores (the row's first line, every line of the tail: up to
    // two when the lanes' alignments differ) of the output rows sixteen rows
    // ahead, fetched for ownership now; else each such store waits for its
    // line from memory and holds up the stores behind it (as in
    // `gen_lanes8`). For contiguous rows of `n` samples those lines lie at
    // the same offsets as this group's (16 rows are whole lines); otherwise
    // the hints are merely less useful.
    if nt && align {
        if let Some((_, dout)) = ahead {
            for (l, ol) in out.iter().enumerate() {
                for &o in ol.iter() {
                    let p = o.wrapping_add(4 * dout);
                    _mm_prefetch::<_MM_HINT_ET0>(p as *const i8);
                    let mut s = from[l];
                    while s < n {
                        _mm_prefetch::<_MM_HINT_ET0>(p.wrapping_add(s) as *const i8);
                        s += bs;
                    }
                }
            }
        }
    }
    // SAFETY: k[l] <= k0 + 7 < n (n >= k0 + 4 bs), rows hold n M values and
    // every output row n values (`ok`).
    unsafe { gen_masked_steps(&g, &mut x, &rows, &out, [k0; L], k) };
    let stream: [[bool; N]; L] = std::array::from_fn(|l| {
        std::array::from_fn(|i| nt && (out[l][i] as usize + k[l] * size).is_multiple_of(64))
    });
    let zero = _mm256_setzero_pd();
    // Block outputs: every entry read is written earlier in the same block
    // (entries `0..bs` of each component), so they are not initialised (a
    // 1.5 KiB memset per group of four short rows otherwise).
    let mut outv = [[std::mem::MaybeUninit::<__m256d>::uninit(); BMAX]; N];
    // Each lane's and component's output at the current block's first
    // sample, advanced by a block at a time: one pointer load per store
    // instead of the address arithmetic of `k[l] + b bs + q L` per store.
    let mut at: [[*mut T; N]; L] =
        std::array::from_fn(|l| std::array::from_fn(|i| out[l][i].wrapping_add(k[l])));
    // Whether every output row is streamed, none is, or some are: the
    // stores' kind is decided once, not per store.
    let all_nt = stream.iter().all(|s| s.iter().all(|&b| b));
    let no_nt = stream.iter().all(|s| s.iter().all(|&b| !b));
    // The block's stores: per component and group of 4 samples, a 4 x 4
    // transpose and one store per lane.
    macro_rules! store_block {
        ($l:ident, $i:ident, $nt:expr) => {
            for ($i, ov) in outv.iter().enumerate() {
                for q in 0..bs / L {
                    // SAFETY: entries q L + s < bs were written in this block.
                    let mut r: [__m256d; L] =
                        std::array::from_fn(|s| unsafe { ov[q * L + s].assume_init() });
                    transpose4(&mut r);
                    for $l in 0..L {
                        // SAFETY: at[l][i] + q L + L <= out[l][i] + k[l] + (b + 1) bs
                        // <= out[l][i] + n (blocks <= (n - k[l]) / bs), within
                        // states[i]; streamed rows are aligned to 64 bytes at
                        // k[l] (checked in `stream`), so to 4 values here.
                        unsafe { store4(at[$l][$i].add(q * L), r[$l], $nt) };
                    }
                }
            }
        };
    }
    for b in 0..blocks {
        if let Some((dz, dout)) = ahead {
            for l in 0..L {
                prefetch(rows[l].as_ptr().wrapping_add(dz + (k[l] + b * bs) * M));
                // Outputs stored with ordinary stores (also the unaligned,
                // unstreamed short f32 rows of a streamed batch: 2.51 -> 2.38
                // ns per sample on 3-state 100,000 x 100, session 22).
                if !all_nt {
                    for o in &at[l] {
                        prefetch(o.wrapping_add(dout));
                    }
                }
            }
        }
        for h in 0..bs / L {
            // zs[s][c]: component c of each lane's sample k[l] + b bs + h L + s.
            let mut zs = [[zero; M]; L];
            for gc in 0..M {
                let mut r: [__m256d; L] = std::array::from_fn(|l| {
                    let at = (k[l] + b * bs + h * L) * M + gc * L;
                    // SAFETY: at + L <= (k[l] + (b + 1) bs) M <= n M <= rows[l].len().
                    unsafe { load4(rows[l].as_ptr().add(at)) }
                });
                transpose4(&mut r);
                for (i, ri) in r.iter().enumerate() {
                    let idx = gc * L + i;
                    zs[idx / M][idx % M] = *ri;
                }
            }
            for (s, zsv) in zs.iter().enumerate() {
                x = gen_vstep(&g, &x, zsv);
                for i in 0..N {
                    outv[i][h * L + s] = std::mem::MaybeUninit::new(x[i]);
                }
            }
        }
        if all_nt {
            store_block!(l, i, true);
        } else if no_nt {
            store_block!(l, i, false);
        } else {
            store_block!(l, i, stream[l][i]);
        }
        for a in at.iter_mut() {
            for p in a.iter_mut() {
                *p = p.wrapping_add(bs);
            }
        }
    }
    // No fence here: the streamed stores are ordered by the caller's
    // `store_fence`, once per task (one per group cost 4 % on 100,000 x 100).
    // SAFETY: as for the heads (from[l] <= n).
    unsafe { gen_masked_steps(&g, &mut x, &rows, &out, from, [n; L]) };
    for i in 0..N {
        let mut t = [0.0; L];
        // SAFETY: t is a plain array of 4 f64.
        unsafe { _mm256_storeu_pd(t.as_mut_ptr(), x[i]) };
        for l in 0..L {
            xs[l][i] = t[l];
        }
    }
}

/// Scalar steps of every general lane `l` over samples `from[l]..to[l]`,
/// the lanes interleaved.
#[inline]
#[target_feature(enable = "fma")]
fn gen_scalar_steps<T: IoFloat, const N: usize, const M: usize>(
    cs: [&GenConst<N, M>; GEN_LANES],
    xs: &mut [[f64; N]; GEN_LANES],
    rows: &[&[T]; GEN_LANES],
    group: &mut [Job<'_, T, N>],
    from: [usize; GEN_LANES],
    to: [usize; GEN_LANES],
) {
    let most = (0..GEN_LANES)
        .map(|l| to[l].saturating_sub(from[l]))
        .max()
        .unwrap_or(0);
    for s in 0..most {
        for l in 0..GEN_LANES.min(group.len()) {
            let k = from[l] + s;
            if k < to[l] {
                let zk: [f64; M] = std::array::from_fn(|j| rows[l][k * M + j].to_f64());
                xs[l] = gen_step::<N, M, true>(cs[l], &xs[l], &zk);
                let o = &mut group[l].2;
                for i in 0..N {
                    o.states[i][k] = T::from_f64(xs[l][i]);
                }
            }
        }
    }
}

/// Whether [`gen_lanes4`] handles `T` and `M`.
pub(super) fn gen_fits<T: 'static>(m: usize) -> bool {
    (is_f64::<T>() || is_f32::<T>()) && (m == 1 || m == 2)
}

// ---------------------------------------------------------------------------
// The general kernel on AVX-512: GEN_LANES8 = 8 tracks in the 8 f64 slots of
// a zmm register.
// ---------------------------------------------------------------------------

/// Tracks of an AVX-512 general group.
pub(super) const GEN_LANES8: usize = 8;

/// Rows at least this long run in the AVX-512 general lanes by default
/// (float64 only), or at least [`GEN8_MIN_SAMPLES_STREAMED`] if the outputs
/// are streamed. On the AVX-512 Xeon (3-state, one thread, outputs reused,
/// ns per sample, 4 lanes -> 8 lanes): 1,000 x 10,000 f64 4.5 -> 3.2-3.4,
/// 3,000 x 1,000 2.9-3.1 -> 2.6-2.8, 50,000 x 200 5.0 -> 3.8, 100,000 x 100
/// 6.6 -> 5.4; but 100,000 x 64 6.0 -> 9.0, 2,000 x 100 (in the caches) 2.3
/// -> 3.7 (docs/benchmarks.md, session 13). Float32: [`GEN8_MIN_SAMPLES_F32`].
pub(super) const GEN8_MIN_SAMPLES: usize = 512;

/// Float32 rows at least this long (streamed or not) run in the AVX-512
/// general lanes, which transpose float32 as float32 ([`transpose8x16`]).
/// On the AVX-512 Xeon (3-state, ns per sample, 4 lanes -> 8 lanes):
/// 10 x 100,000 3.7 -> 2.0, 1,000 x 10,000 2.9 -> 2.2, 40,000 x 250 4.2 ->
/// 3.4-3.6, 2,000 x 300 2.95 -> 2.7; 100,000 x 100 5.3-6.0 either way
/// (docs/benchmarks.md, session 15).
pub(super) const GEN8_MIN_SAMPLES_F32: usize = 200;

/// [`GEN8_MIN_SAMPLES`] for streamed outputs.
pub(super) const GEN8_MIN_SAMPLES_STREAMED: usize = 100;

/// Whether the AVX-512 general lanes ([`gen_lanes8`]) run for rows of `n`
/// samples of `T` (outputs streamed if `nt`): where [`available`], for `f64`
/// rows of at least [`GEN8_MIN_SAMPLES`] ([`GEN8_MIN_SAMPLES_STREAMED`] if
/// `nt`) and `f32` rows of at least [`GEN8_MIN_SAMPLES_F32`]; on an AMD
/// Zen 4 ([`super::zen4_forms`]) `f64` never by default: there the 4-lane
/// kernel's Zen 4 form ([`gen_lanes4_zen4`]) was faster on every `f64`
/// shape measured (`genbench`, 3-state, from memory, one thread, minimum
/// of 3 alternated runs, ns per sample, 8 lanes -> 4 lanes' Zen 4 form):
/// 100,000 x 100 2.66 -> 1.76, 50,000 x 200 2.02 -> 1.38, 19,531 x 512
/// 2.95 -> 1.70, 10,000 x 1,000 1.65 -> 1.12, 4,882 x 2,048 2.46 -> 1.38,
/// 1,000 x 10,000 1.61 -> 1.07, one track of 10^7 (split) 1.67 -> 1.08;
/// `f32` was as fast or faster in the 8 lanes, so it keeps them
/// (docs/benchmarks.md, session 35). The environment variable
/// `ABKIT_GEN_AVX512` (read once) overrides: `0` never, anything else
/// always (short rows too).
/// Results are the same bits either way (tests/test_filters_lanes.py,
/// `test_general_lanes8_equal_scalar_bitwise`).
pub(super) fn gen8_enabled<T: 'static>(n: usize, nt: bool) -> bool {
    use std::sync::OnceLock;
    static MODE: OnceLock<Option<bool>> = OnceLock::new();
    let mode = *MODE.get_or_init(|| std::env::var_os("ABKIT_GEN_AVX512").map(|v| v != "0"));
    let min = if is_f32::<T>() {
        GEN8_MIN_SAMPLES_F32
    } else if nt {
        GEN8_MIN_SAMPLES_STREAMED
    } else {
        GEN8_MIN_SAMPLES
    };
    available() && mode.unwrap_or((is_f64::<T>() || is_f32::<T>()) && n >= min && !gen_zen4::<T>())
}

/// Whether the general lanes of `T` take their AMD Zen 4 routing: `f64`
/// on a CPU with the Zen 4 forms ([`super::zen4_forms`]) runs the 4-lane
/// kernel's Zen 4 form ([`gen_lanes4_zen4`]) and never the 8 lanes by
/// default ([`gen8_enabled`]).
pub(super) fn gen_zen4<T: 'static>() -> bool {
    is_f64::<T>() && super::zen4_forms()
}

/// The general gains of eight lanes in vectors (slot `l`: lane `l`'s).
struct GenMats8<const N: usize, const M: usize> {
    a: [[__m512d; N]; N],
    phi: [[__m512d; N]; N],
    k: [[__m512d; M]; N],
}

/// One vector step of eight general lanes on their measurement vectors `zs`
/// (the AVX-512 [`gen_vstep`]): `A x + K z` where every component of a
/// lane's `z` is valid, else the coast `Phi x` (computed only if some lane
/// needs it); per slot exactly the scalar `gen_step`.
#[inline]
#[target_feature(enable = "avx512f,fma")]
fn gen_vstep8<const N: usize, const M: usize>(
    g: &GenMats8<N, M>,
    x: &[__m512d; N],
    zs: &[__m512d; M],
) -> [__m512d; N] {
    let mut valid = _mm512_cmp_pd_mask::<_CMP_ORD_Q>(zs[0], zs[0]);
    for zc in zs.iter().skip(1) {
        valid &= _mm512_cmp_pd_mask::<_CMP_ORD_Q>(*zc, *zc);
    }
    std::array::from_fn(|i| {
        let mut u = _mm512_mul_pd(g.k[i][0], zs[0]);
        for j in 1..M {
            u = _mm512_fmadd_pd(g.k[i][j], zs[j], u);
        }
        for j in 0..N {
            u = _mm512_fmadd_pd(g.a[i][j], x[j], u);
        }
        if valid == 0xff {
            return u;
        }
        let mut p = _mm512_setzero_pd();
        for j in 0..N {
            p = _mm512_fmadd_pd(g.phi[i][j], x[j], p);
        }
        _mm512_mask_blend_pd(valid, p, u)
    })
}

/// Vector steps of the eight general lanes, lane `l` over samples
/// `from[l]..to[l]` (the AVX-512 [`gen_masked_steps`]): per step the running
/// lanes' `z` gathered into vectors (a done lane's slot gets 0), one
/// [`gen_vstep8`], the new state kept where a lane runs, and each running
/// lane's outputs stored: the same bits as the scalar `gen_step` per lane.
///
/// # Safety
/// AVX-512F and FMA; for every lane `to[l] * M` values are readable at
/// `rows[l]` and `out[l][i]` has `to[l]` writable elements.
#[inline]
#[target_feature(enable = "avx512f,fma")]
unsafe fn gen_masked_steps8<T: IoFloat, const N: usize, const M: usize>(
    g: &GenMats8<N, M>,
    x: &mut [__m512d; N],
    rows: &[*const T; GEN_LANES8],
    out: &[[*mut T; N]; GEN_LANES8],
    from: [usize; GEN_LANES8],
    to: [usize; GEN_LANES8],
) {
    const L: usize = GEN_LANES8;
    let most = (0..L)
        .map(|l| to[l].saturating_sub(from[l]))
        .max()
        .unwrap_or(0);
    // SAFETY: every access below is at a running sample k < to[l] of lane
    // l (the caller's bounds); the rest is register and stack work.
    unsafe {
        for s in 0..most {
            let mut zl = [[0.0f64; L]; M];
            let mut run: __mmask8 = 0;
            for l in 0..L {
                let k = from[l] + s;
                if k < to[l] {
                    for (j, zj) in zl.iter_mut().enumerate() {
                        zj[l] = (*rows[l].add(k * M + j)).to_f64();
                    }
                    run |= 1 << l;
                }
            }
            let zs: [__m512d; M] = std::array::from_fn(|j| _mm512_loadu_pd(zl[j].as_ptr()));
            let xn = gen_vstep8(g, x, &zs);
            let mut t = [[0.0f64; L]; N];
            for i in 0..N {
                x[i] = _mm512_mask_blend_pd(run, x[i], xn[i]);
                _mm512_storeu_pd(t[i].as_mut_ptr(), xn[i]);
            }
            for l in 0..L {
                let k = from[l] + s;
                if k < to[l] {
                    for i in 0..N {
                        *out[l][i].add(k) = T::from_f64(t[i][l]);
                    }
                }
            }
        }
    }
}

/// The eight general lanes over samples `k0..n` (AVX-512; the contract of
/// [`gen_lanes4`] with eight tracks): each lane first steps (masked vector
/// steps, [`gen_masked_steps8`]) to a
/// sample where its first output row is aligned to a cache line; then blocks
/// of one cache line of output per lane and component (8 `f64` or 16 `f32`
/// samples): per 8 samples each lane loads `8 M` consecutive values, 8 x 8
/// transposes give per-sample vectors across the lanes, the steps run in
/// vectors (the coast `Phi x` only for samples where some lane misses), and
/// 8 x 8 transposes give the rows back, stored as whole lines (non-temporal
/// if `nt`, for aligned rows). Each slot does exactly the scalar `gen_step`
/// arithmetic (same FMAs, same order), so results are bit-identical to the
/// scalar lanes. `cs`, `xs`, `rows` and `group` have [`GEN_LANES8`] entries
/// (else everything runs scalar). The streamed stores are not fenced here
/// (the caller's [`super::store_fence`], as for [`gen_lanes4`]).
///
/// # Safety
/// The CPU supports AVX-512F and FMA ([`available`]).
#[allow(clippy::too_many_arguments)]
#[target_feature(enable = "avx512f,fma")]
pub(super) unsafe fn gen_lanes8<T: IoFloat, const N: usize, const M: usize>(
    cs: &[&GenConst<N, M>],
    xs: &mut [[f64; N]],
    k0: usize,
    n: usize,
    rows: &[&[T]],
    group: &mut [Job<'_, T, N>],
    ahead: Option<(usize, usize)>,
    nt: bool,
) {
    const L: usize = GEN_LANES8;
    let size = std::mem::size_of::<T>();
    // Samples per block: one 64-byte line of output.
    let sb = 64 / size;
    let ok = gen_fits::<T>(M)
        && cs.len() == L
        && xs.len() == L
        && rows.len() == L
        && group.len() == L
        && rows.iter().all(|r| r.len() >= n * M)
        && group
            .iter()
            .all(|j| j.2.states.iter().all(|s| s.len() >= n))
        && n >= k0 + 3 * sb;
    if !ok {
        gen_scalar_steps8(cs, xs, rows, group, &[k0; L], &[n; L]);
        return;
    }
    let mut k = [k0; L];
    for l in 0..L {
        let addr = group[l].2.states[0].as_ptr() as usize + k0 * size;
        k[l] = k0 + ((64 - addr % 64) % 64) / size;
    }
    // Streamed: when nearly all neighbouring lanes' x lines share their parity
    // (rows of an even number of lines), the lanes off the alternating
    // pattern take one more masked head block (see `ab_lanes8`). genbench
    // float64 (ns per sample): 1,000 x 10,000 2.18 -> 1.52, 4,882 x 2,048
    // 2.20 -> 1.74, 19,531 x 512 2.60 -> 2.29; rows of 100 or 500 (lines
    // already mixed) lost 7-20 % to it, so they keep their heads; float32
    // (bound by its float64 arithmetic) gained nothing.
    if nt && is_f64::<T>() {
        let line: [usize; L] =
            std::array::from_fn(|l| (group[l].2.states[0].as_ptr() as usize + k[l] * size) / 64);
        let same = (1..L).filter(|&l| (line[l] ^ line[l - 1]) & 1 == 0).count();
        if same >= 6 {
            alternate_parities(&mut k, &line, sb);
        }
    }
    let blocks = k
        .iter()
        .map(|&kl| n.saturating_sub(kl) / sb)
        .min()
        .unwrap_or(0);
    let stream: [[bool; N]; L] = std::array::from_fn(|l| {
        std::array::from_fn(|i| {
            nt && (group[l].2.states[i].as_ptr() as usize + k[l] * size).is_multiple_of(64)
        })
    });
    let v8 = |f: &dyn Fn(&GenConst<N, M>) -> f64| {
        _mm512_set_pd(
            f(cs[7]),
            f(cs[6]),
            f(cs[5]),
            f(cs[4]),
            f(cs[3]),
            f(cs[2]),
            f(cs[1]),
            f(cs[0]),
        )
    };
    let g = GenMats8::<N, M> {
        a: std::array::from_fn(|i| std::array::from_fn(|j| v8(&|c| c.a[i][j]))),
        phi: std::array::from_fn(|i| std::array::from_fn(|j| v8(&|c| c.phi[i][j]))),
        k: std::array::from_fn(|i| std::array::from_fn(|j| v8(&|c| c.k[i][j]))),
    };
    let mut x: [__m512d; N] = std::array::from_fn(|i| {
        _mm512_set_pd(
            xs[7][i], xs[6][i], xs[5][i], xs[4][i], xs[3][i], xs[2][i], xs[1][i], xs[0][i],
        )
    });
    let zero = _mm512_setzero_pd();
    let rp: [*const T; L] = std::array::from_fn(|l| rows[l].as_ptr());
    let op: [[*mut T; N]; L] =
        std::array::from_fn(|l| std::array::from_fn(|i| group[l].2.states[i].as_mut_ptr()));
    // Streamed rows: the lines at both ends of each output row (the start-up,
    // heads and tails write them with ordinary stores) of the group two
    // ahead, fetched for ownership now. Else each such store waits for its
    // line from memory and holds up the stores behind it (in order): a C
    // replica of 100,000 x 100 ran 3.8-4.4 ns per sample, 2.7-2.8 with these
    // prefetches (docs/benchmarks.md, session 15).
    if nt {
        if let Some((_, dout)) = ahead {
            for ol in op.iter() {
                for &o in ol.iter() {
                    let p = o.wrapping_add(2 * dout);
                    _mm_prefetch::<_MM_HINT_ET0>(p as *const i8);
                    _mm_prefetch::<_MM_HINT_ET0>(p.wrapping_add(n - 1) as *const i8);
                }
            }
        }
    }
    // Heads: each lane to its line-aligned sample k[l], in masked vector steps.
    // SAFETY: k[l] <= k0 + sb <= n; rows and outputs hold n samples (`ok`).
    unsafe { gen_masked_steps8(&g, &mut x, &rp, &op, [k0; L], k) };
    // outv[i][h][s]: component i after sample h W + s of the block (made
    // once, as in `gen_lanes4`: every entry stored is written in the block,
    // and the unused half of an `f64` block stays zero).
    let mut outv = [[[zero; W]; 2]; N];
    // Prefetches for lane `l`'s 8 samples at `at`: the next group's `z` (and,
    // unless streamed, outputs) and, once per block (`first`), this row's
    // `z` Z_AHEAD samples ahead.
    let fetch = |l: usize, at: usize, first: bool| {
        if let Some((dz, dout)) = ahead {
            for gi in 0..M {
                prefetch(rp[l].wrapping_add(dz + at * M + gi * W));
            }
            if !nt {
                for i in 0..N {
                    prefetch(op[l][i].wrapping_add(dout + at));
                }
            }
        }
        if first {
            for gi in 0..M {
                prefetch(rp[l].wrapping_add((at + Z_AHEAD) * M + gi * sb));
            }
        }
    };
    for b in 0..blocks {
        if is_f32::<T>() {
            // f32: 16 samples per lane and block, transposed as f32.
            for l in 0..L {
                let at = k[l] + b * sb;
                fetch(l, at, true);
                fetch(l, at + W, false);
            }
            // zs[s][c]: component c of each lane's sample k[l] + b sb + s.
            let mut zs = [[zero; M]; 16];
            for gi in 0..M {
                let mut r: [__m512; L] = std::array::from_fn(|l| {
                    let at = (k[l] + b * sb) * M + gi * 16;
                    // SAFETY: T is f32 and at + 16 <= (k[l] + (b + 1) sb) M
                    // <= n M <= rows[l].len().
                    unsafe { _mm512_loadu_ps(rp[l].add(at) as *const f32) }
                });
                transpose8x16(&mut r);
                for e in 0..16 {
                    let idx = gi * 16 + e;
                    zs[idx / M][idx % M] = widen_step(&r, e);
                }
            }
            for (s, zsv) in zs.iter().enumerate() {
                x = gen_vstep8(&g, &x, zsv);
                for i in 0..N {
                    outv[i][s / W][s % W] = x[i];
                }
            }
            for (i, ov) in outv.iter().enumerate() {
                let mut lines = narrow_steps(ov);
                untranspose8x16(&mut lines);
                for l in 0..L {
                    let at = k[l] + b * sb;
                    // SAFETY: as for the f64 stores below (T is f32).
                    unsafe { store_ps(op[l][i].add(at) as *mut f32, lines[l], stream[l][i]) };
                }
            }
            continue;
        }
        for h in 0..sb / W {
            for l in 0..L {
                fetch(l, k[l] + b * sb + h * W, h == 0);
            }
            // zs[s][c]: component c of each lane's sample k[l] + b sb + h W + s.
            let mut zs = [[zero; M]; W];
            for gi in 0..M {
                let mut r: [__m512d; L] = std::array::from_fn(|l| {
                    let at = (k[l] + b * sb + h * W) * M + gi * W;
                    // SAFETY: at + W <= (k[l] + (b + 1) sb) M <= n M <= rows[l].len().
                    unsafe { load8(rp[l].add(at)) }
                });
                transpose8(&mut r);
                for (i, ri) in r.iter().enumerate() {
                    let idx = gi * W + i;
                    zs[idx / M][idx % M] = *ri;
                }
            }
            for (s, zsv) in zs.iter().enumerate() {
                x = gen_vstep8(&g, &x, zsv);
                for i in 0..N {
                    outv[i][h][s] = x[i];
                }
            }
            for ov in outv.iter_mut() {
                transpose8(&mut ov[h]);
            }
        }
        for (i, ov) in outv.iter().enumerate() {
            for l in 0..L {
                let at = k[l] + b * sb;
                // SAFETY: at + sb <= n <= states[i].len(); streamed rows are
                // aligned to 64 bytes at `at` (checked in `stream`, and
                // `at - k[l]` is a whole number of lines).
                unsafe { store_line(op[l][i].add(at), ov[0][l], ov[1][l], stream[l][i]) };
            }
        }
    }
    // No fence here: the streamed stores are ordered by the caller's
    // `store_fence`, once per task (as in `gen_lanes4`).
    // Tails: in masked vector steps.
    let from: [usize; L] = std::array::from_fn(|l| (k[l] + blocks * sb).min(n));
    // SAFETY: as for the heads.
    unsafe { gen_masked_steps8(&g, &mut x, &rp, &op, from, [n; L]) };
    for i in 0..N {
        let mut t = [0.0; L];
        // SAFETY: t is a plain array of 8 f64.
        unsafe { _mm512_storeu_pd(t.as_mut_ptr(), x[i]) };
        for l in 0..L {
            xs[l][i] = t[l];
        }
    }
}

/// Scalar steps of every general lane `l` over samples `from[l]..to[l]`,
/// the lanes interleaved (any number of lanes: the shortest of the slices).
#[inline]
#[target_feature(enable = "fma")]
fn gen_scalar_steps8<T: IoFloat, const N: usize, const M: usize>(
    cs: &[&GenConst<N, M>],
    xs: &mut [[f64; N]],
    rows: &[&[T]],
    group: &mut [Job<'_, T, N>],
    from: &[usize],
    to: &[usize],
) {
    let lanes = cs
        .len()
        .min(xs.len())
        .min(rows.len())
        .min(group.len())
        .min(from.len())
        .min(to.len());
    let most = (0..lanes)
        .map(|l| to[l].saturating_sub(from[l]))
        .max()
        .unwrap_or(0);
    for s in 0..most {
        for l in 0..lanes {
            let k = from[l] + s;
            if k < to[l] && (k + 1) * M <= rows[l].len() {
                let zk: [f64; M] = std::array::from_fn(|j| rows[l][k * M + j].to_f64());
                xs[l] = gen_step::<N, M, true>(cs[l], &xs[l], &zk);
                let o = &mut group[l].2;
                for i in 0..N {
                    if let Some(d) = o.states[i].get_mut(k) {
                        *d = T::from_f64(xs[l][i]);
                    }
                }
            }
        }
    }
}
