"""The paper's GPS car example and the discrete noise bandwidth.

Expected values are computed here independently: the Kalman recursion run to
convergence (pure Python, float64 and mpmath), and the filter's impulse
response summed directly. Tolerances are relative and stated per test.
"""

from __future__ import annotations

import math

import mpmath
import numpy as np
import pytest

from abkit import alphabeta

SIGMA_W, SIGMA_V, T = 3.2, 32.0, 0.1


def kalman_limit_mp(r: float, dps: int = 40) -> tuple:
    """Riccati recursion of the normalised model in mpmath until converged;
    returns (alpha, beta) = first row of the filtered covariance."""
    with mpmath.workdps(dps):
        r = mpmath.mpf(r)
        m11, m12, m22 = mpmath.mpf(1), mpmath.mpf(0), mpmath.mpf(1)
        prev = None
        for _ in range(200000):
            s = m11 + 1
            p11 = m11 / s
            p12 = m12 / s
            p22 = m22 - m12 * m12 / s
            m11, m12, m22 = p11 + 2 * p12 + p22 + r, p12 + p22 + 2 * r, p22 + 4 * r
            if prev is not None and abs(p11 - prev) < mpmath.mpf(10) ** (-dps + 5) * p11:
                break
            prev = p11
        return float(p11), float(p12)


def test_gps_car_from_the_equations() -> None:
    """The car's design follows eq (9)'s r = 2.5e-7, not the printed chart
    readings (docs/errata.md E7). rtol 1e-12 against the mpmath recursion."""
    car = alphabeta.from_noise(SIGMA_W, SIGMA_V, T)
    r = ((SIGMA_W * T**2 / 2) / SIGMA_V) ** 2
    assert car.r == pytest.approx(r, rel=1e-14)
    a, b = kalman_limit_mp(r)
    assert car.alpha == pytest.approx(a, rel=1e-12)
    assert car.beta == pytest.approx(b, rel=1e-12)
    g1, g2 = car.gains()
    assert (g1, g2) == (car.alpha, pytest.approx(b / T, rel=1e-12))
    # the printed chart readings are far from the car's actual design
    assert car.alpha < 0.05 and abs(car.alpha - 0.68) > 0.6


def test_printed_chart_readings_match_r_of_0_1() -> None:
    """alpha=0.68, beta=0.375, B_N*T=0.175 were read off a chart; they match
    the Kalman design at r = 0.1 to chart-reading accuracy (5 %)."""
    d = alphabeta.from_snr(0.1)
    assert d.alpha == pytest.approx(0.68, rel=0.05)
    assert d.beta == pytest.approx(0.375, rel=0.05)
    assert d.bandwidth_T == pytest.approx(0.175, rel=0.05)
    assert SIGMA_V * math.sqrt(d.alpha) == pytest.approx(26.4, rel=0.05)
    # and do not match the example's own "SNR" of 0.01
    assert abs(alphabeta.from_snr(0.01).alpha - 0.68) > 0.15


def impulse_vrr(alpha: float, beta: float, n: int = 20000) -> float:
    """Sum of squared impulse response from z to the filtered position."""
    x = v = 0.0
    total = 0.0
    for k in range(n):
        z = 1.0 if k == 0 else 0.0
        xp = x + v
        e = z - xp
        x = xp + alpha * e
        v = v + beta * e
        total += x * x
    return total


@pytest.mark.parametrize("alpha, beta", [(0.5, 0.2), (0.9, 0.6), (0.2, 0.02), (1.3, 1.0), (0.67, 0.363)])
def test_bandwidth_T_discrete_is_half_the_impulse_energy(alpha: float, beta: float) -> None:
    """rtol 1e-9 against the summed impulse response."""
    d = alphabeta.analyze(alpha, beta)
    assert d.bandwidth_T_discrete == pytest.approx(0.5 * impulse_vrr(alpha, beta), rel=1e-9)


def test_bandwidth_T_discrete_array_and_unstable() -> None:
    d = alphabeta.analyze(np.array([0.5, 0.5]), np.array([0.2, 3.5]))
    assert np.isfinite(d.bandwidth_T_discrete[0]) and np.isinf(d.bandwidth_T_discrete[1])
