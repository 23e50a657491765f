//! Bindings of `abkit_core::abg` (see `python/abkit/abg.py`).

use crate::convert::rows;
use abkit_core::abg::{self, Analysis, COLOURED_FIELDS, DECOUPLED_WIDTH, FIELDS};
use abkit_core::irregular;
use numpy::{PyArray2, PyReadonlyArray1};
use pyo3::prelude::*;

type Out<'py> = PyResult<Bound<'py, PyArray2<f64>>>;

/// Limiting Kalman gains [alpha, beta, gamma] (paper convention) for
/// Q = diag(sigma_p, sigma_v, sigma_a), R = sigma_m, period h.
#[pyfunction]
pub(crate) fn abg_from_noise<'py>(
    py: Python<'py>,
    sigma_p: PyReadonlyArray1<'py, f64>,
    sigma_v: PyReadonlyArray1<'py, f64>,
    sigma_a: PyReadonlyArray1<'py, f64>,
    sigma_m: PyReadonlyArray1<'py, f64>,
    h: PyReadonlyArray1<'py, f64>,
) -> Out<'py> {
    rows(
        py,
        [sigma_p, sigma_v, sigma_a, sigma_m, h],
        3,
        |[p, v, a, m, h], out| {
            out.copy_from_slice(&abg::from_noise(p, v, a, m, h)?);
            Ok(())
        },
    )
}

/// Normalised (h = 1) steady-state RTS backward gain `A_N` (row-major, 9
/// per row) of the noise design of `abg_from_noise` at period h, from the
/// noise itself (double-double; `abkit_core::irregular::abg_backward_design`).
#[pyfunction]
pub(crate) fn abg_backward_gain_noise<'py>(
    py: Python<'py>,
    sigma_p: PyReadonlyArray1<'py, f64>,
    sigma_v: PyReadonlyArray1<'py, f64>,
    sigma_a: PyReadonlyArray1<'py, f64>,
    sigma_m: PyReadonlyArray1<'py, f64>,
    h: PyReadonlyArray1<'py, f64>,
) -> Out<'py> {
    rows(
        py,
        [sigma_p, sigma_v, sigma_a, sigma_m, h],
        9,
        |[p, v, a, m, h], out| {
            let g = irregular::abg_backward_design(p, v, a, m, h)?;
            out.copy_from_slice(g.as_flattened());
            Ok(())
        },
    )
}

/// Normalised (h = 1) steady-state RTS backward gain `A_N` (row-major, 9
/// per row) of the Kalman-equivalent model of near-optimal gains (paper
/// convention; `abkit_core::irregular::abg_backward_normalised`).
#[pyfunction]
pub(crate) fn abg_backward_gain<'py>(
    py: Python<'py>,
    alpha: PyReadonlyArray1<'py, f64>,
    beta: PyReadonlyArray1<'py, f64>,
    gamma: PyReadonlyArray1<'py, f64>,
) -> Out<'py> {
    rows(py, [alpha, beta, gamma], 9, |[a, b, g], out| {
        let m = irregular::abg_backward_normalised(a, b, g)?;
        out.copy_from_slice(m.as_flattened());
        Ok(())
    })
}

/// Gains from the tracking index: model 0 acceleration-driven / discrete
/// white jerk (closed form), 1 continuous white jerk (Riccati).
#[pyfunction]
pub(crate) fn abg_from_tracking_index<'py>(
    py: Python<'py>,
    lam: PyReadonlyArray1<'py, f64>,
    continuous: bool,
) -> Out<'py> {
    rows(py, [lam], 3, |[l], out| {
        let g = if continuous {
            abg::from_tracking_index_continuous(l)?
        } else {
            abg::from_tracking_index(l)?
        };
        out.copy_from_slice(&g);
        Ok(())
    })
}

/// Corollary (iv)-(vi): [sigma_p, sigma_v, sigma_a] / sigma_m.
#[pyfunction]
pub(crate) fn abg_noise_ratios<'py>(
    py: Python<'py>,
    alpha: PyReadonlyArray1<'py, f64>,
    beta: PyReadonlyArray1<'py, f64>,
    gamma: PyReadonlyArray1<'py, f64>,
    h: PyReadonlyArray1<'py, f64>,
) -> Out<'py> {
    rows(py, [alpha, beta, gamma, h], 3, |[a, b, g, h], out| {
        out.copy_from_slice(&abg::noise_ratios(a, b, g, h)?);
        Ok(())
    })
}

/// Corollary (i)-(iii): [near_optimal, (i), (ii), min eig of P~].
#[pyfunction]
pub(crate) fn abg_conditions<'py>(
    py: Python<'py>,
    alpha: PyReadonlyArray1<'py, f64>,
    beta: PyReadonlyArray1<'py, f64>,
    gamma: PyReadonlyArray1<'py, f64>,
) -> Out<'py> {
    rows(py, [alpha, beta, gamma], 4, |[a, b, g], out| {
        out.copy_from_slice(&abg::near_optimal_conditions(a, b, g)?);
        Ok(())
    })
}

/// Steady-state analysis (rows of ABG_FIELDS).
#[pyfunction]
pub(crate) fn abg_analyze<'py>(
    py: Python<'py>,
    alpha: PyReadonlyArray1<'py, f64>,
    beta: PyReadonlyArray1<'py, f64>,
    gamma: PyReadonlyArray1<'py, f64>,
) -> Out<'py> {
    rows(py, [alpha, beta, gamma], FIELDS.len(), |[a, b, g], out| {
        Analysis::analyze(a, b, g)?.write_row(out);
        Ok(())
    })
}

/// Theorem 2 (rows of ABG_COLOURED_FIELDS).
#[pyfunction]
pub(crate) fn abg_coloured<'py>(
    py: Python<'py>,
    alpha: PyReadonlyArray1<'py, f64>,
    beta: PyReadonlyArray1<'py, f64>,
    gamma: PyReadonlyArray1<'py, f64>,
    theta: PyReadonlyArray1<'py, f64>,
    r: PyReadonlyArray1<'py, f64>,
    h: PyReadonlyArray1<'py, f64>,
) -> Out<'py> {
    rows(
        py,
        [alpha, beta, gamma, theta, r, h],
        COLOURED_FIELDS.len(),
        |[a, b, g, t, r, h], out| {
            out.copy_from_slice(&abg::coloured(a, b, g, t, r, h)?);
            Ok(())
        },
    )
}

/// Theorem 3 (rows of ABG_DECOUPLED_WIDTH).
#[pyfunction]
pub(crate) fn abg_decoupled<'py>(
    py: Python<'py>,
    alpha: PyReadonlyArray1<'py, f64>,
    beta: PyReadonlyArray1<'py, f64>,
    gamma: PyReadonlyArray1<'py, f64>,
    theta: PyReadonlyArray1<'py, f64>,
    r: PyReadonlyArray1<'py, f64>,
    h: PyReadonlyArray1<'py, f64>,
) -> Out<'py> {
    rows(
        py,
        [alpha, beta, gamma, theta, r, h],
        DECOUPLED_WIDTH,
        |[a, b, g, t, r, h], out| {
            out.copy_from_slice(&abg::decoupled(a, b, g, t, r, h)?);
            Ok(())
        },
    )
}

/// Jury stability margins (all > 0 iff stable).
#[pyfunction]
pub(crate) fn abg_jury<'py>(
    py: Python<'py>,
    alpha: PyReadonlyArray1<'py, f64>,
    beta: PyReadonlyArray1<'py, f64>,
    gamma: PyReadonlyArray1<'py, f64>,
) -> Out<'py> {
    rows(py, [alpha, beta, gamma], 4, |[a, b, g], out| {
        out.copy_from_slice(&abg::jury_margins(a, b, g)?);
        Ok(())
    })
}

/// Near-optimal alpha-beta-gamma-theta gains for coloured measurement noise.
#[pyfunction]
#[allow(clippy::too_many_arguments)]
pub(crate) fn abg_coloured_from_noise<'py>(
    py: Python<'py>,
    sigma_p: PyReadonlyArray1<'py, f64>,
    sigma_v: PyReadonlyArray1<'py, f64>,
    sigma_a: PyReadonlyArray1<'py, f64>,
    sigma_m: PyReadonlyArray1<'py, f64>,
    r: PyReadonlyArray1<'py, f64>,
    h: PyReadonlyArray1<'py, f64>,
) -> Out<'py> {
    rows(
        py,
        [sigma_p, sigma_v, sigma_a, sigma_m, r, h],
        4,
        |[p, v, a, m, r, h], out| {
            out.copy_from_slice(&abg::coloured_from_noise(p, v, a, m, r, h)?);
            Ok(())
        },
    )
}
