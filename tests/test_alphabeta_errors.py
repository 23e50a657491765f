"""Input validation, error messages, NaN-freedom and input immutability of
abkit.alphabeta.

Every invalid input must raise ValueError (bad value, shape) or TypeError (bad
type) whose message names the offending parameter. For finite valid input no
output field is ever NaN (inf is allowed where documented: unstable filters,
overflow of a covariance). Property sweeps use hypothesis with
``derandomize=True`` and a modest ``max_examples`` so the suite is
deterministic and fast.
"""

from __future__ import annotations

import math
import re
import tempfile
from pathlib import Path

import mpmath
import numpy as np
import pytest
import scipy.optimize
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.configuration import set_hypothesis_home_dir

from abkit import alphabeta as ab

# keep hypothesis' files (failure patches) out of the repository
set_hypothesis_home_dir(Path(tempfile.gettempdir()) / "abkit-tests-hypothesis")

SQRT_HALF = 1.0 / math.sqrt(2.0)
HYP = settings(max_examples=150, derandomize=True, deadline=None, database=None)
FMAX = np.finfo(float).max
FTINY = np.finfo(float).tiny  # smallest normal

# constructor -> (callable, parameter names, a valid argument tuple)
CONSTRUCTORS = {
    "from_snr": (ab.from_snr, ("r",), (0.1,)),
    "from_noise": (ab.from_noise, ("sigma_w", "sigma_v", "T"), (3.2, 32.0, 0.1)),
    "from_tracking_index": (ab.from_tracking_index, ("lam",), (0.5,)),
    "from_tracking_error": (ab.from_tracking_error, ("ratio",), (0.5,)),
    "from_bandwidth": (ab.from_bandwidth, ("bn_t", "damping"), (0.1, 0.6)),
    "from_natural_frequency": (ab.from_natural_frequency, ("omega_n", "T", "damping"), (2.0, 0.1, 0.5)),
    "analyze": (ab.analyze, ("alpha", "beta"), (0.5, 0.2)),
    "error_covariance": (ab.error_covariance, ("alpha", "beta", "r_true"), (0.5, 0.2, 0.1)),
}


def name_re(name):
    """The parameter name as a word (so 'r' does not match 'must be ... or ...')."""
    return rf"(?<![A-Za-z_]){re.escape(name)}(?![A-Za-z_])"


def _param_cases():
    cases = []
    for cname, (f, names, valid) in CONSTRUCTORS.items():
        for i, pname in enumerate(names):
            if pname == "ratio":
                bads = [0.0, 1.0, -0.5, 1.5, math.nan, math.inf, -math.inf]
            elif pname == "r_true":
                bads = [-1.0, -1e-300, math.nan, math.inf, -math.inf]  # 0 is allowed
            else:
                bads = [-1.0, 0.0, -0.0, math.nan, math.inf, -math.inf]
            for bad in bads:
                cases.append(pytest.param(cname, i, bad, id=f"{cname}-{pname}={bad!r}"))
    return cases


@pytest.mark.parametrize("cname,i,bad", _param_cases())
def test_invalid_value_raises_valueerror_naming_parameter(cname, i, bad):
    """Negative / zero / NaN / inf (ratio: outside (0, 1); r_true: negative or not
    finite) -> ValueError whose message names the parameter; also as one element
    of an array."""
    f, names, valid = CONSTRUCTORS[cname]
    args = list(valid)
    args[i] = bad
    with pytest.raises(ValueError, match=name_re(names[i])):
        f(*args)
    args[i] = np.array([valid[i], bad, valid[i]])
    with pytest.raises(ValueError, match=name_re(names[i])):
        f(*args)


def _type_cases():
    bads = {
        "complex": 0.1 + 0.2j,
        "complex-array": np.array([0.1, 0.2], dtype=complex),
        "complex-zero-imag": np.complex128(0.1),
        "str": "0.1",
        "bytes": b"0.1",
        "str-array": np.array(["0.1", "0.2"]),
        "object-array": np.array([0.1, None], dtype=object),
        "object-of-floats": np.array([0.1, 0.2], dtype=object),
        "datetime": np.datetime64("2020-01-01"),
        "none": None,
    }
    cases = []
    for cname, (f, names, valid) in CONSTRUCTORS.items():
        for i, pname in enumerate(names):
            for bname, bad in bads.items():
                cases.append(pytest.param(cname, i, bad, id=f"{cname}-{pname}-{bname}"))
    return cases


@pytest.mark.parametrize("cname,i,bad", _type_cases())
def test_invalid_type_raises_typeerror_naming_parameter(cname, i, bad):
    """Complex, str/bytes, object, datetime or None input -> TypeError naming the parameter."""
    f, names, valid = CONSTRUCTORS[cname]
    args = list(valid)
    args[i] = bad
    with pytest.raises(TypeError, match=name_re(names[i])):
        f(*args)


MULTI = [c for c, (f, names, v) in CONSTRUCTORS.items() if len(names) > 1]


@pytest.mark.parametrize("cname", MULTI)
def test_non_broadcasting_shapes(cname):
    """Shapes (3,) and (4,) -> ValueError naming both parameters."""
    f, names, valid = CONSTRUCTORS[cname]
    args = list(valid)
    args[0] = np.full(3, valid[0])
    args[1] = np.full(4, valid[1])
    with pytest.raises(ValueError) as ei:
        f(*args)
    msg = str(ei.value)
    assert re.search(name_re(names[0]), msg) and re.search(name_re(names[1]), msg), msg
    assert "broadcast" in msg


def test_empty_input():
    d = ab.from_snr(np.array([]))
    assert d.shape == (0,)
    assert d.alpha.shape == (0,)


# ---------------------------------------------------------------------------
# domain limits
# ---------------------------------------------------------------------------
def bandwidth_sup(delta):
    """sup of eq (16) over omega_n T in (0, min(4 delta, 1/delta)), found numerically
    (dense grid, then bounded scalar maximisation around the best point)."""
    hi = min(4 * delta, 1 / delta)

    def B(x):
        return x * (1 + (2 * delta - x) ** 2) / (8 * delta)

    xs = np.linspace(0, hi, 20001)
    k = int(np.argmax(B(xs)))
    if k == len(xs) - 1:
        return B(hi)
    res = scipy.optimize.minimize_scalar(lambda x: -B(x), bounds=(xs[max(k - 1, 0)], xs[k + 1]),
                                         method="bounded", options={"xatol": 1e-14})
    return max(-res.fun, B(hi))


@pytest.mark.parametrize("delta", [0.05, 0.2, 0.5, SQRT_HALF, 0.8, 0.9, 0.95, 1.0, 1.5, 3.0, 20.0])
def test_from_bandwidth_stable_maximum(delta):
    """bn_t just below the supremum of (16) on the stable, alpha > 0 range works
    (stable, alpha > 0); 1e-6 above it -> ValueError naming bn_t."""
    bmax = bandwidth_sup(delta)
    d = ab.from_bandwidth(bmax * (1 - 1e-6), delta)
    assert d.stable is True and d.alpha > 0
    with pytest.raises(ValueError, match=name_re("bn_t")):
        ab.from_bandwidth(bmax * (1 + 1e-6), delta)


@pytest.mark.parametrize("bn", [np.nextafter(0.25, 1.0), 0.2500001, 0.26, 0.3, 1.0, 1e10])
def test_from_bandwidth_above_quarter_at_default_damping(bn):
    """At the default damping the stable maximum is 0.25: anything above raises a
    ValueError naming bn_t and giving the bound."""
    with pytest.raises(ValueError, match=name_re("bn_t")) as ei:
        ab.from_bandwidth(bn)
    assert "0.25" in str(ei.value)


@pytest.mark.parametrize("omega_n,T,delta", [(15.0, 0.1, SQRT_HALF), (0.9, 1.0, 0.2), (1.0, 1.0, 1.0),
                                             (0.6, 1.0, 2.0), (1e3, 1.0, 0.5)])
def test_from_natural_frequency_out_of_range(omega_n, T, delta):
    """omega_n T >= min(4 delta, 1/delta) -> ValueError naming omega_n."""
    with pytest.raises(ValueError, match=name_re("omega_n")):
        ab.from_natural_frequency(omega_n, T, delta)


@pytest.mark.parametrize("alpha,beta", [(1.5, 1.5), (0.5, 3.0), (1.0, 2.0), (2.0, 1e-3), (2.5, 0.1), (0.1, 10.0)])
def test_error_covariance_unstable_raises(alpha, beta):
    """beta >= 4 - 2 alpha (unstable / marginal) -> ValueError (no steady state)."""
    with pytest.raises(ValueError, match=name_re("beta")):
        ab.error_covariance(alpha, beta, 0.1)
    with pytest.raises(ValueError):
        ab.error_covariance(np.array([0.5, alpha]), np.array([0.2, beta]), 0.0)


@pytest.mark.parametrize("sw,sv,T", [(1e300, 1e-300, 1e10), (1e200, 1e-200, 1.0), (1e-300, 1e300, 1e-10),
                                     (1e-200, 1e200, 1.0)])
def test_from_noise_over_underflow(sw, sv, T):
    """sigma_w T^2 / sigma_v over- or underflowing float64 -> ValueError naming sigma_w."""
    with pytest.raises(ValueError, match=name_re("sigma_w")):
        ab.from_noise(sw, sv, T)


def test_methods_validate_T():
    d = ab.from_noise(3.2, 32.0, 0.1)
    for bad in (0.0, -1.0, math.nan, math.inf):
        with pytest.raises(ValueError, match=name_re("T")):
            d.gains(bad)
        with pytest.raises(ValueError, match=name_re("T")):
            d.continuous(bad)
        with pytest.raises(ValueError, match=name_re("T")):
            d.scaled_covariance(1.0, bad)
        with pytest.raises(ValueError, match=name_re("sigma_v")):
            d.scaled_covariance(bad)
    with pytest.raises(TypeError, match=name_re("T")):
        d.gains(1j)


# ---------------------------------------------------------------------------
# no NaN for finite valid input
# ---------------------------------------------------------------------------
FLOAT_FIELDS = ("alpha", "beta", "r", "snr_db", "tracking_index", "damping", "omega_n_T", "bandwidth_T",
                "tracking_error_ratio", "b1_T", "b2_T2", "K_T", "zero_T")


def assert_no_nan(d, label=""):
    bad = []
    for fld in FLOAT_FIELDS:
        if np.any(np.isnan(getattr(d, fld))):
            bad.append(fld)
    for fld in ("covariance_filtered", "covariance_predicted"):
        if np.any(np.isnan(getattr(d, fld))):
            bad.append(fld)
    p = d.poles
    if np.any(np.isnan(p.real)) or np.any(np.isnan(p.imag)):
        bad.append("poles")
    for nt in (d.variance_reduction, d.lag):
        for k, v in nt._asdict().items():
            if np.any(np.isnan(v)):
                bad.append(k)
    for fld in ("kalman_optimal", "stable", "valid"):
        getattr(d, fld)
    assert not bad, f"NaN in {bad} for {label}: {d!r}"


def assert_kalman_sane(d, label):
    """Gains in the Kalman range 0 <= alpha <= 1, 0 <= beta <= 2 (0 only by underflow)."""
    a, b = np.asarray(d.alpha), np.asarray(d.beta)
    assert np.all((a >= 0) & (a <= 1)), (label, a)
    assert np.all((b >= 0) & (b <= 2)), (label, b)


# Kalman designs are stable in exact arithmetic. For inputs so extreme that the
# float64 gains would round onto the stability boundary (r beyond ~1e31,
# tracking index beyond ~6e15, ratio below ~3e-162), abkit raises a ValueError
# naming the argument instead of returning a marginal filter. Inside these
# bounds every design must be NaN-free and stable.
R_OK, LAM_OK, RATIO_OK = 1e30, 2e15, 1e-160
R_BAD, LAM_BAD, RATIO_BAD = 1e33, 1e17, 1e-163


def kalman_or_rejected(make, value, name, ok, label):
    """Call make(value): a NaN-free stable design when ``ok``; otherwise either
    that or a ValueError naming ``name`` and saying the gains are not representable."""
    try:
        d = make(value)
    except ValueError as e:
        assert not ok, f"{label} rejected inside the representable range: {e}"
        assert re.search(name_re(name), str(e)) and "representable" in str(e), str(e)
        return None
    assert_no_nan(d, label)
    assert_kalman_sane(d, label)
    assert np.all(d.stable), label
    return d


pos_float = st.floats(min_value=5e-324, max_value=FMAX, allow_nan=False, allow_infinity=False)


@HYP
@given(r=pos_float)
def test_from_snr_no_nan(r):
    d = kalman_or_rejected(ab.from_snr, r, "r", r <= R_OK, f"from_snr({r!r})")
    if d is not None:
        assert d.r == r


@HYP
@given(lam=pos_float)
def test_from_tracking_index_no_nan(lam):
    kalman_or_rejected(ab.from_tracking_index, lam, "lam", lam <= LAM_OK, f"from_tracking_index({lam!r})")


@HYP
@given(ratio=st.floats(min_value=0.0, max_value=1.0, exclude_min=True, exclude_max=True))
def test_from_tracking_error_no_nan(ratio):
    d = kalman_or_rejected(ab.from_tracking_error, ratio, "ratio", ratio >= RATIO_OK, f"from_tracking_error({ratio!r})")
    if d is not None:
        assert d.alpha == ratio  # eq (14): alpha is the given ratio, bit for bit


wide = st.floats(min_value=1e-150, max_value=1e150, allow_nan=False, allow_infinity=False)


@HYP
@given(sw=wide, sv=wide, T=st.floats(min_value=1e-60, max_value=1e60))
def test_from_noise_no_nan(sw, sv, T):
    """Either a ValueError because lambda = sigma_w T^2 / sigma_v is not a normal
    float64 (exact arithmetic decides), or a NaN-free design."""
    with mpmath.workdps(30):
        lam = mpmath.mpf(sw) * mpmath.mpf(T) ** 2 / mpmath.mpf(sv)
    representable = FTINY * (1 + 1e-10) <= lam <= FMAX * (1 - 1e-10)
    try:
        d = ab.from_noise(sw, sv, T)
    except ValueError as e:
        assert not representable or lam < FTINY * 4 or lam > LAM_OK, (sw, sv, T, float(lam), str(e))
        assert re.search(name_re("sigma_w"), str(e))
        return
    assert lam > 0 and lam <= FMAX * (1 + 1e-10)
    assert_no_nan(d, f"from_noise{(sw, sv, T)}")
    assert_kalman_sane(d, (sw, sv, T))
    assert d.stable


@HYP
@given(delta=st.floats(min_value=1e-3, max_value=1e3), frac=st.floats(min_value=1e-12, max_value=0.999))
def test_from_bandwidth_no_nan(delta, frac):
    """bn_t = frac * (stable maximum) is valid: NaN-free, stable, alpha > 0."""
    bn = frac * bandwidth_sup(delta)
    d = ab.from_bandwidth(bn, delta)
    assert_no_nan(d, f"from_bandwidth({bn!r}, {delta!r})")
    assert d.stable is True and d.alpha > 0 and d.beta > 0
    assert d.bandwidth_T == pytest.approx(bn, rel=1e-9)
    assert d.damping == pytest.approx(delta, rel=1e-9)


@HYP
@given(delta=st.floats(min_value=1e-3, max_value=1e3), frac=st.floats(min_value=1e-12, max_value=0.999),
       T=st.floats(min_value=1e-6, max_value=1e6))
def test_from_natural_frequency_no_nan(delta, frac, T):
    x = frac * min(4 * delta, 1 / delta)
    d = ab.from_natural_frequency(x / T, T, delta)
    assert_no_nan(d, f"from_natural_frequency({x / T!r}, {T!r}, {delta!r})")
    assert d.stable is True and d.alpha > 0


@HYP
@given(alpha=pos_float, beta=pos_float)
def test_analyze_no_nan(alpha, beta):
    """Any finite positive gains (stable or not) give NaN-free fields; the stable
    flag agrees with Jury."""
    d = ab.analyze(alpha, beta)
    assert_no_nan(d, f"analyze({alpha!r}, {beta!r})")
    assert d.stable == (2 * alpha + beta < 4)


@HYP
@given(alpha=st.floats(min_value=1e-300, max_value=1.999999),
       fb=st.floats(min_value=1e-300, max_value=0.999999),
       r_true=st.one_of(st.just(0.0), st.floats(min_value=0.0, max_value=1e300)))
def test_error_covariance_no_nan(alpha, fb, r_true):
    beta = fb * (4 - 2 * alpha)
    if not (beta > 0 and 2 * alpha + beta < 4):
        return
    c = ab.error_covariance(alpha, beta, r_true)
    assert not np.any(np.isnan(c.filtered)) and not np.any(np.isnan(c.predicted)), (alpha, beta, r_true, c)
    # variances are positive (may underflow to 0 or overflow to inf, never negative)
    assert c.filtered[0, 0] > 0 and c.filtered[1, 1] >= 0 and c.predicted[0, 0] > 0


def _sweeps():
    full = np.concatenate([[5e-324, 1e-320, FTINY], np.logspace(-307, 308, 3001), [FMAX / 4, FMAX / 2, FMAX]])
    unit = np.concatenate([[5e-324, 1e-320, FTINY], np.logspace(-307, -1e-16, 2000), 1 - np.logspace(-1, -16, 500),
                           [np.nextafter(1.0, 0.0)]])
    unit = unit[(unit > 0) & (unit < 1)]
    g = np.concatenate([[5e-324, 1e-300], np.logspace(-300, 308, 121), [FMAX / 4, FMAX / 2, FMAX]])
    A, B = np.meshgrid(g, g)
    dl = np.logspace(-3, 3, 61)
    fr = np.linspace(1e-9, 0.999, 50)
    D, Fr = np.meshgrid(dl, fr)
    hi = np.minimum(4 * D, 1 / D)
    bw = np.array([bandwidth_sup(x) for x in dl])
    return {
        "from_snr": lambda: ab.from_snr(full[full <= R_OK]),
        "from_tracking_index": lambda: ab.from_tracking_index(full[full <= LAM_OK]),
        "from_tracking_error": lambda: ab.from_tracking_error(unit[unit >= RATIO_OK]),
        "analyze": lambda: ab.analyze(A, B),
        "from_natural_frequency": lambda: ab.from_natural_frequency(Fr * hi, 1.0, D),
        "from_bandwidth": lambda: ab.from_bandwidth(Fr * bw, D),
    }


@pytest.mark.parametrize("name", list(_sweeps().keys()))
def test_wide_vectorised_sweep_no_nan(name):
    """Deterministic vectorised sweeps over the whole positive float range
    (subnormals to DBL_MAX; ratio over (0, 1); deterministic designs over the
    stable range): no NaN anywhere."""
    assert_no_nan(_sweeps()[name](), f"{name} sweep")


@pytest.mark.parametrize("make,name", [
    (lambda: ab.from_snr(R_BAD), "r"),
    (lambda: ab.from_snr(FMAX), "r"),
    (lambda: ab.from_tracking_index(LAM_BAD), "lam"),
    (lambda: ab.from_tracking_index(8.98846567431158e307), "lam"),
    (lambda: ab.from_tracking_index(FMAX), "lam"),
    (lambda: ab.from_noise(1e300, 1e-8, 1.0), "sigma_w"),
    (lambda: ab.from_tracking_error(5e-324), "ratio"),
    (lambda: ab.from_tracking_error(RATIO_BAD), "ratio"),
    (lambda: ab.from_snr(np.array([1.0, R_BAD])), "r"),
])
def test_unrepresentable_kalman_designs_are_rejected(make, name):
    """Inputs whose Kalman gains round onto the stability boundary in float64."""
    with pytest.raises(ValueError, match=name_re(name)) as ei:
        make()
    assert "representable" in str(ei.value)


@pytest.mark.parametrize("make,label", [
    (lambda: ab.from_snr(R_OK), "from_snr(1e30)"),
    (lambda: ab.from_tracking_index(LAM_OK), "from_tracking_index(2e15)"),
    (lambda: ab.from_tracking_error(RATIO_OK), "from_tracking_error(1e-160)"),
    (lambda: ab.from_tracking_error(np.nextafter(1.0, 0.0)), "from_tracking_error(1 - eps/2)"),
    (lambda: ab.analyze(2.9961552247705263e307, 2.9961552247705263e307), "analyze(DBL_MAX/6, DBL_MAX/6)"),
    (lambda: ab.analyze(0.5, 1e308), "analyze(0.5, 1e308)"),
    (lambda: ab.analyze(1e308, 0.5), "analyze(1e308, 0.5)"),
], ids=["r-1e30", "lam-2e15", "ratio-1e-160", "ratio-near-1", "analyze-max6", "analyze-beta-1e308",
        "analyze-alpha-1e308"])
def test_no_nan_extreme_regressions(make, label):
    """Finite, documented-valid inputs found (by the sweeps above) to produce NaN."""
    assert_no_nan(make(), label)


# ---------------------------------------------------------------------------
# inputs are not modified; strided / non-contiguous inputs give the same result
# ---------------------------------------------------------------------------
def _array_inputs():
    rng = np.random.default_rng(5)
    return {
        "from_snr": (ab.from_snr, [10 ** rng.uniform(-6, 6, (4, 3))]),
        "from_noise": (ab.from_noise, [rng.uniform(0.5, 5, (4, 3)), rng.uniform(1, 50, (3,)), np.array(0.1)]),
        "from_tracking_index": (ab.from_tracking_index, [rng.uniform(0.01, 5, (4, 3))]),
        "from_tracking_error": (ab.from_tracking_error, [rng.uniform(0.01, 0.99, (4, 3))]),
        "from_bandwidth": (ab.from_bandwidth, [rng.uniform(0.01, 0.2, (4, 3)), rng.uniform(0.5, 0.7, (4, 1))]),
        "from_natural_frequency": (ab.from_natural_frequency, [rng.uniform(0.1, 5, (4, 3)), np.array([0.1, 0.2, 0.05]), np.array(0.6)]),
        "analyze": (ab.analyze, [rng.uniform(0.1, 0.9, (4, 3)), rng.uniform(0.01, 0.5, (4, 3))]),
        "error_covariance": (ab.error_covariance, [rng.uniform(0.1, 0.9, (4, 3)), rng.uniform(0.01, 0.5, (4, 3)), rng.uniform(0, 2, (4, 3))]),
    }


def _outputs(res):
    if isinstance(res, ab.ErrorCovariance):
        return [res.filtered, res.predicted]
    out = [np.asarray(getattr(res, f)) for f in FLOAT_FIELDS]
    out += [res.covariance_filtered, res.covariance_predicted, res.poles]
    out += [np.asarray(v) for v in (*res.variance_reduction, *res.lag)]
    return out


@pytest.mark.parametrize("cname", list(_array_inputs().keys()))
def test_inputs_not_modified(cname):
    """Input arrays (float64, float32, int, non-contiguous) are unchanged after the call."""
    f, args = _array_inputs()[cname]
    for conv in (lambda a: a, lambda a: a.astype(np.float32), lambda a: np.asfortranarray(a)):
        inputs = [conv(np.array(a)) for a in args]
        copies = [a.copy() for a in inputs]
        f(*inputs)
        for a, c in zip(inputs, copies):
            np.testing.assert_array_equal(a, c)
            assert a.dtype == c.dtype
    # integer inputs where integers are meaningful
    if cname == "from_noise":
        ints = [np.array([[3, 4, 5]]), np.array([30, 40, 50]), np.array(1)]
        copies = [a.copy() for a in ints]
        f(*ints)
        for a, c in zip(ints, copies):
            np.testing.assert_array_equal(a, c)
            assert a.dtype == c.dtype


@pytest.mark.parametrize("cname", list(_array_inputs().keys()))
def test_strided_and_fortran_inputs_match_contiguous(cname):
    """Transposed (Fortran-order), reversed and step-sliced views give exactly the
    results of their contiguous copies."""
    f, args = _array_inputs()[cname]
    big = [np.repeat(np.asarray(a)[..., None], 2, axis=-1)[..., ::2] if np.ndim(a) else a for a in args]
    views = {
        "step": big,
        "transposed": [np.asarray(a).T.copy().T if np.ndim(a) == 2 else a for a in args],
        "reversed": [np.asarray(a)[::-1] if np.ndim(a) else a for a in args],
    }
    for vname, vargs in views.items():
        contig = [np.ascontiguousarray(a) for a in vargs]
        r1 = _outputs(f(*vargs))
        r2 = _outputs(f(*contig))
        for x, y in zip(r1, r2):
            np.testing.assert_array_equal(x, y, err_msg=f"{cname} {vname}")
