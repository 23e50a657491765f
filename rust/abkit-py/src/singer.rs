//! Bindings of `abkit_core::singer` (see `python/abkit/singer.py`).

use crate::convert::rows;
use abkit_core::singer::{self, Method, ROW_WIDTH};
use numpy::{PyArray2, PyReadonlyArray1};
use pyo3::prelude::*;

/// Physical (Phi, Q) of the Singer model: rows of 18 (Phi row-major, Q row-major).
#[pyfunction]
#[allow(non_snake_case)]
pub(crate) fn singer_model<'py>(
    py: Python<'py>,
    T: PyReadonlyArray1<'py, f64>,
    tau: PyReadonlyArray1<'py, f64>,
    q: PyReadonlyArray1<'py, f64>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    rows(py, [T, tau, q], 18, |[t, tau, q], out| {
        let (phi, qm) = singer::model(t, tau, q)?;
        for i in 0..3 {
            for j in 0..3 {
                out[3 * i + j] = phi[(i, j)];
                out[9 + 3 * i + j] = qm[(i, j)];
            }
        }
        Ok(())
    })
}

/// Normalised steady state of the Singer filter (rows of SINGER_ROW_WIDTH):
/// theta = T/tau, qn = q T^5/sigma_pos^2, rv = sigma_vel T/sigma_pos (inf:
/// position only), method 0 numeric / 1 closed form / 2 auto.
#[pyfunction]
pub(crate) fn singer_steady_state<'py>(
    py: Python<'py>,
    theta: PyReadonlyArray1<'py, f64>,
    qn: PyReadonlyArray1<'py, f64>,
    rv: PyReadonlyArray1<'py, f64>,
    method: PyReadonlyArray1<'py, f64>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    rows(
        py,
        [theta, qn, rv, method],
        ROW_WIDTH,
        |[th, qn, rv, m], out| {
            singer::steady_state(th, qn, rv, Method::from_code(m)?)?.write_row(out);
            Ok(())
        },
    )
}
