"""abkit.singer.model against Van Loan's discretisation and direct quadrature.

References (tests/singer_ref.py): Van Loan's matrix-exponential method in
float64 (scipy.linalg.expm; accurate only for moderate T/tau, where it is
used), Van Loan in 60-digit mpmath, and mpmath quadrature of the definition
``Q = q int_0^T e^{As} e3 e3' e^{A's} ds`` (any T/tau). Tolerance: 1e-13
relative, entry by entry (every entry of Q is positive).
"""

from __future__ import annotations

import numpy as np
import pytest
import singer_ref as ref

from abkit import singer

THETAS = [1e-8, 1e-6, 1e-3, 0.05, 0.5, 1.0, 1.999, 2.0, 2.001, 3.0, 10.0, 30.0]


@pytest.mark.parametrize("theta", THETAS)
@pytest.mark.parametrize("T", [1e-3, 1.0, 7.5])
def test_against_van_loan_mpmath(theta, T):
    tau = T / theta
    q = 0.37
    Phi, Q = singer.model(T, tau=tau, q=q)
    Phi_r, Q_r = ref.van_loan_mp(repr(T), repr(tau), repr(q))
    assert np.max(np.abs(Q / Q_r - 1)) <= 1e-13
    np.testing.assert_allclose(Phi, Phi_r, rtol=1e-14, atol=1e-300)
    np.testing.assert_array_equal(Q, Q.T)


@pytest.mark.parametrize("theta", [1e-3, 0.1, 1.0, 3.0])
def test_against_van_loan_scipy(theta):
    T, q = 2.0, 1.5
    Phi, Q = singer.model(T, tau=T / theta, q=q)
    Phi_r, Q_r = ref.van_loan(T, T / theta, q)
    assert np.max(np.abs(Q / Q_r - 1)) <= 1e-12
    np.testing.assert_allclose(Phi, Phi_r, rtol=1e-13, atol=1e-15)


@pytest.mark.parametrize("theta", [1e-6, 0.7, 2.5, 1e3])
def test_against_quadrature(theta):
    T, q = 1.0, 2.0
    _, Q = singer.model(T, tau=T / theta, q=q)
    assert np.max(np.abs(Q / ref.q_quad(T, T / theta, q) - 1)) <= 1e-13


def test_sigma_m_alpha_and_q_parametrisations_agree():
    T, tau, sm = 0.5, 8.0, 3.0
    Phi1, Q1 = singer.model(T, tau=tau, sigma_m=sm)
    Phi2, Q2 = singer.model(T, alpha=1 / tau, sigma_m=sm)
    Phi3, Q3 = singer.model(T, tau=tau, q=2 * sm**2 / tau)
    np.testing.assert_allclose(Q1, Q2, rtol=1e-15)
    np.testing.assert_allclose(Q1, Q3, rtol=1e-15)
    np.testing.assert_array_equal(Phi1, Phi3)
    # Stationary acceleration variance: Q33 = sigma_m^2 (1 - e^{-2T/tau}).
    assert Q1[2, 2] == pytest.approx(sm**2 * -np.expm1(-2 * T / tau), rel=1e-15)


def test_constant_acceleration_limit_is_continuous():
    T, q = 0.25, 4.0
    Phi_inf, Q_inf = singer.model(T, tau=np.inf, q=q)
    Phi_a0, Q_a0 = singer.model(T, alpha=0.0, q=q)
    np.testing.assert_array_equal(Q_inf, Q_a0)
    want = q * np.array([[T**5 / 20, T**4 / 8, T**3 / 6], [T**4 / 8, T**3 / 3, T**2 / 2], [T**3 / 6, T**2 / 2, T]])
    np.testing.assert_allclose(Q_inf, want, rtol=1e-15)
    np.testing.assert_allclose(Phi_inf, [[1, T, T**2 / 2], [0, 1, T], [0, 0, 1]], rtol=1e-15)
    for tau in (1e6, 1e9, 1e12):
        Phi, Q = singer.model(T, tau=tau, q=q)
        assert np.max(np.abs(Q / Q_inf - 1)) <= 2 * T / tau
        assert np.max(np.abs(Phi - Phi_inf)) <= 2 * T / tau


def test_broadcasting():
    Phi, Q = singer.model([[0.1], [1.0]], tau=[1.0, 10.0, 100.0], sigma_m=2.0)
    assert Phi.shape == Q.shape == (2, 3, 3, 3)
    P1, Q1 = singer.model(1.0, tau=10.0, sigma_m=2.0)
    np.testing.assert_array_equal(Q[1, 1], Q1)


@pytest.mark.parametrize(
    "kw,match",
    [
        (dict(T=0.0, tau=1.0, sigma_m=1.0), "^T must be"),
        (dict(T=np.nan, tau=1.0, sigma_m=1.0), "^T must be"),
        (dict(T=1.0, tau=-1.0, sigma_m=1.0), "^tau must be"),
        (dict(T=1.0, tau=np.nan, sigma_m=1.0), "^tau must be"),
        (dict(T=1.0, alpha=-1.0, sigma_m=1.0), "^alpha must be"),
        (dict(T=1.0, tau=1.0, sigma_m=0.0), "^sigma_m must be"),
        (dict(T=1.0, tau=1.0, sigma_m=np.inf), "^sigma_m must be"),
        (dict(T=1.0, tau=1.0, q=-2.0), "^q must be"),
        (dict(T=1.0, tau=np.inf, sigma_m=1.0), "sigma_m cannot be used with tau = inf"),
        (dict(T=1.0, tau=1.0, alpha=1.0, sigma_m=1.0), "exactly one of tau"),
        (dict(T=1.0, tau=1.0), "exactly one of sigma_m"),
        (dict(T=[1.0, 2.0], tau=[1.0, 2.0, 3.0], sigma_m=1.0), "do not broadcast"),
    ],
)
def test_bad_input(kw, match):
    with pytest.raises(ValueError, match=match):
        singer.model(**kw)


def test_huge_T_over_tau_does_not_overflow():
    # White acceleration limit: Q33 -> sigma_m^2, everything finite.
    for tau in (1e-5, 1e-100, 1e-300):
        Phi, Q = singer.model(1.0, tau=tau, sigma_m=2.0)
        assert np.all(np.isfinite(Q)) and np.all(np.isfinite(Phi))
        assert Q[2, 2] == pytest.approx(4.0, rel=1e-14)
        assert Phi[2, 2] == 0.0 and Phi[1, 2] == pytest.approx(tau, rel=1e-14)
    s = singer.steady_state(1.0, 1e-5, 1.0, 1.0)
    assert np.all(np.isfinite(s.P_pred)) and s.method_used == "numeric"
    # tau = 1e-300: the position/velocity noise (~ sigma_m^2 tau T) underflows,
    # so no stabilising steady state exists at working precision.
    with pytest.raises(np.linalg.LinAlgError):
        singer.steady_state(1.0, 1e-300, 1.0, 1.0)
