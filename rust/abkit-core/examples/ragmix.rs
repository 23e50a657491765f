//! Micro-benchmark comparing ragged alpha-beta batches of several length
//! mixes in one process (not a test; docs/benchmarks.md): the cases run
//! round robin and each reports its best, so that the host's drifts and
//! the process's memory layout affect all cases alike. `f64`, one thread,
//! fixed gains, outputs reused, every output's planes a few lines apart
//! modulo 4 KiB.
//!
//! ```sh
//! cargo run --release -p abkit-core --example ragmix -- 10000000 9 rect:10000 10000-10000 2000-10000 10-10000
//! ```
//!
//! A case is `rect:N` (the rectangular kernel, rows of `N`), `LO-HI`
//! (log-uniform lengths, or all `LO` if equal), `LO-HI-s` (the same
//! lengths stored in ascending order), `LO-HI-Q` or `LO-HI-sQ` (lengths
//! rounded up to multiples of `Q`).
use abkit_core::filter::{filter_ab, Init, Measurements, TrackState};
use abkit_core::irregular::AbFixed;
use abkit_core::planes::padded_stride;
use abkit_core::ragged::{filter_tracks, NoPost, Options, Samples, TrackFilter};
use std::time::Instant;

mod common;
use common::thp_vec;

enum Case {
    Rect(usize),
    Ragged(Vec<i64>),
}

fn lengths(lo: usize, hi: usize, total: usize, sorted: bool, round: usize) -> Vec<i64> {
    let mut s = 12345u64;
    let mut r = || {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (s >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut lens = Vec::new();
    let mut n = 0usize;
    while n < total {
        let len = if lo == hi {
            lo
        } else {
            let (l0, l1) = ((lo as f64).log10(), (hi as f64).log10());
            10f64.powf(l0 + (l1 - l0) * r()).round() as usize
        };
        let len = (len.div_ceil(round) * round).clamp(1, total - n);
        n += len;
        lens.push(len);
    }
    if sorted {
        lens.sort_unstable();
    }
    let mut off = vec![0i64];
    let mut acc = 0i64;
    for l in lens {
        acc += l as i64;
        off.push(acc);
    }
    off
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [total, reps, specs @ ..] = &args[..] else {
        return Err("usage: ragmix TOTAL REPS CASE...".into());
    };
    let (total, reps): (usize, usize) = (total.parse()?, reps.parse()?);
    let mut cases = Vec::new();
    for sp in specs {
        if let Some(n) = sp.strip_prefix("rect:") {
            cases.push((sp.clone(), Case::Rect(n.parse()?)));
        } else {
            let p: Vec<&str> = sp.split('-').collect();
            let (lo, hi): (usize, usize) = (p[0].parse()?, p.get(1).unwrap_or(&p[0]).parse()?);
            let sorted = p.get(2).is_some_and(|f| f.contains('s'));
            let round = p
                .get(2)
                .and_then(|f| f.trim_start_matches('s').parse().ok())
                .unwrap_or(1);
            cases.push((
                sp.clone(),
                Case::Ragged(lengths(lo, hi, total, sorted, round)),
            ));
        }
    }
    let z: Vec<f64> = thp_vec(total, |i| i as f64 * 0.01 + ((i * 7919) % 13) as f64 * 0.1);
    // Outputs in the padded layout (abkit.empty_states).
    let mut out = thp_vec(2 * total + 8192, |_| 0.0f64);
    let pad = |per: usize, row: usize| padded_stride::<f64>(2, per, row).unwrap_or(per) + per;
    let laws = [AbFixed {
        alpha: 0.5,
        beta: 0.2,
    }];
    let f = TrackFilter {
        laws: &laws[..],
        h: [[1.0, 0.0]],
        h_pinv: [[1.0], [0.0]],
    };
    let o = Options {
        init: Init::TwoPoint,
        t_nominal: 0.1,
        max_gap: None,
        drop_duplicates: false,
    };
    let mut best = vec![f64::INFINITY; cases.len()];
    for _ in 0..reps {
        for (ci, (_, c)) in cases.iter().enumerate() {
            let t0;
            match c {
                Case::Rect(n) => {
                    let rows = total / n;
                    let meas = Measurements::contiguous(&z[..rows * n], rows, *n, 1)?;
                    let mut st = vec![TrackState::default(); rows];
                    let o = &mut out[..pad(rows * n, *n)];
                    t0 = Instant::now();
                    filter_ab(
                        &[(0.5, 0.2, 0.1)],
                        Init::TwoPoint,
                        &meas,
                        &mut st,
                        o,
                        None,
                        false,
                        None,
                    )?;
                }
                Case::Ragged(off) => {
                    let n_tracks = off.len() - 1;
                    let mut st = vec![TrackState::default(); n_tracks];
                    let mut counts = vec![[0i64; 2]; n_tracks];
                    let zs = Samples::flat(&z, 1)?;
                    t0 = Instant::now();
                    filter_tracks(
                        &f,
                        &o,
                        off,
                        &zs,
                        None,
                        &mut st,
                        &mut out[..pad(total, 0)],
                        None,
                        &mut counts,
                        false,
                        &NoPost,
                    )?;
                }
            }
            best[ci] = best[ci].min(t0.elapsed().as_secs_f64());
        }
    }
    let line: Vec<String> = cases
        .iter()
        .zip(&best)
        .map(|((name, _), b)| format!("{name}={:.3}", b * 1e9 / total as f64))
        .collect();
    println!("{}", line.join(" "));
    Ok(())
}
