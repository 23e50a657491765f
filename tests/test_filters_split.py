"""The single-long-track segment split (docs/filtering.md) against the
unsplit recursion: a strided view of the same data is never split, so the
two runs compare the split with the plain sequential loop. Tolerance 1e-12 of
each state's scale (velocity: position scale / T)."""

from __future__ import annotations

import numpy as np
import pytest

import abkit


def _pair(z: np.ndarray) -> tuple:
    zz = np.empty((z.size, 2), dtype=z.dtype)
    zz[:, 0] = z
    return z, zz[:, 0]  # contiguous (split) and strided (unsplit)


@pytest.mark.parametrize(
    "alpha,beta,T,nan_frac,offset",
    [
        (0.5, 0.2, 0.1, 0.0, 0.0),
        (0.5, 0.2, 0.1, 0.05, 1e4),
        (0.3, 0.05, 1.0, 0.2, -5e3),
        (0.9, 0.8, 0.01, 0.01, 0.0),
        (0.05, 0.0013, 1.0, 0.0, 0.0),  # slow loop: not split, still equal
    ],
)
@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_split_equals_sequential(alpha, beta, T, nan_frac, offset, dtype):
    rng = np.random.default_rng(11)
    n = 300_001
    x = offset + np.cumsum(np.cumsum(rng.normal(0, 0.01, n))) * T
    z = (x + rng.normal(size=n)).astype(dtype)
    z[rng.random(n) < nan_frac] = np.nan
    z[150_000:150_500] = np.nan  # a long coast across segment boundaries
    f = abkit.AlphaBetaFilter(alpha, beta, T)
    zc, zs = _pair(z)
    for threads in (1, 2):
        a = f.run(zc, threads=threads)
        b = f.run(zs, threads=1)
        assert np.array_equal(np.isnan(a.states), np.isnan(b.states))
        pscale = float(np.nanmax(np.abs(b.states[0].astype(np.float64))))
        tol = 1e-12 if dtype == np.float64 else 4 * float(np.finfo(np.float32).eps)
        dp = np.nanmax(np.abs(a.states[0].astype(np.float64) - b.states[0]))
        dv = np.nanmax(np.abs(a.states[1].astype(np.float64) - b.states[1]))
        assert dp <= tol * pscale and dv <= tol * pscale / T, (dp, dv, pscale)
        assert np.allclose(a.state.x, b.state.x, rtol=0, atol=tol * pscale / T)
    # thread count never changes the split result
    assert np.array_equal(f.run(zc, threads=1).states, f.run(zc, threads=2).states, equal_nan=True)


# ---------------------------------------------------------------------------
# The general kernel's split (alpha-beta-gamma, Singer with position and
# velocity, a 4-state 2-D model): same comparison, every state component
# within 1e-12 of its scale (component i: position scale / T^i).
# ---------------------------------------------------------------------------
import filterref as fr  # noqa: E402
from test_filters_compliance import _cv2d, _singer  # noqa: E402


def _general_cases():
    P, H, K, T = _singer(0.5)
    yield "singer-m2", abkit.FixedGainFilter(P, H, K, T), 2, T, np.array([1.0, 1 / T, 1 / T**2])
    P, H, K, T = _cv2d(1.0)
    yield "cv2d", abkit.FixedGainFilter(P, H, K, T), 2, T, np.array([1.0, 1.0, 1.0, 1.0])
    yield "abg", abkit.AlphaBetaGammaFilter(0.5, 0.3, 0.05, 0.1), 1, 0.1, np.array([1.0, 10.0, 100.0])
    yield "abg-slow", abkit.AlphaBetaGammaFilter(0.02, 2e-4, 1e-6, 1.0), 1, 1.0, np.array([1.0, 1.0, 1.0])


@pytest.mark.parametrize("case", list(_general_cases()), ids=lambda c: c[0])
@pytest.mark.parametrize("nan_frac", [0.0, 0.05])
@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_general_split_equals_sequential(case, nan_frac, dtype):
    name, f, m, T, comp_scale = case
    rng = np.random.default_rng(12)
    n = 250_003
    z = fr.kinematic_z(rng, 1, n, T, m=m)[0]
    z = np.asarray(z, dtype=float)
    z[rng.random(n) < nan_frac] = np.nan
    z[120_000:120_400] = np.nan
    z = z.astype(dtype)
    init = "first"
    # strided copy: never split
    big = np.empty((n, 2) + z.shape[1:], dtype=dtype)
    big[:, 0] = z
    zs = big[:, 0]
    b = f.run(zs, init=init, threads=1)
    for threads in (1, 2):
        a = f.run(z, init=init, threads=threads)
        assert np.array_equal(np.isnan(a.states), np.isnan(b.states))
        tol = 1e-12 if dtype == np.float64 else 4 * float(np.finfo(np.float32).eps)
        for i in range(f.n):
            bi = b.states[i].astype(np.float64)
            scale = float(np.nanmax(np.abs(bi)))
            d = float(np.nanmax(np.abs(a.states[i].astype(np.float64) - bi)))
            assert d <= tol * max(scale, 1e-300) * 1.0001 or d <= tol * float(np.nanmax(np.abs(b.states[0]))) * comp_scale[i], (name, i, d, scale)
    assert np.array_equal(f.run(z, init=init, threads=1).states, f.run(z, init=init, threads=2).states, equal_nan=True)


# ---------------------------------------------------------------------------
# Long tracks inside a ragged batch (offsets=): where the flat vector kernel
# runs (x86-64 with AVX2 + FMA, vector kernels not switched off) they are
# split exactly as when run alone (bit for bit: same segmentation, same
# arithmetic); everywhere within 1e-12 of the unsplit recursion; thread
# counts and streaming do not change that.
# ---------------------------------------------------------------------------
import os  # noqa: E402
import platform  # noqa: E402

from test_filters_avx2 import FLAGS  # noqa: E402

FLAT = (
    platform.machine() in ("x86_64", "AMD64")
    and {"avx2", "fma"} <= FLAGS
    and os.environ.get("ABKIT_DISABLE_SIMD", "0") == "0"
)


@pytest.mark.parametrize("nan_frac", [0.0, 0.05])
@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_ragged_long_tracks_split_as_alone(nan_frac, dtype):
    rng = np.random.default_rng(23)
    T = 0.1
    # long tracks (split) between short ones, a NaN-led long one, and few
    # tracks in all (most of the flat kernel's slots idle)
    lens = np.array([70_000, 30, 200_000, 5, 0, 3_000, 66_000, 12, 90_000])
    off = np.concatenate([[0], np.cumsum(lens)]).astype(np.int64)
    n = int(off[-1])
    z = (np.cumsum(np.cumsum(rng.normal(0, 0.01, n))) * T + rng.normal(size=n)).astype(dtype)
    z[rng.random(n) < nan_frac] = np.nan
    z[off[6] : off[6] + 40] = np.nan
    f = abkit.AlphaBetaFilter(0.5, 0.2, T)
    r = f.run(z, offsets=off, threads=1)
    assert np.array_equal(r.states, f.run(z, offsets=off, threads=2).states, equal_nan=True)
    seq = f.run(z, offsets=off, return_residuals=True)  # the unsplit scalar loop
    tol = 1e-12 if dtype == np.float64 else 4 * float(np.finfo(np.float32).eps)
    split_seen = False
    for i in range(len(lens)):
        a, b = int(off[i]), int(off[i + 1])
        if b == a:
            continue
        s = seq.states[:, a:b].astype(np.float64)
        alone = f.run(z[a:b], threads=1)
        if FLAT:
            assert np.array_equal(r.states[:, a:b], alone.states, equal_nan=True), i
            assert np.array_equal(r.state.x[i], np.reshape(alone.state.x, -1), equal_nan=True), i
        assert np.array_equal(np.isnan(r.states[:, a:b]), np.isnan(s))
        pscale = float(np.nanmax(np.abs(s[0])))
        dp = np.nanmax(np.abs(r.states[0, a:b] - s[0]))
        dv = np.nanmax(np.abs(r.states[1, a:b] - s[1]))
        assert dp <= tol * pscale and dv <= tol * pscale / T, (i, dp, dv, pscale)
        split_seen |= not np.array_equal(r.states[:, a:b], seq.states[:, a:b], equal_nan=True)
    # the long tracks did take the split (it rounds differently somewhere)
    assert split_seen or not FLAT
    # streaming: two calls with state= equal one call within the same bound
    half = (off[:-1] + off[1:]) // 2
    z1 = np.concatenate([z[off[i] : half[i]] for i in range(len(lens))])
    z2 = np.concatenate([z[half[i] : off[i + 1]] for i in range(len(lens))])
    o1 = np.concatenate([[0], np.cumsum(half - off[:-1])]).astype(np.int64)
    o2 = np.concatenate([[0], np.cumsum(off[1:] - half)]).astype(np.int64)
    r1 = f.run(z1, offsets=o1)
    r2 = f.run(z2, offsets=o2, state=r1.state)
    for i in range(len(lens)):
        a, b = int(off[i]), int(off[i + 1])
        if b == a:
            continue
        got = np.concatenate([r1.states[:, o1[i] : o1[i + 1]], r2.states[:, o2[i] : o2[i + 1]]], axis=1)
        s = seq.states[:, a:b].astype(np.float64)
        assert np.array_equal(np.isnan(got), np.isnan(s))
        pscale = float(np.nanmax(np.abs(s[0])))
        assert np.nanmax(np.abs(got[0] - s[0])) <= tol * pscale, i
        assert np.nanmax(np.abs(got[1] - s[1])) <= tol * pscale / T, i


# ---------------------------------------------------------------------------
# A long track with timestamps (rust/abkit-core/src/ragged_split.rs): split
# where the vector lanes of the track kernel run, compared with the unsplit
# sequential loop (return_residuals=True never splits) within 1e-12 of each
# state's scale; dropped and restarted counts exactly; thread counts give the
# same bits; errors name the same track and sample.
# ---------------------------------------------------------------------------
def _timed_track(rng, n, dtype, nan_frac, dup_frac, gaps):
    dt = rng.uniform(0.05, 0.15, n)
    dt[rng.random(n) < dup_frac] = 0.0  # repeated timestamps
    if gaps:
        dt[rng.choice(n, gaps, replace=False)] = 50.0  # silences
    t = 1e3 + np.cumsum(dt)
    x = np.cumsum(np.cumsum(rng.normal(0, 0.01, n))) * 0.1 + 20.0 * np.sin(t / 300.0)
    z = (x + rng.normal(size=n)).astype(dtype)
    z[rng.random(n) < nan_frac] = np.nan
    return z, t


def _close_to_sequential(r, seq, T, tol):
    assert np.array_equal(np.isnan(r.states), np.isnan(seq.states))
    s = seq.states.astype(np.float64)
    pscale = float(np.nanmax(np.abs(s[0])))
    dp = np.nanmax(np.abs(r.states[0] - s[0]))
    dv = np.nanmax(np.abs(r.states[1] - s[1]))
    assert dp <= tol * pscale and dv <= tol * pscale / T, (dp, dv, pscale)
    assert np.allclose(r.state.x, seq.state.x, rtol=0, atol=tol * pscale / T, equal_nan=True)
    assert np.array_equal(r.n_dropped, seq.n_dropped)
    assert np.array_equal(r.n_restarts, seq.n_restarts)
    return not np.array_equal(r.states, seq.states, equal_nan=True)


TIMED = [
    # schedule, nan_frac, dup_frac, gaps, NaN-led
    ("design", 0.0, 0.0, 0, False),
    ("fixed", 0.0, 0.0, 0, False),
    ("design", 0.05, 0.01, 0, False),
    ("fixed", 0.05, 0.01, 7, False),
    ("design", 0.2, 0.0, 30, True),
]


@pytest.mark.parametrize("case", TIMED, ids=lambda c: "-".join(map(str, c)))
@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_timed_long_track_split_equals_sequential(case, dtype):
    schedule, nan_frac, dup_frac, gaps, nan_led = case
    rng = np.random.default_rng(41)
    T = 0.1
    n = 400_003
    z, t = _timed_track(rng, n, dtype, nan_frac, dup_frac, gaps)
    if nan_led:
        z[:130_000] = np.nan  # the first segments never start: run again in order
        z[200_000:260_000] = np.nan  # a long coast across segment boundaries
    f = abkit.AlphaBetaFilter.from_noise(0.5, 1.0, T) if schedule == "design" else abkit.AlphaBetaFilter(0.5, 0.2, T)
    assert f.gain_schedule == schedule
    kw = dict(on_duplicate="drop") if dup_frac else {}
    if gaps:
        kw["max_gap"] = 10.0
    tol = 1e-12 if dtype == np.float64 else 4 * float(np.finfo(np.float32).eps)
    r1 = f.run(z, t=t, threads=1, **kw)
    r2 = f.run(z, t=t, threads=2, **kw)
    assert np.array_equal(r1.states, r2.states, equal_nan=True)
    seq = f.run(z, t=t, return_residuals=True, **kw)
    split = _close_to_sequential(r1, seq, T, tol)
    if FLAT:
        assert split  # the split did run (it rounds differently somewhere)
    if gaps:
        assert r1.n_restarts[0] == seq.n_restarts[0] > 0
    if dup_frac:
        assert r1.n_dropped[0] == seq.n_dropped[0] > 0


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_timed_few_long_tracks_ragged_and_per_track_gains(dtype):
    rng = np.random.default_rng(43)
    T = 0.1
    lens = np.array([250_000, 40, 180_000, 0, 3])
    off = np.concatenate([[0], np.cumsum(lens)]).astype(np.int64)
    n = int(off[-1])
    z, t = _timed_track(rng, n, dtype, 0.03, 0.0, 0)
    # timestamps restart per track (each track increasing on its own)
    for i in range(len(lens)):
        t[off[i] : off[i + 1]] -= t[off[i]] - 5.0 * i
    tol = 1e-12 if dtype == np.float64 else 4 * float(np.finfo(np.float32).eps)
    for f in (abkit.AlphaBetaFilter.from_noise(0.5, 1.0, T), abkit.AlphaBetaFilter(np.array([0.5, 0.3, 0.6, 0.5, 0.4]), 0.1, T)):
        r = f.run(z, t=t, offsets=off)
        seq = f.run(z, t=t, offsets=off, return_residuals=True)
        for i in range(len(lens)):
            a, b = int(off[i]), int(off[i + 1])
            if b - a < 2:
                continue
            s = seq.states[:, a:b].astype(np.float64)
            pscale = float(np.nanmax(np.abs(s[0])))
            assert np.nanmax(np.abs(r.states[0, a:b] - s[0])) <= tol * pscale, i
            assert np.nanmax(np.abs(r.states[1, a:b] - s[1])) <= tol * pscale / T, i
        assert np.allclose(r.state.x, seq.state.x, rtol=0, atol=tol * 1e3 / T, equal_nan=True)
    # streaming a long timed track: two calls with state= (each split) equal
    # the sequential run within the bound
    f = abkit.AlphaBetaFilter.from_noise(0.5, 1.0, T)
    zz, tt = z[off[0] : off[1]], t[off[0] : off[1]]
    h = 130_001
    r1 = f.run(zz[:h], t=tt[:h])
    r2 = f.run(zz[h:], t=tt[h:], state=r1.state)
    got = np.concatenate([r1.states, r2.states], axis=1)
    seq = f.run(zz, t=tt, return_residuals=True)
    s = seq.states.astype(np.float64)
    pscale = float(np.nanmax(np.abs(s[0])))
    assert np.array_equal(np.isnan(got), np.isnan(s))
    assert np.nanmax(np.abs(got[0] - s[0])) <= tol * pscale
    assert np.nanmax(np.abs(got[1] - s[1])) <= tol * pscale / T


def test_timed_split_errors_name_the_sample():
    rng = np.random.default_rng(47)
    n = 300_000
    z, t = _timed_track(rng, n, np.float64, 0.0, 0.0, 0)
    t[250_001] = t[250_000]  # a repeated timestamp in a late segment
    f = abkit.AlphaBetaFilter(0.5, 0.2, 0.1)
    with pytest.raises(ValueError) as split_err:
        f.run(z, t=t)
    with pytest.raises(ValueError) as seq_err:
        f.run(z, t=t, return_residuals=True)
    assert str(split_err.value) == str(seq_err.value)
    assert "sample 250001" in str(split_err.value)
