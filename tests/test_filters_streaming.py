"""Streaming (state=, Tracker), threads, out=, strides, dtypes and empty input.

Exactness claims here are *bit-identical* (``np.array_equal`` with NaN
positions): chunked runs vs one call, any thread count, any input layout vs a
contiguous copy, ``out=`` vs a fresh output. Values are also checked against
the independent reference (tests/filterref.py) at 1e-12 where they are new.
"""

from __future__ import annotations

import numpy as np
import pytest

import filterref as fr
from abkit import AlphaBetaFilter, AlphaBetaGammaFilter, FilterState, FixedGainFilter, Tracker


def same(a, b):
    return a.shape == b.shape and a.dtype == b.dtype and np.array_equal(a, b, equal_nan=True)


def _singer(T=0.5):
    Phi = fr.singer_phi(T, 0.3)
    H = np.array([[1.0, 0, 0], [0, 1.0, 0]])
    K = fr.dare_gain(Phi, H, np.diag([0.01, 0.02, 0.1]), np.diag([1.0, 0.5]))
    return FixedGainFilter(Phi, H, K, T), fr.general_model(Phi, H, K, T)


def _jerk4(T=1.0):
    Phi = np.array([[1, T, T * T / 2, T**3 / 6], [0, 1, T, T * T / 2], [0, 0, 1, T], [0, 0, 0, 1.0]])
    H = np.array([[1.0, 0, 0, 0]])
    K = fr.dare_gain(Phi, H, np.diag([0, 0, 0, 1e-3]), [[1.0]])
    return FixedGainFilter(Phi, H, K, T), fr.general_model(Phi, H, K, T)


def make(kind, ntr=5, N=300, dtype=np.float64, pattern="mixed", seed=0, per_track=False):
    """(filter, model, z, init, m) for a kind of filter."""
    rng = np.random.default_rng(fr.seed_of(kind, ntr, N, pattern, seed, per_track))
    T = 0.4
    m = 1
    init = "two-point"
    if kind == "ab":
        if per_track:
            a, b = fr.random_ab_gains(rng, ntr)
        else:
            a, b = fr.random_ab_gains(rng)
        f, model = AlphaBetaFilter(a, b, T), fr.ab_model(a, b, T)
    elif kind == "abg":
        a, b, g = fr.random_abg_gains(rng, "standard", T)
        f, model = AlphaBetaGammaFilter(a, b, g, T), fr.abg_model(a, b, g, T)
    elif kind == "fg4":
        f, model = _jerk4(T)
    elif kind == "singer":
        f, model = _singer(T)
        m = 2
        init = "first"
    else:  # pragma: no cover
        raise ValueError(kind)
    z = fr.with_nans(rng, fr.kinematic_z(rng, ntr, N, T, m=m), pattern).astype(dtype)
    return f, model, z, init, m


def assert_chunks_identical(f, z, splits, init, m):
    one = f.run(z, init=init, return_residuals=True)
    edges = [0] + list(splits) + [z.shape[1]]
    state = None
    outs, ress = [], []
    for lo, hi in zip(edges[:-1], edges[1:]):
        r = f.run(z[:, lo:hi], init=init, state=state, return_residuals=True)
        state = r.state
        outs.append(r.states)
        ress.append(r.residuals)
    states = np.concatenate(outs, axis=2)
    res = np.concatenate(ress, axis=1)
    assert same(states, one.states), np.argwhere(~((states == one.states) | (np.isnan(states) & np.isnan(one.states))))[:5]
    assert same(res, one.residuals)
    assert np.array_equal(state.phase, one.state.phase)
    assert np.array_equal(state.x, one.state.x, equal_nan=True)
    return one


KINDS = ["ab", "abg", "fg4", "singer"]


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_chunks_of_one_sample(kind, dtype):
    f, model, z, init, m = make(kind, ntr=4, N=120, dtype=dtype, pattern="mixed")
    one = assert_chunks_identical(f, z, range(1, z.shape[1]), init, m)
    if dtype == np.float64:
        s, res, _ = fr.run_ref(z, model, init)
        fr.assert_states_close(one.states, s)


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_random_splits(kind, seed, dtype):
    f, model, z, init, m = make(kind, ntr=7, N=400, dtype=dtype, pattern=["mixed", "random", "runs", "start-gaps"][seed], seed=seed)
    rng = np.random.default_rng(seed)
    splits = np.unique(rng.integers(0, z.shape[1] + 1, rng.integers(1, 12)))
    assert_chunks_identical(f, z, splits, init, m)


@pytest.mark.parametrize("init", ["two-point", "first", "array"])
def test_splits_per_track_gains(init):
    f, model, z, _, m = make("ab", ntr=6, N=200, pattern="mixed", per_track=True)
    if init == "array":
        init = np.random.default_rng(1).normal(size=(6, 2))
    assert_chunks_identical(f, z, [1, 2, 3, 50, 51, 120, 199], init, m)


# two-point start: first valid at 2, misses at 3..5, second valid at 6, miss at 7
START = np.array([np.nan, np.nan, 10.0, np.nan, np.nan, np.nan, 13.0, np.nan, 14.0, 15.5, 16.0, np.nan, 18.0, 19.0])


@pytest.mark.parametrize("split", range(0, len(START) + 1))
@pytest.mark.parametrize("kind", ["ab", "abg", "fg4"])
def test_split_inside_two_point_start(split, kind):
    f = {"ab": AlphaBetaFilter(0.5, 0.2, 0.5), "abg": AlphaBetaGammaFilter(0.5, 0.2, 0.05, 0.5), "fg4": _jerk4(0.5)[0]}[kind]
    model = {"ab": fr.ab_model(0.5, 0.2, 0.5), "abg": fr.abg_model(0.5, 0.2, 0.05, 0.5), "fg4": _jerk4(0.5)[1]}[kind]
    z = np.stack([START, np.roll(START, 3), START + 1.0])
    splits = [split] if 0 < split < len(START) else []
    one = assert_chunks_identical(f, z, splits, "two-point", 1)
    s, res, st = fr.run_ref(z, model, "two-point")
    fr.assert_states_close(one.states, s)
    fr.assert_resid_close(one.residuals, res)
    # the two-point start itself, spelled out (track 0): position held at 10, velocity (13 - 10) / (4 T)
    assert np.all(np.isnan(one.states[:, 0, :2]))
    assert np.all(one.position[0, 2:6] == 10.0) and np.all(np.isnan(one.states[1:, 0, 2:6]))
    assert one.position[0, 6] == 13.0 and abs(one.velocity[0, 6] - 3.0 / (4 * 0.5)) < 1e-15
    assert np.all(np.isnan(one.residuals[0, :8]))
    # single-track 1-D streaming too, with the phase reported in between
    if 0 < split < len(START):
        r1 = f.run(START[:split])
        exp_phase = 0 if split <= 2 else (1 if split <= 6 else 2)
        assert int(r1.state.phase) == exp_phase
        r2 = f.run(START[split:], state=r1.state)
        assert same(np.concatenate([r1.states, r2.states], axis=-1), one.states[:, 0])


def test_empty_chunk_in_stream():
    f, model, z, init, m = make("ab", ntr=3, N=60)
    one = f.run(z)
    r1 = f.run(z[:, :20])
    r2 = f.run(z[:, 20:20], state=r1.state)
    assert r2.states.shape == (2, 3, 0)
    r3 = f.run(z[:, 20:], state=r2.state)
    assert same(np.concatenate([r1.states, r3.states], axis=2), one.states)


def test_state_is_not_mutated_by_continuing():
    f, model, z, init, m = make("ab", ntr=3, N=60)
    r1 = f.run(z[:, :30])
    x, ph = r1.state.x.copy(), r1.state.phase.copy()
    a = f.run(z[:, 30:], state=r1.state)
    b = f.run(z[:, 30:], state=r1.state)
    assert same(a.states, b.states)
    assert np.array_equal(r1.state.x, x, equal_nan=True) and np.array_equal(r1.state.phase, ph)
    c = f.run(z[:, 30:], state=r1.state.copy())
    assert same(a.states, c.states)


def test_state_float32_continues_float64_precision():
    """The state carried between float32 chunks is the same as in one float32 call."""
    f, model, z, init, m = make("ab", ntr=3, N=500, dtype=np.float32)
    assert_chunks_identical(f, z, [7, 250], init, m)


def test_state_ignores_init_for_running_tracks():
    f, model, z, init, m = make("ab", ntr=3, N=60, pattern="none")
    r1 = f.run(z[:, :30], init="first")
    a = f.run(z[:, 30:], state=r1.state, init="first")
    b = f.run(z[:, 30:], state=r1.state, init=np.zeros(2))
    assert same(a.states, b.states)


# ---------------------------------------------------------------------------
# Tracker
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("kind", KINDS)
def test_tracker_matches_one_call(kind):
    f, model, z, init, m = make(kind, ntr=4, N=200)
    one = f.run(z, init=init, return_residuals=True)
    trk = Tracker(f, n_tracks=4, init=init)
    edges = [0, 1, 2, 17, 17, 90, 200]
    outs, ress = [], []
    for lo, hi in zip(edges[:-1], edges[1:]):
        r = trk.update(z[:, lo:hi], return_residuals=True)
        outs.append(r.states)
        ress.append(r.residuals)
    assert trk.samples == 200
    assert same(np.concatenate(outs, axis=2), one.states)
    assert same(np.concatenate(ress, axis=1), one.residuals)
    trk.reset()
    assert trk.samples == 0 and trk.state is None
    again = trk.update(z)
    assert same(again.states, one.states)


def test_tracker_single_track_lists_and_filter_method():
    f = AlphaBetaFilter(0.5, 0.2, 1.0)
    z = [0.0, 1.0, 2.5, 3.0, float("nan"), 5.5, 6.0]
    trk = f.tracker()
    parts = [trk.update(z[:2]), trk.update([2.5]), trk.update(np.array(z[3:]))]
    got = np.concatenate([p.states for p in parts], axis=-1)
    want = f.run(np.array(z)).states
    assert same(got, want)
    s, _, _ = fr.run_ref(np.array(z), fr.ab_model(0.5, 0.2, 1.0))
    fr.assert_states_close(got, s)
    # integer chunks are accepted by the Tracker (converted to float64)
    trk2 = Tracker(f)
    r = trk2.update([0, 1, 2])
    assert r.states.dtype == np.float64 and same(r.states, f.run(np.array([0.0, 1.0, 2.0])).states)


def test_tracker_one_number_per_update():
    # Real-time use: one measurement (a Python float, NumPy scalar or 0-d
    # array; NaN = missed) per call gives the bits of one whole-array run.
    f = AlphaBetaFilter(0.45, 0.12, 0.5)
    z = np.cumsum(np.random.default_rng(3).normal(size=40))
    z[[0, 7, 8, 20]] = np.nan
    trk = Tracker(f)
    got = []
    for k, v in enumerate(z):
        x = (float(v), np.float64(v), np.array(v))[k % 3]
        got.append(trk.update(x).states)
    assert trk.samples == z.size
    assert same(np.concatenate(got, axis=-1), f.run(z).states)
    # float32 scalars stay float32; vector measurements and multi-track
    # trackers still need arrays of the run layout
    r = Tracker(f).update(np.float32(1.5))
    assert r.states.dtype == np.float32 and r.states.shape == (2, 1)
    with pytest.raises(ValueError, match="z_chunk"):
        Tracker(f, n_tracks=3).update(1.0)
    with pytest.raises(TypeError, match="z_chunk"):
        Tracker(f).update(np.array([1 + 2j]))


def test_tracker_n_tracks_checked_on_the_first_chunk():
    # n_tracks given: the first chunk must have that many tracks (counted
    # per spatial axis with axes=), else a ValueError naming z_chunk and
    # nothing kept; not given: taken from the first chunk; reset() forgets it.
    f = AlphaBetaFilter(0.5, 0.2, 1.0)
    z = np.cumsum(np.random.default_rng(8).normal(size=(3, 12, 2)), axis=1)
    trk = Tracker(f, n_tracks=2)
    with pytest.raises(ValueError, match=r"z_chunk has 3 tracks; this tracker was made with n_tracks=2"):
        trk.update(z[..., 0])
    assert trk.state is None and trk.samples == 0
    a = trk.update(z[:2, :5, 0])
    b = trk.update(z[:2, 5:, 0])
    assert same(np.concatenate([a.states, b.states], axis=-1), f.run(z[:2, :, 0]).states)
    free = Tracker(f)
    assert free.n_tracks is None
    free.update(z[:, :4, 0])
    assert free.n_tracks == 3
    with pytest.raises(ValueError, match="state is for 3 tracks"):
        free.update(z[:2, 4:, 0])
    free.reset()
    assert free.n_tracks is None and free.update(z[:1, :, 0]).states.shape == (2, 1, 12)
    ax = Tracker(f, n_tracks=3)
    r = ax.update(z, axes=2)
    assert ax.n_tracks == 3 and r.states.shape == (2, 3, 12, 2)
    with pytest.raises(ValueError, match=r"n_tracks must be a positive integer or None, got True"):
        Tracker(f, n_tracks=True)


def test_state_copied_and_checked():
    f = AlphaBetaFilter(0.5, 0.2, 1.0)
    z = np.cumsum(np.ones((3, 10)), axis=1)
    a = f.run(z[:, :5])
    packed = a.state._packed.copy()
    b = f.run(z[:, 5:], state=a.state)
    assert np.array_equal(a.state._packed, packed, equal_nan=True)  # not changed
    assert same(np.concatenate([a.states, b.states], axis=2), f.run(z).states)
    bad = FilterState(np.zeros((3, 4)), 2, False)
    with pytest.raises(ValueError, match="packed array of shape"):
        f.run(z, state=bad)
    assert np.array_equal(a.n_dropped, np.zeros(3, np.int64)) and a.n_restarts.shape == (3,)


def test_tracker_first_init():
    f, model, z, init, m = make("singer", ntr=2, N=50)
    trk = Tracker(f, n_tracks=2, init="first")
    a = trk.update(z[:, :25])
    b = trk.update(z[:, 25:])
    assert same(np.concatenate([a.states, b.states], axis=2), f.run(z, init="first").states)


def test_tracker_bad_args():
    with pytest.raises(TypeError):
        Tracker(object())
    with pytest.raises(ValueError):
        Tracker(AlphaBetaFilter(0.5, 0.2, 1.0), n_tracks=0)


# ---------------------------------------------------------------------------
# threads
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_threads_bit_identical(kind, dtype):
    f, model, z, init, m = make(kind, ntr=67, N=300, dtype=dtype)
    base = f.run(z, init=init, return_residuals=True, threads=1)
    for th in [None, 2, 3]:
        r = f.run(z, init=init, return_residuals=True, threads=th)
        assert same(r.states, base.states) and same(r.residuals, base.residuals), th
        assert np.array_equal(r.state.x, base.state.x, equal_nan=True)
    A = np.array([[0.5, 0.1], [0.0, 0.4]]) if model.n == 2 else 0.3 * np.eye(model.n)
    sb = f.smooth(z, init=init, smoother_gain=A, threads=1)
    for th in [None, 2, 3]:
        assert same(f.smooth(z, init=init, smoother_gain=A, threads=th).states, sb.states)
        assert same(f.smooth(z, init=init, smoother_gain=A, lag=4, threads=th).states, f.smooth(z, init=init, smoother_gain=A, lag=4, threads=1).states)


@pytest.mark.parametrize("threads", [None, 1, 2, 3])
def test_threads_single_long_track(threads):
    rng = np.random.default_rng(3)
    z = fr.with_nans(rng, fr.kinematic_z(rng, 1, 200_000, 0.01), "random")[0]
    f = AlphaBetaFilter(0.3, 0.05, 0.01)
    base = f.run(z, threads=1, return_residuals=True)
    r = f.run(z, threads=threads, return_residuals=True)
    assert same(r.states, base.states) and same(r.residuals, base.residuals)
    # and split in two by streaming. Without residuals a single track this
    # long is filtered in segments (docs/filtering.md, "single long tracks"):
    # thread counts still change nothing, chunking agrees within 1e-12 of the
    # state's scale (position scale for the position, position scale / T for
    # the velocity, the conditioning of the recursion).
    r1 = f.run(z[:123_457], threads=threads)
    r2 = f.run(z[123_457:], state=r1.state, threads=threads)
    whole = f.run(z, threads=threads)
    assert same(whole.states, f.run(z, threads=1).states)
    got = np.concatenate([r1.states, r2.states], axis=1)
    assert np.array_equal(np.isnan(got), np.isnan(base.states))
    pscale = np.nanmax(np.abs(base.states[0]))
    assert np.nanmax(np.abs(got[0] - base.states[0])) <= 1e-12 * pscale
    assert np.nanmax(np.abs(got[1] - base.states[1])) <= 1e-12 * pscale / 0.01
    assert np.nanmax(np.abs(whole.states[0] - base.states[0])) <= 1e-12 * pscale
    assert np.nanmax(np.abs(whole.states[1] - base.states[1])) <= 1e-12 * pscale / 0.01


def test_threads_per_track_gains():
    f, model, z, init, m = make("ab", ntr=41, N=200, per_track=True)
    base = f.run(z, threads=1)
    for th in [None, 2, 3]:
        assert same(f.run(z, threads=th).states, base.states)
    s, _, _ = fr.run_ref(z, model)
    fr.assert_states_close(base.states, s)


# ---------------------------------------------------------------------------
# strides and layouts
# ---------------------------------------------------------------------------
def _views_scalar(z):
    """(name, view) pairs of z-like data with unusual strides (value = its own contiguous copy)."""
    ntr, N = z.shape
    big = np.full((2 * ntr + 1, 3 * N + 2), -7.0, dtype=z.dtype)
    big[1::2, 2::3][:ntr, :N] = z
    yield "step-slices", big[1::2, 2::3][:ntr, :N]
    rev = np.ascontiguousarray(z[::-1, ::-1])
    yield "negative-strides", rev[::-1, ::-1]
    yield "fortran", np.asfortranarray(z)
    yield "transposed", np.ascontiguousarray(z.T).T
    yield "broadcast-tracks", np.broadcast_to(z[0], z.shape)
    yield "broadcast-samples", np.broadcast_to(z[:, :1], z.shape)
    yield "single-column-of-2d", np.asfortranarray(np.stack([z[1], z[0]], axis=1))[:, 0]


@pytest.mark.parametrize("kind", ["ab", "abg", "fg4"])
@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_noncontiguous_scalar_input(kind, dtype):
    f, model, z, init, m = make(kind, ntr=5, N=150, dtype=dtype)
    for name, v in _views_scalar(z):
        c = np.ascontiguousarray(v)
        for op in ("run", "smooth"):
            kw = {"smoother_gain": 0.2 * np.eye(model.n)} if op == "smooth" else {}
            a = getattr(f, op)(v, init=init, return_residuals=True, **kw)
            b = getattr(f, op)(c, init=init, return_residuals=True, **kw)
            assert same(a.states, b.states), (name, op)
            assert same(a.residuals, b.residuals), (name, op)
        if name in ("negative-strides", "step-slices"):
            s, _, _ = fr.run_ref(c, model, init)
            if dtype == np.float64:
                fr.assert_states_close(f.run(v, init=init).states, s)


def test_noncontiguous_1d_single_track():
    f, model, z, init, m = make("ab", ntr=2, N=200)
    x = z[0]
    for v in (np.repeat(x, 3)[::3], x[::-1].copy()[::-1], np.stack([x, x], axis=1)[:, 1], np.broadcast_to(x[5], (200,))):
        a = f.run(v, return_residuals=True)
        b = f.run(np.ascontiguousarray(v), return_residuals=True)
        assert same(a.states, b.states) and same(a.residuals, b.residuals)


def _views_vector(z):
    ntr, N, m = z.shape
    big = np.zeros((ntr, 2 * N, 3), dtype=z.dtype)
    big[:, ::2, 1:] = z
    yield "step-slices", big[:, ::2, 1:]
    yield "component-reversed", np.ascontiguousarray(z[..., ::-1])[..., ::-1]
    yield "fortran", np.asfortranarray(z)
    yield "component-major-transposed", np.ascontiguousarray(np.transpose(z, (2, 1, 0))).transpose(2, 1, 0)
    yield "negative-samples", np.ascontiguousarray(z[:, ::-1])[:, ::-1]
    yield "broadcast-tracks", np.broadcast_to(z[:1], z.shape)
    yield "broadcast-components", np.broadcast_to(z[..., :1], z.shape)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_noncontiguous_vector_input(dtype):
    f, model, z, init, m = make("singer", ntr=4, N=120, dtype=dtype)
    for name, v in _views_vector(z):
        c = np.ascontiguousarray(v)
        a = f.run(v, init="first", return_residuals=True)
        b = f.run(c, init="first", return_residuals=True)
        assert same(a.states, b.states) and same(a.residuals, b.residuals), name
        # single-track 2-D view
        a1 = f.run(v[1], init="first")
        assert same(a1.states, f.run(np.ascontiguousarray(v[1]), init="first").states), name


def test_unaligned_input():
    f, model, z, init, m = make("ab", ntr=3, N=100)
    buf2 = bytearray(z.size * 8 + 1)
    u = np.ndarray(z.shape, dtype=np.float64, buffer=buf2, offset=1)
    u[...] = z
    assert not u.flags.aligned
    assert same(f.run(u).states, f.run(z).states)


def test_readonly_input():
    f, model, z, init, m = make("ab", ntr=3, N=100)
    v = z.copy()
    v.flags.writeable = False
    assert same(f.run(v).states, f.run(z).states)


# ---------------------------------------------------------------------------
# out=
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_out_filled_in_place_and_reused(kind, dtype):
    f, model, z, init, m = make(kind, ntr=5, N=150, dtype=dtype)
    n = model.n
    out = np.full((n, 5, 150), 123.0, dtype=dtype)
    r = f.run(z, init=init, out=out)
    assert r.states is out
    assert same(out, f.run(z, init=init).states)
    # reused with other data
    z2 = z[::-1].copy()
    r2 = f.run(z2, init=init, out=out)
    assert r2.states is out and same(out, f.run(z2, init=init).states)
    # smoothing into the same buffer
    A = 0.3 * np.eye(n)
    r3 = f.smooth(z, init=init, smoother_gain=A, out=out)
    assert r3.states is out and same(out, f.smooth(z, init=init, smoother_gain=A).states)
    # streaming into the same (chunk-sized) buffer
    outc = np.empty((n, 5, 50), dtype=dtype)
    st, parts = None, []
    for lo in range(0, 150, 50):
        rc = f.run(z[:, lo : lo + 50], init=init, state=st, out=outc)
        assert rc.states is outc
        st = rc.state
        parts.append(outc.copy())
    assert same(np.concatenate(parts, axis=2), f.run(z, init=init).states)


def test_out_single_track():
    f = AlphaBetaFilter(0.5, 0.2, 1.0)
    z = np.arange(10.0)
    out = np.empty((2, 10))
    assert f.run(z, out=out).states is out
    assert same(out, f.run(z).states)


def test_out_bad():
    f = AlphaBetaFilter(0.5, 0.2, 1.0)
    z = np.arange(20.0).reshape(2, 10)
    for bad in (np.empty((2, 2, 9)), np.empty((3, 2, 10)), np.empty((2, 20)), np.empty((2, 2, 10), np.float32), np.empty((2, 10, 2)).transpose(0, 2, 1), np.empty((2, 2, 20))[:, :, ::2]):
        with pytest.raises(ValueError):
            f.run(z, out=bad)
    ro = np.empty((2, 2, 10))
    ro.flags.writeable = False
    with pytest.raises(ValueError):
        f.run(z, out=ro)
    with pytest.raises(TypeError):
        f.run(z, out=[[0.0] * 10] * 4)
    # overlapping z
    buf = np.zeros((3, 2, 10))
    zz = buf[1]  # z is the second component slab of out
    zz[...] = z
    with pytest.raises(ValueError, match="overlap"):
        f.run(zz, out=buf[:2])
    assert np.array_equal(buf[1], z)
    buf2 = np.zeros((2, 2, 10))
    with pytest.raises(ValueError, match="overlap"):
        f.run(buf2[1], out=buf2)
    with pytest.raises(ValueError):
        f.smooth(z, smoother_gain=np.eye(2), out=np.empty((2, 2, 9)))
    # float32 z needs a float32 out
    with pytest.raises(ValueError):
        f.run(z.astype(np.float32), out=np.empty((2, 2, 10)))


# ---------------------------------------------------------------------------
# dtypes kept and empty input
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("kind", KINDS)
def test_float32_kept(kind):
    f, model, z, init, m = make(kind, ntr=3, N=40, dtype=np.float32)
    r = f.run(z, init=init, return_residuals=True)
    assert r.states.dtype == np.float32 and r.residuals.dtype == np.float32
    s = f.smooth(z, init=init, smoother_gain=0.1 * np.eye(model.n), return_residuals=True)
    assert s.states.dtype == np.float32 and s.residuals.dtype == np.float32


EMPTY_SCALAR = [(0,), (0, 0), (0, 10), (4, 0)]
EMPTY_VECTOR = [(0, 2), (0, 0, 2), (0, 10, 2), (4, 0, 2)]


@pytest.mark.parametrize("shape", EMPTY_SCALAR)
@pytest.mark.parametrize("kind", ["ab", "abg", "fg4"])
@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_empty_scalar(shape, kind, dtype):
    f = {"ab": AlphaBetaFilter(0.5, 0.2, 1.0), "abg": AlphaBetaGammaFilter(0.5, 0.2, 0.05, 1.0), "fg4": _jerk4()[0]}[kind]
    z = np.empty(shape, dtype=dtype)
    r = f.run(z, return_residuals=True)
    assert r.states.shape == (f.n,) + shape and r.states.dtype == dtype
    assert r.residuals.shape == shape and r.residuals.dtype == dtype
    ntr = 1 if len(shape) == 1 else shape[0]
    assert r.state.n_tracks == ntr
    s = f.smooth(z, smoother_gain=np.eye(f.n) * 0.1, lag=3)
    assert s.states.shape == (f.n,) + shape
    s = f.smooth(z, smoother_gain=np.eye(f.n) * 0.1)
    assert s.states.shape == (f.n,) + shape
    out = np.empty((f.n,) + shape, dtype=dtype)
    assert f.run(z, out=out).states is out
    if ntr:
        r2 = f.run(np.ones((ntr, 3), dtype) if len(shape) == 2 else np.ones(3, dtype), state=r.state)
        assert same(r2.states, f.run(np.ones((ntr, 3), dtype) if len(shape) == 2 else np.ones(3, dtype)).states)


@pytest.mark.parametrize("shape", EMPTY_VECTOR)
def test_empty_vector(shape):
    f, model = _singer()
    z = np.empty(shape)
    r = f.run(z, init="first", return_residuals=True)
    samp = shape[:-1]
    assert r.states.shape == (3,) + samp and r.residuals.shape == shape


def test_empty_init_array_zero_tracks():
    f = AlphaBetaFilter(0.5, 0.2, 1.0)
    r = f.run(np.empty((0, 5)), init=np.empty((0, 2)))
    assert r.states.shape == (2, 0, 5)
    r = f.run(np.empty((0, 5)), init=np.zeros(2))
    assert r.states.shape == (2, 0, 5)


def test_tracker_init_array():
    f, model, z, init, m = make("ab", ntr=3, N=60)
    x0 = np.random.default_rng(2).normal(size=(3, 2))
    trk = Tracker(f, n_tracks=3, init=x0)
    a = trk.update(z[:, :10])
    b = trk.update(z[:, 10:])
    one = f.run(z, init=x0)
    assert same(np.concatenate([a.states, b.states], axis=2), one.states)
    s, _, _ = fr.run_ref(z, model, x0)
    fr.assert_states_close(one.states, s)


def test_structured_field_views():
    """Fields of structured arrays: strides not a multiple of the item size (unaligned) or padded."""
    f, model, z, init, m = make("ab", ntr=3, N=50)
    for dt in ([("a", "f4"), ("z", "f8")], [("a", "f8"), ("z", "f8")], [("a", "i1"), ("z", "f8"), ("b", "f4")]):
        st = np.zeros(z.shape, dtype=dt)
        st["z"] = z
        v = st["z"]
        a = f.run(v, return_residuals=True)
        b = f.run(z, return_residuals=True)
        assert same(a.states, b.states) and same(a.residuals, b.residuals), dt
    g, gm, zz, _, _ = make("singer", ntr=3, N=40)
    s3 = np.zeros(zz.shape[:2], dtype=[("a", "f4"), ("p", "f8", (2,))])
    s3["p"] = zz
    assert same(g.run(s3["p"], init="first").states, g.run(zz, init="first").states)


@pytest.mark.parametrize("kind", ["ab", "abg", "fg4", "singer"])
@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_track_result_independent_of_grouping(kind, dtype):
    """docs/filtering.md: "Each track is computed the same way whatever the
    grouping": a track alone (1-D / single-track input), in any sub-batch, or
    in the full batch gives bit-identical states and residuals."""
    f, model, z, init, m = make(kind, ntr=19, N=90, dtype=dtype, pattern="mixed")
    full = f.run(z, init=init, return_residuals=True)
    A = 0.3 * np.eye(model.n)
    sfull = f.smooth(z, init=init, smoother_gain=A, lag=None)
    for i in (0, 5, 7, 8, 15, 18):
        one = f.run(z[i], init=init, return_residuals=True)
        assert same(one.states, full.states[:, i]), i
        assert same(one.residuals, full.residuals[i]), i
        assert same(f.smooth(z[i], init=init, smoother_gain=A).states, sfull.states[:, i]), i
    for lo, hi in ((0, 3), (3, 12), (11, 19), (1, 18)):
        part = f.run(z[lo:hi], init=init)
        assert same(part.states, full.states[:, lo:hi]), (lo, hi)
