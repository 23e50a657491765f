//! PyO3 bindings of `abkit-core`, built as the extension module `abkit._abkit`.
//!
//! Each binding is a few lines: it borrows the (contiguous, float64) numpy
//! inputs as slices, releases the GIL, runs the core function element-wise
//! through [`convert::rows`], and turns core errors into Python exceptions in
//! one place ([`convert::to_pyerr`]). Broadcasting, dtype conversion and
//! argument-level validation live in the Python layer (`python/abkit`).
//! One file per core module.

// No unwrap/expect outside tests: nothing derived from user data may panic.
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]

/// Expand `$go!(N, M)` for the runtime sizes `n` (1..=6) and `m` (1..=2).
macro_rules! dispatch {
    ($n:expr, $m:expr, $go:ident) => {
        match ($n, $m) {
            (1, 1) => $go!(1, 1),
            (2, 1) => $go!(2, 1),
            (3, 1) => $go!(3, 1),
            (4, 1) => $go!(4, 1),
            (5, 1) => $go!(5, 1),
            (6, 1) => $go!(6, 1),
            (1, 2) => $go!(1, 2),
            (2, 2) => $go!(2, 2),
            (3, 2) => $go!(3, 2),
            (4, 2) => $go!(4, 2),
            (5, 2) => $go!(5, 2),
            (6, 2) => $go!(6, 2),
            (n, m) => Err(pyo3::exceptions::PyValueError::new_err(format!(
                "state dimension must be 1..=6 and measurement dimension 1..=2, got n={n}, m={m}"
            ))),
        }
    };
}

mod abg;
mod alphabeta;
mod convert;
mod feed;
mod filter;
mod kalman;
mod riccati;
mod singer;
mod tracks;

use pyo3::prelude::*;

#[pymodule]
mod _abkit {
    #[pymodule_export]
    use super::abg::{
        abg_analyze, abg_backward_gain, abg_backward_gain_noise, abg_coloured,
        abg_coloured_from_noise, abg_conditions, abg_decoupled, abg_from_noise,
        abg_from_tracking_index, abg_jury, abg_noise_ratios,
    };
    #[pymodule_export]
    use super::alphabeta::{
        alphabeta_analyze, alphabeta_error_covariance, alphabeta_from_bandwidth,
        alphabeta_from_natural_frequency, alphabeta_from_noise, alphabeta_from_snr,
        alphabeta_from_tracking_error, alphabeta_from_tracking_index,
    };
    #[pymodule_export]
    use super::feed::{filter_feed_py, time_order_py};
    #[pymodule_export]
    use super::filter::{filter_alphabeta, filter_fixed_gain, plane_stride, prefault};
    #[pymodule_export]
    use super::kalman::{kalman_gain_sequence, kalman_run};
    #[pymodule_export]
    use super::riccati::{riccati_kalman_steady_state, riccati_solve_dare};
    #[pymodule_export]
    use super::singer::{singer_model, singer_steady_state};
    #[pymodule_export]
    use super::tracks::{filter_tracks_f32_py, filter_tracks_py};
    use pyo3::prelude::*;

    #[pymodule_init]
    fn init(m: &Bound<'_, PyModule>) -> PyResult<()> {
        m.add("ABG_FIELDS", abkit_core::abg::FIELDS.to_vec())?;
        m.add(
            "ABG_COLOURED_FIELDS",
            abkit_core::abg::COLOURED_FIELDS.to_vec(),
        )?;
        m.add("ABG_DECOUPLED_WIDTH", abkit_core::abg::DECOUPLED_WIDTH)?;
        m.add("ALPHABETA_FIELDS", abkit_core::alphabeta::FIELDS.to_vec())?;
        m.add("STATE_WIDTH", super::filter::STATE_WIDTH)?;
        m.add("MAX_STATES", abkit_core::filter::MAX_STATES)?;
        m.add("PAD_MIN_BYTES", abkit_core::planes::PAD_MIN_BYTES)?;
        m.add("SINGER_ROW_WIDTH", abkit_core::singer::ROW_WIDTH)?;
        m.add("__version__", env!("CARGO_PKG_VERSION"))?;
        Ok(())
    }
}
