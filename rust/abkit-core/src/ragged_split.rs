//! A long alpha-beta track with timestamps, split into segments: the
//! timestamped counterpart of the single-track split of [`crate::filter`]
//! (`ab_split`, docs/filtering.md, "Single long tracks").
//!
//! A track's recursion is sequential; the track kernel's vector lanes run
//! several tracks side by side, so one long track (or a few, most of the
//! samples) leaves them idle: about 8 ns per sample against about 1 for a
//! batch (Intel Xeon, session 14). The filter is linear in its state for a
//! given sequence of steps: with timestamps the gains depend on the step
//! `dt` only (fixed gains `(alpha, beta / dt)` or the design law's), never
//! on the state, and which samples are dropped (not after the last kept
//! timestamp) or restart the track (a step longer than `max_gap`) depends
//! on the timestamps only. So:
//!
//! - pass 1 runs the track's [`SPLIT_SEGMENTS`] segments as separate
//!   tracks of one call of the track kernel (the lanes fill): segment 0
//!   from the track's true state, segment `j` from a guess (running,
//!   position the last valid sample before it, velocity 0, `t_last` the
//!   timestamp before it, what the sequential run keeps unless that sample
//!   was dropped);
//! - pass 2, in order, takes segment `j - 1`'s true end state, and
//!   propagates the difference `delta` from the guess through segment `j`:
//!   `Phi(dt) = [[1, dt], [0, 1]]` for a missed sample, then `(I - K H)`
//!   with that step's gains for an updated one; a dropped sample leaves it,
//!   a restart ends it. Each estimate gets its `delta` added until `delta`
//!   is below 2^-60 of the estimate; what is left at the end corrects the
//!   segment's end state. Where the true state entering a segment is not
//!   running (or its `t_last` differs from the guess), that segment is run
//!   again, sequentially, from the true state.
//!
//! The result is the sequential recursion up to rounding (tested within
//! 1e-12 of each state's scale, tests/test_filters_split.py). Only without
//! residuals and post-processing (smoothing), and only where the vector
//! lanes run.

use crate::filter::{split_seg_len, IoFloat, TrackState, SPLIT_SEGMENTS};
use crate::irregular::GainLaw;
use crate::ragged::{run_tracks, Counts, NoPost, Options, PostTrack, Samples, TrackFilter};
use crate::{Error, Result};

/// Filter the tracks of `off` (validated) with the long ones split, or
/// `None` when no track is split (the caller runs them as usual). A track
/// is split when it holds at least `1 / (4 width)` of all samples (the
/// lanes would idle on it at the end of a block) and [`split_seg_len`]
/// accepts its gains at the nominal step. (Splitting every track of at
/// least 65,536 samples measured faster for 10 x 10^6 samples, 2.6 -> 2.2
/// ns per sample, but slower for 50 x 200,000, 2.2 -> 2.5, and 100 x
/// 100,000, 2.4 -> 3.2: the lanes are full there anyway and the guesses
/// and corrections cost.)
#[allow(clippy::too_many_arguments)]
pub(crate) fn split_timed<
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
    t: &Samples<'_, f64>,
    states: &mut [TrackState],
    out: &mut [T],
    counts: &mut [Counts],
    parallel: bool,
    post: &P,
) -> Option<Result<()>> {
    let w = crate::ragged_simd::width();
    if N != 2 || M != 1 || !post.is_none() || w == 0 || filt.laws.is_empty() {
        return None;
    }
    let n_tracks = off.len().checked_sub(1)?;
    let n_total = *off.last()?;
    let law = |i: usize| &filt.laws[if filt.laws.len() == 1 { 0 } else { i }];
    let seg_len: Vec<Option<usize>> = (0..n_tracks)
        .map(|i| {
            let len = off[i + 1] - off[i];
            if len.saturating_mul(4 * w) < n_total {
                return None;
            }
            let l = law(i);
            l.ab_law()?;
            let (a, g) = l.clone().ab_gains(opts.t_nominal)?;
            split_seg_len(a, g * opts.t_nominal, len)
        })
        .collect();
    if seg_len.iter().all(Option::is_none) {
        return None;
    }
    Some(run_split(
        filt, opts, off, z, t, states, out, counts, parallel, &seg_len,
    ))
}

/// Where an original track's segments are in the split layout.
struct Split {
    /// Original track.
    track: usize,
    /// Index of its first segment among the split layout's tracks.
    first: usize,
    /// Guessed start states of segments 1.. (index 0 unused).
    guess: Vec<TrackState>,
}

#[allow(clippy::too_many_arguments)]
fn run_split<T: IoFloat, L: GainLaw<N, M>, const N: usize, const M: usize>(
    filt: &TrackFilter<'_, L, N, M>,
    opts: &Options,
    off: &[usize],
    z: &Samples<'_, T>,
    t: &Samples<'_, f64>,
    states: &mut [TrackState],
    out: &mut [T],
    counts: &mut [Counts],
    parallel: bool,
    seg_len: &[Option<usize>],
) -> Result<()> {
    let n_tracks = off.len() - 1;
    let n_total = off[n_tracks];
    // The plane stride of `out` (crate::planes).
    let Some(ps) = crate::planes::stride::<T>(out.len(), N, n_total, 0) else {
        return Err(Error::Shape("output buffer has the wrong size".into()));
    };
    let zat = |k: usize| z.data[z.addr(k) as usize].to_f64();
    let tat = |k: usize| t.data[t.addr(k) as usize];
    // The split layout: every track, the long ones as segments.
    let mut new_off = vec![0usize];
    let mut owner = Vec::new(); // original track of each new track
    let mut new_states = Vec::new();
    let mut splits = Vec::new();
    for i in 0..n_tracks {
        let (a, e) = (off[i], off[i + 1]);
        match seg_len[i] {
            None => {
                new_off.push(e);
                owner.push(i);
                new_states.push(states[i]);
            }
            Some(ls) => {
                let first = owner.len();
                let mut guess = vec![states[i]; SPLIT_SEGMENTS];
                for (j, g) in guess.iter_mut().enumerate() {
                    let s0 = a + j * ls;
                    if j > 0 {
                        // The timestamp before the segment (the sequential
                        // run's t_last unless that sample was dropped: then
                        // pass 2 finds the difference and runs the segment
                        // again) and the last valid sample.
                        let zl = (a..s0).rev().map(zat).find(|v| !v.is_nan());
                        *g = TrackState {
                            x: [0.0; crate::filter::MAX_STATES],
                            phase: 2.0,
                            since: 0.0,
                            t_last: tat(s0 - 1),
                            t_held: f64::NAN,
                        };
                        g.x[0] = zl.unwrap_or(0.0);
                    }
                    new_off.push(if j + 1 == SPLIT_SEGMENTS { e } else { s0 + ls });
                    owner.push(i);
                    new_states.push(*g);
                }
                splits.push(Split {
                    track: i,
                    first,
                    guess,
                });
            }
        }
    }
    let laws: Vec<L>;
    let filt2 = if filt.laws.len() == 1 {
        filt.clone()
    } else {
        laws = owner.iter().map(|&i| filt.laws[i].clone()).collect();
        TrackFilter {
            laws: &laws,
            h: filt.h,
            h_pinv: filt.h_pinv,
        }
    };
    let mut new_counts: Vec<Counts> = vec![[0, 0]; owner.len()];
    // Pass 1: every segment at once.
    let r = run_tracks(
        &filt2,
        opts,
        &new_off,
        z,
        Some(t),
        &mut new_states,
        out,
        None,
        &mut new_counts,
        parallel,
        &NoPost,
    );
    if let Err(e) = r {
        // Name the original track and its sample.
        return Err(match e {
            Error::Data { track, sample, msg } => {
                let i = owner.get(track).copied().unwrap_or(track);
                let at = new_off.get(track).copied().unwrap_or(0);
                Error::Data {
                    track: i,
                    sample: sample + at - off[i],
                    msg,
                }
            }
            other => other,
        });
    }
    // Pass 2: corrections, track by track, segment by segment.
    let tiny = 2f64.powi(-60);
    let max_gap = opts.max_gap.unwrap_or(f64::INFINITY);
    for sp in &splits {
        let mut l = law_of(filt, sp.track).clone();
        for j in 1..SPLIT_SEGMENTS {
            let q = sp.first + j;
            let (g0, g1) = (new_off[q], new_off[q + 1]);
            let prev = new_states[q - 1];
            let guess = &sp.guess[j];
            if !(prev.phase == 2.0 && prev.t_last.to_bits() == guess.t_last.to_bits()) {
                // Not what the guess assumed: this segment again, in order.
                let (st, ct) = rerun(&filt2, q, opts, z, t, g0, g1, prev, out, ps)?;
                new_states[q] = st;
                new_counts[q] = ct;
                continue;
            }
            let (mut d0, mut d1) = (prev.x[0] - guess.x[0], prev.x[1] - guess.x[1]);
            let mut t_last = guess.t_last;
            let mut k = g0;
            while k < g1 && (d0 != 0.0 || d1 != 0.0) {
                let tk = tat(k);
                let dt = if t_last.is_nan() {
                    opts.t_nominal
                } else {
                    tk - t_last
                };
                if dt.is_nan() || dt <= 0.0 {
                    // Dropped (not after the last kept timestamp).
                    k += 1;
                    continue;
                }
                t_last = tk;
                if dt > max_gap {
                    // Restarted in both runs: no difference from here.
                    d0 = 0.0;
                    d1 = 0.0;
                    break;
                }
                let dp = d0 + dt * d1;
                let zk = zat(k);
                if zk.is_nan() {
                    d0 = dp;
                } else {
                    let Some((a, g)) = l.ab_gains(dt) else {
                        return Err(Error::Data {
                            track: sp.track,
                            sample: k - off[sp.track],
                            msg: format!("no gains for the step dt={dt}"),
                        });
                    };
                    d0 = (1.0 - a) * dp;
                    d1 -= g * dp;
                }
                let xn = out[k].to_f64() + d0;
                let vn = out[ps + k].to_f64() + d1;
                out[k] = T::from_f64(xn);
                out[ps + k] = T::from_f64(vn);
                if d0.abs() + (d1 * dt).abs() <= tiny * (xn.abs() + (vn * dt).abs()) {
                    d0 = 0.0;
                    d1 = 0.0;
                }
                k += 1;
            }
            new_states[q].x[0] += d0;
            new_states[q].x[1] += d1;
        }
    }
    // Back to the original tracks.
    for c in counts.iter_mut() {
        *c = [0, 0];
    }
    for (q, &i) in owner.iter().enumerate() {
        // The last segment of a track (or the track itself) holds its state.
        states[i] = new_states[q];
        counts[i][0] += new_counts[q][0];
        counts[i][1] += new_counts[q][1];
    }
    Ok(())
}

fn law_of<'f, L: Clone, const N: usize, const M: usize>(
    filt: &'f TrackFilter<'_, L, N, M>,
    i: usize,
) -> &'f L {
    &filt.laws[if filt.laws.len() == 1 { 0 } else { i }]
}

/// Samples `g0..g1` (one segment, new track `q` of `filt2`) again from the
/// state `st`, in order; writes their outputs, returns the end state and
/// counts (`plane`: the plane stride of `out`).
#[allow(clippy::too_many_arguments)]
fn rerun<T: IoFloat, L: GainLaw<N, M>, const N: usize, const M: usize>(
    filt2: &TrackFilter<'_, L, N, M>,
    q: usize,
    opts: &Options,
    z: &Samples<'_, T>,
    t: &Samples<'_, f64>,
    g0: usize,
    g1: usize,
    st: TrackState,
    out: &mut [T],
    plane: usize,
) -> Result<(TrackState, Counts)> {
    let len = g1 - g0;
    // The segment lies inside one row: a flat view of it.
    let (zb, zs) = (z.addr(g0) as usize, z.s_sample);
    let (tb, ts) = (t.addr(g0) as usize, t.s_sample);
    let zv = Samples {
        base: zb,
        s_row: 0,
        s_sample: zs,
        row_len: len,
        n_rows: 1,
        ..*z
    };
    let tv = Samples {
        base: tb,
        s_row: 0,
        s_sample: ts,
        row_len: len,
        n_rows: 1,
        ..*t
    };
    let one = TrackFilter {
        laws: std::slice::from_ref(law_of(filt2, q)),
        h: filt2.h,
        h_pinv: filt2.h_pinv,
    };
    let mut buf = vec![T::from_f64(0.0); N * len];
    let mut s = [st];
    let mut c: [Counts; 1] = [[0, 0]];
    run_tracks(
        &one,
        opts,
        &[0, len],
        &zv,
        Some(&tv),
        &mut s,
        &mut buf,
        None,
        &mut c,
        false,
        &NoPost,
    )?;
    for comp in 0..N {
        out[comp * plane + g0..comp * plane + g1]
            .copy_from_slice(&buf[comp * len..(comp + 1) * len]);
    }
    Ok((s[0], c[0]))
}
