"""Bad input: clear ValueError/TypeError, no crash, input never modified.

Accepted measurement dtypes: float32 and float64 in native byte order
(documented in FixedGainFilter.run); everything else is a TypeError.
"""

from __future__ import annotations

import numpy as np
import pytest

import filterref as fr
from abkit import AlphaBetaFilter, AlphaBetaGammaFilter, FilterState, FixedGainFilter, Tracker

AB = AlphaBetaFilter(0.5, 0.2, 1.0)


def _singer():
    T = 0.5
    Phi = fr.singer_phi(T, 0.3)
    H = np.array([[1.0, 0, 0], [0, 1.0, 0]])
    K = fr.dare_gain(Phi, H, np.diag([0.01, 0.02, 0.1]), np.diag([1.0, 0.5]))
    return FixedGainFilter(Phi, H, K, T)


SINGER = _singer()


# ---------------------------------------------------------------------------
# shapes
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("shape", [(), (2, 3, 4), (1, 1, 1, 1), (2, 5, 1)])
def test_wrong_ndim_scalar(shape):
    with pytest.raises(ValueError):
        AB.run(np.zeros(shape))
    with pytest.raises(ValueError):
        AB.smooth(np.zeros(shape))


@pytest.mark.parametrize("shape", [(), (10,), (10, 1), (10, 3), (2, 10, 1), (2, 10, 3), (2, 2, 10, 2)])
def test_wrong_shape_vector(shape):
    with pytest.raises(ValueError):
        SINGER.run(np.zeros(shape), init="first")


def test_measurement_dimension_mismatch_message():
    with pytest.raises(ValueError, match="H has 2 rows"):
        SINGER.run(np.zeros((3, 10, 3)), init="first")


# ---------------------------------------------------------------------------
# dtypes
# ---------------------------------------------------------------------------
BAD_DTYPES = [np.int8, np.int32, np.int64, np.uint16, np.bool_, np.float16, np.complex64, np.complex128, object, ">f8", "<f4" if np.little_endian is False else ">f4", "U3", "M8[s]"]
if np.dtype(np.longdouble) != np.dtype(np.float64):
    BAD_DTYPES.append(np.longdouble)


@pytest.mark.parametrize("dtype", BAD_DTYPES, ids=str)
def test_rejected_dtypes_scalar(dtype):
    z = np.zeros((2, 5)).astype(dtype)
    with pytest.raises(TypeError):
        AB.run(z)
    with pytest.raises(TypeError):
        AB.smooth(z)


@pytest.mark.parametrize("dtype", [np.int64, np.complex128, object, np.float16], ids=str)
def test_rejected_dtypes_vector(dtype):
    with pytest.raises(TypeError):
        SINGER.run(np.zeros((2, 5, 2)).astype(dtype), init="first")


def test_rejected_python_ints_and_complex():
    with pytest.raises(TypeError):
        AB.run([1, 2, 3])
    with pytest.raises(TypeError):
        AB.run([1 + 1j, 2.0])
    with pytest.raises(TypeError):
        AB.run(["a", "b"])


def test_accepted_float_list():
    r = AB.run([0.0, 1.0, 2.0])
    assert r.states.dtype == np.float64
    assert np.array_equal(r.states, AB.run(np.array([0.0, 1.0, 2.0])).states, equal_nan=True)


# ---------------------------------------------------------------------------
# gains and models
# ---------------------------------------------------------------------------
UNSTABLE_AB = [(0.0, 0.1), (-0.1, 0.1), (0.5, 0.0), (0.5, -0.1), (1.5, 1.0), (1.9, 0.5), (2.5, 0.1), (0.1, 4.0)]


@pytest.mark.parametrize("a,b", UNSTABLE_AB)
def test_unstable_alphabeta(a, b):
    with pytest.raises(ValueError, match="unstable"):
        AlphaBetaFilter(a, b, 1.0)
    with pytest.raises(ValueError, match="unstable"):
        AlphaBetaFilter(np.array([0.5, a]), np.array([0.2, b]), 1.0)
    f = AlphaBetaFilter(a, b, 1.0, allow_unstable=True)
    z = np.array([0.0, 1.0, 2.5, np.nan, 3.0, 4.2, 5.0, 6.5, 7.0, 8.0])
    s, res, _ = fr.run_ref(z, fr.ab_model(a, b, 1.0), "two-point")
    fr.assert_states_close(f.run(z).states, s)


def test_unstable_alphabetagamma():
    T = 1.0
    a, b, g = 0.5, 0.5, 3.0
    assert fr.closed_loop_radius(fr.abg_model(a, b, g, T))[0] >= 1
    with pytest.raises(ValueError, match="unstable"):
        AlphaBetaGammaFilter(a, b, g, T)
    f = AlphaBetaGammaFilter(a, b, g, T, allow_unstable=True)
    z = np.linspace(0, 5, 12)
    s, _, _ = fr.run_ref(z, fr.abg_model(a, b, g, T), "first")
    fr.assert_states_close(f.run(z, init="first").states, s)
    # stable under one convention, unstable under another
    a, b, g = 0.5, 0.2, 0.9
    rs = {c: fr.closed_loop_radius(fr.abg_model(a, b, g, T, c))[0] for c in fr.ABG_C}
    for c, rho in rs.items():
        if rho < 1:
            AlphaBetaGammaFilter(a, b, g, T, convention=c)
        else:
            with pytest.raises(ValueError):
                AlphaBetaGammaFilter(a, b, g, T, convention=c)


def test_unstable_fixed_gain():
    Phi = [[1.0, 1.0], [0.0, 1.0]]
    with pytest.raises(ValueError, match="unstable"):
        FixedGainFilter(Phi, [[1.0, 0.0]], [[0.0], [0.0]])
    with pytest.raises(ValueError, match="unstable"):
        FixedGainFilter(Phi, [[1.0, 0.0]], [[2.5], [1.0]])
    FixedGainFilter(Phi, [[1.0, 0.0]], [[2.5], [1.0]], allow_unstable=True)


@pytest.mark.parametrize(
    "kw",
    [
        dict(alpha=np.nan, beta=0.1, T=1.0),
        dict(alpha=0.5, beta=np.inf, T=1.0),
        dict(alpha=0.5, beta=0.1, T=0.0),
        dict(alpha=0.5, beta=0.1, T=-1.0),
        dict(alpha=0.5, beta=0.1, T=np.nan),
        dict(alpha=np.ones((2, 2)) * 0.5, beta=0.1, T=1.0),
        dict(alpha=np.array([0.5, 0.4]), beta=np.array([0.1, 0.1, 0.1]), T=1.0),
    ],
)
def test_bad_alphabeta_parameters(kw):
    with pytest.raises(ValueError):
        AlphaBetaFilter(**kw)


def test_bad_parameter_types():
    with pytest.raises(TypeError):
        AlphaBetaFilter("0.5", 0.1, 1.0)
    with pytest.raises(TypeError):
        AlphaBetaFilter(0.5 + 0j, 0.1, 1.0)
    with pytest.raises(TypeError):
        FixedGainFilter([[1.0]], [[1.0]], [[0.5 + 1j]])


def test_bad_convention():
    with pytest.raises(ValueError, match="convention"):
        AlphaBetaGammaFilter(0.5, 0.2, 0.05, 1.0, convention="bar-shalom")


@pytest.mark.parametrize(
    "phi,h,k",
    [
        (np.eye(2), np.zeros((1, 3)), np.zeros((2, 1))),  # H width
        (np.eye(2), np.zeros((3, 2)), np.zeros((2, 3))),  # m = 3
        (np.eye(2), np.zeros((1, 2)), np.zeros((3, 1))),  # K rows
        (np.eye(7), np.eye(7)[:1], np.zeros((7, 1))),  # n = 7
        (np.zeros((2, 3)), np.zeros((1, 3)), np.zeros((3, 1))),  # Phi not square
        (np.full((2, 2), np.nan), np.zeros((1, 2)), np.zeros((2, 1))),
        (np.stack([np.eye(2) * 0.5] * 3), np.zeros((2, 1, 2)), np.zeros((2, 1))),  # per-track counts differ
    ],
)
def test_bad_fixed_gain_shapes(phi, h, k):
    with pytest.raises(ValueError):
        FixedGainFilter(phi, h, k)


# ---------------------------------------------------------------------------
# init, state, params, threads, lag
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("init", ["", "two_point", "First", "kalman", "2-point"])
def test_bad_init_string(init):
    with pytest.raises(ValueError, match="init"):
        AB.run(np.zeros((2, 5)), init=init)
    with pytest.raises(ValueError, match="init"):
        AB.smooth(np.zeros((2, 5)), init=init)


@pytest.mark.parametrize("x0", [np.zeros(3), np.zeros((3, 2)), np.zeros((2, 3)), np.array([np.nan, 0.0]), np.zeros((1, 2, 2))])
def test_bad_init_array(x0):
    with pytest.raises(ValueError):
        AB.run(np.zeros((2, 5)), init=x0)


def test_init_array_bad_type():
    with pytest.raises(TypeError):
        AB.run(np.zeros((2, 5)), init=np.array([1 + 1j, 0]))


def test_two_point_needs_kinematic_state():
    with pytest.raises(ValueError, match="two-point"):
        SINGER.run(np.zeros((2, 5, 2)))
    with pytest.raises(ValueError, match="two-point"):
        FixedGainFilter([[0.9, 0.0], [0.0, 0.9]], [[0.0, 1.0]], [[0.0], [0.5]]).run(np.zeros(5))


def test_state_from_another_shape():
    r = AB.run(np.zeros((3, 5)))
    with pytest.raises(ValueError, match="state"):
        AB.run(np.zeros((4, 5)), state=r.state)
    with pytest.raises(ValueError, match="state"):
        AB.run(np.zeros(5), state=r.state)
    abg = AlphaBetaGammaFilter(0.5, 0.2, 0.05, 1.0)
    with pytest.raises(ValueError, match="state"):
        abg.run(np.zeros((3, 5)), state=r.state)
    with pytest.raises(TypeError):
        AB.run(np.zeros((3, 5)), state=r.state.x)
    with pytest.raises(TypeError):
        AB.run(np.zeros((3, 5)), state={"x": r.state.x})
    # a single-track state continues a single-track (1-D) run and a 1-track 2-D run
    r1 = AB.run(np.arange(5.0))
    AB.run(np.arange(5.0), state=r1.state)
    AB.run(np.arange(5.0)[None], state=r1.state)


def test_per_track_parameter_count_mismatch():
    f = AlphaBetaFilter(np.array([0.5, 0.4, 0.3]), 0.1, 1.0)
    with pytest.raises(ValueError):
        f.run(np.zeros((2, 5)))
    with pytest.raises(ValueError):
        f.run(np.zeros(5))
    f.run(np.zeros((3, 5)))
    with pytest.raises(ValueError):
        AB.smooth(np.zeros((2, 5)), smoother_gain=np.zeros((3, 2, 2)))


@pytest.mark.parametrize("threads", [0, -1, True, 1.5, "2"])
def test_bad_threads(threads):
    with pytest.raises(ValueError):
        AB.run(np.zeros((2, 5)), threads=threads)


@pytest.mark.parametrize("lag", [-1, 1.5, True, "3"])
def test_bad_lag(lag):
    with pytest.raises(ValueError):
        AB.smooth(np.zeros((2, 5)), lag=lag)


def test_bad_smoother_arguments():
    z = np.zeros((2, 5))
    with pytest.raises(ValueError):
        SINGER.smooth(np.zeros((2, 5, 2)), init="first")  # no model for the default gain
    with pytest.raises(ValueError):
        AB.smooth(z, smoother_gain=np.eye(3))
    with pytest.raises(ValueError):
        AB.smooth(z, smoother_gain=np.full((2, 2), np.nan))
    with pytest.raises(ValueError):
        AB.smooth(z, Q=np.eye(2))  # R missing
    with pytest.raises(ValueError):
        AB.smooth(z, Q=np.eye(2), R=[[1.0]], smoother_gain=np.eye(2))
    with pytest.raises(ValueError):
        AB.smooth(z, Q=np.eye(3), R=[[1.0]])
    with pytest.raises(ValueError):
        AlphaBetaFilter(1.2, 0.3, 1.0).smooth(z)  # alpha >= 1: no Kalman-equivalent model
    AlphaBetaFilter(1.2, 0.3, 1.0).smooth(z, smoother_gain=np.eye(2) * 0.1)


def test_covariances_bad():
    with pytest.raises(ValueError):
        AB.covariances(np.eye(3), [[1.0]])
    with pytest.raises(ValueError):
        AB.covariances(sigma_w=1.0)
    with pytest.raises(ValueError):
        AlphaBetaFilter(np.array([0.5, 0.4]), 0.1, 1.0).covariances(np.eye(2), [[1.0]])
    with pytest.raises(ValueError):
        AlphaBetaFilter(1.5, 1.0, 1.0, allow_unstable=True).covariances(np.eye(2), [[1.0]])


# ---------------------------------------------------------------------------
# input never modified
# ---------------------------------------------------------------------------
def _snapshot(*arrays):
    return [(a.copy(), a.flags.writeable, a.strides) for a in arrays]


def _unchanged(arrays, snaps):
    for a, (c, w, s) in zip(arrays, snaps):
        assert np.array_equal(a, c, equal_nan=True) and a.flags.writeable == w and a.strides == s


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_input_never_modified(dtype):
    rng = np.random.default_rng(1)
    z = fr.with_nans(rng, fr.kinematic_z(rng, 4, 80, 0.5), "mixed").astype(dtype)
    zv = np.asfortranarray(z)[:, ::-1]
    x0 = rng.normal(size=(4, 2))
    A = np.array([[0.5, 0.1], [0.0, 0.4]])
    arrays = [z, zv, x0, A]
    snaps = _snapshot(*arrays)
    f = AlphaBetaFilter(np.full(4, 0.5), 0.2, 0.5)
    for zz in (z, zv):
        f.run(zz, return_residuals=True)
        f.run(zz, init=x0)
        f.run(zz, init="first", out=np.empty((2, 4, 80), dtype=dtype))
        f.smooth(zz, smoother_gain=A)
        f.smooth(zz, lag=3, return_residuals=True)
        r = f.run(zz[:, :40])
        f.run(zz[:, 40:], state=r.state)
        Tracker(f, n_tracks=4).update(zz)
        for bad in (np.empty((2, 4, 79), dtype=dtype), np.empty((2, 4, 80), dtype=np.float16)):
            with pytest.raises(ValueError):
                f.run(zz, out=bad)
    _unchanged(arrays, snaps)
    zm = fr.with_nans(rng, fr.kinematic_z(rng, 3, 50, 0.5, m=2), "random").astype(dtype)
    sm = _snapshot(zm)
    SINGER.run(zm, init="first", return_residuals=True)
    SINGER.smooth(zm, init="first", smoother_gain=np.eye(3) * 0.2, lag=2)
    _unchanged([zm], sm)


def test_no_crash_on_extreme_values():
    """huge measurements: no crash, the reference semantics hold (NaN is the
    only 'missed'); an infinite measurement would poison the track, so it is
    a ValueError naming z, the track and the sample (issue 8)."""
    z = np.array([0.0, 1.0, 1e300, 3.0, -1e300, 5.0])
    r = AB.run(z, return_residuals=True)
    s, res, _ = fr.run_ref(z, fr.ab_model(0.5, 0.2, 1.0))
    assert np.array_equal(np.isnan(r.states), np.isnan(s))
    zi = np.array([0.0, 1.0, np.inf, 3.0])
    with pytest.raises(ValueError, match=r"z must be finite or NaN .*track 0, sample 2"):
        AB.run(zi)
