//! Vector lanes of the irregular-timestamp alpha-beta track kernel
//! ([`crate::ragged`]): `W` running tracks in the `W` `f64` slots of one
//! register (AVX-512: 8, AVX2: 4), each slot walking its own track.
//!
//! Per block of `W` steps each lane loads `W` consecutive measurements and
//! timestamps of its track (two vector loads); `W x W` transposes give, per
//! step, the vectors "this step of every lane"; the steps run in vectors:
//! `dt = t_k - t_{k-1}`, the gain law at `dt` (both laws vectorised, see
//! below), the update (a NaN measurement coasts); transposes give the
//! estimates (and residuals) back as rows, stored `W` wide: all `x` rows
//! of a block, then all `v` rows (faster on Zen 3 than lane by lane).
//! Ordinary stores, except for the four `f64` lanes with fixed gains on
//! outputs too big for the caches and long stretches: whole lines put
//! together from two blocks and streamed ([`Lines`]; half-lines streamed
//! block by block had measured slower). With the design
//! law a block without missed measurements skips the coasting blends. A block whose
//! steps are not all plain running steps of every lane (a timestamp not
//! after the last one, not finite, or a gap beyond `max_gap`) is not run
//! here: the caller's scalar lanes take it (restarts, drops and errors stay
//! in the scalar code).
//!
//! Every slot does exactly the scalar arithmetic of the track kernel's lane
//! step (`ab_update::<true>` and the law's `ab_gains`): the same operations
//! (IEEE `+ - * / sqrt` and the same fused multiply-adds) in the same
//! order, so results are bit-identical to the scalar lanes and to a track
//! run alone. Gain laws:
//!
//! - fixed (`AbFixed`): `K = [alpha, beta / dt]`: one division per step;
//! - design (`AbDesign`): [`crate::irregular::ab_design_rate_gains`]:
//!   `lambda = ratio dt^2`, one square root, no division for `lambda <= 4`
//!   (one above; the rate gain
//!   `beta / dt` is formed without dividing by `dt`), the limit `(1, 2 / dt)`
//!   blended in only for `lambda >= 1e300`. (Before: the two-branch closed
//!   form of `kalman_uv_from_lambda` and `beta / dt`: two or three square
//!   roots and divisions per step, bound by the divider.)
//!
//! The vector code runs only on CPUs with AVX2 + FMA (4 lanes; AVX-512F +
//! FMA, 8 lanes, only with `ABKIT_TRACKS_AVX512=1`: bit-identical on an
//! AVX-512 Xeon, but slower there than the 4 lanes, see [`width`]), and
//! not when `ABKIT_DISABLE_SIMD` is set (to anything but `0`, before the
//! first call); the scalar lanes run otherwise. On an AMD Zen 4 the 4 lanes
//! are compiled with AVX-512VL, store without streaming and do not
//! prefetch ([`zen4`]; same bits).
#![allow(clippy::too_many_arguments)]

use crate::filter::IoFloat;
pub use crate::irregular::AbLaw;
use std::any::TypeId;
use std::arch::x86_64::*;

fn disabled() -> bool {
    std::env::var_os("ABKIT_DISABLE_SIMD").is_some_and(|v| v != "0")
}

/// Lanes of the vector kernel on this CPU: 4 (AVX2 + FMA), 8 (AVX-512F +
/// FMA, **opt-in**: the environment variable `ABKIT_TRACKS_AVX512` set to
/// anything but `0`; it shares the generic kernel with the 4-lane one, only
/// the vector type differs) or 0 (no vector kernel; also with
/// `ABKIT_DISABLE_SIMD`). Checked once. The 8 lanes give the same bits
/// (tests/test_tracks_lanes.py runs them in a child process) but were
/// slower on the AVX-512 Xeon this was measured on (`bench/bench_tracks.py
/// --threads 1 --cpu`, 4 -> 8 lanes: 1,000 x 10,000 with `t`, design
/// schedule 556 -> 448 Msamples/s, fixed-gain 563 -> 469; ragged with `t`
/// 479 -> 390; docs/benchmarks.md, session 25), so 4 stays the default.
pub fn width() -> usize {
    use std::sync::OnceLock;
    static W: OnceLock<usize> = OnceLock::new();
    *W.get_or_init(|| {
        let opt_in = std::env::var_os("ABKIT_TRACKS_AVX512").is_some_and(|v| v != "0");
        if disabled() || !is_x86_feature_detected!("fma") {
            0
        } else if opt_in && is_x86_feature_detected!("avx512f") {
            8
        } else if is_x86_feature_detected!("avx2") {
            4
        } else {
            0
        }
    })
}

fn is_f64<T: 'static>() -> bool {
    TypeId::of::<T>() == TypeId::of::<f64>()
}

fn is_f32<T: 'static>() -> bool {
    TypeId::of::<T>() == TypeId::of::<f32>()
}

/// Whether the vector lanes handle the sample type `T`.
pub fn handles<T: 'static>() -> bool {
    is_f64::<T>() || is_f32::<T>()
}

/// One running track in a vector lane: its remaining samples (from the
/// lane's current sample on, stride 1) and its state.
pub struct VLane<'a, T> {
    /// Measurements.
    pub z: &'a [T],
    /// Timestamps.
    pub t: &'a [f64],
    /// Position estimates.
    pub xs: &'a mut [T],
    /// Velocity estimates.
    pub vs: &'a mut [T],
    /// Residuals, if wanted.
    pub rs: Option<&'a mut [T]>,
    /// Position.
    pub x: f64,
    /// Velocity.
    pub v: f64,
    /// Last kept timestamp.
    pub t_last: f64,
    /// Gain law.
    pub law: AbLaw,
}

/// Run the lanes (exactly [`width`] of them, all with the same kind of law)
/// over at most `steps` samples, whole blocks of `width` steps, stopping
/// before the first block that holds a step which is not a plain running
/// step. Returns the number of steps done (the same for every lane); the
/// lanes' states are updated. Every slice must hold `steps` samples.
///
/// With `nt` (outputs too big for the caches) the `f64` position and
/// velocity rows of the four AVX2 lanes with fixed gains are written in
/// whole 64-byte lines with streamed stores ([`Lines`]), fenced before
/// returning (not on a Zen 4: [`zen4`]); every other case stores as
/// without it.
pub fn run<T: IoFloat>(lanes: &mut [VLane<'_, T>], steps: usize, max_gap: f64, nt: bool) -> usize {
    let w = width();
    if w == 0 || lanes.len() != w || !handles::<T>() {
        return 0;
    }
    let fits = lanes.iter().all(|l| {
        l.z.len() >= steps
            && l.t.len() >= steps
            && l.xs.len() >= steps
            && l.vs.len() >= steps
            && l.rs.as_ref().is_none_or(|r| r.len() >= steps)
    });
    let design = matches!(lanes[0].law, AbLaw::Design { .. });
    let same = lanes
        .iter()
        .all(|l| matches!(l.law, AbLaw::Design { .. }) == design);
    if !fits || !same {
        return 0;
    }
    let resid = lanes[0].rs.is_some();
    if lanes.iter().any(|l| l.rs.is_some() != resid) {
        return 0;
    }
    if w == 8 {
        if let Ok(l8) = <&mut [VLane<'_, T>; 8]>::try_from(lanes) {
            // SAFETY: `width() == 8` checked AVX-512F and FMA.
            return unsafe { run8(l8, steps, max_gap, design, resid) };
        }
    } else if w == 4 {
        if let Ok(l4) = <&mut [VLane<'_, T>; 4]>::try_from(lanes) {
            if zen4() {
                // Ordinary stores and no software prefetch ([`zen4`]).
                // SAFETY: `zen4()` checked AVX2, FMA, AVX-512F and -VL.
                return unsafe { run4_zen4(l4, steps, max_gap, design, resid) };
            }
            // Streamed lines for the fixed-gain law only: with the design
            // law they measured slower (docs/benchmarks.md, session 27).
            let nt = nt && is_f64::<T>() && !resid && !design;
            // SAFETY: `width() == 4` checked AVX2 and FMA.
            return unsafe { run4(l4, steps, max_gap, design, resid, nt) };
        }
    }
    0
}

#[target_feature(enable = "avx512f,fma")]
unsafe fn run8<T: IoFloat>(
    lanes: &mut [VLane<'_, T>; 8],
    steps: usize,
    max_gap: f64,
    design: bool,
    resid: bool,
) -> usize {
    // SAFETY: forwarded (AVX-512F and FMA available; slices checked).
    unsafe {
        match (design, resid) {
            (true, true) => kernel::<V8, T, 8, true, true, false>(lanes, steps, max_gap, true),
            (true, false) => kernel::<V8, T, 8, true, false, false>(lanes, steps, max_gap, true),
            (false, true) => kernel::<V8, T, 8, false, true, false>(lanes, steps, max_gap, true),
            (false, false) => kernel::<V8, T, 8, false, false, false>(lanes, steps, max_gap, true),
        }
    }
}

/// Whether the four lanes take their AMD Zen 4 form
/// ([`crate::filter::zen4_forms`]: AMD family 19h with AVX-512F and -VL,
/// unless `ABKIT_ZEN4=0`): the same kernel compiled with AVX-512VL (32
/// vector registers instead of 16: fewer spills; the same operations, so
/// the same bits), with ordinary stores instead of the streamed lines of
/// the fixed-gain law, and without software prefetches. Measured on a Zen 4
/// EPYC guest (`irrbench`, 10^7 samples from memory, ns per sample,
/// docs/benchmarks.md, session 31): fixed gains 1.59-1.63 -> 1.15-1.24,
/// design law 1.94-1.97 -> 1.70-1.75. There the streamed lines were slower
/// than ordinary stores (1.65 against 1.27-1.29) and the prefetches cost
/// more than they saved (1.27-1.31 against 1.19-1.21), unlike on the Zen 3
/// and the Xeon they were tuned on. The design law without residuals
/// also takes the software-pipelined [`kernel_design_pipelined`] there
/// (1.82 -> 1.63-1.66 from memory).
pub(crate) fn zen4() -> bool {
    crate::filter::zen4_forms()
}

#[target_feature(enable = "avx2,fma,avx512f,avx512vl")]
unsafe fn run4_zen4<T: IoFloat>(
    lanes: &mut [VLane<'_, T>; 4],
    steps: usize,
    max_gap: f64,
    design: bool,
    resid: bool,
) -> usize {
    // SAFETY: forwarded (AVX2, FMA, AVX-512F/VL available; slices checked).
    unsafe {
        match (design, resid) {
            (true, true) => kernel::<V4, T, 4, true, true, false>(lanes, steps, max_gap, false),
            (true, false) => kernel_design_pipelined::<V4, T, 4>(lanes, steps, max_gap),
            (false, true) => kernel::<V4, T, 4, false, true, false>(lanes, steps, max_gap, false),
            (false, false) => kernel::<V4, T, 4, false, false, false>(lanes, steps, max_gap, false),
        }
    }
}

#[target_feature(enable = "avx2,fma")]
unsafe fn run4<T: IoFloat>(
    lanes: &mut [VLane<'_, T>; 4],
    steps: usize,
    max_gap: f64,
    design: bool,
    resid: bool,
    nt: bool,
) -> usize {
    // SAFETY: forwarded (AVX2 and FMA available; slices checked).
    unsafe {
        match (design, resid, nt) {
            (true, true, _) => kernel::<V4, T, 4, true, true, false>(lanes, steps, max_gap, true),
            (true, false, _) => kernel::<V4, T, 4, true, false, false>(lanes, steps, max_gap, true),
            (false, true, _) => kernel::<V4, T, 4, false, true, false>(lanes, steps, max_gap, true),
            (false, false, false) => {
                kernel::<V4, T, 4, false, false, false>(lanes, steps, max_gap, true)
            }
            (false, false, true) => {
                kernel::<V4, T, 4, false, false, true>(lanes, steps, max_gap, true)
            }
        }
    }
}

/// The vector operations of the kernel (all exactly rounded IEEE
/// operations; `fmadd(a, b, c) = a b + c` and `fnmadd(a, b, c) = c - a b`
/// fused). Also used by the flat alpha-beta kernel
/// (`filter_flat_vec.rs`).
///
/// # Safety
/// Every method needs the CPU features of its implementation; callers are
/// functions compiled with them.
pub(crate) trait Vd<const W: usize>: Copy {
    type Mask: Copy;
    unsafe fn splat(x: f64) -> Self;
    unsafe fn from_lanes(a: &[f64; W]) -> Self;
    unsafe fn to_lanes(self) -> [f64; W];
    unsafe fn add(self, b: Self) -> Self;
    unsafe fn sub(self, b: Self) -> Self;
    unsafe fn mul(self, b: Self) -> Self;
    unsafe fn div(self, b: Self) -> Self;
    unsafe fn sqrt(self) -> Self;
    /// `min(self, b)` (`b` where either is NaN).
    unsafe fn min(self, b: Self) -> Self;
    unsafe fn fmadd(self, b: Self, c: Self) -> Self;
    unsafe fn fnmadd(self, b: Self, c: Self) -> Self;
    /// `self > b`, `self <= b`, `self < b`, `self >= b` (false for NaN).
    unsafe fn gt(self, b: Self) -> Self::Mask;
    unsafe fn le(self, b: Self) -> Self::Mask;
    unsafe fn ge(self, b: Self) -> Self::Mask;
    /// `self == b` (false for NaN).
    unsafe fn equal(self, b: Self) -> Self::Mask;
    /// Not NaN.
    unsafe fn ord(self) -> Self::Mask;
    unsafe fn and(a: Self::Mask, b: Self::Mask) -> Self::Mask;
    unsafe fn all(m: Self::Mask) -> bool;
    unsafe fn none(m: Self::Mask) -> bool;
    /// `m ? b : a` per slot.
    unsafe fn blend(m: Self::Mask, a: Self, b: Self) -> Self;
    /// `W` consecutive values at `p`, widened.
    unsafe fn load<T: 'static>(p: *const T) -> Self;
    /// `W` values at `p`, narrowed (round to nearest).
    unsafe fn store<T: 'static>(self, p: *mut T);
    unsafe fn transpose(r: &mut [Self; W]);
    /// The mask of the slots whose bit is set in `bits` (bit `i`: slot `i`).
    unsafe fn mask_bits(bits: u32) -> Self::Mask;
    /// Store the `W` values at `p` (aligned to `8 W` bytes if `nt`), past
    /// the caches if `nt`.
    unsafe fn put_f64(self, p: *mut f64, nt: bool);
    /// Store the `2 W` values of `a` then `b` narrowed to `f32` (round to
    /// nearest) at `p` (aligned to `8 W` bytes if `nt`), past the caches if
    /// `nt`.
    unsafe fn put_f32_pair(a: Self, b: Self, p: *mut f32, nt: bool);
}

#[derive(Clone, Copy)]
pub(crate) struct V8(__m512d);

impl Vd<8> for V8 {
    type Mask = __mmask8;
    #[inline(always)]
    unsafe fn splat(x: f64) -> Self {
        V8(_mm512_set1_pd(x))
    }
    #[inline(always)]
    unsafe fn from_lanes(a: &[f64; 8]) -> Self {
        // SAFETY: 8 readable f64.
        V8(unsafe { _mm512_loadu_pd(a.as_ptr()) })
    }
    #[inline(always)]
    unsafe fn to_lanes(self) -> [f64; 8] {
        let mut a = [0.0; 8];
        // SAFETY: 8 writable f64.
        unsafe { _mm512_storeu_pd(a.as_mut_ptr(), self.0) };
        a
    }
    #[inline(always)]
    unsafe fn add(self, b: Self) -> Self {
        V8(_mm512_add_pd(self.0, b.0))
    }
    #[inline(always)]
    unsafe fn sub(self, b: Self) -> Self {
        V8(_mm512_sub_pd(self.0, b.0))
    }
    #[inline(always)]
    unsafe fn mul(self, b: Self) -> Self {
        V8(_mm512_mul_pd(self.0, b.0))
    }
    #[inline(always)]
    unsafe fn div(self, b: Self) -> Self {
        V8(_mm512_div_pd(self.0, b.0))
    }
    #[inline(always)]
    unsafe fn min(self, b: Self) -> Self {
        V8(_mm512_min_pd(self.0, b.0))
    }
    #[inline(always)]
    unsafe fn sqrt(self) -> Self {
        V8(_mm512_sqrt_pd(self.0))
    }
    #[inline(always)]
    unsafe fn fmadd(self, b: Self, c: Self) -> Self {
        V8(_mm512_fmadd_pd(self.0, b.0, c.0))
    }
    #[inline(always)]
    unsafe fn fnmadd(self, b: Self, c: Self) -> Self {
        V8(_mm512_fnmadd_pd(self.0, b.0, c.0))
    }
    #[inline(always)]
    unsafe fn gt(self, b: Self) -> __mmask8 {
        _mm512_cmp_pd_mask::<_CMP_GT_OQ>(self.0, b.0)
    }
    #[inline(always)]
    unsafe fn le(self, b: Self) -> __mmask8 {
        _mm512_cmp_pd_mask::<_CMP_LE_OQ>(self.0, b.0)
    }
    #[inline(always)]
    unsafe fn ge(self, b: Self) -> __mmask8 {
        _mm512_cmp_pd_mask::<_CMP_GE_OQ>(self.0, b.0)
    }
    #[inline(always)]
    unsafe fn equal(self, b: Self) -> __mmask8 {
        _mm512_cmp_pd_mask::<_CMP_EQ_OQ>(self.0, b.0)
    }
    #[inline(always)]
    unsafe fn ord(self) -> __mmask8 {
        _mm512_cmp_pd_mask::<_CMP_ORD_Q>(self.0, self.0)
    }
    #[inline(always)]
    unsafe fn and(a: __mmask8, b: __mmask8) -> __mmask8 {
        a & b
    }
    #[inline(always)]
    unsafe fn all(m: __mmask8) -> bool {
        m == 0xff
    }
    #[inline(always)]
    unsafe fn none(m: __mmask8) -> bool {
        m == 0
    }
    #[inline(always)]
    unsafe fn blend(m: __mmask8, a: Self, b: Self) -> Self {
        V8(_mm512_mask_blend_pd(m, a.0, b.0))
    }
    #[inline(always)]
    unsafe fn load<T: 'static>(p: *const T) -> Self {
        // SAFETY: forwarded (T is f64 or f32, 8 values readable).
        unsafe {
            if is_f64::<T>() {
                V8(_mm512_loadu_pd(p as *const f64))
            } else {
                V8(_mm512_cvtps_pd(_mm256_loadu_ps(p as *const f32)))
            }
        }
    }
    #[inline(always)]
    unsafe fn store<T: 'static>(self, p: *mut T) {
        // SAFETY: forwarded (T is f64 or f32, 8 values writable).
        unsafe {
            if is_f64::<T>() {
                _mm512_storeu_pd(p as *mut f64, self.0)
            } else {
                _mm256_storeu_ps(p as *mut f32, _mm512_cvtpd_ps(self.0))
            }
        }
    }
    #[inline(always)]
    unsafe fn transpose(r: &mut [Self; 8]) {
        let t0 = _mm512_unpacklo_pd(r[0].0, r[1].0);
        let t1 = _mm512_unpackhi_pd(r[0].0, r[1].0);
        let t2 = _mm512_unpacklo_pd(r[2].0, r[3].0);
        let t3 = _mm512_unpackhi_pd(r[2].0, r[3].0);
        let t4 = _mm512_unpacklo_pd(r[4].0, r[5].0);
        let t5 = _mm512_unpackhi_pd(r[4].0, r[5].0);
        let t6 = _mm512_unpacklo_pd(r[6].0, r[7].0);
        let t7 = _mm512_unpackhi_pd(r[6].0, r[7].0);
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
        r[0] = V8(_mm512_shuffle_f64x2::<0b01_00_01_00>(u0, u4));
        r[4] = V8(_mm512_shuffle_f64x2::<0b11_10_11_10>(u0, u4));
        r[1] = V8(_mm512_shuffle_f64x2::<0b01_00_01_00>(u1, u5));
        r[5] = V8(_mm512_shuffle_f64x2::<0b11_10_11_10>(u1, u5));
        r[2] = V8(_mm512_shuffle_f64x2::<0b01_00_01_00>(u2, u6));
        r[6] = V8(_mm512_shuffle_f64x2::<0b11_10_11_10>(u2, u6));
        r[3] = V8(_mm512_shuffle_f64x2::<0b01_00_01_00>(u3, u7));
        r[7] = V8(_mm512_shuffle_f64x2::<0b11_10_11_10>(u3, u7));
    }
    #[inline(always)]
    unsafe fn mask_bits(bits: u32) -> __mmask8 {
        bits as __mmask8
    }
    #[inline(always)]
    unsafe fn put_f64(self, p: *mut f64, nt: bool) {
        // SAFETY: forwarded (8 writable f64, aligned if nt).
        unsafe {
            if nt {
                _mm512_stream_pd(p, self.0)
            } else {
                _mm512_storeu_pd(p, self.0)
            }
        }
    }
    #[inline(always)]
    unsafe fn put_f32_pair(a: Self, b: Self, p: *mut f32, nt: bool) {
        let lo = _mm256_castps_pd(_mm512_cvtpd_ps(a.0));
        let hi = _mm256_castps_pd(_mm512_cvtpd_ps(b.0));
        let line = _mm512_castpd_ps(_mm512_insertf64x4::<1>(_mm512_castpd256_pd512(lo), hi));
        // SAFETY: forwarded (16 writable f32, aligned if nt).
        unsafe {
            if nt {
                _mm512_stream_ps(p, line)
            } else {
                _mm512_storeu_ps(p, line)
            }
        }
    }
}

#[derive(Clone, Copy)]
pub(crate) struct V4(__m256d);

impl Vd<4> for V4 {
    /// All-ones slots where true.
    type Mask = __m256d;
    #[inline(always)]
    unsafe fn splat(x: f64) -> Self {
        V4(_mm256_set1_pd(x))
    }
    #[inline(always)]
    unsafe fn from_lanes(a: &[f64; 4]) -> Self {
        // SAFETY: 4 readable f64.
        V4(unsafe { _mm256_loadu_pd(a.as_ptr()) })
    }
    #[inline(always)]
    unsafe fn to_lanes(self) -> [f64; 4] {
        let mut a = [0.0; 4];
        // SAFETY: 4 writable f64.
        unsafe { _mm256_storeu_pd(a.as_mut_ptr(), self.0) };
        a
    }
    #[inline(always)]
    unsafe fn add(self, b: Self) -> Self {
        V4(_mm256_add_pd(self.0, b.0))
    }
    #[inline(always)]
    unsafe fn sub(self, b: Self) -> Self {
        V4(_mm256_sub_pd(self.0, b.0))
    }
    #[inline(always)]
    unsafe fn mul(self, b: Self) -> Self {
        V4(_mm256_mul_pd(self.0, b.0))
    }
    #[inline(always)]
    unsafe fn div(self, b: Self) -> Self {
        V4(_mm256_div_pd(self.0, b.0))
    }
    #[inline(always)]
    unsafe fn min(self, b: Self) -> Self {
        V4(_mm256_min_pd(self.0, b.0))
    }
    #[inline(always)]
    unsafe fn sqrt(self) -> Self {
        V4(_mm256_sqrt_pd(self.0))
    }
    #[inline(always)]
    unsafe fn fmadd(self, b: Self, c: Self) -> Self {
        V4(_mm256_fmadd_pd(self.0, b.0, c.0))
    }
    #[inline(always)]
    unsafe fn fnmadd(self, b: Self, c: Self) -> Self {
        V4(_mm256_fnmadd_pd(self.0, b.0, c.0))
    }
    #[inline(always)]
    unsafe fn gt(self, b: Self) -> __m256d {
        _mm256_cmp_pd::<_CMP_GT_OQ>(self.0, b.0)
    }
    #[inline(always)]
    unsafe fn le(self, b: Self) -> __m256d {
        _mm256_cmp_pd::<_CMP_LE_OQ>(self.0, b.0)
    }
    #[inline(always)]
    unsafe fn ge(self, b: Self) -> __m256d {
        _mm256_cmp_pd::<_CMP_GE_OQ>(self.0, b.0)
    }
    #[inline(always)]
    unsafe fn equal(self, b: Self) -> __m256d {
        _mm256_cmp_pd::<_CMP_EQ_OQ>(self.0, b.0)
    }
    #[inline(always)]
    unsafe fn ord(self) -> __m256d {
        _mm256_cmp_pd::<_CMP_ORD_Q>(self.0, self.0)
    }
    #[inline(always)]
    unsafe fn and(a: __m256d, b: __m256d) -> __m256d {
        _mm256_and_pd(a, b)
    }
    #[inline(always)]
    unsafe fn all(m: __m256d) -> bool {
        _mm256_movemask_pd(m) == 0xf
    }
    #[inline(always)]
    unsafe fn none(m: __m256d) -> bool {
        _mm256_movemask_pd(m) == 0
    }
    #[inline(always)]
    unsafe fn blend(m: __m256d, a: Self, b: Self) -> Self {
        V4(_mm256_blendv_pd(a.0, b.0, m))
    }
    #[inline(always)]
    unsafe fn load<T: 'static>(p: *const T) -> Self {
        // SAFETY: forwarded (T is f64 or f32, 4 values readable).
        unsafe {
            if is_f64::<T>() {
                V4(_mm256_loadu_pd(p as *const f64))
            } else {
                V4(_mm256_cvtps_pd(_mm_loadu_ps(p as *const f32)))
            }
        }
    }
    #[inline(always)]
    unsafe fn store<T: 'static>(self, p: *mut T) {
        // SAFETY: forwarded (T is f64 or f32, 4 values writable).
        unsafe {
            if is_f64::<T>() {
                _mm256_storeu_pd(p as *mut f64, self.0)
            } else {
                _mm_storeu_ps(p as *mut f32, _mm256_cvtpd_ps(self.0))
            }
        }
    }
    #[inline(always)]
    unsafe fn transpose(r: &mut [Self; 4]) {
        let t0 = _mm256_unpacklo_pd(r[0].0, r[1].0);
        let t1 = _mm256_unpackhi_pd(r[0].0, r[1].0);
        let t2 = _mm256_unpacklo_pd(r[2].0, r[3].0);
        let t3 = _mm256_unpackhi_pd(r[2].0, r[3].0);
        r[0] = V4(_mm256_permute2f128_pd::<0x20>(t0, t2));
        r[1] = V4(_mm256_permute2f128_pd::<0x20>(t1, t3));
        r[2] = V4(_mm256_permute2f128_pd::<0x31>(t0, t2));
        r[3] = V4(_mm256_permute2f128_pd::<0x31>(t1, t3));
    }
    #[inline(always)]
    unsafe fn mask_bits(bits: u32) -> __m256d {
        let b = _mm256_set_epi64x(8, 4, 2, 1);
        let m = _mm256_and_si256(_mm256_set1_epi64x(bits as i64), b);
        _mm256_castsi256_pd(_mm256_cmpeq_epi64(m, b))
    }
    #[inline(always)]
    unsafe fn put_f64(self, p: *mut f64, nt: bool) {
        // SAFETY: forwarded (4 writable f64, aligned if nt).
        unsafe {
            if nt {
                _mm256_stream_pd(p, self.0)
            } else {
                _mm256_storeu_pd(p, self.0)
            }
        }
    }
    #[inline(always)]
    unsafe fn put_f32_pair(a: Self, b: Self, p: *mut f32, nt: bool) {
        let v = _mm256_set_m128(_mm256_cvtpd_ps(b.0), _mm256_cvtpd_ps(a.0));
        // SAFETY: forwarded (8 writable f32, aligned if nt).
        unsafe {
            if nt {
                _mm256_stream_ps(p, v)
            } else {
                _mm256_storeu_ps(p, v)
            }
        }
    }
}

/// Prefetch distance in samples.
const PREFETCH: usize = 64;

#[inline(always)]
fn prefetch<T>(p: *const T) {
    // SAFETY: a prefetch is a hint; it never faults, whatever the address.
    unsafe { _mm_prefetch::<_MM_HINT_T0>(p as *const i8) }
}

/// `(alpha, beta / dt)` of the design law at `dt` in every slot: exactly
/// the operations of the scalar [`crate::irregular::ab_design_rate_gains`]
/// (`sr = sqrt(ratio)`, `c2 = 2 sr`; one square root; `w = (q - m) / 4`
/// for `m <= AB_DESIGN_SMALL_SQRT`; the division `2 / (m + q)`, the cap of
/// `alpha` at 1 and the limit `(1, 2 / dt)` for `m >= AB_DESIGN_BIG_SQRT`
/// only computed when a slot needs them).
#[inline(always)]
unsafe fn design_gains<V: Vd<W>, const W: usize>(sr: V, c2: V, dt: V) -> (V, V) {
    // SAFETY: the caller has the CPU features of V.
    unsafe {
        let m = sr.mul(dt);
        let q = m.mul(m).add(V::splat(8.0)).sqrt();
        let mut w = q.sub(m).mul(V::splat(0.25));
        let small = m.le(V::splat(crate::irregular::AB_DESIGN_SMALL_SQRT));
        let all_small = V::all(small);
        if !all_small {
            w = V::blend(small, V::splat(2.0).div(m.add(q)), w);
        }
        let v = m.mul(w);
        let mut a = v.mul(V::splat(2.0).sub(v));
        let mut g = c2.mul(v.mul(w));
        // For m <= SMALL alpha < 1 (v <= 0.74 there): the cap and the
        // limit only where a slot has a larger m.
        if !all_small {
            let one = V::splat(1.0);
            a = a.min(one);
            // m >= BIG (dt is finite and > 0 here): the limit (1, 2 / dt).
            let big = m.ge(V::splat(crate::irregular::AB_DESIGN_BIG_SQRT));
            if !V::none(big) {
                a = V::blend(big, a, one);
                g = V::blend(big, g, V::splat(2.0).div(dt));
            }
        }
        (a, g)
    }
}

/// The timestamps of the block at `k` after the last timestamp `prev`:
/// whether all its steps are plain running steps (0 < dt <= `gap`, dt
/// finite), their dt, and the block's last timestamp.
///
/// # Safety
/// The CPU features of V; every row of `tp` has `k + W` readable values.
#[inline(always)]
unsafe fn tblock<V: Vd<W>, const W: usize>(
    tp: &[*const f64; W],
    k: usize,
    prev: V,
    gap: V,
) -> (bool, [V; W], V) {
    // SAFETY: forwarded from the caller.
    unsafe {
        let zero = V::splat(0.0);
        let mut tv: [V; W] = std::array::from_fn(|l| V::load(tp[l].add(k)));
        V::transpose(&mut tv);
        let mut dt = [zero; W];
        let mut prev = prev;
        let mut ok = zero.le(zero);
        for j in 0..W {
            let d = tv[j].sub(prev);
            ok = V::and(ok, V::and(d.gt(zero), d.le(gap)));
            dt[j] = d;
            prev = tv[j];
        }
        (V::all(ok), dt, prev)
    }
}

/// The design law's gains `(alpha, rate gain)` at the step `d` of every
/// slot ([`design_gains`] with `sr = sqrt(ratio)`, `c2 = 2 sqrt(ratio)`),
/// reusing the gains of the last step computed where its dt equals `d` in
/// every slot (`last`: that dt and its gains; a NaN dt matches nothing):
/// timestamps on a grid (AIS reports in whole seconds, 1 Hz GNSS logs)
/// compute them once; the same operations on the same dt give the same
/// bits.
///
/// # Safety
/// The CPU features of V.
#[inline(always)]
unsafe fn design_step<V: Vd<W>, const W: usize>(
    d: V,
    sr: V,
    c2: V,
    last: &mut (V, V, V),
) -> (V, V) {
    // SAFETY: forwarded from the caller.
    unsafe {
        if !V::all(d.equal(last.0)) {
            let (a, g) = design_gains::<V, W>(sr, c2, d);
            *last = (d, a, g);
        }
        (last.1, last.2)
    }
}

/// [`design_step`] for each step of a block.
///
/// # Safety
/// The CPU features of V.
#[inline(always)]
unsafe fn design_block<V: Vd<W>, const W: usize>(
    dt: &[V; W],
    sr: V,
    c2: V,
    last: &mut (V, V, V),
) -> ([V; W], [V; W]) {
    // SAFETY: forwarded from the caller.
    unsafe {
        let mut a = [sr; W];
        let mut g = [sr; W];
        for j in 0..W {
            (a[j], g[j]) = design_step::<V, W>(dt[j], sr, c2, last);
        }
        (a, g)
    }
}

/// The measurements of the block at `k`, as "this step of every lane", and
/// (if `check`) whether none is missing (NaN): such a block skips the
/// coasting blends of [`vstep`] (they would select the measured values:
/// the same bits).
///
/// # Safety
/// The CPU features of V; every row of `zp` has `k + W` readable values.
#[inline(always)]
unsafe fn zblock<V: Vd<W>, T: 'static, const W: usize>(
    zp: &[*const T; W],
    k: usize,
    check: bool,
) -> ([V; W], bool) {
    // SAFETY: forwarded from the caller.
    unsafe {
        let mut zv: [V; W] = std::array::from_fn(|l| V::load(zp[l].add(k)));
        V::transpose(&mut zv);
        let clean = check && {
            let mut m = zv[0].ord();
            for zj in &zv[1..] {
                m = V::and(m, zj.ord());
            }
            V::all(m)
        };
        (zv, clean)
    }
}

/// One step of every slot, the scalar `ab_update::<true>`: predict with
/// `d`, update with gains `(a, g)` on the measurement `zj`, or coast where
/// it is NaN (`clean`: none is). Returns the residual (NaN where coasting;
/// only computed if `RESID`).
///
/// # Safety
/// The CPU features of V.
#[inline(always)]
unsafe fn vstep<V: Vd<W>, const W: usize, const RESID: bool>(
    (d, a, g, zj): (V, V, V, V),
    x: &mut V,
    v: &mut V,
    clean: bool,
) -> V {
    // SAFETY: forwarded from the caller.
    unsafe {
        let (zero, one) = (V::splat(0.0), V::splat(1.0));
        let xpred = d.fmadd(*v, *x);
        if clean {
            let w = g.fmadd(zj, *v);
            *x = one.sub(a).fmadd(xpred, a.mul(zj));
            *v = g.fnmadd(xpred, w);
            if RESID {
                return zj.sub(xpred);
            }
        } else {
            let valid = zj.ord();
            let zz = V::blend(valid, zero, zj);
            let c1 = V::blend(valid, one, one.sub(a));
            let gm = V::blend(valid, zero, g);
            let w = gm.fmadd(zz, *v);
            *x = c1.fmadd(xpred, a.mul(zz));
            *v = gm.fnmadd(xpred, w);
            if RESID {
                return V::blend(valid, V::splat(f64::NAN), zj.sub(xpred));
            }
        }
        zero
    }
}

/// The kernel of the design law without residuals, software-pipelined
/// (the Zen 4 form, [`zen4`]): each iteration checks the next block's
/// timestamps and computes its gains (a square root per step, independent
/// of the state) before the current block's update, so that their latency
/// overlaps the update's chain instead of the reorder window filling with
/// one block's instructions before the next block's square roots can
/// start. The same operations per step as [`kernel`] (design law, no
/// residuals, no streamed lines or prefetches), so the same bits. On the
/// Zen 4 EPYC guest (`irrbench`, ns per sample, minimum of alternated
/// runs): z and t in L2 1.62 -> 1.34, 10^7 samples from memory 1.82 ->
/// 1.63. (The fixed-gain law, whose one division per step is shorter, was
/// slower this way from memory, 1.20 -> 1.28, and keeps [`kernel`].)
#[inline(always)]
unsafe fn kernel_design_pipelined<V: Vd<W>, T: IoFloat, const W: usize>(
    lanes: &mut [VLane<'_, T>; W],
    steps: usize,
    max_gap: f64,
) -> usize {
    // SAFETY: the caller has the CPU features of V; `run` checked that every
    // slice holds `steps` samples and T is f32 or f64.
    unsafe {
        // (`run` checked that every lane has the design law.)
        let sr = V::from_lanes(&std::array::from_fn(|l| match lanes[l].law {
            AbLaw::Fixed { alpha, .. } => alpha,
            AbLaw::Design { ratio } => ratio.sqrt(),
        }));
        let c2 = V::from_lanes(&std::array::from_fn(|l| match lanes[l].law {
            AbLaw::Fixed { beta, .. } => beta,
            AbLaw::Design { ratio } => 2.0 * ratio.sqrt(),
        }));
        let mut x = V::from_lanes(&std::array::from_fn(|l| lanes[l].x));
        let mut v = V::from_lanes(&std::array::from_fn(|l| lanes[l].v));
        let mut t_last = V::from_lanes(&std::array::from_fn(|l| lanes[l].t_last));
        let zero = V::splat(0.0);
        let gap = V::splat(max_gap.min(f64::MAX));
        let zp: [*const T; W] = std::array::from_fn(|l| lanes[l].z.as_ptr());
        let tp: [*const f64; W] = std::array::from_fn(|l| lanes[l].t.as_ptr());
        let xp: [*mut T; W] = std::array::from_fn(|l| lanes[l].xs.as_mut_ptr());
        let vp: [*mut T; W] = std::array::from_fn(|l| lanes[l].vs.as_mut_ptr());
        let mut last = (V::splat(f64::NAN), zero, zero);
        let mut k = 0;
        let mut have = false;
        let (mut dt, mut ga, mut gg, mut t_blk) = ([zero; W], [zero; W], [zero; W], t_last);
        if W <= steps {
            let (ok, d, tl) = tblock::<V, W>(&tp, 0, t_last, gap);
            if ok {
                (ga, gg) = design_block::<V, W>(&d, sr, c2, &mut last);
                (have, dt, t_blk) = (true, d, tl);
            }
        }
        while have {
            let mut next = false;
            let (mut dt_n, mut ga_n, mut gg_n, mut t_n) = (dt, ga, gg, t_blk);
            if k + 2 * W <= steps {
                let (ok, d, tl) = tblock::<V, W>(&tp, k + W, t_blk, gap);
                if ok {
                    (ga_n, gg_n) = design_block::<V, W>(&d, sr, c2, &mut last);
                    (next, dt_n, t_n) = (true, d, tl);
                }
            }
            let (zv, clean) = zblock::<V, T, W>(&zp, k, true);
            let mut xo = [zero; W];
            let mut vo = [zero; W];
            for j in 0..W {
                vstep::<V, W, false>((dt[j], ga[j], gg[j], zv[j]), &mut x, &mut v, clean);
                xo[j] = x;
                vo[j] = v;
            }
            t_last = t_blk;
            V::transpose(&mut xo);
            V::transpose(&mut vo);
            for l in 0..W {
                xo[l].store(xp[l].add(k));
            }
            for l in 0..W {
                vo[l].store(vp[l].add(k));
            }
            k += W;
            (have, dt, ga, gg, t_blk) = (next, dt_n, ga_n, gg_n, t_n);
        }
        let (xa, va, ta) = (x.to_lanes(), v.to_lanes(), t_last.to_lanes());
        for l in 0..W {
            lanes[l].x = xa[l];
            lanes[l].v = va[l];
            lanes[l].t_last = ta[l];
        }
        k
    }
}

/// The kernel (see [`run`]).
#[inline(always)]
unsafe fn kernel<
    V: Vd<W>,
    T: IoFloat,
    const W: usize,
    const DESIGN: bool,
    const RESID: bool,
    const NT: bool,
>(
    lanes: &mut [VLane<'_, T>; W],
    steps: usize,
    max_gap: f64,
    pf: bool,
) -> usize {
    // `NT` is chosen by `run` (four f64 lanes with fixed gains); `Lines`
    // writes f64 rows of four lanes.
    let nt = NT && W == 4 && is_f64::<T>();
    // SAFETY: the caller has the CPU features of V; `run` checked that every
    // slice holds `steps` samples and T is f32 or f64.
    unsafe {
        let par = |f: &dyn Fn(&AbLaw) -> f64| {
            let a: [f64; W] = std::array::from_fn(|l| f(&lanes[l].law));
            V::from_lanes(&a)
        };
        let p0 = par(&|law| match *law {
            AbLaw::Fixed { alpha, .. } => alpha,
            AbLaw::Design { ratio } => ratio.sqrt(),
        });
        let p1 = par(&|law| match *law {
            AbLaw::Fixed { beta, .. } => beta,
            AbLaw::Design { ratio } => 2.0 * ratio.sqrt(),
        });
        let mut x = V::from_lanes(&std::array::from_fn(|l| lanes[l].x));
        let mut v = V::from_lanes(&std::array::from_fn(|l| lanes[l].v));
        let mut t_last = V::from_lanes(&std::array::from_fn(|l| lanes[l].t_last));
        let zero = V::splat(0.0);
        let nan = V::splat(f64::NAN);
        // d <= min(max_gap, MAX) also excludes an infinite d.
        let gap = V::splat(max_gap.min(f64::MAX));
        let zp: [*const T; W] = std::array::from_fn(|l| lanes[l].z.as_ptr());
        let tp: [*const f64; W] = std::array::from_fn(|l| lanes[l].t.as_ptr());
        let xp: [*mut T; W] = std::array::from_fn(|l| lanes[l].xs.as_mut_ptr());
        let vp: [*mut T; W] = std::array::from_fn(|l| lanes[l].vs.as_mut_ptr());
        let rp: [*mut T; W] = std::array::from_fn(|l| {
            lanes[l]
                .rs
                .as_deref_mut()
                .map_or(std::ptr::null_mut(), |r| r.as_mut_ptr())
        });
        // Rows 0..4: the lanes' x, 4..8: their v (T is f64 and W is 4).
        let mut lines: Option<[Lines; 8]> = nt.then(|| {
            std::array::from_fn(|i| Lines::new((if i < 4 { xp[i] } else { vp[i - 4] }) as *mut f64))
        });
        // The design law's gains of the last step computed, and its dt: a
        // step whose dt equals it in every slot (timestamps on a grid: AIS
        // reports in whole seconds, 1 Hz GNSS logs) reuses them; the same
        // operations on the same dt give the same bits. NaN: no first step
        // matches. (Fixed gains keep their one division per step: carrying
        // the last gains made that loop 20 % slower.)
        let mut last = (nan, zero, zero);
        let mut k = 0;
        while k + W <= steps {
            // With `pf` (all but the Zen 4 form, [`zen4`]):
            // prefetch PREFETCH samples ahead in every stream of every lane
            // (16 to 20 streams are too many for the hardware prefetchers),
            // once per 64-byte line of f64 samples (every other block of
            // four, every block of eight). Prefetches never fault, so the
            // addresses may lie past the end.
            for l in 0..W {
                if !pf || (W == 4 && k % 8 != 0) {
                    break;
                }
                prefetch(tp[l].wrapping_add(k + PREFETCH));
                prefetch(zp[l].wrapping_add(k + PREFETCH));
                if !nt {
                    // (Streamed rows are not read: no fetch for ownership.)
                    prefetch(xp[l].wrapping_add(k + PREFETCH));
                    prefetch(vp[l].wrapping_add(k + PREFETCH));
                }
                if RESID {
                    prefetch(rp[l].wrapping_add(k + PREFETCH));
                }
            }
            // The block runs only if all its steps are plain steps.
            let (ok, dt, t_blk) = tblock::<V, W>(&tp, k, t_last, gap);
            if !ok {
                break;
            }
            let (zv, clean) = zblock::<V, T, W>(&zp, k, DESIGN);
            let mut xo = [zero; W];
            let mut vo = [zero; W];
            let mut eo = [zero; W];
            for j in 0..W {
                let d = dt[j];
                let (a, g) = if DESIGN {
                    design_step::<V, W>(d, p0, p1, &mut last)
                } else {
                    (p0, p1.div(d))
                };
                eo[j] = vstep::<V, W, RESID>((d, a, g, zv[j]), &mut x, &mut v, clean);
                xo[j] = x;
                vo[j] = v;
            }
            t_last = t_blk;
            V::transpose(&mut xo);
            V::transpose(&mut vo);
            if let Some(lines) = lines.as_mut() {
                for l in 0..4 {
                    lines[l].put(k, &xo[l].to_lanes());
                }
                for l in 0..4 {
                    lines[4 + l].put(k, &vo[l].to_lanes());
                }
                k += W;
                continue;
            }
            for l in 0..W {
                xo[l].store(xp[l].add(k));
            }
            for l in 0..W {
                vo[l].store(vp[l].add(k));
            }
            if RESID {
                V::transpose(&mut eo);
                for l in 0..W {
                    eo[l].store(rp[l].add(k));
                }
            }
            k += W;
        }
        if let Some(lines) = lines.as_mut() {
            for ln in lines.iter_mut() {
                ln.finish(k);
            }
            _mm_sfence();
        }
        let (xa, va, ta) = (x.to_lanes(), v.to_lanes(), t_last.to_lanes());
        for l in 0..W {
            lanes[l].x = xa[l];
            lanes[l].v = va[l];
            lanes[l].t_last = ta[l];
        }
        k
    }
}

/// One `f64` output row of a four-lane block kernel written in whole
/// 64-byte lines with streamed stores ([`run`]): each block hands over
/// its four values at element `k` (a multiple of 4); the 32-byte aligned
/// half-lines are put together from two consecutive blocks when the row
/// is not 32-byte aligned (one or two shuffles), a line is streamed when
/// both its halves are there, and the parts of lines that the call does
/// not write whole (before its first whole line, after its last) get
/// ordinary stores. Before, these lanes wrote their rows with ordinary
/// stores: every output line was read from memory first (48 bytes of
/// traffic per sample instead of 32): 1,000 x 10,000 fixed gains 1.63-1.67
/// -> 1.46-1.47 ns per sample. With the design law (more arithmetic per
/// step) the per-row bookkeeping cost more than the traffic saved
/// (1.71-1.72 -> 1.88-1.90), so it keeps its ordinary stores
/// (docs/benchmarks.md, session 27).
struct Lines {
    base: *mut f64,
    /// Elements of the previous block in the aligned half-line that ends
    /// inside the current one (the row's start, in elements, modulo 4).
    e: usize,
    prev: __m256d,
    /// A first half-line waiting for its second: its first element and
    /// its values.
    held: Option<(usize, __m256d)>,
    /// Blocks handed over.
    started: bool,
}

impl Lines {
    fn new(base: *mut f64) -> Self {
        Lines {
            base,
            e: (base as usize / 8) % 4,
            // SAFETY: plain register value (AVX is available to every
            // caller, see `put`).
            prev: unsafe { _mm256_setzero_pd() },
            held: None,
            started: false,
        }
    }

    /// The block's values `a` at elements `k..k + 4` of the row.
    ///
    /// # Safety
    /// AVX2 is available; the row has `k + 4` writable elements.
    #[inline(always)]
    unsafe fn put(&mut self, k: usize, a: &[f64]) {
        let Some(a) = a.first_chunk::<4>() else {
            return;
        };
        // SAFETY: forwarded from the caller.
        unsafe {
            let cur = _mm256_loadu_pd(a.as_ptr());
            let e = self.e;
            if e == 0 {
                self.half(k, cur);
            } else {
                if self.started {
                    // [prev's last e | cur's first 4 - e] at element k - e.
                    let t = _mm256_permute2f128_pd::<0x21>(self.prev, cur);
                    let h = match e {
                        1 => _mm256_shuffle_pd::<5>(t, cur),
                        2 => t,
                        _ => _mm256_shuffle_pd::<5>(self.prev, t),
                    };
                    self.half(k - e, h);
                } else {
                    // The first 4 - e values finish a half-line that began
                    // before this call: ordinary stores.
                    for (i, v) in a.iter().enumerate().take(4 - e) {
                        *self.base.add(k + i) = *v;
                    }
                }
                self.prev = cur;
            }
            self.started = true;
        }
    }

    /// An aligned half-line `h` at element `at`.
    ///
    /// # Safety
    /// AVX is available; elements `at..at + 4` are writable and 32-byte
    /// aligned.
    #[inline(always)]
    unsafe fn half(&mut self, at: usize, h: __m256d) {
        // SAFETY: forwarded from the caller.
        unsafe {
            let p = self.base.add(at);
            if (p as usize).is_multiple_of(64) {
                if let Some((hk, hv)) = self.held.take() {
                    _mm256_store_pd(self.base.add(hk), hv);
                }
                self.held = Some((at, h));
            } else if let Some((hk, hv)) = self.held.take() {
                // hk == at - 4: the line's first half, then its second.
                _mm256_stream_pd(self.base.add(hk), hv);
                _mm256_stream_pd(p, h);
            } else {
                // The second half of a line whose first half this call does
                // not write.
                _mm256_store_pd(p, h);
            }
        }
    }

    /// After the last block (the row written up to element `end`): the
    /// waiting half-line and the values after the last whole half-line.
    ///
    /// # Safety
    /// AVX is available; the row has `end` writable elements.
    #[inline(always)]
    unsafe fn finish(&mut self, end: usize) {
        // SAFETY: forwarded from the caller.
        unsafe {
            if let Some((hk, hv)) = self.held.take() {
                _mm256_store_pd(self.base.add(hk), hv);
            }
            if self.started && self.e > 0 {
                let mut a = [0.0; 4];
                _mm256_storeu_pd(a.as_mut_ptr(), self.prev);
                for (i, v) in a.iter().enumerate().skip(4 - self.e) {
                    *self.base.add(end - 4 + i) = *v;
                }
            }
            self.started = false;
        }
    }
}
