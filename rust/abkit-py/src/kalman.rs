//! Bindings of `abkit_core::kalman` (see `python/abkit/kalman.py`).

use crate::convert::{guard, opt_slice, to_pyerr};
use crate::filter::measurements;
use abkit_core::filter::{IoFloat, Measurements};
use abkit_core::kalman::{self, Model};
use numpy::{Element, PyArray1, PyArray3, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray3};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;

type Flat<'py> = PyReadonlyArray1<'py, f64>;

fn model<const N: usize, const M: usize>(
    phi: &[f64],
    h: &[f64],
    q: &[f64],
    r: &[f64],
) -> Model<N, M> {
    Model {
        phi: std::array::from_fn(|i| std::array::from_fn(|j| phi[i * N + j])),
        h: std::array::from_fn(|i| std::array::from_fn(|j| h[i * N + j])),
        q: std::array::from_fn(|i| std::array::from_fn(|j| q[i * N + j])),
        r: std::array::from_fn(|i| std::array::from_fn(|j| r[i * M + j])),
    }
}

fn sq<const N: usize>(p: &[f64]) -> [[f64; N]; N] {
    std::array::from_fn(|i| std::array::from_fn(|j| p[i * N + j]))
}

fn check(
    n: usize,
    m: usize,
    phi: &[f64],
    h: &[f64],
    q: &[f64],
    r: &[f64],
    p0: &[f64],
) -> PyResult<()> {
    if n == 0
        || m == 0
        || phi.len() != n * n
        || h.len() != m * n
        || q.len() != n * n
        || r.len() != m * m
        || p0.len() != n * n
    {
        return Err(PyValueError::new_err(
            "F, H, Q, R, P0 sizes do not match n, m",
        ));
    }
    Ok(())
}

/// Kalman gain sequence: returns (K (steps, n, m), P_prior (steps, n, n), P_post (steps, n, n)) flattened.
#[pyfunction]
#[allow(clippy::too_many_arguments, clippy::type_complexity)]
pub(crate) fn kalman_gain_sequence<'py>(
    py: Python<'py>,
    n: usize,
    m: usize,
    phi: Flat<'py>,
    h: Flat<'py>,
    q: Flat<'py>,
    r: Flat<'py>,
    p0: Flat<'py>,
    steps: usize,
) -> PyResult<(
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<f64>>,
)> {
    let (phi, h, q, r, p0) = (
        phi.as_slice()?,
        h.as_slice()?,
        q.as_slice()?,
        r.as_slice()?,
        p0.as_slice()?,
    );
    check(n, m, phi, h, q, r, p0)?;
    macro_rules! go {
        ($n:literal, $m:literal) => {{
            let md = model::<$n, $m>(phi, h, q, r);
            let p = sq::<$n>(p0);
            let (k, pri, post) = py
                .detach(|| guard(|| kalman::gain_sequence(&md, &p, steps)))?
                .map_err(|e| to_pyerr((0, e)))?;
            let flat =
                |v: Vec<[[f64; $m]; $n]>| v.into_iter().flatten().flatten().collect::<Vec<f64>>();
            let flatn =
                |v: Vec<[[f64; $n]; $n]>| v.into_iter().flatten().flatten().collect::<Vec<f64>>();
            Ok((
                PyArray1::from_vec(py, flat(k)),
                PyArray1::from_vec(py, flatn(pri)),
                PyArray1::from_vec(py, flatn(post)),
            ))
        }};
    }
    dispatch!(n, m, go)
}

#[allow(clippy::too_many_arguments)]
fn run_typed<'py, T: IoFloat + Element, const N: usize, const M: usize>(
    py: Python<'py>,
    md: &Model<N, M>,
    x0: &[[f64; N]],
    p0: &[[f64; N]; N],
    z: PyReadonlyArray3<'py, T>,
    out: &Bound<'py, PyArray3<T>>,
    resid: Option<&Bound<'py, PyArray3<T>>>,
    p_final: &Bound<'py, PyArray3<f64>>,
    parallel: bool,
) -> PyResult<()> {
    let view = z.as_array();
    let meas: Measurements<'_, T> = measurements(&view);
    let mut out_rw = out.readwrite();
    let o = crate::convert::planes_slice(&mut out_rw)?;
    let mut resid_rw = resid.map(|r| r.readwrite());
    let r = opt_slice(&mut resid_rw)?;
    let mut pf_rw = p_final.readwrite();
    let pf = pf_rw.as_slice_mut()?;
    py.detach(|| guard(|| kalman::run_batch(md, x0, p0, &meas, o, r, pf, parallel)))?
        .map_err(|e| to_pyerr((0, e)))
}

/// Kalman filtering of `z` (n_tracks, n_samples, m) into `out` (n, n_tracks,
/// n_samples); `x0` is (1 or n_tracks, n) flattened, `p_final` (n_tracks, n, n).
#[pyfunction]
#[pyo3(signature = (z, n, m, phi, h, q, r, x0, p0, out, p_final, resid=None, threads=None))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn kalman_run<'py>(
    py: Python<'py>,
    z: &Bound<'py, PyAny>,
    n: usize,
    m: usize,
    phi: Flat<'py>,
    h: Flat<'py>,
    q: Flat<'py>,
    r: Flat<'py>,
    x0: Flat<'py>,
    p0: Flat<'py>,
    out: &Bound<'py, PyAny>,
    p_final: Bound<'py, PyArray3<f64>>,
    resid: Option<&Bound<'py, PyAny>>,
    threads: Option<usize>,
) -> PyResult<()> {
    let (phi, h, q, r, x0, p0) = (
        phi.as_slice()?,
        h.as_slice()?,
        q.as_slice()?,
        r.as_slice()?,
        x0.as_slice()?,
        p0.as_slice()?,
    );
    check(n, m, phi, h, q, r, p0)?;
    if x0.is_empty() || x0.len() % n != 0 {
        return Err(PyValueError::new_err("x0 has the wrong size"));
    }
    if threads == Some(0) {
        return Err(PyValueError::new_err("threads must be >= 1 or None"));
    }
    let parallel = threads != Some(1);
    macro_rules! go {
        ($n:literal, $m:literal) => {{
            let md = model::<$n, $m>(phi, h, q, r);
            let p = sq::<$n>(p0);
            let xs: Vec<[f64; $n]> = x0
                .chunks_exact($n)
                .map(|c| std::array::from_fn(|i| c[i]))
                .collect();
            if let Ok(z64) = z.cast::<PyArray3<f64>>() {
                let o = out
                    .cast::<PyArray3<f64>>()
                    .map_err(|_| PyTypeError::new_err("out must have the dtype of z"))?;
                let rs = resid
                    .map(|r| r.cast::<PyArray3<f64>>())
                    .transpose()
                    .map_err(|_| PyTypeError::new_err("residuals must have the dtype of z"))?;
                run_typed::<f64, $n, $m>(
                    py,
                    &md,
                    &xs,
                    &p,
                    z64.readonly(),
                    o,
                    rs,
                    &p_final,
                    parallel,
                )
            } else if let Ok(z32) = z.cast::<PyArray3<f32>>() {
                let o = out
                    .cast::<PyArray3<f32>>()
                    .map_err(|_| PyTypeError::new_err("out must have the dtype of z"))?;
                let rs = resid
                    .map(|r| r.cast::<PyArray3<f32>>())
                    .transpose()
                    .map_err(|_| PyTypeError::new_err("residuals must have the dtype of z"))?;
                run_typed::<f32, $n, $m>(
                    py,
                    &md,
                    &xs,
                    &p,
                    z32.readonly(),
                    o,
                    rs,
                    &p_final,
                    parallel,
                )
            } else {
                Err(PyTypeError::new_err(
                    "z must be a 3-D float32 or float64 array",
                ))
            }
        }};
    }
    dispatch!(n, m, go)
}
