//! `abkit-core`: the pure-Rust core of abkit.
//!
//! No Python here: the functions work on plain `f64` values and slices and
//! return [`Error`] for inputs they cannot handle. The Python bindings
//! (`abkit-py`) are a thin layer over these functions.
//!
//! Modules, one per idea:
//! - [`abg`]: near-optimal alpha-beta-gamma filters of Chen & Chui (paper
//!   004): gains from noise, noise ratios from gains, coloured measurement
//!   noise (alpha-beta-gamma-theta), decoupled recursive forms.
//! - [`alphabeta`]: the alpha-beta filter of Painter, Kerstetter & Jowers
//!   (1990): Kalman design from the SNR, deterministic design from damping,
//!   natural frequency or noise bandwidth, and the steady-state analysis of
//!   any gains (covariances, poles, lag, variance reduction).
//! - [`riccati`]: the discrete algebraic Riccati equation (structured
//!   doubling, with residual and stabilisation checks) and the steady-state
//!   Kalman filter.
//! - [`singer`]: the Singer (ECA) model of Yoon & Hong / Singer (1970) and
//!   the steady state of its Kalman filter (numeric route).
//! - [`singer_closed`]: the paper's closed-form Hamiltonian route.
//! - [`batch`]: element-wise evaluation of a scalar solver over arrays,
//!   in parallel on rayon's global pool.
//! - [`filter`]: the batched fixed-gain filtering kernels (general `n <= 6`,
//!   `m <= 2`; alpha-beta specialisation), start-up, missed samples, streaming
//!   state; `filter::f32arith`: alpha-beta on `f32` data in `f32`
//!   arithmetic (the opt-in `AlphaBetaFilter(float32_arithmetic=True)`).
//! - [`smooth`]: steady-state fixed-interval (RTS) and fixed-lag smoothing.
//! - [`kalman`]: the time-varying Kalman recursion (paper 002), batched.
//! - [`irregular`]: gain laws for irregular sampling (the step model as a
//!   function of `dt`: per-dt steady-state designs or fixed gains).
//! - [`planes`]: the layout of the estimate buffers (component planes,
//!   contiguous or each on its own cache-line phase).
//! - [`ragged`]: the track kernel over ragged batches (Arrow offsets) with
//!   optional timestamps, gaps and duplicates.
//! - `ragged_simd` (x86-64): the vector lanes (AVX-512 / AVX2) of the
//!   track kernel's alpha-beta laws with timestamps.

// No unwrap/expect outside tests: nothing derived from user data may panic.
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

pub mod abg;
pub mod alphabeta;
pub mod batch;
mod dd;
mod error;
pub mod feed;
pub mod filter;
pub mod irregular;
pub mod kalman;
pub mod planes;
pub mod ragged;
#[cfg(target_arch = "x86_64")]
pub mod ragged_simd;
#[cfg(target_arch = "x86_64")]
mod ragged_split;
pub mod riccati;
pub mod singer;
pub mod singer_closed;
pub mod smooth;

pub use error::Error;

/// Result alias used throughout the crate.
pub type Result<T> = std::result::Result<T, Error>;
