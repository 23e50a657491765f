//! AVX2 (+FMA) alpha-beta lanes for CPUs without AVX-512: the eight tracks
//! of an [`AB_LANES`] group in two 4-slot `f64` registers (lanes 0-3 and
//! 4-7).
//!
//! Per block of eight samples each lane loads its eight consecutive samples
//! (two 4-wide loads), 4 x 4 transposes of the four quadrants give "step
//! `j` of lanes 0-3" and "step `j` of lanes 4-7", eight vector steps run the
//! recursion of both halves (two independent dependency chains), and 4 x 4
//! transposes turn the estimates back into rows, stored a whole 64-byte
//! cache line at a time (two 32-byte stores; `f32`: blocks of sixteen
//! samples, narrowed to a line of sixteen `f32`). The order of the stores
//! matters on Zen 3: `f64` writes the eight `x` lines of a block, then the
//! eight `v` lines (0.93 of the non-temporal copy ceiling on 1,000 x 10,000,
//! against 0.6 lane by lane); `f32` lane by lane (`x` line, `v` line), the
//! faster order there. The arithmetic of each
//! slot is exactly the scalar [`ab_step`] with FMA (the same fused
//! operations in the same order), so results are bit-identical to the
//! scalar lanes and to the AVX-512 lanes.
//!
//! As in the AVX-512 lanes, every lane first steps (scalar) to a sample
//! whose `x` output starts a cache line, so the stores are aligned and, for
//! outputs too big for the caches, non-temporal.

use std::arch::x86_64::*;

use super::simd::{fits, is_f64};
use super::{ab_step, prefetch, AbConst, IoFloat, AB_LANES};

/// Slots per register.
const V: usize = 4;
/// Samples per sub-block (two registers per lane).
const W: usize = 8;

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

/// Store 32 bytes at `p`: 4 `f64` (`a`), or 8 `f32` (`a` then `b`, narrowed
/// with round to nearest); streamed past the caches if `nt`.
///
/// # Safety
/// `T` is `f64` or `f32`, the 32 bytes at `p` are writable and, if `nt`,
/// aligned to 32 bytes; AVX is available.
#[inline]
#[target_feature(enable = "avx2")]
unsafe fn store32<T: 'static>(p: *mut T, a: __m256d, b: __m256d, nt: bool) {
    // SAFETY: forwarded from the caller.
    unsafe {
        if is_f64::<T>() {
            if nt {
                _mm256_stream_pd(p as *mut f64, a)
            } else {
                _mm256_storeu_pd(p as *mut f64, a)
            }
        } else {
            let v = _mm256_set_m128(_mm256_cvtpd_ps(b), _mm256_cvtpd_ps(a));
            if nt {
                _mm256_stream_ps(p as *mut f32, v)
            } else {
                _mm256_storeu_ps(p as *mut f32, v)
            }
        }
    }
}

/// Per-slot constants of four lanes.
#[derive(Clone, Copy)]
struct Consts {
    t: __m256d,
    alpha: __m256d,
    oma: __m256d,
    g2: __m256d,
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
    // Streamed stores need 32-byte alignment (x rows are line-aligned by
    // the head; v rows are streamed only if aligned too).
    let aligned = |p: *const T, at: usize| (p as usize + at * size).is_multiple_of(32);
    let x_nt: [bool; AB_LANES] = std::array::from_fn(|l| nt && aligned(xs[l].as_ptr(), k[l]));
    let v_nt: [bool; AB_LANES] = std::array::from_fn(|l| nt && aligned(vs[l].as_ptr(), k[l]));
    let blocks = k.iter().map(|&kl| (n - kl) / sb).min().unwrap_or(0);
    let consts = |g: usize| {
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
    };
    let cs = [consts(0), consts(1)];
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
        x_nt: &x_nt,
        v_nt: &v_nt,
        ahead,
        nt,
        blocks,
        sb,
    };
    // SAFETY: this function is compiled with AVX2 and FMA.
    unsafe { body::<T>(&ctx, &cs, one, &mut xv, &mut vv, &mut xs, &mut vs) };
    if nt {
        _mm_sfence();
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
    x_nt: &'a [bool; AB_LANES],
    v_nt: &'a [bool; AB_LANES],
    ahead: Option<(usize, usize)>,
    nt: bool,
    blocks: usize,
    sb: usize,
}

/// The vector blocks of the eight lanes (two groups of four, two
/// independent dependency chains).
///
/// # Safety
/// Called only from functions compiled with AVX2 and FMA. Always inlined
/// into them: as an `#[inline]` target-feature function it was inlined only
/// while it had a single caller (a second caller made LLVM keep it out of
/// line and the row lanes lost 45 %; docs/benchmarks.md, "Ragged without
/// t: long tracks in the row lanes, tried").
#[allow(clippy::too_many_arguments)]
// (the inner `unsafe` blocks keep their SAFETY notes inside the outer one)
#[allow(unused_unsafe)]
#[inline(always)]
unsafe fn body<T: IoFloat>(
    ctx: &Body<'_, '_, T>,
    cs: &[Consts; 2],
    one: __m256d,
    xv: &mut [__m256d; 2],
    vv: &mut [__m256d; 2],
    xs: &mut [&mut [T]; AB_LANES],
    vs: &mut [&mut [T]; AB_LANES],
) {
    // SAFETY: the caller has AVX2 and FMA (see above).
    unsafe {
        let Body {
            z,
            k,
            x_nt,
            v_nt,
            ahead,
            nt,
            blocks,
            sb,
        } = *ctx;
        let zero = _mm256_setzero_pd();
        // Local copies of the states (kept in registers).
        let (mut xl, mut vl) = (*xv, *vv);
        for b in 0..blocks {
            // xbuf[h][l][q]: lane l's samples h W + q V .. + V of the block.
            let mut xbuf = [[[zero; 2]; AB_LANES]; 2];
            let mut vbuf = [[[zero; 2]; AB_LANES]; 2];
            for h in 0..sb / W {
                // zq[g][q][j]: step q V + j of lanes 4 g .. 4 g + 4.
                let mut zq = [[[zero; V]; 2]; 2];
                for g in 0..2 {
                    for q in 0..2 {
                        let mut r: [__m256d; V] = std::array::from_fn(|i| {
                            let l = V * g + i;
                            let at = k[l] + b * sb + h * W + q * V;
                            if q == 0 {
                                if let Some((dz, dout)) = ahead {
                                    prefetch(z[l].as_ptr().wrapping_add(dz + at));
                                    if !nt {
                                        prefetch(xs[l].as_ptr().wrapping_add(dout + at));
                                        prefetch(vs[l].as_ptr().wrapping_add(dout + at));
                                    }
                                }
                            }
                            // SAFETY: at + V <= k[l] + blocks * sb <= n = z[l].len().
                            unsafe { load4(z[l].as_ptr().add(at)) }
                        });
                        transpose4(&mut r);
                        zq[g][q] = r;
                    }
                }
                // xo[g][q][j]: estimate after step q V + j of lanes 4 g .. 4 g + 4.
                let mut xo = [[[zero; V]; 2]; 2];
                let mut vo = [[[zero; V]; 2]; 2];
                for q in 0..2 {
                    for j in 0..V {
                        for g in 0..2 {
                            step(&cs[g], one, &mut xl[g], &mut vl[g], zq[g][q][j]);
                            xo[g][q][j] = xl[g];
                            vo[g][q][j] = vl[g];
                        }
                    }
                }
                for g in 0..2 {
                    for q in 0..2 {
                        transpose4(&mut xo[g][q]);
                        transpose4(&mut vo[g][q]);
                        for i in 0..V {
                            xbuf[h][V * g + i][q] = xo[g][q][i];
                            vbuf[h][V * g + i][q] = vo[g][q][i];
                        }
                    }
                }
            }
            // f64: all x lines of the lanes, then all v lines; f32: lane by
            // lane (x line, v line). Measured the faster order of each on Zen 3.
            if is_f64::<T>() {
                for (c, buf, stream) in [(0, &xbuf, x_nt), (1, &vbuf, v_nt)] {
                    for l in 0..AB_LANES {
                        let at = k[l] + b * sb;
                        let p = if c == 0 {
                            xs[l].as_mut_ptr()
                        } else {
                            vs[l].as_mut_ptr()
                        };
                        // SAFETY: at + sb <= n = xs[l].len() = vs[l].len();
                        // streamed stores are 32-byte aligned (x_nt, v_nt), and
                        // every store is 32 bytes at a multiple of 32 bytes past
                        // `at`.
                        unsafe {
                            store32(p.add(at), buf[0][l][0], zero, stream[l]);
                            store32(p.add(at + V), buf[0][l][1], zero, stream[l]);
                        }
                    }
                }
            } else {
                for l in 0..AB_LANES {
                    let at = k[l] + b * sb;
                    let (px, pv) = (xs[l].as_mut_ptr(), vs[l].as_mut_ptr());
                    // SAFETY: as above (a line of 16 f32 is two 32-byte stores).
                    unsafe {
                        store32(px.add(at), xbuf[0][l][0], xbuf[0][l][1], x_nt[l]);
                        store32(px.add(at + W), xbuf[1][l][0], xbuf[1][l][1], x_nt[l]);
                        store32(pv.add(at), vbuf[0][l][0], vbuf[0][l][1], v_nt[l]);
                        store32(pv.add(at + W), vbuf[1][l][0], vbuf[1][l][1], v_nt[l]);
                    }
                }
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
