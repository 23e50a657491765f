"""Ragged batches (Arrow offsets) and multi-axis positions."""

from __future__ import annotations

import numpy as np
import pytest

from abkit import AlphaBetaFilter, AlphaBetaGammaFilter, FixedGainFilter, singer

SW, SV = 3.2, 32.0


def ragged(rng, lens, m=None, nan=0.1, dtype=np.float64):
    off = np.concatenate([[0], np.cumsum(lens)]).astype(np.int64)
    N = int(off[-1])
    t = np.empty(N)
    for a, b in zip(off[:-1], off[1:]):
        t[a:b] = np.cumsum(rng.exponential(0.3, b - a)) + rng.uniform(-50, 50)
    shape = (N,) if m is None else (N, m)
    z = (np.cumsum(rng.normal(0, 1, shape), axis=0) + rng.normal(0, 0.5, shape)).astype(dtype)
    z[rng.random(N) < nan] = np.nan
    return off, t, z


FILTERS = {
    "ab-design": lambda: AlphaBetaFilter.from_noise(SW, SV, 0.3),
    "ab-fixed": lambda: AlphaBetaFilter(0.5, 0.2, 0.3),
    "abg-design": lambda: AlphaBetaGammaFilter.from_noise(0.0, 0.0, 0.01, 1.0, 0.3),
    "abg-fixed": lambda: AlphaBetaGammaFilter(0.5, 0.2, 0.02, 0.3),
    "singer": lambda: singer.tracking_filter(0.3, tau=10.0, sigma_m=1.0, sigma_pos=1.0),
}


@pytest.mark.parametrize("name", sorted(FILTERS))
@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_ragged_with_t_is_bit_identical_to_each_track_alone(name, dtype):
    rng = np.random.default_rng(0)
    lens = [0, 1, 2, 3, 57, 0, 1000, 5]
    off, t, z = ragged(rng, lens, dtype=dtype)
    f = FILTERS[name]()
    r = f.run(z, t=t, offsets=off, max_gap=2.0, return_residuals=True)
    assert r.states.shape == (f.n, z.size) and r.states.dtype == dtype
    assert np.array_equal(r.offsets, off) and r.n_dropped.shape == (len(lens),)
    for i, (a, b) in enumerate(zip(off[:-1], off[1:])):
        one = f.run(z[a:b], t=t[a:b], max_gap=2.0, return_residuals=True)
        np.testing.assert_array_equal(r.states[:, a:b], one.states, err_msg=f"track {i}")
        np.testing.assert_array_equal(r.residuals[a:b], one.residuals)
        assert r.n_restarts[i] == one.n_restarts[0]


@pytest.mark.parametrize("name", ["ab-fixed", "abg-fixed"])
def test_ragged_without_t_equals_the_rectangular_kernel(name):
    rng = np.random.default_rng(1)
    f = FILTERS[name]()
    z = np.cumsum(rng.normal(0, 1, (5, 300)), axis=1)
    z[rng.random(z.shape) < 0.1] = np.nan
    rect = f.run(z, return_residuals=True)
    flat = f.run(z.reshape(-1), offsets=np.arange(6) * 300, return_residuals=True)
    np.testing.assert_allclose(flat.states.reshape(rect.states.shape), rect.states, rtol=1e-12, atol=1e-12, equal_nan=True)
    np.testing.assert_allclose(flat.residuals.reshape(z.shape), rect.residuals, rtol=1e-12, atol=1e-10, equal_nan=True)


def test_general_vector_filter_ragged_equals_rectangular():
    rng = np.random.default_rng(2)
    phi = [[1.0, 1.0], [0.0, 1.0]]
    f = FixedGainFilter(phi, np.eye(2), [[0.5, 0.1], [0.05, 0.4]])
    z = rng.normal(0, 1, (3, 40, 2))
    z[0, 5, 1] = np.nan
    rect = f.run(z, init="first")
    flat = f.run(z.reshape(-1, 2), offsets=[0, 40, 80, 120], init="first")
    np.testing.assert_allclose(flat.states.reshape(rect.states.shape), rect.states, rtol=1e-12, atol=1e-12, equal_nan=True)


def test_rectangular_with_t_equals_flat_with_offsets():
    rng = np.random.default_rng(3)
    t = np.cumsum(rng.exponential(1.0, (4, 50)), axis=1)
    z = rng.normal(0, 1, (4, 50))
    f = FILTERS["ab-design"]()
    a = f.run(z, t=t)
    b = f.run(z.reshape(-1), t=t.reshape(-1), offsets=np.arange(5) * 50)
    np.testing.assert_array_equal(a.states.reshape(2, -1), b.states)
    # non-contiguous views, no copy needed
    zt = np.asfortranarray(z)
    np.testing.assert_array_equal(f.run(zt, t=np.asfortranarray(t)).states, a.states)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
@pytest.mark.parametrize("init", ["two-point", "first"])
@pytest.mark.parametrize("n_long", [19, 300])
def test_long_ragged_tracks_without_t_equal_each_track_alone(dtype, init, n_long):
    # Long tracks of close lengths (one flat-kernel region each); 300 of
    # them make float64 outputs of more than 8 MiB (streamed stores; the
    # AVX2 kernel may then reorder its regions). Equal to each track alone,
    # bit for bit, also continued from the first half's states.
    rng = np.random.default_rng(11)
    lens = np.concatenate([rng.integers(2048, 2300, n_long), [5003, 0, 7, 100, 2047]])
    rng.shuffle(lens)
    off, _, z = ragged(rng, lens, nan=0.05, dtype=dtype)
    j = int(np.argmax(lens >= 2048))
    z[off[j] : off[j] + 5] = np.nan  # a long track starting with NaN
    f = AlphaBetaFilter(0.5, 0.2, 0.1)
    r = f.run(z, offsets=off, init=init)
    half = [(a + b) // 2 for a, b in zip(off[:-1], off[1:])]
    i1 = np.concatenate([np.arange(a, m) for a, m in zip(off[:-1], half)])
    i2 = np.concatenate([np.arange(m, b) for m, b in zip(half, off[1:])])
    o1 = np.concatenate([[0], np.cumsum([m - a for a, m in zip(off[:-1], half)])]).astype(np.int64)
    o2 = np.concatenate([[0], np.cumsum([b - m for m, b in zip(half, off[1:])])]).astype(np.int64)
    r1 = f.run(z[i1], offsets=o1, init=init)
    r2 = f.run(z[i2], offsets=o2, init=init, state=r1.state)
    np.testing.assert_array_equal(r2.states, r.states[:, i2])
    for i, (a, b) in enumerate(zip(off[:-1], off[1:])):
        one = f.run(z[a:b], init=init)
        np.testing.assert_array_equal(r.states[:, a:b], one.states, err_msg=f"track {i}")
        np.testing.assert_array_equal(r.state._packed[i], one.state._packed[0], err_msg=f"state of track {i}")


def test_threads_do_not_change_results():
    rng = np.random.default_rng(4)
    lens = rng.integers(10, 3000, 60)
    off, t, z = ragged(rng, lens)
    f = FILTERS["ab-design"]()
    a = f.run(z, t=t, offsets=off, threads=1)
    b = f.run(z, t=t, offsets=off)
    c = f.run(z, t=t, offsets=off, threads=3)
    np.testing.assert_array_equal(a.states, b.states)
    np.testing.assert_array_equal(a.states, c.states)


def test_ragged_streaming_equals_one_call():
    rng = np.random.default_rng(5)
    lens = [30, 0, 12, 50]
    off, t, z = ragged(rng, lens)
    f = FILTERS["ab-design"]()
    full = f.run(z, t=t, offsets=off)
    # split every track at its middle
    mid = [(a + b) // 2 for a, b in zip(off[:-1], off[1:])]
    i1 = np.concatenate([np.arange(a, m) for a, m in zip(off[:-1], mid)])
    i2 = np.concatenate([np.arange(m, b) for m, b in zip(mid, off[1:])])
    o1 = np.concatenate([[0], np.cumsum([m - a for a, m in zip(off[:-1], mid)])])
    o2 = np.concatenate([[0], np.cumsum([b - m for m, b in zip(mid, off[1:])])])
    r1 = f.run(z[i1], t=t[i1], offsets=o1)
    r2 = f.run(z[i2], t=t[i2], offsets=o2, state=r1.state)
    np.testing.assert_array_equal(r1.states, full.states[:, i1])
    np.testing.assert_array_equal(r2.states, full.states[:, i2])


@pytest.mark.parametrize(
    "off, msg",
    [
        ([1, 3, 5], "offsets must start at 0, got offsets\\[0\\] = 1"),
        ([0, 3, 2, 5], "non-decreasing: offsets\\[2\\] = 2 < offsets\\[1\\] = 3"),
        ([0, 3, 4], "must end at the number of samples of z \\(5\\), got offsets\\[-1\\] = 4"),
        ([[0, 5]], "1-D array"),
    ],
)
def test_bad_offsets(off, msg):
    f = AlphaBetaFilter(0.5, 0.2, 1.0)
    with pytest.raises(ValueError, match=msg):
        f.run(np.ones(5), offsets=off)


def test_bad_offsets_types_and_shapes():
    f = AlphaBetaFilter(0.5, 0.2, 1.0)
    with pytest.raises(TypeError, match="offsets must be an integer array"):
        f.run(np.ones(5), offsets=[0.0, 5.0])
    with pytest.raises(ValueError, match="with offsets, z must have shape"):
        f.run(np.ones((2, 5)), offsets=[0, 5])
    with pytest.raises(ValueError, match="t must have the sample shape"):
        f.run(np.ones(5), offsets=[0, 5], t=np.arange(4.0))
    with pytest.raises(ValueError, match="track 1, sample 1: t=1"):
        f.run(np.ones(5), offsets=[0, 2, 5], t=[0.0, 1.0, 2.0, 1.0, 3.0])


def test_per_track_params_with_offsets():
    f = AlphaBetaFilter([0.5, 0.3], [0.2, 0.1], 1.0)
    z = np.arange(7.0)
    r = f.run(z, offsets=[0, 3, 7], init="first")
    np.testing.assert_allclose(r.states[:, :3], AlphaBetaFilter(0.5, 0.2, 1.0).run(z[:3], init="first").states, rtol=1e-12)
    np.testing.assert_allclose(r.states[:, 3:], AlphaBetaFilter(0.3, 0.1, 1.0).run(z[3:], init="first").states, rtol=1e-12)
    with pytest.raises(ValueError, match="2 per-track parameter sets"):
        f.run(z, offsets=[0, 7])


def test_out_buffer_with_offsets():
    f = AlphaBetaFilter(0.5, 0.2, 1.0)
    z = np.arange(7.0)
    o = np.empty((2, 7))
    r = f.run(z, offsets=[0, 3, 7], out=o)
    assert r.states is o


@pytest.mark.parametrize("d", [2, 3])
def test_axes_equal_per_axis_runs(d):
    rng = np.random.default_rng(6)
    off, t, z = ragged(rng, [40, 3, 100], m=d)
    f = FILTERS["ab-design"]()
    r = f.run(z, axes=d, t=t, offsets=off, return_residuals=True)
    assert r.position.shape == z.shape and r.residuals.shape == z.shape
    for a in range(d):
        one = f.run(z[:, a], t=t, offsets=off, return_residuals=True)
        np.testing.assert_array_equal(r.states[..., a], one.states)
        np.testing.assert_array_equal(r.residuals[..., a], one.residuals)
    # rectangular tracks with axes, and streaming with the axes state
    zr = rng.normal(0, 1, (2, 30, d))
    tr = np.cumsum(rng.exponential(1, (2, 30)), axis=1)
    full = f.run(zr, axes=d, t=tr)
    assert full.position.shape == (2, 30, d)
    r1 = f.run(zr[:, :10], axes=d, t=tr[:, :10])
    r2 = f.run(zr[:, 10:], axes=d, t=tr[:, 10:], state=r1.state)
    np.testing.assert_array_equal(np.concatenate([r1.states, r2.states], axis=2), full.states)
    with pytest.raises(ValueError, match="axes="):
        f.run(zr[:, 10:, 0], t=tr[:, 10:], state=r1.state)


def test_axes_with_vector_measurements():
    f = FixedGainFilter([[1.0, 1.0], [0.0, 1.0]], np.eye(2), [[0.5, 0.1], [0.05, 0.4]])
    rng = np.random.default_rng(7)
    z = rng.normal(0, 1, (30, 3, 2))
    r = f.run(z, axes=3, init="first")
    assert r.states.shape == (2, 30, 3)
    for a in range(3):
        np.testing.assert_array_equal(r.states[..., a], f.run(z[:, a, :], offsets=[0, 30], init="first").states)


def test_bad_axes():
    f = AlphaBetaFilter(0.5, 0.2, 1.0)
    with pytest.raises(ValueError, match="axes must be 2, 3 or None"):
        f.run(np.ones((5, 4)), axes=4)
    with pytest.raises(ValueError, match="must end with the spatial axis"):
        f.run(np.ones((5, 3)), axes=2)


@pytest.mark.parametrize("name", ["ab-design", "ab-fixed"])
def test_interleaved_tracks_with_duplicates_and_gaps_equal_each_track_alone(name):
    # Many tracks: the alpha-beta kernel runs running stretches of several
    # tracks interleaved; duplicates, gaps, missed samples and start-ups hand
    # single samples to the general code. Each track must still equal its
    # own run bit for bit.
    rng = np.random.default_rng(11)
    lens = rng.integers(0, 400, 60)
    off, t, z = ragged(rng, lens, nan=0.2)
    t = np.round(t, 1)  # duplicates
    big = rng.random(t.size) < 0.01
    t = t + np.cumsum(np.where(big, 20.0, 0.0))  # gaps (per track still sorted but shifted)
    f = FILTERS[name]()
    kw = dict(max_gap=5.0, on_duplicate="drop", return_residuals=True)
    r = f.run(z, t=t, offsets=off, **kw)
    s = f.smooth(z, t=t, offsets=off, max_gap=5.0, on_duplicate="drop", lag=3)
    assert r.n_dropped.sum() > 0 and r.n_restarts.sum() > 0
    for i, (a, b) in enumerate(zip(off[:-1], off[1:])):
        one = f.run(z[a:b], t=t[a:b], **kw)
        np.testing.assert_array_equal(r.states[:, a:b], one.states, err_msg=f"track {i}")
        np.testing.assert_array_equal(r.residuals[a:b], one.residuals)
        assert (r.n_dropped[i], r.n_restarts[i]) == (one.n_dropped[0], one.n_restarts[0])
        one_s = f.smooth(z[a:b], t=t[a:b], max_gap=5.0, on_duplicate="drop", lag=3)
        np.testing.assert_array_equal(s.states[:, a:b], one_s.states)
    # streaming state after the call: equal to the single-track runs
    for i, (a, b) in enumerate(zip(off[:-1], off[1:])):
        one = f.run(z[a:b], t=t[a:b], **kw)
        np.testing.assert_array_equal(r.state._packed[i], one.state._packed[0])
