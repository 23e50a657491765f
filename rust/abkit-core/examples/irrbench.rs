//! Micro-benchmark of the irregular-timestamp alpha-beta lanes (not a
//! test; docs/benchmarks.md, "Irregular timestamps: the design law in one
//! square root and one division"): ns per sample of `filter_tracks` on `n`
//! tracks of `len` samples with exponential time steps (mean 0.1), best of
//! `reps` runs, design law (`ratio = 0.1`) and fixed gains.
//!
//! ```sh
//! cargo run --release -p abkit-core --example irrbench -- 4 4000 3000     # in L2
//! cargo run --release -p abkit-core --example irrbench -- 1000 10000 3    # 10^7 samples
//! cargo run --release -p abkit-core --example irrbench -- 4 4000 3000 1   # steps 0.1 / 0.2
//! cargo run --release -p abkit-core --example irrbench -- 4 4000 3000 2   # whole seconds
//! ```
use abkit_core::filter::{Init, TrackState};
use abkit_core::irregular::{AbDesign, AbFixed, GainLaw};
use abkit_core::ragged::{filter_tracks, NoPost, Options, Samples, TrackFilter};
use std::time::Instant;

mod common;
use common::{thp_capacity, thp_vec};

fn bench<L: GainLaw<2, 1>>(
    name: &str,
    laws: &[L],
    z: &[f64],
    t: &[f64],
    off: &[i64],
    reps: usize,
) -> Result<(), abkit_core::Error> {
    let f = TrackFilter {
        laws,
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
    let mut states = thp_vec(2 * z.len(), |_| 0.0f64);
    let zs = Samples::flat(z, 1)?;
    let ts = Samples::flat(t, 1)?;
    let mut best = f64::INFINITY;
    for _ in 0..reps {
        st.iter_mut().for_each(|s| *s = TrackState::default());
        let t0 = Instant::now();
        filter_tracks(
            &f,
            &o,
            off,
            &zs,
            Some(&ts),
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
        "{name}: {:.2} ns/sample = {:.0} Ms/s",
        best * 1e9 / z.len() as f64,
        z.len() as f64 / best / 1e6
    );
    Ok(())
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let a = std::env::args()
        .skip(1)
        .map(|s| s.parse::<usize>())
        .collect::<Result<Vec<_>, _>>()?;
    let &[n, len, reps, ..] = &a[..] else {
        return Err(
            "usage: irrbench N_TRACKS LEN REPS [1: steps 0.1 / 0.2, 2: whole seconds]".into(),
        );
    };
    let mut s = 12345u64;
    let mut r = || {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (s >> 11) as f64 / (1u64 << 53) as f64
    };
    let (mut z, mut t) = (thp_capacity(n * len), thp_capacity(n * len));
    let off: Vec<i64> = (0..=n).map(|i| (i * len) as i64).collect();
    for _ in 0..n {
        let mut tk = 0.0;
        for _ in 0..len {
            tk += match a.get(3) {
                Some(1) => 0.1 * (1.0 + (r() < 0.1) as u32 as f64),
                // whole seconds, 1 % of the reports missed
                Some(2) => 1.0 + (r() < 0.01) as u32 as f64,
                _ => -0.1 * (1.0 - r()).ln(),
            };
            t.push(tk);
            z.push(2.0 * tk + r());
        }
    }
    bench("design", &[AbDesign::new(0.1)], &z, &t, &off, reps)?;
    bench(
        "fixed ",
        &[AbFixed {
            alpha: 0.3,
            beta: 0.05,
        }],
        &z,
        &t,
        &off,
        reps,
    )?;
    Ok(())
}
