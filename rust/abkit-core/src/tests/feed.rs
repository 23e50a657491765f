//! Tests of the feed kernel (`crate::feed`).
use super::*;
use crate::filter::Init;
use crate::irregular::{AbDesign, AbgFixed};
use crate::ragged::{filter_tracks, NoPost};

/// Rows of `n_tracks` interleaved pseudo-randomly, increasing times;
/// the feed equals the ragged kernel on the grouped rows, bit for bit.
fn check<L: GainLaw<N, 1>, const N: usize>(laws: &[L], h: [[f64; N]; 1], h_pinv: [[f64; 1]; N]) {
    let n_tracks = 7;
    let n_rows = 600;
    let mut seed = 12345u64;
    let mut rnd = || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    let codes: Vec<i64> = (0..n_rows)
        .map(|_| (rnd() * n_tracks as f64) as i64)
        .collect();
    let mut tt = 0.0;
    let t: Vec<f64> = (0..n_rows)
        .map(|r| {
            // some duplicate timestamps and some long gaps
            if r % 37 != 5 {
                tt += 0.05 + rnd() * if r % 101 == 3 { 50.0 } else { 0.5 };
            }
            tt
        })
        .collect();
    let z: Vec<f64> = (0..n_rows)
        .map(|r| {
            if rnd() < 0.1 {
                f64::NAN
            } else {
                3.0 * t[r] + codes[r] as f64 * 10.0 + rnd()
            }
        })
        .collect();
    for init in [Init::TwoPoint, Init::First] {
        for max_gap in [None, Some(5.0)] {
            let opts = Options {
                init,
                t_nominal: 0.3,
                max_gap,
                drop_duplicates: true,
            };
            let filt = TrackFilter { laws, h, h_pinv };
            for with_t in [true, false] {
                let zs = [Samples::flat(&z, 1).unwrap()];
                let ts = Samples::flat(&t, 1).unwrap();
                let mut st = vec![TrackState::default(); n_tracks];
                for s in &mut st {
                    s.t_last = f64::NAN;
                    s.t_held = f64::NAN;
                }
                let mut st_ref = st.clone();
                let mut out = vec![0.0; N * n_rows];
                let mut res = vec![0.0; n_rows];
                let mut ct = vec![[0; 2]; n_tracks];
                let mut tr = vec![TrackRows::default(); n_tracks];
                filter_feed(
                    &filt,
                    &opts,
                    &codes,
                    &zs,
                    with_t.then_some(&ts),
                    &mut st,
                    &mut out,
                    Some(&mut res),
                    &mut ct,
                    &mut tr,
                    false,
                )
                .unwrap();
                // the grouped reference
                let mut order: Vec<usize> = (0..n_rows).collect();
                order.sort_by_key(|&r| codes[r]); // stable
                let zg: Vec<f64> = order.iter().map(|&r| z[r]).collect();
                let tg: Vec<f64> = order.iter().map(|&r| t[r]).collect();
                let mut off = vec![0i64; n_tracks + 1];
                for &c in &codes {
                    off[c as usize + 1] += 1;
                }
                for i in 0..n_tracks {
                    off[i + 1] += off[i];
                }
                let mut out_g = vec![0.0; N * n_rows];
                let mut res_g = vec![0.0; n_rows];
                let mut ct_g = vec![[0; 2]; n_tracks];
                let tgs = Samples::flat(&tg, 1).unwrap();
                filter_tracks(
                    &filt,
                    &opts,
                    &off,
                    &Samples::flat(&zg, 1).unwrap(),
                    with_t.then_some(&tgs),
                    &mut st_ref,
                    &mut out_g,
                    Some(&mut res_g),
                    &mut ct_g,
                    false,
                    &NoPost,
                )
                .unwrap();
                for (g, &r) in order.iter().enumerate() {
                    for c in 0..N {
                        assert_eq!(
                            out[c * n_rows + r].to_bits(),
                            out_g[c * n_rows + g].to_bits(),
                            "state {c} row {r}"
                        );
                    }
                    assert_eq!(res[r].to_bits(), res_g[g].to_bits());
                }
                assert_eq!(ct, ct_g);
                for i in 0..n_tracks {
                    assert_eq!(st[i].x, st_ref[i].x);
                    assert_eq!(tr[i].n, off[i + 1] - off[i]);
                    assert_eq!(
                        tr[i].first,
                        codes
                            .iter()
                            .position(|&c| c == i as i64)
                            .map_or(-1, |p| p as i64)
                    );
                }
            }
        }
    }
}

#[test]
fn feed_equals_grouped_ragged_kernel() {
    check(&[AbDesign::new(0.7)], [[1.0, 0.0]], [[1.0], [0.0]]);
    check(
        &[AbgFixed {
            alpha: 0.5,
            beta: 0.3,
            cgamma: 0.05,
        }],
        [[1.0, 0.0, 0.0]],
        [[1.0], [0.0], [0.0]],
    );
}

#[test]
fn time_order_is_a_stable_argsort_with_nan_last() {
    let t = [
        3.0,
        f64::NAN,
        -0.0,
        0.0,
        f64::NEG_INFINITY,
        -0.0,
        f64::INFINITY,
        -1.5,
        3.0,
        -f64::NAN,
        0.0,
        -1e-300,
        1e-300,
    ];
    let want = [4, 7, 11, 2, 3, 5, 10, 12, 0, 8, 6, 1, 9];
    for par in [false, true] {
        assert_eq!(time_order(&t, par), want);
    }
    assert!(time_order(&[], true).is_empty());
}

#[test]
fn feed_errors_name_track_and_sample() {
    let laws = [AbDesign::new(1.0)];
    let filt = TrackFilter {
        laws: &laws,
        h: [[1.0, 0.0]],
        h_pinv: [[1.0], [0.0]],
    };
    let opts = Options {
        init: Init::TwoPoint,
        t_nominal: 1.0,
        max_gap: None,
        drop_duplicates: false,
    };
    let codes = [0i64, 1, 1, 0, 1];
    let t = [0.0, 0.0, 1.0, 2.0, 1.0];
    let z = [1.0; 5];
    let mut st = vec![TrackState::default(); 2];
    for s in &mut st {
        s.t_last = f64::NAN;
        s.t_held = f64::NAN;
    }
    let mut out = vec![0.0; 10];
    let mut ct = vec![[0; 2]; 2];
    let mut tr = vec![TrackRows::default(); 2];
    let err = filter_feed(
        &filt,
        &opts,
        &codes,
        &[Samples::flat(&z, 1).unwrap()],
        Some(&Samples::flat(&t, 1).unwrap()),
        &mut st,
        &mut out,
        None,
        &mut ct,
        &mut tr,
        false,
    )
    .unwrap_err();
    match err {
        (0, Error::Data { track, sample, .. }) => assert_eq!((track, sample), (1, 2)),
        other => panic!("{other:?}"),
    }
    let bad = filter_feed(
        &filt,
        &opts,
        &[0, 2],
        &[Samples::flat(&z[..2], 1).unwrap()],
        None,
        &mut st,
        &mut out[..4],
        None,
        &mut ct,
        &mut tr,
        false,
    );
    assert!(matches!(bad, Err((0, Error::Shape(_)))));
}
