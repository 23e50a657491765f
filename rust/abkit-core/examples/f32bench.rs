//! Micro-benchmark (not a test): the alpha-beta rows on `f32` data in `f64`
//! arithmetic ([`filter_ab`], the default) against `f32` arithmetic
//! ([`filter_ab_f32`]), alternating in one process, ns per sample (best of
//! `reps`), one thread, outputs reused, and the memory ceiling (one pass
//! reading `z` and writing both outputs with streamed stores, the same
//! bytes) in the same alternation; and the largest difference between the
//! two kernels relative to the array's scale.
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
    // The ceiling pass writes its own outputs (its streamed stores evict
    // what they write: on o32 the kernels' "in cache" runs were not).
    let mut oc = thp_vec(2 * n * len, |_| 0f32);
    let p = [(0.5, 0.2, 0.1)];
    let (mut b64, mut b32, mut bc) = (f64::INFINITY, f64::INFINITY, f64::INFINITY);
    for _ in 0..reps {
        let t0 = Instant::now();
        ceiling(&z, &mut oc);
        bc = bc.min(t0.elapsed().as_secs_f64());
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
        "{n}x{len}: f64 arithmetic {:.3} ns/sample ({:.2} of ceiling), f32 arithmetic {:.3} ({:.2}), ceiling {:.3}; max |dx| / scale {:.1e}",
        ns(b64),
        bc / b64,
        ns(b32),
        bc / b32,
        ns(bc),
        dev / scale
    );
    Ok(())
}

/// The memory ceiling: read `z` once, write it to both output halves
/// (streamed stores where the CPU has AVX; a plain copy elsewhere).
fn ceiling(z: &[f32], out: &mut [f32]) {
    let (x, v) = out.split_at_mut(z.len());
    #[cfg(target_arch = "x86_64")]
    if is_x86_feature_detected!("avx") {
        // SAFETY: AVX checked.
        unsafe { ceiling_avx(z, x, v) };
        return;
    }
    x.copy_from_slice(z);
    v.copy_from_slice(z);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
unsafe fn ceiling_avx(z: &[f32], x: &mut [f32], v: &mut [f32]) {
    use std::arch::x86_64::*;
    let n = z.len();
    // Plain copies up to where x is 32-byte aligned; streamed stores from
    // there when v is aligned at the same element.
    let h = (x.as_ptr().align_offset(32)).min(n);
    let ok = (v.as_ptr() as usize + 4 * h).is_multiple_of(32);
    let end = if ok { h + (n - h) / 8 * 8 } else { h };
    for i in (h..end).step_by(8) {
        // SAFETY: i + 8 <= n for all three; x and v 32-byte aligned at i.
        unsafe {
            let a = _mm256_loadu_ps(z.as_ptr().add(i));
            _mm256_stream_ps(x.as_mut_ptr().add(i), a);
            _mm256_stream_ps(v.as_mut_ptr().add(i), a);
        }
    }
    _mm_sfence();
    x[..h].copy_from_slice(&z[..h]);
    v[..h].copy_from_slice(&z[..h]);
    x[end..].copy_from_slice(&z[end..]);
    v[end..].copy_from_slice(&z[end..]);
}
