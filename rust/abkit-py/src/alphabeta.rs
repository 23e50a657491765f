//! Bindings of `abkit_core::alphabeta` (see `python/abkit/alphabeta.py`).

use crate::convert::rows;
use abkit_core::alphabeta::{self, AlphaBeta, FIELDS};
use numpy::{PyArray2, PyReadonlyArray1};
use pyo3::prelude::*;

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
pub(crate) fn alphabeta_from_snr<'py>(
    py: Python<'py>,
    r: PyReadonlyArray1<'py, f64>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    design_rows(py, [r], |[r]| AlphaBeta::from_snr(r))
}

/// Kalman alpha-beta design from sigma_w, sigma_v and T.
#[pyfunction]
#[allow(non_snake_case)]
pub(crate) fn alphabeta_from_noise<'py>(
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
pub(crate) fn alphabeta_from_tracking_index<'py>(
    py: Python<'py>,
    lam: PyReadonlyArray1<'py, f64>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    design_rows(py, [lam], |[l]| AlphaBeta::from_tracking_index(l))
}

/// Kalman alpha-beta design from the normalised tracking error variance.
#[pyfunction]
pub(crate) fn alphabeta_from_tracking_error<'py>(
    py: Python<'py>,
    ratio: PyReadonlyArray1<'py, f64>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    design_rows(py, [ratio], |[x]| AlphaBeta::from_tracking_error(x))
}

/// Deterministic alpha-beta design from B_N*T and damping.
#[pyfunction]
pub(crate) fn alphabeta_from_bandwidth<'py>(
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
pub(crate) fn alphabeta_from_natural_frequency<'py>(
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
pub(crate) fn alphabeta_analyze<'py>(
    py: Python<'py>,
    alpha: PyReadonlyArray1<'py, f64>,
    beta: PyReadonlyArray1<'py, f64>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    design_rows(py, [alpha, beta], |[a, b]| AlphaBeta::analyze(a, b))
}

/// Steady-state covariance (filtered p11 p12 p22, predicted m11 m12 m22) of
/// gains (alpha, beta) under the true SNR r_true.
#[pyfunction]
pub(crate) fn alphabeta_error_covariance<'py>(
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
