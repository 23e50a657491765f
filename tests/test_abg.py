"""abkit.abg (Chen & Chui, paper 004): conventions, gains from noise and back,
analysis, coloured measurement noise, decoupled recursive forms.

Every reference here is independent of the printed formulas:
scipy.linalg.solve_discrete_are / solve_discrete_lyapunov, the Kalman
recursion run to convergence, mpmath root finding, state-space simulation
and scipy.signal.ss2tf / lfilter.
"""

from __future__ import annotations

import itertools

import mpmath
import numpy as np
import pytest
import scipy.linalg as sla
from scipy.signal import lfilter, ss2tf

from abkit import AlphaBetaGammaFilter, FixedGainFilter, abg
from abkit.filters import ABG_CONVENTIONS
from abkit.riccati import solve_dare


def phi(h: float = 1.0) -> np.ndarray:
    return np.array([[1.0, h, h * h / 2], [0.0, 1.0, h], [0.0, 0.0, 1.0]])


H3 = np.array([[1.0, 0.0, 0.0]])


def ref_gains(sp: float, sv: float, sa: float, sm: float, h: float = 1.0) -> np.ndarray:
    """Chen-Chui gains from scipy's DARE (physical units, then scaled)."""
    F = phi(h)
    S = sla.solve_discrete_are(F.T, H3.T, np.diag([sp, sv, sa]), np.array([[sm]]))
    w = (S @ H3.T / (S[0, 0] + sm)).ravel()
    return w * np.array([1.0, h, h * h])


def coloured_model(r: float, h: float = 1.0):
    F = np.zeros((4, 4))
    F[:3, :3] = phi(h)
    F[3, 3] = r
    return F, np.array([[1.0, 0.0, 0.0, 1.0]])


def kalman_recursion_r0(F, H, Q, n=4000):
    """Kalman prediction-covariance recursion with R = 0, run to convergence."""
    S = np.eye(F.shape[0]) * 10.0
    for _ in range(n):
        s0 = (H @ S @ H.T).item()
        Sn = F @ (S - S @ H.T @ H @ S / s0) @ F.T + Q
        Sn = 0.5 * (Sn + Sn.T)
        if np.max(np.abs(Sn - S)) <= 1e-15 * np.max(np.abs(Sn)):
            S = Sn
            break
        S = Sn
    return S


# --------------------------------------------------------------- conventions
def test_conventions_are_the_filters_ones() -> None:
    assert abg.CONVENTIONS is ABG_CONVENTIONS
    for frm, to in itertools.product(ABG_CONVENTIONS, repeat=2):
        g = abg.convert(0.5, 0.2, np.array([0.01, 0.04]), frm=frm, to=to)
        back = abg.convert(*g, frm=to, to=frm)
        np.testing.assert_allclose(back.gamma, [0.01, 0.04], rtol=1e-15)
        # the same physical filter in both conventions
        z = np.cumsum(np.cumsum(np.random.default_rng(0).normal(size=50)))
        x1 = AlphaBetaGammaFilter(0.5, 0.2, 0.04, 0.5, convention=frm).run(z).states
        x2 = AlphaBetaGammaFilter(0.5, 0.2, abg.convert(0.5, 0.2, 0.04, frm=frm, to=to).gamma, 0.5, convention=to).run(z).states
        np.testing.assert_allclose(x1, x2, rtol=1e-12, atol=1e-12)


def test_convert_values_and_errors() -> None:
    assert abg.convert(0.5, 0.2, 0.04, frm="standard", to="chen-chui").gamma == pytest.approx(0.02)
    assert abg.convert(0.5, 0.2, 0.02, frm="chen-chui", to="ghk").gamma == pytest.approx(0.01)
    with pytest.raises(ValueError, match="frm"):
        abg.convert(0.5, 0.2, 0.1, frm="bogus")
    with pytest.raises(ValueError, match="to"):
        abg.convert(0.5, 0.2, 0.1, to="bogus")
    with pytest.raises(ValueError, match="convention"):
        abg.from_noise(1, 1, 1, 1, convention="x")


@pytest.mark.parametrize("convention", sorted(ABG_CONVENTIONS))
def test_predictor_form_round_trip(convention: str) -> None:
    a, b, g, h = 0.6, 0.3, np.array([0.05, 0.1]), 0.25
    K = abg.to_predictor(a, b, g, h, convention=convention)
    w = np.stack([np.full(2, a), np.full(2, b / h), ABG_CONVENTIONS[convention] * g / h**2], axis=-1)
    np.testing.assert_allclose(K, w @ phi(h).T, rtol=1e-14)
    back = abg.from_predictor(K, h, convention=convention)
    np.testing.assert_allclose(back.gamma, g, rtol=1e-12)
    np.testing.assert_allclose(back.alpha, a, rtol=1e-12)
    np.testing.assert_allclose(back.beta, b, rtol=1e-12)


# ---------------------------------------------------------------- from_noise
NOISE_CASES = [
    (0.3, 0.2, 0.1, 1.0, 0.7),
    (0.0, 0.0, 1.0, 1.0, 1.0),
    (0.0, 1.0, 1e-3, 1.0, 2.0),
    (5.0, 0.0, 1e-2, 0.5, 0.1),
    (1e-4, 1e-3, 1e-6, 1.0, 1.0),
    (1e3, 1e2, 10.0, 1.0, 1.0),
    (1.0, 1.0, 1e4, 1e-2, 1.0),
]


@pytest.mark.parametrize("sp,sv,sa,sm,h", NOISE_CASES)
def test_from_noise_matches_scipy_dare_and_round_trips(sp, sv, sa, sm, h) -> None:
    d = abg.from_noise(sp, sv, sa, sm, h)
    np.testing.assert_allclose([d.alpha, d.beta, d.gamma], ref_gains(sp, sv, sa, sm, h), rtol=1e-7)
    assert d.near_optimal and d.stable
    q = abg.noise_ratios(d.alpha, d.beta, d.gamma, h)
    scale = max(sp, sv, sa) / sm
    np.testing.assert_allclose(q, [sp / sm, sv / sm, sa / sm], rtol=1e-10, atol=1e-10 * scale)


def test_round_trip_grid_broadcast_and_conventions() -> None:
    e = 10.0 ** np.arange(-3, 3.5, 1.5)
    sp, sv, sa = np.meshgrid(np.concatenate([[0.0], e]), np.concatenate([[0.0], e]), e, indexing="ij")
    d = abg.from_noise(sp, sv, sa, 1.0, 1.0)
    assert d.shape == sp.shape and np.all(d.near_optimal)
    q = abg.noise_ratios(d.alpha, d.beta, d.gamma)
    scale = np.maximum(np.maximum(sp, sv), sa)
    for got, want in zip(q, (sp, sv, sa)):
        assert np.all(np.abs(got - want) <= 1e-10 * scale + 1e-10 * np.abs(want))
    s = abg.from_noise(sp, sv, sa, 1.0, 1.0, convention="standard")
    np.testing.assert_allclose(s.gamma, 2 * d.gamma, rtol=1e-15)


def test_from_noise_kalman_recursion_converges_to_it() -> None:
    h, sp, sv, sa, sm = 0.5, 0.2, 0.1, 0.05, 1.0
    F, Q, S = phi(h), np.diag([sp, sv, sa]), np.eye(3) * 100.0
    for _ in range(3000):
        S = F @ (S - S @ H3.T @ H3 @ S / (S[0, 0] + sm)) @ F.T + Q
    w = (S @ H3.T / (S[0, 0] + sm)).ravel() * [1, h, h * h]
    d = abg.from_noise(sp, sv, sa, sm, h)
    np.testing.assert_allclose([d.alpha, d.beta, d.gamma], w, rtol=1e-10)


def test_from_noise_errors() -> None:
    with pytest.raises(np.linalg.LinAlgError, match="Lemma 2"):
        abg.from_noise(1.0, 1.0, 0.0, 1.0)
    with pytest.raises(np.linalg.LinAlgError, match=r"index \(1,\)"):
        abg.from_noise(1.0, 1.0, [1.0, 0.0], 1.0)
    for i, name in enumerate(("sigma_p", "sigma_v", "sigma_a")):
        args = [1.0, 1.0, 1.0, 1.0]
        args[i] = -1.0
        with pytest.raises(ValueError, match=name):
            abg.from_noise(*args)
        args[i] = float("nan")
        with pytest.raises(ValueError, match=name):
            abg.from_noise(*args)
    with pytest.raises(ValueError, match="sigma_m"):
        abg.from_noise(1.0, 1.0, 1.0, 0.0)
    with pytest.raises(ValueError, match="h"):
        abg.from_noise(1.0, 1.0, 1.0, 1.0, h=-1.0)
    with pytest.raises(ValueError, match="broadcast"):
        abg.from_noise([1.0, 2.0], [1.0, 2.0, 3.0], 1.0, 1.0)
    with pytest.raises(TypeError):
        abg.from_noise("a", 1.0, 1.0, 1.0)


# ------------------------------------------------------- from_tracking_index
def _mp_root(lam: float) -> list:
    """Bisection in 50-digit arithmetic on 2 u^3 = lam (1 - u)(2 - u), u = 1 - s."""
    with mpmath.workdps(50):
        lam_ = mpmath.mpf(lam)
        lo, hi = mpmath.mpf(0), mpmath.mpf(1)
        for _ in range(200):
            mid = (lo + hi) / 2
            if 2 * mid**3 - lam_ * (1 - mid) * (2 - mid) < 0:
                lo = mid
            else:
                hi = mid
        u = (lo + hi) / 2
        return [float(u * (2 - u)), float(2 * u * u), float(2 * u**3 / (2 - u))]


@pytest.mark.parametrize("lam", [1e-9, 1e-4, 0.05, 1.0, 7.0, 300.0, 1e6])
def test_tracking_index_closed_form(lam: float) -> None:
    d = abg.from_tracking_index(lam)
    np.testing.assert_allclose([d.alpha, d.beta, d.gamma], _mp_root(lam), rtol=1e-13)
    if 1e-4 <= lam <= 300:
        np.testing.assert_allclose([d.alpha, d.beta, d.gamma], ref_gains(0, 0, lam**2, 1.0), rtol=1e-7)
        # Bar-Shalom's discrete Wiener process acceleration model gives the same gains
        g = phi() @ np.array([[0.0], [0.0], [1.0]])
        F = phi()
        S = sla.solve_discrete_are(F.T, H3.T, lam**2 * g @ g.T, np.array([[1.0]]))
        w = (S @ H3.T / (S[0, 0] + 1.0)).ravel()
        np.testing.assert_allclose([d.alpha, d.beta, d.gamma], w, rtol=1e-7)
        s = abg.from_tracking_index(lam, convention="standard")
        assert s.beta == pytest.approx(2 * (2 - s.alpha) - 4 * np.sqrt(1 - s.alpha), rel=1e-9)
        assert s.gamma == pytest.approx(s.beta**2 / s.alpha, rel=1e-9)
        assert s.gamma**2 / (4 * (1 - s.alpha)) == pytest.approx(lam**2, rel=1e-9)


def test_tracking_index_matches_from_noise_and_errors() -> None:
    lam = np.array([0.1, 1.0, 10.0])
    d1, d2 = abg.from_tracking_index(lam), abg.from_noise(0.0, 0.0, lam**2, 1.0)
    np.testing.assert_array_equal(d1.gamma, d2.gamma)
    for bad in (0.0, -1.0, np.nan, np.inf):
        with pytest.raises(ValueError, match="lam"):
            abg.from_tracking_index(bad)


# ----------------------------------------------- noise_ratios / near-optimal
def test_noise_ratios_errors_name_the_gain() -> None:
    with pytest.raises(ValueError, match="alpha"):
        abg.noise_ratios(1.2, 0.5, 0.1)
    with pytest.raises(ValueError, match="gamma"):
        abg.noise_ratios(0.5, 0.2, -0.1)
    with pytest.raises(ValueError, match="beta"):
        abg.noise_ratios(0.5, 0.1, 0.1)  # beta < sqrt(2 alpha gamma)
    with pytest.raises(ValueError, match="beta"):
        abg.noise_ratios(0.5, 0.4, 0.1)  # beta > alpha (alpha + gamma/2) / (2 - alpha)
    with pytest.raises(ValueError, match=r"h"):
        abg.noise_ratios(0.5, 0.2, 0.02, h=0.0)
    with pytest.raises(ValueError, match=r"at index \(1,\)"):
        d = abg.from_tracking_index(1.0)
        abg.noise_ratios([d.alpha, 1.5], d.beta, d.gamma)


def test_is_near_optimal_agrees_with_the_riccati_round_trip() -> None:
    """Random gains: the Corollary's verdict equals 'the DARE with the
    Corollary's noise gives back these gains'."""
    rng = np.random.default_rng(5)
    a = rng.uniform(0.02, 0.98, 400)
    b = rng.uniform(0.0, 1.0, 400) * a
    g = rng.uniform(0.0, 1.0, 400) * b * b / (2 * a) * 1.5
    verdict = abg.is_near_optimal(a, b, g)
    n_true = 0
    for i in range(a.size):
        try:
            q = abg.noise_ratios(a[i], b[i], g[i])
        except ValueError:
            assert not verdict[i]
            continue
        back = ref_gains(*q, 1.0)
        same = np.allclose(back, [a[i], b[i], g[i]], rtol=1e-6)
        assert same == verdict[i], (a[i], b[i], g[i], back)
        n_true += int(same)
    assert 20 < n_true < 400


def test_p_tilde_is_scaled_prediction_covariance() -> None:
    d = abg.from_noise(0.3, 0.2, 0.1, 1.0)
    a, b, g = d.alpha, d.beta, d.gamma
    pt = np.array(
        [[a, b, g], [b, b * (a + b + g / 4) - g / 2 * (2 + a), g * (a + b / 2)], [g, g * (a + b / 2), g * (b + g)]]
    )
    S = sla.solve_discrete_are(phi().T, H3.T, np.diag([0.3, 0.2, 0.1]), np.array([[1.0]]))
    np.testing.assert_allclose(pt, (1 - a) * S, rtol=1e-9)
    np.testing.assert_allclose(d.covariance_predicted, S, rtol=1e-9)


# ----------------------------------------------------------------- analysis
@pytest.mark.parametrize("gains", [(0.5, 0.2, 0.02), (0.9, 0.8, 0.3), (0.2, 0.02, 0.001), (1.5, 1.5, 0.5)])
def test_analysis_against_independent_references(gains) -> None:
    a, b, g = gains
    d = abg.analyze(a, b, g)
    w = np.array([[a], [b], [g]])
    B = (np.eye(3) - w @ H3) @ phi()
    ev = np.linalg.eigvals(B)
    np.testing.assert_allclose(np.sort_complex(d.poles), np.sort_complex(ev), atol=1e-12)
    rho = max(abs(ev))
    assert d.stable == (rho < 1) and d.spectral_radius == pytest.approx(rho)
    if not d.stable:
        assert np.isinf(d.variance_reduction.position_filtered)
        return
    Pf = sla.solve_discrete_lyapunov(B, w @ w.T)
    vr = d.variance_reduction
    np.testing.assert_allclose([vr.position_filtered, vr.velocity_filtered, vr.acceleration_filtered], np.diag(Pf), rtol=1e-9)
    M = phi() @ Pf @ phi().T
    np.testing.assert_allclose([vr.position_predicted, vr.velocity_predicted, vr.acceleration_predicted], np.diag(M), rtol=1e-9)
    # constant-jerk lag by simulation of the filter itself
    n = 3000
    k = np.arange(n, dtype=float)
    z = k**3 / 6.0
    st = AlphaBetaGammaFilter(a, b, g, 1.0, convention="chen-chui").run(z, init=np.zeros(3)).states
    truth = np.stack([k**3 / 6, k**2 / 2, k])
    lag = truth[:, -1] - st[:, -1]
    np.testing.assert_allclose([d.lag.position_filtered, d.lag.velocity_filtered, d.lag.acceleration_filtered], lag, rtol=1e-6)
    pred = phi() @ st[:, -1]
    tnext = np.array([n**3 / 6, n**2 / 2, n])
    np.testing.assert_allclose([d.lag.position_predicted, d.lag.velocity_predicted, d.lag.acceleration_predicted], tnext - pred, rtol=1e-6)


def test_analysis_model_covariance_and_nan_when_not_near_optimal() -> None:
    d = abg.from_noise(0.3, 0.2, 0.1, 1.0)
    S = sla.solve_discrete_are(phi().T, H3.T, np.diag([0.3, 0.2, 0.1]), np.array([[1.0]]))
    Pf = S - S @ H3.T @ H3 @ S / (S[0, 0] + 1.0)
    np.testing.assert_allclose(d.covariance_filtered, Pf, rtol=1e-9)
    assert d.covariance_filtered[0, 0] == pytest.approx(d.alpha)
    x = abg.analyze(0.5, 0.2, 0.02)
    assert not x.near_optimal and np.all(np.isnan(x.covariance_filtered))
    assert all(np.isnan(v) for v in x.noise_ratios)
    with pytest.raises(ValueError, match="gamma"):
        abg.analyze(0.5, 0.2, np.nan)


# ----------------------------------------------------------------- coloured
def _coloured_reference(sp, sv, sa, sm, r, h):
    F, H = coloured_model(r, h)
    Q = np.diag([sp, sv, sa, sm])
    S = kalman_recursion_r0(F, H, Q)
    w = (S @ H.T / (H @ S @ H.T)).ravel() * np.array([1.0, h, h * h, 1.0])
    return S, w


@pytest.mark.parametrize("sp,sv,sa,sm,r,h", [(3.0, 2.0, 1.0, 5.0, 0.6, 0.8), (0.1, 0.5, 1.0, 0.3, -0.4, 1.0), (0.0, 0.0, 1.0, 2.0, 0.9, 0.5)])
def test_coloured_theorem_2(sp, sv, sa, sm, r, h) -> None:
    S, w = _coloured_reference(sp, sv, sa, sm, r, h)
    # abkit.riccati handles the singular R = 0 of this problem
    F, H = coloured_model(r, h)
    X = solve_dare(F.T, H.T, np.diag([sp, sv, sa, sm]), np.zeros((1, 1)))
    np.testing.assert_allclose(X, S, rtol=1e-8, atol=1e-10 * np.max(np.abs(S)))
    c = abg.coloured(*w, r, h)
    assert c.near_optimal and c.conditions_hold
    assert c.gain_mismatch < 1e-8
    np.testing.assert_allclose(c.riccati_gains, w, rtol=1e-8)
    np.testing.assert_allclose([c.sigma_p_over_sigma_a, c.sigma_v_over_sigma_a, c.sigma_m_over_sigma_a], np.array([sp, sv, sm]) / sa, rtol=1e-8, atol=1e-9)
    assert abs(c.alpha_plus_theta_minus_1) < 1e-12
    # with alpha + theta = 1 kept, a slightly different beta is near-optimal
    # for other noise (3 ratios <-> 3 free gains); the Riccati solver agrees
    p = abg.coloured(w[0], w[1] * 1.01, w[2], w[3], r, h)
    if min(p.sigma_p_over_sigma_a, p.sigma_v_over_sigma_a, p.sigma_m_over_sigma_a) >= 0:
        assert p.near_optimal and p.conditions_hold and p.gain_mismatch < 1e-8
    else:
        # the printed conditions (i)-(v), (ix) alone would accept these gains
        # (errata, Paper 004: Theorem 2 misses "the ratios are >= 0")
        assert np.all(p.conditions[[0, 1]] > 0) and np.all(p.conditions[2:] >= 0) and p.sigma_tilde_min_eig >= 0
        assert not p.near_optimal and not p.conditions_hold
    # breaking alpha + theta = 1 is never near-optimal
    assert not abg.coloured(w[0] * 0.99, w[1], w[2], w[3], r, h).near_optimal


def test_coloured_errors_and_broadcast() -> None:
    with pytest.raises(ValueError, match="r"):
        abg.coloured(0.9, 0.5, 0.1, 0.1, 1.0)
    with pytest.raises(ValueError, match="r"):
        abg.coloured(0.9, 0.5, 0.1, 0.1, 0.0)
    with pytest.raises(ValueError, match="gamma"):
        abg.coloured(0.9, 0.5, 0.0, 0.1, 0.5)
    with pytest.raises(ValueError, match="theta"):
        abg.coloured(0.9, 0.5, 0.1, np.inf, 0.5)
    c = abg.coloured(0.9, 0.5, 0.1, np.array([0.1, 0.2, 0.3]), 0.5)
    assert c.conditions.shape == (3, 5) and c.riccati_gains.shape == (3, 4)


def test_fixed_gain_filter_runs_the_coloured_filter() -> None:
    sp, sv, sa, sm, r, h = 0.5, 0.3, 1.0, 2.0, 0.7, 0.5
    S, w = _coloured_reference(sp, sv, sa, sm, r, h)
    F, H = coloured_model(r, h)
    K = (w / np.array([1.0, h, h * h, 1.0]))[:, None]
    rng = np.random.default_rng(3)
    n = 400
    x = np.zeros(3)
    v = 0.0
    z = np.empty(n)
    for k in range(n):
        x = phi(h) @ x + rng.normal(size=3) * np.sqrt([sp, sv, sa])
        v = r * v + rng.normal() * np.sqrt(sm)
        z[k] = x[0] + v
    out = FixedGainFilter(F, H, K).run(z, init=np.zeros(4)).states
    y = np.zeros(4)
    ref = np.empty((4, n))
    for k in range(n):
        yp = F @ y
        y = yp + K[:, 0] * (z[k] - (H @ yp).item())
        ref[:, k] = y
    np.testing.assert_allclose(out, ref, rtol=1e-9, atol=1e-9 * np.max(np.abs(ref)))
    # alpha + theta = 1: the filter reproduces z exactly (no white measurement noise)
    np.testing.assert_allclose(out[0] + out[3], z, rtol=1e-9, atol=1e-9)


# ---------------------------------------------------------------- decoupled
@pytest.mark.parametrize("a,b,g,th,r,h", [(0.5, 0.2, 0.02, 0.0, 0.0, 1.0), (0.6, 0.4, 0.1, 0.3, 0.5, 0.7), (0.93, 0.57, 0.14, 0.07, 0.6, 0.8), (0.3, 0.9, 0.8, 0.6, -0.8, 2.0)])
def test_decoupled_against_ss2tf_and_simulation(a, b, g, th, r, h) -> None:
    d = abg.decoupled(a, b, g, th, r, h)
    F, H = coloured_model(r, h)
    w = np.array([a, b / h, g / h**2, th])
    A = F - np.outer(w, H @ F)
    for i in range(4):
        num, den = ss2tf(A, w[:, None], A[[i], :], np.array([[w[i]]]))
        np.testing.assert_allclose(d.b[i], num.ravel()[:4], atol=1e-12 * (1 + np.max(np.abs(num))))
        assert abs(num.ravel()[4]) < 1e-12 * (1 + np.max(np.abs(num)))
        np.testing.assert_allclose(d.a, den.ravel(), atol=1e-12)
    ev = np.linalg.eigvals(A)
    np.testing.assert_allclose(np.sort_complex(d.poles), np.sort_complex(ev), atol=1e-9)
    assert d.stable == (max(abs(ev)) < 1)
    # lfilter reproduces the coupled filter from rest
    z = np.random.default_rng(1).normal(size=60).cumsum()
    y = np.zeros(4)
    ref = np.empty((4, z.size))
    for k in range(z.size):
        y = A @ y + w * z[k]
        ref[:, k] = y
    for i in range(4):
        np.testing.assert_allclose(lfilter(d.b[i], d.a, z), ref[i], rtol=1e-8, atol=1e-8 * np.max(np.abs(ref[i])))


def test_decoupled_white_case_matches_alpha_beta_gamma_filter_and_errors() -> None:
    d = abg.decoupled(0.5, 0.2, 0.04, convention="standard")
    z = np.arange(20.0) ** 2
    x = AlphaBetaGammaFilter(0.5, 0.2, 0.04, 1.0).run(z, init=np.zeros(3)).states
    for i in range(3):
        np.testing.assert_allclose(lfilter(d.b[i], d.a, z), x[i], rtol=1e-10, atol=1e-10)
    dd = abg.decoupled([0.5, 0.6], 0.2, 0.02)
    assert dd.b.shape == (2, 4, 4) and dd.a.shape == (2, 5) and dd.poles.shape == (2, 4)
    with pytest.raises(ValueError, match="h"):
        abg.decoupled(0.5, 0.2, 0.02, h=0.0)
    with pytest.raises(ValueError, match="alpha"):
        abg.decoupled(np.nan, 0.2, 0.02)


# ------------------------------------------------------- extremes, properties
@pytest.mark.parametrize("lam", [1e-12, 1e-6, 1e3, 1e8])
def test_poles_and_stability_at_extreme_gains(lam: float) -> None:
    """Near-optimal gains are stable, also where all poles crowd z = 1;
    poles against 40-digit roots of the characteristic polynomial."""
    d = abg.from_tracking_index(lam)
    assert d.stable and d.spectral_radius < 1
    with mpmath.workdps(40):
        a, b, g = (mpmath.mpf(x) for x in (d.alpha, d.beta, d.gamma))
        roots = mpmath.polyroots([1, -(3 - a - b - g / 2), 3 - 2 * a - b + g / 2, -(1 - a)], maxsteps=200, extraprec=200)
        want = np.array([complex(r) for r in roots])
    got = d.poles
    for w in want:
        assert np.min(np.abs(got - w)) <= 1e-9 * max(1.0, abs(w)) + 1e-12


def test_no_nan_for_finite_gains() -> None:
    rng = np.random.default_rng(11)
    a = np.concatenate([rng.uniform(-1, 3, 300), [1e-300, 1e300, 0.0, 1.0]])
    b = np.concatenate([rng.uniform(-1, 3, 300), [1e-300, 1e300, 0.0, 2.0]])
    g = np.concatenate([rng.uniform(-1, 3, 300), [1e-300, 1e300, 0.0, 0.5]])
    d = abg.analyze(a, b, g)
    rows = d._rows
    model = [abg._IDX[k] for k in ("q_p", "q_v", "q_a", "p11", "p12", "p13", "p22", "p23", "p33", "m11", "m12", "m13", "m22", "m23", "m33")]
    other = np.setdiff1d(np.arange(rows.shape[1]), model)
    assert not np.isnan(rows[:, other]).any()
    # the model columns are NaN exactly where the gains are not near-optimal (or unstable: inf)
    assert np.all(np.isnan(rows[~d.near_optimal][:, model[:3]]))
    assert not np.isnan(rows[d.near_optimal][:, model]).any()


def test_round_trip_property_random_noise() -> None:
    """noise -> gains -> noise to 1e-10 (relative to the largest normalised
    ratio) for random noise over six decades."""
    rng = np.random.default_rng(2)
    n = 300
    sp, sv, sa = (10.0 ** rng.uniform(-3, 3, n) * (rng.random(n) > 0.2) for _ in range(3))
    sa = np.where(sa == 0, 1.0, sa)
    sm, h = 10.0 ** rng.uniform(-1, 1, n), 10.0 ** rng.uniform(-0.5, 0.5, n)
    d = abg.from_noise(sp, sv, sa, sm, h)
    # (beyond, the ratios divide by a 1 - alpha that float64 gains hold only
    # to eps / (1 - alpha); see docs/abg.md)
    assert np.min(1 - d.alpha) > 1e-5
    q = abg.noise_ratios(d.alpha, d.beta, d.gamma, h)
    scale = np.maximum(np.maximum(sp, sv * h**2), sa * h**4) / sm
    for got, want, hp in zip(q, (sp / sm, sv / sm, sa / sm), (1.0, h**2, h**4)):
        assert np.all(np.abs(got - want) * hp <= 1e-10 * scale + 1e-12 * np.abs(want) * hp)


def test_stability_region_matches_eigenvalues() -> None:
    rng = np.random.default_rng(8)
    a, b, g = rng.uniform(-0.5, 2.5, 3000), rng.uniform(-0.5, 4.0, 3000), rng.uniform(-0.5, 3.0, 3000)
    jury = abg.stability_region(a, b, g).stable
    eig = abg.analyze(a, b, g).stable
    rho = np.array([max(abs(np.linalg.eigvals((np.eye(3) - np.array([[x], [y], [z]]) @ H3) @ phi()))) for x, y, z in zip(a, b, g)])
    clear = np.abs(rho - 1) > 1e-9
    np.testing.assert_array_equal(jury[clear], rho[clear] < 1)
    np.testing.assert_array_equal(eig[clear], rho[clear] < 1)
    assert 300 < jury.sum() < 2700
    s = abg.stability_region(0.5, 0.2, 0.04, convention="standard")
    assert s.stable and s.gamma == pytest.approx(0.02)


@pytest.mark.parametrize("sp,sv,sa,sm,r,h", [(3.0, 2.0, 1.0, 5.0, 0.6, 0.8), (0.1, 0.5, 1.0, 0.3, -0.4, 1.0), (0.0, 0.2, 2.0, 1.0, 0.9, 0.5), (1.0, 1.0, 1.0, 0.0, 0.5, 1.0)])
def test_coloured_from_noise_against_recursion_and_round_trip(sp, sv, sa, sm, r, h) -> None:
    S, w = _coloured_reference(sp, sv, sa, sm, r, h)
    g = abg.coloured_from_noise(sp, sv, sa, sm, r, h)
    np.testing.assert_allclose(g, w, rtol=1e-8, atol=1e-12)
    assert g.alpha + g.theta == pytest.approx(1.0, abs=1e-12)
    if sm > 0:
        c = abg.coloured(*g, r, h)
        assert c.near_optimal
        np.testing.assert_allclose([c.sigma_p_over_sigma_a, c.sigma_v_over_sigma_a, c.sigma_m_over_sigma_a], np.array([sp, sv, sm]) / sa, rtol=1e-9, atol=1e-9)
    s = abg.coloured_from_noise(sp, sv, sa, sm, r, h, convention="standard")
    assert s.gamma == pytest.approx(2 * g.gamma, rel=1e-15)


def test_coloured_from_noise_errors() -> None:
    with pytest.raises(np.linalg.LinAlgError, match="sigma_a"):
        abg.coloured_from_noise(1.0, 1.0, 0.0, 1.0, 0.5)
    with pytest.raises(ValueError, match="r"):
        abg.coloured_from_noise(1.0, 1.0, 1.0, 1.0, 1.0)
    with pytest.raises(ValueError, match="sigma_m"):
        abg.coloured_from_noise(1.0, 1.0, 1.0, -1.0, 0.5)
    g = abg.coloured_from_noise([1.0, 2.0], 1.0, 1.0, 1.0, [[0.1], [0.5]])
    assert np.shape(g.theta) == (2, 2)


@pytest.mark.parametrize("lam", [1e-3, 0.1, 1.0, 10.0, 1e3])
def test_tracking_index_continuous_white_jerk(lam: float) -> None:
    Qc = lam**2 * np.array([[1 / 20, 1 / 8, 1 / 6], [1 / 8, 1 / 3, 1 / 2], [1 / 6, 1 / 2, 1.0]])
    S = sla.solve_discrete_are(phi().T, H3.T, Qc, np.array([[1.0]]))
    w = (S @ H3.T / (S[0, 0] + 1.0)).ravel()
    d = abg.from_tracking_index(lam, model="continuous")
    np.testing.assert_allclose([d.alpha, d.beta, d.gamma], w, rtol=1e-7)
    assert d.stable
    assert abg.from_tracking_index(lam, model="dwpa").gamma == abg.from_tracking_index(lam).gamma
    with pytest.raises(ValueError, match="model"):
        abg.from_tracking_index(lam, model="singer")


def test_conversion_helpers_reject_bad_input() -> None:
    with pytest.raises(ValueError, match="gamma"):
        abg.convert(0.5, 0.2, np.nan)
    with pytest.raises(ValueError, match="alpha"):
        abg.to_predictor(np.inf, 0.2, 0.1)
    with pytest.raises(ValueError, match="h"):
        abg.to_predictor(0.5, 0.2, 0.1, h=0.0)
    with pytest.raises(ValueError, match="K"):
        abg.from_predictor([0.5, 0.2])
    with pytest.raises(ValueError, match="K"):
        abg.from_predictor([0.5, np.nan, 0.1])
    with pytest.raises(TypeError):
        abg.convert("a", 0.2, 0.1)


def test_design_filter_and_repr() -> None:
    d = abg.from_noise(0.3, 0.2, 0.1, 1.0, h=0.7, convention="standard")
    f = d.filter()
    assert f.convention == "standard" and f.T == 0.7
    np.testing.assert_allclose(f.gamma, d.gamma)
    assert "near_optimal=True" in repr(d)
    assert "shape=(2,)" in repr(abg.analyze([0.5, 0.6], 0.2, 0.02))
    assert abg.analyze([0.5, 0.6], 0.2, 0.02).table().startswith("ABG(")
