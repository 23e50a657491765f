"""Kalman (Riccati) designs of abkit.alphabeta against independent solutions.

References (tests/abref.py, none of which uses abkit):

* ``dare_mp``: 50-digit structure-preserving doubling solution of the DARE of
  the normalised model, verified by its residual (< 1e-40) and stability;
* ``dare_scipy``: ``scipy.linalg.solve_discrete_are(F.T, H.T, Q, R)``;
* ``riccati_iterate``: brute-force float64 predict/update iteration.

Tolerances (relative, elementwise):

* ``RTOL_MP = 1e-12`` against the 50-digit solution, for alpha, beta, every
  entry of P (filtered) and M (predicted), over r in [1e-12, 1e12];
* against scipy: ``SCIPY_RTOL_CORE = 1e-10`` for r in [1e-9, 1e7] and
  ``SCIPY_RTOL_EDGE = 5e-9`` outside it -- the accuracy scipy itself reaches
  (measured against dare_mp: <= 1.4e-13 inside, <= 9.3e-10 at r = 1e12).
  P is compared to scipy only for r <= 1e4 because forming
  P = M - M h h' M / (h' M h + 1) from scipy's M cancels for large r;
* ``RTOL_ITER = 1e-11`` against the brute-force iteration (stopped when the
  step is below 1e-15 relative).
"""

from __future__ import annotations

import math

import mpmath
import numpy as np
import pytest

import abref
from abkit import alphabeta as ab

RTOL_MP = 1e-12
SCIPY_RTOL_CORE = 1e-10
SCIPY_RTOL_EDGE = 5e-9
RTOL_ITER = 1e-11

R_GRID = np.logspace(-12, 12, 49)
R_IDS = [f"r={r:.1e}" for r in R_GRID]

SQRT_HALF = 1.0 / math.sqrt(2.0)


def _fields(d, i=None):
    """alpha, beta, P and M entries of an AlphaBeta (element i of a vector design)."""
    P = d.covariance_filtered
    M = d.covariance_predicted
    a, b = d.alpha, d.beta
    if i is not None:
        P, M, a, b = P[i], M[i], a[i], b[i]
    return dict(
        alpha=a, beta=b,
        p11=P[0, 0], p12=P[0, 1], p21=P[1, 0], p22=P[1, 1],
        m11=M[0, 0], m12=M[0, 1], m21=M[1, 0], m22=M[1, 1],
    )


def _ref_fields(ref):
    return dict(
        alpha=ref["alpha"], beta=ref["beta"],
        p11=ref["p11"], p12=ref["p12"], p21=ref["p12"], p22=ref["p22"],
        m11=ref["m11"], m12=ref["m12"], m21=ref["m12"], m22=ref["m22"],
    )


def _assert_close_fields(got, want, rtol, label=""):
    bad = []
    for k, w in want.items():
        g = got[k]
        err = abs(g - w) / abs(w)
        if not err <= rtol:
            bad.append(f"{k}: got {g!r}, want {w!r}, rel err {err:.3g}")
    assert not bad, f"{label} exceeds rtol {rtol:g}:\n  " + "\n  ".join(bad)


# ---------------------------------------------------------------------------
# reference self-checks (these test the references, not abkit)
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("r", [1e-12, 1e-4, 1.0, 1e4, 1e12])
def test_reference_mp_satisfies_kalata_and_kalman_damping(r):
    """The 50-digit DARE solution obeys Kalata's beta^2/(1-alpha) = 4 r and has
    damping (alpha + beta/2)/(2 sqrt(beta)) = 1/sqrt(2) (to 1e-35: forming 1 - alpha
    at r = 1e12 costs 12 of the 50 digits)."""
    ref = abref.dare_mp(r)
    with mpmath.workdps(60):
        a, b = ref["alpha"], ref["beta"]
        assert abs(b * b / (1 - a) / (4 * mpmath.mpf(r)) - 1) < mpmath.mpf(10) ** -35
        assert abs((a + b / 2) / (2 * mpmath.sqrt(b)) * mpmath.sqrt(2) - 1) < mpmath.mpf(10) ** -35


@pytest.mark.parametrize("r", [1e-3, 1.0, 1e3])
def test_reference_mp_agrees_with_float_iteration(r):
    """dare_mp and the brute-force float iteration agree (rtol 1e-11)."""
    M, P, _ = abref.riccati_iterate(r)
    ref = abref.dare_mp_float(r)
    assert abref.relerr(M, [[ref["m11"], ref["m12"]], [ref["m12"], ref["m22"]]]) < RTOL_ITER
    assert abref.relerr(P, [[ref["p11"], ref["p12"]], [ref["p12"], ref["p22"]]]) < RTOL_ITER


# ---------------------------------------------------------------------------
# from_snr
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("r", R_GRID, ids=R_IDS)
def test_from_snr_scalar_vs_mpmath(r):
    """from_snr(r) alpha, beta, P, M vs the 50-digit DARE, rtol RTOL_MP = 1e-12."""
    d = ab.from_snr(r)
    ref = abref.dare_mp_float(r)
    _assert_close_fields(_fields(d), _ref_fields(ref), RTOL_MP, f"from_snr({r!r})")
    # the design's own SNR is the input
    assert abs(d.r - r) <= RTOL_MP * r
    assert abs(d.tracking_error_ratio - ref["alpha"]) <= RTOL_MP * ref["alpha"]


def test_from_snr_vector_vs_mpmath():
    """The vectorised call gives the same 1e-12 agreement element by element."""
    d = ab.from_snr(R_GRID)
    assert d.shape == R_GRID.shape
    for i, r in enumerate(R_GRID):
        _assert_close_fields(_fields(d, i), _ref_fields(abref.dare_mp_float(r)), RTOL_MP, f"from_snr(grid)[{i}] r={r:g}")


def test_from_snr_vs_scipy_dare():
    """from_snr vs scipy.linalg.solve_discrete_are over the full grid.

    rtol SCIPY_RTOL_CORE = 1e-10 for 1e-9 <= r <= 1e7 and SCIPY_RTOL_EDGE = 5e-9
    outside (scipy's own accuracy there); p22 only for r <= 1e4 (see module doc).
    """
    d = ab.from_snr(R_GRID)
    for i, r in enumerate(R_GRID):
        M, P = abref.dare_scipy(r)
        rtol = SCIPY_RTOL_CORE if 1e-9 <= r <= 1e7 else SCIPY_RTOL_EDGE
        s = M[0, 0] + 1.0
        want = dict(
            alpha=M[0, 0] / s, beta=M[0, 1] / s,
            m11=M[0, 0], m12=M[0, 1], m21=M[1, 0], m22=M[1, 1],
        )
        if r <= 1e4:
            want.update(p11=P[0, 0], p12=P[0, 1], p22=P[1, 1])
        got = _fields(d, i)
        _assert_close_fields(got, want, rtol, f"from_snr({r:g}) vs scipy")


@pytest.mark.parametrize("r", np.logspace(-4, 4, 9), ids=lambda r: f"r={r:.0e}")
def test_from_snr_vs_brute_force_iteration(r):
    """from_snr vs brute-force Riccati iteration to a fixed point, rtol 1e-11."""
    M, P, _ = abref.riccati_iterate(r)
    d = ab.from_snr(r)
    want = dict(
        alpha=P[0, 0], beta=P[0, 1],
        p11=P[0, 0], p12=P[0, 1], p21=P[1, 0], p22=P[1, 1],
        m11=M[0, 0], m12=M[0, 1], m21=M[1, 0], m22=M[1, 1],
    )
    _assert_close_fields(_fields(d), want, RTOL_ITER, f"from_snr({r:g}) vs iteration")
    # Kalman gain K = M h'/(h M h' + 1) equals the first column of P
    K = M[:, 0] / (M[0, 0] + 1.0)
    assert abs(d.alpha - K[0]) <= RTOL_ITER * K[0]
    assert abs(d.beta - K[1]) <= RTOL_ITER * K[1]


def _check_vs_scipy(d, r, label):
    """alpha, beta and M of a design vs scipy's DARE at r (scipy tolerances above)."""
    M, _ = abref.dare_scipy(r)
    rtol = SCIPY_RTOL_CORE if 1e-9 <= r <= 1e7 else SCIPY_RTOL_EDGE
    s = M[0, 0] + 1.0
    want = dict(alpha=M[0, 0] / s, beta=M[0, 1] / s, m11=M[0, 0], m12=M[0, 1], m21=M[1, 0], m22=M[1, 1])
    _assert_close_fields(_fields(d), want, rtol, f"{label} vs scipy")


# ---------------------------------------------------------------------------
# from_noise / from_tracking_index
# ---------------------------------------------------------------------------
NOISE_CASES = [
    # sigma_w, sigma_v, T
    (3.2, 32.0, 0.1),  # the paper's GPS car: lambda = 1e-3, r = 2.5e-7
    (1.0, 1.0, 1.0),
    (9.81, 5.0, 0.5),
    (0.01, 100.0, 0.01),  # lambda = 1e-8
    (2e-4, 1.0, 1e-2),  # r ~ 1e-16 (outside the grid, still well defined)
    (50.0, 0.1, 2.0),  # lambda = 2000
    (1e3, 1e-3, 1.0),  # lambda = 1e6, r = 2.5e11
    (0.3, 7.0, 3.0),
    (1.0, 3.0, 1e-3),
    (1e6, 1.0, 1.0),  # r = 2.5e11
]


@pytest.mark.parametrize("sigma_w,sigma_v,T", NOISE_CASES)
def test_from_noise_vs_mpmath(sigma_w, sigma_v, T):
    """from_noise == 50-digit DARE at r = ((sigma_w T^2/2)/sigma_v)^2, rtol 1e-12
    (r and the tracking index too; r evaluated exactly from the float inputs)."""
    with mpmath.workdps(60):
        lam = mpmath.mpf(sigma_w) * mpmath.mpf(T) ** 2 / mpmath.mpf(sigma_v)
        r = lam * lam / 4
    ref = abref.dare_mp_float(r)
    d = ab.from_noise(sigma_w, sigma_v, T)
    _assert_close_fields(_fields(d), _ref_fields(ref), RTOL_MP, f"from_noise{(sigma_w, sigma_v, T)}")
    assert abs(d.r - float(r)) <= RTOL_MP * float(r)
    assert abs(d.tracking_index - float(lam)) <= RTOL_MP * float(lam)
    assert d.T == T
    assert d.kalman_optimal is True
    if 1e-13 <= float(r) <= 1e13:
        _check_vs_scipy(d, float(r), f"from_noise{(sigma_w, sigma_v, T)}")


def test_from_noise_vector_matches_scalar_reference():
    """Vectorised from_noise over the case table, rtol 1e-12 vs mpmath."""
    sw, sv, T = (np.array(c) for c in zip(*NOISE_CASES))
    d = ab.from_noise(sw, sv, T)
    assert d.T is None  # array T is not recorded
    for i, (a, b, c) in enumerate(NOISE_CASES):
        with mpmath.workdps(60):
            r = (mpmath.mpf(a) * mpmath.mpf(c) ** 2 / mpmath.mpf(b)) ** 2 / 4
        _assert_close_fields(_fields(d, i), _ref_fields(abref.dare_mp_float(r)), RTOL_MP, f"case {i}")


LAMBDAS = np.logspace(-6, 6, 25)


@pytest.mark.parametrize("lam", LAMBDAS, ids=lambda x: f"lam={x:.1e}")
def test_from_tracking_index_vs_mpmath(lam):
    """from_tracking_index(lam) == 50-digit DARE at r = lam^2/4, rtol 1e-12."""
    with mpmath.workdps(60):
        r = mpmath.mpf(lam) ** 2 / 4
    ref = abref.dare_mp_float(r)
    d = ab.from_tracking_index(lam)
    _assert_close_fields(_fields(d), _ref_fields(ref), RTOL_MP, f"from_tracking_index({lam!r})")
    assert abs(d.tracking_index - lam) <= RTOL_MP * lam
    assert abs(d.r - float(r)) <= RTOL_MP * float(r)
    if 1e-13 <= float(r) <= 1e13:
        _check_vs_scipy(d, float(r), f"from_tracking_index({lam!r})")


def test_equivalent_constructors_agree():
    """from_snr(r), from_tracking_index(2 sqrt r) and from_noise with the same r
    give the same gains and covariances (rtol 1e-12)."""
    r = np.logspace(-10, 10, 21)
    lam = 2.0 * np.sqrt(r)
    a = ab.from_snr(r)
    b = ab.from_tracking_index(lam)
    c = ab.from_noise(lam, 1.0, 1.0)  # sigma_w T^2 / sigma_v = lam
    for other in (b, c):
        for name in ("alpha", "beta", "covariance_filtered", "covariance_predicted"):
            np.testing.assert_allclose(getattr(other, name), getattr(a, name), rtol=RTOL_MP, atol=0, err_msg=name)


# ---------------------------------------------------------------------------
# Kalman identities
# ---------------------------------------------------------------------------
def _kalman_designs():
    return {
        "from_snr": ab.from_snr(R_GRID),
        "from_tracking_index": ab.from_tracking_index(LAMBDAS),
        "from_noise": ab.from_noise(np.array([3.2, 1.0, 50.0, 0.01]), np.array([32.0, 1.0, 0.1, 100.0]), 0.1),
        "from_tracking_error": ab.from_tracking_error(np.array([1e-6, 1e-3, 0.1, 0.5, 0.9, 0.999, 1 - 1e-9])),
        "from_bandwidth": ab.from_bandwidth(np.array([1e-6, 1e-3, 0.05, 0.1, 0.2, 0.249])),
        "from_natural_frequency": ab.from_natural_frequency(np.array([1e-4, 0.01, 1.0, 10.0, 14.0]), 0.1),
    }


@pytest.mark.parametrize("name", list(_kalman_designs().keys()))
def test_kalman_damping_is_one_over_sqrt2(name):
    """Every Kalman design has damping 1/sqrt(2) (rtol 1e-12) and is flagged
    kalman_optimal; KALMAN_DAMPING is 1/sqrt(2)."""
    assert ab.KALMAN_DAMPING == SQRT_HALF
    d = _kalman_designs()[name]
    np.testing.assert_allclose(d.damping, SQRT_HALF, rtol=1e-12, atol=0)
    assert np.all(d.kalman_optimal)
    # and eq (15) evaluated on the returned gains gives the same damping
    delta = (d.alpha + d.beta / 2) / (2 * np.sqrt(d.beta))
    np.testing.assert_allclose(delta, SQRT_HALF, rtol=1e-12, atol=0)


@pytest.mark.parametrize("name", list(_kalman_designs().keys()))
def test_kalata_relation(name):
    """beta^2/(1 - alpha) = lambda^2 = 4 r (Kalata) for the returned gains.

    Forming 1 - alpha from a rounded alpha amplifies its error by
    1/(1 - alpha), so the relative tolerance is 1e-12 * max(1, 1/(1 - alpha)).
    Also beta = 2(2 - alpha) - 4 sqrt(1 - alpha), same tolerance.
    """
    d = _kalman_designs()[name]
    a, b, lam, r = (np.atleast_1d(x) for x in (d.alpha, d.beta, d.tracking_index, d.r))
    for ai, bi, li, ri in zip(a, b, lam, r):
        with mpmath.workdps(50):
            A, B = mpmath.mpf(ai), mpmath.mpf(bi)
            lhs = B * B / (1 - A)
            kb = 2 * (2 - A) - 4 * mpmath.sqrt(1 - A)
        tol = 1e-12 * max(1.0, 1.0 / (1.0 - ai))
        assert abs(float(lhs) / li**2 - 1) <= tol, (ai, bi, li)
        assert abs(float(lhs) / (4 * ri) - 1) <= tol, (ai, bi, ri)
        assert abs(float(kb) / bi - 1) <= tol, (ai, bi)


@pytest.mark.parametrize("name", list(_kalman_designs().keys()))
def test_tracking_error_ratio_equals_alpha(name):
    """For Kalman designs tracking_error_ratio (= P11 at the design r) == alpha,
    rtol 1e-12 (eq (14))."""
    d = _kalman_designs()[name]
    np.testing.assert_allclose(d.tracking_error_ratio, d.alpha, rtol=1e-12, atol=0)
    np.testing.assert_allclose(d.covariance_filtered[..., 0, 0], d.alpha, rtol=1e-12, atol=0)
    np.testing.assert_allclose(d.covariance_filtered[..., 0, 1], d.beta, rtol=1e-12, atol=0)


@pytest.mark.parametrize("r", [1e-12, 1e-3, 0.1, 1.0, 7.5, 1e6, 1e12])
def test_snr_db_and_tracking_index(r):
    """snr_db == 10 log10(r) (abs tol 1e-12 max(1, |dB|)); tracking_index ==
    2 sqrt(r) (rtol 1e-14); both for the from_snr design at that r."""
    d = ab.from_snr(r)
    db = 10.0 * math.log10(r)
    assert abs(d.snr_db - db) <= 1e-12 * max(1.0, abs(db))
    assert abs(d.tracking_index - 2.0 * math.sqrt(r)) <= 1e-14 * 2.0 * math.sqrt(r)
    assert isinstance(d.snr_db, float)


def test_snr_db_vector():
    """snr_db on the grid, abs tol 1e-12 * max(1, |dB|)."""
    d = ab.from_snr(R_GRID)
    db = 10.0 * np.log10(R_GRID)
    assert np.all(np.abs(d.snr_db - db) <= 1e-12 * np.maximum(1.0, np.abs(db)))
    np.testing.assert_allclose(d.tracking_index, 2.0 * np.sqrt(R_GRID), rtol=1e-14, atol=0)


def test_paper_gps_car():
    """The paper's example: sigma_w = 3.2 ft/s^2, sigma_v = 32 ft, T = 0.1 s gives
    lambda = 1e-3, r = 2.5e-7 (exact arithmetic), and the Kalman gains of the
    50-digit DARE at that r; g2 = beta / T."""
    d = ab.from_noise(3.2, 32.0, 0.1)
    with mpmath.workdps(60):
        lam = mpmath.mpf(3.2) * mpmath.mpf(0.1) ** 2 / mpmath.mpf(32.0)
        r = lam * lam / 4
    assert abs(d.tracking_index - 1e-3) < 1e-15
    assert abs(d.r - 2.5e-7) < 1e-12 * 2.5e-7
    ref = abref.dare_mp_float(r)
    g1, g2 = d.gains()
    assert abs(g1 - ref["alpha"]) <= RTOL_MP * ref["alpha"]
    assert abs(g2 - ref["beta"] / 0.1) <= RTOL_MP * ref["beta"] / 0.1


def test_kalman_gains_within_bounds():
    """Kalman gains always satisfy 0 < alpha < 1 and 0 < beta < 2 (alpha = 1 - u^2,
    beta = 2 (1 - u)^2 with 0 < u < 1); after rounding to float64 the closed
    bounds 0 <= alpha <= 1, 0 <= beta <= 2 must still hold, and so must
    tracking_error_ratio = P11 <= 1 (the filter never does worse than the raw
    measurement). Sweep of r over [1e-300, 1e30] (0.1-decade steps), denser
    (1e-3 decade) over [1e26, 1e30] where alpha and beta approach 1 and 2.
    (Beyond ~1e31 the gains round onto the stability boundary and abkit
    rejects r; see test_alphabeta_errors.)"""
    r = np.concatenate([np.logspace(-300, 30, 3301), np.logspace(26, 30, 4001)])
    d = ab.from_snr(r)
    for name, hi in (("alpha", 1.0), ("beta", 2.0), ("tracking_error_ratio", 1.0)):
        x = getattr(d, name)
        bad = ~((x >= 0) & (x <= hi))
        assert not bad.any(), f"{name} outside [0, {hi}] at r = {r[bad][:5].tolist()}: {x[bad][:5].tolist()}"
