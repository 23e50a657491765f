"""The closed-form (Yoon & Hong / Vaughan) route and method="auto".

* Where the closed form accepts a problem it agrees with the numeric solver
  and with scipy.linalg.solve_discrete_are to <= 1e-9 (correlation-scaled:
  |P - P_ref|_ij / sqrt(P_ii P_jj)) over the grid of issue 4.
* The stated range (docs/errata.md, "Numerical range of the closed form"):
  the closed form is accepted for p2 = sigma_m T^2/sigma_pos in [1e-4, 1e3]
  and T/tau in [1e-3, 10] when sigma_vel T/sigma_pos >= 1 or position only
  (a very accurate velocity measurement, sigma_vel T/sigma_pos = 1e-3, is
  accepted only in parts of that range) -- asserted here.
* Elsewhere "closed-form" raises LinAlgError and "auto" falls back to the
  numeric solver and says so in method_used.
* Complex Hamiltonian eigenvalues are handled (most accepted cases have a
  complex pair).
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
import scipy.linalg

from abkit import singer

THETAS = np.array([1e-3, 1e-2, 1e-1, 1.0, 10.0, 100.0, 1e3])
P2S = np.array([1e-6, 1e-4, 1e-2, 1.0, 1e2, 1e4])
RVS = [None, 1e-3, 1.0, 1e3, 1e8]


def scaled_err(P, Pref):
    d = np.sqrt(np.diagonal(Pref, axis1=-2, axis2=-1))
    return np.max(np.abs(P - Pref) / (d[..., :, None] * d[..., None, :]), axis=(-1, -2))


@pytest.mark.parametrize("rv", RVS)
def test_auto_on_grid_agrees_with_numeric_and_scipy(rv):
    TH, P2 = np.meshgrid(THETAS, P2S, indexing="ij")
    T, sp = 2.0, 0.5
    sv = None if rv is None else rv * sp / T
    args = (T, T / TH, P2 * sp / T**2, sp, sv)
    auto = singer.steady_state(*args, method="auto")
    num = singer.steady_state(*args, method="numeric")
    closed = auto.method_used == "closed-form"
    assert closed.any() and (~closed).any()
    assert np.all(scaled_err(auto.P_pred, num.P_pred)[closed] <= 1e-9)
    assert np.all(scaled_err(auto.P_pred, num.P_pred)[~closed] == 0)
    # Stated range of the closed form (docs/errata.md): T/tau <= 10 and
    # 1e-4 <= p2 <= 1e3 when sigma_vel T/sigma_pos >= 1 or position only.
    if rv is None or rv >= 1:
        band = (P2 >= 1e-4) & (P2 <= 1e3) & (TH <= 10)
        assert np.all(closed[band]), np.argwhere(band & ~closed)
    assert not closed[TH >= 100].any()
    for i, j in zip(*np.nonzero(closed)):
        Ps = scipy.linalg.solve_discrete_are(auto.Phi[i, j].T, auto.H.T, auto.Q[i, j], auto.R[i, j])
        assert scaled_err(auto.P_pred[i, j], Ps) <= 1e-9
        assert scaled_err(auto.P_filt[i, j], num.P_filt[i, j]) <= 1e-9
        assert scaled_err(auto.P_smooth[i, j], num.P_smooth[i, j]) <= 1e-8
        # Compared as closed-loop poles 1/l (the numeric path gets l as the
        # reciprocal of a pole, which has absolute, not relative, accuracy).
        np.testing.assert_allclose(1 / auto.eigenvalues[i, j], 1 / num.eigenvalues[i, j], rtol=1e-8, atol=1e-13)


def test_closed_form_method_and_complex_eigenvalues():
    s = singer.steady_state(1.0, 10.0, 1.0, 1.0, 2.0, method="closed-form")
    assert s.method_used == "closed-form"
    assert np.sum(np.abs(s.eigenvalues.imag) > 0) == 2  # one complex pair
    n = singer.steady_state(1.0, 10.0, 1.0, 1.0, 2.0, method="numeric")
    assert scaled_err(s.P_pred, n.P_pred) <= 1e-12
    np.testing.assert_allclose(s.K, n.K, rtol=1e-10, atol=1e-14)
    # Position only.
    s = singer.steady_state(1.0, 10.0, 1.0, 1.0, method="closed-form")
    n = singer.steady_state(1.0, 10.0, 1.0, 1.0, method="numeric")
    assert scaled_err(s.P_pred, n.P_pred) <= 1e-12
    assert s.alpha == pytest.approx(n.alpha, rel=1e-12)
    # Constant acceleration (tau = inf) through the closed form.
    s = singer.steady_state(1.0, np.inf, sigma_pos=1.0, q=1.0, method="closed-form")
    n = singer.steady_state(1.0, np.inf, sigma_pos=1.0, q=1.0, method="numeric")
    assert scaled_err(s.P_pred, n.P_pred) <= 1e-12


@pytest.mark.parametrize("theta,p2", [(1e-3, 1e-6), (1e-2, 1e-6), (100.0, 1.0), (1e3, 1e-2)])
def test_closed_form_rejects_ill_conditioned_and_auto_falls_back(theta, p2):
    with pytest.raises(np.linalg.LinAlgError, match="closed form rejected"):
        singer.steady_state(1.0, 1.0 / theta, p2, 1.0, method="closed-form")
    a = singer.steady_state(1.0, 1.0 / theta, p2, 1.0, method="auto")
    assert a.method_used == "numeric"


def test_mixed_batch_reports_method_per_element():
    a = singer.steady_state(1.0, 1000.0, [1e-6, 1.0], 1.0, method="auto")
    assert list(a.method_used) == ["numeric", "closed-form"]


def test_closed_form_is_never_silently_wrong():
    """Random parameters far beyond the stated range: wherever "auto" used the
    closed form, it agrees with the numeric solution to 1e-9."""
    rng = np.random.default_rng(11)
    n = 4000
    theta = 10 ** rng.uniform(-4, 3, n)
    p2 = 10 ** rng.uniform(-7, 5, n)
    rv = np.where(rng.uniform(size=n) < 0.3, np.inf, 10 ** rng.uniform(-4, 6, n))
    a = singer.steady_state(1.0, 1.0 / theta, p2, 1.0, rv, method="auto")
    num = singer.steady_state(1.0, 1.0 / theta, p2, 1.0, rv, method="numeric")
    closed = a.method_used == "closed-form"
    assert closed.mean() > 0.3
    err = scaled_err(a.P_pred, num.P_pred)
    assert np.all(err[closed] <= 1e-9), (np.max(err[closed]), np.argmax(np.where(closed, err, 0)))
    assert np.all(err[~closed] == 0)
