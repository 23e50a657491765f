//! The design and analysis solvers with arbitrary parameters (NaN, ±Inf,
//! 0, 1e±300, raw bit patterns). Invariants: no panic; a returned design is
//! finite where it must be and stable where theory says so.
#![no_main]

use abkit_core::{abg, alphabeta::AlphaBeta, singer};
use libfuzzer_sys::fuzz_target;

#[path = "common.rs"]
mod common;
use common::Bytes;

fn check_kalman_ab(d: &AlphaBeta) {
    assert!(
        d.alpha.is_finite() && d.beta.is_finite(),
        "non-finite gains {d:?}"
    );
    assert!(
        d.alpha > 0.0 && d.alpha <= 1.0 && d.beta >= 0.0,
        "gains out of range {d:?}"
    );
    if d.beta > 0.0 {
        assert!(d.stable, "Kalman design not stable {d:?}");
    }
}

fuzz_target!(|data: &[u8]| {
    let mut b = Bytes::new(data);
    let (x, y, z, w, v, u) = (b.f64(), b.f64(), b.f64(), b.f64(), b.f64(), b.f64());
    match b.u8() % 10 {
        0 => {
            if let Ok(d) = AlphaBeta::from_snr(x) {
                check_kalman_ab(&d);
            }
        }
        1 => {
            if let Ok(d) = AlphaBeta::from_noise(x, y, z) {
                check_kalman_ab(&d);
            }
        }
        2 => {
            if let Ok(d) = AlphaBeta::from_tracking_index(x) {
                check_kalman_ab(&d);
            }
        }
        3 => {
            let _ = AlphaBeta::from_tracking_error(x);
            let _ = AlphaBeta::from_bandwidth(x, y);
            let _ = AlphaBeta::from_natural_frequency(x, y, z);
        }
        4 => {
            if let Ok(d) = AlphaBeta::analyze(x, y) {
                assert_eq!(d.stable, x > 0.0 && y > 0.0 && 2.0 * x + y < 4.0, "{d:?}");
            }
            let _ = abkit_core::alphabeta::error_covariance(x, y, z);
        }
        5 => {
            if let Ok(g) = abg::from_noise(x, y, z, w, v) {
                assert!(g.iter().all(|t| t.is_finite()), "{g:?}");
                if let Ok(m) = abg::jury_margins(g[0], g[1], g[2]) {
                    assert!(
                        m.iter().all(|t| *t >= -1e-9),
                        "near-optimal gains {g:?} unstable: {m:?}"
                    );
                }
            }
            let _ = abg::from_tracking_index(x);
        }
        6 => {
            let _ = abg::Analysis::analyze(x, y, z);
            let _ = abg::noise_ratios(x, y, z, w);
            let _ = abg::near_optimal_conditions(x, y, z);
        }
        7 => {
            let _ = abg::coloured(x, y, z, w, v, u);
            let _ = abg::coloured_from_noise(x, y, z, w, v, u);
            let _ = abg::decoupled(x, y, z, w, v, u);
        }
        _ => {
            let method = [
                singer::Method::Numeric,
                singer::Method::ClosedForm,
                singer::Method::Auto,
            ][b.usize_below(3)];
            let _ = singer::model(x, y, z);
            if let Ok(s) = singer::steady_state(x, y, z, method) {
                let p = s.p_pred;
                assert!(p.iter().all(|t| t.is_finite()), "{s:?}");
                // non-negative to the solver's tolerance (1e-8 of ||P||)
                let scale = p.iter().fold(0.0f64, |m, t| m.max(t.abs()));
                for i in 0..3 {
                    assert!(p[(i, i)] >= -1e-7 * scale, "negative variance {s:?}");
                }
            }
        }
    }
});
