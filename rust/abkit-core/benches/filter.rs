//! Criterion benchmark of the pure-Rust filtering kernels (no Python).
//!
//! Part of the cross-language benchmark in `bench/` (see `bench/README.md`
//! and `docs/benchmarks.md`); `python bench/run.py` runs it and reads the
//! times back. Workloads are `n_tracks x n_samples` with 10^7 samples in all:
//! `1 x 10^7`, `100_000 x 100` and `1_000 x 10_000`, in `f64` and `f32`,
//! on one thread with the output buffers reused, as in the Python numbers.
//! Each iteration also resets the per-track start-up state (as a fresh
//! `run` does).
//!
//! Besides criterion's estimate (a mean per iteration), each benchmark
//! prints the fastest single iteration it saw, as
//! `min-iteration <group>/<id>: <seconds> s`, comparable with the minimum of
//! warm runs that the Python side reports (on a busy 2-core machine the mean
//! is inflated by other load much more than the minimum).
//!
//! `ABKIT_BENCH_SCALE=k` divides every workload's sample count by `k` (for a
//! quick smoke run). Run with
//! `cargo bench -p abkit-core --bench filter` (add `-- ab_serial` etc. to
//! select groups).

use abkit_core::filter::{
    filter_ab, filter_general, Gains, Init, IoFloat, Measurements, TrackState,
};
use criterion::measurement::WallTime;
use criterion::{
    criterion_group, criterion_main, BenchmarkGroup, BenchmarkId, Criterion, Throughput,
};
use std::cell::Cell;
use std::hint::black_box;
use std::time::{Duration, Instant};

const ALPHA: f64 = 0.5;
const BETA: f64 = 0.2;
const T: f64 = 0.1;

fn scale() -> usize {
    std::env::var("ABKIT_BENCH_SCALE")
        .ok()
        .and_then(|s| s.parse().ok())
        .filter(|&k: &usize| k >= 1)
        .unwrap_or(1)
}

/// `(label, n_tracks, n_samples)`.
fn workloads() -> Vec<(String, usize, usize)> {
    let k = scale();
    let total = 10_000_000 / k;
    [
        (1, total),
        (100_000 / k, 100),
        (1_000 / k.min(1_000), total / (1_000 / k.min(1_000))),
    ]
    .into_iter()
    .map(|(nt, ns)| (format!("{nt}x{ns}"), nt, ns))
    .collect()
}

/// A constant-velocity target plus noise, per track (deterministic LCG).
fn measurements<F: IoFloat>(n_tracks: usize, n_samples: usize) -> Vec<F> {
    let mut s: u64 = 0x9E37_79B9_7F4A_7C15;
    let mut out = Vec::with_capacity(n_tracks * n_samples);
    for i in 0..n_tracks {
        let v = (i % 17) as f64 - 8.0;
        for k in 0..n_samples {
            s = s
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            let u = (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
            out.push(F::from_f64(100.0 * i as f64 + v * T * k as f64 + u));
        }
    }
    out
}

/// Benchmark `f` as `<group>/<id>`: criterion's statistics, plus the
/// fastest single iteration printed on stdout.
fn case(g: &mut BenchmarkGroup<'_, WallTime>, group: &str, id: &str, mut f: impl FnMut()) {
    let min = Cell::new(f64::INFINITY);
    g.bench_function(BenchmarkId::from_parameter(id), |b| {
        b.iter_custom(|iters| {
            let mut total = Duration::ZERO;
            for _ in 0..iters {
                let t0 = Instant::now();
                f();
                let dt = t0.elapsed();
                total += dt;
                min.set(min.get().min(dt.as_secs_f64()));
            }
            total
        })
    });
    if min.get().is_finite() {
        println!("min-iteration {group}/{id}: {:.9} s", min.get());
    }
}

fn bench_ab<F: IoFloat>(c: &mut Criterion, dtype: &str, parallel: bool) {
    let name = if parallel {
        format!("ab_parallel/{dtype}")
    } else {
        format!("ab_serial/{dtype}")
    };
    let mut g = c.benchmark_group(&name);
    g.sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2));
    for (label, nt, ns) in workloads() {
        if parallel && nt == 1 {
            continue;
        }
        let z = measurements::<F>(nt, ns);
        let meas = Measurements::contiguous(&z, nt, ns, 1).expect("shape");
        let mut states = vec![TrackState::default(); nt];
        let mut out = vec![F::from_f64(0.0); 2 * nt * ns];
        g.throughput(Throughput::Elements((nt * ns) as u64));
        case(&mut g, &name, &label, || {
            states.fill(TrackState::default());
            filter_ab(
                &[(ALPHA, BETA, T)],
                Init::TwoPoint,
                black_box(&meas),
                &mut states,
                &mut out,
                None,
                parallel,
                None,
            )
            .expect("filter_ab");
            black_box(&out);
        });
    }
    g.finish();
}

fn abg_gains() -> Gains<3, 1> {
    let (a, b, gm) = (0.5, 0.4, 0.1);
    Gains {
        phi: [[1.0, T, T * T / 2.0], [0.0, 1.0, T], [0.0, 0.0, 1.0]],
        h: [[1.0, 0.0, 0.0]],
        k: [[a], [b / T], [gm / (2.0 * T * T)]],
        h_pinv: [[1.0], [0.0], [0.0]],
        t: T,
    }
}

fn bench_general3<F: IoFloat>(c: &mut Criterion, dtype: &str) {
    let name = format!("general3_serial/{dtype}");
    let mut g = c.benchmark_group(&name);
    g.sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2));
    let gains = [abg_gains()];
    for (label, nt, ns) in workloads() {
        let z = measurements::<F>(nt, ns);
        let meas = Measurements::contiguous(&z, nt, ns, 1).expect("shape");
        let mut states = vec![TrackState::default(); nt];
        let mut out = vec![F::from_f64(0.0); 3 * nt * ns];
        g.throughput(Throughput::Elements((nt * ns) as u64));
        case(&mut g, &name, &label, || {
            states.fill(TrackState::default());
            filter_general(
                &gains,
                Init::TwoPoint,
                black_box(&meas),
                &mut states,
                &mut out,
                None,
                false,
                None,
            )
            .expect("filter_general");
            black_box(&out);
        });
    }
    g.finish();
}

/// Per-track overhead: 100,000 tracks of 2 samples (start-up only) and of 10.
fn bench_overhead(c: &mut Criterion) {
    let name = "overhead/f64";
    let mut g = c.benchmark_group(name);
    g.sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(1));
    for (nt, ns) in [(100_000 / scale(), 2), (100_000 / scale(), 10)] {
        let z = measurements::<f64>(nt, ns);
        let meas = Measurements::contiguous(&z, nt, ns, 1).expect("shape");
        let mut states = vec![TrackState::default(); nt];
        let mut out = vec![0.0; 2 * nt * ns];
        g.throughput(Throughput::Elements((nt * ns) as u64));
        case(&mut g, name, &format!("{nt}x{ns}"), || {
            states.fill(TrackState::default());
            filter_ab(
                &[(ALPHA, BETA, T)],
                Init::TwoPoint,
                black_box(&meas),
                &mut states,
                &mut out,
                None,
                false,
                None,
            )
            .expect("filter_ab");
            black_box(&out);
        });
    }
    g.finish();
}

fn benches(c: &mut Criterion) {
    bench_ab::<f64>(c, "f64", false);
    bench_ab::<f32>(c, "f32", false);
    bench_ab::<f64>(c, "f64", true);
    bench_ab::<f32>(c, "f32", true);
    bench_general3::<f64>(c, "f64");
    bench_general3::<f32>(c, "f32");
    bench_overhead(c);
}

criterion_group!(filter_benches, benches);
criterion_main!(filter_benches);
