"""Property tests (issue 8) over the whole parameter domain of the solvers,
filling the gaps left by the per-module tests (which already cover: DARE
similarity/scaling, alpha-beta NaN-freedom, abg round trips on grids).

Properties, each against an independent computation in this file:

* steady-state Kalman (``riccati.kalman_steady_state``): Riccati residual
  recomputed here, symmetry and PSD of ``P_pred``/``P_filt``, stability of
  the returned gain, and the design/analysis round trip: a fixed-gain filter
  run with the returned gain has, by its own Lyapunov analysis
  (``FixedGainFilter.covariances``), exactly the returned covariances;
* alpha-beta (``alphabeta.from_noise``): invariance to scaling both noises,
  monotonicity (more process noise -> larger alpha and beta), design/analysis
  round trip through ``AlphaBetaFilter.covariances``;
* alpha-beta-gamma (``abg.from_noise``): invariance to scaling all noises,
  alpha increasing with the process noise ``(sigma_p, sigma_v, sigma_a)`` (the prediction covariance is
  monotone in Q, and alpha = P11 / (P11 + R)), stability;
* Singer (``singer.steady_state``): symmetric PSD covariances, stable gain,
  invariance to scaling ``sigma_m`` and ``sigma_pos`` together, alpha
  increasing with ``sigma_m``, and the recomputed Riccati residual.

Derandomized (tests/conftest.py), so CI is reproducible.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

import abkit  # noqa: E402
from abkit import abg, alphabeta, riccati, singer  # noqa: E402

SET = settings(max_examples=60, deadline=None)
logs = st.floats(-6, 6)


def _psd(P: np.ndarray, rtol: float = 1e-10) -> bool:
    P = np.asarray(P)
    return bool(np.linalg.eigvalsh(0.5 * (P + P.T)).min() >= -rtol * np.abs(P).max())


def _riccati_residual(F, H, Q, R, P) -> float:
    """Relative residual of P = F P F' - F P H' (H P H' + R)^-1 H P F' + Q."""
    S = H @ P @ H.T + R
    rhs = F @ P @ F.T - F @ P @ H.T @ np.linalg.solve(S, H @ P @ F.T) + Q
    scale = np.linalg.norm(F @ P @ F.T) + np.linalg.norm(P) + np.linalg.norm(Q)
    return float(np.linalg.norm(rhs - P) / scale)


def _kinematic(n: int, T: float) -> np.ndarray:
    F = np.eye(n)
    for k in range(1, n):
        F += np.diag(np.full(n - k, T**k / np.prod(np.arange(1, k + 1))), k)
    return F


@SET
@given(n=st.integers(1, 4), m=st.integers(1, 2), logq=st.floats(-4, 4), logT=st.floats(-1, 1), seed=st.integers(0, 2**31))
def test_kalman_steady_state_properties_and_round_trip(n, m, logq, logT, seed):
    """(The domain stops where kinematic models of order 4 become so badly
    scaled that the solver refuses them with LinAlgError, as documented.)"""
    rng = np.random.default_rng(seed)
    T = 10.0**logT
    F = _kinematic(n, T)
    H = np.eye(m, n) if m <= n else np.eye(1, n)
    G = rng.normal(size=(n, n))
    Q = 10.0**logq * (G @ G.T + 1e-3 * np.eye(n))
    R = np.diag(rng.uniform(0.5, 2.0, H.shape[0]))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", abkit.AccuracyWarning)
        ks = riccati.kalman_steady_state(F, H, Q, R)
    P, Pf, K = ks.P_pred, ks.P_filt, ks.K
    assert np.array_equal(P, P.T) or np.allclose(P, P.T, rtol=1e-14, atol=0)
    assert _psd(P) and _psd(Pf)
    assert _riccati_residual(F, H, Q, R, P) <= 1e-7
    A = (np.eye(n) - K @ H) @ F
    assert np.max(np.abs(np.linalg.eigvals(A))) < 1.0
    # analysis of the designed gain reproduces the design's covariances
    f = abkit.FixedGainFilter(F, H, K, T)
    cov = f.covariances(Q, R)
    scale = np.abs(P).max()
    assert np.abs(cov.predicted - P).max() <= 1e-7 * scale
    assert np.abs(cov.filtered - Pf).max() <= 1e-7 * scale


@SET
@given(logw=st.floats(-8, 8), logv=st.floats(-8, 8), logT=st.floats(-3, 3), logc=st.floats(-100, 100))
def test_alphabeta_noise_scaling_invariance(logw, logv, logT, logc):
    sw, sv, T, c = 10.0**logw, 10.0**logv, 10.0**logT, 10.0**logc
    d = alphabeta.from_noise(sw, sv, T)
    e = alphabeta.from_noise(c * sw, c * sv, T)
    assert e.alpha == pytest.approx(d.alpha, rel=1e-12)
    assert e.beta == pytest.approx(d.beta, rel=1e-12)


@SET
@given(logw=st.floats(-8, 8), logv=st.floats(-8, 8), logT=st.floats(-3, 3), dlog=st.floats(1e-3, 4))
def test_alphabeta_more_process_noise_larger_gains(logw, logv, logT, dlog):
    # beyond sigma_w T^2 / sigma_v ~ 1e14 the gains round to the stability boundary (refused, documented)
    hypothesis.assume(logw + 2 * logT - logv + dlog < 12)
    sw, sv, T = 10.0**logw, 10.0**logv, 10.0**logT
    lo = alphabeta.from_noise(sw, sv, T)
    hi = alphabeta.from_noise(sw * 10.0**dlog, sv, T)
    assert hi.alpha >= lo.alpha and hi.beta >= lo.beta
    assert (hi.alpha > lo.alpha) or lo.alpha == 1.0 or hi.alpha > 1 - 1e-15
    assert lo.stable and hi.stable


@SET
@given(logr=st.floats(-8, 8), logT=st.floats(-2, 2))
def test_alphabeta_design_analysis_round_trip_through_the_filter(logr, logT):
    """from_noise designs gains; AlphaBetaFilter.covariances analyses them
    (Lyapunov of the loop): the analysed filtered covariance equals the
    design's, scaled to physical units."""
    T = 10.0**logT
    sv = 1.0
    sw = 2.0 * np.sqrt(10.0**logr) / T**2  # r = (sigma_w T^2 / (2 sigma_v))^2, paper 000
    d = alphabeta.from_noise(sw, sv, T)
    f = abkit.AlphaBetaFilter.from_design(d)
    cov = f.covariances(sigma_w=sw, sigma_v=sv)
    want = d.scaled_covariance(sv, T)
    np.testing.assert_allclose(cov.filtered, want, rtol=1e-7, atol=1e-12 * np.abs(want).max())


noise = st.floats(-3, 3)


@SET
@given(sp=noise, sv=noise, sa=noise, sm=noise, logc=st.floats(-50, 50))
def test_abg_noise_scaling_invariance_and_stability(sp, sv, sa, sm, logc):
    s = [10.0**x for x in (sp, sv, sa, sm)]
    c = 10.0**logc
    g = abg.from_noise(*s)
    h = abg.from_noise(*(c * x for x in s))
    for a, b in ((g.alpha, h.alpha), (g.beta, h.beta), (g.gamma, h.gamma)):
        assert b == pytest.approx(a, rel=1e-9)
    assert bool(g.stable)


@SET
@given(sp=noise, sv=noise, sa=noise, sm=noise, dlog=st.floats(0.01, 3))
def test_abg_alpha_increases_with_process_noise(sp, sv, sa, sm, dlog):
    s = [10.0**x for x in (sp, sv, sa, sm)]
    lo = abg.from_noise(*s)
    c = 10.0**dlog  # process noise (sigma_p, sigma_v, sigma_a) up, measurement noise sigma_m fixed
    hi = abg.from_noise(s[0] * c, s[1] * c, s[2] * c, s[3])
    assert hi.alpha >= lo.alpha * (1 - 1e-12)


@SET
@given(logtheta=st.floats(-3, 2), logp2=st.floats(-4, 4), logc=st.floats(-50, 50), vel=st.booleans())
def test_singer_properties(logtheta, logp2, logc, vel):
    T = 1.0
    tau = T / 10.0**logtheta
    sm, sp = 10.0**logp2, 1.0
    kw = dict(sigma_vel=0.7) if vel else {}
    s = singer.steady_state(T, tau, sm, sp, **kw)
    P, Pf = s.P_pred, s.P_filt
    assert np.allclose(P, P.T, rtol=1e-12, atol=0) and _psd(P, 1e-9) and _psd(Pf, 1e-9)
    H, R, Phi, Q = s.H, s.R, s.Phi, s.Q
    assert _riccati_residual(Phi, H, Q, R, P) <= 1e-8
    A = (np.eye(3) - s.K @ H) @ Phi
    assert np.max(np.abs(np.linalg.eigvals(A))) < 1.0
    c = 10.0**logc
    kw2 = dict(sigma_vel=0.7 * c) if vel else {}
    s2 = singer.steady_state(T, tau, sm * c, sp * c, **kw2)
    np.testing.assert_allclose(s2.K, s.K, rtol=1e-8, atol=1e-14)
    if not vel:
        s3 = singer.steady_state(T, tau, sm * 2.0, sp)
        assert s3.alpha >= s.alpha * (1 - 1e-12)


@SET
@given(a=st.floats(1e-6, 1.999), fb=st.floats(1e-6, 0.999), logT=st.floats(-3, 3), seed=st.integers(0, 2**31))
def test_stable_alphabeta_filter_output_bounded_by_input(a, fb, logT, seed):
    """A stable fixed-gain filter driven by bounded measurements gives finite
    estimates whose position stays within the loop's l1 gain of the input
    bound (BIBO), and its final state equals a plain Python loop's."""
    b = fb * (4 - 2 * a)
    T = 10.0**logT
    z = np.random.default_rng(seed).uniform(-1, 1, 300)
    f = abkit.AlphaBetaFilter(a, b, T)
    r = f.run(z, init=[0.0, 0.0])
    # l1 norm of the impulse response from z to the position estimate
    A = f.closed_loop
    K = f.K[:, 0]
    x = K.copy()
    l1 = abs(x[0])
    for _ in range(20000):
        x = A @ x
        l1 += abs(x[0])
        if np.abs(x).max() < 1e-18 * max(1.0, l1):
            break
    assert np.all(np.isfinite(r.states))
    assert np.abs(r.position).max() <= l1 * (1 + 1e-9) + 1e-12
    xs = np.zeros(2)
    for zk in z:
        xp = np.array([xs[0] + T * xs[1], xs[1]])
        e = zk - xp[0]
        xs = xp + np.array([a, b / T]) * e
    np.testing.assert_allclose(r.state.x, xs, rtol=1e-9, atol=1e-9 * (1 + np.abs(xs).max()))
