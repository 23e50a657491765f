"""Accuracy of the alpha-beta-gamma design ``abkit.abg.from_noise`` over its domain.

Independent reference: the filter-form discrete algebraic Riccati equation
of the model in physical units (``Phi(h)``, ``H = e1``,
``Q = diag(sigma_p, sigma_v, sigma_a)``, ``R = sigma_m``) solved by the
structure-preserving doubling algorithm in mpmath at 50 digits, then the
filter-form gain ``w = S H / (H' S H + R)`` (Chen & Chui's
``[alpha, beta/h, gamma/h^2]``) and ``1 - alpha = R / (H' S H + R)``
(without cancellation). ``scipy.linalg.solve_discrete_are`` is a
double-precision cross-check where it is accurate.

The dimensionless parameters are ``q_p = sigma_p / sigma_m``,
``q_v = sigma_v h^2 / sigma_m`` and ``q_a = sigma_a h^4 / sigma_m`` (the
square of the tracking index); the sweep covers ``q_a`` from 1e-16 to 1e16
with ``q_p``, ``q_v`` zero or 1e-12 .. 1e12, and ``h`` from 1e-3 to 1e4.

Stated tolerance (docs/abg.md, "Accuracy"): ``alpha``, ``beta``, ``gamma``
to ``RTOL = 1e-13`` relative; ``1 - alpha`` (computed by the user from the
returned ``alpha``) to ``RTOL`` relative plus the rounding of ``alpha``
itself, ``2 eps / (1 - alpha)``.
"""

from __future__ import annotations

import itertools
from functools import lru_cache

import numpy as np
import pytest
import scipy.linalg

from abkit import AlphaBetaGammaFilter, abg

mp = pytest.importorskip("mpmath")

RTOL = 1e-13
EPS = np.finfo(float).eps


@lru_cache(maxsize=None)
def ref_gains(sp: float, sv: float, sa: float, sm: float, h: float):
    """(alpha, beta, gamma, 1 - alpha) by SDA at 50 digits (physical units)."""
    with mp.workdps(50):
        sp_, sv_, sa_, sm_, h_ = (mp.mpf(x) for x in (sp, sv, sa, sm, h))
        phi = mp.matrix([[1, h_, h_ * h_ / 2], [0, 1, h_], [0, 0, 1]])
        # S = Phi S (I + G S)^-1 Phi' + Q: control form with A = Phi', G = H R^-1 H'.
        a = phi.T
        g = mp.zeros(3, 3)
        g[0, 0] = 1 / sm_
        hk = mp.diag([sp_, sv_, sa_])
        eye = mp.eye(3)
        tol = mp.mpf(10) ** -42
        for _ in range(200):
            w = mp.inverse(eye + g * hk)
            a, g, hn = a * w * a, g + a * w * g * a.T, hk + a.T * hk * w * a
            change = mp.mnorm(hn - hk, 1) / mp.mnorm(hn, 1)
            hk = hn
            if change < tol and mp.mnorm(a, 1) < tol:
                break
        else:  # pragma: no cover - the reference itself failed
            raise RuntimeError("SDA did not converge")
        den = hk[0, 0] + sm_
        return (float(hk[0, 0] / den), float(hk[1, 0] / den * h_), float(hk[2, 0] / den * h_ * h_), float(sm_ / den))


H_VALUES = (1e-3, 1.0, 2000.0, 1e4)
QA = tuple(10.0**k for k in range(-16, 17, 4))
OTHER = (0.0, 1e-12, 1e-4, 1.0, 1e4, 1e12)


def _grid():
    pts = []
    for i, (qa, (qp, qv)) in enumerate(itertools.product(QA, [(0.0, 0.0), (0.0, 1.0), (1.0, 0.0), (1e-12, 1e4), (1e12, 1e-4), (1e4, 1e12), (1e-4, 1e-12)])):
        pts.append((qp, qv, qa, H_VALUES[i % len(H_VALUES)]))
    return pts


GRID = _grid()


def _physical(qp, qv, qa, h, sm=2.0):
    return qp * sm, qv * sm / h**2, qa * sm / h**4, sm


def _errors(d, r):
    a, b, g = float(d.alpha), float(d.beta), float(d.gamma)
    return abs(a - r[0]) / r[0], abs(b - r[1]) / r[1], abs(g - r[2]) / r[2], abs((1.0 - a) - r[3]) / r[3]


@pytest.mark.parametrize("qp,qv,qa,h", GRID)
def test_from_noise_matches_50_digit_riccati(qp, qv, qa, h):
    sp, sv, sa, sm = _physical(qp, qv, qa, h)
    r = ref_gains(sp, sv, sa, sm, h)
    d = abg.from_noise(sp, sv, sa, sm, h)
    ea, eb, eg, eom = _errors(d, r)
    assert max(ea, eb, eg) <= RTOL, (ea, eb, eg)
    assert eom <= RTOL + 2 * EPS / r[3], eom


def test_large_tracking_index_regression():
    # The case that showed beta off by ~5e-6 (Riccati + Newton polish in alpha, which divided by 1 - alpha).
    for sp, sv, sa, sm, h in [(1.0, 1e-3, 1e-6, 1.0, 2000.0), (0.0, 1e-3, 1e-6, 1.0, 2000.0), (1.0, 0.0, 1e-6, 1.0, 2000.0), (1e-2, 1e-2, 1.0, 1.0, 1e4)]:
        r = ref_gains(sp, sv, sa, sm, h)
        ea, eb, eg, _ = _errors(abg.from_noise(sp, sv, sa, sm, h), r)
        assert max(ea, eb, eg) <= RTOL, (sp, sv, sa, sm, h, ea, eb, eg)


def test_conventions_scale_gamma_only():
    sp, sv, sa, sm = _physical(1e-4, 1.0, 1e8, 2000.0)
    r = ref_gains(sp, sv, sa, sm, 2000.0)
    for conv, c in abg.CONVENTIONS.items():
        d = abg.from_noise(sp, sv, sa, sm, 2000.0, convention=conv)
        np.testing.assert_allclose([d.alpha, d.beta, d.gamma], [r[0], r[1], r[2] / c], rtol=RTOL)


def test_vectorised_equals_scalar():
    pts = np.array([_physical(qp, qv, qa, h) + (h,) for qp, qv, qa, h in GRID])
    d = abg.from_noise(*pts.T)
    for i, row in enumerate(pts):
        s = abg.from_noise(*row)
        assert (d.alpha[i], d.beta[i], d.gamma[i]) == (s.alpha, s.beta, s.gamma)


def _dare_gains(qp, qv, qa):
    phi = np.array([[1.0, 1.0, 0.5], [0.0, 1.0, 1.0], [0.0, 0.0, 1.0]])
    s = scipy.linalg.solve_discrete_are(phi.T, np.array([[1.0], [0.0], [0.0]]), np.diag([qp, qv, qa]), np.array([[1.0]]))
    return s[:, 0] / (s[0, 0] + 1.0)


@pytest.mark.parametrize("qa", [1e-6, 1e-3, 1.0, 1e3, 1e6])
@pytest.mark.parametrize("qp,qv", [(0.0, 0.0), (0.3, 0.0), (0.0, 0.2), (1e-2, 1e2)])
def test_scipy_dare_cross_check(qp, qv, qa):
    d = abg.from_noise(qp, qv, qa, 1.0, 1.0)
    np.testing.assert_allclose([d.alpha, d.beta, d.gamma], _dare_gains(qp, qv, qa), rtol=1e-8)


@pytest.mark.parametrize(
    "args,exc",
    [
        ((1.0, 1.0, 0.0, 1.0, 1.0), np.linalg.LinAlgError),  # Lemma 2: sigma_a = 0
        ((-1.0, 1.0, 1.0, 1.0, 1.0), ValueError),
        ((1.0, np.nan, 1.0, 1.0, 1.0), ValueError),
        ((1.0, 1.0, np.inf, 1.0, 1.0), ValueError),
        ((1.0, 1.0, 1.0, 0.0, 1.0), ValueError),
        ((1.0, 1.0, 1.0, 1.0, 0.0), ValueError),
        ((1.0, 1.0, 1.0, 1.0, 1e100), ValueError),  # sigma_a h^4 / sigma_m overflows
    ],
)
def test_errors_at_extremes(args, exc):
    with pytest.raises(exc):
        abg.from_noise(*args)


def _one_step_gains(f, dts):
    """Filter-form gain at each dt from one step of ``run(z, t=...)``: start
    at rest at z = 0 (t = 0), measure z = 1 at t = dt: the state is K."""
    n = dts.size
    z = np.tile([0.0, 1.0], (n, 1))
    t = np.stack([np.zeros(n), dts], axis=1)
    return f.run(z, t=t, init="first").states[:, :, 1]


@pytest.mark.parametrize("noise", [(0.0, 0.0, 0.1, 1.0), (0.3, 0.2, 0.1, 1.0), (1.0, 1e-3, 1e-6, 1.0), (1e-6, 1e2, 1e-4, 2.0)])
def test_irregular_gains_equal_from_noise(noise):
    """The irregular kernel's per-dt design is ``abg::from_noise`` at h = dt
    (the same Rust function): alpha and beta/dt bit-identical; gamma/dt^2
    within 1 ulp (the kernel stores gamma/dt^2, Python divides the
    returned gamma by dt^2 again)."""
    rng = np.random.default_rng(20241201)
    dts = np.concatenate([10.0 ** rng.uniform(-3, 4, 60), [1e-3, 1.0, 2000.0, 1e4]])
    f = AlphaBetaGammaFilter.from_noise(*noise, T=1.0)
    assert f.gain_schedule == "design"
    k = _one_step_gains(f, dts)
    d = abg.from_noise(*noise, h=dts, convention="chen-chui")
    np.testing.assert_array_equal(k[0], d.alpha)
    np.testing.assert_allclose(k[1], d.beta / dts, rtol=2 * EPS, atol=0)
    np.testing.assert_allclose(k[2], d.gamma / dts**2, rtol=2 * EPS, atol=0)
    # and both are the 50-digit design at that dt
    for i in range(0, dts.size, 8):
        r = ref_gains(*noise, float(dts[i]))
        np.testing.assert_allclose([d.alpha[i], d.beta[i], d.gamma[i]], r[:3], rtol=RTOL)


def test_alpha_rounding_to_one_is_a_value_error():
    """Process noise ~1e32 times the measurement noise: 1 - alpha ~ 4e-32
    is not representable next to 1, so there is no float64 gain to
    return (as for from_tracking_index); the design and the irregular
    kernel at such a dt raise ValueError naming the parameter."""
    with pytest.raises(ValueError, match="sigma_m"):
        abg.from_noise(1e-12, 1e-12, 1e16, 1.0, 1e4)
    with pytest.raises(ValueError, match="lam"):
        abg.from_noise(0.0, 0.0, 1e16, 1.0, 1e4)
    f = AlphaBetaGammaFilter.from_noise(1e-6, 1e2, 1e4, 2.0, T=1.0)
    with pytest.raises(ValueError, match="sigma_m"):
        f.run(np.array([0.0, 1.0]), t=np.array([0.0, 1e5]), init="first")

