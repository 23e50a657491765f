//! The helpers every binding uses: error conversion in one place
//! ([`to_pyerr`]) and GIL-free element-wise evaluation ([`rows`]).

use abkit_core::batch::map_rows;
use abkit_core::Error;
use numpy::{PyArray2, PyArrayMethods, PyReadonlyArray1, PyUntypedArrayMethods};
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;

/// The one conversion of core errors into Python exceptions.
pub(crate) fn to_pyerr((index, err): (usize, Error)) -> PyErr {
    match err {
        Error::Domain { .. } => PyValueError::new_err(format!("{err} (at flat index {index})")),
        Error::Shape(_) => PyValueError::new_err(err.to_string()),
    }
}

/// Run `f`, turning a Rust panic (a bug in abkit, never expected) into a
/// Python `RuntimeError` instead of letting it cross into Python.
pub(crate) fn guard<T>(f: impl FnOnce() -> T) -> PyResult<T> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)).map_err(|payload| {
        let msg = payload
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| payload.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "unknown panic".to_string());
        PyRuntimeError::new_err(format!("internal error in abkit (please report it): {msg}"))
    })
}

/// Release the GIL and evaluate `f` element-wise over equal-length 1-D
/// inputs, returning an `(n, width)` float64 array.
pub(crate) fn rows<'py, const N: usize>(
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
    py.detach(|| guard(|| map_rows(slices, width, out_slice, f)))?
        .map_err(to_pyerr)?;
    drop(out_rw);
    Ok(out)
}
