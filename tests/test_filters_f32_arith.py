"""AlphaBetaFilter(float32_arithmetic=True): float32 data in float32 arithmetic.

Checked against the independent float64 reference (tests/filterref.py)
within the documented drift bound, and for the guarantees the mode keeps
among its own paths (bit-identical across threads, chunked streaming,
batch layouts, strides, out= reuse), plus its errors. The kernel's
arithmetic is checked bit for bit against an independent float32
recursion in the Rust tests (rust/abkit-core/src/tests/f32arith.rs).
"""

import numpy as np
import pytest

import abkit
from filterref import ab_model, assert_states_close, run_ref

EPS32 = float(np.finfo(np.float32).eps)


def bound(alpha: float) -> float:
    """Documented drift of float32 arithmetic: 2 (1 + 1/alpha) float32
    epsilons of the scale (measured here: at most 0.2 / alpha + 2.3)."""
    return 2.0 * EPS32 * (1.0 + 1.0 / alpha)


def tracks(n_tracks: int, n: int, offset: float, seed: int = 0, nan_rate: float = 0.0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    k = np.arange(n)
    z = offset + (1.0 + 0.01 * np.arange(n_tracks))[:, None] * 0.1 * k + rng.standard_normal((n_tracks, n))
    if nan_rate:
        z[rng.random(z.shape) < nan_rate] = np.nan
    return z.astype(np.float32)


# (alpha, beta, T): tiny to large alpha
GAINS = [(0.0045, 1.0e-5, 0.1), (0.05, 1.3e-3, 1.0), (0.5, 0.2, 0.1), (1.2, 0.9, 2.0)]


@pytest.mark.parametrize("alpha,beta,T", GAINS)
@pytest.mark.parametrize("offset", [0.0, 1e3, 1e5])
@pytest.mark.parametrize("init", ["two-point", "first"])
def test_within_documented_bound_of_float64_reference(alpha, beta, T, offset, init):
    # 16 tracks (one vector group) of 3,000 samples with missed detections
    z = tracks(16, 3000, offset, seed=1, nan_rate=0.02)
    z[3, :5] = np.nan
    z[5] = np.nan
    f = abkit.AlphaBetaFilter(alpha, beta, T, float32_arithmetic=True)
    r = f.run(z, init=init, threads=1)
    assert r.states.dtype == np.float32
    want, _, _ = run_ref(z.astype(np.float64), ab_model(alpha, beta, T), init=init)
    assert_states_close(r.states, want, rtol=bound(alpha), what="float32 arithmetic", kin_T=T)


def test_mode_changes_float32_results_and_not_float64():
    z = tracks(16, 5000, 1e3, seed=2)
    a, b, T = 0.01, 5e-5, 0.1
    d = abkit.AlphaBetaFilter(a, b, T).run(z).states
    s = abkit.AlphaBetaFilter(a, b, T, float32_arithmetic=True).run(z).states
    # every step rounds to float32 now: the results differ somewhere
    assert not np.array_equal(d, s)
    z64 = z.astype(np.float64)
    d64 = abkit.AlphaBetaFilter(a, b, T).run(z64).states
    s64 = abkit.AlphaBetaFilter(a, b, T, float32_arithmetic=True).run(z64).states
    assert s64.dtype == np.float64
    np.testing.assert_array_equal(d64, s64)


@pytest.mark.parametrize("n_tracks,n", [(16, 300), (35, 257), (17, 64), (16, 70_000), (1, 1000), (40, 3)])
def test_paths_bit_identical(n_tracks, n):
    """Threads, streaming in chunks, each track alone, strided input and
    out= reuse give the same bits (full vector groups, scalar groups and
    streamed outputs included)."""
    z = tracks(n_tracks, n, 50.0, seed=3, nan_rate=0.01)
    f = abkit.AlphaBetaFilter(0.3, 0.05, 0.5, float32_arithmetic=True)
    ref = f.run(z, threads=1)
    for th in (None, 2):
        np.testing.assert_array_equal(f.run(z, threads=th).states, ref.states)
    # chunks with state=
    cuts = [0, 1, max(2, n // 3), n]
    st = None
    parts = []
    for c0, c1 in zip(cuts[:-1], cuts[1:]):
        r = f.run(z[:, c0:c1], state=st)
        st = r.state
        parts.append(r.states)
    np.testing.assert_array_equal(np.concatenate(parts, axis=-1), ref.states)
    np.testing.assert_array_equal(st.x, ref.state.x)
    # each track alone (1-D input); a track of 2^16 samples or more alone
    # is split into segments (the documented exception: float32 rounding)
    for i in {0, n_tracks // 2, n_tracks - 1}:
        if n < 1 << 16:
            np.testing.assert_array_equal(f.run(z[i]).states, ref.states[:, i])
        else:
            assert_states_close(f.run(z[i]).states, ref.states[:, i], rtol=2 * bound(0.3), kin_T=0.5)
    # strided input: every other sample of a wider array
    wide = np.repeat(z, 2, axis=1)
    np.testing.assert_array_equal(f.run(wide[:, ::2]).states, ref.states)
    # out= reused
    out = np.full_like(ref.states, 7.0)
    r = f.run(z, out=out)
    assert r.states is out or np.shares_memory(r.states, out)
    np.testing.assert_array_equal(out, ref.states)


def test_per_track_gains_and_residuals():
    n_tracks, n = 20, 500
    z = tracks(n_tracks, n, -30.0, seed=4, nan_rate=0.03)
    a = np.linspace(0.2, 0.9, n_tracks)
    b = np.linspace(0.02, 0.3, n_tracks)
    T = np.linspace(0.1, 1.0, n_tracks)
    f = abkit.AlphaBetaFilter(a, b, T, float32_arithmetic=True)
    r = f.run(z, return_residuals=True)
    np.testing.assert_array_equal(f.run(z).states, r.states)
    for i in (0, 7, 19):
        g = abkit.AlphaBetaFilter(a[i], b[i], T[i], float32_arithmetic=True)
        np.testing.assert_array_equal(g.run(z[i]).states, r.states[:, i])
        want, _, _ = run_ref(z[i].astype(np.float64), ab_model(a[i], b[i], T[i]))
        assert_states_close(r.states[:, i], want, rtol=bound(a[i]), kin_T=T[i])
    # residual = z - (x + T v) from the previous estimates (float32), NaN
    # where z is NaN or the track is starting
    x, v = r.position.astype(np.float64), r.velocity.astype(np.float64)
    pred = x[:, :-1] + T[:, None] * v[:, :-1]
    res = r.residuals[:, 1:].astype(np.float64)
    zz = z[:, 1:].astype(np.float64)
    ok = ~np.isnan(res)
    assert np.array_equal(np.isnan(res), np.isnan(zz) | np.isnan(pred))
    scale = np.nanmax(np.abs(z))
    assert np.max(np.abs(res[ok] - (zz - pred)[ok])) <= 4 * EPS32 * scale


def test_tracker_streams_like_one_call():
    z = tracks(16, 900, 10.0, seed=5)
    f = abkit.AlphaBetaFilter(0.5, 0.2, 0.1, float32_arithmetic=True)
    one = f.run(z)
    tr = abkit.Tracker(f)
    got = np.concatenate([tr.update(z[:, k : k + 100]).states for k in range(0, 900, 100)], axis=-1)
    np.testing.assert_array_equal(got, one.states)


def test_errors():
    with pytest.raises(TypeError, match="float32_arithmetic"):
        abkit.AlphaBetaFilter(0.5, 0.2, 0.1, float32_arithmetic="yes")
    with pytest.raises(ValueError, match="float32_arithmetic"):
        abkit.AlphaBetaFilter(0.5, 0.2, 0.1, float32_arithmetic=True, transient="kalman")
    f = abkit.AlphaBetaFilter.from_noise(1.0, 2.0, 0.1, float32_arithmetic=True)
    assert f.float32_arithmetic
    z = tracks(2, 50, 0.0)
    t = np.arange(50) * 0.1
    for call in (
        lambda: f.smooth(z),
        lambda: f.smooth(z, lag=3),
        lambda: f.run(z, t=t),
        lambda: f.run(z.reshape(-1), t=np.r_[t, t + 5.0], offsets=[0, 50, 100]),
        lambda: f.run(z.reshape(-1), offsets=[0, 50, 100], max_gap=1.0),
        lambda: f.run(z.reshape(-1), offsets=[0, 50, 100], on_duplicate="drop"),
    ):
        with pytest.raises(ValueError, match="float32_arithmetic=True"):
            call()
    # the report feed (no float32-arithmetic path yet)
    trk = abkit.FeedTracker(f)
    with pytest.raises(ValueError, match="float32_arithmetic=True"):
        trk.update(np.array([1, 1, 2]), np.array([0.0, 0.1, 0.0]), np.ones(3, np.float32))
    trk.update(np.array([1, 1, 2]), np.array([0.0, 0.1, 0.0]), np.ones(3))
    # a period beyond float32's range: a ValueError naming it
    with pytest.raises(ValueError, match="T"):
        abkit.AlphaBetaFilter(0.5, 0.2, 1e39, float32_arithmetic=True).run(z)
    # float64 data: every path available (float64 arithmetic)
    z64 = z.astype(np.float64)
    f.smooth(z64)
    f.run(z64, t=t)
    # the default filter keeps every path for float32 data
    abkit.AlphaBetaFilter.from_noise(1.0, 2.0, 0.1).smooth(z)


@pytest.mark.parametrize("alpha,beta,T", [(0.5, 0.2, 0.1), (0.05, 1.3e-3, 1.0)])
def test_single_long_track_split(alpha, beta, T):
    """A long single track (split into 16 segments, as in the default
    kernels) stays within the bound of the float64 reference, also in
    chunks, with missed detections; thread counts give the same bits."""
    n = (1 << 18) + 77
    z = tracks(1, n, 1e3, seed=6, nan_rate=0.01)[0]
    z[100_000:100_300] = np.nan
    f = abkit.AlphaBetaFilter(alpha, beta, T, float32_arithmetic=True)
    r = f.run(z, threads=1)
    want, _, _ = run_ref(z.astype(np.float64), ab_model(alpha, beta, T))
    # each coasting step rounds the prediction: a run of G missed samples
    # adds up to G / 2 epsilons (documented)
    tol = bound(alpha) + 0.5 * 300 * EPS32
    assert_states_close(r.states, want, rtol=tol, kin_T=T)
    np.testing.assert_array_equal(f.run(z, threads=2).states, r.states)
    a = f.run(z[: n // 3])
    b = f.run(z[n // 3 :], state=a.state)
    assert_states_close(np.concatenate([a.states, b.states], axis=-1), want, rtol=tol, kin_T=T)


def test_vector_kernels_bit_identical_to_scalar_loop(tmp_path):
    # The same float32 batches in a process with every vector kernel off
    # (ABKIT_DISABLE_SIMD=1: the scalar loop) give the same bits as the
    # default: short rows straight from the batch (from memory: streamed
    # outputs through the stages), longer rows in groups, rows with NaN at
    # their starts and all-NaN rows; streamed outputs whose v rows are not
    # at the x rows' line offsets (33 x 40,001, and a ragged batch).
    import os
    import subprocess
    import sys

    code = r"""
import sys, numpy as np
from abkit import AlphaBetaFilter
rng = np.random.default_rng(11)
res = {}
for n_tracks, n in [(3000, 45), (20000, 100), (333, 300), (40, 2000), (33, 40001)]:
    z = rng.normal(size=(n_tracks, n)).cumsum(1).astype(np.float32) + 100.0
    z[rng.random(z.shape) < 0.02] = np.nan
    z[::9, :3] = np.nan
    z[5::97] = np.nan
    for init in ["two-point", "first"]:
        f = AlphaBetaFilter(0.4, 0.1, 0.5, float32_arithmetic=True)
        r = f.run(z, init=init)
        res[f"{n_tracks}x{n}{init}"] = r.states
        res[f"{n_tracks}x{n}{init}state"] = r.state._packed
# ragged, outputs streamed (over 1e6 samples), the v row not at the x row's
# line offset (N % 16 != 0), tracks of 0..2,000 samples
lens = rng.integers(0, 2000, 1200)
lens[-1] += 1 if lens.sum() % 16 == 0 else 0
off = np.r_[0, np.cumsum(lens)]
zr = rng.normal(size=off[-1]).cumsum().astype(np.float32)
zr[rng.random(zr.shape) < 0.01] = np.nan
for init in ["two-point", "first"]:
    r = AlphaBetaFilter(0.4, 0.1, 0.5, float32_arithmetic=True).run(zr, offsets=off, init=init)
    res[f"ragged{init}"] = r.states
    res[f"ragged{init}state"] = r.state._packed
np.savez(sys.argv[1] + "/" + sys.argv[2] + ".npz", **res)
"""
    runs = (("on", {}), ("off", {"ABKIT_DISABLE_SIMD": "1"}))
    for tag, extra in runs:
        e = dict(os.environ)
        e.pop("ABKIT_DISABLE_SIMD", None)
        e.update(extra)
        subprocess.run([sys.executable, "-c", code, str(tmp_path), tag], check=True, env=e)
    off = np.load(tmp_path / "off.npz")
    for tag, _ in runs[:-1]:
        on = np.load(tmp_path / f"{tag}.npz")
        assert sorted(on.files) == sorted(off.files)
        for k in on.files:
            a, b = on[k], off[k]
            assert np.array_equal(np.isnan(a), np.isnan(b)), (tag, k)
            ok = ~np.isnan(a)
            assert np.array_equal(a[ok].view(np.uint8), b[ok].view(np.uint8)), (tag, k)


def ragged(seed: int, n_tracks: int, hi: int, nan_rate: float = 0.02):
    """A ragged float32 batch: lengths 0..hi (and 0, 1, 2, 3, 17 first),
    NaN at random, one all-NaN track, one starting late."""
    rng = np.random.default_rng(seed)
    lens = rng.integers(0, hi, n_tracks)
    lens[:6] = [0, 1, 2, 3, 17, 0]
    lens[6:8] = [40, 300]
    off = np.r_[0, np.cumsum(lens)].astype(np.int64)
    z = (50.0 + 0.1 * rng.standard_normal(off[-1]).cumsum()).astype(np.float32)
    z[rng.random(z.shape) < nan_rate] = np.nan
    z[off[6] : off[7]] = np.nan
    z[off[7] : off[7] + 50] = np.nan
    return z, off


@pytest.mark.parametrize("init", ["two-point", "first"])
@pytest.mark.parametrize("per_track", [False, True])
def test_ragged_each_track_as_alone(init, per_track):
    # offsets=: every track (estimates, residuals, final state) has the
    # bits of that track run alone, whatever the threads; groups of 16
    # tracks of different lengths in the vector lanes, the rest scalar.
    z, off = ragged(3, 400, 700)
    n = off.size - 1
    if per_track:
        alpha = np.linspace(0.2, 0.8, n)
        beta = np.linspace(0.01, 0.3, n)
    else:
        alpha, beta = np.full(n, 0.45), np.full(n, 0.12)
    T = 0.25
    f = abkit.AlphaBetaFilter(alpha if per_track else 0.45, beta if per_track else 0.12, T, float32_arithmetic=True)
    r = f.run(z, offsets=off, init=init, return_residuals=True)
    r1 = f.run(z, offsets=off, init=init, threads=1)
    assert r.states.dtype == np.float32 and r.residuals.dtype == np.float32
    np.testing.assert_array_equal(r1.states, r.states)
    np.testing.assert_array_equal(r1.state._packed, r.state._packed)
    for i in range(n):
        a, b = off[i], off[i + 1]
        one = abkit.AlphaBetaFilter(alpha[i], beta[i], T, float32_arithmetic=True).run(z[a:b], init=init, return_residuals=True)
        assert np.array_equal(r.states[:, a:b], one.states, equal_nan=True), i
        assert np.array_equal(r.residuals[a:b], one.residuals, equal_nan=True), i
        assert np.array_equal(r.state._packed[i], one.state._packed[0], equal_nan=True), i


def test_ragged_streams_strides_axes_and_out():
    z, off = ragged(4, 300, 900)
    f = abkit.AlphaBetaFilter(0.3, 0.05, 0.1, float32_arithmetic=True)
    whole = f.run(z, offsets=off)
    # chunked: the first half of every track, then the rest with state=
    lens = np.diff(off)
    half = lens // 2
    idx1 = np.concatenate([np.arange(off[i], off[i] + half[i]) for i in range(lens.size)])
    idx2 = np.concatenate([np.arange(off[i] + half[i], off[i + 1]) for i in range(lens.size)])
    r1 = f.run(z[idx1], offsets=np.r_[0, np.cumsum(half)])
    r2 = f.run(z[idx2], offsets=np.r_[0, np.cumsum(lens - half)], state=r1.state)
    got = np.empty_like(whole.states)
    got[:, idx1] = r1.states
    got[:, idx2] = r2.states
    np.testing.assert_array_equal(got, whole.states)
    np.testing.assert_array_equal(r2.state._packed, whole.state._packed)
    # strided z: the same bits
    zz = np.zeros(2 * z.size, np.float32)
    zz[::2] = z
    np.testing.assert_array_equal(f.run(zz[::2], offsets=off).states, whole.states)
    # out= filled in place
    out = np.full((2, z.size), -1.0, np.float32)
    r = f.run(z, offsets=off, out=out)
    assert r.states is out or np.shares_memory(r.states, out)
    np.testing.assert_array_equal(out, whole.states)
    # axes=2: each axis as its own ragged batch
    z2 = np.stack([z, z[::-1].copy()], axis=-1)
    ra = f.run(z2, offsets=off, axes=2)
    for a in range(2):
        np.testing.assert_array_equal(ra.states[..., a], f.run(np.ascontiguousarray(z2[:, a]), offsets=off).states)
    # float64 data: the default kernels (float64 arithmetic)
    d = f.run(z.astype(np.float64), offsets=off)
    assert d.states.dtype == np.float64
