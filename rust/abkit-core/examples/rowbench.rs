//! Micro-benchmark of the rectangular alpha-beta row kernels (not a test):
//! ns per sample of `filter_ab` on `n` tracks of `len` samples (best of
//! `reps` runs), `f64` and `f32`, one thread, outputs reused.
//!
//! ```sh
//! cargo run --release -p abkit-core --example rowbench -- 8 2048 20000   # in L2
//! cargo run --release -p abkit-core --example rowbench -- 1000 10000 5   # 10^7 samples
//! cargo run --release -p abkit-core --example rowbench -- 100000 10 20 1 # continuing (state=)
//! ```
//!
//! A fourth argument `1`: every timed run continues from the previous
//! run's final states (streaming with `state=`), instead of fresh tracks; a
//! fifth, `64` or `32`: only that precision.
use abkit_core::filter::{filter_ab, Init, IoFloat, Measurements, TrackState};
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
    let z: Vec<F> = thp_vec(n * len, |i| {
        F::from_f64((i % len) as f64 * 0.7 + ((i * 7919) % 13) as f64 * 0.1)
    });
    let meas = Measurements::contiguous(&z, n, len, 1)?;
    let mut states = vec![TrackState::default(); n];
    let mut out = thp_vec(2 * n * len, |_| F::from_f64(0.0));
    let mut best = f64::INFINITY;
    for _ in 0..reps {
        if !cont {
            states.fill(TrackState::default());
        }
        let t0 = Instant::now();
        filter_ab(
            &[(0.5, 0.2, 0.1)],
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
    println!(
        "{name} {n}x{len}: {:.3} ns/sample = {:.0} Ms/s",
        best * 1e9 / (n * len) as f64,
        (n * len) as f64 / best / 1e6
    );
    Ok(())
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let a = std::env::args()
        .skip(1)
        .map(|s| s.parse::<usize>())
        .collect::<Result<Vec<_>, _>>()?;
    let &[n, len, reps, ..] = &a[..] else {
        return Err("usage: rowbench N_TRACKS LEN REPS [CONTINUE [DTYPE]]".into());
    };
    let cont = a.get(3) == Some(&1);
    // DTYPE: 0 both (default), 64 only f64, 32 only f32.
    let dtype = a.get(4).copied().unwrap_or(0);
    if dtype != 32 {
        bench::<f64>("f64", n, len, reps, cont)?;
    }
    if dtype != 64 {
        bench::<f32>("f32", n, len, reps, cont)?;
    }
    Ok(())
}
