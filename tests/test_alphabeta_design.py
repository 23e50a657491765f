"""Deterministic designs, round trips, poles, flags and shapes of abkit.alphabeta.

Independent references: eq (15) written out from the inputs
(beta = (omega_n T)^2, alpha = 2 delta omega_n T - beta/2), scipy.integrate.quad
of |H(j 2 pi f)|^2 for the noise bandwidth, numpy.roots for the cubic (16) and
for the closed-loop characteristic polynomial, the Jury conditions, and
Kalata's beta(alpha) in mpmath.

Tolerances:

* ``RTOL = 1e-12`` for round trips and closed-form values. Where a round trip
  has to invert an ill-conditioned map, the tolerance is ``RTOL * max(1, cond)``
  with the condition number stated next to the test: recovering r (or the
  Kalman beta) from alpha has cond <= 4 + 3/(1 - alpha); recovering
  x = omega_n T from B_N T has cond (1 + (2d - x)^2) / |1 + (2d - x)(2d - 3x)|.
* ``RTOL_QUAD = 1e-8`` against numerical integration.
"""

from __future__ import annotations

import math

import mpmath
import numpy as np
import pytest

import abref
from abkit import alphabeta as ab

RTOL = 1e-12
RTOL_QUAD = 1e-8
SQRT_HALF = 1.0 / math.sqrt(2.0)

R_GRID = np.logspace(-12, 12, 49)
DAMPINGS = [0.2, 0.35, 0.5, SQRT_HALF, 0.8, 0.9, 1.0, 1.3, 2.0]
FRACTIONS = [1e-4, 0.01, 0.2, 0.5, 0.8, 0.97]


def cond_alpha(alpha):
    """Upper bound of |d ln r / d ln alpha| (and of d ln beta_K / d ln alpha)."""
    return 4.0 + 3.0 / (1.0 - np.asarray(alpha, dtype=float))


def cond_bandwidth(x, delta):
    """|d ln x / d ln B_N T| for eq (16)."""
    return (1 + (2 * delta - x) ** 2) / abs(1 + (2 * delta - x) * (2 * delta - 3 * x))


def x_upper(delta):
    """omega_n T range of stable filters with positive alpha: (0, min(4 delta, 1/delta))."""
    return min(4 * delta, 1 / delta)


def det_cases():
    """(x = omega_n T, delta) covering every damping and the whole range of x."""
    return [(f * x_upper(d), d) for d in DAMPINGS for f in FRACTIONS]


DET_IDS = [f"d={d:.3g}-x={x:.3g}" for x, d in det_cases()]


def _close(got, want, rtol, what=""):
    got = np.asarray(got, dtype=float)
    want = np.asarray(want, dtype=float)
    rtol = np.broadcast_to(np.asarray(rtol, dtype=float), want.shape)
    err = np.abs(got - want) / np.abs(want)
    bad = ~(err <= rtol)
    assert not bad.any(), (
        f"{what}: rel err {err[bad]} > rtol {rtol[bad]}; got {got[bad]!r}, want {want[bad]!r}"
    )


# ---------------------------------------------------------------------------
# closed-form design values
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("x,delta", det_cases(), ids=DET_IDS)
def test_from_natural_frequency_values(x, delta):
    """beta = (omega_n T)^2, alpha = omega_n T (2 delta - omega_n T / 2); damping,
    omega_n_T read back; rtol 1e-12. T = 0.25 s."""
    T = 0.25
    d = ab.from_natural_frequency(x / T, T, delta)
    xt = (x / T) * T
    with mpmath.workdps(40):
        X, D = mpmath.mpf(xt), mpmath.mpf(delta)
        alpha = float(X * (2 * D - X / 2))
        beta = float(X * X)
    _close(d.alpha, alpha, RTOL * max(1.0, abs(2 * delta * xt) / alpha), "alpha")
    _close(d.beta, beta, RTOL, "beta")
    _close(d.damping, delta, RTOL, "damping")
    _close(d.omega_n_T, xt, RTOL, "omega_n_T")
    assert d.T == T
    assert d.stable is True


@pytest.mark.parametrize("x,delta", det_cases(), ids=DET_IDS)
def test_bandwidth_T_vs_quad(x, delta):
    """bandwidth_T of from_natural_frequency == integral_0^inf |H(j 2 pi f)|^2 df * T
    (scipy quad) with H(s) = (b1 s + b2)/(s^2 + 2 delta w s + w^2), b1 = w (2 delta - w T),
    b2 = w^2; rtol RTOL_QUAD = 1e-8. T = 0.5 s."""
    T = 0.5
    d = ab.from_natural_frequency(x / T, T, delta)
    want = abref.noise_bandwidth_quad(x, delta, T=T)
    _close(d.bandwidth_T, want, RTOL_QUAD, "bandwidth_T")


@pytest.mark.parametrize("x,delta", det_cases(), ids=DET_IDS)
def test_from_bandwidth_realises_bandwidth_quad(x, delta):
    """from_bandwidth(bn, delta): the returned gains, mapped to (omega_n T, delta) by
    eq (15) and integrated with quad, have noise bandwidth bn (rtol 1e-8) and the
    requested damping (rtol 1e-12). bn is taken from quad at (x, delta)."""
    bn = abref.noise_bandwidth_quad(x, delta)
    # (in the non-monotone case any root realises bn; the smallest-root choice is tested below)
    d = ab.from_bandwidth(bn, delta)
    wT, dd = abref.continuous_from_gains(d.alpha, d.beta)
    _close(dd, delta, RTOL * 10, "damping from gains")
    _close(abref.noise_bandwidth_quad(wT, dd), bn, RTOL_QUAD, "quad bandwidth of returned gains")
    _close(d.bandwidth_T, bn, RTOL, "bandwidth_T field")


@pytest.mark.parametrize("delta", [0.87, 0.9, 0.93, 0.96, 0.99])
@pytest.mark.parametrize("where", [0.05, 0.3, 0.6, 0.9])
def test_from_bandwidth_nonmonotone_returns_smallest_root(delta, where):
    """For sqrt(3)/2 < delta < 1, eq (16) rises then falls on (0, 1/delta). With
    bn between B(1/delta) and the local maximum there are two roots in the
    interval; from_bandwidth must return the smallest (numpy.roots on the cubic
    x^3 - 4 d x^2 + (1 + 4 d^2) x - 8 d bn). rtol 1e-12 * max(1, cond)."""
    def B(x):
        return x * (1 + (2 * delta - x) ** 2) / (8 * delta)

    x_max = (8 * delta - math.sqrt(16 * delta * delta - 12)) / 6  # local maximum of (16)
    assert x_max < 1 / delta
    lo, hi = B(1 / delta), B(x_max)
    bn = lo + where * (hi - lo)
    roots = abref.bandwidth_cubic_roots(bn, delta)
    assert len(roots) == 2, roots  # genuinely two admissible roots
    x0 = roots[0]
    d = ab.from_bandwidth(bn, delta)
    tol = RTOL * max(1.0, cond_bandwidth(x0, delta))
    _close(d.omega_n_T, x0, tol, "omega_n_T (smallest root)")
    _close(d.beta, x0 * x0, 2 * tol, "beta")
    _close(d.alpha, 2 * delta * x0 - x0 * x0 / 2, 4 * tol, "alpha")
    assert d.stable is True
    # it realises bn according to quad as well
    _close(abref.noise_bandwidth_quad(x0, delta), bn, RTOL_QUAD, "quad")


@pytest.mark.parametrize("delta", [0.87, 0.9, 0.95, 0.99])
def test_from_bandwidth_nonmonotone_single_root_below(delta):
    """bn below B(1/delta) has a single root in the interval; it is returned."""
    bn = 0.5 * (1 / delta) * (1 + (2 * delta - 1 / delta) ** 2) / (8 * delta)
    roots = abref.bandwidth_cubic_roots(bn, delta)
    assert len(roots) == 1
    d = ab.from_bandwidth(bn, delta)
    _close(d.omega_n_T, roots[0], RTOL * max(1.0, cond_bandwidth(roots[0], delta)), "omega_n_T")


# ---------------------------------------------------------------------------
# round trips
# ---------------------------------------------------------------------------
def _kalman_grid():
    return ab.from_snr(R_GRID)


def test_round_trip_kalman_analyze():
    """from_snr(r) -> (alpha, beta) -> analyze: same r (rtol 1e-12 max(1, cond),
    cond = 4 + 3/(1 - alpha)), damping, bandwidth_T, omega_n_T, beta (rtol 1e-12),
    and flagged Kalman-optimal."""
    d = _kalman_grid()
    a = ab.analyze(d.alpha, d.beta)
    _close(a.r, R_GRID, RTOL * np.maximum(1.0, cond_alpha(d.alpha)), "r")
    for name in ("alpha", "beta", "damping", "bandwidth_T", "omega_n_T"):
        _close(getattr(a, name), getattr(d, name), RTOL, name)
    assert np.all(a.kalman_optimal)


def test_analyze_r_vs_kalata_mpmath():
    """analyze(alpha, beta).r == beta_K(alpha)^2 / (4 (1 - alpha)) evaluated at 50
    digits for the exact float alpha (Kalata), rtol 1e-12 max(1, cond)."""
    alphas = np.concatenate([np.logspace(-8, -0.5, 16), 1 - np.logspace(-1, -12, 12)])
    betas = np.array([float(abref.kalata_beta_mp(a)) for a in alphas])
    d = ab.analyze(alphas, betas)
    want = np.array([float(abref.kalata_r_mp(a)) for a in alphas])
    _close(d.r, want, RTOL * np.maximum(1.0, cond_alpha(alphas)), "r(alpha)")
    assert np.all(d.kalman_optimal)


def test_round_trip_from_tracking_error():
    """from_tracking_error(d.alpha) reproduces the from_snr design: alpha, beta, r,
    rtol 1e-12 * max(1, cond), cond = 4 + 3/(1 - alpha)."""
    d = _kalman_grid()
    ok = d.alpha < 1.0  # ratio must be in (0, 1)
    e = ab.from_tracking_error(d.alpha[ok])
    tol = RTOL * np.maximum(1.0, cond_alpha(d.alpha[ok]))
    _close(e.alpha, d.alpha[ok], RTOL, "alpha")
    _close(e.beta, d.beta[ok], tol, "beta")
    _close(e.r, R_GRID[ok], tol, "r")
    assert np.all(e.kalman_optimal)


@pytest.mark.parametrize("ratio", [1e-9, 1e-4, 0.01, 0.25, 0.5, 0.75, 0.99, 1 - 1e-6])
def test_from_tracking_error_vs_mpmath(ratio):
    """from_tracking_error(ratio): alpha == ratio (eq (14)), beta == Kalata beta(ratio)
    and r == Kalata r(ratio) at 50 digits, and the DARE at that r has alpha == ratio.
    rtol 1e-12 * max(1, cond)."""
    d = ab.from_tracking_error(ratio)
    tol = RTOL * max(1.0, float(cond_alpha(ratio)))
    _close(d.alpha, ratio, RTOL, "alpha")
    _close(d.tracking_error_ratio, ratio, RTOL, "tracking_error_ratio")
    _close(d.beta, float(abref.kalata_beta_mp(ratio)), tol, "beta")
    r = abref.kalata_r_mp(ratio)
    _close(d.r, float(r), tol, "r")
    ref = abref.dare_mp(r)
    assert abs(float(ref["alpha"]) / ratio - 1) < 1e-14  # closes the loop on the reference


@pytest.mark.parametrize("x,delta", det_cases(), ids=DET_IDS)
def test_round_trip_deterministic(x, delta):
    """from_natural_frequency -> analyze -> same damping, omega_n_T, bandwidth_T;
    from_bandwidth(d.bandwidth_T, d.damping) -> same gains (rtol 1e-12 * max(1,
    cond_bw * cond_alpha_x)); from_natural_frequency(d.omega_n_T / T, T, d.damping)
    -> same gains (rtol 1e-12)."""
    T = 0.1
    d = ab.from_natural_frequency(x / T, T, delta)
    a = ab.analyze(d.alpha, d.beta)
    for name in ("damping", "omega_n_T", "bandwidth_T", "r", "alpha", "beta"):
        if name == "r" and not np.isfinite(d.r):
            assert not np.isfinite(a.r)
            continue
        _close(getattr(a, name), getattr(d, name), RTOL, name)

    xx = d.omega_n_T
    cb = cond_bandwidth(xx, delta)
    ca = max(2.0, abs(2 * delta * xx - xx * xx) / d.alpha)  # d ln alpha / d ln x
    b = ab.from_bandwidth(d.bandwidth_T, d.damping)
    if delta > math.sqrt(3) / 2 and delta < 1 and len(abref.bandwidth_cubic_roots(d.bandwidth_T, delta)) > 1 \
            and abs(xx - abref.bandwidth_cubic_roots(d.bandwidth_T, delta)[0]) > 1e-6:
        # the larger of two roots: from_bandwidth correctly returns the smaller one
        assert b.omega_n_T < xx
    else:
        _close(b.beta, d.beta, RTOL * max(1.0, 2 * cb), "from_bandwidth beta")
        _close(b.alpha, d.alpha, RTOL * max(1.0, ca * cb), "from_bandwidth alpha")

    n = ab.from_natural_frequency(d.omega_n_T / T, T, d.damping)
    _close(n.alpha, d.alpha, RTOL * ca, "from_natural_frequency alpha")
    _close(n.beta, d.beta, RTOL, "from_natural_frequency beta")


def test_round_trip_kalman_via_bandwidth_and_natural_frequency():
    """Kalman designs: from_bandwidth(bandwidth_T, damping) and
    from_natural_frequency(omega_n_T / T, T, damping) give the same gains
    (rtol 1e-12 * max(1, cond)); at delta = 1/sqrt(2) (16) is monotone with
    cond <= 2 + sqrt(3)."""
    d = _kalman_grid()
    T = 2.0
    b = ab.from_bandwidth(d.bandwidth_T, d.damping)
    n = ab.from_natural_frequency(d.omega_n_T / T, T, d.damping)
    x = d.omega_n_T
    cb = cond_bandwidth(x, SQRT_HALF)
    assert np.all(cb <= 2 + math.sqrt(3) + 1e-9)
    ca = np.maximum(2.0, np.abs(2 * SQRT_HALF * x - x * x) / d.alpha)
    for o, label in ((b, "from_bandwidth"), (n, "from_natural_frequency")):
        _close(o.beta, d.beta, RTOL * 2 * cb, f"{label} beta")
        _close(o.alpha, d.alpha, RTOL * ca * cb, f"{label} alpha")
        assert np.all(o.kalman_optimal)


# ---------------------------------------------------------------------------
# shapes and types
# ---------------------------------------------------------------------------
FLOAT_FIELDS = ("alpha", "beta", "r", "snr_db", "tracking_index", "damping", "omega_n_T", "bandwidth_T",
                "tracking_error_ratio", "b1_T", "b2_T2", "K_T", "zero_T")
BOOL_FIELDS = ("kalman_optimal", "stable", "valid")


def _broadcast_calls():
    a31 = np.array([[0.05], [0.1], [0.2]])
    d4 = np.array([0.5, SQRT_HALF, 0.9, 1.2])
    return {
        "from_bandwidth": (ab.from_bandwidth, (a31, d4)),
        "from_noise": (ab.from_noise, (np.array([[1.0], [3.0], [10.0]]), np.array([1.0, 2.0, 5.0, 30.0]), 0.1)),
        "from_natural_frequency": (ab.from_natural_frequency, (np.array([[0.5], [1.0], [2.0]]), np.array([0.05, 0.1, 0.2, 0.3]), 0.8)),
        "analyze": (ab.analyze, (np.array([[0.2], [0.5], [0.9]]), np.array([0.01, 0.1, 0.3, 0.5]))),
    }


@pytest.mark.parametrize("name", list(_broadcast_calls().keys()))
def test_broadcasting_shapes_and_elementwise(name):
    """(3,1) with (4,) -> (3,4); every field has the broadcast shape (+ (2,) for
    poles, + (2,2) for covariances) and equals the scalar call element-wise
    (rtol 1e-15)."""
    f, args = _broadcast_calls()[name]
    d = f(*args)
    assert d.shape == (3, 4)
    for fld in FLOAT_FIELDS:
        v = getattr(d, fld)
        assert isinstance(v, np.ndarray) and v.shape == (3, 4) and v.dtype == np.float64, fld
    for fld in BOOL_FIELDS:
        v = getattr(d, fld)
        assert isinstance(v, np.ndarray) and v.shape == (3, 4) and v.dtype == bool, fld
    assert d.poles.shape == (3, 4, 2)
    assert d.covariance_filtered.shape == (3, 4, 2, 2)
    assert d.covariance_predicted.shape == (3, 4, 2, 2)
    for nt in (d.variance_reduction, d.lag):
        for v in nt:
            assert v.shape == (3, 4)
    bargs = np.broadcast_arrays(*[np.asarray(a, dtype=float) for a in args])
    for i in range(3):
        for j in range(4):
            s = f(*[float(b[i, j]) for b in bargs])
            for fld in FLOAT_FIELDS:
                np.testing.assert_allclose(getattr(d, fld)[i, j], getattr(s, fld), rtol=1e-15, atol=0, err_msg=fld)
            for fld in BOOL_FIELDS:
                assert getattr(d, fld)[i, j] == getattr(s, fld), fld
            np.testing.assert_allclose(d.covariance_filtered[i, j], s.covariance_filtered, rtol=1e-15, atol=0)
            np.testing.assert_allclose(d.poles[i, j], s.poles, rtol=1e-15, atol=0)


def test_broadcasting_error_covariance():
    """error_covariance with (3,1), (4,) and scalar -> (3, 4, 2, 2)."""
    c = ab.error_covariance(np.array([[0.2], [0.5], [0.9]]), np.array([0.01, 0.1, 0.3, 0.5]), 0.01)
    assert c.filtered.shape == (3, 4, 2, 2) and c.predicted.shape == (3, 4, 2, 2)
    s = ab.error_covariance(0.5, 0.3, 0.01)
    np.testing.assert_allclose(c.filtered[1, 2], s.filtered, rtol=1e-15, atol=0)
    assert s.filtered.shape == (2, 2)


@pytest.mark.parametrize("make", [
    lambda: ab.from_snr(0.1),
    lambda: ab.from_snr(np.float64(0.1)),
    lambda: ab.from_snr(np.array(0.1)),
    lambda: ab.from_snr(np.float32(0.1)),
    lambda: ab.from_snr(1),
    lambda: ab.from_noise(3.2, 32.0, 0.1),
    lambda: ab.from_tracking_index(0.5),
    lambda: ab.from_tracking_error(0.5),
    lambda: ab.from_bandwidth(0.1),
    lambda: ab.from_bandwidth(0.1, 0.5),
    lambda: ab.from_natural_frequency(2.0, 0.1),
    lambda: ab.analyze(0.5, 0.2),
], ids=["snr", "snr-f64", "snr-0d", "snr-f32", "snr-int", "noise", "lambda", "ratio", "bw", "bw-d", "wn", "analyze"])
def test_scalar_in_python_scalars_out(make):
    """Scalar input -> Python float (not numpy) fields, bool flags, shape ()."""
    d = make()
    assert d.shape == ()
    for fld in FLOAT_FIELDS:
        assert type(getattr(d, fld)) is float, fld
    for fld in BOOL_FIELDS:
        assert type(getattr(d, fld)) is bool, fld
    for nt in (d.variance_reduction, d.lag):
        for v in nt:
            assert type(v) is float
    assert d.poles.shape == (2,)
    assert d.covariance_filtered.shape == (2, 2)


def test_list_input_gives_arrays():
    d = ab.from_snr([0.1, 1.0])
    assert isinstance(d.alpha, np.ndarray) and d.alpha.shape == (2,)
    np.testing.assert_allclose(d.alpha[1], ab.from_snr(1.0).alpha, rtol=1e-15)


# ---------------------------------------------------------------------------
# poles and stability
# ---------------------------------------------------------------------------
def _random_gains(n, seed, amax=2.2, bmax=4.5):
    rng = np.random.default_rng(seed)
    a = rng.uniform(0, amax, n)
    b = rng.uniform(0, bmax, n)
    a[a == 0] = 0.5
    b[b == 0] = 0.5
    # plus a decade-wide log sample of small gains
    a2 = 10 ** rng.uniform(-6, 0, n // 4)
    b2 = a2**2 * 10 ** rng.uniform(-1, 1, n // 4)
    return np.concatenate([a, a2]), np.concatenate([b, b2])


def test_poles_vs_numpy_roots():
    """poles == numpy.roots([1, -(2 - alpha - beta), 1 - alpha]) as a set, abs tol
    1e-12 * (1 + 1/|z1 - z2|) (root conditioning near a double root); and Vieta:
    z1 + z2 = 2 - alpha - beta, z1 z2 = 1 - alpha to 1e-13 abs."""
    a, b = _random_gains(400, 1)
    k = ab.from_snr(np.logspace(-8, 8, 33))
    a = np.concatenate([a, k.alpha])
    b = np.concatenate([b, k.beta])
    d = ab.analyze(a, b)
    P = d.poles
    for i in range(a.size):
        want = np.roots([1.0, -(2.0 - a[i] - b[i]), 1.0 - a[i]])
        got = P[i]
        sep = abs(want[0] - want[1])
        tol = 1e-12 * (1 + 1 / max(sep, 1e-4))
        # match as multisets
        e1 = max(abs(got[0] - want[0]), abs(got[1] - want[1]))
        e2 = max(abs(got[0] - want[1]), abs(got[1] - want[0]))
        assert min(e1, e2) <= tol, (a[i], b[i], got, want)
        assert abs(got[0] + got[1] - (2 - a[i] - b[i])) <= 1e-13 * (1 + abs(2 - a[i] - b[i]))
        assert abs(got[0] * got[1] - (1 - a[i])) <= 1e-13 * (1 + abs(got[0]) ** 2)
        if abs(got[0].imag) > 0:
            assert abs(got[0] - np.conj(got[1])) <= 1e-13 * (1 + abs(got[0]))


def test_stable_flag_vs_jury_and_pole_radius():
    """stable == (max |pole| < 1) == Jury (alpha > 0, beta > 0, 2 alpha + beta < 4)
    on random gains, skipping points within 1e-9 of the boundary."""
    a, b = _random_gains(2000, 2, amax=3.0, bmax=6.0)
    d = ab.analyze(a, b)
    rho = np.array([np.max(np.abs(np.roots([1.0, -(2.0 - ai - bi), 1.0 - ai]))) for ai, bi in zip(a, b)])
    jury = (a > 0) & (b > 0) & (2 * a + b < 4)
    clear = (np.abs(rho - 1) > 1e-9) & (np.abs(2 * a + b - 4) > 1e-9)
    assert clear.sum() > 2000
    assert np.array_equal(jury[clear], (rho < 1)[clear])
    assert np.array_equal(np.asarray(d.stable)[clear], jury[clear])
    # valid = stable and alpha < 1 and sqrt(beta) <= pi
    valid = jury & (a < 1) & (np.sqrt(b) <= math.pi)
    assert np.array_equal(np.asarray(d.valid)[clear], valid[clear])
    assert np.any(d.stable) and not np.all(d.stable)
    assert np.any(d.valid) and not np.all(d.valid)


def test_stability_boundary_points():
    """Just inside / outside 2 alpha + beta = 4 and alpha = 2."""
    inside = ab.analyze(np.array([1.0, 0.5, 1.9]), np.array([2.0 - 1e-9, 3.0 - 1e-9, 0.2 - 1e-9]))
    outside = ab.analyze(np.array([1.0, 0.5, 1.9]), np.array([2.0 + 1e-9, 3.0 + 1e-9, 0.2 + 1e-9]))
    assert np.all(inside.stable) and not np.any(outside.stable)


# ---------------------------------------------------------------------------
# kalman_optimal flag
# ---------------------------------------------------------------------------
ALPHAS = [1e-4, 0.01, 0.1, 0.3, 0.5, 0.7, 0.9, 0.99]


@pytest.mark.parametrize("alpha", ALPHAS)
def test_kalman_optimal_flag(alpha):
    """Kalata beta(alpha) (mpmath) -> True, also perturbed by 1e-12 relative;
    perturbed by 1e-7 -> False (flag tolerance is 1e-9 relative);
    Benedict-Bordner beta = alpha^2 / (2 - alpha) -> False wherever it differs
    from the Kalman beta by more than 1e-8 (all alpha here except 1e-4)."""
    bk = float(abref.kalata_beta_mp(alpha))
    assert ab.analyze(alpha, bk).kalman_optimal is True
    assert ab.analyze(alpha, bk * (1 + 1e-12)).kalman_optimal is True
    assert ab.analyze(alpha, bk * (1 - 1e-12)).kalman_optimal is True
    assert ab.analyze(alpha, bk * (1 + 1e-7)).kalman_optimal is False
    assert ab.analyze(alpha, bk * (1 - 1e-7)).kalman_optimal is False
    bb = alpha**2 / (2 - alpha)
    # BB and Kalman beta differ by ~ alpha^2/16 relative: at alpha = 1e-4 that is
    # below the flag's 1e-9 tolerance, so BB gains *are* Kalman-optimal there.
    differ = abs(bb / bk - 1)
    assert differ > 1e-8 or differ < 1e-9
    assert ab.analyze(alpha, bb).kalman_optimal is (differ < 1e-9)


@pytest.mark.parametrize("delta", [0.3, 0.5, 0.9, 1.0, 2.0])
def test_non_kalman_damping_is_not_optimal(delta):
    d = ab.from_bandwidth(0.05, delta)
    assert d.kalman_optimal is False
    assert ab.from_bandwidth(0.05).kalman_optimal is True


# ---------------------------------------------------------------------------
# gains() and continuous()
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("omega_n,T,delta", [(2.0, 0.1, 0.5), (0.3, 1.0, SQRT_HALF), (40.0, 0.01, 1.5),
                                             (5.0, 0.05, 0.25), (1.0, 0.5, 1.0)])
def test_gains_and_continuous(omega_n, T, delta):
    """From the inputs alone: g1 = alpha, g2 = beta / T; b1 = w (2 delta - w T),
    b2 = w^2, K = b1, zero z = -b2/b1, omega_n, damping; and eq (6):
    alpha = b1 T + b2 T^2 / 2, beta = b2 T^2. rtol 1e-12."""
    d = ab.from_natural_frequency(omega_n, T, delta)
    wT = omega_n * T
    alpha = wT * (2 * delta - wT / 2)
    beta = wT * wT
    g1, g2 = d.gains()
    _close(g1, alpha, RTOL, "g1")
    _close(g2, beta / T, RTOL, "g2")
    c = d.continuous()
    b1 = omega_n * (2 * delta - wT)
    b2 = omega_n**2
    _close(c["b1"], b1, RTOL * (1 + 2 * delta / abs(2 * delta - wT)), "b1")
    _close(c["K"], b1, RTOL * (1 + 2 * delta / abs(2 * delta - wT)), "K")
    _close(c["b2"], b2, RTOL, "b2")
    _close(c["z"], -b2 / b1, RTOL * (1 + 2 * delta / abs(2 * delta - wT)), "z")
    _close(c["omega_n"], omega_n, RTOL, "omega_n")
    _close(c["damping"], delta, RTOL, "damping")
    # dimensionless fields
    _close(d.b1_T, b1 * T, RTOL * (1 + 2 * delta / abs(2 * delta - wT)), "b1_T")
    _close(d.K_T, b1 * T, RTOL * (1 + 2 * delta / abs(2 * delta - wT)), "K_T")
    _close(d.b2_T2, b2 * T * T, RTOL, "b2_T2")
    _close(d.zero_T, -b2 * T / b1, RTOL * (1 + 2 * delta / abs(2 * delta - wT)), "zero_T")
    # eq (6)
    _close(c["b1"] * T + c["b2"] * T * T / 2, alpha, 1e-12, "eq (6) g1")
    _close(c["b2"] * T * T, beta, RTOL, "eq (6) g2 T")
    # explicit T overrides
    T2 = 3 * T
    g1b, g2b = d.gains(T2)
    assert g1b == g1
    _close(g2b, beta / T2, RTOL, "g2 with explicit T")
    _close(d.continuous(T2)["omega_n"], wT / T2, RTOL, "omega_n with explicit T")


def test_gains_need_T_when_not_recorded():
    d = ab.from_snr(0.1)
    with pytest.raises(ValueError, match="T"):
        d.gains()
    with pytest.raises(ValueError, match="T"):
        d.continuous()
    g1, g2 = d.gains(np.array([0.1, 1.0]))
    assert isinstance(g2, np.ndarray) and g2.shape == (2,)
    _close(g2, d.beta / np.array([0.1, 1.0]), RTOL, "g2 array T")
    # kalman gains in physical units: g2 = P12 / T
    ref = abref.dare_mp_float(0.1)
    _close(d.gains(0.25)[1], ref["beta"] / 0.25, RTOL, "g2 vs DARE")


@pytest.mark.parametrize("alpha,beta", [(0.5, 0.1), (0.05, 0.2), (1.2, 0.5), (0.3, 0.3)])
def test_continuous_of_analyze(alpha, beta):
    """analyze: b1 T = alpha - beta/2 (eq (6)), b2 T^2 = beta, zero T = -b2 T^2 / (b1 T),
    omega_n T = sqrt(beta), damping = (alpha + beta/2) / (2 sqrt(beta)). rtol 1e-12."""
    d = ab.analyze(alpha, beta)
    c = d.continuous(1.0)
    b1T = alpha - beta / 2
    _close(c["b1"], b1T, RTOL, "b1")
    _close(c["b2"], beta, RTOL, "b2")
    _close(c["z"], -beta / b1T, RTOL, "z")
    _close(c["omega_n"], math.sqrt(beta), RTOL, "omega_n")
    _close(c["damping"], (alpha + beta / 2) / (2 * math.sqrt(beta)), RTOL, "damping")
