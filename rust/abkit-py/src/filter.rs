//! Bindings of `abkit_core::filter` (see `python/abkit/filters.py`).
//!
//! The Python layer validates shapes and dtypes, reshapes measurements to a
//! 3-D view `(n_tracks, n_samples, m)` without copying, and allocates (or
//! checks) the output buffers; these functions only borrow, release the GIL
//! and run the kernels.

use crate::convert::{guard, opt_slice, to_pyerr};
use abkit_core::filter::f32arith::filter_ab_f32;
use abkit_core::filter::{
    filter_ab, filter_general, states_from_f64, Gains, Init, IoFloat, Measurements, Smoother,
    TrackState,
};
use numpy::ndarray::ArrayView3;
use numpy::{
    Element, PyArray2, PyArray3, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2,
    PyReadonlyArray3, PyReadwriteArray1,
};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use std::collections::HashMap;
use std::sync::{Arc, Mutex, OnceLock};

pub(crate) use abkit_core::filter::STATE_WIDTH;

pub(crate) fn parse_init(init: &str) -> PyResult<Init> {
    match init {
        "first" => Ok(Init::First),
        "two-point" => Ok(Init::TwoPoint),
        _ => Err(PyValueError::new_err(format!(
            "init must be 'two-point' or 'first', got {init:?}"
        ))),
    }
}

/// A view of any strides as core `Measurements`.
pub(crate) fn measurements<'a, T: IoFloat>(v: &ArrayView3<'a, T>) -> Measurements<'a, T> {
    let (nt, ns, m) = v.dim();
    let s = v.strides();
    if nt == 0 || ns == 0 || m == 0 {
        return Measurements {
            data: &[],
            base: 0,
            s_track: 0,
            s_sample: 0,
            s_comp: 0,
            n_tracks: nt,
            n_samples: ns,
            m,
        };
    }
    let dims = [nt, ns, m];
    let (mut lo, mut hi) = (0isize, 0isize);
    for (d, st) in dims.iter().zip(s) {
        let span = (*d as isize - 1) * st;
        lo += span.min(0);
        hi += span.max(0);
    }
    // SAFETY: every element of the view lies in [ptr + lo, ptr + hi]
    // (elements, same allocation, owned by the numpy array that the caller's
    // readonly borrow keeps alive and unmodified for 'a).
    let data = unsafe { std::slice::from_raw_parts(v.as_ptr().offset(lo), (hi - lo + 1) as usize) };
    Measurements {
        data,
        base: (-lo) as usize,
        s_track: s[0],
        s_sample: s[1],
        s_comp: s[2],
        n_tracks: nt,
        n_samples: ns,
        m,
    }
}

/// rayon pools for an explicit `threads=k`, built once per `k` and reused.
fn pool(k: usize) -> PyResult<Arc<rayon::ThreadPool>> {
    static POOLS: OnceLock<Mutex<HashMap<usize, Arc<rayon::ThreadPool>>>> = OnceLock::new();
    let mut map = POOLS
        .get_or_init(|| Mutex::new(HashMap::new()))
        .lock()
        .map_err(|_| PyValueError::new_err("thread pool registry poisoned"))?;
    if let Some(p) = map.get(&k) {
        return Ok(p.clone());
    }
    let p = Arc::new(
        rayon::ThreadPoolBuilder::new()
            .num_threads(k)
            .build()
            .map_err(|e| PyValueError::new_err(format!("threads={k}: {e}")))?,
    );
    map.insert(k, p.clone());
    Ok(p)
}

/// Fault in the pages of a fresh output buffer (`buf`: its bytes), one
/// write per 4 KiB page, on rayon's pool unless `threads == 1`.
#[pyfunction]
#[pyo3(signature = (buf, threads=None))]
pub(crate) fn prefault<'py>(
    py: Python<'py>,
    mut buf: PyReadwriteArray1<'py, u8>,
    threads: Option<usize>,
) -> PyResult<()> {
    let s = buf.as_slice_mut()?;
    py.detach(|| guard(|| with_threads(threads, |par| abkit_core::batch::touch_pages(s, par))))??;
    Ok(())
}

/// The plane stride (elements) of the padded output layout for `n` planes
/// of `per` elements of `itemsize` bytes (4 or 8) in rows of `row` (`0`:
/// flat): `abkit_core::planes::padded_stride`, the one definition the
/// kernels check `out=` against.
#[pyfunction]
pub(crate) fn plane_stride(n: usize, per: usize, row: usize, itemsize: usize) -> PyResult<usize> {
    let s = match itemsize {
        8 => guard(|| abkit_core::planes::padded_stride::<f64>(n, per, row))?,
        4 => guard(|| abkit_core::planes::padded_stride::<f32>(n, per, row))?,
        _ => return Err(PyValueError::new_err("itemsize must be 4 or 8")),
    };
    s.ok_or_else(|| PyValueError::new_err("the output is too large"))
}

/// Release the GIL and run the kernel call `f(parallel)` per `threads` (see
/// [`with_threads`]): a panic and the kernel's error become Python
/// exceptions.
pub(crate) fn run_detached<R: Send>(
    py: Python<'_>,
    threads: Option<usize>,
    f: impl FnOnce(bool) -> abkit_core::Result<R> + Send,
) -> PyResult<R> {
    py.detach(|| guard(|| with_threads(threads, f)))??
        .map_err(|e| to_pyerr((0, e)))
}

/// Alpha-beta parameter rows `(alpha, beta, T)` of a `(P, 3)` array.
pub(crate) fn ab_param_rows(params: &PyReadonlyArray2<'_, f64>) -> PyResult<Vec<(f64, f64, f64)>> {
    Ok(params
        .as_slice()?
        .chunks_exact(3)
        .map(|r| (r[0], r[1], r[2]))
        .collect())
}

/// Run `f(parallel)` per the `threads` argument: None = rayon's global pool,
/// 1 = this thread, k = a cached pool of k threads.
pub(crate) fn with_threads<R: Send>(
    threads: Option<usize>,
    f: impl FnOnce(bool) -> R + Send,
) -> PyResult<R> {
    match threads {
        None => Ok(f(true)),
        Some(0) => Err(PyValueError::new_err("threads must be >= 1 or None")),
        Some(1) => Ok(f(false)),
        Some(k) => Ok(pool(k)?.install(|| f(true))),
    }
}

struct Buffers<'py, T: Element> {
    out: Bound<'py, PyArray3<T>>,
    resid: Option<Bound<'py, PyArray3<T>>>,
    state: Bound<'py, PyArray2<f64>>,
}

/// Run a batch kernel; returns whether some started track's final state is
/// not finite (the caller then finds which; `n`: states per track).
fn run_typed<'py, T: IoFloat + Element>(
    py: Python<'py>,
    z: PyReadonlyArray3<'py, T>,
    bufs: Buffers<'py, T>,
    threads: Option<usize>,
    n: usize,
    run: impl FnOnce(
            &Measurements<'_, T>,
            &mut [TrackState],
            &mut [T],
            Option<&mut [T]>,
            bool,
        ) -> abkit_core::Result<()>
        + Send,
) -> PyResult<bool> {
    let view = z.as_array();
    let meas = measurements(&view);
    let mut out_rw = bufs.out.readwrite();
    let out = crate::convert::planes_slice(&mut out_rw)?;
    let mut resid_rw = bufs.resid.as_ref().map(|r| r.readwrite());
    let resid = opt_slice(&mut resid_rw)?;
    let mut st_rw = bufs.state.readwrite();
    let packed = st_rw.as_slice_mut()?;
    if packed.len() != meas.n_tracks * STATE_WIDTH {
        return Err(PyValueError::new_err(
            "state has the wrong number of tracks",
        ));
    }
    let states = states_from_f64(packed).map_err(|e| to_pyerr((0, e)))?;
    run_detached(py, threads, |par| {
        run(&meas, states, out, resid, par).map(|()| not_finite(states, n))
    })
}

/// Whether a started track's state is not finite (a held first position,
/// or any of the `n` states of a running track).
pub(crate) fn not_finite(states: &[TrackState], n: usize) -> bool {
    let n = n.min(abkit_core::filter::MAX_STATES);
    states.iter().any(|s| {
        (s.phase == 1.0 && !s.x[0].is_finite())
            || (s.phase >= 2.0 && !s.x[..n].iter().all(|v| v.is_finite()))
    })
}

fn dispatch_dtype<'py>(
    z: &Bound<'py, PyAny>,
    out: &Bound<'py, PyAny>,
    resid: Option<&Bound<'py, PyAny>>,
) -> PyResult<bool> {
    // true = float64, false = float32
    let is64 = if z.cast::<PyArray3<f64>>().is_ok() {
        true
    } else if z.cast::<PyArray3<f32>>().is_ok() {
        false
    } else {
        return Err(PyTypeError::new_err(
            "z must be a 3-D float32 or float64 array",
        ));
    };
    let ok = |a: &Bound<'py, PyAny>| {
        if is64 {
            a.cast::<PyArray3<f64>>().is_ok()
        } else {
            a.cast::<PyArray3<f32>>().is_ok()
        }
    };
    if !ok(out) || resid.is_some_and(|r| !ok(r)) {
        return Err(PyTypeError::new_err(
            "out and residuals must have the dtype of z",
        ));
    }
    Ok(is64)
}

macro_rules! typed {
    ($py:expr, $is64:expr, $z:expr, $out:expr, $resid:expr, $state:expr, $threads:expr, $n:expr, $run:expr) => {
        if $is64 {
            run_typed::<f64>(
                $py,
                $z.cast::<PyArray3<f64>>()?.readonly(),
                Buffers {
                    out: $out.cast::<PyArray3<f64>>()?.clone(),
                    resid: $resid
                        .map(|r| r.cast::<PyArray3<f64>>().cloned())
                        .transpose()?,
                    state: $state,
                },
                $threads,
                $n,
                $run,
            )
        } else {
            run_typed::<f32>(
                $py,
                $z.cast::<PyArray3<f32>>()?.readonly(),
                Buffers {
                    out: $out.cast::<PyArray3<f32>>()?.clone(),
                    resid: $resid
                        .map(|r| r.cast::<PyArray3<f32>>().cloned())
                        .transpose()?,
                    state: $state,
                },
                $threads,
                $n,
                $run,
            )
        }
    };
}

/// Alpha-beta filtering of `z` (n_tracks, n_samples, 1) into `out`
/// (2, n_tracks, n_samples); `params` rows are (alpha, beta, T).
/// `f32_arith`: float32 data in float32 arithmetic (no smoother).
#[pyfunction]
#[pyo3(signature = (z, params, init, state, out, resid=None, threads=None, smoother_gain=None, lag=None, f32_arith=false))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn filter_alphabeta<'py>(
    py: Python<'py>,
    z: &Bound<'py, PyAny>,
    params: PyReadonlyArray2<'py, f64>,
    init: &str,
    state: Bound<'py, PyArray2<f64>>,
    out: &Bound<'py, PyAny>,
    resid: Option<&Bound<'py, PyAny>>,
    threads: Option<usize>,
    smoother_gain: Option<PyReadonlyArray1<'py, f64>>,
    lag: Option<usize>,
    f32_arith: bool,
) -> PyResult<bool> {
    let a = smoother_gains::<2>(smoother_gain.as_ref())?;
    let init = parse_init(init)?;
    let p = ab_param_rows(&params)?;
    let is64 = dispatch_dtype(z, out, resid)?;
    if f32_arith && !is64 {
        if a.is_some() {
            return Err(PyValueError::new_err("float32 arithmetic has no smoother"));
        }
        let bufs = Buffers {
            out: out.cast::<PyArray3<f32>>()?.clone(),
            resid: resid
                .map(|r| r.cast::<PyArray3<f32>>().cloned())
                .transpose()?,
            state,
        };
        let z = z.cast::<PyArray3<f32>>()?.readonly();
        return run_typed::<f32>(py, z, bufs, threads, 2, |m, s, o, r, par| {
            filter_ab_f32(&p, init, m, s, o, r, par)
        });
    }
    let sm = a.as_deref().map(|a| Smoother { a, lag });
    typed!(
        py,
        is64,
        z,
        out,
        resid,
        state,
        threads,
        2,
        |m, s, o, r, par| { filter_ab(&p, init, m, s, o, r, par, sm) }
    )
}

fn smoother_gains<const N: usize>(
    a: Option<&PyReadonlyArray1<'_, f64>>,
) -> PyResult<Option<Vec<[[f64; N]; N]>>> {
    let Some(a) = a else { return Ok(None) };
    let s = a.as_slice()?;
    if s.is_empty() || s.len() % (N * N) != 0 {
        return Err(PyValueError::new_err("smoother gain has the wrong size"));
    }
    Ok(Some(
        s.chunks_exact(N * N)
            .map(|c| std::array::from_fn(|i| std::array::from_fn(|j| c[i * N + j])))
            .collect(),
    ))
}

fn gains<const N: usize, const M: usize>(
    phi: &[f64],
    h: &[f64],
    k: &[f64],
    h_pinv: &[f64],
    t: &[f64],
) -> Vec<Gains<N, M>> {
    (0..t.len())
        .map(|p| Gains {
            phi: std::array::from_fn(|i| std::array::from_fn(|j| phi[p * N * N + i * N + j])),
            h: std::array::from_fn(|i| std::array::from_fn(|j| h[p * M * N + i * N + j])),
            k: std::array::from_fn(|i| std::array::from_fn(|j| k[p * N * M + i * M + j])),
            h_pinv: std::array::from_fn(|i| std::array::from_fn(|j| h_pinv[p * N * M + i * M + j])),
            t: t[p],
        })
        .collect()
}

/// General fixed-gain filtering: `phi` (P, n, n), `h` (P, m, n), `k` and
/// `h_pinv` (P, n, m), `t` (P,) with P = 1 or n_tracks, flattened.
#[pyfunction]
#[pyo3(signature = (z, n, m, phi, h, k, h_pinv, t, init, state, out, resid=None, threads=None, smoother_gain=None, lag=None))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn filter_fixed_gain<'py>(
    py: Python<'py>,
    z: &Bound<'py, PyAny>,
    n: usize,
    m: usize,
    phi: PyReadonlyArray1<'py, f64>,
    h: PyReadonlyArray1<'py, f64>,
    k: PyReadonlyArray1<'py, f64>,
    h_pinv: PyReadonlyArray1<'py, f64>,
    t: PyReadonlyArray1<'py, f64>,
    init: &str,
    state: Bound<'py, PyArray2<f64>>,
    out: &Bound<'py, PyAny>,
    resid: Option<&Bound<'py, PyAny>>,
    threads: Option<usize>,
    smoother_gain: Option<PyReadonlyArray1<'py, f64>>,
    lag: Option<usize>,
) -> PyResult<bool> {
    let init = parse_init(init)?;
    let (phi, h, k, hp, t) = (
        phi.as_slice()?,
        h.as_slice()?,
        k.as_slice()?,
        h_pinv.as_slice()?,
        t.as_slice()?,
    );
    let np = t.len();
    if phi.len() != np * n * n
        || h.len() != np * m * n
        || k.len() != np * n * m
        || hp.len() != np * n * m
    {
        return Err(PyValueError::new_err("Phi, H, K sizes do not match n, m"));
    }
    let is64 = dispatch_dtype(z, out, resid)?;
    macro_rules! go {
        ($n:literal, $m:literal) => {{
            let g = gains::<$n, $m>(phi, h, k, hp, t);
            let a = smoother_gains::<$n>(smoother_gain.as_ref())?;
            let sm = a.as_deref().map(|a| Smoother { a, lag });
            typed!(
                py,
                is64,
                z,
                out,
                resid,
                state,
                threads,
                n,
                |mm, s, o, r, par| { filter_general(&g, init, mm, s, o, r, par, sm) }
            )
        }};
    }
    dispatch!(n, m, go)
}
