//! Bindings of `abkit_core::ragged` and `abkit_core::irregular` (see
//! `python/abkit/filters.py`): the track kernel over ragged or rectangular
//! batches with optional timestamps.
//!
//! The Python layer validates and views `z` as `(rows, row_len, m)` (one row
//! of all samples for a flat ragged batch, or the rectangular tracks) and
//! `t` as `(rows, row_len)` without copying, and allocates the outputs.

use crate::convert::{opt_slice, to_pyerr};
use crate::filter::{ab_param_rows, parse_init, run_detached};
use abkit_core::filter::f32arith::filter_ab_f32_tracks;
use abkit_core::filter::{states_from_f64, IoFloat};
use abkit_core::irregular::{AbBackward, Kin3Backward};
use abkit_core::irregular::{
    AbDesign, AbFixed, AbgDesign, AbgFixed, Constant, GainLaw, SingerDesign, Step,
};
use abkit_core::ragged::{
    filter_tracks, AbSmooth, ConstSmooth, Counts, Kin3Smooth, NoPost, Options, PostTrack, Samples,
    TrackFilter,
};
use numpy::ndarray::{ArrayView2, ArrayView3};
use numpy::{
    Element, PyArray2, PyArray3, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2,
    PyReadonlyArray3,
};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;

/// Any-strides view as `Samples` (rows, row_len, m).
pub(crate) fn samples<'a, T: Copy>(
    ptr: *const T,
    dims: [usize; 3],
    s: [isize; 3],
) -> Samples<'a, T> {
    let [rows, len, m] = dims;
    if rows == 0 || len == 0 || m == 0 {
        return Samples {
            data: &[],
            base: 0,
            s_row: 0,
            s_sample: 0,
            s_comp: 0,
            row_len: len,
            n_rows: rows,
            m,
        };
    }
    let (mut lo, mut hi) = (0isize, 0isize);
    for (d, st) in dims.iter().zip(s) {
        let span = (*d as isize - 1) * st;
        lo += span.min(0);
        hi += span.max(0);
    }
    // SAFETY: every element of the view lies in [ptr + lo, ptr + hi]
    // (elements, same allocation, owned by the numpy array that the caller's
    // readonly borrow keeps alive and unmodified for 'a).
    let data = unsafe { std::slice::from_raw_parts(ptr.offset(lo), (hi - lo + 1) as usize) };
    Samples {
        data,
        base: (-lo) as usize,
        s_row: s[0],
        s_sample: s[1],
        s_comp: s[2],
        row_len: len,
        n_rows: rows,
        m,
    }
}

fn z_samples<'a, T: Copy>(v: &ArrayView3<'a, T>) -> Samples<'a, T> {
    let (r, l, m) = v.dim();
    let s = v.strides();
    samples(v.as_ptr(), [r, l, m], [s[0], s[1], s[2]])
}

fn t_samples<'a>(v: &ArrayView2<'a, f64>) -> Samples<'a, f64> {
    let (r, l) = v.dim();
    let s = v.strides();
    samples(v.as_ptr(), [r, l, 1], [s[0], s[1], 1])
}

/// The gain law of a filter, by kind, with its parameter rows.
pub(crate) enum Law {
    Constant(Vec<f64>),
    AbFixed(Vec<AbFixed>),
    AbDesign(Vec<AbDesign>),
    AbgFixed(Vec<AbgFixed>),
    AbgDesign(Vec<AbgDesign>),
    Singer(Vec<SingerDesign>),
}

pub(crate) fn parse_law(kind: &str, params: &[f64], width: usize) -> PyResult<Law> {
    let need = match kind {
        "constant" => width,
        "ab-fixed" => 2,
        "ab-design" => 1,
        "abg-fixed" => 3,
        "abg-design" => 4,
        "singer" => 3,
        _ => {
            return Err(PyValueError::new_err(format!("unknown gain law {kind:?}")));
        }
    };
    if need == 0 || params.is_empty() || !params.len().is_multiple_of(need) {
        return Err(PyValueError::new_err(
            "gain law parameters have the wrong size",
        ));
    }
    let rows = params.chunks_exact(need);
    let err = |e| to_pyerr((0, e));
    Ok(match kind {
        "constant" => Law::Constant(params.to_vec()),
        "ab-fixed" => Law::AbFixed(
            rows.map(|r| AbFixed {
                alpha: r[0],
                beta: r[1],
            })
            .collect(),
        ),
        "ab-design" => Law::AbDesign(rows.map(|r| AbDesign::new(r[0])).collect()),
        "abg-fixed" => Law::AbgFixed(
            rows.map(|r| AbgFixed {
                alpha: r[0],
                beta: r[1],
                cgamma: r[2],
            })
            .collect(),
        ),
        "abg-design" => Law::AbgDesign(
            rows.map(|r| AbgDesign::new(r[0], r[1], r[2], r[3]))
                .collect::<abkit_core::Result<_>>()
                .map_err(err)?,
        ),
        _ => Law::Singer(
            rows.map(|r| SingerDesign::new(r[0], r[1], r[2]))
                .collect::<abkit_core::Result<_>>()
                .map_err(err)?,
        ),
    })
}

struct Io<'py, T: Element> {
    z: Bound<'py, PyArray3<T>>,
    out: Bound<'py, PyArray2<T>>,
    resid: Option<Bound<'py, PyArray2<T>>>,
}

#[allow(clippy::too_many_arguments)]
fn run_typed<
    'py,
    T: IoFloat + Element,
    L: GainLaw<N, M>,
    P: PostTrack<T, N>,
    const N: usize,
    const M: usize,
>(
    py: Python<'py>,
    io: Io<'py, T>,
    t: Option<&PyReadonlyArray2<'py, f64>>,
    offsets: &[i64],
    laws: &[L],
    h: &[f64],
    h_pinv: &[f64],
    opts: Options,
    state: &Bound<'py, PyArray2<f64>>,
    counts: &Bound<'py, PyArray2<i64>>,
    threads: Option<usize>,
    post: &P,
) -> PyResult<bool> {
    if h.len() != N * M || h_pinv.len() != N * M {
        return Err(PyValueError::new_err("H has the wrong size"));
    }
    let filt = TrackFilter {
        laws,
        h: std::array::from_fn(|j| std::array::from_fn(|i| h[j * N + i])),
        h_pinv: std::array::from_fn(|i| std::array::from_fn(|j| h_pinv[i * M + j])),
    };
    let zr = io.z.readonly();
    let zv = zr.as_array();
    let zs = z_samples(&zv);
    let tv = t.map(|t| t.as_array());
    let ts = tv.as_ref().map(t_samples);
    let mut out_rw = io.out.readwrite();
    let out = crate::convert::planes_slice(&mut out_rw)?;
    let mut resid_rw = io.resid.as_ref().map(|r| r.readwrite());
    let resid = opt_slice(&mut resid_rw)?;
    let mut st_rw = state.readwrite();
    let states = states_from_f64(st_rw.as_slice_mut()?).map_err(|e| to_pyerr((0, e)))?;
    let mut ct_rw = counts.readwrite();
    let ct_flat = ct_rw.as_slice_mut()?;
    if !ct_flat.len().is_multiple_of(2) {
        return Err(PyValueError::new_err("counts must have 2 columns"));
    }
    // SAFETY: [i64; 2] has the layout of two consecutive i64; the slice is
    // reborrowed exclusively.
    let cts: &mut [Counts] = unsafe {
        std::slice::from_raw_parts_mut(ct_flat.as_mut_ptr().cast::<Counts>(), ct_flat.len() / 2)
    };
    run_detached(py, threads, |par| {
        filter_tracks(
            &filt,
            &opts,
            offsets,
            &zs,
            ts.as_ref(),
            states,
            out,
            resid,
            cts,
            par,
            post,
        )
        .map(|()| crate::filter::not_finite(states, N))
    })
}

pub(crate) fn constant_laws<const N: usize, const M: usize>(
    p: &[f64],
) -> PyResult<Vec<Constant<N, M>>> {
    let w = N * N + N * M;
    if p.is_empty() || !p.len().is_multiple_of(w) {
        return Err(PyValueError::new_err("Phi, K sizes do not match n, m"));
    }
    Ok(p.chunks_exact(w)
        .map(|c| {
            Constant(Step {
                phi: std::array::from_fn(|i| std::array::from_fn(|j| c[i * N + j])),
                k: std::array::from_fn(|i| std::array::from_fn(|j| c[N * N + i * M + j])),
            })
        })
        .collect())
}

/// The track kernel. `z` is `(rows, row_len, m)`, `t` `(rows, row_len)` or
/// None, `offsets` int64 `(n_tracks + 1,)`, `law` one of "constant" (params
/// rows `Phi (n*n) | K (n*m)`), "ab-fixed" (alpha, beta), "ab-design"
/// (sigma_w/sigma_v), "abg-fixed" (alpha, beta, c*gamma), "abg-design"
/// (sigma_p, sigma_v, sigma_a, sigma_m), "singer" (tau, q, sigma_pos);
/// `smoother`: None, "const" (rows `Phi | A`), "ab" (alpha-beta laws, rows
/// of 5) or "kin3" (3-state kinematic laws, rows of 10; see below);
/// `out` `(n, N)`, `resid` `(N, m)`, `state` `(n_tracks, STATE_WIDTH)`,
/// `counts` int64 `(n_tracks, 2)`. Returns whether some started track's
/// final state is not finite (the caller then finds which).
#[pyfunction]
#[pyo3(name = "filter_tracks", signature = (z, t, offsets, n, m, law, params, h, h_pinv, t_nominal, init, max_gap, drop_duplicates, state, out, counts, resid=None, threads=None, smoother=None, smoother_params=None, lag=None))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn filter_tracks_py<'py>(
    py: Python<'py>,
    z: &Bound<'py, PyAny>,
    t: Option<PyReadonlyArray2<'py, f64>>,
    offsets: PyReadonlyArray1<'py, i64>,
    n: usize,
    m: usize,
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
    resid: Option<&Bound<'py, PyAny>>,
    threads: Option<usize>,
    smoother: Option<&str>,
    smoother_params: Option<PyReadonlyArray1<'py, f64>>,
    lag: Option<usize>,
) -> PyResult<bool> {
    let sp: &[f64] = match &smoother_params {
        Some(a) => a.as_slice()?,
        None => &[],
    };
    let opts = Options {
        init: parse_init(init)?,
        t_nominal,
        max_gap,
        drop_duplicates,
    };
    let law = parse_law(law, params.as_slice()?, n * n + n * m)?;
    let offsets = offsets.as_slice()?;
    let (h, hp) = (h.as_slice()?, h_pinv.as_slice()?);
    let is64 = if z.cast::<PyArray3<f64>>().is_ok() {
        true
    } else if z.cast::<PyArray3<f32>>().is_ok() {
        false
    } else {
        return Err(PyTypeError::new_err(
            "z must be a 3-D float32 or float64 array",
        ));
    };
    macro_rules! typed {
        ($laws:expr, $n:literal, $m:literal) => {{
            match smoother {
                None => typed!($laws, $n, $m, &NoPost),
                Some("const") => {
                    let w = $n * $n;
                    if sp.is_empty() || !sp.len().is_multiple_of(2 * w) {
                        return Err(PyValueError::new_err("smoother gains have the wrong size"));
                    }
                    let rows = || sp.chunks_exact(2 * w);
                    let mat = |c: &[f64]| -> [[f64; $n]; $n] {
                        std::array::from_fn(|i| std::array::from_fn(|j| c[i * $n + j]))
                    };
                    let phi: Vec<[[f64; $n]; $n]> = rows().map(|r| mat(&r[..w])).collect();
                    let a: Vec<[[f64; $n]; $n]> = rows().map(|r| mat(&r[w..])).collect();
                    typed!(
                        $laws,
                        $n,
                        $m,
                        &ConstSmooth {
                            phi: &phi,
                            a: &a,
                            lag
                        }
                    )
                }
                Some(other) => Err(PyValueError::new_err(format!(
                    "smoother {other:?} does not apply to this filter"
                ))),
            }
        }};
        ($laws:expr, $n:literal, $m:literal, $post:expr) => {{
            if is64 {
                let io = Io::<f64> {
                    z: z.cast::<PyArray3<f64>>()?.clone(),
                    out: out.cast::<PyArray2<f64>>()?.clone(),
                    resid: resid
                        .map(|r| r.cast::<PyArray2<f64>>().cloned())
                        .transpose()?,
                };
                run_typed::<f64, _, _, $n, $m>(
                    py,
                    io,
                    t.as_ref(),
                    offsets,
                    $laws,
                    h,
                    hp,
                    opts,
                    &state,
                    &counts,
                    threads,
                    $post,
                )
            } else {
                let io = Io::<f32> {
                    z: z.cast::<PyArray3<f32>>()?.clone(),
                    out: out.cast::<PyArray2<f32>>()?.clone(),
                    resid: resid
                        .map(|r| r.cast::<PyArray2<f32>>().cloned())
                        .transpose()?,
                };
                run_typed::<f32, _, _, $n, $m>(
                    py,
                    io,
                    t.as_ref(),
                    offsets,
                    $laws,
                    h,
                    hp,
                    opts,
                    &state,
                    &counts,
                    threads,
                    $post,
                )
            }
        }};
    }
    let kin = |want: usize| -> PyResult<()> {
        if n == want && m == 1 {
            Ok(())
        } else {
            Err(PyValueError::new_err("gain law does not match n, m"))
        }
    };
    // Alpha-beta smoother: rows (kind, p1..p4): kind 0 = per-dt design
    // (p1 = sigma_w / sigma_v), 1 = fixed normalised gain A_N (p1..p4).
    let ab_back = || -> PyResult<Vec<AbBackward>> {
        if sp.is_empty() || !sp.len().is_multiple_of(5) {
            return Err(PyValueError::new_err(
                "alpha-beta smoother parameters have the wrong size",
            ));
        }
        Ok(sp
            .chunks_exact(5)
            .map(|r| {
                if r[0] == 0.0 {
                    AbBackward::Design(r[1])
                } else {
                    AbBackward::Fixed([[r[1], r[2]], [r[3], r[4]]])
                }
            })
            .collect())
    };
    fn ab_post(back: &[AbBackward], t_nominal: f64, lag: Option<usize>) -> AbSmooth<'_> {
        AbSmooth {
            back,
            t_nominal,
            lag,
        }
    }
    // 3-state kinematic smoother: rows (kind, p1..p9): kind 0 = per-dt
    // alpha-beta-gamma design (p1..p4 = sigma_p, sigma_v, sigma_a,
    // sigma_m), 1 = per-dt Singer design (p1..p3 = tau, q, sigma_pos),
    // 2 = fixed normalised gain A_N (p1..p9, row-major).
    let kin3_back = || -> PyResult<Vec<Kin3Backward>> {
        if sp.is_empty() || !sp.len().is_multiple_of(10) {
            return Err(PyValueError::new_err(
                "3-state smoother parameters have the wrong size",
            ));
        }
        let err = |e| to_pyerr((0, e));
        sp.chunks_exact(10)
            .map(|r| match r[0] {
                0.0 => AbgDesign::new(r[1], r[2], r[3], r[4])
                    .map(|d| Kin3Backward::AbgDesign(d.noise))
                    .map_err(err),
                1.0 => SingerDesign::new(r[1], r[2], r[3])
                    .map(|d| Kin3Backward::Singer {
                        tau: d.tau,
                        q: d.q,
                        sigma_pos: d.sigma_pos,
                    })
                    .map_err(err),
                2.0 if r[1..].iter().all(|v| v.is_finite()) => {
                    Ok(Kin3Backward::Fixed(std::array::from_fn(|i| {
                        std::array::from_fn(|j| r[1 + 3 * i + j])
                    })))
                }
                _ => Err(PyValueError::new_err(
                    "3-state smoother parameters: unknown kind or non-finite gain",
                )),
            })
            .collect()
    };
    fn kin3_post(back: &[Kin3Backward], t_nominal: f64, lag: Option<usize>) -> Kin3Smooth<'_> {
        Kin3Smooth {
            back,
            t_nominal,
            lag,
        }
    }
    match &law {
        Law::AbgFixed(l) if smoother == Some("kin3") => {
            kin(3)?;
            let b = kin3_back()?;
            typed!(l, 3, 1, &kin3_post(&b, t_nominal, lag))
        }
        Law::AbgDesign(l) if smoother == Some("kin3") => {
            kin(3)?;
            let b = kin3_back()?;
            typed!(l, 3, 1, &kin3_post(&b, t_nominal, lag))
        }
        Law::Singer(l) if smoother == Some("kin3") => {
            kin(3)?;
            let b = kin3_back()?;
            typed!(l, 3, 1, &kin3_post(&b, t_nominal, lag))
        }
        Law::AbFixed(l) if smoother == Some("ab") => {
            kin(2)?;
            let b = ab_back()?;
            typed!(l, 2, 1, &ab_post(&b, t_nominal, lag))
        }
        Law::AbDesign(l) if smoother == Some("ab") => {
            kin(2)?;
            let b = ab_back()?;
            typed!(l, 2, 1, &ab_post(&b, t_nominal, lag))
        }
        Law::AbFixed(l) => {
            kin(2)?;
            typed!(l, 2, 1)
        }
        Law::AbDesign(l) => {
            kin(2)?;
            typed!(l, 2, 1)
        }
        Law::AbgFixed(l) => {
            kin(3)?;
            typed!(l, 3, 1)
        }
        Law::AbgDesign(l) => {
            kin(3)?;
            typed!(l, 3, 1)
        }
        Law::Singer(l) => {
            kin(3)?;
            typed!(l, 3, 1)
        }
        Law::Constant(p) => {
            macro_rules! go {
                ($n:literal, $m:literal) => {{
                    let l = constant_laws::<$n, $m>(p)?;
                    typed!(&l, $n, $m)
                }};
            }
            dispatch!(n, m, go)
        }
    }
}

/// Alpha-beta over a ragged `float32` batch in `float32` arithmetic (the
/// `float32_arithmetic=True` route of `run(z, offsets=...)` without
/// timestamps): `z` `(rows, row_len, 1)` float32 (any strides), `offsets`
/// int64 `(n_tracks + 1,)`, `params` rows `(alpha, beta, T)`, `out` `(2, N)`
/// float32, `resid` `(N, 1)`, `state` `(n_tracks, STATE_WIDTH)`. Returns
/// whether some started track's final state is not finite.
#[pyfunction]
#[pyo3(name = "filter_tracks_f32", signature = (z, offsets, params, init, state, out, resid=None, threads=None))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn filter_tracks_f32_py<'py>(
    py: Python<'py>,
    z: PyReadonlyArray3<'py, f32>,
    offsets: PyReadonlyArray1<'py, i64>,
    params: PyReadonlyArray2<'py, f64>,
    init: &str,
    state: Bound<'py, PyArray2<f64>>,
    out: Bound<'py, PyArray2<f32>>,
    resid: Option<Bound<'py, PyArray2<f32>>>,
    threads: Option<usize>,
) -> PyResult<bool> {
    let init = parse_init(init)?;
    let p = ab_param_rows(&params)?;
    let zv = z.as_array();
    let zs = z_samples(&zv);
    let offsets = offsets.as_slice()?;
    let mut out_rw = out.readwrite();
    let out = crate::convert::planes_slice(&mut out_rw)?;
    let mut resid_rw = resid.as_ref().map(|r| r.readwrite());
    let resid = opt_slice(&mut resid_rw)?;
    let mut st_rw = state.readwrite();
    let states = states_from_f64(st_rw.as_slice_mut()?).map_err(|e| to_pyerr((0, e)))?;
    run_detached(py, threads, |par| {
        filter_ab_f32_tracks(&p, init, offsets, &zs, states, out, resid, par)
            .map(|()| crate::filter::not_finite(states, 2))
    })
}
