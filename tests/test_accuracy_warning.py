"""Numerical honesty (issue 8): on constructed ill-conditioned problems abkit
either holds its tolerance (``abkit._errors.ACCURACY_RTOL`` = 1e-6
relative) against an mpmath reference at 60 digits, or raises
``abkit.AccuracyWarning`` with an estimated error that is not optimistic by
more than a factor 10 -- never a silent large error.

References (nothing here calls abkit):

* DARE: the structure-preserving doubling iteration in mpmath
  (``X = A' X (I + G X)^-1 A + Q``, ``G = B R^-1 B'``), iterated to 60 digits;
* Lyapunov ``X = A X A' + Q``: the Kronecker linear system solved in mpmath.
"""

from __future__ import annotations

import re
import warnings

import mpmath
import numpy as np
import pytest

import abkit
from abkit import alphabeta, riccati, singer
from abkit._errors import ACCURACY_RTOL

mpmath.mp.dps = 60


def _mp(a) -> mpmath.matrix:
    return mpmath.matrix(np.asarray(a, dtype=float).tolist())


def dare_ref(A, B, Q, R) -> np.ndarray:
    """Stabilising DARE solution by doubling in mpmath."""
    A, B, Q, R = (_mp(x) for x in (A, B, Q, R))
    n = A.rows
    I = mpmath.eye(n)
    Ak, Gk, Hk = A, B * mpmath.inverse(R) * B.T, Q
    for _ in range(200):
        W = mpmath.inverse(I + Gk * Hk)
        A1 = Ak * W * Ak
        G1 = Gk + Ak * W * Gk * Ak.T
        H1 = Hk + Ak.T * Hk * W * Ak
        done = mpmath.mnorm(H1 - Hk, 1) <= mpmath.mpf(10) ** -55 * mpmath.mnorm(H1, 1)
        Ak, Gk, Hk = A1, G1, H1
        if done:
            break
    return np.array(Hk.tolist(), dtype=float)


def dlyap_ref(A, Q) -> np.ndarray:
    A, Q = np.asarray(A, float), np.asarray(Q, float)
    n = A.shape[0]
    M = mpmath.eye(n * n) - _mp(np.kron(A, A))
    x = mpmath.lu_solve(M, _mp(Q.reshape(-1, 1)))
    return np.array(x.tolist(), dtype=float).reshape(n, n)


def _call(f):
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        out = f()
    acc = [x for x in w if issubclass(x.category, abkit.AccuracyWarning)]
    return out, acc


def _estimate(ws) -> float:
    m = re.search(r"estimated relative error ([0-9.e+-]+)", str(ws[0].message))
    assert m, str(ws[0].message)
    return float(m.group(1))


def _honest(err: float, ws) -> None:
    if ws:
        est = _estimate(ws)
        assert est > ACCURACY_RTOL
        assert est >= err / 10, f"warning estimate {est:.2e} is optimistic: actual error {err:.2e}"
    else:
        assert err <= ACCURACY_RTOL, f"silent error {err:.2e} > {ACCURACY_RTOL:g}"


def _rel(x, ref) -> float:
    return float(np.linalg.norm(np.asarray(x) - ref) / np.linalg.norm(ref))


# Constant-velocity and constant-acceleration tracking with vanishing process
# noise: the steady-state filter's eigenvalues approach 1 as q -> 0.
def _cv(T=1.0):
    return np.array([[1.0, T], [0.0, 1.0]]), np.array([[1.0, 0.0]]), np.array([[T**4 / 4, T**3 / 2], [T**3 / 2, T**2]])


def _ca(T=1.0):
    F = np.array([[1.0, T, T * T / 2], [0.0, 1.0, T], [0.0, 0.0, 1.0]])
    g = np.array([[T**3 / 6], [T * T / 2], [T]])
    return F, np.array([[1.0, 0.0, 0.0]]), g @ g.T


@pytest.mark.parametrize("model", ["cv", "ca"])
@pytest.mark.parametrize("q", [1.0, 1e-6, 1e-12, 1e-20, 1e-28, 1e-32, 1e-36])
def test_kalman_steady_state_near_unit_circle(model, q):
    F, H, G = _cv() if model == "cv" else _ca()
    Q, R = q * G + 0.0, np.array([[1.0]])
    try:
        ks, ws = _call(lambda: riccati.kalman_steady_state(F, H, Q, R))
    except np.linalg.LinAlgError:
        return  # refused outright: honest too
    ref = dare_ref(F.T, H.T, Q, R)
    _honest(_rel(ks.P_pred, ref), ws)
    if q >= 1e-6:
        assert not ws, "a well-conditioned problem must not warn"


@pytest.mark.parametrize("delta", [1e-2, 1e-6, 1e-10, 1e-14])
def test_solve_dare_with_a_nearly_undamped_mode(delta):
    """a = 1 - delta scalar with weak control: closed loop close to 1."""
    A = np.array([[1.0 - delta, 1.0], [0.0, 0.5]])
    B = np.array([[0.0], [1.0]])
    Q = np.diag([delta, 1.0])
    R = np.array([[1.0]])
    try:
        X, ws = _call(lambda: riccati.solve_dare(A, B, Q, R))
    except np.linalg.LinAlgError:
        return
    _honest(_rel(X, dare_ref(A, B, Q, R)), ws)


@pytest.mark.parametrize("a", [0.5, 1e-4, 1e-7, 1e-9])
def test_fixed_gain_covariances_with_poles_near_one(a):
    """alpha-beta gains (a, a^2/2): poles approach 1 as a -> 0; the Lyapunov
    solve of ``covariances`` either holds tolerance or warns."""
    f = abkit.AlphaBetaFilter(a, a * a / 2, 1.0)
    Q = np.array([[0.25, 0.5], [0.5, 1.0]]) * 1e-6
    R = np.array([[1.0]])
    cov, ws = _call(lambda: f.covariances(Q, R))
    phi, k, h = f.Phi, f.K, f.H
    A = phi @ (np.eye(2) - k @ h)
    ref = dlyap_ref(A, phi @ k @ R @ k.T @ phi.T + Q)
    _honest(_rel(cov.predicted, ref), ws)
    if a == 0.5:
        assert not ws


@pytest.mark.parametrize("theta", [1e-3, 1e-6, 1e-9])
def test_singer_small_p2_near_unit_circle(theta):
    """Singer steady state with tiny manoeuvre noise: eigenvalues near 1.
    Reference: the DARE of the returned model, by mpmath doubling."""
    s, ws = _call(lambda: singer.steady_state(1.0, 1.0 / theta, 1e-7, 1.0, method="numeric"))
    ref = dare_ref(s.Phi.T, s.H.T, s.Q, s.R)
    _honest(_rel(s.P_pred, ref), ws)


@pytest.mark.parametrize("r", [1e-300, 1e-200, 1e-100, 1e-30, 1e30, 1e100, 1e200, 1e300])
def test_alphabeta_closed_forms_hold_tolerance_at_extreme_snr(r):
    """The closed forms keep full accuracy at any SNR (no warning needed):
    alpha = 1 - u^2, beta = 2 (1 - u)^2 with u from Kalata's lambda, in mpmath."""
    try:
        d, ws = _call(lambda: alphabeta.from_snr(r))
    except ValueError as exc:  # refused where the gains round to the stability boundary
        assert r > 1e30 and str(exc).startswith("r must be")
        return
    assert not ws
    with mpmath.workdps(80):
        lam = 2 * mpmath.sqrt(mpmath.mpf(r))
        s = mpmath.sqrt(lam * (lam + 8))
        u = 4 / (lam + 4 + s)  # sqrt(1 - alpha)
        v = (lam + s) / (lam + 4 + s)  # 1 - u, without cancellation
        alpha = v * (1 + u)
        beta = 2 * v * v  # 2 (2 - alpha) - 4 sqrt(1 - alpha) = 2 (1 - u)^2
    assert d.alpha == pytest.approx(float(alpha), rel=1e-13)
    assert d.beta == pytest.approx(float(beta), rel=1e-12)


def test_the_warning_path_is_exercised():
    """At least one constructed case above does warn (so the warning path,
    not only the tolerance path, is tested), with the estimate in the message."""
    F, H, G = _cv()
    _, ws = _call(lambda: riccati.kalman_steady_state(F, H, 1e-36 * G, [[1.0]]))
    assert ws and "estimated relative error" in str(ws[0].message)
    f = abkit.AlphaBetaFilter(1e-9, 5e-19, 1.0)
    _, ws = _call(lambda: f.covariances(np.array([[0.25, 0.5], [0.5, 1.0]]) * 1e-6, [[1.0]]))
    assert ws and issubclass(ws[0].category, UserWarning)


def test_accuracy_warning_is_exported_once():
    from abkit import _errors

    assert abkit.AccuracyWarning is _errors.AccuracyWarning
    assert issubclass(abkit.AccuracyWarning, UserWarning)
    assert "AccuracyWarning" in abkit.__all__
