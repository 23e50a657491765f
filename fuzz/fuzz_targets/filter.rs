//! Fixed-gain filtering with arbitrary gains, periods, start-up and
//! measurements (NaN = missed detection, Inf, huge values).
//!
//! Invariants: no panic; a run in two chunks (streaming state) is bit for bit
//! one run; sequential and parallel runs agree bit for bit; and when the
//! filter is stable, the period moderate and every measurement finite and
//! bounded, every estimate after start-up is finite. Alpha-beta in float32
//! arithmetic (`f32arith`, batches of 16-20 tracks of 1-200 samples so the
//! vector rows and the column steps run):
//! no panic, parallel = sequential, two chunks = one run, and each track
//! equals the track run alone (the scalar loop), bit for bit; the same
//! samples cut into a ragged batch (`filter_ab_f32_tracks`): each track
//! equals that track alone.
#![no_main]

use abkit_core::filter::f32arith::{filter_ab_f32, filter_ab_f32_tracks};
use abkit_core::filter::{filter_ab, filter_general, Gains, Init, Measurements, TrackState};
use abkit_core::ragged::Samples;
use libfuzzer_sys::fuzz_target;

#[path = "common.rs"]
mod common;
use common::Bytes;

/// Equal bit for bit, except that +0 == -0 (a chunk of one sample can take
/// a code path that gives -0 where the whole run gives +0: numerically equal)
/// and NaN == NaN.
fn same(a: &[f64], b: &[f64]) -> bool {
    a.len() == b.len()
        && a.iter()
            .zip(b)
            .all(|(x, y)| x.to_bits() == y.to_bits() || x == y || (x.is_nan() && y.is_nan()))
}

struct Case {
    nt: usize,
    ns: usize,
    z: Vec<f64>,
    init: Init,
    split: usize,
}

fn case(b: &mut Bytes) -> Case {
    let nt = 1 + b.usize_below(5);
    let ns = b.usize_below(48);
    let init = if b.u8() % 2 == 0 {
        Init::First
    } else {
        Init::TwoPoint
    };
    let split = b.usize_below(ns + 1);
    let mode = b.u8();
    let mut z = Vec::with_capacity(nt * ns);
    for i in 0..nt * ns {
        z.push(match mode % 3 {
            0 => b.f64(),               // anything
            1 => b.in_range(-1e6, 1e6), // bounded
            _ => {
                if b.u8() < 40 {
                    f64::NAN
                } else {
                    (i % ns) as f64 * 0.5 + b.in_range(-1.0, 1.0)
                }
            }
        });
    }
    Case {
        nt,
        ns,
        z,
        init,
        split,
    }
}

/// Run `f` on the whole batch and on two chunks; check they agree.
fn run2(
    c: &Case,
    n: usize,
    f: &dyn Fn(
        &Measurements<'_, f64>,
        &mut [TrackState],
        &mut [f64],
        bool,
    ) -> Result<(), abkit_core::Error>,
) -> Option<Vec<f64>> {
    let meas = Measurements::contiguous(&c.z, c.nt, c.ns, 1).ok()?;
    let mut st = vec![TrackState::default(); c.nt];
    let mut out = vec![0.0; n * c.nt * c.ns];
    let r = f(&meas, &mut st, &mut out, false);
    let mut st_p = vec![TrackState::default(); c.nt];
    let mut out_p = vec![0.0; n * c.nt * c.ns];
    let rp = f(&meas, &mut st_p, &mut out_p, true);
    assert_eq!(r.is_ok(), rp.is_ok());
    r.ok()?;
    assert!(same(&out, &out_p), "parallel run differs");
    if c.z.iter().any(|v| v.is_infinite()) {
        // +-Inf measurements: no panic is all that is required (the Python
        // layer rejects them with a ValueError naming track and sample).
        return Some(out);
    }
    // two chunks with the streaming state
    let (k, ns) = (c.split, c.ns);
    let mut st2 = vec![TrackState::default(); c.nt];
    let mut full = vec![0.0; n * c.nt * ns];
    for (lo, hi) in [(0, k), (k, ns)] {
        let w = hi - lo;
        let zc: Vec<f64> = (0..c.nt)
            .flat_map(|i| c.z[i * ns + lo..i * ns + hi].to_vec())
            .collect();
        let m = Measurements::contiguous(&zc, c.nt, w, 1).ok()?;
        let mut o = vec![0.0; n * c.nt * w];
        f(&m, &mut st2, &mut o, false).ok()?;
        for comp in 0..n {
            for i in 0..c.nt {
                full[(comp * c.nt + i) * ns + lo..(comp * c.nt + i) * ns + hi]
                    .copy_from_slice(&o[(comp * c.nt + i) * w..(comp * c.nt + i) * w + w]);
            }
        }
    }
    if !same(&out, &full) {
        let i = (0..out.len())
            .find(|&i| !same(&out[i..i + 1], &full[i..i + 1]))
            .unwrap_or(0);
        panic!(
            "chunked run differs from one run: nt {} ns {} split {} init {:?} at {i}: {} vs {}; z {:?}",
            c.nt, c.ns, c.split, c.init, out[i], full[i], &c.z[..c.z.len().min(12)]
        );
    }
    let sa: Vec<f64> = st.iter().flat_map(|s| s.x).collect();
    let sb: Vec<f64> = st2.iter().flat_map(|s| s.x).collect();
    assert!(same(&sa, &sb), "chunked final state differs");
    Some(out)
}

fn check_finite(c: &Case, n: usize, out: &[f64]) {
    if !c.z.iter().all(|z| z.is_finite() && z.abs() <= 1e6) {
        return;
    }
    for comp in 0..n {
        for i in 0..c.nt {
            for k in 2..c.ns {
                let v = out[(comp * c.nt + i) * c.ns + k];
                assert!(
                    v.is_finite(),
                    "non-finite estimate {v} (component {comp}, track {i}, sample {k})"
                );
            }
        }
    }
}

/// `filter_ab_f32` on `nt x ns` float32 samples with the given params.
fn run32(
    p: &[(f64, f64, f64)],
    init: Init,
    z: &[f32],
    nt: usize,
    ns: usize,
    st: &mut [TrackState],
    par: bool,
) -> Option<Vec<f32>> {
    let m = Measurements::contiguous(z, nt, ns, 1).ok()?;
    let mut o = vec![0f32; 2 * nt * ns];
    filter_ab_f32(p, init, &m, st, &mut o, None, par).ok()?;
    Some(o)
}

fn same32(a: &[f32], b: &[f32]) -> bool {
    a.len() == b.len()
        && a.iter()
            .zip(b)
            .all(|(x, y)| x.to_bits() == y.to_bits() || x == y || (x.is_nan() && y.is_nan()))
}

/// Alpha-beta parameters `(alpha, beta, T)`: any three numbers from the
/// input, or from the stable region's usual ranges.
fn ab_params(b: &mut Bytes) -> (f64, f64, f64) {
    if b.u8() % 2 == 0 {
        (b.f64(), b.f64(), b.f64())
    } else {
        (
            b.in_range(1e-4, 1.99),
            b.in_range(1e-6, 1.0),
            b.in_range(1e-3, 1e3),
        )
    }
}

/// Alpha-beta in float32 arithmetic over a batch big enough for the vector
/// rows (16-20 tracks of 1-200 samples: whole blocks and the column steps),
/// NaN runs and values from the input.
fn f32_case(b: &mut Bytes) {
    let (a, be, t) = ab_params(b);
    let nt = 16 + b.usize_below(5);
    let ns = 1 + b.usize_below(200);
    let init = if b.u8() % 2 == 0 {
        Init::First
    } else {
        Init::TwoPoint
    };
    let (nan_every, off, mode) = (1 + b.usize_below(64), b.in_range(-1e5, 1e5), b.u8());
    let mut z = vec![0f32; nt * ns];
    for (i, v) in z.iter_mut().enumerate() {
        let k = i % ns;
        *v = if (i / 7 + k) % nan_every == 0 && mode % 2 == 0 {
            f32::NAN
        } else if !b.is_empty() && mode % 3 == 0 {
            b.f64() as f32
        } else {
            (off + k as f64 * 0.25 + (i % 13) as f64 * 0.1) as f32
        };
    }
    let p = [(a, be, t)];
    let mut st = vec![TrackState::default(); nt];
    let Some(out) = run32(&p, init, &z, nt, ns, &mut st, false) else {
        return;
    };
    let mut st_p = vec![TrackState::default(); nt];
    let out_p = run32(&p, init, &z, nt, ns, &mut st_p, true).expect("parallel run failed");
    assert!(
        same32(&out, &out_p),
        "float32 arithmetic: parallel run differs"
    );
    // Two chunks with the streaming state.
    let k = b.usize_below(ns + 1);
    let mut st2 = vec![TrackState::default(); nt];
    for (lo, hi) in [(0, k), (k, ns)] {
        let w = hi - lo;
        let zc: Vec<f32> = (0..nt)
            .flat_map(|i| z[i * ns + lo..i * ns + hi].to_vec())
            .collect();
        let o = run32(&p, init, &zc, nt, w, &mut st2, false).expect("chunk failed");
        for comp in 0..2 {
            for i in 0..nt {
                let got = &o[(comp * nt + i) * w..(comp * nt + i) * w + w];
                let want = &out[(comp * nt + i) * ns + lo..(comp * nt + i) * ns + hi];
                assert!(
                    same32(got, want),
                    "float32 arithmetic: chunk differs (track {i}, split {k})"
                );
            }
        }
    }
    // Each track alone (a batch of one: the scalar loop).
    for i in [0, nt / 2, nt - 1] {
        let mut s1 = [TrackState::default()];
        let o = run32(&p, init, &z[i * ns..(i + 1) * ns], 1, ns, &mut s1, false).expect("alone");
        assert!(
            same32(&o[..ns], &out[i * ns..(i + 1) * ns]),
            "float32: track {i} alone differs (x)"
        );
        assert!(
            same32(&o[ns..], &out[(nt + i) * ns..(nt + i + 1) * ns]),
            "float32: track {i} alone differs (v)"
        );
    }
    // The same samples as a ragged batch (`filter_ab_f32_tracks`), cut into
    // tracks of 0..2 ns samples (the rest in the last): each track equals
    // that track alone.
    let total = nt * ns;
    let mut offs = vec![0i64];
    let mut at = 0usize;
    while at < total {
        let l = if b.is_empty() || offs.len() > 4 * nt {
            total - at
        } else {
            b.usize_below(2 * ns + 1)
        };
        at = (at + l).min(total);
        offs.push(at as i64);
    }
    let Ok(smp) = Samples::flat(&z, 1) else {
        return;
    };
    let mut st_r = vec![TrackState::default(); offs.len() - 1];
    let mut out_r = vec![0f32; 2 * total];
    let par = b.u8() % 2 == 0;
    filter_ab_f32_tracks(&p, init, &offs, &smp, &mut st_r, &mut out_r, None, par)
        .expect("ragged float32 run failed where the batch ran");
    for (i, w) in offs.windows(2).enumerate() {
        let (lo, hi) = (w[0] as usize, w[1] as usize);
        if hi == lo {
            continue;
        }
        let mut s1 = [TrackState::default()];
        let o = run32(&p, init, &z[lo..hi], 1, hi - lo, &mut s1, false).expect("alone");
        assert!(
            same32(&o[..hi - lo], &out_r[lo..hi])
                && same32(&o[hi - lo..], &out_r[total + lo..total + hi]),
            "float32 ragged: track {i} ({lo}..{hi}) differs from the track alone"
        );
    }
}

fuzz_target!(|data: &[u8]| {
    let mut b = Bytes::new(data);
    let kind = b.u8();
    if kind % 5 == 4 {
        f32_case(&mut b);
        return;
    }
    match kind % 3 {
        0 => {
            // alpha-beta
            let (a, be, t) = ab_params(&mut b);
            let c = case(&mut b);
            let params = [(a, be, t)];
            if std::env::var("FUZZ_DEBUG").is_ok() {
                eprintln!("alpha-beta params {a:e} {be:e} {t:e}");
            }
            let f = |m: &Measurements<'_, f64>, st: &mut [TrackState], o: &mut [f64], par: bool| {
                filter_ab(&params, c.init, m, st, o, None, par, None)
            };
            if let Some(out) = run2(&c, 2, &f) {
                let stable = a > 0.0 && be > 0.0 && 2.0 * a + be < 4.0 - 1e-9;
                if stable && (1e-3..=1e3).contains(&t) && (a * be).is_finite() {
                    check_finite(&c, 2, &out);
                }
            }
        }
        _ => {
            // general n = 3, m = 1
            let t = b.in_range(1e-2, 1e2);
            let mut phi = [[1.0, t, t * t / 2.0], [0.0, 1.0, t], [0.0, 0.0, 1.0]];
            if b.u8() % 4 == 0 {
                for row in phi.iter_mut() {
                    for x in row.iter_mut() {
                        *x = b.f64();
                    }
                }
            }
            let k = [[b.f64()], [b.f64()], [b.f64()]];
            if std::env::var("FUZZ_DEBUG").is_ok() {
                eprintln!("general phi {phi:?} k {k:?} t {t:e}");
            }
            let g = Gains::<3, 1> {
                phi,
                h: [[1.0, 0.0, 0.0]],
                k,
                h_pinv: [[1.0], [0.0], [0.0]],
                t,
            };
            let c = case(&mut b);
            let gains = [g];
            let f = |m: &Measurements<'_, f64>, st: &mut [TrackState], o: &mut [f64], par: bool| {
                filter_general(&gains, c.init, m, st, o, None, par, None)
            };
            let _ = run2(&c, 3, &f);
        }
    }
});
