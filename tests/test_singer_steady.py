"""abkit.singer.steady_state (numeric and auto paths) against independent references.

* scipy.linalg.solve_discrete_are on the physical model over the grid of
  issue 4: T/tau 1e-3..1e3, p2 = sigma_m T^2/sigma_pos 1e-6..1e4, sigma_vel
  from tiny to effectively infinite. Error measure: max |P - P_ref|_ij /
  sqrt(P_ii P_jj) <= 1e-9 (the "correlation-scaled" error, insensitive to
  the huge spread of the entries' scales).
* The joint-information (batch least-squares) smoother of
  tests/singer_ref.py for P_pred, P_filt and P_smooth (no Riccati or Lyapunov
  recursion involved), <= 1e-10.
* numpy.linalg.eigvals of the paper's Hamiltonian H_f (Vaughan), built from
  its definition, for the eigenvalues.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
import scipy.linalg
import singer_ref as ref

from abkit import singer

THETAS = [1e-3, 1e-1, 1.0, 10.0, 1e3]
P2S = [1e-6, 1e-2, 1.0, 1e2, 1e4]
RVS = [None, 1e-3, 1.0, 1e8]


def scaled_err(P, Pref):
    d = np.sqrt(np.outer(np.diag(Pref), np.diag(Pref)))
    return float(np.max(np.abs(P - Pref) / d))


def _case(theta, p2, rv, method="numeric"):
    T, sp = 0.5, 3.0
    sm = p2 * sp / T**2
    sv = None if rv is None else rv * sp / T
    return singer.steady_state(T, T / theta, sm, sp, sv, method=method)


@pytest.mark.parametrize("theta,p2,rv", list(itertools.product(THETAS, P2S, RVS)))
def test_grid_against_scipy(theta, p2, rv):
    s = _case(theta, p2, rv)
    Ps = scipy.linalg.solve_discrete_are(s.Phi.T, s.H.T, s.Q, s.R)
    assert scaled_err(s.P_pred, Ps) <= 1e-9
    # K, P_filt from the scipy solution by eqs (7), (8).
    S = s.H @ Ps @ s.H.T + s.R
    K = Ps @ s.H.T @ np.linalg.inv(S)
    I_KH = np.eye(3) - K @ s.H
    Pf = I_KH @ Ps @ I_KH.T + K @ s.R @ K.T
    assert scaled_err(s.P_filt, Pf) <= 1e-9
    # Gains in the units of their effect: K_ij sqrt(S_jj) / sqrt(P_ii) (a
    # gain on a nearly useless measurement is tiny and ill-determined on its
    # own, so an absolute floor of 1e-15 times the state's largest gain);
    # 1e-8, as the gain is a quotient of P entries.
    scale = np.sqrt(np.diag(Ps))[:, None] / np.sqrt(np.diag(S))[None, :]
    floor = 1e-15 * np.abs(K).max(axis=1, keepdims=True)
    assert np.all(np.abs(s.K - K) <= 1e-8 * scale + floor)
    assert np.all(np.abs(s.eigenvalues) > 1)
    assert s.method_used == "numeric"


@pytest.mark.parametrize("theta,p2,sv", [(0.1, 1.0, None), (0.5, 0.3, 2.0), (1.0, 3.0, 0.5), (0.02, 0.05, None)])
def test_against_batch_smoother(theta, p2, sv):
    s = singer.steady_state(1.0, 1.0 / theta, p2, 1.0, sv, method="numeric")
    Pp, Pf, Ps = ref.batch_smoother(s.Phi, s.H, s.Q, s.R, N=401 if theta < 0.05 else 241)
    # 1e-9: the accuracy of the reference (inverse of a ~1200x1200 information matrix).
    assert scaled_err(s.P_pred, Pp) <= 1e-9
    assert scaled_err(s.P_filt, Pf) <= 1e-9
    assert scaled_err(s.P_smooth, Ps) <= 1e-9
    # Ordering: smoothing <= filtering <= prediction.
    assert np.linalg.eigvalsh(s.P_filt - s.P_smooth).min() >= -1e-12 * np.abs(s.P_filt).max()
    assert np.linalg.eigvalsh(s.P_pred - s.P_filt).min() >= -1e-12 * np.abs(s.P_pred).max()


@pytest.mark.parametrize("theta,p2,rv", [(0.1, 1.0, None), (1.0, 3.0, 0.5), (0.01, 1e-3, 2.0), (3.0, 10.0, None), (0.3, 1.0, 5e-2)])
def test_eigenvalues_are_those_of_the_papers_hamiltonian(theta, p2, rv):
    # (Cases where numpy's eig of the non-normal H_f is itself accurate; for
    # e.g. p2 = 100, rv = 0.01 its largest eigenvalue, ~1e7, is off by 4e-5.)
    s = _case(theta, p2, rv)
    ev = np.linalg.eigvals(ref.hamiltonian(s.Phi, s.H, s.Q, s.R))
    out = ev[np.abs(ev) > 1]
    assert len(out) == 3
    # Symplectic: the others are the reciprocals.
    np.testing.assert_allclose(np.sort_complex(1 / ev[np.abs(ev) <= 1]), np.sort_complex(out), rtol=1e-8)
    np.testing.assert_allclose(np.sort_complex(s.eigenvalues), np.sort_complex(out), rtol=1e-9)
    assert np.all(np.diff(np.abs(s.eigenvalues)) <= 0)


def test_position_only_gains_and_limits():
    s = singer.steady_state(1.0, 20.0, 1.0, 10.0, method="numeric")
    assert s.K.shape == (3, 1) and s.H.shape == (1, 3) and s.R.shape == (1, 1)
    assert s.alpha == pytest.approx(s.K[0, 0], rel=1e-15)
    assert s.beta == pytest.approx(s.K[1, 0] * 1.0, rel=1e-15)
    assert s.gamma == pytest.approx(2 * s.K[2, 0] * 1.0, rel=1e-15)
    # sigma_vel -> inf is the position-only filter.
    s_inf = singer.steady_state(1.0, 20.0, 1.0, 10.0, sigma_vel=np.inf, method="numeric")
    s_big = singer.steady_state(1.0, 20.0, 1.0, 10.0, sigma_vel=1e9, method="numeric")
    np.testing.assert_allclose(s_inf.P_pred, s.P_pred, rtol=1e-14)
    assert scaled_err(s_big.P_pred, s.P_pred) <= 1e-12
    assert s_inf.alpha is None and s_inf.K.shape == (3, 2)
    np.testing.assert_allclose(s_inf.K[:, 0], s.K[:, 0], rtol=1e-14)
    assert np.all(s_inf.K[:, 1] == 0)


def test_constant_acceleration_limit():
    T, sa, sp = 0.5, 2.0, 4.0
    q = sa**2 * T
    s_inf = singer.steady_state(T, np.inf, sigma_pos=sp, q=q, method="numeric")
    assert s_inf.theta == 0.0
    # Against scipy with the white-jerk model.
    Phi = np.array([[1, T, T**2 / 2], [0, 1, T], [0, 0, 1]])
    Q = q * np.array([[T**5 / 20, T**4 / 8, T**3 / 6], [T**4 / 8, T**3 / 3, T**2 / 2], [T**3 / 6, T**2 / 2, T]])
    Ps = scipy.linalg.solve_discrete_are(Phi.T, np.array([[1.0], [0], [0]]), Q, np.array([[sp**2]]))
    assert scaled_err(s_inf.P_pred, Ps) <= 1e-10
    # Continuous in tau at fixed q.
    for tau in (1e6, 1e9, 1e12):
        s = singer.steady_state(T, tau, sigma_pos=sp, q=q, method="numeric")
        assert scaled_err(s.P_pred, s_inf.P_pred) <= 10 * T / tau + 1e-12
    # alpha = 0 is tau = inf.
    s0 = singer.steady_state(T, alpha=0.0, sigma_pos=sp, q=q, method="numeric")
    np.testing.assert_array_equal(s0.P_pred, s_inf.P_pred)


def test_scaling_and_units():
    # The normalised solution depends only on (T/tau, p2, sigma_vel T/sigma_pos).
    a = singer.steady_state(1.0, 10.0, 2.0, 5.0, 1.0, method="numeric")
    c = 7.0
    b = singer.steady_state(1.0, 10.0, 2.0 * c, 5.0 * c, 1.0 * c, method="numeric")
    np.testing.assert_allclose(b.P_pred, a.P_pred * c**2, rtol=1e-12)
    np.testing.assert_allclose(b.K, a.K, rtol=1e-12)
    assert a.rms_position == pytest.approx(np.sqrt(a.P_pred[0, 0]) / 5.0, rel=1e-14)
    assert a.rms_velocity == pytest.approx(np.sqrt(a.P_pred[1, 1]) * 1.0 / 5.0, rel=1e-14)
    assert a.rms_acceleration == pytest.approx(np.sqrt(a.P_pred[2, 2]) / 5.0, rel=1e-14)
    assert a.p2 == pytest.approx(2.0 / 5.0)
    Phi, Q = singer.model(1.0, tau=10.0, sigma_m=2.0)
    np.testing.assert_allclose(a.Phi, Phi, rtol=1e-15)
    np.testing.assert_allclose(a.Q, Q, rtol=1e-14)


def test_broadcasting_and_parallel_batch_match_scalar_calls():
    T = np.array([0.5, 1.0, 2.0])[:, None]
    tau = np.array([5.0, 50.0])
    s = singer.steady_state(T, tau, 1.0, 3.0, 0.7, method="numeric")
    assert s.P_pred.shape == (3, 2, 3, 3) and s.K.shape == (3, 2, 3, 2) and s.eigenvalues.shape == (3, 2, 3)
    assert s.method_used.shape == (3, 2)
    one = singer.steady_state(1.0, 50.0, 1.0, 3.0, 0.7, method="numeric")
    np.testing.assert_array_equal(s.P_pred[1, 1], one.P_pred)
    # A batch big enough to run on rayon's pool (> 16384) is bit-identical to scalar calls.
    rng = np.random.default_rng(0)
    n = 20000
    taus = 10 ** rng.uniform(-1, 2, n)
    sms = 10 ** rng.uniform(-2, 1, n)
    big = singer.steady_state(1.0, taus, sms, 1.0, method="numeric")
    for i in (0, 12345, n - 1):
        si = singer.steady_state(1.0, taus[i], sms[i], 1.0, method="numeric")
        np.testing.assert_array_equal(big.P_pred[i], si.P_pred)


@pytest.mark.parametrize(
    "args,kw,match",
    [
        ((0.0, 1.0, 1.0, 1.0), {}, "^T must be"),
        ((1.0, -1.0, 1.0, 1.0), {}, "^tau must be"),
        ((1.0, 1.0, np.nan, 1.0), {}, "^sigma_m must be"),
        ((1.0, 1.0, 1.0, 0.0), {}, "^sigma_pos must be"),
        ((1.0, 1.0, 1.0, 1.0, -1.0), {}, "^sigma_vel must be"),
        ((1.0, 1.0, 1.0, 1.0, np.nan), {}, "^sigma_vel must be"),
        ((1.0, 1.0, 1.0), {}, "^sigma_pos .* is required"),
        ((1.0, 1.0, 1.0, 1.0), {"method": "schur"}, "^method must be"),
        ((1.0, np.inf, 1.0, 1.0), {}, "sigma_m cannot be used with tau = inf"),
        ((1.0, [1.0, 2.0], 1.0, [1.0, 2.0, 3.0]), {}, "do not broadcast"),
    ],
)
def test_bad_input(args, kw, match):
    with pytest.raises(ValueError, match=match):
        singer.steady_state(*args, **kw)


def test_fuzz_regression_tiny_noise_gives_no_nan_rms() -> None:
    """Found by fuzzing (fuzz/regressions/designs/): theta = 0.498, q and the
    velocity noise at 1.2e-250 made the solver return variances of -1e-16
    next to ||P|| = 7e-9 (within its tolerance), and rms_velocity was
    sqrt(negative) = NaN. Now they are zero to that tolerance."""
    v = 1.224167783418391e-250
    s = singer.steady_state(1.0, 1.0 / 0.49811553955078125, sigma_pos=1.0, sigma_vel=v, q=v, method="numeric")
    for x in (s.rms_position, s.rms_velocity, s.rms_acceleration):
        assert np.isfinite(x) and x >= 0.0
    assert s.rms_velocity <= 1e-3 * s.rms_position
