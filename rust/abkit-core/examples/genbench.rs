//! Micro-benchmark of the general fixed-gain kernel (not a test;
//! docs/benchmarks.md): ns per sample of `filter_general::<3, 1>` (an
//! alpha-beta-gamma filter) on `n` tracks of `len` samples, best of `reps`
//! runs, `f64` and `f32`, one thread, outputs reused; `z` and the outputs
//! on huge pages, as NumPy allocates them (before session 27 on 4 KiB
//! pages: 3-state 100,000 x 100 `f64` 3.0-3.35 ns per sample, now
//! 2.9-3.0).
//!
//! ```sh
//! cargo run --release -p abkit-core --example genbench -- 100000 100 5   # short rows, streamed
//! cargo run --release -p abkit-core --example genbench -- 1000 10000 5   # long rows
//! cargo run --release -p abkit-core --example genbench -- 100000 100 5 1 # continued (no start-ups)
//! ```
use abkit_core::filter::{filter_general, Gains, Init, IoFloat, Measurements, TrackState};
use std::time::Instant;

mod common;
use common::thp_vec;

fn bench<F: IoFloat>(
    name: &str,
    n: usize,
    len: usize,
    reps: usize,
    cont: bool,
) -> abkit_core::Result<()> {
    let t = 0.1;
    let (a, b, g) = (0.5, 0.4, 0.1);
    let gains = [Gains::<3, 1> {
        phi: [[1.0, t, t * t / 2.0], [0.0, 1.0, t], [0.0, 0.0, 1.0]],
        h: [[1.0, 0.0, 0.0]],
        k: [[a], [b / t], [g / (2.0 * t * t)]],
        h_pinv: [[1.0], [0.0], [0.0]],
        t,
    }];
    let z: Vec<F> = thp_vec(n * len, |i| {
        F::from_f64((i % len) as f64 * 0.7 + ((i * 7919) % 13) as f64 * 0.1)
    });
    let meas = Measurements::contiguous(&z, n, len, 1)?;
    let mut states = vec![TrackState::default(); n];
    let mut out = thp_vec(3 * n * len, |_| F::from_f64(0.0));
    let mut best = f64::INFINITY;
    for _ in 0..reps {
        if !cont {
            states.fill(TrackState::default());
        }
        let t0 = Instant::now();
        filter_general(
            &gains,
            Init::TwoPoint,
            &meas,
            &mut states,
            &mut out,
            None,
            false,
            None,
        )?;
        best = best.min(t0.elapsed().as_secs_f64());
    }
    let per = best / (n * len) as f64 * 1e9;
    println!(
        "{name} {n}x{len}: {per:.3} ns/sample = {:.0} Ms/s",
        1e3 / per
    );
    Ok(())
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let a = std::env::args()
        .skip(1)
        .map(|s| s.parse::<usize>())
        .collect::<Result<Vec<_>, _>>()?;
    let &[n, len, reps, ..] = &a[..] else {
        return Err("usage: genbench TRACKS SAMPLES REPS [CONT]".into());
    };
    // CONT = 1: every run continues the previous one's states (no start-ups
    // after the first run).
    let cont = a.get(3) == Some(&1);
    bench::<f64>("f64", n, len, reps, cont)?;
    bench::<f32>("f32", n, len, reps, cont)?;
    Ok(())
}
