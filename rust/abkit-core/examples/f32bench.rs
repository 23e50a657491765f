//! Micro-benchmark (not a test): the alpha-beta rows on `f32` data in `f64`
//! arithmetic ([`filter_ab`], the default) against `f32` arithmetic
//! ([`filter_ab_f32`]), alternating in one process, ns per sample (best of
//! `reps`), one thread, outputs reused; and the largest difference between
//! the two relative to the array's scale.
//!
//! ```sh
//! cargo run --release -p abkit-core --example f32bench -- 16 2048 20000   # in L2
//! cargo run --release -p abkit-core --example f32bench -- 1000 10000 5    # 10^7 samples
//! ```
use abkit_core::filter::f32arith::filter_ab_f32;
use abkit_core::filter::{filter_ab, Init, Measurements, TrackState};
use std::time::Instant;

mod common;
use common::thp_vec;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let a = std::env::args()
        .skip(1)
        .map(|s| s.parse::<usize>())
        .collect::<Result<Vec<_>, _>>()?;
    let &[n, len, reps, ..] = &a[..] else {
        return Err("usage: f32bench N_TRACKS LEN REPS".into());
    };
    let z: Vec<f32> = thp_vec(n * len, |i| {
        ((i % len) as f64 * 0.7 + ((i * 7919) % 13) as f64 * 0.1) as f32
    });
    let meas = Measurements::contiguous(&z, n, len, 1)?;
    let mut states = vec![TrackState::default(); n];
    let mut o64 = thp_vec(2 * n * len, |_| 0f32);
    let mut o32 = thp_vec(2 * n * len, |_| 0f32);
    let p = [(0.5, 0.2, 0.1)];
    let (mut b64, mut b32) = (f64::INFINITY, f64::INFINITY);
    for _ in 0..reps {
        states.fill(TrackState::default());
        let t0 = Instant::now();
        filter_ab(
            &p,
            Init::TwoPoint,
            &meas,
            &mut states,
            &mut o64,
            None,
            false,
            None,
        )?;
        b64 = b64.min(t0.elapsed().as_secs_f64());
        states.fill(TrackState::default());
        let t0 = Instant::now();
        filter_ab_f32(
            &p,
            Init::TwoPoint,
            &meas,
            &mut states,
            &mut o32,
            None,
            false,
        )?;
        b32 = b32.min(t0.elapsed().as_secs_f64());
    }
    let scale = z.iter().fold(0f32, |m, v| m.max(v.abs())) as f64;
    let dev = o64[..n * len]
        .iter()
        .zip(&o32[..n * len])
        .map(|(a, b)| (*a as f64 - *b as f64).abs())
        .fold(0.0, f64::max);
    let ns = |t: f64| t * 1e9 / (n * len) as f64;
    println!(
        "{n}x{len}: f64 arithmetic {:.3} ns/sample, f32 arithmetic {:.3} ns/sample ({:.2}x); max |dx| / scale {:.1e}",
        ns(b64),
        ns(b32),
        b64 / b32,
        dev / scale
    );
    Ok(())
}
