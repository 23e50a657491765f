//! Alpha-beta over many tracks stored back to back (AVX-512): short rows of
//! a rectangular batch and ragged batches (the Arrow list layout).
//!
//! The row kernel ([`super::simd::ab_lanes8`]) keeps eight tracks in the
//! eight slots of a register for their whole length; on short tracks its
//! per-track start-up, alignment heads and tails cost more than the vector
//! loop saves. Here a slot is not tied to a track but to a *region*: a run
//! of consecutive tracks, contiguous in memory, of a few thousand samples.
//! Each slot walks its region in whole cache lines (8 `f64` or 16 `f32`
//! samples per block) straight across the track boundaries; when its region
//! ends it takes the next one (longest first), so the slots stay busy until
//! the last regions.
//!
//! At a boundary inside a block the slot's track changes:
//! - the old track's final state is read from the block's (`f64`) rows at
//!   its last sample;
//! - the new track's start-up (two-point or first-sample start, or whatever
//!   NaN pattern it begins with) runs scalar, with the same code as
//!   everywhere else, and writes its own outputs; the block does not store
//!   over them (masked stores);
//! - at the first running sample the slot's state (and, for per-track
//!   gains, its constants) is replaced by the started track's (masked
//!   blends before that step).
//!
//! Every running sample is the scalar `ab_step` with FMA, so each track is
//! bit-identical to the row kernel and to the scalar lanes, whatever its
//! region, slot or neighbours.
//!
//! Slot phases: the slots move in lockstep, one line per block each, so the
//! lines they read and stream at the same time keep the distances at which
//! their regions began. On the Intel Xeon of docs/benchmarks.md (session
//! 26) streams whose current lines all have the same parity (address bit
//! 6) ran up to 1.3x slower than streams alternating in parity (a C copy
//! of eight streams: 0.97-1.0 against 0.80-0.82 ns per `f64` sample), and
//! which one a batch got depended on its region length (rows of 100: 8,200
//! samples, an odd number of lines, fast; rows of 128, 256, 400: even,
//! slow). With streamed outputs a slot therefore starts each region in
//! the phase that keeps slot `l` on lines of parity `step + l` (one extra
//! block at most, in which it stores nothing). Scheduling only: the same
//! bits.
//!
//! `v` off `x`'s lines: the blocks follow the `x` output's lines; when the
//! `v` output's lines lie elsewhere (its start is not a whole number of
//! lines after `x`'s, as in 7 of 8 `f64` batch shapes), streamed `f64`
//! `v` lines are put together from two consecutive blocks of a slot
//! ([`VShift`]) instead of being written with ordinary stores.

use std::arch::x86_64::*;

use super::simd::{
    clean_step8, clean_steps8, is_f64, load8, masked_step8, masked_steps8, narrow_steps, no_nan16,
    no_nan8, store_line, store_ps, transpose8, transpose8x16, untranspose8x16, widen_step, VLines,
};
use super::{AbConst, Init, IoFloat, TrackState};
use crate::Result;

const W: usize = 8;
const LANES: usize = 8;
/// Blocks (cache lines) of a slot's z prefetched ahead.
const PREFETCH_BLOCKS: isize = 8;
/// Samples of a slot's start-up stage (from its current block's first
/// sample): three lines of `f32`, six of `f64`.
pub(super) const STG: usize = 48;

/// Samples of one block: one 64-byte line of `T`.
const fn block_len<T>() -> usize {
    64 / std::mem::size_of::<T>()
}

/// Per-step replacement of slot states at the first running sample of a
/// started track.
struct Inject {
    mask: [u8; 16],
    x: [[f64; LANES]; 16],
    v: [[f64; LANES]; 16],
    c: [[[f64; LANES]; 4]; 16],
}

impl Inject {
    /// Slot `l` takes the state `(x, v)` and the constants `c` before block
    /// step `p`.
    fn set(&mut self, p: usize, l: usize, x: f64, v: f64, c: &AbConst) {
        self.mask[p] |= 1 << l;
        self.x[p][l] = x;
        self.v[p][l] = v;
        self.c[p][0][l] = c.t;
        self.c[p][1][l] = c.alpha;
        self.c[p][2][l] = c.one_minus_alpha;
        self.c[p][3][l] = c.g2;
    }
}

/// Where one slot is.
#[derive(Clone, Copy)]
pub(super) struct Slot {
    /// First sample of the current block (64-byte aligned output).
    pub(super) pos: isize,
    /// Current track (index into the tracks), and the end of its region.
    pub(super) cur: usize,
    pub(super) region_end: usize,
    /// Whether the slot has a region.
    pub(super) busy: bool,
    /// Samples before `skip` are not stored (start-up outputs).
    pub(super) skip: isize,
    /// The current track is running in the slot (its final state is read
    /// from the block rows at its end).
    pub(super) running: bool,
    /// A started track begins running at sample `inj` (pending).
    pub(super) inj: isize,
    pub(super) inj_x: f64,
    pub(super) inj_v: f64,
    pub(super) inj_c: AbConst,
    /// End of the current track.
    pub(super) end: isize,
    /// Start-up outputs waiting in the slot's stage: bit `i` for sample
    /// `pos + i`.
    pub(super) stg: u64,
    /// A track started in the vector steps: its first sample (`vs0`) and,
    /// for a two-point start, its second (`vs1`), while pending
    /// (`isize::MAX`: none).
    pub(super) vs0: isize,
    pub(super) vs1: isize,
}

impl Slot {
    /// Whole blocks of `sbi` samples from `pos` in which the slot has only
    /// running samples to store (no start-up output, pending injection or
    /// vector start, or end of its track); 0 if the block at `pos` has any.
    #[inline(always)]
    pub(super) fn quiet_blocks(&self, sbi: isize) -> isize {
        let lim = (self.end - 1).min(self.inj).min(self.vs0).min(self.vs1);
        if self.pos >= self.skip && lim >= self.pos + sbi {
            (lim - self.pos) / sbi
        } else {
            0
        }
    }
}

/// Which fresh tracks start in the flat kernel's vector steps, and with
/// whose arithmetic (each the same bits as its scalar start-up).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum VecStart {
    /// As `filter::ab_start`: `Init::First` starts with the rate `+0.0`.
    Rows(Init),
    /// As `ragged::track_tv`: the state `H^+ z` summed from `-0.0`, so
    /// `Init::First` starts with the rate `-0.0 + 0 * z` (`-0.0` for a
    /// negative `z`).
    Tracks(Init),
}

impl VecStart {
    fn init(self) -> Init {
        match self {
            VecStart::Rows(i) | VecStart::Tracks(i) => i,
        }
    }
}

/// Per-step lane masks of the vector start-ups in a block: `s0[p]` the
/// lanes whose track starts at step `p`, `s1[p]` those at their second
/// sample (two-point start); `v0`: the velocity at the first sample
/// (`Init::First`: `v0 + signed * z`; two-point: NaN).
struct Starts {
    s0: [u8; 16],
    s1: [u8; 16],
    v0: __m512d,
    signed: Option<__m512d>,
}

/// Regions: runs of consecutive tracks of at least `target` samples (a
/// longer track is a region by itself), longest first. Tracks `j` with
/// `skip[j]` are in no region (the caller runs them).
pub(super) fn regions(off: &[usize], target: usize, skip: Option<&[bool]>) -> Vec<(usize, usize)> {
    let n = off.len() - 1;
    let skipped = |j: usize| skip.is_some_and(|s| s.get(j).copied().unwrap_or(false));
    let mut r = Vec::with_capacity(n / 8 + 1);
    let mut j0 = 0;
    while j0 < n {
        if skipped(j0) {
            j0 += 1;
            continue;
        }
        let mut j1 = j0 + 1;
        while j1 < n && !skipped(j1) && off[j1] - off[j0] < target {
            j1 += 1;
        }
        r.push((j0, j1));
        j0 = j1;
    }
    // Longest first (stable: ties keep memory order), so the slots finish
    // together.
    r.sort_by_key(|&(a, b)| std::cmp::Reverse(off[b] - off[a]));
    r
}

/// The per-track start-up: `start(j, state, z_j, x_j, v_j)` runs track
/// `j`'s samples until it is running (writing their outputs) and returns
/// how many it consumed; the track then runs from `state.x` if
/// `state.phase == 2`.
pub(crate) type Start<'s, T> =
    dyn FnMut(usize, &mut TrackState, &[T], &mut [T], &mut [T]) -> Result<usize> + 's;

/// What the flat kernels need to start a track in a slot (shared by
/// [`ab_flat`] and the generic kernel of `filter_flat_vec`).
pub(super) struct Starter<'a, 's, T> {
    pub(super) off: &'a [usize],
    pub(super) z: &'a [T],
    pub(super) konst: &'a dyn Fn(usize) -> AbConst,
    pub(super) shared: bool,
    /// `konst(0)`, the constants of every track if `shared`.
    pub(super) c0: AbConst,
    pub(super) vstart: Option<VecStart>,
    pub(super) start: &'a mut Start<'s, T>,
}

impl<T: IoFloat> Starter<'_, '_, T> {
    /// Start track `j` (at the start of its region or at a boundary) in
    /// slot `sl`, whose start-up stage is `gx`, `gv` (see `Slot::stg`):
    /// in the vector steps (`Slot::vs0`) where its start allows, otherwise
    /// with the scalar start-up, its outputs staged, and the state injected
    /// at its first running sample (`Slot::inj`).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub(super) fn track(
        &mut self,
        sl: &mut Slot,
        j: usize,
        states: &mut [TrackState],
        xs: &mut [T],
        vs: &mut [T],
        gx: &mut [T; STG],
        gv: &mut [T; STG],
    ) -> Result<()> {
        if self.vector_start(sl, j, states) {
            Ok(())
        } else {
            self.scalar_start(sl, j, states, xs, vs, gx, gv)
        }
    }

    /// Start track `j` in slot `sl`'s vector steps if its start allows
    /// (the usual case, inlined into the block bookkeeping).
    #[inline(always)]
    fn vector_start(&mut self, sl: &mut Slot, j: usize, states: &mut [TrackState]) -> bool {
        let (off, z) = (self.off, self.z);
        let (a, e) = (off[j], off[j + 1]);
        // The slot's next tracks' states: the states are touched once per
        // track, too sparsely for the hardware prefetcher.
        if let Some(ahead) = states.get(j + 4) {
            let p = ahead as *const TrackState;
            super::prefetch(p);
            super::prefetch(p.wrapping_byte_add(64));
        }
        // And the offsets two lines ahead: each slot reads its own run of
        // them, a line per eight tracks, which the hardware prefetcher
        // misses too (rows of 100 from memory: the bookkeeping's ticks
        // -14 %; docs/benchmarks.md, session 33).
        super::prefetch(off.as_ptr().wrapping_add(j + 16));
        let st = &mut states[j];
        // The usual start (a fresh track, its first one or two samples
        // valid) runs in the vector steps: the same values as the scalar
        // start-up (`VecStart`).
        // `ab_start` (`VecStart::Rows`) has its `+0.0` rate only on its fast
        // path (first two samples valid; otherwise its general start-up
        // gives `-0.0 + 0 z`), so rows need two valid samples for either
        // init; the track code (`Tracks`) starts `Init::First` alike
        // whatever follows.
        let two_valid = || e - a >= 2 && !z[a].to_f64().is_nan() && !z[a + 1].to_f64().is_nan();
        let in_vector = st.phase == 0.0
            && match self.vstart {
                Some(VecStart::Rows(_)) | Some(VecStart::Tracks(Init::TwoPoint)) => two_valid(),
                Some(VecStart::Tracks(Init::First)) => e > a && !z[a].to_f64().is_nan(),
                None => false,
            };
        if in_vector {
            st.phase = 2.0;
            st.since = 0.0;
            sl.cur = j;
            sl.end = e as isize;
            sl.skip = a as isize;
            sl.running = true;
            sl.inj = isize::MAX;
            sl.vs0 = a as isize;
            sl.vs1 = if self.vstart.map(VecStart::init) == Some(Init::TwoPoint) {
                a as isize + 1
            } else {
                isize::MAX
            };
            if !self.shared {
                // Its constants enter the slot at its first sample.
                sl.inj_c = (self.konst)(j);
            }
            return true;
        }
        false
    }

    /// Start track `j` in slot `sl` with the scalar start-up (see
    /// [`Self::track`]).
    #[allow(clippy::too_many_arguments)]
    #[inline(never)]
    fn scalar_start(
        &mut self,
        sl: &mut Slot,
        j: usize,
        states: &mut [TrackState],
        xs: &mut [T],
        vs: &mut [T],
        gx: &mut [T; STG],
        gv: &mut [T; STG],
    ) -> Result<()> {
        let (off, z) = (self.off, self.z);
        let (a, e) = (off[j], off[j + 1]);
        let st = &mut states[j];
        // The start-up writes its outputs into the slot's stage, from which
        // the blocks take them, so that the lines at the track boundaries are
        // stored whole (streamed): a store of part of a line waits for the
        // line from memory. A start-up longer than the stage (a track
        // beginning with many NaN) goes on in the outputs themselves.
        let start = &mut *self.start;
        let d = (a as isize - sl.pos) as usize;
        let n_run = if st.phase >= 2.0 {
            0
        } else if d < STG {
            let l1 = (e - a).min(STG - d);
            let (sx, sv) = (&mut gx[d..d + l1], &mut gv[d..d + l1]);
            let r1 = start(j, st, &z[a..a + l1], sx, sv)?.min(l1);
            if r1 > 0 {
                sl.stg |= ((1u64 << r1) - 1) << d;
            }
            if r1 == l1 && st.phase < 2.0 && a + l1 < e {
                let b = a + l1;
                r1 + start(j, st, &z[b..e], &mut xs[b..e], &mut vs[b..e])?
            } else {
                r1
            }
        } else {
            start(j, st, &z[a..e], &mut xs[a..e], &mut vs[a..e])?
        };
        let q = a + n_run.min(e - a);
        sl.cur = j;
        sl.end = e as isize;
        sl.skip = q as isize;
        if st.phase >= 2.0 && q < e {
            sl.running = true;
            sl.inj = q as isize;
            // Two separate loads: each is forwarded from the start-up's store
            // (one 16-byte load of both would wait until the stores, queued
            // behind the start-up's output stores, reach the cache).
            // SAFETY: reads of two f64 fields of a live state.
            unsafe {
                sl.inj_x = std::ptr::read_volatile(&st.x[0]);
                sl.inj_v = std::ptr::read_volatile(&st.x[1]);
            }
            sl.inj_c = if self.shared {
                self.c0
            } else {
                (self.konst)(j)
            };
        } else {
            sl.running = false;
            sl.inj = isize::MAX;
        }
        Ok(())
    }

    /// The bookkeeping of slot `l` (`s`) for its block of `sb` samples at
    /// `s.pos`, in which something happens: pending injections and vector
    /// start-up steps go to `ev`, the final states of tracks ending in it
    /// to `caps` (slot, block sample, track), the next tracks of the
    /// region start ([`Self::track`]). Returns the block's store mask (bit
    /// `p`: sample `pos + p` is stored; staged start-up outputs included)
    /// and whether the slot's region ends in it.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub(super) fn block(
        &mut self,
        s: &mut Slot,
        l: usize,
        sb: usize,
        ev: &mut impl BlockEvents,
        caps: &mut Vec<(usize, usize, usize)>,
        states: &mut [TrackState],
        xs: &mut [T],
        vs: &mut [T],
        gx: &mut [T; STG],
        gv: &mut [T; STG],
    ) -> Result<(u32, bool)> {
        let full = ((1u64 << sb) - 1) as u32;
        let pos = s.pos;
        let bend = pos + sb as isize;
        // Samples in [pos, skip) are not stored.
        let mut m = full;
        let clear = |m: &mut u32, from: isize, to: isize| {
            let (a, b) = (from.max(pos), to.min(bend));
            if a < b {
                let bits = ((1u64 << (b - a)) - 1) << (a - pos);
                *m &= !(bits as u32);
            }
        };
        clear(&mut m, pos, s.skip);
        let mut done = false;
        loop {
            // A pending start of running in this block.
            if s.inj < bend {
                ev.inject((s.inj - pos) as usize, l, s.inj_x, s.inj_v, &s.inj_c);
                s.inj = isize::MAX;
            }
            // Pending vector start-up steps in this block.
            if s.vs0 < bend {
                let p = (s.vs0 - pos) as usize;
                if !self.shared {
                    // The track's constants (and a state the start replaces)
                    // before its first step.
                    ev.inject(p, l, 0.0, 0.0, &s.inj_c);
                }
                ev.start(p, l, false);
                s.vs0 = isize::MAX;
            }
            if s.vs1 < bend {
                ev.start((s.vs1 - pos) as usize, l, true);
                s.vs1 = isize::MAX;
            }
            if s.end > bend {
                break;
            }
            // The current track ends in this block.
            if s.running {
                caps.push((l, (s.end - 1 - pos) as usize, s.cur));
            }
            let nxt = s.cur + 1;
            if nxt >= s.region_end {
                clear(&mut m, s.end, bend);
                done = true;
                break;
            }
            self.track(s, nxt, states, xs, vs, gx, gv)?;
            clear(&mut m, self.off[nxt] as isize, s.skip);
        }
        // Staged start-up outputs are stored with the block.
        Ok((m | (s.stg as u32 & full), done))
    }
}

/// Where the per-slot bookkeeping of a block with events
/// ([`Starter::block`]) puts the slots' replacements and vector start-ups:
/// each kernel's own tables.
pub(super) trait BlockEvents {
    /// Slot `l` takes the state `(x, v)` and the constants `c` before block
    /// step `p`.
    fn inject(&mut self, p: usize, l: usize, x: f64, v: f64, c: &AbConst);
    /// Slot `l`'s track is at its first (`second`: its second) sample in
    /// block step `p`, started in the vector steps.
    fn start(&mut self, p: usize, l: usize, second: bool);
}

/// [`ab_flat`]'s tables of one block with events, and whether anything
/// went into them.
struct Events<'a> {
    inject: &'a mut Inject,
    starts: &'a mut Starts,
    any_inj: bool,
    any_vs: bool,
}

impl BlockEvents for Events<'_> {
    fn inject(&mut self, p: usize, l: usize, x: f64, v: f64, c: &AbConst) {
        self.inject.set(p, l, x, v, c);
        self.any_inj = true;
    }
    fn start(&mut self, p: usize, l: usize, second: bool) {
        let m = if second {
            &mut self.starts.s1
        } else {
            &mut self.starts.s0
        };
        m[p] |= 1 << l;
        self.any_vs = true;
    }
}

/// Alpha-beta over the tracks `off[j]..off[j+1]` of the flat `z`, `xs`,
/// `vs` (see the module docs). `konst(j)` gives track `j`'s constants
/// (`shared`: the same for all); `nt`: non-temporal stores of whole lines.
///
/// # Safety
/// The CPU supports AVX-512F and FMA (`simd::available()`); `T` is `f32`
/// or `f64`.
#[allow(clippy::too_many_arguments)]
#[target_feature(enable = "avx512f,fma")]
pub(super) unsafe fn ab_flat<T: IoFloat>(
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
    let n_tracks = states.len();
    let total = off.last().copied().unwrap_or(0);
    if off.len() != n_tracks + 1 || z.len() < total || xs.len() < total || vs.len() < total {
        return Err(crate::Error::Shape(
            "flat alpha-beta: buffers do not match the offsets".into(),
        ));
    }
    let len = total as isize;
    let sb = block_len::<T>();
    let sbi = sb as isize;
    let halves = sb / W;
    let es = std::mem::size_of::<T>();
    // Blocks are aligned to the x output's lines.
    let mis = ((xs.as_ptr() as usize) % 64 / es) as isize;
    let align_down = |p: isize| p - (p + mis).rem_euclid(sbi);
    let v_aligned = (vs.as_ptr() as usize) % 64 == (xs.as_ptr() as usize) % 64;
    let vmis = ((vs.as_ptr() as usize) % 64 / es) as isize;
    let mut vsh = VShift::new(vs, nt, mis, vmis);
    let regs = regions(off, (total / 64).clamp(512, 8192), skip);
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
    }; LANES];
    let mut inject = Inject {
        mask: [0; 16],
        x: [[0.0; LANES]; 16],
        v: [[0.0; LANES]; 16],
        c: [[[0.0; LANES]; 4]; 16],
    };
    let zero = _mm512_setzero_pd();
    let one = _mm512_set1_pd(1.0);
    // Per-slot constants (replaced when a track starts running in a slot).
    let ct = _mm512_set1_pd(c0.t);
    let calpha = _mm512_set1_pd(c0.alpha);
    let coma = _mm512_set1_pd(c0.one_minus_alpha);
    let cg2 = _mm512_set1_pd(c0.g2);

    // Start-up stages, one per slot: sample `pos + i` of the slot at index
    // `i` (bit `i` of `Slot::stg` set when it holds a start-up output).
    let mut stg_x = [[T::from_f64(0.0); STG]; LANES];
    let mut stg_v = [[T::from_f64(0.0); STG]; LANES];
    let mut cx = Starter {
        off,
        z,
        konst,
        shared,
        c0,
        vstart,
        start,
    };
    // Blocks run so far (every busy slot moves on by one block per block).
    let mut step: isize = 0;
    // Where slot `l` starts a region when outputs are streamed: at the
    // region's first line, or a line before it (a block in which the slot
    // stores nothing), so that at every block the slots' lines alternate in
    // parity, slot `l`'s line being `step + l` modulo 2 (module docs,
    // "Slot phases").
    let phased = |p: isize, l: usize, step: isize| {
        if nt && ((p + mis).div_euclid(sbi) - step - l as isize) & 1 != 0 {
            p - sbi
        } else {
            p
        }
    };
    // Give slot `l` its next region (or mark it idle).
    macro_rules! refill {
        ($l:expr) => {{
            let l: usize = $l;
            if next_region < regs.len() {
                let (j0, j1) = regs[next_region];
                next_region += 1;
                slots[l].busy = true;
                slots[l].region_end = j1;
                slots[l].pos = phased(align_down(off[j0] as isize), l, step);
                let (sl, gx, gv) = (&mut slots[l], &mut stg_x[l], &mut stg_v[l]);
                cx.track(sl, j0, states, xs, vs, gx, gv)?;
            } else {
                slots[l].busy = false;
            }
        }};
    }
    for l in 0..LANES {
        refill!(l);
    }
    let full: u32 = if sb == 16 { 0xffff } else { 0xff };
    let mut k = Kern {
        xv: zero,
        vv: zero,
        ct,
        calpha,
        coma,
        cg2,
        one,
    };
    let mut starts = Starts {
        s0: [0; 16],
        s1: [0; 16],
        v0: _mm512_set1_pd(match vstart {
            Some(VecStart::Rows(Init::First)) => 0.0,
            Some(VecStart::Tracks(Init::First)) => -0.0,
            _ => f64::NAN,
        }),
        signed: match vstart {
            Some(VecStart::Tracks(Init::First)) => Some(_mm512_setzero_pd()),
            _ => None,
        },
    };
    let mut xbuf = [[zero; W]; 2];
    let mut vbuf = [[zero; W]; 2];
    let mut caps: Vec<(usize, usize, usize)> = Vec::with_capacity(4 * LANES);
    let mut tmp = [[T::from_f64(0.0); 16]; LANES];
    let zline = [T::from_f64(0.0); 16];
    loop {
        if slots.iter().all(|s| !s.busy) {
            break;
        }
        // Blocks in which no slot has anything but running samples, run
        // without bookkeeping.
        // Idle slots (no region left for them) do not hold the others back:
        // they compute on a line of zeros and store nothing.
        let mut n_fast = isize::MAX;
        for s in slots.iter().filter(|s| s.busy) {
            n_fast = n_fast.min(s.quiet_blocks(sbi));
            if n_fast == 0 {
                break;
            }
        }
        if n_fast > 0 && slots.iter().all(|s| s.busy) {
            // Every slot busy (all but the last blocks): the same blocks
            // with the slots' pointers hoisted.
            let zb: [*const T; LANES] =
                std::array::from_fn(|l| z.as_ptr().wrapping_offset(slots[l].pos));
            let xb: [*mut T; LANES] =
                std::array::from_fn(|l| xs.as_mut_ptr().wrapping_offset(slots[l].pos));
            let vb: [*mut T; LANES] =
                std::array::from_fn(|l| vs.as_mut_ptr().wrapping_offset(slots[l].pos));
            for b in 0..n_fast {
                let o = b * sbi;
                let src: [*const T; LANES] = std::array::from_fn(|l| {
                    let p = zb[l].wrapping_offset(o);
                    super::prefetch(p.wrapping_offset(PREFETCH_BLOCKS * sbi));
                    p
                });
                if !is_f64::<T>() {
                    // f32: the eight lines transposed as f32 (half the
                    // shuffles of widened f64 transposes), as in the row
                    // lanes (`simd::ab_lanes8`).
                    // SAFETY: T is f32; every src[l] has 16 readable samples;
                    // the stores as in the blocks below.
                    unsafe {
                        let mut rows: [__m512; W] =
                            std::array::from_fn(|l| _mm512_loadu_ps(src[l] as *const f32));
                        let clean = no_nan16(&rows);
                        transpose8x16(&mut rows);
                        let c = [k.ct, k.calpha, k.coma, k.cg2];
                        for h in 0..2 {
                            let zt: [__m512d; W] =
                                std::array::from_fn(|j| widen_step(&rows, h * W + j));
                            let (xo, vo) = (&mut xbuf[h], &mut vbuf[h]);
                            if clean {
                                clean_steps8(&zt, c, &mut k.xv, &mut k.vv, xo, vo);
                            } else {
                                masked_steps8(&zt, c, &mut k.xv, &mut k.vv, xo, vo);
                            }
                        }
                        let mut xl = narrow_steps(&xbuf);
                        let mut vl = narrow_steps(&vbuf);
                        untranspose8x16(&mut xl);
                        untranspose8x16(&mut vl);
                        for l in 0..LANES {
                            store_ps(xb[l].wrapping_offset(o) as *mut f32, xl[l], nt);
                            let vn = nt && v_aligned;
                            store_ps(vb[l].wrapping_offset(o) as *mut f32, vl[l], vn);
                        }
                    }
                    continue;
                }
                // SAFETY: every src[l] has sb readable samples (fast blocks
                // end before each slot's track's last sample).
                unsafe { compute(&src, halves, &mut k, None, None, &mut xbuf, &mut vbuf) };
                for l in 0..LANES {
                    // SAFETY: as in the blocks below.
                    unsafe {
                        store_line(xb[l].wrapping_offset(o), xbuf[0][l], xbuf[1][l], nt);
                        if let Some(sh) = vsh.as_mut() {
                            sh.put(
                                vs.as_mut_ptr() as *mut f64,
                                l,
                                slots[l].pos + o,
                                vbuf[0][l],
                                full,
                            );
                        } else {
                            let vn = nt && v_aligned;
                            store_line(vb[l].wrapping_offset(o), vbuf[0][l], vbuf[1][l], vn);
                        }
                    }
                }
            }
            for s in slots.iter_mut() {
                s.pos += n_fast * sbi;
            }
            step += n_fast;
            continue;
        }
        for _ in 0..n_fast {
            let mut src = [std::ptr::null::<T>(); LANES];
            for (l, s) in slots.iter().enumerate() {
                src[l] = if s.busy {
                    // SAFETY (pointer): pos..pos+sb is inside the current
                    // track (fast blocks end before the track's last sample).
                    let p = unsafe { z.as_ptr().offset(s.pos) };
                    super::prefetch(p.wrapping_offset(PREFETCH_BLOCKS * sbi));
                    p
                } else {
                    zline.as_ptr()
                };
            }
            // SAFETY: every src[l] has sb readable samples.
            unsafe { compute(&src, halves, &mut k, None, None, &mut xbuf, &mut vbuf) };
            for (l, s) in slots.iter_mut().enumerate() {
                if !s.busy {
                    continue;
                }
                // SAFETY: pos..pos+sb is inside xs and vs; x stores are
                // line-aligned (blocks follow x's lines), v streamed only if
                // aligned too.
                unsafe {
                    store_line(xs.as_mut_ptr().offset(s.pos), xbuf[0][l], xbuf[1][l], nt);
                    if let Some(sh) = vsh.as_mut() {
                        sh.put(vs.as_mut_ptr() as *mut f64, l, s.pos, vbuf[0][l], full);
                    } else {
                        store_line(
                            vs.as_mut_ptr().offset(s.pos),
                            vbuf[0][l],
                            vbuf[1][l],
                            nt && v_aligned,
                        );
                    }
                }
                s.pos += sbi;
            }
        }
        if n_fast > 0 {
            step += n_fast;
            continue;
        }
        // One block with events: masks (bit p: sample pos + p is stored),
        // start-ups, starts of running, end-of-track captures.
        let mut masks = [0u32; LANES];
        starts.s0 = [0; 16];
        starts.s1 = [0; 16];
        let mut done = [false; LANES];
        caps.clear();
        let mut ev = Events {
            inject: &mut inject,
            starts: &mut starts,
            any_inj: false,
            any_vs: false,
        };
        for l in 0..LANES {
            let s = &mut slots[l];
            if s.busy {
                (masks[l], done[l]) = cx.block(
                    s,
                    l,
                    sb,
                    &mut ev,
                    &mut caps,
                    states,
                    xs,
                    vs,
                    &mut stg_x[l],
                    &mut stg_v[l],
                )?;
            }
        }
        let (any_inj, any_vs) = (ev.any_inj, ev.any_vs);
        let mut src = [std::ptr::null::<T>(); LANES];
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
        let inj = if any_inj { Some(&mut inject) } else { None };
        let vst = if any_vs { Some(&mut starts) } else { None };
        // SAFETY: every src[l] has sb readable samples.
        unsafe {
            compute(
                &src,
                halves,
                &mut k,
                inj.map(|i| (i, shared)),
                vst,
                &mut xbuf,
                &mut vbuf,
            )
        };
        for l in 0..LANES {
            let s = &slots[l];
            let m = masks[l];
            if !s.busy || (m == 0 && vsh.is_none()) {
                continue;
            }
            let sbits = s.stg as u32 & full;
            if sbits != 0 {
                // SAFETY: the stage holds STG >= 16 samples.
                unsafe { merge_stage(&mut xbuf, &mut vbuf, l, sbits, &stg_x[l], &stg_v[l]) };
            }
            let pos = s.pos;
            let inside = pos >= 0 && pos + sbi <= len;
            // `v` whole lines across blocks (the samples kept back from the
            // slot's previous block, also when this block stores nothing).
            let vsep = if let Some(sh) = vsh.as_mut() {
                // SAFETY: `v` has `len` samples; AVX-512F.
                unsafe { sh.put(vs.as_mut_ptr() as *mut f64, l, pos, vbuf[0][l], m) };
                true
            } else {
                false
            };
            if m == 0 {
                continue;
            }
            if m == full && inside {
                // SAFETY: as in the fast blocks.
                unsafe {
                    store_line(xs.as_mut_ptr().offset(pos), xbuf[0][l], xbuf[1][l], nt);
                    if !vsep {
                        let vn = nt && v_aligned;
                        store_line(vs.as_mut_ptr().offset(pos), vbuf[0][l], vbuf[1][l], vn);
                    }
                }
            } else if inside {
                // SAFETY: the line is inside the outputs; masked-off samples
                // are not written.
                unsafe {
                    store_masked(xs.as_mut_ptr().offset(pos), xbuf[0][l], xbuf[1][l], m);
                    if !vsep {
                        store_masked(vs.as_mut_ptr().offset(pos), vbuf[0][l], vbuf[1][l], m);
                    }
                }
            } else {
                let xr = rows_of(&xbuf, l);
                let vr = rows_of(&vbuf, l);
                for p in 0..sb {
                    if m & (1 << p) != 0 {
                        let g = (pos + p as isize) as usize;
                        xs[g] = T::from_f64(xr[p]);
                        if !vsep {
                            vs[g] = T::from_f64(vr[p]);
                        }
                    }
                }
            }
        }
        // Final states of the tracks that ended in this block.
        for &(l, p, j) in caps.iter() {
            states[j].x[0] = at(&xbuf, l, p);
            states[j].x[1] = at(&vbuf, l, p);
        }
        step += 1;
        for l in 0..LANES {
            let s = &mut slots[l];
            if s.stg != 0 {
                s.stg >>= sb;
                if s.stg != 0 {
                    stg_x[l].copy_within(sb.., 0);
                    stg_v[l].copy_within(sb.., 0);
                }
            }
            if done[l] {
                if let Some(sh) = vsh.as_mut() {
                    // SAFETY: `v` has `len` samples.
                    unsafe { sh.flush(vs.as_mut_ptr() as *mut f64, l, slots[l].pos) };
                }
                refill!(l);
            } else if slots[l].busy {
                slots[l].pos += sbi;
            }
        }
    }
    if nt {
        _mm_sfence();
    }
    Ok(())
}

/// `v` stored in whole streamed lines when its lines do not lie at `x`'s
/// line offsets (`f64`; the blocks follow `x`'s lines): `v`'s lines begin
/// at block sample `e`, so each slot's `v` line is the last `8 - e`
/// samples of its previous block and the first `e` of the current one
/// (one permute). Before, such `v` rows were stored with ordinary stores,
/// each line read from memory first (docs/benchmarks.md, session 26).
struct VShift {
    /// `vs`'s length (`vs` itself is passed to each call).
    len: isize,
    e: isize,
    /// `permutex2var` indices: `prev[e..8]` then `cur[0..e]`.
    idx: __m512i,
    /// Each slot's previous block of `v` and its store mask.
    prev: [__m512d; LANES],
    pm: [u32; LANES],
}

impl VShift {
    /// For `f64` outputs streamed with `v`'s lines off `x`'s (`mis`, `vmis`:
    /// their first samples' offsets in their lines).
    #[target_feature(enable = "avx512f")]
    fn new<T: 'static>(vs: &mut [T], nt: bool, mis: isize, vmis: isize) -> Option<VShift> {
        let e = (mis - vmis).rem_euclid(8);
        if !(nt && is_f64::<T>() && e != 0 && (vs.as_ptr() as usize).is_multiple_of(8)) {
            return None;
        }
        Some(VShift {
            len: vs.len() as isize,
            e,
            idx: VLines::idx(e as usize),
            prev: [_mm512_setzero_pd(); LANES],
            pm: [0; LANES],
        })
    }

    /// Samples `at..at + 8` of `v` of which those of mask `m` are stored:
    /// masked, element by element where they reach past an end of `v`.
    ///
    /// # Safety
    /// `v` points to `self.len` writable `f64`; AVX-512F.
    #[inline(always)]
    unsafe fn masked(&self, v: *mut f64, at: isize, a: __m512d, m: u32) {
        // SAFETY: inside `v` (checked), masked-off elements untouched.
        unsafe {
            if at >= 0 && at + 8 <= self.len {
                _mm512_mask_storeu_pd(v.offset(at), m as u8, a);
            } else {
                let mut r = [0.0; 8];
                _mm512_storeu_pd(r.as_mut_ptr(), a);
                for (i, &x) in r.iter().enumerate() {
                    let g = at + i as isize;
                    if m & (1 << i) != 0 && g >= 0 && g < self.len {
                        *v.offset(g) = x;
                    }
                }
            }
        }
    }

    /// The `v` line at `at` (a line start) of which the samples of mask `m`
    /// are stored: streamed if all and inside `v`, else [`Self::masked`].
    ///
    /// # Safety
    /// As [`Self::masked`].
    #[inline(always)]
    unsafe fn line(&self, v: *mut f64, at: isize, a: __m512d, m: u32) {
        // SAFETY: inside `v` (checked); `at` is 64-byte aligned.
        unsafe {
            if m == 0xff && at >= 0 && at + 8 <= self.len {
                _mm512_stream_pd(v.offset(at), a);
            } else {
                self.masked(v, at, a, m);
            }
        }
    }

    /// Slot `l`'s block at `pos` has the `v` estimates `cur`, those of mask
    /// `m` to be stored: store the `v` line that ends at `pos + e` and keep
    /// the rest for the slot's next block.
    ///
    /// # Safety
    /// As [`Self::line`]; AVX-512F.
    #[inline(always)]
    unsafe fn put(&mut self, v: *mut f64, l: usize, pos: isize, cur: __m512d, m: u32) {
        let e = self.e;
        let lm = ((self.pm[l] >> e) | ((m & ((1 << e) - 1)) << (8 - e))) & 0xff;
        if lm != 0 {
            // SAFETY: forwarded.
            unsafe {
                let a = _mm512_permutex2var_pd(self.prev[l], self.idx, cur);
                self.line(v, pos - 8 + e, a, lm);
            }
        }
        self.prev[l] = cur;
        self.pm[l] = m;
    }

    /// Slot `l`'s region ended in its block at `pos`: store the samples
    /// kept back.
    ///
    /// # Safety
    /// As [`Self::line`].
    #[inline(always)]
    unsafe fn flush(&mut self, v: *mut f64, l: usize, pos: isize) {
        let rest = self.pm[l] & !((1u32 << self.e) - 1) & 0xff;
        if rest != 0 {
            // SAFETY: forwarded (the block's samples start at `pos`, not a
            // line start).
            unsafe { self.masked(v, pos, self.prev[l], rest) };
        }
        self.pm[l] = 0;
    }
}

/// The running state and constants of the eight slots.
struct Kern {
    xv: __m512d,
    vv: __m512d,
    ct: __m512d,
    calpha: __m512d,
    coma: __m512d,
    cg2: __m512d,
    one: __m512d,
}

/// One block: `sb = 8 * halves` samples of every slot from `src[l]`,
/// transposed, run (with the slot replacements of `inj`, whose masks are
/// cleared), and transposed back into `xbuf`, `vbuf` (row `l`: slot `l`'s
/// estimates, `f64`).
///
/// # Safety
/// AVX-512F and FMA are available; `T` is `f32` or `f64`; each `src[l]`
/// points to `8 * halves` readable samples.
#[inline(always)]
unsafe fn compute<T: IoFloat>(
    src: &[*const T; LANES],
    halves: usize,
    k: &mut Kern,
    inj: Option<(&mut Inject, bool)>,
    starts: Option<&mut Starts>,
    xbuf: &mut [[__m512d; W]; 2],
    vbuf: &mut [[__m512d; W]; 2],
) {
    // SAFETY: forwarded from the caller.
    unsafe {
        let mut inj = inj;
        let mut starts = starts;
        for h in 0..halves {
            let mut rows: [__m512d; W] = std::array::from_fn(|l| load8(src[l].add(h * W)));
            // Without NaN the steps need no missed-detection masks (the same
            // bits): the whole half-block at once if nothing else happens in
            // it, else step by step between the start-ups and injections.
            let nan_free = no_nan8(&rows);
            let clean = inj.is_none() && starts.is_none() && nan_free;
            transpose8(&mut rows);
            let (xo, vo) = (&mut xbuf[h], &mut vbuf[h]);
            if clean {
                let c = [k.ct, k.calpha, k.coma, k.cg2];
                clean_steps8(&rows, c, &mut k.xv, &mut k.vv, xo, vo);
                transpose8(xo);
                transpose8(vo);
                continue;
            }
            for j in 0..W {
                if let Some((inject, shared)) = inj.as_mut() {
                    let p = h * W + j;
                    let m = inject.mask[p];
                    if m != 0 {
                        k.xv = _mm512_mask_loadu_pd(k.xv, m, inject.x[p].as_ptr());
                        k.vv = _mm512_mask_loadu_pd(k.vv, m, inject.v[p].as_ptr());
                        if !*shared {
                            k.ct = _mm512_mask_loadu_pd(k.ct, m, inject.c[p][0].as_ptr());
                            k.calpha = _mm512_mask_loadu_pd(k.calpha, m, inject.c[p][1].as_ptr());
                            k.coma = _mm512_mask_loadu_pd(k.coma, m, inject.c[p][2].as_ptr());
                            k.cg2 = _mm512_mask_loadu_pd(k.cg2, m, inject.c[p][3].as_ptr());
                        }
                        inject.mask[p] = 0;
                    }
                }
                let c = [k.ct, k.calpha, k.coma, k.cg2];
                let (m0, m1) = match starts.as_deref_mut() {
                    Some(st) => {
                        let p = h * W + j;
                        (std::mem::take(&mut st.s0[p]), std::mem::take(&mut st.s1[p]))
                    }
                    None => (0, 0),
                };
                if m0 | m1 == 0 {
                    if nan_free {
                        clean_step8(c, &mut k.xv, &mut k.vv, rows[j]);
                    } else {
                        masked_step8(c, k.one, &mut k.xv, &mut k.vv, rows[j]);
                    }
                } else {
                    // Start-ups: at the first sample x = z (velocity `v0`),
                    // at the second (two-point) x = z, v = (z - z0) / T,
                    // as `ab_start`.
                    let (zj, x0) = (rows[j], k.xv);
                    if nan_free {
                        clean_step8(c, &mut k.xv, &mut k.vv, zj);
                    } else {
                        masked_step8(c, k.one, &mut k.xv, &mut k.vv, zj);
                    }
                    let vel = _mm512_div_pd(_mm512_sub_pd(zj, x0), k.ct);
                    k.xv = _mm512_mask_blend_pd(m0 | m1, k.xv, zj);
                    k.vv = _mm512_mask_blend_pd(m1, k.vv, vel);
                    if let Some(st) = starts.as_deref() {
                        let v0 = match st.signed {
                            Some(zero) => _mm512_add_pd(st.v0, _mm512_mul_pd(zero, zj)),
                            None => st.v0,
                        };
                        k.vv = _mm512_mask_blend_pd(m0, k.vv, v0);
                    }
                }
                xo[j] = k.xv;
                vo[j] = k.vv;
            }
            transpose8(xo);
            transpose8(vo);
        }
    }
}

/// Replace slot `l`'s samples `p` with bit `p` of `bits` set in a transposed
/// block by the staged start-up outputs `gx[p]`, `gv[p]` (exact: an `f32`
/// output is narrowed from its `f64` again on store).
///
/// # Safety
/// AVX-512F is available; `T` is `f32` or `f64`.
#[inline]
#[target_feature(enable = "avx512f")]
unsafe fn merge_stage<T: 'static>(
    xbuf: &mut [[__m512d; W]; 2],
    vbuf: &mut [[__m512d; W]; 2],
    l: usize,
    bits: u32,
    gx: &[T; STG],
    gv: &[T; STG],
) {
    for h in 0..2 {
        let hb = (bits >> (h * W)) as u8;
        if hb != 0 {
            // SAFETY: h * W + 8 <= 16 <= STG elements.
            unsafe {
                let (x, v) = (load8(gx.as_ptr().add(h * W)), load8(gv.as_ptr().add(h * W)));
                xbuf[h][l] = _mm512_mask_blend_pd(hb, xbuf[h][l], x);
                vbuf[h][l] = _mm512_mask_blend_pd(hb, vbuf[h][l], v);
            }
        }
    }
}

/// The `f64` values of slot `l` in a transposed block (8 or 16 samples).
#[inline]
#[target_feature(enable = "avx512f")]
fn rows_of(buf: &[[__m512d; W]; 2], l: usize) -> [f64; 16] {
    let mut r = [0.0; 16];
    // SAFETY: a plain array of 16 f64.
    unsafe {
        _mm512_storeu_pd(r.as_mut_ptr(), buf[0][l]);
        _mm512_storeu_pd(r.as_mut_ptr().add(8), buf[1][l]);
    }
    r
}

/// Sample `p` of slot `l` in a transposed block (one permute, no round
/// trip through memory).
#[inline]
#[target_feature(enable = "avx512f")]
fn at(buf: &[[__m512d; W]; 2], l: usize, p: usize) -> f64 {
    let v = buf[p / W][l];
    _mm512_cvtsd_f64(_mm512_permutexvar_pd(_mm512_set1_epi64((p % W) as i64), v))
}

/// Store the samples of a line whose bit is set in `m` (`f64`: the 8 of
/// `a`; `f32`: the 16 of `a` then `b`, narrowed).
///
/// # Safety
/// `T` is `f64` or `f32`; the line at `p` is inside the output.
#[inline]
#[target_feature(enable = "avx512f")]
unsafe fn store_masked<T: 'static>(p: *mut T, a: __m512d, b: __m512d, m: u32) {
    // SAFETY: forwarded from the caller; masked-off elements are not
    // accessed.
    unsafe {
        if is_f64::<T>() {
            _mm512_mask_storeu_pd(p as *mut f64, m as u8, a)
        } else {
            let lo = _mm256_castps_pd(_mm512_cvtpd_ps(a));
            let hi = _mm256_castps_pd(_mm512_cvtpd_ps(b));
            let line = _mm512_castpd_ps(_mm512_insertf64x4::<1>(_mm512_castpd256_pd512(lo), hi));
            _mm512_mask_storeu_ps(p as *mut f32, m as u16, line)
        }
    }
}
