"""Steady-state RTS smoothing (fixed interval and fixed lag) and theoretical covariances.

Expected values: tests/filterref.py (plain NumPy smoother recursion over the
reference filter output; covariances from scipy's Lyapunov/DARE solvers).
Tolerance: 1e-12 of each state component's scale (float64); covariance and
gain matrices within 1e-10 relative to the matrix's largest entry.
Statistical checks use fixed seeds and tolerances of several standard errors.
"""

from __future__ import annotations

import numpy as np
import pytest

import abkit
import filterref as fr
from abkit import AlphaBetaFilter, AlphaBetaGammaFilter, FixedGainFilter

RTOL = 1e-12
LAGS = [None, 0, 1, 2, 7, 40, 10_000]


def ref_smooth(z, model, init, A, lag):
    s3_in, single = fr.as_tracks(z, model.m)
    xf, res, _ = fr.filter_ref(s3_in, model, init)
    xs = fr.smooth_ref(xf, model, A, lag)
    s, r = fr.to_user(xs, res, single, model.m)
    return s, r


def mat_close(got, want, rtol=1e-10):
    got, want = np.asarray(got), np.asarray(want)
    assert got.shape == want.shape, (got.shape, want.shape)
    scale = np.max(np.abs(want))
    assert np.max(np.abs(got - want)) <= rtol * scale, (got, want)


# ---------------------------------------------------------------------------
# against the reference recursion, explicit backward gain
# ---------------------------------------------------------------------------
SM_CASES = [(pat, init, lag) for pat in ["none", "mixed", "start-gaps", "one-valid", "all-nan-tracks"] for init in ["two-point", "first", "array"] for lag in LAGS]


@pytest.mark.parametrize("pattern,init,lag", SM_CASES)
def test_alphabeta_smoother(pattern, init, lag):
    rng = np.random.default_rng(fr.seed_of("ab", pattern, init, lag))
    a, b = fr.random_ab_gains(rng)
    T = rng.uniform(0.1, 2.0)
    z = fr.with_nans(rng, fr.kinematic_z(rng, 5, 160, T), pattern)
    A = rng.normal(0, 0.3, (2, 2)) + 0.5 * np.eye(2)
    init_v = rng.normal(size=2) if init == "array" else init
    r = AlphaBetaFilter(a, b, T).smooth(z, lag=lag, smoother_gain=A, init=init_v, return_residuals=True)
    s, res = ref_smooth(z, fr.ab_model(a, b, T), init_v, A, lag)
    fr.assert_states_close(r.states, s, RTOL)
    fr.assert_resid_close(r.residuals, res, RTOL)


@pytest.mark.parametrize("conv", list(fr.ABG_C))
@pytest.mark.parametrize("lag", LAGS)
def test_alphabetagamma_smoother(conv, lag):
    rng = np.random.default_rng(fr.seed_of("abg", conv, lag))
    T = 0.5
    a, b, g = fr.random_abg_gains(rng, conv, T)
    z = fr.with_nans(rng, fr.kinematic_z(rng, 4, 150, T), "mixed")
    A = rng.normal(0, 0.2, (3, 3)) + 0.5 * np.eye(3)
    r = AlphaBetaGammaFilter(a, b, g, T, convention=conv).smooth(z, lag=lag, smoother_gain=A)
    s, _ = ref_smooth(z, fr.abg_model(a, b, g, T, conv), "two-point", A, lag)
    fr.assert_states_close(r.states, s, RTOL)


def _singer(T=0.5):
    Phi = fr.singer_phi(T, 0.3)
    H = np.array([[1.0, 0, 0], [0, 1.0, 0]])
    Q = np.diag([0.01, 0.02, 0.1])
    R = np.diag([1.0, 0.5])
    K = fr.dare_gain(Phi, H, Q, R)
    return Phi, H, K, T, Q, R


@pytest.mark.parametrize("lag", LAGS)
@pytest.mark.parametrize("pattern", ["none", "mixed"])
def test_fixed_gain_vector_smoother_QR(lag, pattern):
    Phi, H, K, T, Q, R = _singer()
    rng = np.random.default_rng(fr.seed_of("singer", lag, pattern))
    z = fr.with_nans(rng, fr.kinematic_z(rng, 4, 150, T, m=2), pattern)
    f = FixedGainFilter(Phi, H, K, T)
    A = fr.fixed_gain_cov(Phi, H, K, Q, R).smoother_gain
    mat_close(f.smoother_gain(Q, R)[0], A)
    r = f.smooth(z, lag=lag, Q=Q, R=R, init="first", return_residuals=True)
    s, res = ref_smooth(z, fr.general_model(Phi, H, K, T), "first", A, lag)
    fr.assert_states_close(r.states, s, RTOL)
    fr.assert_resid_close(r.residuals, res, RTOL, m=2)


@pytest.mark.parametrize("lag", [None, 3])
def test_per_track_smoother_gains(lag):
    rng = np.random.default_rng(5)
    ntr = 6
    a, b = fr.random_ab_gains(rng, ntr)
    T = rng.uniform(0.1, 1.0, ntr)
    A = rng.normal(0, 0.3, (ntr, 2, 2))
    z = fr.with_nans(rng, fr.kinematic_z(rng, ntr, 120, T), "mixed")
    r = AlphaBetaFilter(a, b, T).smooth(z, lag=lag, smoother_gain=A)
    s, _ = ref_smooth(z, fr.ab_model(a, b, T), "two-point", A, lag)
    fr.assert_states_close(r.states, s, RTOL)
    # per-track gains with a shared filter
    r = AlphaBetaFilter(0.5, 0.2, 0.3).smooth(z, lag=lag, smoother_gain=A)
    s, _ = ref_smooth(z, fr.ab_model(0.5, 0.2, 0.3), "two-point", A, lag)
    fr.assert_states_close(r.states, s, RTOL)


def test_smoother_single_track():
    rng = np.random.default_rng(6)
    z = fr.with_nans(rng, fr.kinematic_z(rng, 1, 400, 0.2), "random")[0]
    f = AlphaBetaFilter(0.4, 0.1, 0.2)
    A = f.smoother_gain()
    for lag in (None, 5):
        r = f.smooth(z, lag=lag)
        s, _ = ref_smooth(z, fr.ab_model(0.4, 0.1, 0.2), "two-point", A, lag)
        fr.assert_states_close(r.states, s, RTOL)


def _f32_case(kind):
    T = 0.2
    if kind == "ab":
        f = AlphaBetaFilter(0.4, 0.1, T)
        return f, fr.ab_model(0.4, 0.1, T), f.smoother_gain()[0], "two-point", 1
    if kind == "abg":
        f = AlphaBetaGammaFilter(0.5, 0.2, 0.02, T)
        Q = np.diag([1e-4, 1e-3, 1e-2])
        return f, fr.abg_model(0.5, 0.2, 0.02, T), f.smoother_gain(Q, [[1.0]])[0], "two-point", 1
    Phi, H, K, T, Q, R = _singer(T)
    f = FixedGainFilter(Phi, H, K, T)
    return f, fr.general_model(Phi, H, K, T), f.smoother_gain(Q, R)[0], "first", 2


@pytest.mark.parametrize("kind", ["ab", "abg", "singer"])
@pytest.mark.parametrize("lag", [None, 5])
def test_smoother_float32(kind, lag):
    """docs/filtering.md: float32 ``run`` outputs are the float64 results rounded
    once, but ``smooth``'s backward pass works from the float32-rounded filtered
    estimates, and is documented to agree with the float64 smoother (from the
    same float32 inputs) within 64 float32 eps of each component's scale.
    The message reports the worst error in float32 eps x the component's scale."""
    f, model, A, init, m = _f32_case(kind)
    rng = np.random.default_rng(fr.seed_of("f32s", kind, lag))
    z32 = fr.with_nans(rng, fr.kinematic_z(rng, 3, 600, model.T[0], m=m), "random").astype(np.float32)
    r32 = f.smooth(z32, lag=lag, smoother_gain=A, init=init)
    assert r32.states.dtype == np.float32
    z3, single = fr.as_tracks(z32, m)
    xf, _, _ = fr.filter_ref(z3, model, init)
    want64 = np.moveaxis(fr.smooth_ref(xf, model, A, lag), 2, 0)
    got = r32.states.astype(np.float64)
    fin = ~np.isnan(want64)
    assert np.array_equal(np.isnan(got), ~fin)
    eps32 = float(np.finfo(np.float32).eps)
    report = []
    ok = True
    for c in range(model.n):
        w, g, fc = want64[c], got[c], fin[c]
        scale = np.max(np.abs(w[fc]))
        ulp = np.spacing(np.abs(w[fc]).astype(np.float32)).astype(np.float64)
        err = np.abs(g[fc] - w[fc])
        ok &= bool(np.all(err <= 64 * eps32 * scale))
        report.append(f"component {c}: worst {np.max(err / ulp):.3g} ulp of the element, {np.max(err) / (eps32 * scale):.3g} eps32 x scale")
    assert ok, f"float32 smooth({kind}, lag={lag}) exceeds the documented bound: " + "; ".join(report)


def test_lag_zero_is_filtered_and_state_residuals_match_run():
    rng = np.random.default_rng(7)
    z = fr.with_nans(rng, fr.kinematic_z(rng, 3, 100, 1.0), "mixed")
    f = AlphaBetaFilter(0.5, 0.2, 1.0)
    run = f.run(z, return_residuals=True)
    for lag in (None, 0, 4):
        sm = f.smooth(z, lag=lag, return_residuals=True)
        assert np.array_equal(sm.residuals, run.residuals, equal_nan=True)
        assert np.array_equal(sm.state.x, run.state.x, equal_nan=True)
        assert np.array_equal(sm.state.phase, run.state.phase)
        # the last sample of every track is its filtered estimate
        assert np.array_equal(sm.states[:, :, -1], run.states[:, :, -1], equal_nan=True)
    assert np.array_equal(f.smooth(z, lag=0).states, run.states, equal_nan=True)


def test_long_lag_equals_fixed_interval():
    rng = np.random.default_rng(8)
    z = fr.with_nans(rng, fr.kinematic_z(rng, 3, 100, 1.0), "mixed")
    f = AlphaBetaFilter(0.5, 0.2, 1.0)
    fi = f.smooth(z).states
    for lag in (99, 100, 5000):
        fr.assert_states_close(f.smooth(z, lag=lag).states, fi, RTOL)


def test_smoother_nan_rules_spelled_out():
    """Start-up samples (NaN component in the filtered estimate) stay as filtered."""
    z = np.array([np.nan, 1.0, np.nan, 2.0, 3.1, np.nan, 5.0, 6.2])
    f = AlphaBetaFilter(0.5, 0.2, 1.0)
    run = f.run(z)
    sm = f.smooth(z)
    assert np.isnan(sm.states[0, 0]) and np.isnan(sm.states[1, 0])
    assert np.array_equal(sm.states[:, :3], run.states[:, :3], equal_nan=True)  # [NaN], [1, NaN], [1, NaN]
    assert np.all(np.isfinite(sm.states[:, 3:]))
    # sample 3 is the end of the chain (its successor chain starts at 7)
    A = f.smoother_gain()[0]
    Phi = np.array([[1.0, 1.0], [0.0, 1.0]])
    xs = run.states[:, 7]
    for k in range(6, 2, -1):
        xs = run.states[:, k] + A @ (xs - Phi @ run.states[:, k])
        np.testing.assert_allclose(sm.states[:, k], xs, rtol=1e-13, atol=1e-13)


# ---------------------------------------------------------------------------
# default backward gain and covariances
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("r", [1e-4, 1e-2, 0.1, 1.0, 10.0, 100.0])
@pytest.mark.parametrize("T", [0.05, 1.0, 4.0])
def test_default_gain_of_kalman_design_is_dare(r, T):
    alpha, beta, A = fr.kalman_ab_dare(r, T)
    d = abkit.alphabeta.from_snr(r)
    assert abs(d.alpha - alpha) < 1e-12 and abs(d.beta - beta) < 1e-12
    f = AlphaBetaFilter.from_design(d, T)
    got = f.smoother_gain()
    assert got.shape == (1, 2, 2)
    mat_close(got[0], A, 1e-10)
    # and the smoother uses it by default
    rng = np.random.default_rng(9)
    z = fr.with_nans(rng, fr.kinematic_z(rng, 2, 120, T), "mixed")
    s, _ = ref_smooth(z, fr.ab_model(d.alpha, d.beta, T), "two-point", A, None)
    fr.assert_states_close(f.smooth(z).states, s, 1e-10)


@pytest.mark.parametrize("a,b,T", [(0.5, 0.2, 1.0), (0.3, 0.3 ** 2 / 1.7, 0.1), (0.9, 0.05, 2.0), (0.05, 0.5, 1.0), (0.7, 1.2, 0.5)])
def test_default_gain_non_kalman_gains(a, b, T):
    """Documented: these gains' covariances under the Kalman-equivalent model (the SNR whose
    Kalman design has this alpha)."""
    f = AlphaBetaFilter(a, b, T)
    mat_close(f.smoother_gain()[0], fr.default_ab_smoother_gain(a, b, T), 1e-10)


def test_default_gain_per_track():
    a = np.array([0.2, 0.5, 0.8])
    b = np.array([0.02, 0.2, 0.5])
    T = np.array([0.1, 1.0, 3.0])
    g = AlphaBetaFilter(a, b, T).smoother_gain()
    assert g.shape == (3, 2, 2)
    for i in range(3):
        mat_close(g[i], fr.default_ab_smoother_gain(a[i], b[i], T[i]), 1e-10)


@pytest.mark.parametrize("sigma_w,sigma_v,T,a,b", [(0.5, 2.0, 0.1, 0.3, 0.05), (2.0, 1.0, 1.0, 0.6, 0.3), (0.0, 3.0, 0.5, 0.2, 0.02), (1.0, 1.0, 2.0, 1.2, 0.9)])
def test_alphabeta_covariances(sigma_w, sigma_v, T, a, b):
    f = AlphaBetaFilter(a, b, T)
    Q = fr.white_accel_Q(T, sigma_w)
    R = np.array([[sigma_v**2]])
    want = fr.fixed_gain_cov(f.Phi, f.H, f.K, Q, R)
    K = np.array([[a], [b / T]])
    assert np.allclose(f.K, K, rtol=1e-15)
    for got in (f.covariances(sigma_w=sigma_w, sigma_v=sigma_v), f.covariances(Q, R)):
        mat_close(got.predicted, want.predicted)
        mat_close(got.filtered, want.filtered)
        if sigma_w > 0:  # (no process noise: no steady-state smoother, see below)
            mat_close(got.smoothed, want.smoothed)
            mat_close(got.smoother_gain, want.smoother_gain)


@pytest.mark.parametrize("a,b", [(0.2, 0.02), (0.5, 0.2)])
def test_covariances_without_process_noise_have_no_steady_state_smoother(a, b):
    """Q = 0: M = Phi P Phi^T exactly, so A = P Phi^T M^-1 = Phi^-1 (eigenvalues 1):
    the smoothed estimate is the final filtered one propagated backwards and its
    error covariance grows without bound away from the end of the interval.
    There is no steady-state smoothed covariance: ``smoothed`` must be None
    (documented: "ndarray or None") or non-finite, not a finite matrix."""
    f = AlphaBetaFilter(a, b, 0.5)
    c = f.covariances(sigma_w=0.0, sigma_v=3.0)
    phi_inv = np.linalg.inv(f.Phi)
    mat_close(c.smoother_gain, phi_inv, 1e-8)  # the gain itself is right
    assert c.smoothed is None or not np.all(np.isfinite(c.smoothed)), c.smoothed


def test_kalman_covariances_are_dare():
    r, T = 0.2, 0.5
    alpha, beta, A = fr.kalman_ab_dare(r, T)
    f = AlphaBetaFilter(alpha, beta, T)
    Q = fr.white_accel_Q(T, fr.snr_sigma_w(r, T))
    M = __import__("scipy.linalg").linalg.solve_discrete_are(f.Phi.T, f.H.T, Q, np.eye(1))
    c = f.covariances(Q, [[1.0]])
    mat_close(c.predicted, M)
    mat_close(c.smoother_gain, A)
    # smoothed <= filtered <= predicted (Loewner order)
    assert np.all(np.linalg.eigvalsh(c.filtered - c.smoothed) > -1e-12)
    assert np.all(np.linalg.eigvalsh(c.predicted - c.filtered) > -1e-12)


@pytest.mark.parametrize("conv", list(fr.ABG_C))
def test_alphabetagamma_and_fixed_gain_covariances(conv):
    T = 0.5
    f = AlphaBetaGammaFilter(0.5, 0.3, 0.05, T, convention=conv)
    Q = np.diag([1e-3, 1e-2, 1e-1])
    R = [[2.0]]
    m = fr.abg_model(0.5, 0.3, 0.05, T, conv)
    want = fr.fixed_gain_cov(m.Phi[0], m.H[0], m.K[0], Q, R)
    got = f.covariances(Q, R)
    for name in ("predicted", "filtered", "smoothed", "smoother_gain"):
        mat_close(getattr(got, name), getattr(want, name))
    Phi, H, K, T, Q, R = _singer()
    got = FixedGainFilter(Phi, H, K, T).covariances(Q, R)
    want = fr.fixed_gain_cov(Phi, H, K, Q, R)
    for name in ("predicted", "filtered", "smoothed", "smoother_gain"):
        mat_close(getattr(got, name), getattr(want, name))


# ---------------------------------------------------------------------------
# statistics: simulated white-acceleration model
# ---------------------------------------------------------------------------
def simulate_white_accel(rng, ntr, N, T, sigma_w, sigma_v):
    w = rng.normal(0, sigma_w, (ntr, N))
    vel = rng.normal(0, 3, (ntr, 1)) + T * np.concatenate([np.zeros((ntr, 1)), np.cumsum(w[:, :-1], axis=1)], axis=1)
    dpos = T * vel[:, :-1] + 0.5 * T * T * w[:, :-1]
    pos = rng.normal(0, 10, (ntr, 1)) + np.concatenate([np.zeros((ntr, 1)), np.cumsum(dpos, axis=1)], axis=1)
    z = pos + rng.normal(0, sigma_v, (ntr, N))
    return np.stack([pos, vel]), z


def _cov(err):
    """err (n, ntr, N) -> empirical covariance (n, n)."""
    e = err.reshape(err.shape[0], -1)
    return e @ e.T / e.shape[1]


def _assert_cov_agrees(emp, theo, rel=0.04, corr=0.03):
    d = np.sqrt(np.diag(theo))
    assert np.all(np.abs(np.diag(emp) / np.diag(theo) - 1) < rel), (np.diag(emp), np.diag(theo))
    ce = emp / np.outer(d, d)
    ct = theo / np.outer(d, d)
    assert np.all(np.abs(ce - ct) < corr), (ce, ct)


@pytest.mark.parametrize("r,T", [(0.05, 0.1), (1.0, 1.0)])
def test_smoothed_error_matches_theory(r, T):
    """Kalman gains for the model: empirical predicted/filtered/smoothed error
    covariances over 2.4e5 samples (40 tracks, edges cut) agree with
    covariances(...) within 4 % (variances) and 0.03 (correlations); the
    standard error of a variance here is about 1 %."""
    sigma_v = 2.0
    sigma_w = fr.snr_sigma_w(r, T, sigma_v)
    alpha, beta, _ = fr.kalman_ab_dare(r, T)
    f = AlphaBetaFilter(alpha, beta, T)
    cov = f.covariances(sigma_w=sigma_w, sigma_v=sigma_v)
    rng = np.random.default_rng(fr.seed_of("stat", r, T))
    truth, z = simulate_white_accel(rng, 40, 6400, T, sigma_w, sigma_v)
    cut = slice(200, -200)
    filt = f.run(z)
    sm = f.smooth(z)
    _assert_cov_agrees(_cov((filt.states - truth)[:, :, cut]), cov.filtered)
    _assert_cov_agrees(_cov((sm.states - truth)[:, :, cut]), cov.smoothed)
    Phi = f.Phi
    pred = np.einsum("ij,jtk->itk", Phi, filt.states[:, :, :-1])
    _assert_cov_agrees(_cov((pred - truth[:, :, 1:])[:, :, cut]), cov.predicted)
    # the smoother helps: smoothed position variance well below filtered
    assert cov.smoothed[0, 0] < 0.9 * cov.filtered[0, 0]
    # the default gain is the Kalman smoother gain of this model
    mat_close(f.smoother_gain()[0], cov.smoother_gain, 1e-9)


@pytest.mark.parametrize("lag", [None, 0, 2])
def test_fixed_gain_per_track_smoothing(lag):
    rng = np.random.default_rng(91)
    ntr = 5
    Ts = rng.uniform(0.2, 1.0, ntr)
    mods = [_singer(T) for T in Ts]
    Phi = np.stack([mm[0] for mm in mods])
    H = mods[0][1]
    K = np.stack([mm[2] for mm in mods])
    A = np.stack([fr.fixed_gain_cov(mm[0], mm[1], mm[2], mm[4], mm[5]).smoother_gain for mm in mods])
    z = fr.with_nans(rng, fr.kinematic_z(rng, ntr, 120, Ts, m=2), "mixed")
    f = FixedGainFilter(Phi, H, K, Ts)
    model = fr.general_model(Phi, H, K, Ts)
    r = f.smooth(z, lag=lag, smoother_gain=A, init="first", return_residuals=True)
    s, res = ref_smooth(z, model, "first", A, lag)
    fr.assert_states_close(r.states, s, RTOL)
    fr.assert_resid_close(r.residuals, res, RTOL, m=2)
    with pytest.raises(ValueError):
        f.smooth(z, Q=mods[0][4], R=mods[0][5], init="first")  # per-track filter needs smoother_gain
