//! PyO3 bindings of `abkit-core`, built as the extension module `abkit._abkit`.
//!
//! Each binding is a few lines: it borrows the (contiguous, float64) numpy
//! inputs as slices, releases the GIL, runs the core function element-wise
//! through [`convert::rows`], and turns core errors into Python exceptions in
//! one place ([`convert::to_pyerr`]). Broadcasting, dtype conversion and
//! argument-level validation live in the Python layer (`python/abkit`).
//! One file per core module.

mod alphabeta;
mod convert;
mod riccati;
mod singer;

use pyo3::prelude::*;

#[pymodule]
mod _abkit {
    #[pymodule_export]
    use super::alphabeta::{
        alphabeta_analyze, alphabeta_error_covariance, alphabeta_from_bandwidth,
        alphabeta_from_natural_frequency, alphabeta_from_noise, alphabeta_from_snr,
        alphabeta_from_tracking_error, alphabeta_from_tracking_index,
    };
    #[pymodule_export]
    use super::riccati::{riccati_kalman_steady_state, riccati_solve_dare};
    #[pymodule_export]
    use super::singer::{singer_model, singer_steady_state};
    use pyo3::prelude::*;

    #[pymodule_init]
    fn init(m: &Bound<'_, PyModule>) -> PyResult<()> {
        m.add("ALPHABETA_FIELDS", abkit_core::alphabeta::FIELDS.to_vec())?;
        m.add("SINGER_ROW_WIDTH", abkit_core::singer::ROW_WIDTH)?;
        m.add("__version__", env!("CARGO_PKG_VERSION"))?;
        Ok(())
    }
}
