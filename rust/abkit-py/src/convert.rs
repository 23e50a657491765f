//! The helpers every binding uses: error conversion in one place
//! ([`to_pyerr`]) and GIL-free element-wise evaluation ([`rows`]).

use abkit_core::batch::map_rows;
use abkit_core::Error;
use nalgebra::DMatrix;
use numpy::{PyArray2, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;

pyo3::import_exception!(numpy.linalg, LinAlgError);

/// The one conversion of core errors into Python exceptions.
pub(crate) fn to_pyerr((index, err): (usize, Error)) -> PyErr {
    match err {
        Error::Domain { .. } => PyValueError::new_err(format!("{err} (at flat index {index})")),
        Error::Shape(_) | Error::Data { .. } => PyValueError::new_err(err.to_string()),
        Error::NoSolution(_) => LinAlgError::new_err(format!("{err} (at flat index {index})")),
    }
}

/// Core errors of a single (non-batch) problem.
pub(crate) fn to_pyerr_single(err: Error) -> PyErr {
    match err {
        Error::Domain { .. } | Error::Shape(_) | Error::Data { .. } => {
            PyValueError::new_err(err.to_string())
        }
        Error::NoSolution(_) => LinAlgError::new_err(err.to_string()),
    }
}

/// A 2-D float64 numpy array (any strides) as an owned nalgebra matrix.
pub(crate) fn to_dmatrix(a: &PyReadonlyArray2<'_, f64>) -> DMatrix<f64> {
    let v = a.as_array();
    let (r, c) = v.dim();
    DMatrix::from_fn(r, c, |i, j| v[[i, j]])
}

/// An nalgebra matrix as a new C-ordered numpy array.
pub(crate) fn from_dmatrix<'py>(py: Python<'py>, m: &DMatrix<f64>) -> Bound<'py, PyArray2<f64>> {
    let out = PyArray2::<f64>::zeros(py, [m.nrows(), m.ncols()], false);
    {
        let mut rw = out.readwrite();
        let mut v = rw.as_array_mut();
        for ((i, j), x) in v.indexed_iter_mut() {
            *x = m[(i, j)];
        }
    }
    out
}

/// The slice of an optional read-write borrow (e.g. of a residual buffer).
pub(crate) fn opt_slice<'a, T: numpy::Element, D: numpy::ndarray::Dimension>(
    a: &'a mut Option<numpy::PyReadwriteArray<'_, T, D>>,
) -> PyResult<Option<&'a mut [T]>> {
    Ok(a.as_mut().map(|r| r.as_slice_mut()).transpose()?)
}

/// The estimate buffer `out` (component planes on axis 0, each plane
/// C-contiguous) as one slice from its first element to its last: the
/// planes back to back, or at a larger plane stride (the padded layout of
/// `abkit_core::planes`, which the kernels recognise by the slice's length
/// and check). The padding between planes is inside the slice but never
/// read or written.
pub(crate) fn planes_slice<'a, T: numpy::Element, D: numpy::ndarray::Dimension>(
    rw: &'a mut numpy::PyReadwriteArray<'_, T, D>,
) -> PyResult<&'a mut [T]> {
    if rw.is_c_contiguous() {
        return Ok(rw.as_slice_mut()?);
    }
    let shape = rw.shape().to_vec();
    let strides = rw.strides().to_vec();
    if shape.contains(&0) {
        return Ok(&mut []);
    }
    let size = std::mem::size_of::<T>() as isize;
    let mut want = size;
    for k in (1..shape.len()).rev() {
        if shape[k] > 1 && strides[k] != want {
            return Err(PyValueError::new_err(
                "out: each component plane out[i] must be C-contiguous",
            ));
        }
        want *= shape[k] as isize;
    }
    let per: usize = shape[1..].iter().product();
    let s0 = strides.first().copied().unwrap_or(want);
    if shape[0] > 1 && (s0 < want || s0 % size != 0) {
        return Err(PyValueError::new_err(
            "out: the component planes must follow each other in memory, each whole",
        ));
    }
    let span = (shape[0] - 1) * (s0 / size) as usize + per;
    let ptr = rw.as_array_mut().as_mut_ptr();
    // SAFETY: the planes lie at `ptr + i * s0` (i < shape[0]), each `per`
    // contiguous elements (checked above), so [ptr, ptr + span) is inside
    // the array's memory; the read-write borrow makes it exclusive, and
    // the slice's lifetime is that of the borrow.
    Ok(unsafe { std::slice::from_raw_parts_mut(ptr, span) })
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
