"""Accuracy of the steady-state RTS backward gain of alpha-beta-gamma filters.

``A = P Phi' M^-1`` (``M`` predicted, ``P`` filtered steady-state
covariance) is what ``AlphaBetaGammaFilter.smooth`` uses: from the noise
itself for a ``from_noise`` design (``smoother_gain()``, and per ``dt`` for
``smooth(t=...)``), from the gains' Kalman-equivalent model for fixed gains.

Independent reference: the filter-form Riccati equation solved by the
structure-preserving doubling algorithm in mpmath at 50 digits (as in
``tests/test_abg_accuracy.py``), then ``P = M - M H' H M / (H M H' + R)``
and ``A = P Phi' M^-1``, all at 50 digits. For fixed gains the model is the
noise of Chen & Chui's Corollary (iv)-(vi), evaluated at 50 digits from the
(exact) float64 gains.

Error measure (docs/abg.md, "Backward (smoother) gains"): the gain in
normalised units (``h = 1``: ``A_N = D A D^-1``, ``D = diag(1, h, h^2)``),
per row, relative to that row's largest entry. Stated tolerance:
``RTOL = 1e-13`` (measured maximum over the 1296-point sweep of
docs/abg_backward_sweep.py: 6e-14 for the design, 2e-16 for fixed gains). Before the double-double evaluation the design's gain
was off by up to ``eps / (1 - alpha)`` (5e-6 at ``q_a = 1e12``).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import pytest

from abkit import AlphaBetaGammaFilter, abg

mp = pytest.importorskip("mpmath")

from test_abg_accuracy import GRID, _physical  # noqa: E402

RTOL = 1e-13


def _sda(phi, q, r):
    """Predicted covariance M of the filter DARE at the working precision."""
    a = phi.T
    g = mp.zeros(3, 3)
    g[0, 0] = 1 / r
    hk = q
    eye = mp.eye(3)
    tol = mp.mpf(10) ** -44
    for _ in range(300):
        w = mp.inverse(eye + g * hk)
        a, g, hn = a * w * a, g + a * w * g * a.T, hk + a.T * hk * w * a
        change = mp.mnorm(hn - hk, 1) / mp.mnorm(hn, 1)
        hk = hn
        if change < tol and mp.mnorm(a, 1) < tol:
            return hk
    raise RuntimeError("SDA did not converge")  # pragma: no cover - the reference itself failed


def _rts_normalised(phi, q, r, h):
    m = _sda(phi, q, r)
    p = m - m[:, 0] * m[0, :] / (m[0, 0] + r)
    a = p * phi.T * mp.inverse(m)
    d = mp.diag([1, h, h * h])
    an = d * a * mp.inverse(d)
    return np.array([[float(an[i, j]) for j in range(3)] for i in range(3)])


@lru_cache(maxsize=None)
def ref_backward_noise(sp: float, sv: float, sa: float, sm: float, h: float) -> np.ndarray:
    """Normalised RTS gain of the physical noise model at step h, 50 digits."""
    with mp.workdps(50):
        sp_, sv_, sa_, sm_, h_ = (mp.mpf(x) for x in (sp, sv, sa, sm, h))
        phi = mp.matrix([[1, h_, h_ * h_ / 2], [0, 1, h_], [0, 0, 1]])
        return _rts_normalised(phi, mp.diag([sp_, sv_, sa_]), sm_, h_)


@lru_cache(maxsize=None)
def ref_backward_gains(alpha: float, beta: float, gamma: float) -> np.ndarray:
    """Normalised RTS gain of the Kalman-equivalent model of exact gains
    (Chen & Chui convention): Corollary (iv)-(vi) at 50 digits, h = 1."""
    with mp.workdps(50):
        a, b, g = (mp.mpf(x) for x in (alpha, beta, gamma))
        om = 1 - a
        q = mp.diag([(a * a + a * b + a * g / 2 - 2 * b) / om, (b * b - 2 * a * g) / om, g * g / om])
        phi = mp.matrix([[1, 1, mp.mpf(1) / 2], [0, 1, 1], [0, 0, 1]])
        return _rts_normalised(phi, q, mp.mpf(1), mp.mpf(1))


def row_error(a: np.ndarray, ref: np.ndarray) -> float:
    """Max over rows of max |a - ref| / max |ref| (row)."""
    return float(np.max(np.max(np.abs(a - ref), axis=1) / np.max(np.abs(ref), axis=1)))


def _normalise(a: np.ndarray, h: float) -> np.ndarray:
    d = np.array([1.0, h, h * h])
    return a * d[:, None] / d[None, :]


@pytest.mark.parametrize("qp,qv,qa,h", GRID)
def test_design_backward_gain_matches_50_digit_rts(qp, qv, qa, h):
    sp, sv, sa, sm = _physical(qp, qv, qa, h)
    ref = ref_backward_noise(sp, sv, sa, sm, h)
    f = AlphaBetaGammaFilter.from_noise(sp, sv, sa, sm, T=h)
    a = f.smoother_gain()
    assert a.shape == (1, 3, 3)
    err = row_error(_normalise(a[0], h), ref)
    assert err <= RTOL, err


@pytest.mark.parametrize("qp,qv,qa,h", GRID)
def test_fixed_gain_backward_gain_matches_50_digit_rts(qp, qv, qa, h):
    """The gains as given (here: a design's rounded gains, exact floats)."""
    sp, sv, sa, sm = _physical(qp, qv, qa, h)
    d = abg.from_noise(sp, sv, sa, sm, h, convention="chen-chui")
    al, be, ga = float(d.alpha), float(d.beta), float(d.gamma)
    ref = ref_backward_gains(al, be, ga)
    f = AlphaBetaGammaFilter(al, be, ga, h, convention="chen-chui")
    err = row_error(_normalise(f.smoother_gain()[0], h), ref)
    assert err <= RTOL, err


def _rts_loop(xf, dts, gains):
    """Plain-loop RTS over one track: x_s[k] = x_f[k] + A_k (x_s[k+1] - Phi_k x_f[k])."""
    xs = xf.copy()
    for k in range(xf.shape[0] - 2, -1, -1):
        dt = dts[k]
        phi = np.array([[1.0, dt, dt * dt / 2], [0.0, 1.0, dt], [0.0, 0.0, 1.0]])
        xs[k] = xf[k] + gains[k] @ (xs[k + 1] - phi @ xf[k])
    return xs


@pytest.mark.parametrize("noise", [(1.0, 0.0, 1e12, 1.0), (1e-4, 1e-12, 1e8, 2.0), (1.0, 1e-3, 1e-6, 1.0)])
def test_smooth_with_timestamps_uses_the_accurate_per_dt_gain(noise):
    """smooth(t=...) of a design: each backward step uses the 50-digit RTS
    gain at its dt (the plain loop with the reference gains reproduces the
    kernel from its own filtered states)."""
    rng = np.random.default_rng(20261201)
    dts = np.array([0.5, 1.0, 2.0, 0.5, 1.0, 3.0, 1.0, 0.5, 2.0])
    t = np.concatenate([[0.0], np.cumsum(dts)])
    z = rng.standard_normal(t.size) * 1e3 + 5.0 * t**2
    f = AlphaBetaGammaFilter.from_noise(*noise, T=1.0)
    xf = f.run(z, t=t, init="first").states.T
    xs = f.smooth(z, t=t, init="first").states.T
    assert np.all(np.isfinite(xf))
    gains = []
    for dt in dts:
        an = ref_backward_noise(*noise, float(dt))
        d = np.array([1.0, dt, dt * dt])
        gains.append(an * d[None, :] / d[:, None])
    ref = _rts_loop(xf, dts, gains)
    # Each state component relative to the size of its smoother correction
    # (plus 1 % of the state): measured <= 2e-13; the former float64 gains
    # from the rounded gains gave 6e-12 .. 6e-10 for the first two models.
    scale = np.max(np.abs(ref - xf), axis=0) + np.max(np.abs(ref), axis=0) * 1e-2
    np.testing.assert_array_less(np.max(np.abs(xs - ref), axis=0), 1e-12 * scale)


def test_fixed_gains_without_a_model_still_raise():
    f = AlphaBetaGammaFilter(0.5, 0.2, 0.001, 1.0, convention="chen-chui")
    assert not abg.analyze(0.5, 0.2, 0.001).near_optimal
    with pytest.raises(ValueError, match="Kalman-equivalent"):
        f.smoother_gain()
