//! The filtering kernels' memory contract: arbitrary measurement layouts
//! (base offset, strides of any sign, counts), state and output buffers of
//! any length and per-track parameter counts. Invariant: an error or a
//! normal return, never a panic or an out-of-bounds access.
#![no_main]

use abkit_core::filter::{filter_ab, filter_general, Gains, Init, Measurements, TrackState};
use libfuzzer_sys::fuzz_target;

#[path = "common.rs"]
mod common;
use common::Bytes;

fn stride(b: &mut Bytes) -> isize {
    match b.u8() % 4 {
        0 => b.usize_below(64) as isize,
        1 => -(b.usize_below(64) as isize),
        2 => i64::from_le_bytes([
            b.u8(),
            b.u8(),
            b.u8(),
            b.u8(),
            b.u8(),
            b.u8(),
            b.u8(),
            b.u8(),
        ]) as isize,
        _ => 1,
    }
}

fuzz_target!(|data: &[u8]| {
    let mut b = Bytes::new(data);
    let len = b.usize_below(256);
    let z: Vec<f64> = (0..len).map(|_| b.f64()).collect();
    let big = b.u8() % 8 == 0;
    let meas = Measurements {
        data: &z,
        base: if big {
            usize::MAX - b.usize_below(8)
        } else {
            b.usize_below(300)
        },
        s_track: stride(&mut b),
        s_sample: stride(&mut b),
        s_comp: stride(&mut b),
        n_tracks: if big {
            usize::MAX / (1 + b.usize_below(4))
        } else {
            b.usize_below(6)
        },
        n_samples: b.usize_below(40),
        m: 1 + b.usize_below(2),
    };
    let n_states = b.usize_below(8);
    let mut states: Vec<TrackState> = (0..n_states)
        .map(|_| {
            let mut s = TrackState::default();
            s.phase = [0.0, 1.0, 2.0, b.f64()][b.usize_below(4)];
            s.since = [0.0, 1.0, b.f64()][b.usize_below(3)];
            s.x[0] = b.f64();
            s.x[1] = b.f64();
            s
        })
        .collect();
    let mut out = vec![0.0f64; b.usize_below(1200)];
    let mut resid_buf = vec![0.0f64; b.usize_below(600)];
    let resid = if b.u8() % 2 == 0 {
        Some(&mut resid_buf[..])
    } else {
        None
    };
    let init = if b.u8() % 2 == 0 {
        Init::First
    } else {
        Init::TwoPoint
    };
    let par = b.u8() % 2 == 0;
    let n_params = 1 + b.usize_below(4);
    if b.u8() % 2 == 0 {
        let params: Vec<(f64, f64, f64)> = (0..n_params)
            .map(|_| (0.5, 0.2, b.in_range(1e-3, 1e3)))
            .collect();
        let _ = filter_ab(
            &params,
            init,
            &meas,
            &mut states,
            &mut out,
            resid,
            par,
            None,
        );
    } else if meas.m == 1 {
        let g = Gains::<2, 1> {
            phi: [[1.0, 1.0], [0.0, 1.0]],
            h: [[1.0, 0.0]],
            k: [[0.5], [0.2]],
            h_pinv: [[1.0], [0.0]],
            t: 1.0,
        };
        let gains = vec![g; n_params];
        let _ = filter_general(&gains, init, &meas, &mut states, &mut out, resid, par, None);
    } else {
        let g = Gains::<2, 2> {
            phi: [[1.0, 1.0], [0.0, 1.0]],
            h: [[1.0, 0.0], [0.0, 1.0]],
            k: [[0.5, 0.0], [0.0, 0.4]],
            h_pinv: [[1.0, 0.0], [0.0, 1.0]],
            t: 1.0,
        };
        let gains = vec![g; n_params];
        let _ = filter_general(&gains, init, &meas, &mut states, &mut out, resid, par, None);
    }
});
