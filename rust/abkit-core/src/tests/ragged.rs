use super::*;
use crate::irregular::{AbDesign, AbFixed, AbgDesign, AbgFixed};

fn ab_filter(laws: &[AbDesign]) -> TrackFilter<'_, AbDesign, 2, 1> {
    TrackFilter {
        laws,
        h: [[1.0, 0.0]],
        h_pinv: [[1.0], [0.0]],
    }
}

fn opts(init: Init, max_gap: Option<f64>, drop: bool) -> Options {
    Options {
        init,
        t_nominal: 1.0,
        max_gap,
        drop_duplicates: drop,
    }
}

struct Run {
    out: Vec<f64>,
    counts: Vec<Counts>,
    states: Vec<TrackState>,
}

fn run(offsets: &[i64], z: &[f64], t: Option<&[f64]>, o: &Options, parallel: bool) -> Result<Run> {
    let laws = [AbDesign::new(0.3)];
    let f = ab_filter(&laws);
    let n_tracks = offsets.len().saturating_sub(1);
    let mut states = vec![TrackState::default(); n_tracks];
    let mut counts = vec![[0i64; 2]; n_tracks];
    let mut out = vec![0.0; 2 * z.len()];
    let zs = Samples::flat(z, 1)?;
    let ts = t.map(|t| Samples::flat(t, 1)).transpose()?;
    filter_tracks(
        &f,
        o,
        offsets,
        &zs,
        ts.as_ref(),
        &mut states,
        &mut out,
        None,
        &mut counts,
        parallel,
        &NoPost,
    )?;
    Ok(Run {
        out,
        counts,
        states,
    })
}

#[test]
fn constant_velocity_is_tracked_exactly_with_irregular_times() {
    let t: Vec<f64> = (0..200)
        .map(|k| k as f64 + 0.5 * ((k * 7919) % 13) as f64 / 13.0)
        .collect();
    let z: Vec<f64> = t.iter().map(|&t| 3.0 - 2.5 * t).collect();
    let r = run(
        &[0, 200],
        &z,
        Some(&t),
        &opts(Init::TwoPoint, None, false),
        false,
    )
    .unwrap();
    for k in 1..200 {
        assert!(
            (r.out[k] - z[k]).abs() < 1e-9 * z[k].abs().max(1.0),
            "k={k}"
        );
        assert!(
            (r.out[200 + k] + 2.5).abs() < 1e-9,
            "k={k}: {}",
            r.out[200 + k]
        );
    }
    assert_eq!(r.states[0].t_last, t[199]);
}

#[test]
fn ragged_equals_each_track_alone_and_any_blocking() {
    let lens = [0usize, 5, 1, 40_000, 3, 17];
    let mut offsets = vec![0i64];
    for l in lens {
        offsets.push(offsets.last().unwrap() + l as i64);
    }
    let n = *offsets.last().unwrap() as usize;
    let z: Vec<f64> = (0..n)
        .map(|g| ((g * 37) % 101) as f64 * 0.1 + if g % 9 == 0 { f64::NAN } else { 0.0 })
        .collect();
    let t: Vec<f64> = (0..n)
        .map(|g| g as f64 * 0.25 + ((g * 13) % 7) as f64 * 0.01)
        .collect();
    let o = opts(Init::TwoPoint, Some(2.0), false);
    assert_each_track_alone(&offsets, &z, &t, &o, true);
}

/// The batch (in parallel or not) gives each track the bits of the track
/// run alone.
fn assert_each_track_alone(offsets: &[i64], z: &[f64], t: &[f64], o: &Options, parallel: bool) {
    let n = z.len();
    let all = run(offsets, z, Some(t), o, parallel).unwrap();
    for i in 0..offsets.len() - 1 {
        let (a, b) = (offsets[i] as usize, offsets[i + 1] as usize);
        let one = run(&[0, (b - a) as i64], &z[a..b], Some(&t[a..b]), o, false).unwrap();
        for k in 0..b - a {
            for c in 0..2 {
                let (u, v) = (all.out[c * n + a + k], one.out[c * (b - a) + k]);
                assert!(
                    u.to_bits() == v.to_bits(),
                    "track {i} sample {k}: {u} vs {v}"
                );
            }
        }
    }
}

/// Timestamps on a grid (whole seconds, every 37th report missed): the
/// vector lanes reuse the design law's gains while every slot's dt repeats.
/// Grid tracks mixed with irregular ones (blocks where only some slots
/// repeat), missed measurements: bit-identical to each track alone (the
/// scalar code, which computes the gains at every step).
#[test]
fn grid_timestamps_equal_each_track_alone() {
    let lens = [3000usize, 2500, 17, 2048, 999, 1500, 1200, 700, 64, 1];
    let mut offsets = vec![0i64];
    for l in lens {
        offsets.push(offsets.last().unwrap() + l as i64);
    }
    let n = *offsets.last().unwrap() as usize;
    let mut t = vec![0.0; n];
    for i in 0..lens.len() {
        let (a, b) = (offsets[i] as usize, offsets[i + 1] as usize);
        let mut tk = (i * 100) as f64;
        for (k, tv) in t[a..b].iter_mut().enumerate() {
            tk += if i % 3 == 2 {
                0.5 + ((k * 7919) % 101) as f64 / 101.0
            } else if (a + k) % 37 == 0 {
                2.0
            } else {
                1.0
            };
            *tv = tk;
        }
    }
    let z: Vec<f64> = (0..n)
        .map(|g| {
            t[g] * 2.0 + ((g * 37) % 101) as f64 * 0.1 + if g % 23 == 0 { f64::NAN } else { 0.0 }
        })
        .collect();
    assert_each_track_alone(&offsets, &z, &t, &opts(Init::TwoPoint, None, false), false);
}

#[test]
fn duplicates_raise_with_track_and_sample_or_are_dropped() {
    let z = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0];
    let t = [0.0, 1.0, 2.0, 0.0, 1.0, 1.0];
    let e = run(
        &[0, 3, 6],
        &z,
        Some(&t),
        &opts(Init::First, None, false),
        false,
    )
    .err()
    .unwrap();
    assert_eq!(
        e,
        Error::Data {
            track: 1,
            sample: 2,
            msg: "t=1 not after t=1 (use on_duplicate='drop' to drop such samples)".into()
        }
    );
    let r = run(
        &[0, 3, 6],
        &z,
        Some(&t),
        &opts(Init::First, None, true),
        false,
    )
    .unwrap();
    assert_eq!(r.counts, vec![[0, 0], [1, 0]]);
    assert!(r.out[5].is_nan() && r.out[6 + 5].is_nan());
    assert_eq!(r.states[1].t_last, 1.0);
}

#[test]
fn nan_timestamps_are_errors() {
    let e = run(
        &[0, 2],
        &[1.0, 2.0],
        Some(&[0.0, f64::NAN]),
        &opts(Init::First, None, false),
        false,
    )
    .err()
    .unwrap();
    assert!(matches!(
        e,
        Error::Data {
            track: 0,
            sample: 1,
            ..
        }
    ));
}

#[test]
fn max_gap_restarts_and_counts() {
    let z = [0.0, 1.0, 2.0, 100.0, 101.0, 102.0];
    let t = [0.0, 1.0, 2.0, 10.0, 11.0, 12.0];
    let r = run(
        &[0, 6],
        &z,
        Some(&t),
        &opts(Init::TwoPoint, Some(5.0), false),
        false,
    )
    .unwrap();
    assert_eq!(r.counts, vec![[0, 1]]);
    // Restarted: position held at 100 with velocity NaN, then two-point.
    assert_eq!(r.out[3], 100.0);
    assert!(r.out[6 + 3].is_nan());
    assert_eq!(r.out[6 + 4], 1.0);
}

#[test]
fn bad_offsets_are_shape_errors() {
    let z = [1.0, 2.0, 3.0];
    for off in [&[1i64, 3][..], &[0, 2, 1, 3], &[0, 2], &[]] {
        assert!(
            matches!(
                run(off, &z, None, &opts(Init::First, None, false), false),
                Err(Error::Shape(_))
            ),
            "{off:?}"
        );
    }
}

#[test]
fn fixed_gain_law_without_times_is_the_plain_filter() {
    let laws = [AbFixed {
        alpha: 0.5,
        beta: 0.2,
    }];
    let f = TrackFilter {
        laws: &laws,
        h: [[1.0, 0.0]],
        h_pinv: [[1.0], [0.0]],
    };
    let z = [1.0, 2.0, 4.0, f64::NAN, 5.0];
    let mut st = vec![TrackState::default()];
    let mut counts = vec![[0; 2]];
    let mut out = vec![0.0; 10];
    let o = Options {
        init: Init::First,
        t_nominal: 2.0,
        max_gap: None,
        drop_duplicates: false,
    };
    filter_tracks(
        &f,
        &o,
        &[0, 5],
        &Samples::flat(&z, 1).unwrap(),
        None,
        &mut st,
        &mut out,
        None,
        &mut counts,
        false,
        &NoPost,
    )
    .unwrap();
    // Hand recursion: x=1, v=0; then xp = x + 2v, x = xp + .5 e, v += .1 e.
    let (mut x, mut v) = (1.0, 0.0);
    for k in 1..5 {
        let xp = x + 2.0 * v;
        if z[k].is_nan() {
            x = xp;
        } else {
            let e = z[k] - xp;
            x = xp + 0.5 * e;
            v += 0.1 * e;
        }
        assert!((out[k] - x).abs() < 1e-14 && (out[5 + k] - v).abs() < 1e-14);
    }
}

fn first_error(law: &[AbgFixed], t: &[f64]) -> Error {
    let f = TrackFilter {
        laws: law,
        h: [[1.0, 0.0, 0.0]],
        h_pinv: [[1.0], [0.0], [0.0]],
    };
    let z = vec![1.0; t.len()];
    let mut st = vec![TrackState::default()];
    let mut counts = vec![[0; 2]];
    let mut out = vec![0.0; 3 * z.len()];
    let o = opts(Init::First, None, false);
    let ts = Samples::flat(t, 1).unwrap();
    filter_tracks(
        &f,
        &o,
        &[0, t.len() as i64],
        &Samples::flat(&z, 1).unwrap(),
        Some(&ts),
        &mut st,
        &mut out,
        None,
        &mut counts,
        false,
        &NoPost,
    )
    .err()
    .unwrap()
}

#[test]
fn steps_whose_gains_overflow_are_errors_naming_t() {
    // gamma / dt^2 overflows at dt = 1e-200: an error at that sample, not Inf estimates
    let law = [AbgFixed {
        alpha: 0.5,
        beta: 0.2,
        cgamma: 0.02,
    }];
    match first_error(&law, &[0.0, 1e-200]) {
        Error::Data { track, sample, msg } => {
            assert_eq!((track, sample), (0, 1));
            assert!(msg.starts_with("t: the step dt="), "{msg}");
        }
        e => panic!("{e:?}"),
    }
}

#[test]
fn steps_without_a_design_are_errors_naming_t() {
    // sigma_a h^4 / sigma_m underflows at h = 1e-300: the design has no gains there
    let laws = [AbgDesign::new(0.0, 0.0, 0.1, 1.0).unwrap()];
    let f = TrackFilter {
        laws: &laws,
        h: [[1.0, 0.0, 0.0]],
        h_pinv: [[1.0], [0.0], [0.0]],
    };
    let t = [0.0, 1e-300];
    let z = [1.0, 2.0];
    let mut st = vec![TrackState::default()];
    let mut counts = vec![[0; 2]];
    let mut out = vec![0.0; 6];
    let ts = Samples::flat(&t, 1).unwrap();
    let e = filter_tracks(
        &f,
        &opts(Init::First, None, false),
        &[0, 2],
        &Samples::flat(&z, 1).unwrap(),
        Some(&ts),
        &mut st,
        &mut out,
        None,
        &mut counts,
        false,
        &NoPost,
    )
    .err()
    .unwrap();
    match e {
        Error::Data { track, sample, msg } => {
            assert_eq!((track, sample), (0, 1));
            assert!(msg.starts_with("t: no gains for the step dt="), "{msg}");
        }
        e => panic!("{e:?}"),
    }
}

#[test]
fn smoothing_steps_whose_backward_gain_overflows_are_errors_naming_t() {
    let back = [crate::irregular::AbBackward::Design(0.3)];
    let post = AbSmooth {
        back: &back,
        t_nominal: 1.0,
        lag: None,
    };
    let mut x = [0.0, 1.0];
    let mut v = [0.0, 1.0];
    let t = [0.0, 1e-300];
    let tf = |k: usize| t[k];
    let e = PostTrack::<f64, 2>::post(&post, 0, &mut [&mut x[..], &mut v[..]], Some(&tf), None)
        .err()
        .unwrap();
    assert!(matches!(e, Error::Domain { name: "t", .. }), "{e:?}");
}

#[test]
fn kin3_smoother_errors_name_the_track_and_sample() {
    let back = [crate::irregular::Kin3Backward::Singer {
        tau: 20.0,
        q: 0.1,
        sigma_pos: 2.0,
    }];
    let post = Kin3Smooth {
        back: &back,
        t_nominal: 1.0,
        lag: None,
    };
    let ts = [0.0, 1.0, 2.0, 2.0 + 1e-70, 3.0];
    let mut x = vec![0.0, 1.0, 2.0, 3.0, 4.0];
    let mut v = vec![1.0; 5];
    let mut a = vec![0.0; 5];
    let tf = |k: usize| ts[k];
    let mut st: [&mut [f64]; 3] = [&mut x, &mut v, &mut a];
    // The backward pass reaches the step 2 -> 3 (dt = 1e-70: q dt^5 underflows).
    match PostTrack::<f64, 3>::post(&post, 7, &mut st, Some(&tf), None) {
        Err(Error::Data { track, sample, msg }) => {
            assert_eq!((track, sample), (7, 3));
            assert!(msg.contains("no backward gain"), "{msg}");
        }
        other => panic!("expected a data error, got {other:?}"),
    }
    // Without the bad step the smoother runs and moves the estimates.
    let ts = [0.0, 1.0, 2.0, 3.0, 4.0];
    let tf = |k: usize| ts[k];
    let (mut x, mut v, mut a) = (vec![0.0, 1.5, 1.7, 3.2, 4.0], vec![1.0; 5], vec![0.0; 5]);
    let mut st: [&mut [f64]; 3] = [&mut x, &mut v, &mut a];
    PostTrack::<f64, 3>::post(&post, 0, &mut st, Some(&tf), None).unwrap();
    assert_eq!(x[4], 4.0);
    assert!(x[1] != 1.5 && x[1].is_finite());
}

/// Without timestamps, alpha-beta tracks run in the flat vector kernel
/// (AVX-512 or AVX2), fresh tracks with valid first samples starting in its
/// vector steps: each track must get the bits of the scalar track code
/// (`track_tv`) run on it alone, both inits (the first-sample start's rate
/// `-0.0 + 0 * z`: `-0.0` after a negative first sample, also a `-0.0`
/// sample), NaN-led, all-NaN and tiny tracks, given states, shared and
/// per-track gains, `f64` and `f32`.
fn flat_case<T: IoFloat>(init: Init, shared: bool, given: bool) {
    let lens: Vec<usize> = (0..700)
        .map(|i| [0, 1, 2, 3, 5, 8, 9, 15, 16, 17, 40, 100, 7][(i * 7) % 13])
        .chain([1000, 0, 2, 257, 300])
        // Long tracks of close lengths (regions of one track each, refilled
        // one at a time), some starting with NaN, some continuing (`given`).
        .chain([
            2100, 2101, 2150, 2049, 2120, 9, 2190, 2222, 2130, 2047, 2160, 2111, 2180, 2200, 2140,
            2170, 2050, 2049, 5003,
        ])
        .collect();
    let mut off = vec![0i64];
    for &l in &lens {
        off.push(off.last().copied().unwrap_or(0) + l as i64);
    }
    let total = *off.last().unwrap_or(&0) as usize;
    let z: Vec<T> = (0..total)
        .map(|i| {
            let h = (i.wrapping_mul(2654435761) >> 7) % 1000;
            let v = if h < 60 || i % 211 > 195 {
                f64::NAN
            } else if h % 97 == 0 {
                -0.0
            } else {
                (h as f64 - 500.0) * 0.013 + (i % 37) as f64 * 0.7 - 12.0
            };
            T::from_f64(v)
        })
        .collect();
    let n_tracks = lens.len();
    let laws: Vec<AbFixed> = (0..if shared { 1 } else { n_tracks })
        .map(|j| AbFixed {
            alpha: 0.2 + 0.6 * ((j * 7) % 11) as f64 / 11.0,
            beta: 0.01 + 0.1 * ((j * 3) % 5) as f64 / 5.0,
        })
        .collect();
    let f = TrackFilter {
        laws: &laws,
        h: [[1.0, 0.0]],
        h_pinv: [[1.0], [0.0]],
    };
    let o = Options {
        init,
        t_nominal: 0.25,
        max_gap: None,
        drop_duplicates: false,
    };
    let state0 = |j: usize| {
        let mut s = TrackState::default();
        if given && j.is_multiple_of(3) {
            s.x[0] = j as f64 * 0.5;
            s.x[1] = -0.25;
            s.phase = 2.0;
        }
        s
    };
    let mut st: Vec<TrackState> = (0..n_tracks).map(state0).collect();
    let mut counts = vec![[0i64; 2]; n_tracks];
    let mut out = vec![T::from_f64(-7.0); 2 * total];
    filter_tracks(
        &f,
        &o,
        &off,
        &Samples::flat(&z, 1).unwrap(),
        None,
        &mut st,
        &mut out,
        None,
        &mut counts,
        false,
        &NoPost,
    )
    .unwrap();
    let (xs, vs) = out.split_at(total);
    for j in 0..n_tracks {
        let (a, b) = (off[j] as usize, off[j + 1] as usize);
        let mut law = laws[if shared { 0 } else { j }];
        let mut s = state0(j);
        let mut x = vec![T::from_f64(-7.0); b - a];
        let mut v = vec![T::from_f64(-7.0); b - a];
        let mut c = [0i64; 2];
        let mut to = TrackOut {
            states: [&mut x[..], &mut v[..]],
            resid: None,
        };
        let zf = |k: usize| [z[a + k].to_f64()];
        track_tv::<T, AbFixed, 2, 1, true>(
            &mut law,
            &f.h,
            &f.h_pinv,
            &o,
            &mut s,
            b - a,
            zf,
            None::<&fn(usize) -> f64>,
            &mut to,
            &mut c,
            j,
            0,
            false,
        )
        .unwrap();
        let bits = |p: &[T], q: &[T]| {
            p.iter()
                .zip(q)
                .position(|(p, q)| p.to_f64().to_bits() != q.to_f64().to_bits())
        };
        let what = format!(
            "track {j} (len {}) {init:?} shared {shared} given {given}",
            b - a
        );
        assert_eq!(bits(&xs[a..b], &x), None, "x of {what}");
        assert_eq!(bits(&vs[a..b], &v), None, "v of {what}");
        let (p, q) = (&st[j], &s);
        let same = (0..2).all(|i| p.x[i].to_bits() == q.x[i].to_bits())
            && p.phase.to_bits() == q.phase.to_bits()
            && p.since.to_bits() == q.since.to_bits();
        assert!(same, "state of {what}: {p:?} vs {q:?}");
    }
}

#[test]
fn tracks_without_times_equal_the_scalar_track_code() {
    for init in [Init::TwoPoint, Init::First] {
        for (shared, given) in [(true, false), (false, false), (true, true)] {
            flat_case::<f64>(init, shared, given);
            flat_case::<f32>(init, shared, given);
        }
    }
}

#[test]
fn rows_of_no_samples_are_an_empty_result_not_a_panic() {
    // A rectangular (n_tracks, 0) batch with timestamps: rows of length 0
    // (found by the Python fuzzer: the sample address divided by the row
    // length). Every track is empty; the states stay fresh.
    let laws = [AbDesign::new(0.3)];
    let f = ab_filter(&laws);
    let empty: &[f64] = &[];
    for n_tracks in [1usize, 2, 3] {
        let rows = |data: &'static [f64]| Samples {
            data,
            base: 0,
            s_row: 0,
            s_sample: 1,
            s_comp: 1,
            row_len: 0,
            n_rows: n_tracks,
            m: 1,
        };
        let (zs, ts) = (rows(empty), rows(empty));
        let offsets = vec![0i64; n_tracks + 1];
        let mut states = vec![TrackState::default(); n_tracks];
        let mut counts = vec![[0i64; 2]; n_tracks];
        let mut out: Vec<f64> = Vec::new();
        for t in [Some(&ts), None] {
            filter_tracks(
                &f,
                &opts(Init::TwoPoint, None, false),
                &offsets,
                &zs,
                t,
                &mut states,
                &mut out,
                None,
                &mut counts,
                false,
                &NoPost,
            )
            .unwrap();
            // bit for bit (the default's timestamps are NaN)
            let bits = |s: &TrackState| {
                let a: [f64; 4] = [s.phase, s.since, s.t_last, s.t_held];
                (s.x.map(f64::to_bits), a.map(f64::to_bits))
            };
            assert!(states
                .iter()
                .all(|s| bits(s) == bits(&TrackState::default())));
            assert!(counts.iter().all(|c| *c == [0, 0]));
        }
    }
}
