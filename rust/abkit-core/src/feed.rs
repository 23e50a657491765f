//! A feed of reports in arrival order: rows of many tracks interleaved
//! (an AIS/ADS-B dump ordered by time), filtered row by row.
//!
//! Row `r` belongs to track `codes[r]`; the track's state lives in a table
//! indexed by track and is updated in place, so measurements, timestamps and
//! estimates are read and written in row order (sequential memory access)
//! instead of gathering every track's rows into a ragged batch and
//! scattering the estimates back. Each sample goes through the same per-sample
//! code as [`crate::ragged::filter_tracks`] (the module's `track_tv`), so the
//! estimates, residuals, counts and errors equal those of the ragged kernel
//! run on the rows grouped by track (in row order within each track) —
//! bit-identical.
//!
//! Several measurement columns (e.g. the x and y of a position, each
//! filtered with the scalar-measurement filter) share the codes and
//! timestamps; each column has its own state table and runs on rayon's
//! pool when `parallel`.
use crate::filter::{IoFloat, TrackOut, TrackState};
use crate::irregular::GainLaw;
use crate::ragged::{ab_update, track_tv, Counts, Options, Samples, TrackFilter};
use crate::{Error, Result};
use rayon::prelude::*;

/// Where a feed's error happened: the column and the core error (a
/// [`Error::Data`] names the track and the sample within the track).
pub type FeedError = (usize, Error);

/// Per-track bookkeeping of a feed: rows seen so far and the first row.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TrackRows {
    /// Number of rows of the track.
    pub n: i64,
    /// Row index of its first row (`-1`: none).
    pub first: i64,
}

impl Default for TrackRows {
    fn default() -> Self {
        TrackRows { n: 0, first: -1 }
    }
}

/// Filter the rows of a feed (see the module docs).
///
/// `codes[r]` in `0..n_tracks` is the track of row `r`; `z` one
/// [`Samples`] per column (each `codes.len()` samples of `M` components);
/// `t` the rows' timestamps or `None` (every step the nominal period);
/// `states` `n_columns * n_tracks` (column `c`'s table at `c * n_tracks`);
/// `out` `(n_columns, N, n_rows)`; `resid` `(n_columns, n_rows, M)`;
/// `counts` (`[n_dropped, n_restarts]`) and `rows` per track, from column 0
/// (the counts of the ragged kernel's first column). The first column with
/// an error (in column order) is reported.
#[allow(clippy::too_many_arguments)]
pub fn filter_feed<T: IoFloat, L: GainLaw<N, M>, const N: usize, const M: usize>(
    filt: &TrackFilter<'_, L, N, M>,
    opts: &Options,
    codes: &[i64],
    z: &[Samples<'_, T>],
    t: Option<&Samples<'_, f64>>,
    states: &mut [TrackState],
    out: &mut [T],
    resid: Option<&mut [T]>,
    counts: &mut [Counts],
    rows: &mut [TrackRows],
    parallel: bool,
) -> std::result::Result<(), FeedError> {
    let n_rows = codes.len();
    let n_cols = z.len();
    let n_tracks = rows.len();
    let shape = |m: String| (0, Error::Shape(m));
    for (c, zc) in z.iter().enumerate() {
        if zc.m != M || zc.len() != n_rows {
            return Err(shape(format!(
                "column {c}: {} samples of {} components, need {n_rows} of {M}",
                zc.len(),
                zc.m
            )));
        }
        zc.validate("measurement").map_err(|e| (c, e))?;
    }
    if let Some(ts) = t {
        if ts.len() != n_rows {
            return Err(shape(format!(
                "t has {} samples, the feed {n_rows} rows",
                ts.len()
            )));
        }
        ts.validate("timestamp").map_err(|e| (0, e))?;
    }
    if filt.laws.len() != 1 && filt.laws.len() != n_tracks {
        return Err(shape(format!(
            "{} parameter sets for {n_tracks} tracks (need 1 or one per track)",
            filt.laws.len()
        )));
    }
    if states.len() != n_cols * n_tracks || counts.len() != n_tracks {
        return Err(shape(
            "state or count buffers do not match the tracks".into(),
        ));
    }
    if out.len() != n_cols * N * n_rows {
        return Err(shape("output buffer has the wrong size".into()));
    }
    if let Some(r) = &resid {
        if r.len() != n_cols * M * n_rows {
            return Err(shape("residual buffer has the wrong size".into()));
        }
    }
    if !(opts.t_nominal.is_finite() && opts.t_nominal > 0.0) {
        return Err((0, Error::domain("T", "finite and > 0", opts.t_nominal)));
    }
    if let Some(g) = opts.max_gap {
        if g.is_nan() || g <= 0.0 {
            return Err((0, Error::domain("max_gap", "> 0", g)));
        }
    }
    if let Some(r) = codes
        .iter()
        .position(|&i| i < 0 || i as u64 >= n_tracks as u64)
    {
        return Err(shape(format!(
            "row {r}: track code {} outside 0..{n_tracks}",
            codes[r]
        )));
    }
    if n_rows == 0 || n_cols == 0 {
        return Ok(());
    }
    // Per-column jobs with disjoint buffers.
    struct Job<'a, T, const N: usize> {
        col: usize,
        out: [&'a mut [T]; N],
        resid: Option<&'a mut [T]>,
        states: &'a mut [TrackState],
    }
    let mut out_cols = out.chunks_exact_mut(N * n_rows);
    let mut resid_cols = resid.map(|r| r.chunks_exact_mut(M * n_rows));
    let mut jobs: Vec<Job<'_, T, N>> = Vec::with_capacity(n_cols);
    for (col, st) in states.chunks_exact_mut(n_tracks).enumerate() {
        let Some(o) = out_cols.next() else { break };
        let mut comps = o.chunks_exact_mut(n_rows);
        let out: [&mut [T]; N] = std::array::from_fn(|_| comps.next().unwrap_or_default());
        let resid = resid_cols.as_mut().and_then(|it| it.next());
        jobs.push(Job {
            col,
            out,
            resid,
            states: st,
        });
    }
    let mut c0: Vec<Counts> = vec![[0; 2]; n_tracks];
    let mut r0: Vec<TrackRows> = vec![TrackRows::default(); n_tracks];
    let run = |job: &mut Job<'_, T, N>, ct: &mut [Counts], tr: &mut [TrackRows]| {
        run_column_dispatch(
            filt,
            opts,
            codes,
            &z[job.col],
            t,
            job.states,
            &mut job.out,
            job.resid.as_deref_mut(),
            ct,
            tr,
        )
        .map_err(|e| (job.col, e))
    };
    let (first, rest) = jobs.split_at_mut(1);
    let results: Vec<std::result::Result<(), FeedError>> = if parallel && n_cols > 1 {
        let (a, b) = rayon::join(
            || run(&mut first[0], &mut c0, &mut r0),
            || {
                rest.par_iter_mut()
                    .map(|j| {
                        let mut ct = vec![[0; 2]; n_tracks];
                        let mut tr = vec![TrackRows::default(); n_tracks];
                        run(j, &mut ct, &mut tr)
                    })
                    .collect::<Vec<_>>()
            },
        );
        std::iter::once(a).chain(b).collect()
    } else {
        let mut v = vec![run(&mut first[0], &mut c0, &mut r0)];
        let (mut ct, mut tr) = (vec![[0; 2]; n_tracks], vec![TrackRows::default(); n_tracks]);
        for j in rest.iter_mut() {
            ct.fill([0; 2]);
            tr.fill(TrackRows::default());
            v.push(run(j, &mut ct, &mut tr));
        }
        v
    };
    counts.copy_from_slice(&c0);
    rows.copy_from_slice(&r0);
    results.into_iter().collect()
}

/// The stable ascending order of timestamps `t` (ties in index order),
/// equal to numpy's `argsort(t, kind="stable")`: `-0.0 == 0.0`, NaN last.
/// The keys are the floats' bits mapped to ordered integers, paired with
/// the index (so the pairs are distinct and an unstable sort is stable),
/// sorted on rayon's pool when `parallel`.
pub fn time_order(t: &[f64], parallel: bool) -> Vec<i64> {
    #[inline]
    fn key(x: f64) -> u64 {
        if x.is_nan() {
            return u64::MAX;
        }
        let b = (x + 0.0).to_bits(); // -0.0 + 0.0 = +0.0
        if b >> 63 == 1 {
            !b
        } else {
            b | (1 << 63)
        }
    }
    let mut pairs: Vec<(u64, u64)> = t
        .iter()
        .enumerate()
        .map(|(i, &x)| (key(x), i as u64))
        .collect();
    if parallel {
        pairs.par_sort_unstable();
    } else {
        pairs.sort_unstable();
    }
    pairs.into_iter().map(|(_, i)| i as i64).collect()
}

#[allow(clippy::too_many_arguments)]
fn run_column_dispatch<T: IoFloat, L: GainLaw<N, M>, const N: usize, const M: usize>(
    filt: &TrackFilter<'_, L, N, M>,
    opts: &Options,
    codes: &[i64],
    z: &Samples<'_, T>,
    t: Option<&Samples<'_, f64>>,
    states: &mut [TrackState],
    out: &mut [&mut [T]; N],
    resid: Option<&mut [T]>,
    counts: &mut [Counts],
    rows: &mut [TrackRows],
) -> Result<()> {
    #[cfg(target_arch = "x86_64")]
    {
        if crate::filter::uses_fma() {
            // SAFETY: the CPU supports FMA (checked at run time by `uses_fma`).
            return unsafe {
                run_column_fma(filt, opts, codes, z, t, states, out, resid, counts, rows)
            };
        }
        run_column::<T, L, N, M, false>(filt, opts, codes, z, t, states, out, resid, counts, rows)
    }
    #[cfg(target_arch = "aarch64")]
    {
        run_column::<T, L, N, M, true>(filt, opts, codes, z, t, states, out, resid, counts, rows)
    }
    #[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
    {
        run_column::<T, L, N, M, false>(filt, opts, codes, z, t, states, out, resid, counts, rows)
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "fma")]
#[allow(clippy::too_many_arguments)]
fn run_column_fma<T: IoFloat, L: GainLaw<N, M>, const N: usize, const M: usize>(
    filt: &TrackFilter<'_, L, N, M>,
    opts: &Options,
    codes: &[i64],
    z: &Samples<'_, T>,
    t: Option<&Samples<'_, f64>>,
    states: &mut [TrackState],
    out: &mut [&mut [T]; N],
    resid: Option<&mut [T]>,
    counts: &mut [Counts],
    rows: &mut [TrackRows],
) -> Result<()> {
    run_column::<T, L, N, M, true>(filt, opts, codes, z, t, states, out, resid, counts, rows)
}

/// One column: every row through the ragged kernel's per-sample code with
/// its track's state, law and counts.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn run_column<T: IoFloat, L: GainLaw<N, M>, const N: usize, const M: usize, const FMA: bool>(
    filt: &TrackFilter<'_, L, N, M>,
    opts: &Options,
    codes: &[i64],
    z: &Samples<'_, T>,
    t: Option<&Samples<'_, f64>>,
    states: &mut [TrackState],
    out: &mut [&mut [T]; N],
    mut resid: Option<&mut [T]>,
    counts: &mut [Counts],
    rows: &mut [TrackRows],
) -> Result<()> {
    // One law per track (a law may cache its last step), or one shared.
    let mut shared = filt.laws[0].clone();
    let mut own: Vec<L> = if filt.laws.len() > 1 {
        filt.laws.to_vec()
    } else {
        Vec::new()
    };
    // Alpha-beta laws: a running track's plain step inline (the arithmetic
    // of `track_tv`'s alpha-beta fast path); any other sample through
    // `track_tv` itself.
    let is_ab = N == 2 && M == 1 && filt.laws[0].clone().ab_gains(opts.t_nominal).is_some();
    let max_gap = opts.max_gap.unwrap_or(f64::INFINITY);
    for (r, &code) in codes.iter().enumerate() {
        let i = code as usize;
        let tr = &mut rows[i];
        let sample = tr.n as usize;
        if tr.n == 0 {
            tr.first = r as i64;
        }
        tr.n += 1;
        let law = if own.is_empty() {
            &mut shared
        } else {
            &mut own[i]
        };
        let za = z.addr(r);
        if is_ab && states[i].phase >= 2.0 {
            let st = &mut states[i];
            let step = match t {
                Some(ts) => {
                    let tk = ts.data[ts.addr(r) as usize];
                    let dt = tk - st.t_last;
                    (dt > 0.0 && dt <= max_gap && dt < f64::INFINITY).then_some((dt, tk))
                }
                None => Some((opts.t_nominal, st.t_last)),
            };
            let gains = step.and_then(|(dt, _)| {
                law.ab_gains(dt)
                    .filter(|(a, g)| a.is_finite() && g.is_finite())
            });
            if let (Some((dt, tk)), Some((a, g))) = (step, gains) {
                let zk = z.data[za as usize].to_f64();
                let (x1, v1, e) = ab_update::<FMA>(st.x[0], st.x[1], dt, a, g, zk);
                st.x[0] = x1;
                st.x[1] = v1;
                st.t_last = tk;
                out[0][r] = T::from_f64(x1);
                out[1][r] = T::from_f64(v1);
                if let Some(res) = resid.as_deref_mut() {
                    res[r] = T::from_f64(e);
                }
                continue;
            }
        }
        let zf = |_: usize| -> [f64; M] {
            std::array::from_fn(|c| z.data[(za + c as isize * z.s_comp) as usize].to_f64())
        };
        let mut o = TrackOut {
            states: out.each_mut().map(|s| &mut s[r..r + 1]),
            resid: resid.as_deref_mut().map(|s| &mut s[r * M..(r + 1) * M]),
        };
        let res = match t {
            Some(ts) => {
                let tk = ts.data[ts.addr(r) as usize];
                let tf = |_: usize| -> f64 { tk };
                track_tv::<T, L, N, M, FMA>(
                    law,
                    &filt.h,
                    &filt.h_pinv,
                    opts,
                    &mut states[i],
                    1,
                    zf,
                    Some(&tf),
                    &mut o,
                    &mut counts[i],
                    i,
                    0,
                    false,
                )
            }
            None => track_tv::<T, L, N, M, FMA>(
                law,
                &filt.h,
                &filt.h_pinv,
                opts,
                &mut states[i],
                1,
                zf,
                None::<&fn(usize) -> f64>,
                &mut o,
                &mut counts[i],
                i,
                0,
                false,
            ),
        };
        if let Err(e) = res {
            // the sample within the track, not within this one-row call
            return Err(match e {
                Error::Data { track, msg, .. } => Error::Data { track, sample, msg },
                other => other,
            });
        }
    }
    Ok(())
}

#[cfg(test)]
#[path = "tests/feed.rs"]
mod tests;
