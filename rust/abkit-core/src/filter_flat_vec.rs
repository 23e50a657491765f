//! The flat alpha-beta kernel of [`super::flat`] (many short tracks stored
//! back to back, slots walking *regions* of consecutive tracks in whole
//! cache lines across the track boundaries) written once over a small
//! vector trait ([`crate::ragged_simd::Vd`]): `W` slots per register, `R`
//! registers (independent dependency chains), `L = R W` slots.
//!
//! Instances:
//! - AVX2 + FMA ([`ab_flat_avx2`]): `W = 4`, one register (4 slots). The
//!   default on CPUs with AVX2 and FMA but without AVX-512. (Two registers,
//!   8 slots, `kernel::<V4, T, 4, 2, 8>`, measured no faster in `f64` and
//!   slower in `f32` on an AMD EPYC (Zen 3): 16 concurrent non-temporal
//!   output streams instead of 8. Half-line `f32` blocks were slower too.)
//!   Its blocks without events (`FAST4`) run through the AVX2 row lanes'
//!   [`super::avx2::group_block`] with the slot states held in registers
//!   across the blocks (+5 % `f64`, +10-20 % `f32` on Zen 3; the same bits).
//! - AVX-512F + FMA ([`ab_flat_avx512`]): `W = 8`, one register; only with
//!   `ABKIT_FLAT_AVX512=1` (the default on AVX-512 CPUs stays the
//!   hand-written [`super::flat`]). `ABKIT_FLAT_AVX2=1` takes the AVX2
//!   instance on AVX-512 CPUs too (tests and comparisons).
//!
//! The structure is that of [`super::flat`] (see its module docs): a block
//! is one 64-byte line of `T` per slot (8 `f64` or 16 `f32` samples), run as
//! sub-blocks of `W` samples (per register: `W` loads, a `W x W`
//! transpose, `W` vector steps, transposes back); blocks in which every
//! slot has only running samples run without bookkeeping and store whole
//! lines (non-temporal for large outputs; AVX2: `f64` only). At a track
//! boundary the new track starts as in [`super::flat`]
//! ([`super::flat::Starter`]): a fresh track whose first samples are valid
//! in the vector steps (per-step slot masks: `x = z` and the first-sample
//! rate at its first sample, `x = z, v = (z - z0) / T` at its second), any
//! other start-up scalar, its outputs written into the slot's stage and
//! stored with the block, the slot's state (and per-track gains) replaced
//! by blends before its first running step; a track's final state is read
//! from the block rows at its last sample. So the lines at the boundaries
//! are stored whole too.
//!
//! In the AVX2 instance the usual block with events (shared gains; each
//! track boundary a track ending and the next starting in the vector
//! steps; no injection, staged start-up output or region end: 24,704 of
//! the 25,315 event blocks of 100,000 rows of 100 `f64`) also runs through
//! the row lanes' block ([`avx2::group_block_ev`]): the starts blended in
//! per step with the operations of [`compute`], the final states taken
//! from the steps' registers, whole lines stored (10-11 % fewer
//! instructions on rows of 100 and ragged lengths 10..10,000; on an AMD
//! EPYC rows of 100 in the caches 4 % faster, ragged 10..10,000 from memory
//! 6 %, 100,000 x 100 `f64` from Python 10 %; docs/benchmarks.md, session
//! 20). Other event blocks take [`compute`].
//!
//! With streamed outputs a slot that needs a new region takes, of the next
//! few, one whose output lines are not at another slot's line offset modulo
//! 4 KiB ([`spread_region`]; Zen 3 runs such non-temporal streams slowly).
//!
//! Every running sample is the scalar `ab_step::<true>` (the same fused
//! operations in the same order) and every start the scalar start-up's
//! arithmetic, so each track is bit-identical to the scalar lanes and to the
//! track run alone, whatever its slot or region.

use std::arch::x86_64::*;

use super::flat::{regions, BlockEvents, Slot, Start, Starter, VecStart, STG};
use super::simd::is_f64;
use super::{avx2, AbConst, Init, IoFloat, TrackState};
use crate::ragged_simd::{Vd, V4, V8};
use crate::Result;

/// Blocks (cache lines) of a slot's z prefetched ahead.
const PREFETCH_BLOCKS: isize = 8;
/// Most samples in a block (16 `f32`).
const MAXB: usize = 16;

/// Regions looked at by [`spread_region`].
const SPREAD_LOOKAHEAD: usize = 8;

/// The region (index into `cand`, the regions not yet given out, in
/// order) for slot `l` when outputs are streamed: the first of the next
/// [`SPREAD_LOOKAHEAD`] whose first `x` and `v` lines are not at the line
/// offset, modulo 4 KiB, of another busy slot's `x` or `v` line (else the
/// next one). All slots move on by a line per block, so these offsets hold
/// until the next refill. On an AMD EPYC (Zen 3) streams of non-temporal
/// stores that agree modulo 4 KiB run much slower (docs/benchmarks.md,
/// sessions 11 and 19): equal tracks whose slots' `x` and `v` lines agreed
/// ran 1.7-2.1 ns per sample against 0.94-1.2 for others (lines next to
/// each other are not slow), and ragged batches of lengths 10..10,000,
/// 10..1,000 and 1,000..10,000 gained 5-10 %. Any order of the regions
/// gives the same results.
fn spread_region<const L: usize>(
    cand: &[(usize, usize)],
    off: &[usize],
    l: usize,
    slots: &[Slot; L],
    (xb, vb): (usize, usize),
    es: usize,
    align_down: impl Fn(isize) -> isize,
) -> usize {
    const PAGE: usize = 4096;
    let at = |base: usize, pos: isize| base.wrapping_add((pos as usize).wrapping_mul(es)) % PAGE;
    let near = |a: usize, b: usize| {
        let d = (a + PAGE - b) % PAGE;
        !(64..=PAGE - 64).contains(&d)
    };
    // The other busy slots' x and v line offsets (L <= 32, asserted by the
    // kernel).
    let mut taken = [0usize; 64];
    let mut n = 0;
    for (m, s) in slots.iter().enumerate() {
        if m != l && s.busy {
            taken[n] = at(xb, s.pos);
            taken[n + 1] = at(vb, s.pos);
            n += 2;
        }
    }
    cand.iter()
        .take(SPREAD_LOOKAHEAD)
        .position(|&(j0, _)| {
            let p = align_down(off[j0] as isize);
            let (x, v) = (at(xb, p), at(vb, p));
            taken[..n].iter().all(|&t| !near(t, x) && !near(t, v))
        })
        .unwrap_or(0)
}

/// One block of samples, 64-byte aligned.
#[repr(C, align(64))]
struct Line<T>([T; MAXB]);
/// Most sub-blocks in a block (`W >= 4`).
const MAXH: usize = 4;

/// Per-step replacement of slot states at the first running sample of a
/// started track (bit `l` of `mask[p]`: slot `l` at block sample `p`).
struct Inject<const L: usize> {
    /// Bit `p`: `mask[p] != 0`.
    steps: u32,
    mask: [u32; MAXB],
    x: [[f64; L]; MAXB],
    v: [[f64; L]; MAXB],
    c: [[[f64; L]; 4]; MAXB],
}

impl<const L: usize> Inject<L> {
    /// Slot `l` takes the state `(x, v)` and the constants `c` before block
    /// step `p`.
    fn set(&mut self, p: usize, l: usize, x: f64, v: f64, c: &AbConst) {
        self.mask[p] |= 1 << l;
        self.steps |= 1 << p;
        self.x[p][l] = x;
        self.v[p][l] = v;
        self.c[p][0][l] = c.t;
        self.c[p][1][l] = c.alpha;
        self.c[p][2][l] = c.one_minus_alpha;
        self.c[p][3][l] = c.g2;
    }
}

/// Per-step slot masks of the vector start-ups in a block (as
/// `flat::Starts`): bit `l` of `s0[p]` for a slot whose track starts at
/// step `p`, of `s1[p]` at its second sample (two-point start); `v0`: the
/// velocity at the first sample (`Init::First`: `v0 + signed * z`;
/// two-point: NaN).
struct Starts<V> {
    /// Bit `p`: `s0[p] | s1[p] != 0`.
    steps: u32,
    s0: [u32; MAXB],
    s1: [u32; MAXB],
    v0: V,
    signed: Option<V>,
}

/// A block's events into the kernel's tables (their `steps` say whether
/// anything went in).
impl<const L: usize, V> BlockEvents for (&mut Inject<L>, &mut Starts<V>) {
    fn inject(&mut self, p: usize, l: usize, x: f64, v: f64, c: &AbConst) {
        self.0.set(p, l, x, v, c);
    }
    fn start(&mut self, p: usize, l: usize, second: bool) {
        let st = &mut *self.1;
        let m = if second { &mut st.s1 } else { &mut st.s0 };
        m[p] |= 1 << l;
        st.steps |= 1 << p;
    }
}

/// The running states and constants of the slots, per register.
struct Kern<V, const R: usize> {
    xv: [V; R],
    vv: [V; R],
    ct: [V; R],
    calpha: [V; R],
    coma: [V; R],
    cg2: [V; R],
}

/// Block outputs: `buf[h][r][i]` holds the `W` samples of sub-block `h` of
/// slot `r W + i`.
type Buf<V, const W: usize, const R: usize> = [[[V; W]; R]; MAXH];

/// Alpha-beta over the tracks `off[j]..off[j+1]` (AVX2 + FMA, 4 slots):
/// the contract of [`super::flat::ab_flat`].
///
/// # Safety
/// The CPU supports AVX2 and FMA; `T` is `f32` or `f64`.
#[allow(clippy::too_many_arguments)]
#[target_feature(enable = "avx2,fma")]
pub(super) unsafe fn ab_flat_avx2<T: IoFloat>(
    konst: &dyn Fn(usize) -> AbConst,
    shared: bool,
    start: &mut Start<'_, T>,
    off: &[usize],
    z: &[T],
    xs: &mut [T],
    vs: &mut [T],
    states: &mut [TrackState],
    nt: bool,
    skip: Option<&[bool]>,
    vstart: Option<VecStart>,
) -> Result<()> {
    // Non-temporal stores in f64 only: in f32 (16-sample blocks, a track
    // boundary in every few lines) regular stores measured 1.1-2x faster on
    // an AMD EPYC (Zen 3).
    let nt = nt && is_f64::<T>();
    if super::zen4_forms() {
        // SAFETY: `zen4_forms()` checked AVX2, FMA, AVX-512F and -VL.
        return unsafe {
            ab_flat_avx2_zen4(
                konst, shared, start, off, z, xs, vs, states, nt, skip, vstart,
            )
        };
    }
    // SAFETY: forwarded (AVX2 and FMA available, T is f32 or f64).
    unsafe {
        kernel::<V4, T, 4, 1, 4, true>(
            konst, shared, start, off, z, xs, vs, states, nt, skip, vstart,
        )
    }
}

/// [`ab_flat_avx2`] compiled with AVX-512VL as well (its Zen 4 form,
/// [`super::zen4_forms`]): the same kernel and operations (the same bits)
/// with 32 vector registers. On a Zen 4 EPYC guest (`ragbench`, 10^7
/// samples from memory, ns per sample, minimum of 3 alternated runs):
/// lengths 10..10,000 0.87 -> 0.81, all 10,000 0.77 -> 0.68, 1,000..10,000
/// 0.95 -> 0.82, 10..300 and all 100 unchanged (docs/benchmarks.md,
/// session 31).
///
/// # Safety
/// The CPU supports AVX2, FMA, AVX-512F and AVX-512VL; `T` is `f32` or
/// `f64`.
#[allow(clippy::too_many_arguments)]
#[target_feature(enable = "avx2,fma,avx512f,avx512vl")]
unsafe fn ab_flat_avx2_zen4<T: IoFloat>(
    konst: &dyn Fn(usize) -> AbConst,
    shared: bool,
    start: &mut Start<'_, T>,
    off: &[usize],
    z: &[T],
    xs: &mut [T],
    vs: &mut [T],
    states: &mut [TrackState],
    nt: bool,
    skip: Option<&[bool]>,
    vstart: Option<VecStart>,
) -> Result<()> {
    // SAFETY: forwarded (AVX2, FMA and AVX-512VL available, T is f32 or f64).
    unsafe {
        kernel::<V4, T, 4, 1, 4, true>(
            konst, shared, start, off, z, xs, vs, states, nt, skip, vstart,
        )
    }
}

/// Alpha-beta over the tracks `off[j]..off[j+1]` (AVX-512F + FMA, 8
/// slots): the contract of [`super::flat::ab_flat`].
///
/// # Safety
/// The CPU supports AVX-512F and FMA; `T` is `f32` or `f64`.
#[allow(clippy::too_many_arguments)]
#[target_feature(enable = "avx512f,fma")]
pub(super) unsafe fn ab_flat_avx512<T: IoFloat>(
    konst: &dyn Fn(usize) -> AbConst,
    shared: bool,
    start: &mut Start<'_, T>,
    off: &[usize],
    z: &[T],
    xs: &mut [T],
    vs: &mut [T],
    states: &mut [TrackState],
    nt: bool,
    skip: Option<&[bool]>,
    vstart: Option<VecStart>,
) -> Result<()> {
    // SAFETY: forwarded (AVX-512F and FMA available, T is f32 or f64).
    unsafe {
        kernel::<V8, T, 8, 1, 8, false>(
            konst, shared, start, off, z, xs, vs, states, nt, skip, vstart,
        )
    }
}

/// The kernel (see the module docs).
///
/// # Safety
/// The CPU has the features of `V`; `T` is `f32` or `f64`; `L == R W`,
/// `W` is 4 or 8 and `L <= 32`.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
unsafe fn kernel<
    V: Vd<W>,
    T: IoFloat,
    const W: usize,
    const R: usize,
    const L: usize,
    const FAST4: bool,
>(
    konst: &dyn Fn(usize) -> AbConst,
    shared: bool,
    start: &mut Start<'_, T>,
    off: &[usize],
    z: &[T],
    xs: &mut [T],
    vs: &mut [T],
    states: &mut [TrackState],
    nt: bool,
    skip: Option<&[bool]>,
    vstart: Option<VecStart>,
) -> Result<()> {
    const { assert!(L == R * W && (W == 4 || W == 8) && L <= 32) };
    const { assert!(!FAST4 || (W == 4 && R == 1 && L == 4)) };
    let n_tracks = states.len();
    let total = off.last().copied().unwrap_or(0);
    if off.len() != n_tracks + 1 || z.len() < total || xs.len() < total || vs.len() < total {
        return Err(crate::Error::Shape(
            "flat alpha-beta: buffers do not match the offsets".into(),
        ));
    }
    if n_tracks == 0 {
        return Ok(());
    }
    let len = total as isize;
    let es = std::mem::size_of::<T>();
    let sb = 64 / es;
    let sbi = sb as isize;
    let halves = sb / W;
    // Blocks are aligned to the x output's lines.
    let mis = ((xs.as_ptr() as usize) % 64 / es) as isize;
    let align_down = |p: isize| p - (p + mis).rem_euclid(sbi);
    let v_aligned = (vs.as_ptr() as usize) % 64 == (xs.as_ptr() as usize) % 64;
    let mut regs = regions(off, (total / 64).clamp(512, 8192), skip);
    let bases = (xs.as_ptr() as usize, vs.as_ptr() as usize);
    let mut next_region = 0;
    let c0 = konst(0);
    let mut slots = [Slot {
        pos: 0,
        cur: 0,
        region_end: 0,
        busy: false,
        skip: 0,
        running: false,
        inj: isize::MAX,
        inj_x: 0.0,
        inj_v: 0.0,
        inj_c: c0,
        end: 0,
        stg: 0,
        vs0: isize::MAX,
        vs1: isize::MAX,
    }; L];
    let mut inject = Inject::<L> {
        steps: 0,
        mask: [0; MAXB],
        x: [[0.0; L]; MAXB],
        v: [[0.0; L]; MAXB],
        c: [[[0.0; L]; 4]; MAXB],
    };

    // Start-up stages, one per slot (see `flat`): sample `pos + i` of the
    // slot at index `i` (bit `i` of `Slot::stg` set when it holds a start-up
    // output).
    let mut stg_x = [[T::from_f64(0.0); STG]; L];
    let mut stg_v = [[T::from_f64(0.0); STG]; L];
    let mut cx = Starter {
        off,
        z,
        konst,
        shared,
        c0,
        vstart,
        start,
    };
    // Give slot `l` its next region (or mark it idle).
    macro_rules! refill {
        ($l:expr) => {{
            let l: usize = $l;
            if next_region < regs.len() {
                if nt {
                    let c =
                        spread_region(&regs[next_region..], off, l, &slots, bases, es, align_down);
                    regs.swap(next_region, next_region + c);
                }
                let (j0, j1) = regs[next_region];
                next_region += 1;
                slots[l].busy = true;
                slots[l].region_end = j1;
                slots[l].pos = align_down(off[j0] as isize);
                let (sl, gx, gv) = (&mut slots[l], &mut stg_x[l], &mut stg_v[l]);
                cx.track(sl, j0, states, xs, vs, gx, gv)?;
            } else {
                slots[l].busy = false;
            }
        }};
    }
    for l in 0..L {
        refill!(l);
    }
    let full: u32 = if sb == 16 { 0xffff } else { 0xff };
    // SAFETY (whole block below): the CPU has V's features (caller).
    let zero = unsafe { V::splat(0.0) };
    let cv = |f: f64| [unsafe { V::splat(f) }; R];
    let mut k = Kern::<V, R> {
        xv: [zero; R],
        vv: [zero; R],
        ct: cv(c0.t),
        calpha: cv(c0.alpha),
        coma: cv(c0.one_minus_alpha),
        cg2: cv(c0.g2),
    };
    let mut xbuf: Buf<V, W, R> = [[[zero; W]; R]; MAXH];
    let mut vbuf: Buf<V, W, R> = [[[zero; W]; R]; MAXH];
    let mut caps: Vec<(usize, usize, usize)> = Vec::with_capacity(4 * L);
    // SAFETY: the CPU has V's features (caller).
    let mut starts = Starts::<V> {
        steps: 0,
        s0: [0; MAXB],
        s1: [0; MAXB],
        v0: unsafe {
            V::splat(match vstart {
                Some(VecStart::Rows(Init::First)) => 0.0,
                Some(VecStart::Tracks(Init::First)) => -0.0,
                _ => f64::NAN,
            })
        },
        signed: match vstart {
            Some(VecStart::Tracks(Init::First)) => Some(zero),
            _ => None,
        },
    };
    let mut tmp = [[T::from_f64(0.0); MAXB]; L];
    // Line staging of the AVX2 fast blocks (`FAST4`).
    let mut stage = [[T::from_f64(0.0); 16]; 8];
    // Input and outputs of idle slots in fast blocks (aligned: they may be
    // streamed).
    let zline = Line([T::from_f64(0.0); MAXB]);
    let mut scratch = [
        Line([T::from_f64(0.0); MAXB]),
        Line([T::from_f64(0.0); MAXB]),
    ];
    // The AVX2 instance (`FAST4`: W == 4, so each `[f64; W]` holds the four
    // slots): its constants and states as `__m256d` (`regs4!`) and back
    // (`unregs4!`).
    macro_rules! regs4 {
        () => {{
            let c = avx2::Consts {
                t: _mm256_loadu_pd(k.ct[0].to_lanes().as_ptr()),
                alpha: _mm256_loadu_pd(k.calpha[0].to_lanes().as_ptr()),
                oma: _mm256_loadu_pd(k.coma[0].to_lanes().as_ptr()),
                g2: _mm256_loadu_pd(k.cg2[0].to_lanes().as_ptr()),
            };
            let x = _mm256_loadu_pd(k.xv[0].to_lanes().as_ptr());
            let v = _mm256_loadu_pd(k.vv[0].to_lanes().as_ptr());
            (c, x, v)
        }};
    }
    macro_rules! unregs4 {
        ($x:expr, $v:expr) => {{
            let mut a = [0.0; W];
            _mm256_storeu_pd(a.as_mut_ptr(), $x);
            k.xv[0] = V::from_lanes(&a);
            _mm256_storeu_pd(a.as_mut_ptr(), $v);
            k.vv[0] = V::from_lanes(&a);
        }};
    }
    // The four slots' block rows at their `pos` for `group_block` and how
    // far each moves per block: x lines are aligned (blocks follow them), v
    // streamed only if aligned too; idle slots: zeros in, a scratch line
    // out, not moving. (Each busy slot's block must be inside z, xs, vs.)
    macro_rules! rows4 {
        () => {{
            let busy: [bool; 4] = std::array::from_fn(|l| slots[l].busy);
            let adv: [isize; 4] = std::array::from_fn(|l| if busy[l] { sbi } else { 0 });
            let rows = avx2::Rows {
                z: std::array::from_fn(|l| {
                    if busy[l] {
                        z.as_ptr().offset(slots[l].pos)
                    } else {
                        zline.0.as_ptr()
                    }
                }),
                x: std::array::from_fn(|l| {
                    if busy[l] {
                        xs.as_mut_ptr().offset(slots[l].pos)
                    } else {
                        scratch[0].0.as_mut_ptr()
                    }
                }),
                v: std::array::from_fn(|l| {
                    if busy[l] {
                        vs.as_mut_ptr().offset(slots[l].pos)
                    } else {
                        scratch[1].0.as_mut_ptr()
                    }
                }),
                stream: std::array::from_fn(|i| nt && (i < 4 || v_aligned)),
            };
            (rows, adv)
        }};
    }
    // One block of the four slots through the row lanes' block code (with
    // the starts and captures of `$ev`), streamed if `nt`.
    macro_rules! block4 {
        ($c:expr, $one:expr, $x:expr, $v:expr, $rows:expr, $ev:expr) => {
            if nt {
                avx2::group_block_ev::<T, true>(
                    &$c, $one, &mut $x, &mut $v, &$rows, sb, &mut stage, $ev,
                )
            } else {
                avx2::group_block_ev::<T, false>(
                    &$c, $one, &mut $x, &mut $v, &$rows, sb, &mut stage, $ev,
                )
            }
        };
    }
    // (FAST4) The first-sample velocity of the vector starts, and the
    // states at the captures of a block with events.
    let (v0_4, signed_4) = if FAST4 {
        // SAFETY: W == 4 (FAST4); the CPU has AVX2 (caller).
        unsafe {
            (
                _mm256_loadu_pd(starts.v0.to_lanes().as_ptr()),
                starts
                    .signed
                    .map(|s| _mm256_loadu_pd(s.to_lanes().as_ptr())),
            )
        }
    } else {
        // SAFETY: the CPU has AVX (caller).
        unsafe { (_mm256_setzero_pd(), None) }
    };
    // SAFETY: the CPU has AVX (caller).
    let mut capx = [unsafe { _mm256_setzero_pd() }; MAXB];
    let mut capv = capx;
    loop {
        if slots.iter().all(|s| !s.busy) {
            break;
        }
        // Blocks in which no slot has anything but running samples, run
        // without bookkeeping.
        // Idle slots (no region left for them) do not hold the others back:
        // they compute on a line of zeros and store into a scratch line.
        let mut n_fast = isize::MAX;
        for s in slots.iter().filter(|s| s.busy) {
            n_fast = n_fast.min(s.quiet_blocks(sbi));
            if n_fast == 0 {
                break;
            }
        }
        if FAST4 && n_fast > 0 {
            // The AVX2 instance (4 slots in one register): the fast blocks
            // through the row lanes' `group_block` (states in registers,
            // quarter by quarter, whole streamed lines); the same bits.
            // SAFETY: W == 4 (asserted above), so each [f64; W] holds the
            // four slots; the CPU has AVX2 and FMA (caller).
            unsafe {
                let (c, mut x, mut v) = regs4!();
                // pos..pos+sb is inside each slot's current track for each
                // fast block (they end before the track's last sample).
                let (mut rows, adv) = rows4!();
                let one = _mm256_set1_pd(1.0);
                for _ in 0..n_fast {
                    // (An idle slot's prefetch is of a line near `zline`:
                    // harmless, and no branch.)
                    for zl in rows.z {
                        super::prefetch(zl.wrapping_offset(PREFETCH_BLOCKS * sbi));
                    }
                    block4!(c, one, x, v, rows, None);
                    for l in 0..4 {
                        rows.z[l] = rows.z[l].wrapping_offset(adv[l]);
                        rows.x[l] = rows.x[l].wrapping_offset(adv[l]);
                        rows.v[l] = rows.v[l].wrapping_offset(adv[l]);
                    }
                }
                for s in slots.iter_mut() {
                    s.pos += n_fast * sbi;
                }
                unregs4!(x, v);
            }
        } else {
            for _ in 0..n_fast {
                let mut src = [std::ptr::null::<T>(); L];
                for (l, s) in slots.iter().enumerate() {
                    src[l] = if s.busy {
                        // SAFETY (pointer): pos..pos+sb is inside the current
                        // track (fast blocks end before the track's last sample).
                        let p = unsafe { z.as_ptr().offset(s.pos) };
                        super::prefetch(p.wrapping_offset(PREFETCH_BLOCKS * sbi));
                        p
                    } else {
                        zline.0.as_ptr()
                    };
                }
                // SAFETY: every src[l] has sb readable samples.
                unsafe {
                    compute::<V, T, W, R, L>(&src, halves, &mut k, None, None, &mut xbuf, &mut vbuf)
                };
                for (l, s) in slots.iter_mut().enumerate() {
                    if !s.busy {
                        continue;
                    }
                    // SAFETY: pos..pos+sb is inside xs and vs; x stores are
                    // line-aligned (blocks follow x's lines), v streamed only if
                    // aligned too.
                    unsafe {
                        put_line::<V, T, W, R>(xs.as_mut_ptr().offset(s.pos), &xbuf, l, halves, nt);
                        put_line::<V, T, W, R>(
                            vs.as_mut_ptr().offset(s.pos),
                            &vbuf,
                            l,
                            halves,
                            nt && v_aligned,
                        );
                    }
                    s.pos += sbi;
                }
            }
        }
        // One block with events (after a run of blocks without, the next
        // block has some): masks (bit p: sample pos + p is stored),
        // start-ups, starts of running, end-of-track captures.
        let mut masks = [0u32; L];
        let mut done = [false; L];
        starts.steps = 0;
        caps.clear();
        for l in 0..L {
            let s = &mut slots[l];
            // A slot with nothing but running samples in this block needs
            // no bookkeeping: its whole line is stored (as `block` would
            // find). Rows of 100 from memory: the bookkeeping's ticks -45 %
            // with `block` inlined (docs/benchmarks.md, session 33).
            if s.busy && s.quiet_blocks(sbi) > 0 {
                masks[l] = full;
            } else if s.busy {
                (masks[l], done[l]) = cx.block(
                    s,
                    l,
                    sb,
                    &mut (&mut inject, &mut starts),
                    &mut caps,
                    states,
                    xs,
                    vs,
                    &mut stg_x[l],
                    &mut stg_v[l],
                )?;
            }
        }
        if FAST4
            && inject.steps == 0
            && (0..L).all(|l| {
                let s = &slots[l];
                !done[l]
                    && s.stg == 0
                    && (!s.busy || (masks[l] == full && s.pos >= 0 && s.pos + sbi <= len))
            })
        {
            // The usual block with events (shared gains; every boundary a
            // track ending and the next starting in the vector steps; no
            // injection, staged output or region end): the fast blocks'
            // `group_block` with the starts blended in per step (the
            // operations of `compute`: the same bits) and the states kept at
            // the captures; whole lines stored.
            // SAFETY: W == 4 (FAST4); each busy slot's block is inside z,
            // xs and vs (checked above); the CPU has AVX2 and FMA (caller).
            unsafe {
                let (c, mut x, mut v) = regs4!();
                let (rows, _) = rows4!();
                let mut ev = avx2::BlockStarts {
                    steps: starts.steps,
                    s0: &mut starts.s0,
                    s1: &mut starts.s1,
                    v0: v0_4,
                    signed: signed_4,
                    caps: caps.iter().fold(0, |a, &(_, p, _)| a | 1 << p),
                    capx: &mut capx,
                    capv: &mut capv,
                };
                let one = _mm256_set1_pd(1.0);
                block4!(c, one, x, v, rows, Some(&mut ev));
                for &(l, p, j) in caps.iter() {
                    let (mut a, mut b) = ([0.0; 4], [0.0; 4]);
                    _mm256_storeu_pd(a.as_mut_ptr(), capx[p]);
                    _mm256_storeu_pd(b.as_mut_ptr(), capv[p]);
                    states[j].x[0] = a[l];
                    states[j].x[1] = b[l];
                }
                unregs4!(x, v);
            }
            for s in slots.iter_mut().filter(|s| s.busy) {
                s.pos += sbi;
            }
            continue;
        }
        let mut src = [std::ptr::null::<T>(); L];
        for (l, s) in slots.iter().enumerate() {
            let at = s.pos;
            src[l] = if s.busy && at >= 0 && at + sbi <= len {
                // SAFETY (pointer): at..at+sb is inside z.
                unsafe { z.as_ptr().offset(at) }
            } else {
                // Partly outside z (or an idle slot): the samples inside.
                let t = &mut tmp[l];
                for p in 0..sb {
                    let g = at + p as isize;
                    t[p] = if s.busy && g >= 0 && g < len {
                        z[g as usize]
                    } else {
                        T::from_f64(0.0)
                    };
                }
                t.as_ptr()
            };
        }
        let inj = if inject.steps != 0 {
            Some(&mut inject)
        } else {
            None
        };
        let vst = if starts.steps != 0 {
            Some(&mut starts)
        } else {
            None
        };
        // SAFETY: every src[l] has sb readable samples.
        unsafe {
            compute::<V, T, W, R, L>(
                &src,
                halves,
                &mut k,
                inj.map(|i| (i, shared)),
                vst,
                &mut xbuf,
                &mut vbuf,
            )
        };
        for l in 0..L {
            let s = &slots[l];
            let m = masks[l];
            if !s.busy || m == 0 {
                continue;
            }
            let sbits = s.stg as u32 & full;
            if sbits != 0 {
                // SAFETY: the CPU has V's features (caller); the stage holds
                // STG >= 16 samples.
                unsafe {
                    merge_stage::<V, T, W, R>(
                        &mut xbuf, &mut vbuf, l, sbits, halves, &stg_x[l], &stg_v[l],
                    )
                };
            }
            let pos = s.pos;
            let inside = pos >= 0 && pos + sbi <= len;
            if m == full && inside {
                // SAFETY: as in the fast blocks.
                unsafe {
                    put_line::<V, T, W, R>(xs.as_mut_ptr().offset(pos), &xbuf, l, halves, nt);
                    put_line::<V, T, W, R>(
                        vs.as_mut_ptr().offset(pos),
                        &vbuf,
                        l,
                        halves,
                        nt && v_aligned,
                    );
                }
            } else {
                // The kept samples: whole sub-blocks with plain vector
                // stores, the others scalar (a masked vector store is slow
                // on some AVX2 CPUs).
                let (r, i) = (l / W, l % W);
                let lane_bits = (1u32 << W) - 1;
                for h in 0..halves {
                    let bits = (m >> (h * W)) & lane_bits;
                    if bits == 0 {
                        continue;
                    }
                    let at = pos + (h * W) as isize;
                    if bits == lane_bits && at >= 0 && at + W as isize <= len {
                        // SAFETY: at..at+W is inside xs and vs.
                        unsafe {
                            xbuf[h][r][i].store::<T>(xs.as_mut_ptr().offset(at));
                            vbuf[h][r][i].store::<T>(vs.as_mut_ptr().offset(at));
                        }
                        continue;
                    }
                    // SAFETY: the CPU has V's features (caller).
                    let (xr, vr) = unsafe { (xbuf[h][r][i].to_lanes(), vbuf[h][r][i].to_lanes()) };
                    for q in 0..W {
                        if bits & (1 << q) != 0 {
                            let g = (at + q as isize) as usize;
                            xs[g] = T::from_f64(xr[q]);
                            vs[g] = T::from_f64(vr[q]);
                        }
                    }
                }
            }
        }
        // Final states of the tracks that ended in this block.
        for &(l, p, j) in caps.iter() {
            let (r, i) = (l / W, l % W);
            // SAFETY: the CPU has V's features (caller).
            let (xr, vr) = unsafe { (xbuf[p / W][r][i].to_lanes(), vbuf[p / W][r][i].to_lanes()) };
            states[j].x[0] = xr[p % W];
            states[j].x[1] = vr[p % W];
        }
        for l in 0..L {
            let s = &mut slots[l];
            if s.stg != 0 {
                s.stg >>= sb;
                if s.stg != 0 {
                    stg_x[l].copy_within(sb.., 0);
                    stg_v[l].copy_within(sb.., 0);
                }
            }
            if !done[l] && slots[l].busy {
                slots[l].pos += sbi;
            }
        }
        // (After the others moved on: a refill sees where they are.)
        for l in 0..L {
            if done[l] {
                refill!(l);
            }
        }
    }
    if nt {
        _mm_sfence();
    }
    Ok(())
}

/// One block: `W * halves` samples of every slot from `src[l]`, per
/// sub-block and register transposed, run (with the slot replacements of
/// `inj`, whose masks are cleared), and transposed back into `xbuf`, `vbuf`.
/// Per slot exactly `ab_step::<true>`.
///
/// # Safety
/// The CPU has V's features; `T` is `f32` or `f64`; each `src[l]` points to
/// `W * halves` readable samples; `halves <= MAXH`.
#[inline(always)]
unsafe fn compute<V: Vd<W>, T: IoFloat, const W: usize, const R: usize, const L: usize>(
    src: &[*const T; L],
    halves: usize,
    k: &mut Kern<V, R>,
    inj: Option<(&mut Inject<L>, bool)>,
    starts: Option<&mut Starts<V>>,
    xbuf: &mut Buf<V, W, R>,
    vbuf: &mut Buf<V, W, R>,
) {
    // SAFETY: forwarded from the caller.
    unsafe {
        let zero = V::splat(0.0);
        let one = V::splat(1.0);
        let lane_bits = (1u32 << W) - 1;
        let mut inj = inj;
        let mut starts = starts;
        for h in 0..halves {
            let mut rows: [[V; W]; R] = std::array::from_fn(|r| {
                std::array::from_fn(|i| V::load(src[r * W + i].add(h * W)))
            });
            for rr in rows.iter_mut() {
                V::transpose(rr);
            }
            for j in 0..W {
                if let Some((inject, shared)) = inj.as_mut() {
                    let p = h * W + j;
                    if inject.steps & (1 << p) != 0 {
                        let m = inject.mask[p];
                        for r in 0..R {
                            let bits = (m >> (r * W)) & lane_bits;
                            if bits == 0 {
                                continue;
                            }
                            let mk = V::mask_bits(bits);
                            let at = |a: &[f64; L]| {
                                V::from_lanes(&*(a.as_ptr().add(r * W) as *const [f64; W]))
                            };
                            k.xv[r] = V::blend(mk, k.xv[r], at(&inject.x[p]));
                            k.vv[r] = V::blend(mk, k.vv[r], at(&inject.v[p]));
                            if !*shared {
                                k.ct[r] = V::blend(mk, k.ct[r], at(&inject.c[p][0]));
                                k.calpha[r] = V::blend(mk, k.calpha[r], at(&inject.c[p][1]));
                                k.coma[r] = V::blend(mk, k.coma[r], at(&inject.c[p][2]));
                                k.cg2[r] = V::blend(mk, k.cg2[r], at(&inject.c[p][3]));
                            }
                        }
                        inject.mask[p] = 0;
                        inject.steps &= !(1 << p);
                    }
                }
                let p = h * W + j;
                let (m0, m1) = match starts.as_deref_mut() {
                    Some(st) if st.steps & (1 << p) != 0 => {
                        st.steps &= !(1 << p);
                        (std::mem::take(&mut st.s0[p]), std::mem::take(&mut st.s1[p]))
                    }
                    _ => (0, 0),
                };
                for r in 0..R {
                    // ab_step::<true>.
                    let zj = rows[r][j];
                    let x0 = k.xv[r];
                    let xpred = k.ct[r].fmadd(k.vv[r], k.xv[r]);
                    let valid = zj.ord();
                    let zz = V::blend(valid, zero, zj);
                    let c1 = V::blend(valid, one, k.coma[r]);
                    let g = V::blend(valid, zero, k.cg2[r]);
                    let w = g.fmadd(zz, k.vv[r]);
                    k.xv[r] = c1.fmadd(xpred, k.calpha[r].mul(zz));
                    k.vv[r] = g.fnmadd(xpred, w);
                    let (b0, b1) = ((m0 >> (r * W)) & lane_bits, (m1 >> (r * W)) & lane_bits);
                    if b0 | b1 != 0 {
                        // Start-ups: at the first sample x = z (velocity
                        // `v0`), at the second (two-point) x = z,
                        // v = (z - z0) / T, as `ab_start` (`flat::compute`).
                        let vel = zj.sub(x0).div(k.ct[r]);
                        k.xv[r] = V::blend(V::mask_bits(b0 | b1), k.xv[r], zj);
                        k.vv[r] = V::blend(V::mask_bits(b1), k.vv[r], vel);
                        if let Some(st) = starts.as_deref() {
                            let v0 = match st.signed {
                                Some(zs) => st.v0.add(zs.mul(zj)),
                                None => st.v0,
                            };
                            k.vv[r] = V::blend(V::mask_bits(b0), k.vv[r], v0);
                        }
                    }
                    xbuf[h][r][j] = k.xv[r];
                    vbuf[h][r][j] = k.vv[r];
                }
            }
            for r in 0..R {
                V::transpose(&mut xbuf[h][r]);
                V::transpose(&mut vbuf[h][r]);
            }
        }
    }
}

/// Replace slot `l`'s samples `p` with bit `p` of `bits` set in a block's
/// outputs by the staged start-up outputs `gx[p]`, `gv[p]` (exact: an `f32`
/// output is narrowed from its `f64` again on store).
///
/// # Safety
/// The CPU has V's features; `T` is `f32` or `f64`; `W * halves <= STG`.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
unsafe fn merge_stage<V: Vd<W>, T: 'static, const W: usize, const R: usize>(
    xbuf: &mut Buf<V, W, R>,
    vbuf: &mut Buf<V, W, R>,
    l: usize,
    bits: u32,
    halves: usize,
    gx: &[T; STG],
    gv: &[T; STG],
) {
    let (r, i) = (l / W, l % W);
    let lane_bits = (1u32 << W) - 1;
    for h in 0..halves {
        let hb = (bits >> (h * W)) & lane_bits;
        if hb != 0 {
            // SAFETY: forwarded from the caller; h * W + W <= STG.
            unsafe {
                let mk = V::mask_bits(hb);
                let (x, v) = (
                    V::load(gx.as_ptr().add(h * W)),
                    V::load(gv.as_ptr().add(h * W)),
                );
                xbuf[h][r][i] = V::blend(mk, xbuf[h][r][i], x);
                vbuf[h][r][i] = V::blend(mk, vbuf[h][r][i], v);
            }
        }
    }
}

/// Store slot `l`'s line of a block at `p` (`f64`: one store per sub-block;
/// `f32`: one per pair of sub-blocks, narrowed), past the caches if `nt`.
///
/// # Safety
/// The CPU has V's features; `T` is `f32` or `f64`; the `W * halves`
/// values at `p` are writable and, if `nt`, `p` is aligned to 64 bytes.
#[inline(always)]
unsafe fn put_line<V: Vd<W>, T: 'static, const W: usize, const R: usize>(
    p: *mut T,
    buf: &Buf<V, W, R>,
    l: usize,
    halves: usize,
    nt: bool,
) {
    let (r, i) = (l / W, l % W);
    // SAFETY: forwarded from the caller.
    unsafe {
        if is_f64::<T>() {
            for h in 0..halves {
                buf[h][r][i].put_f64((p as *mut f64).add(h * W), nt);
            }
        } else {
            for h in (0..halves).step_by(2) {
                V::put_f32_pair(
                    buf[h][r][i],
                    buf[h + 1][r][i],
                    (p as *mut f32).add(h * W),
                    nt,
                );
            }
        }
    }
}
