//! Binding of `abkit_core::feed`: a feed of reports in arrival order (rows
//! of many tracks interleaved), filtered row by row with per-track state
//! tables (see `python/abkit/frame.py`, which uses it for time-ordered
//! frames).

use crate::convert::{guard, opt_slice, to_pyerr};
use crate::filter::{parse_init, with_threads};
use crate::tracks::{constant_laws, parse_law, samples, Law};
use abkit_core::feed::{filter_feed, time_order, TrackRows};
use abkit_core::filter::{states_from_f64, IoFloat};
use abkit_core::irregular::GainLaw;
use abkit_core::ragged::{Counts, Options, Samples, TrackFilter};
use numpy::{Element, PyArray1, PyArray2, PyArray3, PyArrayMethods, PyReadonlyArray1};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;

fn column<'a, T: Copy>(a: &numpy::ndarray::ArrayView1<'a, T>) -> Samples<'a, T> {
    samples(a.as_ptr(), [1, a.len(), 1], [0, a.strides()[0], 1])
}

/// `(n_tracks, 2)` int64 as `[i64; 2]` rows.
fn pairs(a: &mut [i64]) -> PyResult<&mut [[i64; 2]]> {
    if !a.len().is_multiple_of(2) {
        return Err(PyValueError::new_err("counts and rows must have 2 columns"));
    }
    // SAFETY: [i64; 2] has the layout of two consecutive i64; the slice is
    // reborrowed exclusively.
    Ok(unsafe { std::slice::from_raw_parts_mut(a.as_mut_ptr().cast::<[i64; 2]>(), a.len() / 2) })
}

#[allow(clippy::too_many_arguments)]
fn feed_typed<'py, T: IoFloat + Element, L: GainLaw<N, M>, const N: usize, const M: usize>(
    py: Python<'py>,
    zs: &[Bound<'py, PyAny>],
    out: &Bound<'py, PyAny>,
    resid: Option<&Bound<'py, PyAny>>,
    t: Option<&PyReadonlyArray1<'py, f64>>,
    codes: &[i64],
    laws: &[L],
    h: &[f64],
    h_pinv: &[f64],
    opts: Options,
    state: &Bound<'py, PyArray2<f64>>,
    counts: &Bound<'py, PyArray2<i64>>,
    rows: &Bound<'py, PyArray2<i64>>,
    threads: Option<usize>,
) -> PyResult<()> {
    if h.len() != N * M || h_pinv.len() != N * M {
        return Err(PyValueError::new_err("H has the wrong size"));
    }
    let filt = TrackFilter {
        laws,
        h: std::array::from_fn(|j| std::array::from_fn(|i| h[j * N + i])),
        h_pinv: std::array::from_fn(|i| std::array::from_fn(|j| h_pinv[i * M + j])),
    };
    let zr = zs
        .iter()
        .map(|z| Ok(z.cast::<PyArray1<T>>()?.readonly()))
        .collect::<PyResult<Vec<_>>>()?;
    let zv: Vec<_> = zr.iter().map(|r| r.as_array()).collect();
    let zsam: Vec<Samples<'_, T>> = zv.iter().map(column).collect();
    let tv = t.map(|t| t.as_array());
    let ts = tv.as_ref().map(column);
    let out = out.cast::<PyArray3<T>>()?;
    let mut out_rw = out.readwrite();
    let out = out_rw.as_slice_mut()?;
    let resid = resid
        .map(|r| r.cast::<PyArray2<T>>().cloned())
        .transpose()?;
    let mut resid_rw = resid.as_ref().map(|r| r.readwrite());
    let resid = opt_slice(&mut resid_rw)?;
    let mut st_rw = state.readwrite();
    let states = states_from_f64(st_rw.as_slice_mut()?).map_err(|e| to_pyerr((0, e)))?;
    let mut ct_rw = counts.readwrite();
    let cts: &mut [Counts] = pairs(ct_rw.as_slice_mut()?)?;
    let mut rows_rw = rows.readwrite();
    let rows_flat = pairs(rows_rw.as_slice_mut()?)?;
    let mut tr = vec![TrackRows::default(); rows_flat.len()];
    let res = py.detach(|| {
        guard(|| {
            with_threads(threads, |par| {
                filter_feed(
                    &filt,
                    &opts,
                    codes,
                    &zsam,
                    ts.as_ref(),
                    states,
                    out,
                    resid,
                    cts,
                    &mut tr,
                    par,
                )
            })
        })
    })??;
    for (o, r) in rows_flat.iter_mut().zip(&tr) {
        *o = [r.n, r.first];
    }
    res.map_err(|(c, e)| match e {
        abkit_core::Error::Data { .. } => PyValueError::new_err(format!("column {c}: {e}")),
        other => to_pyerr((0, other)),
    })
}

/// The feed kernel. `zs` a list of 1-D measurement columns (one dtype,
/// `n_rows` each), `t` float64 `(n_rows,)` or None, `codes` int64
/// `(n_rows,)` in `0..n_tracks`, `law`/`params`/`h`/`h_pinv`/`t_nominal`/
/// `init`/`max_gap`/`drop_duplicates` as for `filter_tracks`; `state`
/// `(n_columns * n_tracks, STATE_WIDTH)`, `out` `(n_columns, n, n_rows)`,
/// `resid` `(n_columns, n_rows)`, `counts` int64 `(n_tracks, 2)` (column 0's
/// `[n_dropped, n_restarts]`), `rows` int64 `(n_tracks, 2)` (`[n_rows,
/// first row]`). A data error's message starts `column c: track i, sample k`.
#[pyfunction]
#[pyo3(name = "filter_feed", signature = (zs, t, codes, n, law, params, h, h_pinv, t_nominal, init, max_gap, drop_duplicates, state, out, counts, rows, resid=None, threads=None))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn filter_feed_py<'py>(
    py: Python<'py>,
    zs: Vec<Bound<'py, PyAny>>,
    t: Option<PyReadonlyArray1<'py, f64>>,
    codes: PyReadonlyArray1<'py, i64>,
    n: usize,
    law: &str,
    params: PyReadonlyArray1<'py, f64>,
    h: PyReadonlyArray1<'py, f64>,
    h_pinv: PyReadonlyArray1<'py, f64>,
    t_nominal: f64,
    init: &str,
    max_gap: Option<f64>,
    drop_duplicates: bool,
    state: Bound<'py, PyArray2<f64>>,
    out: &Bound<'py, PyAny>,
    counts: Bound<'py, PyArray2<i64>>,
    rows: Bound<'py, PyArray2<i64>>,
    resid: Option<&Bound<'py, PyAny>>,
    threads: Option<usize>,
) -> PyResult<()> {
    let opts = Options {
        init: parse_init(init)?,
        t_nominal,
        max_gap,
        drop_duplicates,
    };
    let law = parse_law(law, params.as_slice()?, n * n + n)?;
    let codes = codes.as_slice()?;
    let (h, hp) = (h.as_slice()?, h_pinv.as_slice()?);
    let Some(z0) = zs.first() else {
        return Err(PyValueError::new_err("no measurement columns"));
    };
    let is64 = if z0.cast::<PyArray1<f64>>().is_ok() {
        true
    } else if z0.cast::<PyArray1<f32>>().is_ok() {
        false
    } else {
        return Err(PyTypeError::new_err(
            "zs must be 1-D float32 or float64 arrays",
        ));
    };
    macro_rules! typed {
        ($laws:expr, $n:literal) => {{
            if is64 {
                feed_typed::<f64, _, $n, 1>(
                    py,
                    &zs,
                    out,
                    resid,
                    t.as_ref(),
                    codes,
                    $laws,
                    h,
                    hp,
                    opts,
                    &state,
                    &counts,
                    &rows,
                    threads,
                )
            } else {
                feed_typed::<f32, _, $n, 1>(
                    py,
                    &zs,
                    out,
                    resid,
                    t.as_ref(),
                    codes,
                    $laws,
                    h,
                    hp,
                    opts,
                    &state,
                    &counts,
                    &rows,
                    threads,
                )
            }
        }};
    }
    let kin = |want: usize| -> PyResult<()> {
        if n == want {
            Ok(())
        } else {
            Err(PyValueError::new_err("gain law does not match n"))
        }
    };
    match &law {
        Law::AbFixed(l) => {
            kin(2)?;
            typed!(l, 2)
        }
        Law::AbDesign(l) => {
            kin(2)?;
            typed!(l, 2)
        }
        Law::AbgFixed(l) => {
            kin(3)?;
            typed!(l, 3)
        }
        Law::AbgDesign(l) => {
            kin(3)?;
            typed!(l, 3)
        }
        Law::Singer(l) => {
            kin(3)?;
            typed!(l, 3)
        }
        Law::Constant(p) => {
            macro_rules! go {
                ($n:literal) => {{
                    let l = constant_laws::<$n, 1>(p)?;
                    typed!(&l, $n)
                }};
            }
            match n {
                1 => go!(1),
                2 => go!(2),
                3 => go!(3),
                4 => go!(4),
                5 => go!(5),
                6 => go!(6),
                _ => Err(PyValueError::new_err(format!(
                    "state dimension must be 1..=6, got n={n}"
                ))),
            }
        }
    }
}

/// The stable order of timestamps (numpy's `argsort(t, kind="stable")`:
/// ties in row order, `-0.0 == 0.0`, NaN last), sorted in Rust on rayon's
/// pool without the GIL.
#[pyfunction]
#[pyo3(name = "time_order", signature = (t, threads=None))]
pub(crate) fn time_order_py<'py>(
    py: Python<'py>,
    t: PyReadonlyArray1<'py, f64>,
    threads: Option<usize>,
) -> PyResult<Bound<'py, PyArray1<i64>>> {
    let owned: Vec<f64>;
    let ts: &[f64] = match t.as_slice() {
        Ok(s) => s,
        Err(_) => {
            owned = t.as_array().iter().copied().collect();
            &owned
        }
    };
    let order = py.detach(|| guard(|| with_threads(threads, |par| time_order(ts, par))))??;
    Ok(PyArray1::from_vec(py, order))
}
