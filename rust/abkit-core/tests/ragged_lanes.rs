//! The vector lanes of the irregular-timestamp alpha-beta track kernel
//! (`ragged_simd`; used on CPUs with AVX-512F or AVX2 + FMA): a batch of
//! tracks must give, per track, the same bits as that track run alone (one
//! track runs in the scalar lane code), with both gain laws, `f32`/`f64`,
//! NaN measurements, `max_gap` restarts, dropped duplicates and residuals;
//! and match an independent plain loop (Kalata's tracking-index formula,
//! no FMA) within 1e-9 relative to each track's scale.

use abkit_core::filter::{Init, IoFloat, TrackState};
use abkit_core::irregular::{AbDesign, AbFixed, GainLaw};
use abkit_core::ragged::{filter_tracks, Counts, NoPost, Options, Samples, TrackFilter};

/// Deterministic uniform numbers in [0, 1) (64-bit LCG, top 53 bits).
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

struct Data {
    z: Vec<f64>,
    t: Vec<f64>,
    off: Vec<i64>,
}

fn data(seed: u64, lens: &[usize], wide: bool, dup: f64, gap: f64, nan: f64) -> Data {
    let mut r = Lcg(seed);
    let mut off = vec![0i64];
    let (mut z, mut t) = (Vec::new(), Vec::new());
    for &n in lens {
        let mut tk = 200.0 * r.next() - 100.0;
        let t0 = tk;
        for _ in 0..n {
            let u = r.next();
            let dt = if u < dup {
                0.0
            } else if u < dup + gap {
                50.0
            } else if wide {
                10f64.powf(-2.0 + 3.5 * r.next())
            } else {
                0.05 + 0.1 * r.next()
            };
            tk += dt;
            t.push(tk);
            let s = tk - t0;
            let noise = r.next() - 0.5;
            z.push(if r.next() < nan {
                f64::NAN
            } else {
                5.0 + 2.0 * s + 0.01 * s * s + noise
            });
        }
        off.push(off.last().copied().unwrap_or(0) + n as i64);
    }
    Data { z, t, off }
}

struct Out<T> {
    states: Vec<T>,
    resid: Vec<T>,
    st: Vec<TrackState>,
    counts: Vec<Counts>,
}

fn run<T: IoFloat, L: GainLaw<2, 1>>(
    laws: &[L],
    o: &Options,
    z: &[T],
    t: &[f64],
    off: &[i64],
    resid: bool,
) -> Out<T> {
    let f = TrackFilter {
        laws,
        h: [[1.0, 0.0]],
        h_pinv: [[1.0], [0.0]],
    };
    let n_tracks = off.len() - 1;
    let mut st = vec![TrackState::default(); n_tracks];
    let mut counts = vec![[0i64; 2]; n_tracks];
    let mut states = vec![T::from_f64(0.0); 2 * z.len()];
    let mut res = vec![T::from_f64(0.0); if resid { z.len() } else { 0 }];
    let zs = Samples::flat(z, 1).unwrap();
    let ts = Samples::flat(t, 1).unwrap();
    filter_tracks(
        &f,
        o,
        off,
        &zs,
        Some(&ts),
        &mut st,
        &mut states,
        if resid { Some(&mut res[..]) } else { None },
        &mut counts,
        false,
        &NoPost,
    )
    .unwrap();
    Out {
        states,
        resid: res,
        st,
        counts,
    }
}

fn same(a: f64, b: f64) -> bool {
    a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan())
}

/// Batch vs each track alone, bit for bit.
fn check_alone<T: IoFloat, L: GainLaw<2, 1>>(laws: &[L], d: &Data, o: &Options, resid: bool) {
    let z: Vec<T> = d.z.iter().map(|&v| T::from_f64(v)).collect();
    let n = z.len();
    let all = run(laws, o, &z, &d.t, &d.off, resid);
    for i in 0..d.off.len() - 1 {
        let (a, b) = (d.off[i] as usize, d.off[i + 1] as usize);
        let law = &laws[if laws.len() == 1 { 0 } else { i }..][..1];
        let one = run(law, o, &z[a..b], &d.t[a..b], &[0, (b - a) as i64], resid);
        let m = b - a;
        for k in 0..m {
            for c in 0..2 {
                let (p, q) = (
                    all.states[c * n + a + k].to_f64(),
                    one.states[c * m + k].to_f64(),
                );
                assert!(same(p, q), "track {i} sample {k} comp {c}: {p} vs {q}");
            }
            if resid {
                let (p, q) = (all.resid[a + k].to_f64(), one.resid[k].to_f64());
                assert!(same(p, q), "track {i} sample {k} residual: {p} vs {q}");
            }
        }
        for c in 0..2 {
            assert!(same(all.st[i].x[c], one.st[0].x[c]), "track {i} state");
        }
        assert!(same(all.st[i].t_last, one.st[0].t_last));
        assert_eq!(all.counts[i], one.counts[0], "track {i} counts");
    }
}

fn opts(max_gap: Option<f64>, drop: bool, init: Init) -> Options {
    Options {
        init,
        t_nominal: 0.1,
        max_gap,
        drop_duplicates: drop,
    }
}

fn lens() -> Vec<usize> {
    let mut l: Vec<usize> = (0..=40).collect();
    l.extend([3000, 7, 2500, 0, 1, 2048, 999, 1500, 33, 1200, 4096, 513]);
    l
}

#[test]
fn design_law_batch_equals_tracks_alone() {
    for (seed, wide) in [(1, true), (2, false)] {
        let d = data(seed, &lens(), wide, 0.0, 0.0, 0.1);
        let laws = [AbDesign::new(0.1)];
        check_alone::<f64, _>(&laws, &d, &opts(None, false, Init::TwoPoint), true);
        check_alone::<f64, _>(&laws, &d, &opts(None, false, Init::TwoPoint), false);
        check_alone::<f32, _>(&laws, &d, &opts(None, false, Init::First), true);
    }
}

#[test]
fn fixed_law_batch_equals_tracks_alone() {
    let d = data(3, &lens(), true, 0.0, 0.0, 0.1);
    let laws = [AbFixed {
        alpha: 0.45,
        beta: 0.12,
    }];
    check_alone::<f64, _>(&laws, &d, &opts(None, false, Init::TwoPoint), true);
    check_alone::<f32, _>(&laws, &d, &opts(None, false, Init::TwoPoint), false);
}

#[test]
fn gaps_drops_and_per_track_laws_equal_tracks_alone() {
    let l = lens();
    let d = data(4, &l, true, 0.01, 0.01, 0.3);
    let mut r = Lcg(77);
    let design: Vec<AbDesign> = l.iter().map(|_| AbDesign::new(0.01 + r.next())).collect();
    let fixed: Vec<AbFixed> = l
        .iter()
        .map(|_| AbFixed {
            alpha: 0.2 + 0.6 * r.next(),
            beta: 0.02 + 0.3 * r.next(),
        })
        .collect();
    let o = opts(Some(20.0), true, Init::TwoPoint);
    check_alone::<f64, _>(&design, &d, &o, true);
    check_alone::<f64, _>(&fixed, &d, &o, true);
    check_alone::<f32, _>(&design, &d, &opts(Some(20.0), true, Init::First), false);
}

/// Kalata's closed form of the steady-state gains from the tracking index
/// (independent of the kernel's cancellation-free form).
fn kalata(lambda: f64) -> (f64, f64) {
    let s = (lambda * lambda + 8.0 * lambda).sqrt();
    let alpha = -(lambda * lambda + 8.0 * lambda - (lambda + 4.0) * s) / 8.0;
    let beta = (lambda * lambda + 4.0 * lambda - lambda * s) / 4.0;
    (alpha, beta)
}

#[test]
fn batch_matches_plain_reference_loop() {
    let l = [700usize, 3, 1000, 64, 400, 900, 17, 1200, 800];
    let d = data(5, &l, true, 0.0, 0.0, 0.1);
    let ratio = 0.1;
    let laws = [AbDesign::new(ratio)];
    let o = opts(None, false, Init::TwoPoint);
    let out = run(&laws, &o, &d.z, &d.t, &d.off, false);
    let n = d.z.len();
    for i in 0..l.len() {
        let (a, b) = (d.off[i] as usize, d.off[i + 1] as usize);
        // plain loop: two-point start, then predict / update (NaN coasts)
        let mut phase = 0;
        let (mut x, mut v, mut held, mut th, mut tl) = (0.0, 0.0, 0.0, 0.0, 0.0);
        let scale = d.z[a..b]
            .iter()
            .filter(|z| !z.is_nan())
            .fold(1.0f64, |m, z| m.max(z.abs()));
        for k in a..b {
            let (zk, tk) = (d.z[k], d.t[k]);
            if phase == 2 {
                let dt = tk - tl;
                let (al, be) = kalata(ratio * dt * dt);
                let xp = x + dt * v;
                if zk.is_nan() {
                    x = xp;
                } else {
                    let e = zk - xp;
                    x = xp + al * e;
                    v += be / dt * e;
                }
            } else if !zk.is_nan() {
                if phase == 0 {
                    (held, th, phase) = (zk, tk, 1);
                } else {
                    v = (zk - held) / (tk - th);
                    x = zk;
                    phase = 2;
                }
            }
            tl = tk;
            if phase == 2 {
                let (px, pv) = (out.states[k], out.states[n + k]);
                assert!(
                    (px - x).abs() <= 1e-9 * scale,
                    "track {i} sample {k}: {px} vs {x}"
                );
                assert!(
                    (pv - v).abs() <= 1e-9 * scale,
                    "track {i} sample {k}: {pv} vs {v}"
                );
            }
        }
    }
}
