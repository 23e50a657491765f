//! Alpha-beta over short rows of a rectangular batch, sixteen rows at a
//! time (AVX-512): two groups of eight lanes, one row per lane.
//!
//! The flat kernel ([`super::flat::ab_flat`]) keeps one register of eight
//! slots: its steps wait on one dependency chain (about 8 cycles a step,
//! one cycle per sample), and on rows of ~100 samples every slot crosses a
//! track boundary every few blocks, where the bookkeeping costs many times
//! a block. Here the sixteen rows of a group run in lockstep (they have the
//! same length): each row's start-up is the scalar `ab_start`, the rows
//! step to a common first running sample, and then both groups run their
//! blocks (one line of each row: 8 `f64` or 16 `f32` samples) with two
//! independent chains and no bookkeeping; the last block is masked.
//!
//! Outputs streamed past the caches (`nt`) go through a stage of the
//! sixteen rows (in the caches) that drains to the outputs in whole lines
//! while the next group runs, as in `avx2::ab_short_rows` (its eight-row,
//! AVX2 counterpart, which also takes the rows left over here).
//!
//! Every running sample is `ab_step::<true>`: each row is bit-identical to
//! the row run alone and to the other kernels.
//!
//! Opt-in (`ABKIT_ROWS16=1`, read by `filter::ab_flat_batch`): on an Intel
//! Xeon (Sapphire Rapids class) it was faster than the AVX2 short rows only
//! with z and outputs in the caches and in `f32`, and slower from memory in
//! both precisions (docs/benchmarks.md, session 18).

use std::arch::x86_64::*;

use super::avx2::{self, Drain};
use super::simd::{
    clean_step8, clean_steps8, is_f64, masked_step8, masked_steps8, narrow_steps, no_nan16,
    no_nan8, transpose8, transpose8x16, untranspose8x16, widen_step,
};
use super::{ab_loop, ab_start, AbConst, Init, IoFloat, TrackOut, TrackState};
use crate::Result;

/// Rows per group (two registers of eight lanes).
const R: usize = 16;
/// Lanes per register.
const W: usize = 8;

/// Alpha-beta over `states.len()` rows of `n` samples back to back in `z`,
/// `xs`, `vs` (row `j` has the gains `params[j]`, or `params[0]` for all),
/// sixteen rows at a time (see the module docs); `nt`: outputs streamed
/// past the caches.
///
/// # Safety
/// The CPU supports AVX-512F, AVX2 and FMA; `T` is `f32` or `f64`.
#[allow(clippy::too_many_arguments)]
#[target_feature(enable = "avx512f,avx2,fma")]
pub(super) unsafe fn ab_rows16<T: IoFloat>(
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
    if cn == 0 {
        return Ok(());
    }
    let shared = params.len() == 1;
    if params.is_empty() || (!shared && params.len() < cn) {
        return Err(crate::Error::Shape(
            "short rows: fewer gains than rows".into(),
        ));
    }
    let groups = cn / R;
    let seg = R * n;
    // Streamed outputs: two stages of sixteen rows per component; while the
    // lanes fill one, the other drains to the outputs a few lines per block.
    let mut stage = vec![T::from_f64(0.0); if nt && groups > 0 { 4 * seg } else { 0 }];
    let sp = stage.as_mut_ptr();
    let (xp, vp) = (xs.as_mut_ptr(), vs.as_mut_ptr());
    let mut cur = 0;
    let mut drains: [Option<Drain<T>>; 2] = [None, None];
    let par = |j: usize| params[if shared { 0 } else { j }];
    let sb = 64 / std::mem::size_of::<T>();
    for g in 0..groups {
        let j0 = g * R;
        let zb = &z[j0 * n..(j0 + R) * n];
        // SAFETY: (j0 + R) n <= total <= xs.len(), vs.len(); the groups are
        // disjoint and every access to xs and vs goes through xp, vp (a
        // drain writes the previous group's while this one runs).
        let (ox, ov) = unsafe {
            (
                std::slice::from_raw_parts_mut(xp.add(j0 * n), seg),
                std::slice::from_raw_parts_mut(vp.add(j0 * n), seg),
            )
        };
        let sts = &mut states[j0..j0 + R];
        let (dx, dv): (&mut [T], &mut [T]) = if nt {
            // SAFETY: stage `cur` (x: segment 2 cur, v: 2 cur + 1) is inside
            // `stage` and disjoint from the draining one; all accesses go
            // through `sp`.
            unsafe {
                (
                    std::slice::from_raw_parts_mut(sp.add(2 * cur * seg), seg),
                    std::slice::from_raw_parts_mut(sp.add((2 * cur + 1) * seg), seg),
                )
            }
        } else {
            (&mut *ox, &mut *ov)
        };
        let c: [AbConst; R] = std::array::from_fn(|l| {
            let (a, b, t) = par(j0 + l);
            AbConst::new(a, b, t)
        });
        let mut k0 = [0usize; R];
        for (l, st) in sts.iter_mut().enumerate() {
            let zr = &zb[l * n..(l + 1) * n];
            let (a, b, t) = par(j0 + l);
            let mut o = TrackOut {
                states: [&mut dx[l * n..(l + 1) * n], &mut dv[l * n..(l + 1) * n]],
                resid: None,
            };
            k0[l] = ab_start::<T>(a, b, t, init, st, n, &|k| zr[k].to_f64(), &mut o);
        }
        let running = sts.iter().all(|s| s.phase >= 2.0);
        let kmax = if running {
            k0.iter().copied().max().unwrap_or(n)
        } else {
            n
        };
        let mut x = [0.0; R];
        let mut v = [0.0; R];
        for (l, st) in sts.iter_mut().enumerate() {
            if st.phase < 2.0 {
                continue;
            }
            // A group with a row that does not run: every row alone.
            let to = if running { kmax } else { n };
            let zr = &zb[l * n..(l + 1) * n];
            let mut o = TrackOut {
                states: [&mut dx[l * n..(l + 1) * n], &mut dv[l * n..(l + 1) * n]],
                resid: None,
            };
            ab_loop::<T, true>(&c[l], st, k0[l], to, |k| zr[k].to_f64(), &mut o);
            x[l] = st.x[0];
            v[l] = st.x[1];
        }
        if running && kmax < n {
            // The next group's z, fetched while this group runs
            // (sixteen interleaved rows defeat the hardware prefetcher).
            let next = if j0 + 2 * R <= cn {
                Some(z[(j0 + R) * n..].as_ptr())
            } else {
                None
            };
            let len = n - kmax;
            let blocks = len.div_ceil(sb);
            let drain_per = drains
                .iter()
                .map(|d| d.as_ref().map_or(0, |d| d.lines_left().div_ceil(blocks)))
                .max()
                .unwrap_or(0);
            // SAFETY: the CPU features (caller); rows of n samples from
            // zb, dx, dv, read and written from kmax on; `next` is only
            // prefetched.
            unsafe {
                body(
                    &Rows {
                        z: zb.as_ptr(),
                        x: dx.as_mut_ptr(),
                        v: dv.as_mut_ptr(),
                        n,
                        kmax,
                        next,
                    },
                    &c,
                    &mut x,
                    &mut v,
                    &mut drains,
                    drain_per,
                )
            };
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
    // Rows left over (fewer than sixteen): the eight-row AVX2 lanes.
    let j0 = groups * R;
    if j0 < cn {
        let pr = if shared { params } else { &params[j0..cn] };
        let (a, e) = (j0 * n, total);
        // SAFETY: the CPU has AVX2 and FMA (caller).
        unsafe {
            avx2::ab_short_rows(
                pr,
                init,
                n,
                &z[a..e],
                &mut xs[a..e],
                &mut vs[a..e],
                &mut states[j0..],
                nt,
            )?
        };
    }
    Ok(())
}

/// A group's rows: row `l` at `z + l n` (`x`, `v` alike), the lanes from
/// sample `kmax`; `next`: the next group's rows of z (prefetched).
struct Rows<T> {
    z: *const T,
    x: *mut T,
    v: *mut T,
    n: usize,
    kmax: usize,
    next: Option<*const T>,
}

/// The lanes of a group of sixteen rows from `kmax` to `n`: blocks of one
/// line per row (the last one masked), the running states `x`, `v` in and
/// out; `drain_per` lines of each drain streamed per block.
///
/// # Safety
/// AVX-512F, AVX2 and FMA are available; `T` is `f32` or `f64`; the rows of
/// `rows` are readable (z) and writable (x, v) from `kmax` to `n`.
#[inline]
#[target_feature(enable = "avx512f,avx2,fma")]
unsafe fn body<T: IoFloat>(
    rows: &Rows<T>,
    c: &[AbConst; R],
    x: &mut [f64; R],
    v: &mut [f64; R],
    drains: &mut [Option<Drain<T>>; 2],
    drain_per: usize,
) {
    let lane = |g: usize, f: fn(&AbConst) -> f64| {
        let a: [f64; W] = std::array::from_fn(|i| f(&c[g * W + i]));
        // SAFETY: a plain array of 8 f64.
        unsafe { _mm512_loadu_pd(a.as_ptr()) }
    };
    let cs: [[__m512d; 4]; 2] = std::array::from_fn(|g| {
        [
            lane(g, |c| c.t),
            lane(g, |c| c.alpha),
            lane(g, |c| c.one_minus_alpha),
            lane(g, |c| c.g2),
        ]
    });
    // SAFETY: plain arrays of 16 f64.
    let (mut xv, mut vv): ([__m512d; 2], [__m512d; 2]) = unsafe {
        (
            [
                _mm512_loadu_pd(x.as_ptr()),
                _mm512_loadu_pd(x.as_ptr().add(W)),
            ],
            [
                _mm512_loadu_pd(v.as_ptr()),
                _mm512_loadu_pd(v.as_ptr().add(W)),
            ],
        )
    };
    let Rows {
        z,
        x: xo,
        v: vo,
        n,
        kmax,
        next,
    } = *rows;
    let sb = 64 / std::mem::size_of::<T>();
    let len = n - kmax;
    let blocks = len.div_ceil(sb);
    for b in 0..blocks {
        let k = kmax + b * sb;
        let steps = (n - k).min(sb);
        if let Some(nx) = next {
            if b == 0 {
                for r in 0..R {
                    super::prefetch(nx.wrapping_add(r * n));
                }
            }
            for r in 0..R {
                super::prefetch(nx.wrapping_add(r * n + k + sb));
            }
        }
        for g in 0..2 {
            let r0 = g * W * n + k;
            // SAFETY: rows g W .. g W + 8 have samples k .. k + steps
            // (masked loads and stores touch only those).
            unsafe {
                if is_f64::<T>() {
                    let m = ((1u32 << steps) - 1) as u8;
                    block_f64(
                        z.add(r0) as *const f64,
                        xo.add(r0) as *mut f64,
                        vo.add(r0) as *mut f64,
                        n,
                        m,
                        steps,
                        cs[g],
                        &mut xv[g],
                        &mut vv[g],
                    );
                } else {
                    let m = ((1u32 << steps) - 1) as u16;
                    block_f32(
                        z.add(r0) as *const f32,
                        xo.add(r0) as *mut f32,
                        vo.add(r0) as *mut f32,
                        n,
                        m,
                        steps,
                        cs[g],
                        &mut xv[g],
                        &mut vv[g],
                    );
                }
            }
        }
        for d in drains.iter_mut().flatten() {
            // SAFETY: the CPU has AVX2 (caller).
            unsafe { d.lines(drain_per) };
        }
    }
    // SAFETY: plain arrays of 16 f64.
    unsafe {
        _mm512_storeu_pd(x.as_mut_ptr(), xv[0]);
        _mm512_storeu_pd(x.as_mut_ptr().add(W), xv[1]);
        _mm512_storeu_pd(v.as_mut_ptr(), vv[0]);
        _mm512_storeu_pd(v.as_mut_ptr().add(W), vv[1]);
    }
}

/// `steps` (<= 8) steps of eight `f64` rows (row `i` at `z + i n`, the
/// samples of mask `m`), estimates to `xo`, `vo` alike.
///
/// # Safety
/// AVX-512F and FMA are available; the masked samples are readable (z) and
/// writable (x, v).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
unsafe fn block_f64(
    z: *const f64,
    xo: *mut f64,
    vo: *mut f64,
    n: usize,
    m: u8,
    steps: usize,
    c: [__m512d; 4],
    xv: &mut __m512d,
    vv: &mut __m512d,
) {
    // SAFETY: forwarded from the caller.
    unsafe {
        let mut rows: [__m512d; W] =
            std::array::from_fn(|i| _mm512_maskz_loadu_pd(m, z.add(i * n)));
        let clean = no_nan8(&rows);
        transpose8(&mut rows);
        let zero = _mm512_setzero_pd();
        let (mut xb, mut vb) = ([zero; W], [zero; W]);
        if steps == W {
            if clean {
                clean_steps8(&rows, c, xv, vv, &mut xb, &mut vb);
            } else {
                masked_steps8(&rows, c, xv, vv, &mut xb, &mut vb);
            }
        } else {
            partial_steps(&rows, steps, clean, c, xv, vv, &mut xb, &mut vb);
        }
        transpose8(&mut xb);
        transpose8(&mut vb);
        for i in 0..W {
            _mm512_mask_storeu_pd(xo.add(i * n), m, xb[i]);
            _mm512_mask_storeu_pd(vo.add(i * n), m, vb[i]);
        }
    }
}

/// `steps` (<= 16) steps of eight `f32` rows (row `i` at `z + i n`, the
/// samples of mask `m`), estimates to `xo`, `vo` alike (narrowed).
///
/// # Safety
/// AVX-512F and FMA are available; the masked samples are readable (z) and
/// writable (x, v).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
unsafe fn block_f32(
    z: *const f32,
    xo: *mut f32,
    vo: *mut f32,
    n: usize,
    m: u16,
    steps: usize,
    c: [__m512d; 4],
    xv: &mut __m512d,
    vv: &mut __m512d,
) {
    // SAFETY: forwarded from the caller.
    unsafe {
        let mut rows: [__m512; W] = if steps == 2 * W {
            std::array::from_fn(|i| _mm512_loadu_ps(z.add(i * n)))
        } else {
            std::array::from_fn(|i| _mm512_maskz_loadu_ps(m, z.add(i * n)))
        };
        let clean = no_nan16(&rows);
        transpose8x16(&mut rows);
        let zero = _mm512_setzero_pd();
        let (mut xb, mut vb) = ([[zero; W]; 2], [[zero; W]; 2]);
        for h in 0..2 {
            let hs = steps.saturating_sub(h * W).min(W);
            if hs == 0 {
                break;
            }
            let zt: [__m512d; W] = std::array::from_fn(|j| widen_step(&rows, h * W + j));
            let (xh, vh) = (&mut xb[h], &mut vb[h]);
            if hs == W {
                if clean {
                    clean_steps8(&zt, c, xv, vv, xh, vh);
                } else {
                    masked_steps8(&zt, c, xv, vv, xh, vh);
                }
            } else {
                partial_steps(&zt, hs, clean, c, xv, vv, xh, vh);
            }
        }
        let mut xl = narrow_steps(&xb);
        let mut vl = narrow_steps(&vb);
        untranspose8x16(&mut xl);
        untranspose8x16(&mut vl);
        if steps == 2 * W {
            for i in 0..W {
                _mm512_storeu_ps(xo.add(i * n), xl[i]);
                _mm512_storeu_ps(vo.add(i * n), vl[i]);
            }
        } else {
            for i in 0..W {
                _mm512_mask_storeu_ps(xo.add(i * n), m, xl[i]);
                _mm512_mask_storeu_ps(vo.add(i * n), m, vl[i]);
            }
        }
    }
}

/// The first `steps` (< 8) steps of transposed samples `zt`.
///
/// # Safety
/// AVX-512F and FMA are available.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
unsafe fn partial_steps(
    zt: &[__m512d; W],
    steps: usize,
    clean: bool,
    c: [__m512d; 4],
    xv: &mut __m512d,
    vv: &mut __m512d,
    xo: &mut [__m512d; W],
    vo: &mut [__m512d; W],
) {
    // SAFETY: forwarded from the caller.
    unsafe {
        let one = _mm512_set1_pd(1.0);
        for j in 0..steps {
            if clean {
                clean_step8(c, xv, vv, zt[j]);
            } else {
                masked_step8(c, one, xv, vv, zt[j]);
            }
            xo[j] = *xv;
            vo[j] = *vv;
        }
    }
}
