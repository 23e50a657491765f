//! PyO3 bindings of `abkit-core`, built as the extension module `abkit._abkit`.
//!
//! Each binding is a few lines: it borrows the (contiguous, float64) numpy
//! inputs as slices, releases the GIL, runs the core function element-wise
//! through [`rows`], and turns core errors into Python exceptions in one
//! place ([`to_pyerr`]). Broadcasting, dtype conversion and argument-level
//! validation live in the Python layer (`python/abkit`).

use abkit_core::alphabeta::{self, AlphaBeta, FIELDS};
use abkit_core::batch::map_rows;
use abkit_core::Error;
use numpy::{PyArray2, PyArrayMethods, PyReadonlyArray1, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

/// The one conversion of core errors into Python exceptions.
fn to_pyerr((index, err): (usize, Error)) -> PyErr {
    match err {
        Error::Domain { .. } => PyValueError::new_err(format!("{err} (at flat index {index})")),
        Error::Shape(_) => PyValueError::new_err(err.to_string()),
    }
}

/// Release the GIL and evaluate `f` element-wise over equal-length 1-D
/// inputs, returning an `(n, width)` float64 array.
fn rows<'py, const N: usize>(
    py: Python<'py>,
    inputs: [PyReadonlyArray1<'py, f64>; N],
    width: usize,
    f: impl Fn([f64; N], &mut [f64]) -> abkit_core::Result<()> + Sync + Send,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let n = inputs.first().map_or(0, |a| a.len());
    let out = PyArray2::<f64>::zeros(py, [n, width], false);
    let mut out_rw = out.readwrite();
    let out_slice = out_rw.as_slice_mut()?;
    let mut slices: [&[f64]; N] = [&[]; N];
    for (s, a) in slices.iter_mut().zip(inputs.iter()) {
        *s = a.as_slice()?;
    }
    py.detach(|| map_rows(slices, width, out_slice, f))
        .map_err(to_pyerr)?;
    drop(out_rw);
    Ok(out)
}

fn design_rows<'py, const N: usize>(
    py: Python<'py>,
    inputs: [PyReadonlyArray1<'py, f64>; N],
    make: impl Fn([f64; N]) -> abkit_core::Result<AlphaBeta> + Sync + Send,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    rows(py, inputs, FIELDS.len(), |args, out| {
        make(args)?.write_row(out);
        Ok(())
    })
}

/// Kalman alpha-beta design from the SNR r (rows of ALPHABETA_FIELDS).
#[pyfunction]
fn alphabeta_from_snr<'py>(
    py: Python<'py>,
    r: PyReadonlyArray1<'py, f64>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    design_rows(py, [r], |[r]| AlphaBeta::from_snr(r))
}

/// Kalman alpha-beta design from sigma_w, sigma_v and T.
#[pyfunction]
#[allow(non_snake_case)]
fn alphabeta_from_noise<'py>(
    py: Python<'py>,
    sigma_w: PyReadonlyArray1<'py, f64>,
    sigma_v: PyReadonlyArray1<'py, f64>,
    T: PyReadonlyArray1<'py, f64>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    design_rows(py, [sigma_w, sigma_v, T], |[w, v, t]| {
        AlphaBeta::from_noise(w, v, t)
    })
}

/// Kalman alpha-beta design from Kalata's tracking index.
#[pyfunction]
fn alphabeta_from_tracking_index<'py>(
    py: Python<'py>,
    lam: PyReadonlyArray1<'py, f64>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    design_rows(py, [lam], |[l]| AlphaBeta::from_tracking_index(l))
}

/// Kalman alpha-beta design from the normalised tracking error variance.
#[pyfunction]
fn alphabeta_from_tracking_error<'py>(
    py: Python<'py>,
    ratio: PyReadonlyArray1<'py, f64>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    design_rows(py, [ratio], |[x]| AlphaBeta::from_tracking_error(x))
}

/// Deterministic alpha-beta design from B_N*T and damping.
#[pyfunction]
fn alphabeta_from_bandwidth<'py>(
    py: Python<'py>,
    bn_t: PyReadonlyArray1<'py, f64>,
    damping: PyReadonlyArray1<'py, f64>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    design_rows(py, [bn_t, damping], |[b, d]| {
        AlphaBeta::from_bandwidth(b, d)
    })
}

/// Deterministic alpha-beta design from omega_n, T and damping.
#[pyfunction]
#[allow(non_snake_case)]
fn alphabeta_from_natural_frequency<'py>(
    py: Python<'py>,
    omega_n: PyReadonlyArray1<'py, f64>,
    T: PyReadonlyArray1<'py, f64>,
    damping: PyReadonlyArray1<'py, f64>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    design_rows(py, [omega_n, T, damping], |[w, t, d]| {
        AlphaBeta::from_natural_frequency(w, t, d)
    })
}

/// Analysis of arbitrary alpha-beta gains.
#[pyfunction]
fn alphabeta_analyze<'py>(
    py: Python<'py>,
    alpha: PyReadonlyArray1<'py, f64>,
    beta: PyReadonlyArray1<'py, f64>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    design_rows(py, [alpha, beta], |[a, b]| AlphaBeta::analyze(a, b))
}

/// Steady-state covariance (filtered p11 p12 p22, predicted m11 m12 m22) of
/// gains (alpha, beta) under the true SNR r_true.
#[pyfunction]
fn alphabeta_error_covariance<'py>(
    py: Python<'py>,
    alpha: PyReadonlyArray1<'py, f64>,
    beta: PyReadonlyArray1<'py, f64>,
    r_true: PyReadonlyArray1<'py, f64>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    rows(py, [alpha, beta, r_true], 6, |[a, b, r], out| {
        let c = alphabeta::error_covariance(a, b, r)?;
        out[..3].copy_from_slice(&c.filtered);
        out[3..].copy_from_slice(&c.predicted);
        Ok(())
    })
}

#[pymodule]
mod _abkit {
    #[pymodule_export]
    use super::{
        alphabeta_analyze, alphabeta_error_covariance, alphabeta_from_bandwidth,
        alphabeta_from_natural_frequency, alphabeta_from_noise, alphabeta_from_snr,
        alphabeta_from_tracking_error, alphabeta_from_tracking_index,
    };
    use pyo3::prelude::*;

    #[pymodule_init]
    fn init(m: &Bound<'_, PyModule>) -> PyResult<()> {
        m.add("ALPHABETA_FIELDS", super::FIELDS.to_vec())?;
        m.add("__version__", env!("CARGO_PKG_VERSION"))?;
        Ok(())
    }
}
