//! Bindings of `abkit_core::riccati` (see `python/abkit/riccati.py`).

use crate::convert::{from_dmatrix, guard, to_dmatrix, to_pyerr_single};
use abkit_core::riccati;
use numpy::{PyArray2, PyReadonlyArray2};
use pyo3::prelude::*;

type Arr<'py> = Bound<'py, PyArray2<f64>>;

/// Stabilising DARE solution: (X, K, rho, residual, iterations).
#[pyfunction]
#[pyo3(signature = (a, b, q, r, s=None))]
#[allow(clippy::type_complexity)]
pub(crate) fn riccati_solve_dare<'py>(
    py: Python<'py>,
    a: PyReadonlyArray2<'py, f64>,
    b: PyReadonlyArray2<'py, f64>,
    q: PyReadonlyArray2<'py, f64>,
    r: PyReadonlyArray2<'py, f64>,
    s: Option<PyReadonlyArray2<'py, f64>>,
) -> PyResult<(Arr<'py>, Arr<'py>, f64, f64, usize)> {
    let (a, b, q, r) = (
        to_dmatrix(&a),
        to_dmatrix(&b),
        to_dmatrix(&q),
        to_dmatrix(&r),
    );
    let s = s.as_ref().map(to_dmatrix);
    let d = py
        .detach(|| guard(|| riccati::solve_dare(&a, &b, &q, &r, s.as_ref())))?
        .map_err(to_pyerr_single)?;
    Ok((
        from_dmatrix(py, &d.x),
        from_dmatrix(py, &d.k),
        d.rho,
        d.residual,
        d.iterations,
    ))
}

/// Steady-state Kalman filter: (P_pred, K_filt, K_pred, P_filt, S, rho).
#[pyfunction]
#[allow(clippy::type_complexity)]
pub(crate) fn riccati_kalman_steady_state<'py>(
    py: Python<'py>,
    f: PyReadonlyArray2<'py, f64>,
    h: PyReadonlyArray2<'py, f64>,
    q: PyReadonlyArray2<'py, f64>,
    r: PyReadonlyArray2<'py, f64>,
) -> PyResult<(Arr<'py>, Arr<'py>, Arr<'py>, Arr<'py>, Arr<'py>, f64)> {
    let (f, h, q, r) = (
        to_dmatrix(&f),
        to_dmatrix(&h),
        to_dmatrix(&q),
        to_dmatrix(&r),
    );
    let k = py
        .detach(|| guard(|| riccati::kalman_steady_state(&f, &h, &q, &r)))?
        .map_err(to_pyerr_single)?;
    Ok((
        from_dmatrix(py, &k.p_pred),
        from_dmatrix(py, &k.k_filt),
        from_dmatrix(py, &k.k_pred),
        from_dmatrix(py, &k.p_filt),
        from_dmatrix(py, &k.innovation),
        k.rho,
    ))
}
