"""Steady-state analysis of arbitrary gains: error_covariance, analyze() covariances,
variance reduction, lag, scaled_covariance.

Independent references (tests/abref.py): scipy.linalg.solve_discrete_lyapunov,
a 50-digit mpmath linear solve of the same Lyapunov equation, Kalata's r(alpha)
in mpmath, the physical-unit scipy DARE, Monte-Carlo simulation of the
generating model with the filter recursion, and deterministic simulation of
the recursion on a parabola.

Error measure for a covariance X: ``|dX_ij| / sqrt(X_ii X_jj)`` (relative error
on the diagonal, error relative to the correlation scale off the diagonal,
where entries can pass through zero).

Tolerances:

* ``RTOL_LYAP = 1e-10`` against scipy on random stable gains (kept away from
  the stability boundary: 4 - 2 alpha - beta >= 1e-3 (alpha + beta), spectral
  radius <= 0.995, where scipy itself is accurate to ~1e-13).
* ``RTOL_MP = 1e-12 * kappa`` against the 50-digit Lyapunov solution, where
  ``kappa = max(1, (2 alpha + beta) / (4 - 2 alpha - beta))`` is the relative
  condition number of the covariance with respect to the gains (every entry
  is proportional to 1 / (4 - 2 alpha - beta)); this matters only close to the
  stability boundary, e.g. for the Kalman gains of r >= 1e8.
* Monte Carlo: 5 standard errors of the sample (co)variance, fixed seeds.
* ``RTOL_LAG = 1e-9`` against the simulated lag.
"""

from __future__ import annotations

import math

import mpmath
import numpy as np
import pytest
import scipy.linalg

import abref
from abkit import alphabeta as ab

RTOL_LYAP = 1e-10
RTOL_MP = 1e-12
RTOL_LAG = 1e-9
MC_SIGMAS = 5.0
SQRT_HALF = 1.0 / math.sqrt(2.0)


def kappa(alpha, beta):
    alpha = np.asarray(alpha, dtype=float)
    beta = np.asarray(beta, dtype=float)
    return np.maximum(1.0, (2 * alpha + beta) / (4 - 2 * alpha - beta))


def cov_err(got, want):
    """max |dX_ij| / sqrt(X_ii X_jj) for 2x2 covariances."""
    got = np.asarray(got, dtype=float)
    want = np.asarray(want, dtype=float)
    d = np.sqrt(np.abs(np.diag(want)))
    return float(np.max(np.abs(got - want) / np.outer(d, d)))


def mat(v):
    """[x11, x12, x22] (floats or mpf) -> symmetric 2x2 float array."""
    return np.array([[float(v[0]), float(v[1])], [float(v[1]), float(v[2])]])


def spectral_radius(a, b):
    return float(np.max(np.abs(np.roots([1.0, -(2.0 - a - b), 1.0 - a]))))


def random_stable_gains(n, seed, margin=1e-3, rho_max=0.995):
    """Stable (alpha, beta) kept away from the boundary, plus small gains."""
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < n:
        a = rng.uniform(0.005, 1.99)
        b = rng.uniform(0.0, 4 - 2 * a)
        if b <= 0 or 4 - 2 * a - b < margin * (a + b):
            continue
        if spectral_radius(a, b) > rho_max:
            continue
        out.append((a, b))
    return out


# ---------------------------------------------------------------------------
# error_covariance
# ---------------------------------------------------------------------------
def _lyap_cases():
    rng = np.random.default_rng(11)
    cases = []
    for a, b in random_stable_gains(60, 10):
        r = 0.0 if rng.uniform() < 0.2 else float(10 ** rng.uniform(-8, 4))
        cases.append((a, b, r))
    return cases


LYAP_CASES = _lyap_cases()


@pytest.mark.parametrize("alpha,beta,r_true", LYAP_CASES, ids=[f"case{i}" for i in range(len(LYAP_CASES))])
def test_error_covariance_vs_scipy_lyapunov(alpha, beta, r_true):
    """error_covariance == scipy.linalg.solve_discrete_lyapunov of
    M = F(I - K h) M (F(I - K h))' + F K K' F' + Q, P = (I - K h) M (I - K h)' + K K'.
    RTOL_LYAP = 1e-10 (normalised entrywise measure)."""
    P, M = abref.lyap_scipy(alpha, beta, r_true)
    c = ab.error_covariance(alpha, beta, r_true)
    assert c.filtered.shape == (2, 2) and c.predicted.shape == (2, 2)
    assert cov_err(c.filtered, P) <= RTOL_LYAP
    assert cov_err(c.predicted, M) <= RTOL_LYAP
    np.testing.assert_array_equal(c.filtered, c.filtered.T)


def test_error_covariance_vectorised_vs_scipy():
    """One vectorised call over all random cases, same tolerance."""
    a, b, r = (np.array(x) for x in zip(*LYAP_CASES))
    c = ab.error_covariance(a, b, r)
    assert c.filtered.shape == (len(a), 2, 2)
    for i in range(len(a)):
        P, M = abref.lyap_scipy(a[i], b[i], r[i])
        assert cov_err(c.filtered[i], P) <= RTOL_LYAP
        assert cov_err(c.predicted[i], M) <= RTOL_LYAP


R_DESIGN = [1e-12, 1e-8, 1e-4, 1e-2, 1.0, 1e2, 1e4, 1e8, 1e12]
R_TRUE = [0.0, 1e-12, 1e-6, 1e-2, 1.0, 1e3, 1e12]


@pytest.mark.parametrize("r_design", R_DESIGN)
def test_error_covariance_mismatched_vs_mpmath(r_design):
    """Kalman gains of r_design applied at every r_true (mismatched designs),
    against the 50-digit Lyapunov solution: rtol 1e-12 * kappa."""
    d = ab.from_snr(r_design)
    a, b = d.alpha, d.beta
    tol = RTOL_MP * float(kappa(a, b))
    c = ab.error_covariance(a, b, np.array(R_TRUE))
    for i, rt in enumerate(R_TRUE):
        P, M = abref.lyap_mp(a, b, rt)
        assert cov_err(c.filtered[i], mat(P)) <= tol, (r_design, rt, c.filtered[i], mat(P))
        assert cov_err(c.predicted[i], mat(M)) <= tol, (r_design, rt, c.predicted[i], mat(M))


@pytest.mark.parametrize("r_design", [1e-6, 1e-3, 0.1, 10.0])
@pytest.mark.parametrize("factor", [0.01, 0.5, 2.0, 100.0])
def test_error_covariance_mismatched_vs_scipy(r_design, factor):
    """Mismatched: Kalman gains of r_design, truth r_design * factor; scipy
    Lyapunov, RTOL_LYAP. The Kalman filter of r_true does at least as well:
    P(mismatched) - P_kalman(r_true) is positive semidefinite."""
    d = ab.from_snr(r_design)
    rt = r_design * factor
    c = ab.error_covariance(d.alpha, d.beta, rt)
    P, M = abref.lyap_scipy(d.alpha, d.beta, rt)
    assert cov_err(c.filtered, P) <= RTOL_LYAP
    assert cov_err(c.predicted, M) <= RTOL_LYAP
    Mk, Pk = abref.dare_scipy(rt)
    scale = np.trace(Pk)
    assert np.min(np.linalg.eigvalsh(c.filtered - Pk)) >= -1e-10 * scale
    assert c.filtered[0, 0] > Pk[0, 0]


@pytest.mark.parametrize("r", [1e-12, 1e-6, 1e-2, 1.0, 1e4, 1e12])
def test_error_covariance_of_kalman_gains_is_dare(r):
    """error_covariance(Kalman gains of r, r) == the DARE solution (50 digits),
    rtol 1e-12 * kappa."""
    d = ab.from_snr(r)
    ref = abref.dare_mp_float(r)
    c = ab.error_covariance(d.alpha, d.beta, r)
    tol = RTOL_MP * float(kappa(d.alpha, d.beta))
    assert cov_err(c.filtered, [[ref["p11"], ref["p12"]], [ref["p12"], ref["p22"]]]) <= tol
    assert cov_err(c.predicted, [[ref["m11"], ref["m12"]], [ref["m12"], ref["m22"]]]) <= tol


def test_error_covariance_method_matches_function():
    d = ab.from_bandwidth(np.array([0.02, 0.1]), 0.6)
    c1 = d.error_covariance(0.3)
    c2 = ab.error_covariance(d.alpha, d.beta, 0.3)
    np.testing.assert_array_equal(c1.filtered, c2.filtered)
    np.testing.assert_array_equal(c1.predicted, c2.predicted)


# ---------------------------------------------------------------------------
# analyze(): covariances at the model r
# ---------------------------------------------------------------------------
ANALYZE_GAINS = [(a, b) for a, b in random_stable_gains(30, 20) if a < 0.99] + [
    (0.5, 0.25 / 1.5),  # Benedict-Bordner
    (0.1, 0.1**2 / 1.9),
    (0.9, 0.81 / 1.1),
    (0.3, 0.3),
    (0.05, 0.2),
]


@pytest.mark.parametrize("alpha,beta", ANALYZE_GAINS, ids=[f"g{i}" for i in range(len(ANALYZE_GAINS))])
def test_analyze_covariances_at_model_r(alpha, beta):
    """analyze(alpha, beta): r == Kalata r(alpha) (mpmath, rtol 1e-12), and
    covariance_filtered / covariance_predicted / tracking_error_ratio are the
    fixed-gain Lyapunov solution of *these* gains at that r (scipy, RTOL_LYAP);
    tracking_error_ratio >= alpha (Kalman is optimal at that r)."""
    d = ab.analyze(alpha, beta)
    r = float(abref.kalata_r_mp(alpha))
    assert abs(d.r - r) <= 1e-12 * r
    P, M = abref.lyap_scipy(alpha, beta, r)
    assert cov_err(d.covariance_filtered, P) <= RTOL_LYAP
    assert cov_err(d.covariance_predicted, M) <= RTOL_LYAP
    assert abs(d.tracking_error_ratio - P[0, 0]) <= RTOL_LYAP * P[0, 0]
    assert d.tracking_error_ratio >= alpha * (1 - 1e-12)
    # P - P_kalman(r) is positive semidefinite
    ref = abref.dare_mp_float(r)
    Pk = np.array([[ref["p11"], ref["p12"]], [ref["p12"], ref["p22"]]])
    assert np.min(np.linalg.eigvalsh(d.covariance_filtered - Pk)) >= -1e-10 * np.trace(Pk)


@pytest.mark.parametrize("r", [1e-12, 1e-6, 1e-2, 1.0, 1e2, 1e4, 1e8, 1e12])
def test_analyze_kalman_gains_vs_mpmath(r):
    """analyze(Kalman gains of r): covariances == 50-digit Lyapunov solution of
    those (float) gains at the exact Kalata r(alpha), rtol 1e-12 * kappa; and
    tracking_error_ratio == alpha within the same tolerance."""
    k = ab.from_snr(r)
    d = ab.analyze(k.alpha, k.beta)
    rm = abref.kalata_r_mp(k.alpha)
    assert abs(d.r / float(rm) - 1) <= 1e-12
    P, M = abref.lyap_mp(k.alpha, k.beta, rm)
    tol = RTOL_MP * float(kappa(k.alpha, k.beta))
    assert cov_err(d.covariance_filtered, mat(P)) <= tol
    assert cov_err(d.covariance_predicted, mat(M)) <= tol
    assert abs(d.tracking_error_ratio / k.alpha - 1) <= tol
    assert d.kalman_optimal is True


def test_analyze_unstable_gives_inf():
    """Unstable gains: stable False; steady-state covariances, variance reduction
    and lag are inf (documented), never NaN."""
    alpha = np.array([1.5, 0.5, 2.5, 1.0])
    d = ab.analyze(alpha, np.array([1.5, 3.5, 0.5, 2.0]))
    assert not np.any(d.stable) and not np.any(d.valid)
    for x in (d.covariance_filtered, d.covariance_predicted):
        assert not np.any(np.isnan(x))
    assert np.all(np.isinf(d.tracking_error_ratio))
    for v in (*d.variance_reduction, *d.lag):
        assert not np.any(np.isnan(v))
        assert np.all(np.isinf(v))
    assert np.all(np.isinf(d.r[alpha >= 1]))
    assert np.all(np.isfinite(d.r[alpha < 1]))


# ---------------------------------------------------------------------------
# variance reduction
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("alpha,beta", random_stable_gains(25, 30) + [(0.5, 0.25 / 1.5), (1e-4, 5e-9), (1.5, 0.4)])
def test_variance_reduction_vs_lyapunov(alpha, beta):
    """variance_reduction == diagonal of the fixed-gain covariance at r = 0:
    position_filtered = P11, velocity_filtered = P22, position_predicted = M11,
    velocity_predicted = M22 (scipy Lyapunov, RTOL_LYAP; mpmath, 1e-12 * kappa)."""
    d = ab.analyze(alpha, beta)
    vr = d.variance_reduction
    got = np.array([vr.position_filtered, vr.velocity_filtered, vr.position_predicted, vr.velocity_predicted])
    P, M = abref.lyap_mp(alpha, beta, 0)
    want = np.array([float(P[0]), float(P[2]), float(M[0]), float(M[2])])
    np.testing.assert_allclose(got, want, rtol=RTOL_MP * float(kappa(alpha, beta)), atol=0)
    if spectral_radius(alpha, beta) < 0.995:
        Ps, Ms = abref.lyap_scipy(alpha, beta, 0.0)
        np.testing.assert_allclose(got, [Ps[0, 0], Ps[1, 1], Ms[0, 0], Ms[1, 1]], rtol=RTOL_LYAP, atol=0)
    # and it is what error_covariance gives at r_true = 0
    c = ab.error_covariance(alpha, beta, 0.0)
    np.testing.assert_allclose(got, [c.filtered[0, 0], c.filtered[1, 1], c.predicted[0, 0], c.predicted[1, 1]],
                               rtol=1e-14, atol=0)


MC_CASES = [
    # alpha, beta, r_true, chains, steps
    (0.5, 0.2, 0.0, 100_000, 120),
    (1.2, 0.8, 0.0, 100_000, 120),
    (0.4673280449, 0.1459687576, 0.0, 100_000, 150),  # ~ Kalman gains of r = 0.01
    (0.4673280449, 0.1459687576, 0.1, 100_000, 150),  # mismatched truth
    (0.8, 0.5, 2.0, 100_000, 120),
]


@pytest.mark.parametrize("alpha,beta,r_true,chains,steps", MC_CASES)
def test_covariances_vs_monte_carlo(alpha, beta, r_true, chains, steps):
    """Monte Carlo of the generating model x' = F x + sqrt(r) [1, 2] n and
    z = x1 + v with the alpha-beta recursion (independent chains, fixed seed),
    against variance_reduction (r = 0) and error_covariance (all r):
    |sample - abkit| <= 5 standard errors, se(S_ij) = sqrt((S_ii S_jj + S_ij^2)/N).
    The transient is < 1e-6 of the variance after `steps` steps."""
    rho = spectral_radius(alpha, beta)
    assert rho ** (2 * steps) < 1e-6
    Ps, Ms = abref.monte_carlo_covariance(alpha, beta, r_true, chains, steps, seed=12345)
    c = ab.error_covariance(alpha, beta, r_true)
    for got, S in ((c.filtered, Ps), (c.predicted, Ms)):
        se = np.sqrt((np.outer(np.diag(got), np.diag(got)) + got**2) / chains)
        assert np.all(np.abs(S - got) <= MC_SIGMAS * se), (S, got, se)
    if r_true == 0.0:
        vr = ab.analyze(alpha, beta).variance_reduction
        got = np.array([vr.position_filtered, vr.velocity_filtered, vr.position_predicted, vr.velocity_predicted])
        sample = np.array([Ps[0, 0], Ps[1, 1], Ms[0, 0], Ms[1, 1]])
        se = got * math.sqrt(2.0 / chains)
        assert np.all(np.abs(sample - got) <= MC_SIGMAS * se), (sample, got)


# ---------------------------------------------------------------------------
# lag
# ---------------------------------------------------------------------------
def _lag_cases():
    cases = []
    for r in (1e-3, 1e-2, 0.1, 1.0, 10.0, 100.0):
        k = ab.from_snr(r)
        cases.append((k.alpha, k.beta))
    for a in (0.2, 0.5, 0.8):
        cases.append((a, a * a / (2 - a)))  # Benedict-Bordner
    cases += [(0.5, 1.0), (0.3, 0.6), (1.2, 0.8), (1.5, 0.3), (0.9, 2.0), (0.05, 0.2)]
    return cases


LAG_CASES = _lag_cases()


@pytest.mark.parametrize("alpha,beta", LAG_CASES, ids=[f"a={a:.4g}-b={b:.4g}" for a, b in LAG_CASES])
def test_lag_vs_simulation(alpha, beta):
    """Steady-state lag (truth minus estimate) under constant acceleration, from a
    50-digit deterministic simulation of the recursion on x_k = a (kT)^2 / 2 with
    the truth advanced by F x + a [T^2/2, T]: position in a T^2, velocity in a T,
    filtered and one-step predicted. rtol RTOL_LAG = 1e-9 (abs 1e-12 for zero lags)."""
    want = abref.simulate_lag(alpha, beta)
    lag = ab.analyze(alpha, beta).lag
    got = (lag.position_filtered, lag.velocity_filtered, lag.position_predicted, lag.velocity_predicted)
    np.testing.assert_allclose(got, want, rtol=RTOL_LAG, atol=1e-12)


def test_lag_vectorised_and_per_design():
    """Lag is the same from analyze and from every constructor (vectorised), rtol 1e-9
    vs the simulation."""
    d = ab.from_bandwidth(np.array([0.02, 0.08, 0.2]), np.array([0.5, 1.0, SQRT_HALF]))
    for i in range(3):
        want = abref.simulate_lag(d.alpha[i], d.beta[i])
        got = [x[i] for x in d.lag]
        np.testing.assert_allclose(got, want, rtol=RTOL_LAG, atol=1e-12)


# ---------------------------------------------------------------------------
# scaled_covariance
# ---------------------------------------------------------------------------
PHYS_CASES = [(3.2, 32.0, 0.1), (1.0, 1.0, 1.0), (9.81, 5.0, 0.5), (0.2, 0.03, 2.0), (50.0, 2.0, 0.02)]


def _physical_dare(sigma_w, sigma_v, T):
    Fp = np.array([[1.0, T], [0.0, 1.0]])
    dp = np.array([[T * T / 2], [T]])
    Qp = sigma_w**2 * (dp @ dp.T)
    Rp = np.array([[sigma_v**2]])
    M = scipy.linalg.solve_discrete_are(Fp.T, abref.H.T, Qp, Rp)
    S = M[0, 0] + sigma_v**2
    P = M - np.outer(M[:, 0], M[0, :]) / S
    return P, M


@pytest.mark.parametrize("sigma_w,sigma_v,T", PHYS_CASES)
def test_scaled_covariance_vs_physical_dare(sigma_w, sigma_v, T):
    """from_noise(...).scaled_covariance(sigma_v) (filtered and predicted) == the DARE
    of the un-normalised model F = [[1, T], [0, 1]], Q = sigma_w^2 d d',
    d = [T^2/2, T], R = sigma_v^2 (scipy; rtol 1e-9 normalised measure); the
    physical Kalman gain is (P11, P12) / sigma_v^2 = (alpha, beta / T)."""
    d = ab.from_noise(sigma_w, sigma_v, T)
    P, M = _physical_dare(sigma_w, sigma_v, T)
    assert cov_err(d.scaled_covariance(sigma_v), P) <= 1e-9
    assert cov_err(d.scaled_covariance(sigma_v, kind="filtered"), P) <= 1e-9
    assert cov_err(d.scaled_covariance(sigma_v, T, kind="predicted"), M) <= 1e-9
    g1, g2 = d.gains()
    assert abs(g1 - P[0, 0] / sigma_v**2) <= 1e-9 * g1
    assert abs(g2 - P[0, 1] / sigma_v**2) <= 1e-9 * g2


@pytest.mark.parametrize("alpha,beta", [(0.5, 0.2), (0.2, 0.01), (0.95, 0.9)])
def test_scaled_covariance_fixed_gain_physical(alpha, beta):
    """analyze(alpha, beta).scaled_covariance(sigma_v, T) == physical-unit Lyapunov
    solution with gains (alpha, beta / T), F = [[1, T], [0, 1]], Q = sigma_w^2 d d'
    with sigma_w chosen so that ((sigma_w T^2/2)/sigma_v)^2 = the design r;
    R = sigma_v^2. rtol 1e-10 (normalised measure)."""
    sigma_v, T = 7.0, 0.3
    d = ab.analyze(alpha, beta)
    sigma_w = 2.0 * math.sqrt(d.r) * sigma_v / T**2
    Fp = np.array([[1.0, T], [0.0, 1.0]])
    K = np.array([[alpha], [beta / T]])
    IKh = np.eye(2) - K @ abref.H
    dp = np.array([[T * T / 2], [T]])
    Qp = sigma_w**2 * (dp @ dp.T)
    M = scipy.linalg.solve_discrete_lyapunov(Fp @ IKh, Fp @ K @ K.T @ Fp.T * sigma_v**2 + Qp)
    P = IKh @ M @ IKh.T + K @ K.T * sigma_v**2
    assert cov_err(d.scaled_covariance(sigma_v, T), P) <= 1e-10
    assert cov_err(d.scaled_covariance(sigma_v, T, kind="predicted"), M) <= 1e-10


def test_scaled_covariance_units_and_broadcast():
    """Entry scaling [[s^2, s^2/T], [s^2/T, s^2/T^2]] (exact up to rounding),
    broadcast over sigma_v arrays; invalid kind and sigma_v raise."""
    d = ab.from_snr(0.3)
    C = d.covariance_filtered
    sv = np.array([0.5, 2.0, 10.0])
    T = 0.25
    S = d.scaled_covariance(sv, T)
    assert S.shape == (3, 2, 2)
    for i, s in enumerate(sv):
        want = np.array([[C[0, 0] * s * s, C[0, 1] * s * s / T], [C[1, 0] * s * s / T, C[1, 1] * s * s / T / T]])
        np.testing.assert_allclose(S[i], want, rtol=1e-15, atol=0)
    with pytest.raises(ValueError, match="kind"):
        d.scaled_covariance(1.0, 1.0, kind="smoothed")
    with pytest.raises(ValueError, match="sigma_v"):
        d.scaled_covariance(-1.0, 1.0)
    with pytest.raises(ValueError, match="T"):
        d.scaled_covariance(1.0)  # no T recorded
    with pytest.raises(ValueError, match="T"):
        d.scaled_covariance(1.0, 0.0)
