//! Tests of `filter::f32arith` (alpha-beta in `f32` arithmetic).

use super::super::{filter_ab, Init, Measurements, TrackState};
use super::*;

/// The alpha-beta recursion in `f32`, written here independently: the
/// two-point or first-sample start, then the kernel's arrangement of the
/// step (`x_p = x + T v`, `x = (1 - a) x_p + a z`, `v = (v + g2 z) - g2 x_p`,
/// fused when the kernels fuse), coasting on NaN.
fn reference32(a: f64, b: f64, t: f64, init: Init, z: &[f32]) -> (Vec<f32>, Vec<f32>) {
    let fused = crate::filter::uses_fma();
    let fma = |p: f32, q: f32, r: f32| if fused { p.mul_add(q, r) } else { p * q + r };
    let (t32, a32, c1, g2) = (t as f32, a as f32, (1.0 - a) as f32, (b / t) as f32);
    let n = z.len();
    let (mut xs, mut vs) = (vec![f32::NAN; n], vec![f32::NAN; n]);
    let valid: Vec<usize> = (0..n).filter(|&k| !z[k].is_nan()).collect();
    let Some(&k1) = valid.first() else {
        return (xs, vs);
    };
    let (mut x, mut v, from) = if init == Init::First {
        xs[k1] = z[k1];
        vs[k1] = 0.0;
        (z[k1], 0f32, k1 + 1)
    } else {
        for k in k1..n {
            xs[k] = z[k1];
        }
        let Some(&k2) = valid.get(1) else {
            return (xs, vs);
        };
        let v = (z[k2] - z[k1]) / ((k2 - k1) as f32 * t32);
        xs[k2] = z[k2];
        vs[k2] = v;
        (z[k2], v, k2 + 1)
    };
    for k in from..n {
        let xp = fma(t32, v, x);
        if z[k].is_nan() {
            x = xp;
        } else {
            let w = fma(g2, z[k], v);
            x = fma(c1, xp, a32 * z[k]);
            v = fma(-g2, xp, w);
        }
        xs[k] = x;
        vs[k] = v;
    }
    (xs, vs)
}

/// `n_tracks x n` samples of constant-velocity targets with noise, offset
/// `off`, and NaN at the positions `nan(i, k)` says.
fn data(n_tracks: usize, n: usize, off: f32, nan: impl Fn(usize, usize) -> bool) -> Vec<f32> {
    let mut s = 0x2545_f491_4f6c_dd1du64;
    let mut noise = || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 40) as f32 / (1u64 << 24) as f32 - 0.5
    };
    let mut z = vec![0f32; n_tracks * n];
    for i in 0..n_tracks {
        for k in 0..n {
            z[i * n + k] = if nan(i, k) {
                f32::NAN
            } else {
                off + (1.0 + i as f32 * 0.01) * k as f32 * 0.1 + noise()
            };
        }
    }
    z
}

/// Run `filter_ab_f32` on the whole batch from `st`; the outputs `(x, v)`
/// per track.
#[allow(clippy::too_many_arguments)]
fn run32_from(
    p: &[(f64, f64, f64)],
    init: Init,
    z: &[f32],
    n_tracks: usize,
    n: usize,
    parallel: bool,
    st: &mut [TrackState],
) -> Vec<f32> {
    let meas = Measurements::contiguous(z, n_tracks, n, 1).unwrap();
    let mut out = vec![0f32; 2 * n_tracks * n];
    filter_ab_f32(p, init, &meas, st, &mut out, None, parallel).unwrap();
    out
}

/// [`run32_from`] from fresh states.
fn run32(
    p: &[(f64, f64, f64)],
    init: Init,
    z: &[f32],
    n_tracks: usize,
    n: usize,
    parallel: bool,
) -> Vec<f32> {
    let mut st = vec![TrackState::default(); n_tracks];
    run32_from(p, init, z, n_tracks, n, parallel, &mut st)
}

fn same(a: f32, b: f32) -> bool {
    a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan())
}

/// Every path (vector rows of full groups, scalar groups, single tracks,
/// chunks, threads) equals the independent `f32` recursion bit for bit,
/// with NaN patterns inside and outside the vector blocks, both inits,
/// shared and per-track gains, and rows long enough for streamed outputs.
#[test]
fn f32_paths_match_the_reference_bit_for_bit() {
    // (16, 1024): rows 4 KiB apart (the lanes staggered). (35, 100),
    // (4100, 256), (1600, 700), (17, 64), (33, 17), (40, 3): the short rows
    // straight from the batch (`short_batch`), (4100, 256) and (1600, 700)
    // with streamed outputs through the stages, (33, 17) and (40, 3) all in
    // the column steps.
    let cases: [(usize, usize); 10] = [
        (16, 300),
        (35, 257),
        (16, 70_000),
        (17, 64),
        (16, 1024),
        (35, 100),
        (4100, 256),
        (1600, 700),
        (33, 17),
        (40, 3),
    ];
    for (n_tracks, n) in cases {
        let nan = |i: usize, k: usize| {
            (i % 5 == 1 && k % 97 == 3)
                || (i == 2 && k < 7)
                || (i == 3 && (k == 1 || k == 2))
                || (i == 4 && (100..140).contains(&k))
                || i == 6
        };
        let z = data(n_tracks, n, 1000.0, nan);
        let per: Vec<(f64, f64, f64)> = (0..n_tracks)
            .map(|i| {
                (
                    0.2 + 0.03 * i as f64,
                    0.05 + 0.01 * i as f64,
                    0.1 + 0.001 * i as f64,
                )
            })
            .collect();
        for params in [vec![(0.5, 0.2, 0.1)], per] {
            for init in [Init::TwoPoint, Init::First] {
                let out = run32(&params, init, &z, n_tracks, n, false);
                let par = run32(&params, init, &z, n_tracks, n, true);
                assert!(out.iter().zip(&par).all(|(a, b)| same(*a, *b)));
                // The batch in two chunks of samples, the states carried
                // (each chunk a contiguous batch of its own).
                let h = (n / 2 + 3).min(n - 1);
                let part = |a: usize, b: usize| -> Vec<f32> {
                    (0..n_tracks)
                        .flat_map(|i| z[i * n + a..i * n + b].iter().copied())
                        .collect()
                };
                let mut st = vec![TrackState::default(); n_tracks];
                let o1 = run32_from(&params, init, &part(0, h), n_tracks, h, true, &mut st);
                let o2 = run32_from(&params, init, &part(h, n), n_tracks, n - h, true, &mut st);
                let (m1, m2) = (n_tracks * h, n_tracks * (n - h));
                for i in 0..n_tracks {
                    for (c, base) in [(0, 0), (1, n_tracks * n)] {
                        let got = o1[c * m1 + i * h..c * m1 + (i + 1) * h]
                            .iter()
                            .chain(&o2[c * m2 + i * (n - h)..c * m2 + (i + 1) * (n - h)]);
                        let want = &out[base + i * n..base + (i + 1) * n];
                        assert!(
                            got.zip(want).all(|(a, b)| same(*a, *b)),
                            "{n_tracks}x{n} chunked, track {i}"
                        );
                    }
                }
                for i in 0..n_tracks {
                    let (a, b, t) = params[if params.len() == 1 { 0 } else { i }];
                    let row = &z[i * n..(i + 1) * n];
                    let (rx, rv) = reference32(a, b, t, init, row);
                    let per = n_tracks * n;
                    for k in 0..n {
                        let (x, v) = (out[i * n + k], out[per + i * n + k]);
                        assert!(
                            same(x, rx[k]) && same(v, rv[k]),
                            "{n_tracks}x{n} {init:?} track {i} sample {k}: ({x}, {v}) vs ({}, {})",
                            rx[k],
                            rv[k]
                        );
                    }
                    // The track alone (scalar path), in three chunks.
                    let mut st = [TrackState::default()];
                    let mut got = vec![0f32; 2 * n];
                    let (q1, q2) = (5.min(n), (n / 2).max(5.min(n)));
                    for (c0, c1) in [(0, q1), (q1, q2), (q2, n)] {
                        let meas = Measurements::contiguous(&row[c0..c1], 1, c1 - c0, 1).unwrap();
                        let mut o = vec![0f32; 2 * (c1 - c0)];
                        filter_ab_f32(&[(a, b, t)], init, &meas, &mut st, &mut o, None, false)
                            .unwrap();
                        got[c0..c1].copy_from_slice(&o[..c1 - c0]);
                        got[n + c0..n + c1].copy_from_slice(&o[c1 - c0..]);
                    }
                    for k in 0..n {
                        assert!(same(got[k], rx[k]) && same(got[n + k], rv[k]));
                    }
                }
            }
        }
    }
}

/// Residuals (scalar path) and a non-contiguous batch (every other sample
/// of a wider array) agree with the reference too.
#[test]
fn f32_residuals_and_strided_input() {
    let (n_tracks, n) = (16, 400);
    let z = data(n_tracks, 2 * n, -50.0, |i, k| k % 61 == i);
    let (a, b, t) = (0.3, 0.05, 0.5);
    let meas = Measurements {
        data: &z,
        base: 0,
        s_track: (2 * n) as isize,
        s_sample: 2,
        s_comp: 1,
        n_tracks,
        n_samples: n,
        m: 1,
    };
    let mut st = vec![TrackState::default(); n_tracks];
    let mut out = vec![0f32; 2 * n_tracks * n];
    let mut res = vec![0f32; n_tracks * n];
    filter_ab_f32(
        &[(a, b, t)],
        Init::TwoPoint,
        &meas,
        &mut st,
        &mut out,
        Some(&mut res),
        true,
    )
    .unwrap();
    for i in 0..n_tracks {
        let row: Vec<f32> = (0..n).map(|k| z[i * 2 * n + 2 * k]).collect();
        let (rx, rv) = reference32(a, b, t, Init::TwoPoint, &row);
        for k in 0..n {
            assert!(same(out[i * n + k], rx[k]) && same(out[n_tracks * n + i * n + k], rv[k]));
            // The residual of a running step is z minus the prediction from
            // the previous estimates.
            if k >= 2 && !rx[k - 1].is_nan() && !rv[k - 1].is_nan() {
                let xp = if crate::filter::uses_fma() {
                    (t as f32).mul_add(rv[k - 1], rx[k - 1])
                } else {
                    t as f32 * rv[k - 1] + rx[k - 1]
                };
                assert!(same(res[i * n + k], row[k] - xp), "track {i} sample {k}");
            }
        }
    }
}

/// Against the `f64`-arithmetic kernel on the same `f32` data: within
/// `8 (1 + 1 / alpha)` `f32` epsilons of the array's scale for positions
/// (and of scale / T for velocities), over gains from tiny to large alpha
/// and offsets up to 1e5 (the measured drift is about 0.3 / alpha
/// epsilons, bench/f32_arith_accuracy.py).
#[test]
fn f32_arithmetic_stays_within_its_bound_of_f64() {
    let (n_tracks, n) = (16, 20_000);
    for off in [0f32, 1e3, 1e5] {
        let z = data(n_tracks, n, off, |i, k| (k + i) % 211 == 0);
        let scale = z
            .iter()
            .filter(|v| !v.is_nan())
            .fold(0f32, |m, v| m.max(v.abs())) as f64;
        for (a, b, t) in [
            (0.0045, 1.0e-5, 0.1),
            (0.05, 1.3e-3, 1.0),
            (0.5, 0.2, 0.1),
            (1.2, 0.9, 2.0),
        ] {
            let o32 = run32(&[(a, b, t)], Init::TwoPoint, &z, n_tracks, n, false);
            let meas = Measurements::contiguous(&z, n_tracks, n, 1).unwrap();
            let mut st = vec![TrackState::default(); n_tracks];
            let mut o64 = vec![0f32; 2 * n_tracks * n];
            filter_ab(
                &[(a, b, t)],
                Init::TwoPoint,
                &meas,
                &mut st,
                &mut o64,
                None,
                false,
                None,
            )
            .unwrap();
            let tol = 8.0 * f32::EPSILON as f64 * (1.0 + 1.0 / a) * scale;
            let per = n_tracks * n;
            for j in 0..2 * per {
                let (p, q) = (o32[j] as f64, o64[j] as f64);
                assert_eq!(p.is_nan(), q.is_nan(), "NaN pattern at {j}");
                let tol = if j < per { tol } else { tol / t };
                assert!(
                    p.is_nan() || (p - q).abs() <= tol,
                    "alpha {a} offset {off} at {j}: {p} vs {q} (tolerance {tol:.3e})"
                );
            }
        }
    }
}

/// Bad arguments are errors, as for the `f64` kernel.
#[test]
fn f32_bad_arguments() {
    let z = vec![1f32; 10];
    let meas = Measurements::contiguous(&z, 1, 10, 1).unwrap();
    let mut st = vec![TrackState::default(); 1];
    let mut out = vec![0f32; 20];
    // NaN/Inf gains, T <= 0, and values beyond float32's range (T = 1e39
    // rounds to infinity, 1e-50 to zero, alpha = 1e39 to infinity, beta / T
    // = 1e40 to infinity).
    for p in [
        (f64::NAN, 0.1, 1.0),
        (0.5, f64::INFINITY, 1.0),
        (0.5, 0.1, 0.0),
        (0.5, 0.1, 1e39),
        (0.5, 0.1, 1e-50),
        (1e39, 0.1, 1.0),
        (0.5, 1e30, 1e-10),
    ] {
        assert!(
            filter_ab_f32(&[p], Init::TwoPoint, &meas, &mut st, &mut out, None, false).is_err()
        );
    }
    let mut short = vec![0f32; 19];
    assert!(filter_ab_f32(
        &[(0.5, 0.1, 1.0)],
        Init::TwoPoint,
        &meas,
        &mut st,
        &mut short,
        None,
        false
    )
    .is_err());
}

/// A single long track is split into segments (pass 1 in the vector lanes,
/// pass 2 corrections): within float32 rounding of the unsplit recursion
/// (both within the drift bound of float64), NaN runs across segment
/// boundaries included; a split chunk continues from the true state.
#[test]
fn f32_split_track_agrees_with_the_recursion() {
    let n = (1 << 18) + 123;
    for (a, b, t) in [(0.5, 0.2, 0.1), (0.05, 1.3e-3, 1.0)] {
        let Some(ls) = crate::filter::split_seg_len(a, b, n - 2) else {
            panic!("alpha {a}: not split");
        };
        // NaN runs across every segment boundary, and at the start of one.
        let z = data(1, n, 1e3, |_, k| {
            let j = k.saturating_sub(2) % ls;
            j < 3 || j + 2 >= ls || (7 * ls..7 * ls + 40).contains(&k)
        });
        let scale = z
            .iter()
            .filter(|v| !v.is_nan())
            .fold(0f32, |m, v| m.max(v.abs())) as f64;
        let (rx, rv) = reference32(a, b, t, Init::TwoPoint, &z);
        let out = run32(&[(a, b, t)], Init::TwoPoint, &z, 1, n, false);
        let tol = 4.0 * f32::EPSILON as f64 * (1.0 + 1.0 / a) * scale;
        let mut differs = false;
        for k in 0..n {
            let (x, v) = (out[k] as f64, out[n + k] as f64);
            assert_eq!(x.is_nan(), rx[k].is_nan(), "x NaN at {k}");
            assert_eq!(v.is_nan(), rv[k].is_nan(), "v NaN at {k}");
            if !x.is_nan() {
                assert!(
                    (x - rx[k] as f64).abs() <= tol,
                    "alpha {a} x at {k}: {x} vs {}",
                    rx[k]
                );
                differs |= x.to_bits() != (rx[k] as f64).to_bits();
            }
            if !v.is_nan() {
                assert!(
                    (v - rv[k] as f64).abs() <= tol / t,
                    "alpha {a} v at {k}: {v} vs {}",
                    rv[k]
                );
            }
        }
        // The split ran (its rounding differs from the recursion somewhere).
        assert!(
            differs,
            "alpha {a}: bit-identical, so the split did not run"
        );
        // In two chunks: the second continues from the first's state.
        let mut st = [TrackState::default()];
        let h = n / 2;
        let mut got = vec![0f32; 2 * n];
        for (c0, c1) in [(0, h), (h, n)] {
            let meas = Measurements::contiguous(&z[c0..c1], 1, c1 - c0, 1).unwrap();
            let mut o = vec![0f32; 2 * (c1 - c0)];
            filter_ab_f32(
                &[(a, b, t)],
                Init::TwoPoint,
                &meas,
                &mut st,
                &mut o,
                None,
                true,
            )
            .unwrap();
            got[c0..c1].copy_from_slice(&o[..c1 - c0]);
            got[n + c0..n + c1].copy_from_slice(&o[c1 - c0..]);
        }
        for k in 0..n {
            let (x, v) = (got[k] as f64, got[n + k] as f64);
            assert!(
                x.is_nan() == rx[k].is_nan() && (x.is_nan() || (x - rx[k] as f64).abs() <= tol)
            );
            assert!(
                v.is_nan() == rv[k].is_nan() && (v.is_nan() || (v - rv[k] as f64).abs() <= tol / t)
            );
        }
    }
}

/// A ragged batch (`filter_ab_f32_tracks`) gives each track the bits of
/// that track alone through `filter_ab_f32`, states included: mixed lengths
/// (empty, one and two samples, rows too short for a block, a split track
/// of 2 x 2^16 + samples: split in both calls), NaN starts and gaps, all-NaN tracks, shared and
/// per-track gains, both inits, strided measurements, residuals, one
/// thread or the pool, and a second call continuing the states.
#[test]
fn ragged_tracks_equal_each_track_alone() {
    use crate::ragged::Samples;
    let mut lens: Vec<usize> = vec![0, 1, 2, 3, 17, 15, 16, 31, 100, 333, 1000, 140_000, 0, 5];
    let mut s = 7u64;
    for _ in 0..200 {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        // log-uniform 10..4,000
        lens.push((10.0 * 400f64.powf((s >> 11) as f64 / (1u64 << 53) as f64)) as usize);
    }
    let total: usize = lens.iter().sum();
    let mut offsets = vec![0i64];
    for &l in &lens {
        offsets.push(offsets.last().copied().unwrap_or(0) + l as i64);
    }
    let n_tracks = lens.len();
    let z = data(1, total, 3.0, |_, k| k % 97 == 5 || (k * 7) % 1009 < 3);
    let mut z = z;
    // An all-NaN track and a track starting late.
    let (a3, b3) = (offsets[4] as usize, offsets[5] as usize);
    z[a3..b3].fill(f32::NAN);
    let a9 = offsets[9] as usize;
    z[a9..a9 + 40].fill(f32::NAN);
    let per_track: Vec<(f64, f64, f64)> = (0..n_tracks)
        .map(|i| (0.3 + 0.002 * i as f64, 0.05 + 0.0005 * i as f64, 0.1))
        .collect();
    let shared = [(0.5, 0.2, 0.25)];
    for params in [&shared[..], &per_track[..]] {
        for init in [Init::TwoPoint, Init::First] {
            for (strided, resid, parallel) in [
                (false, false, false),
                (false, false, true),
                (true, false, false),
                (false, true, true),
            ] {
                // Strided: every other element of a buffer twice as long.
                let spread = |v: &[f32]| -> Vec<f32> {
                    if strided {
                        v.iter().flat_map(|&x| [x, -1.0]).collect()
                    } else {
                        v.to_vec()
                    }
                };
                let stride = if strided { 2 } else { 1 };
                // Two calls: the first half of every track, then the rest.
                let half: Vec<usize> = lens.iter().map(|&l| l / 2).collect();
                let part_of = |i: usize, part: usize| {
                    if part == 0 {
                        (0, half[i])
                    } else {
                        (half[i], lens[i])
                    }
                };
                let mut st = vec![TrackState::default(); n_tracks];
                let mut got = vec![Vec::new(); 2];
                let mut got_r = vec![Vec::new(); 2];
                let mut chunk_off: Vec<Vec<i64>> = vec![vec![0i64]; 2];
                for part in 0..2 {
                    let off = &mut chunk_off[part];
                    let mut cz: Vec<f32> = Vec::new();
                    for i in 0..n_tracks {
                        let (a, b) = part_of(i, part);
                        let o = offsets[i] as usize;
                        cz.extend_from_slice(&z[o + a..o + b]);
                        off.push(off.last().copied().unwrap_or(0) + (b - a) as i64);
                    }
                    let n = cz.len();
                    let buf = spread(&cz);
                    let smp = Samples {
                        data: &buf,
                        base: 0,
                        s_row: 0,
                        s_sample: stride,
                        s_comp: 1,
                        row_len: n,
                        n_rows: 1,
                        m: 1,
                    };
                    let mut out = vec![0f32; 2 * n];
                    let mut r = vec![0f32; n];
                    filter_ab_f32_tracks(
                        params,
                        init,
                        off,
                        &smp,
                        &mut st,
                        &mut out,
                        resid.then_some(&mut r[..]),
                        parallel,
                    )
                    .unwrap();
                    got[part] = out;
                    got_r[part] = r;
                }
                // Alone: each track through the rectangular kernel, in the
                // same two chunks and the same layout (strided rows are not
                // split there either).
                for i in 0..n_tracks {
                    let p = [params[if params.len() == 1 { 0 } else { i }]];
                    let mut st1 = [TrackState::default()];
                    let o = offsets[i] as usize;
                    for part in 0..2 {
                        let (a, b) = part_of(i, part);
                        let n = b - a;
                        let zt = spread(&z[o + a..o + b]);
                        let meas = Measurements {
                            data: &zt,
                            base: 0,
                            s_track: stride * n as isize,
                            s_sample: stride,
                            s_comp: 1,
                            n_tracks: 1,
                            n_samples: n,
                            m: 1,
                        };
                        let mut out = vec![0f32; 2 * n];
                        let mut r = vec![0f32; n];
                        if n > 0 {
                            filter_ab_f32(
                                &p,
                                init,
                                &meas,
                                &mut st1,
                                &mut out,
                                resid.then_some(&mut r[..]),
                                false,
                            )
                            .unwrap();
                        }
                        // This track's place in the chunk's flat layout.
                        let before = chunk_off[part][i] as usize;
                        let nc = got_r[part].len();
                        for k in 0..n {
                            let g = &got[part];
                            assert!(
                                same(g[before + k], out[k]) && same(g[nc + before + k], out[n + k]),
                                "track {i} (len {}) part {part} sample {k}: {:?} vs {:?} \
                                 (strided {strided}, resid {resid}, {} params, {init:?})",
                                lens[i],
                                (g[before + k], g[nc + before + k]),
                                (out[k], out[n + k]),
                                params.len()
                            );
                            if resid {
                                assert!(same(got_r[part][before + k], r[k]), "residual {i} {k}");
                            }
                        }
                    }
                    assert_eq!(st[i].phase, st1[0].phase, "track {i}");
                    assert!(
                        same(st[i].x[0] as f32, st1[0].x[0] as f32)
                            && same(st[i].x[1] as f32, st1[0].x[1] as f32),
                        "state of track {i}"
                    );
                }
            }
        }
    }
}
