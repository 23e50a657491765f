//! Micro-benchmark of ragged alpha-beta batches without timestamps (not a
//! test; docs/benchmarks.md): ns per sample of `filter_tracks` over tracks
//! of log-uniform lengths `lo..hi` up to `total` samples (or all of length
//! `lo` if `lo == hi`), best of `reps` runs, fixed gains.
//!
//! ```sh
//! cargo run --release -p abkit-core --example ragbench -- 10 10000 10000000 5
//! cargo run --release -p abkit-core --example ragbench -- 100 100 10000000 5
//! ```
use abkit_core::filter::{Init, TrackState};
use abkit_core::irregular::AbFixed;
use abkit_core::ragged::{filter_tracks, NoPost, Options, Samples, TrackFilter};
use std::time::Instant;

mod common;
use common::thp_vec;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let a = std::env::args()
        .skip(1)
        .map(|s| s.parse::<usize>())
        .collect::<Result<Vec<_>, _>>()?;
    let &[lo, hi, total, reps, ..] = &a[..] else {
        return Err("usage: ragbench LO HI TOTAL REPS [1: with timestamps]".into());
    };
    let timed = a.get(4) == Some(&1);
    let mut s = 12345u64;
    let mut r = || {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (s >> 11) as f64 / (1u64 << 53) as f64
    };
    // RAGBENCH_ROUND=q: lengths rounded to multiples of q (at least q).
    let round: usize = std::env::var("RAGBENCH_ROUND")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(1)
        .max(1);
    let mut off: Vec<i64> = vec![0];
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
        off.push(n as i64);
    }
    // RAGBENCH_ZSHIFT=s: z starts s samples into its allocation (moves z
    // against the outputs modulo 4 KiB).
    let zshift: usize = std::env::var("RAGBENCH_ZSHIFT")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(0);
    let zbuf: Vec<f64> = thp_vec(n + zshift, |i| i as f64 * 0.01 + r());
    let z = &zbuf[zshift..];
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
    let n_tracks = off.len() - 1;
    let mut st = thp_vec(n_tracks, |_| TrackState::default());
    let mut counts = vec![[0i64; 2]; n_tracks];
    let mut states = thp_vec(2 * n, |_| 0.0f64);
    let zs = Samples::flat(z, 1)?;
    // Timestamps (optional): steps uniform in 0.05..0.15.
    let mut acc = 0.0;
    let t: Vec<f64> = thp_vec(n, |_| {
        acc += 0.05 + 0.1 * r();
        acc
    });
    let ts = Samples::flat(&t, 1)?;
    let mut best = f64::INFINITY;
    for _ in 0..reps {
        st.iter_mut().for_each(|s| *s = TrackState::default());
        let t0 = Instant::now();
        filter_tracks(
            &f,
            &o,
            &off,
            &zs,
            timed.then_some(&ts),
            &mut st,
            &mut states,
            None,
            &mut counts,
            false,
            &NoPost,
        )?;
        best = best.min(t0.elapsed().as_secs_f64());
    }
    println!(
        "{n_tracks} tracks, {n} samples: {:.3} ns/sample = {:.0} Ms/s",
        best * 1e9 / n as f64,
        n as f64 / best / 1e6
    );
    Ok(())
}
