"""transient="kalman": the exact time-varying Kalman start followed by the
fixed gains. Checked against an independent NumPy Kalman loop (rtol 1e-10),
against the fixed-gain filter once converged, and for its purpose (lower
transient error than the two-point start, fixed seed)."""

from __future__ import annotations

import numpy as np
import pytest

import abkit
from abkit import alphabeta


def kalman_loop(F, H, Q, R, x0, P0, z):
    n = F.shape[0]
    x, P = np.array(x0, float), np.array(P0, float)
    out = []
    for k, zk in enumerate(z):
        if k:
            x, P = F @ x, F @ P @ F.T + Q
        if not np.isnan(zk):
            S = H @ P @ H.T + R
            K = P @ H.T / S
            x = x + (K * (zk - H @ x)).ravel()
            IKH = np.eye(n) - K @ H
            P = IKH @ P @ IKH.T + K @ R @ K.T
        out.append(x.copy())
    return np.array(out).T


def white_accel(r, T):
    sw = 2 * np.sqrt(r) / T**2
    d = np.array([[T * T / 2], [T]])
    return sw**2 * d @ d.T


@pytest.mark.parametrize("r,T", [(0.01, 1.0), (1.0, 0.1), (1e-4, 2.0)])
def test_alpha_beta_transient_is_the_kalman_filter(r, T):
    d = alphabeta.from_snr(r)
    f = abkit.AlphaBetaFilter(d.alpha, d.beta, T, transient="kalman", P0=np.diag([100.0, 100.0 / T**2]), x0=[1.0, 0.0])
    rng = np.random.default_rng(7)
    z = np.cumsum(rng.normal(size=(3, 300)), axis=1)
    z[1, 10:20] = np.nan
    res = f.run(z)
    F = np.array([[1.0, T], [0.0, 1.0]])
    H = np.array([[1.0, 0.0]])
    for i in range(3):
        ref = kalman_loop(F, H, white_accel(r, T), np.eye(1), [1.0, 0.0], np.diag([100.0, 100.0 / T**2]), z[i])
        scale = np.max(np.abs(ref), axis=1, keepdims=True)
        assert np.all(np.abs(res.states[:, i] - ref) <= 1e-10 * scale)


def test_transient_converges_to_the_fixed_gain_filter_and_helps():
    d = alphabeta.from_snr(0.01)
    f = abkit.AlphaBetaFilter(d.alpha, d.beta, 1.0, transient="kalman")
    g = abkit.AlphaBetaFilter(d.alpha, d.beta, 1.0)
    rng = np.random.default_rng(0)
    n = 400
    x = np.cumsum(np.cumsum(rng.normal(0, 0.2, (2000, n)), axis=1), axis=1) + 5 * np.arange(n)
    z = x + rng.normal(size=x.shape)
    a, b = f.run(z), g.run(z)
    late = slice(n - 50, n)
    assert np.max(np.abs(a.position[:, late] - b.position[:, late])) <= 1e-9 * np.max(np.abs(x))
    early = slice(2, 30)
    mse_k = np.mean((a.position[:, early] - x[:, early]) ** 2)
    mse_2p = np.mean((b.position[:, early] - x[:, early]) ** 2)
    assert mse_k < 0.95 * mse_2p
    assert np.array_equal(a.state.x, a.states[:, :, -1].T)


def test_transient_with_explicit_model_for_abg():
    from abkit import kalman

    T = 0.5
    F = np.array([[1, T, T * T / 2], [0, 1, T], [0, 0, 1.0]])
    H = np.array([[1.0, 0, 0]])
    G = np.array([[T**3 / 6], [T**2 / 2], [T]])
    Q, R = 0.01 * G @ G.T, np.eye(1)
    K = kalman.gain_sequence(F, H, Q, R, np.eye(3) * 1e6, 5000).K[-1][:, 0]
    P0 = np.diag([1e2, 1e2, 1e2])  # moderate prior: a diffuse one is ill-conditioned for both codes
    f = abkit.AlphaBetaGammaFilter(
        K[0], K[1] * T, K[2] * T * T, T, convention="chen-chui", transient="kalman", Q=Q, R=R, P0=P0
    )
    z = np.cumsum(np.random.default_rng(1).normal(size=200))
    res = f.run(z)
    ref = kalman_loop(F, H, Q, R, np.zeros(3), P0, z)
    assert np.all(np.abs(res.states - ref) <= 1e-10 * np.max(np.abs(ref), axis=1, keepdims=True))


def test_transient_errors():
    with pytest.raises(ValueError, match="Kalman-optimal"):
        abkit.AlphaBetaFilter(0.5, 0.1, 1.0, transient="kalman")
    with pytest.raises(ValueError, match="transient"):
        abkit.AlphaBetaFilter(0.5, 0.1, 1.0, transient="exact")
    with pytest.raises(ValueError, match="only with"):
        abkit.AlphaBetaFilter(0.5, 0.1, 1.0, P0=np.eye(2))
    d = alphabeta.from_snr(0.1)
    f = abkit.AlphaBetaFilter(d.alpha, d.beta, 1.0, transient="kalman")
    r = f.run(np.arange(10.0))
    with pytest.raises(ValueError, match="streaming"):
        f.run(np.arange(10.0), state=r.state)
    with pytest.raises(ValueError, match="limiting Kalman gains"):
        abkit.AlphaBetaFilter(d.alpha, d.beta, 1.0, transient="kalman", Q=np.eye(2), R=np.eye(1))


def test_singer_fixed_gain_filter_with_kalman_transient():
    """A Singer position+velocity design (abkit.singer) run with the exact
    Kalman start: equals abkit.kalman's filter of the same model, and the
    fixed-gain filter once the gains have converged (rtol 1e-9)."""
    from abkit import kalman, singer

    ss = singer.steady_state(T=1.0, tau=10.0, sigma_m=2.0, sigma_pos=5.0, sigma_vel=1.0)
    Phi, H, K, Q, R = ss.Phi, ss.H, ss.K, ss.Q, ss.R
    P0 = np.eye(3) * 100.0
    f = abkit.FixedGainFilter(Phi, H, K, transient="kalman", Q=Q, R=R, P0=P0, x0=np.zeros(3))
    rng = np.random.default_rng(5)
    z = np.cumsum(rng.normal(size=(4, 500, 2)), axis=1)
    got = f.run(z, init="first").states
    want = kalman.KalmanFilter(Phi, H, Q, R, x0=np.zeros(3), P0=P0).run(z).states
    assert np.array_equal(got, want)
    fixed = abkit.FixedGainFilter(Phi, H, K).run(z, init="first").states
    late = slice(450, 500)
    scale = np.max(np.abs(fixed[:, :, late]))
    assert np.max(np.abs(got[:, :, late] - fixed[:, :, late])) <= 1e-9 * scale


def test_gain_sequence_converges_to_abkit_riccati_limit():
    """Paper 004, Lemma 1: K_k -> the limiting gain of abkit's own Riccati solver."""
    from abkit import kalman, riccati

    ss_model = abkit.singer.model(1.0, tau=5.0, sigma_m=1.0)
    Phi, Q = ss_model
    H = np.array([[1.0, 0.0, 0.0]])
    R = np.array([[4.0]])
    lim = riccati.kalman_steady_state(Phi, H, Q, R)
    K = kalman.gain_sequence(Phi, H, Q, R, np.eye(3) * 50.0, 3000).K[-1]
    assert np.allclose(K, lim.K, rtol=1e-10, atol=1e-13)
