"""Bad input on the track-kernel paths (``run`` with ``t``, ``offsets`` or
``axes``; ``FeedTracker``; ``abkit.frame.filter``): a ``ValueError`` or
``TypeError`` that names the argument and the problem, raised before any
output is written, and the input left as it was.

These are the error branches a coverage run of the whole suite (session 21)
found unexercised; the messages are checked by their distinctive words.
"""

from __future__ import annotations

import numpy as np
import pytest

import abkit
from abkit import AlphaBetaFilter, FeedTracker

F = AlphaBetaFilter(0.5, 0.2, 0.1)
T2 = np.cumsum(np.ones((2, 5)), axis=1)


def test_integer_list_z_with_t_is_a_type_error():
    with pytest.raises(TypeError, match=r"z must be a float32 or float64 array, got int64"):
        F.run([[1, 2, 3, 4, 5], [1, 2, 3, 4, 5]], t=T2)


@pytest.mark.parametrize("threads", [0, -1, 1.5, True, "2"])
def test_bad_threads_with_t_names_threads(threads):
    with pytest.raises(ValueError, match=r"threads must be a positive integer or None"):
        F.run(np.zeros((2, 5)), t=T2, threads=threads)


@pytest.mark.parametrize("kw", [dict(t=T2), dict(offsets=[0, 5, 10])])
def test_per_track_T_with_t_or_offsets_is_refused(kw):
    f = AlphaBetaFilter([0.5, 0.4], [0.2, 0.1], [0.1, 0.2])
    z = np.zeros((2, 5)) if "t" in kw else np.zeros(10)
    with pytest.raises(ValueError, match=r"one sampling period T for all tracks \(the filter has per-track T\)"):
        f.run(z, **kw)


def test_axes_state_of_the_wrong_kind_or_axes():
    z2 = np.zeros((2, 5, 2))
    r2 = F.run(z2, axes=2)
    with pytest.raises(TypeError, match=r"state must be a FilterState \(result.state\), got ndarray"):
        F.run(z2, axes=2, state=np.zeros((4, 8)))
    with pytest.raises(ValueError, match=r"state is for axes=3, the call has axes=2"):
        F.run(z2, axes=2, state=F.run(np.zeros((2, 5, 3)), axes=3).state)
    with pytest.raises(ValueError, match=r"state is for axes=None, the call has axes=2"):
        F.run(z2, axes=2, state=F.run(np.zeros((2, 5))).state)
    # the matching state still continues
    assert F.run(z2, axes=2, state=r2.state).states.shape == (2, 2, 5, 2)


@pytest.mark.parametrize("path", ["offsets", "t", "rectangle"])
def test_overflowing_estimates_name_the_track(path):
    # z near the float64 limit with alternating signs: the residuals
    # overflow to inf; every path reports it instead of returning inf.
    z = np.array([[1.0, 2.0, 3.0, 4.0, 5.0], [1e308, -1e308, 1e308, -1e308, 1e308]])
    zc = z.copy()
    with pytest.raises(ValueError, match=r"the estimates of track 1 overflowed float64: z values up to 1e\+308"):
        if path == "offsets":
            F.run(z.ravel(), offsets=[0, 5, 10])
        elif path == "t":
            F.run(z, t=T2)
        else:
            F.run(z)
    assert np.array_equal(z, zc)


def test_overflow_allowed_when_unstable_filters_are():
    f = AlphaBetaFilter(0.5, 0.2, 0.1, allow_unstable=True)
    z = np.array([1e308, -1e308, 1e308, -1e308, 1e308])
    r = f.run(z, offsets=[0, 5])
    assert not np.all(np.isfinite(r.position))


def test_feed_tracker_refuses_a_kalman_transient_filter():
    fk = AlphaBetaFilter.from_noise(3.2, 32.0, 0.1, transient="kalman")
    with pytest.raises(ValueError, match=r"FeedTracker runs the steady-state filter: a filter with transient='kalman'"):
        FeedTracker(fk)


@pytest.mark.parametrize("init", [np.array([0.0, 1.0]), None, 2, "two_point"])
def test_feed_tracker_init_must_be_a_start_name(init):
    with pytest.raises(ValueError, match=r"init must be 'two-point' or 'first', got"):
        FeedTracker(F, init=init)


def test_frame_filter_refuses_a_kalman_transient_filter():
    pd = pytest.importorskip("pandas")
    fk = AlphaBetaFilter.from_noise(3.2, 32.0, 0.1, transient="kalman")
    df = pd.DataFrame({"id": [1, 1, 2, 2], "time": [0.0, 1.0, 0.0, 1.0], "x": [1.0, 2.0, 3.0, 4.0]})
    for kw in (dict(time="time"), dict()):
        with pytest.raises(ValueError, match=r"abkit.frame.filter runs the steady-state filter: a filter with transient='kalman'"):
            abkit.frame.filter(df, id="id", columns=["x"], filter=fk, **kw)


# ---------------------------------------------------------------------------
# smooth(..., offsets=, smoother_gain=): the track kernel's constant backward
# gain given by the caller (this path had no test before session 21).

def _smooth_case():
    f = AlphaBetaFilter.from_noise(3.2, 32.0, 0.1)
    rng = np.random.default_rng(21)
    z = np.cumsum(rng.normal(size=(3, 40)), axis=1) + rng.normal(size=(3, 40))
    z[1, 7] = np.nan
    return f, z


def test_smooth_offsets_with_a_given_gain_equals_the_rectangle():
    f, z = _smooth_case()
    a = 0.5 * f.smoother_gain()  # not the default: the given gain must be the one used
    rect = f.smooth(z, smoother_gain=a)
    flat = f.smooth(z.ravel(), offsets=[0, 40, 80, 120], smoother_gain=a)
    assert np.array_equal(rect.states.reshape(2, -1), flat.states, equal_nan=True)
    default = f.smooth(z.ravel(), offsets=[0, 40, 80, 120])
    assert not np.array_equal(default.states, flat.states, equal_nan=True)
    # one gain per track (3 parameter sets) also goes through
    fp = AlphaBetaFilter.from_noise([3.2, 3.2, 3.2], [32.0, 32.0, 32.0], 0.1)
    per = fp.smooth(z.ravel(), offsets=[0, 40, 80, 120], smoother_gain=np.stack([a[0]] * 3))
    assert np.array_equal(per.states, flat.states, equal_nan=True)


@pytest.mark.parametrize(
    "gain, match",
    [
        (np.eye(3), r"smoother_gain must be finite with shape \(2, 2\) or \(n_tracks, 2, 2\), got \(3, 3\)"),
        (np.full((2, 2), np.nan), r"smoother_gain must be finite"),
        (np.stack([np.eye(2)] * 2), r"smoother_gain has 2 gains for 3 parameter sets"),
    ],
)
def test_smooth_offsets_bad_smoother_gain(gain, match):
    f = AlphaBetaFilter.from_noise([3.2, 3.0, 2.8], [32.0, 32.0, 32.0], 0.1)
    z = np.zeros(30)
    with pytest.raises(ValueError, match=match):
        f.smooth(z, offsets=[0, 10, 20, 30], smoother_gain=gain)


def test_smooth_offsets_gain_and_model_not_both():
    f, z = _smooth_case()
    with pytest.raises(ValueError, match=r"give smoother_gain or \(Q, R\), not both"):
        f.smooth(z.ravel(), offsets=[0, 40, 80, 120], smoother_gain=f.smoother_gain(), Q=np.eye(2), R=np.eye(1))


def test_smooth_track_paths_refuse_a_kalman_transient():
    fk = AlphaBetaFilter.from_noise(3.2, 32.0, 0.1, transient="kalman")
    with pytest.raises(ValueError, match=r"transient='kalman' does not support t, offsets, axes"):
        fk.smooth(np.zeros(20), offsets=[0, 10, 20])


# ---------------------------------------------------------------------------
# Zero samples with timestamps (the Python fuzzer, session 21: rows of no
# samples made the track kernel divide by zero, a RuntimeError).

@pytest.mark.parametrize("n_tracks", [1, 2, 5])
@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_zero_samples_with_t_give_an_empty_result(n_tracks, dtype):
    z = np.zeros((n_tracks, 0), dtype=dtype)
    t = np.zeros((n_tracks, 0))
    for f in (F, AlphaBetaFilter.from_noise(3.2, 32.0, 0.1), abkit.AlphaBetaGammaFilter(0.5, 0.3, 0.05, 0.1)):
        r = f.run(z, t=t)
        assert r.states.shape == (f.n, n_tracks, 0) and r.states.dtype == dtype
        assert r.state.n_tracks == n_tracks and np.all(r.state.x == 0)
        # continuing from it is continuing from fresh tracks
        z2 = np.cumsum(np.ones((n_tracks, 6), dtype=dtype), axis=1)
        t2 = np.cumsum(np.ones((n_tracks, 6)), axis=1)
        assert np.array_equal(f.run(z2, t=t2, state=r.state).states, f.run(z2, t=t2).states, equal_nan=True)
    d = AlphaBetaFilter.from_noise(3.2, 32.0, 0.1)
    assert d.smooth(z, t=t).states.shape == (2, n_tracks, 0)
    r = F.run(np.zeros((n_tracks, 0, 2), dtype=dtype), t=t, axes=2)
    assert r.states.shape == (2, n_tracks, 0, 2)
