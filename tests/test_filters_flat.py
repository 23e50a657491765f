"""The flat alpha-beta vector kernel (rust/abkit-core/src/filter_flat.rs on
AVX-512 CPUs, its generic form rust/abkit-core/src/filter_flat_vec.rs with 4
AVX2 slots on CPUs with AVX2 + FMA only; opt-in ABKIT_FLAT_AVX512=1 runs the
generic form with 8 AVX-512 slots; ABKIT_FLAT_AVX2=1 the AVX2 form on
AVX-512 CPUs too; on an AMD Zen 4 ragged float64 batches take the AVX2 form
by default, and ABKIT_FLAT_AVX2=0 keeps them in the AVX-512 kernel):
short rows (fewer than 256 samples) of a batch, and ragged batches without
timestamps, run as one flat sequence of back-to-back tracks whose vector
slots cross track boundaries (fresh tracks started in the vector steps,
other start-ups scalar into a per-slot stage, state replacement at the
first running sample, final states read at the last).

It runs only without residuals, so ``run(z)`` (flat kernel) is compared
with ``run(z, return_residuals=True)`` (the scalar per-track loop): the
arithmetic per running sample is the same, so the states must be
**bit-identical**, and both match the independent NumPy reference
(tests/filterref.py; float64 within 1e-12 of the array's scale, float32
within 0.5 ulp + 1e-12 of the scale). The ragged case is also compared with
the scalar track kernel of another process (``ABKIT_DISABLE_SIMD=1``).

Cases: row lengths 1..255 (every alignment and block position of the
boundaries), tracks shorter than a block, many tracks (several regions per
slot and slot refills), NaN patterns incl. NaN-led and all-NaN tracks
(start-ups longer than a block), per-track gains, every init mode, streaming
with state=, outputs >= 64 MiB (non-temporal stores), smoothing, +-Inf
measurements.
"""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

import filterref as fr
from abkit import AlphaBetaFilter
from test_filters_compliance import assert_f32_rounded

RTOL = 1e-12


def _z(rng, shape, pattern, dtype):
    z = np.cumsum(rng.normal(0, 1.0, shape), axis=-1) + rng.normal(0, 0.5, shape)
    flat = z.reshape(-1)
    if pattern == "random":
        flat[rng.random(flat.size) < 0.1] = np.nan
    elif pattern == "dense":
        flat[rng.random(flat.size) < 0.7] = np.nan
    elif pattern == "runs":
        for _ in range(max(1, flat.size // 50)):
            a = int(rng.integers(0, flat.size))
            flat[a : a + int(rng.integers(1, 30))] = np.nan
    return z.astype(dtype)


def _check(f, z, **kw):
    flat = f.run(z, **kw)
    scalar = f.run(z, return_residuals=True, **kw)
    assert np.array_equal(flat.states, scalar.states, equal_nan=True)
    assert np.array_equal(flat.state.x, scalar.state.x, equal_nan=True)
    assert np.array_equal(flat.state._packed, scalar.state._packed, equal_nan=True)
    return flat


CASES = [
    (ntr, n, pat, dt)
    for ntr, n in [(1, 1), (3, 2), (50, 1), (41, 3), (97, 7), (130, 9), (64, 16), (33, 17), (300, 31), (257, 100), (90, 255)]
    for pat in ["none", "random", "dense", "runs"]
    for dt in [np.float64, np.float32]
]


@pytest.mark.parametrize("ntr,n,pattern,dtype", CASES)
def test_short_rows_bit_identical_to_scalar_and_match_reference(ntr, n, pattern, dtype):
    rng = np.random.default_rng(ntr * 1000 + n)
    z = _z(rng, (ntr, n), pattern, dtype)
    a, b = 0.45, 0.2
    f = AlphaBetaFilter(a, b, 0.1)
    r = _check(f, z)
    s, _, _ = fr.run_ref(z, fr.ab_model(a, b, 0.1), "two-point")
    if dtype == np.float64:
        fr.assert_states_close(r.states, s, RTOL)
    else:
        assert_f32_rounded(r.states, s)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
@pytest.mark.parametrize("init", ["two-point", "first", "array"])
def test_short_rows_per_track_gains_and_inits(dtype, init):
    rng = np.random.default_rng(21)
    ntr, n = 700, 37
    z = _z(rng, (ntr, n), "random", dtype)
    z[::11, :5] = np.nan  # NaN-led tracks
    z[::29] = np.nan  # all-NaN tracks
    a = rng.uniform(0.05, 0.95, ntr)
    b = rng.uniform(0.01, 0.5, ntr) * a
    T = rng.uniform(0.01, 5.0, ntr)
    iv = rng.normal(0, 3, (ntr, 2)) if init == "array" else init
    _check(AlphaBetaFilter(a, b, T), z, init=iv)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_short_rows_streaming_bit_identical(dtype):
    rng = np.random.default_rng(23)
    z = _z(rng, (500, 200), "runs", dtype)
    f = AlphaBetaFilter(0.6, 0.25, 0.5)
    whole = f.run(z)
    parts, st = [], None
    for a, b in [(0, 1), (1, 2), (2, 9), (9, 77), (77, 200)]:
        r = f.run(z[:, a:b], state=st)
        parts.append(r.states)
        st = r.state
    assert np.array_equal(np.concatenate(parts, axis=2), whole.states, equal_nan=True)
    assert np.array_equal(st._packed, whole.state._packed, equal_nan=True)


@pytest.mark.parametrize("threads", [1, 2, 3])
def test_short_rows_threads_bit_identical(threads):
    rng = np.random.default_rng(25)
    z = _z(rng, (6000, 50), "random", np.float64)
    f = AlphaBetaFilter(0.5, 0.1, 1.0)
    assert np.array_equal(f.run(z, threads=threads).states, f.run(z, threads=1).states, equal_nan=True)


@pytest.mark.parametrize(
    "dtype,ntr,n",
    [(np.float64, 42_000, 100), (np.float32, 42_000, 200), (np.float64, 41_999, 100), (np.float64, 21_001, 301), (np.float32, 41_999, 201)],
)
def test_short_rows_large_output_streamed(dtype, ntr, n):
    # 2 x ntr x n outputs >= 64 MiB: non-temporal stores of whole lines.
    # With ntr x n not a multiple of 8 (float64) the v row's lines lie off
    # the x row's: the flat kernel streams v lines put together from two
    # consecutive blocks of a slot.
    rng = np.random.default_rng(27)
    z = _z(rng, (ntr, n), "random", dtype)
    f = AlphaBetaFilter(0.4, 0.1, 1.0)
    flat = f.run(z)
    idx = np.r_[0:9, 20_000:20_017, ntr - 10 : ntr]
    scalar = f.run(z[idx], return_residuals=True)
    assert np.array_equal(flat.states[:, idx], scalar.states, equal_nan=True)
    out = np.empty_like(flat.states)
    again = f.run(z, out=out)
    assert again.states is out and np.array_equal(out, flat.states, equal_nan=True)


@pytest.mark.parametrize(
    "dtype,ntr,n",
    [
        (np.float64, 30_000, 20), (np.float64, 30_000, 70), (np.float64, 230_000, 20), (np.float32, 30_000, 60), (np.float32, 70_000, 9),
        (np.float64, 6_000, 256), (np.float64, 1_500, 1_024), (np.float64, 400, 4_096), (np.float32, 3_000, 512), (np.float64, 7_001, 200),
    ],
)
def test_short_rows_in_memory_bit_identical(dtype, ntr, n):
    # Batches bigger than the caches. Rows of <= 80 samples (float32: <= 64)
    # run in the AVX2 short-row lanes on AVX2-only CPUs (230,000 x 20
    # float64: outputs >= 64 MiB, streamed through the stages). From 32 MiB
    # (z and outputs) rows a multiple of 2 KiB long with streamed outputs
    # run in the AVX2 flat kernel (AVX2-only CPUs, and float64 on an AMD
    # Zen 4, where rows shorter than 256 take it too). Every track equals
    # the scalar row kernel's (residuals on: no flat or short-row kernel)
    # bit for bit, for one thread and for two.
    rng = np.random.default_rng(29)
    z = _z(rng, (ntr, n), "random", dtype)
    f = AlphaBetaFilter(0.45, 0.12, 1.0)
    big = f.run(z, threads=1)
    idx = np.r_[0:9, ntr // 2 : ntr // 2 + 17, ntr - 10 : ntr]
    scalar = f.run(z[idx], return_residuals=True)
    assert np.array_equal(big.states[:, idx], scalar.states, equal_nan=True)
    assert np.array_equal(big.state._packed[idx], scalar.state._packed, equal_nan=True)
    assert np.array_equal(f.run(z, threads=2).states, big.states, equal_nan=True)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_short_rows_smooth_bit_identical(dtype):
    rng = np.random.default_rng(29)
    z = _z(rng, (300, 60), "random", dtype)
    f = AlphaBetaFilter(0.5, 0.15, 0.2)
    a = f.smooth(z)
    b = f.smooth(z, return_residuals=True)
    assert np.array_equal(a.states, b.states, equal_nan=True)


def _ragged(rng, max_len, n_tracks, dtype, pattern):
    lens = rng.integers(0, max_len + 1, n_tracks)
    lens[rng.random(n_tracks) < 0.05] = 0
    off = np.concatenate([[0], np.cumsum(lens)]).astype(np.int64)
    z = _z(rng, (int(off[-1]),), pattern, dtype)
    return z, off


RAGGED = [(ml, nt, pat, dt) for ml, nt in [(3, 400), (12, 300), (40, 200), (300, 60), (3000, 12)] for pat in ["none", "random", "runs"] for dt in [np.float64, np.float32]]


@pytest.mark.parametrize("max_len,n_tracks,pattern,dtype", RAGGED)
def test_ragged_bit_identical_to_scalar_and_to_each_track_alone(max_len, n_tracks, pattern, dtype):
    rng = np.random.default_rng(max_len * 7 + n_tracks)
    z, off = _ragged(rng, max_len, n_tracks, dtype, pattern)
    f = AlphaBetaFilter.from_noise(1.5, 4.0, 0.1)
    r = _check(f, z, offsets=off)
    for i in rng.choice(n_tracks, 8, replace=False):
        a, b = int(off[i]), int(off[i + 1])
        if b > a:
            alone = f.run(z[a:b], return_residuals=True)
            assert np.array_equal(r.states[:, a:b], alone.states, equal_nan=True)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_ragged_per_track_gains_inits_smooth(dtype):
    rng = np.random.default_rng(31)
    z, off = _ragged(rng, 50, 500, dtype, "random")
    n = len(off) - 1
    f = AlphaBetaFilter(rng.uniform(0.1, 0.9, n), rng.uniform(0.01, 0.1, n), 0.3)
    for init in ["two-point", "first"]:
        _check(f, z, offsets=off, init=init)
    a = f.smooth(z, offsets=off)
    b = f.smooth(z, offsets=off, return_residuals=True)
    assert np.array_equal(a.states, b.states, equal_nan=True)


def test_ragged_inf_named_after_the_run():
    rng = np.random.default_rng(33)
    z, off = _ragged(rng, 30, 100, np.float64, "random")
    f = AlphaBetaFilter(0.5, 0.1, 1.0)
    i = int(np.flatnonzero(np.diff(off) > 10)[3])
    z[off[i] + 7] = -np.inf
    with pytest.raises(ValueError, match=rf"track {i}, sample 7: z must be finite or NaN \(a missed detection\), got -inf"):
        f.run(z, offsets=off)
    # an Inf as the first (start-up) sample of a track, too
    z[off[i] + 7] = 1.0
    z[off[i]] = np.inf
    with pytest.raises(ValueError, match=rf"track {i}, sample 0: .* got inf"):
        f.run(z, offsets=off)


# The kernel switches (read once per process): tests set them in children.
_SWITCHES = (
    "ABKIT_DISABLE_SIMD",
    "ABKIT_FLAT_AVX512",
    "ABKIT_FLAT_AVX2",
    "ABKIT_SHORT_ROWS_FLAT",
    "ABKIT_ROWS16",
    "ABKIT_ZEN4",
)


def test_flat_kernel_equals_scalar_track_kernel_bitwise(tmp_path):
    # The same short rows and ragged batch in a process with the vector
    # kernels switched off (ABKIT_DISABLE_SIMD=1: scalar lanes and the
    # scalar track kernel) gives the same bits.
    code = r"""
import sys, numpy as np
from abkit import AlphaBetaFilter
rng = np.random.default_rng(5)
res = {}
for k, dt in enumerate([np.float64, np.float32]):
    for init in ["two-point", "first"]:
        z = rng.normal(size=(3000, 45)).cumsum(1).astype(dt)
        z[rng.random(z.shape) < 0.1] = np.nan
        z[::7, 0] = -0.0  # signed zeros at track starts (first-sample rates)
        res[f"rows{k}{init}"] = AlphaBetaFilter(0.4, 0.1, 0.5).run(z, init=init).states
        z = rng.normal(size=(20000, 100)).cumsum(1).astype(dt)  # from memory
        z[rng.random(z.shape) < 0.01] = np.nan
        res[f"rows100{k}{init}"] = AlphaBetaFilter(0.4, 0.1, 0.5).run(z, init=init).states
        # rows of 4 KiB / 8 (float64 rows of 128) from memory: the short-row
        # lanes on AVX2-only CPUs, the flat kernel with ABKIT_SHORT_ROWS_FLAT=1
        z = rng.normal(size=(12000, 128)).cumsum(1).astype(dt)
        z[rng.random(z.shape) < 0.01] = np.nan
        res[f"rows128{k}{init}"] = AlphaBetaFilter(0.4, 0.1, 0.5).run(z, init=init).states
        lens = rng.integers(0, 200, 700)
        off = np.concatenate([[0], np.cumsum(lens)]).astype(np.int64)
        zr = rng.normal(size=int(off[-1])).cumsum().astype(dt) - 5.0
        zr[rng.random(zr.size) < 0.1] = np.nan
        zr[off[:-1:5][lens[::5] > 0]] = -0.0
        r = AlphaBetaFilter.from_noise(2.0, 5.0, 0.1).run(zr, offsets=off, init=init)
        res[f"ragged{k}{init}"] = r.states
        res[f"state{k}{init}"] = r.state._packed
np.savez(sys.argv[1] + "/" + sys.argv[2] + ".npz", **res)
"""
    # Also the AVX2 flat kernel (ABKIT_FLAT_AVX2=1, the flat paths of an
    # AVX2-only CPU, on AVX-512 CPUs too) and the generic kernel at 8 lanes
    # (ABKIT_FLAT_AVX512=1), short rows forced into the flat kernels; and
    # the sixteen-row AVX-512 lanes (ABKIT_ROWS16=1).
    runs = (
        ("on", {}),
        ("avx512", {"ABKIT_FLAT_AVX2": "0"}),  # Zen 4's ragged f64 in the AVX-512 kernel
        ("nozen4", {"ABKIT_ZEN4": "0"}),  # Zen 4's ragged f64: the AVX2 kernel without AVX-512VL
        ("rows16", {"ABKIT_ROWS16": "1"}),
        ("avx2", {"ABKIT_FLAT_AVX2": "1", "ABKIT_SHORT_ROWS_FLAT": "1"}),
        ("gen", {"ABKIT_FLAT_AVX512": "1", "ABKIT_SHORT_ROWS_FLAT": "1"}),
        ("off", {"ABKIT_DISABLE_SIMD": "1"}),
    )
    for tag, extra in runs:
        e = dict(os.environ)
        for k in _SWITCHES:
            e.pop(k, None)
        e.update(extra)
        subprocess.run([sys.executable, "-c", code, str(tmp_path), tag], check=True, env=e)
    off = np.load(tmp_path / "off.npz")
    for tag, _ in runs[:-1]:
        on = np.load(tmp_path / f"{tag}.npz")
        for k in on.files:
            a, b = on[k], off[k]
            # bit for bit (signed zeros too), NaN where NaN
            assert np.array_equal(np.isnan(a), np.isnan(b)), (tag, k)
            ok = ~np.isnan(a)
            assert np.array_equal(a[ok].view(np.uint8), b[ok].view(np.uint8)), (tag, k)


# ---------------------------------------------------------------------------
# Boundary conditions of the flat kernel on every CPU it runs on (AVX-512:
# filter_flat.rs, AVX2: filter_flat_vec.rs with 4 slots; on CPUs with
# neither, these compare the scalar paths with each other and still hold).
# ---------------------------------------------------------------------------


def _ragged_lens(rng, lens, dtype, pattern):
    off = np.concatenate([[0], np.cumsum(lens)]).astype(np.int64)
    z = _z(rng, (int(off[-1]),), pattern, dtype)
    return z, off


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
@pytest.mark.parametrize("pattern", ["none", "random", "runs"])
def test_ragged_tiny_tracks_every_boundary(dtype, pattern):
    # Tracks of 0..3 samples (start-ups that end inside the same block, or
    # never run), around a block (7..9, 15..17), and longer ones, in many
    # orders: boundaries at every position of a block, several per block.
    rng = np.random.default_rng(41 if dtype == np.float64 else 43)
    lens = rng.choice([0, 1, 2, 3, 4, 5, 7, 8, 9, 15, 16, 17, 33, 100], 2500)
    z, off = _ragged_lens(rng, lens, dtype, pattern)
    f = AlphaBetaFilter(0.35, 0.07, 0.25)
    r = _check(f, z, offsets=off)
    for i in rng.choice(len(lens), 40, replace=False):
        a, b = int(off[i]), int(off[i + 1])
        if b > a:
            alone = f.run(z[a:b], return_residuals=True)
            assert np.array_equal(r.states[:, a:b], alone.states, equal_nan=True)
            assert np.array_equal(r.state._packed[i], alone.state._packed[0], equal_nan=True)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_ragged_nan_led_all_nan_and_nan_mid_track(dtype):
    rng = np.random.default_rng(45)
    lens = rng.integers(0, 60, 1500)
    z, off = _ragged_lens(rng, lens, dtype, "none")
    for i in range(len(lens)):
        a, b = int(off[i]), int(off[i + 1])
        if b == a:
            continue
        kind = i % 5
        if kind == 0:
            z[a : a + int(rng.integers(1, b - a + 1))] = np.nan  # NaN-led (maybe all)
        elif kind == 1:
            z[a:b] = np.nan  # all-NaN
        elif kind == 2:
            z[a + (b - a) // 2] = np.nan  # one NaN mid-track
        elif kind == 3:
            z[a + 1 : b : 2] = np.nan  # every other sample (start-up spans)
    n = len(lens)
    per_track = AlphaBetaFilter(rng.uniform(0.05, 0.95, n), rng.uniform(0.001, 0.05, n), 0.4)
    for f in [AlphaBetaFilter(0.5, 0.12, 1.0), per_track]:
        for init in ["two-point", "first"]:
            _check(f, z, offsets=off, init=init)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
@pytest.mark.parametrize("total_mod", [0, 3, 5])
def test_ragged_large_output_streamed(dtype, total_mod):
    # A ragged batch with streamed outputs (>= 8 MiB) whose total is 0, 3
    # or 5 modulo 8 (v's lines off x's for 3 and 5): every track equals the
    # scalar track code's (residuals on) bit for bit, states too.
    rng = np.random.default_rng(61 + total_mod)
    lens = rng.integers(10, 1_000, 6_000)
    lens[-1] += (total_mod - int(lens.sum())) % 8
    off = np.concatenate([[0], np.cumsum(lens)]).astype(np.int64)
    z = _z(rng, (int(off[-1]),), "random", dtype)
    f = AlphaBetaFilter(0.5, 0.15, 0.2)
    r = f.run(z, offsets=off)
    ref = f.run(z, offsets=off, return_residuals=True)
    assert int(off[-1]) % 8 == total_mod
    assert np.array_equal(r.states, ref.states, equal_nan=True)
    assert np.array_equal(r.state._packed, ref.state._packed, equal_nan=True)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
@pytest.mark.parametrize("shift", [0, 1, 3, 5, 7, 13])
def test_short_rows_misaligned_buffers(dtype, shift):
    # z and out= at element offsets: blocks follow the x output's lines,
    # so x and v (and z) fall at different positions within their lines.
    rng = np.random.default_rng(47 + shift)
    ntr, n = 211, 23
    base = _z(rng, (ntr * n + 16,), "random", dtype)
    z = base[shift : shift + ntr * n].reshape(ntr, n)
    f = AlphaBetaFilter(0.55, 0.2, 0.3)
    ref = f.run(z, return_residuals=True)
    buf = np.empty(2 * ntr * n + 16, dtype)
    out = buf[shift : shift + 2 * ntr * n].reshape(2, ntr, n)
    r = f.run(z, out=out)
    assert r.states is out
    assert np.array_equal(out, ref.states, equal_nan=True)
    assert np.array_equal(r.state._packed, ref.state._packed, equal_nan=True)
    # the ragged path with the same buffers
    off = np.concatenate([[0], np.cumsum(rng.integers(0, 40, 150))]).astype(np.int64)
    zr = base[shift : shift + int(off[-1])]
    outr = buf[shift : shift + 2 * int(off[-1])].reshape(2, -1)
    rr = f.run(zr, offsets=off, out=outr)
    refr = f.run(zr, offsets=off, return_residuals=True)
    assert np.array_equal(outr, refr.states, equal_nan=True)
    assert np.array_equal(rr.state._packed, refr.state._packed, equal_nan=True)


@pytest.mark.parametrize("threads", [1, 2, 3, 5, 8])
def test_ragged_threads_bit_identical(threads):
    rng = np.random.default_rng(49)
    z, off = _ragged(rng, 300, 3000, np.float64, "random")
    f = AlphaBetaFilter(0.5, 0.1, 1.0)
    a = f.run(z, offsets=off, threads=threads)
    b = f.run(z, offsets=off, threads=1)
    assert np.array_equal(a.states, b.states, equal_nan=True)
    assert np.array_equal(a.state._packed, b.state._packed, equal_nan=True)


@pytest.mark.parametrize("threads", [2, 5, 8])
def test_short_rows_more_threads_bit_identical(threads):
    rng = np.random.default_rng(51)
    z = _z(rng, (9000, 41), "runs", np.float32)
    f = AlphaBetaFilter(rng.uniform(0.2, 0.8, 9000), 0.05, 1.0)
    a = f.run(z, threads=threads)
    b = f.run(z, return_residuals=True, threads=1)
    assert np.array_equal(a.states, b.states, equal_nan=True)
    assert np.array_equal(a.state._packed, b.state._packed, equal_nan=True)


_CHILD = r"""
import sys, numpy as np
from abkit import AlphaBetaFilter
rng = np.random.default_rng(7)
res = {}
for k, dt in enumerate([np.float64, np.float32]):
    for n in (1, 2, 3, 4, 9, 17, 100, 255):
        z = rng.normal(size=(997, n)).cumsum(1).astype(dt)
        z[rng.random(z.shape) < 0.15] = np.nan
        z[::7, : max(1, n // 3)] = np.nan
        z[::13] = np.nan
        a = rng.uniform(0.1, 0.9, 997)
        for g, f in enumerate([AlphaBetaFilter(0.4, 0.1, 0.5), AlphaBetaFilter(a, 0.3 * a * a, 0.2)]):
            for init in ("two-point", "first"):
                r = f.run(z, init=init)
                res[f"rows{k}_{n}_{g}_{init}"] = r.states
                res[f"rst{k}_{n}_{g}_{init}"] = r.state._packed
    lens = rng.choice([0, 1, 2, 3, 5, 8, 16, 31, 250, 3000], 900)
    off = np.concatenate([[0], np.cumsum(lens)]).astype(np.int64)
    zr = rng.normal(size=int(off[-1])).cumsum().astype(dt)
    zr[rng.random(zr.size) < 0.1] = np.nan
    for i in range(0, 900, 11):
        zr[off[i] : off[i + 1]] = np.nan
    m = len(lens)
    for g, f in enumerate([AlphaBetaFilter.from_noise(2.0, 5.0, 0.1), AlphaBetaFilter(rng.uniform(0.1, 0.9, m), 0.02, 0.3)]):
        for thr in (1, 3):
            r = f.run(zr, offsets=off, threads=thr)
            res[f"ragged{k}_{g}_{thr}"] = r.states
            res[f"state{k}_{g}_{thr}"] = r.state._packed
        res[f"sm{k}_{g}"] = f.smooth(zr, offsets=off).states
np.savez(sys.argv[1] + "/" + sys.argv[2] + ".npz", **res)
"""


def test_flat_kernels_equal_scalar_lanes_bitwise_in_child_processes(tmp_path):
    # Default (the flat kernel of this CPU), the generic kernel's AVX-512
    # instance where the CPU has AVX-512 (opt-in ABKIT_FLAT_AVX512=1; on
    # other CPUs the variable changes nothing), the AVX2 flat kernel
    # (ABKIT_FLAT_AVX2=1, on AVX-512 CPUs too) and the scalar lanes and
    # track kernel (ABKIT_DISABLE_SIMD=1): the same bits. Short rows run in
    # the AVX2 short-row lanes by default on AVX2-only CPUs (small batches)
    # and in the flat kernel with ABKIT_SHORT_ROWS_FLAT=1: the same bits.
    runs = (
        ("on", {}),
        ("avx512", {"ABKIT_FLAT_AVX2": "0"}),  # Zen 4's ragged f64 in the AVX-512 kernel
        ("nozen4", {"ABKIT_ZEN4": "0"}),  # Zen 4's ragged f64: the AVX2 kernel without AVX-512VL
        ("gen", {"ABKIT_FLAT_AVX512": "1"}),
        ("flat", {"ABKIT_SHORT_ROWS_FLAT": "1"}),
        ("avx2", {"ABKIT_FLAT_AVX2": "1", "ABKIT_SHORT_ROWS_FLAT": "1"}),
        ("off", {"ABKIT_DISABLE_SIMD": "1"}),
    )
    for tag, extra in runs:
        e = dict(os.environ)
        for k in _SWITCHES:
            e.pop(k, None)
        e.update(extra)
        subprocess.run([sys.executable, "-c", _CHILD, str(tmp_path), tag], check=True, env=e)
    off = np.load(tmp_path / "off.npz")
    for tag, _ in runs[:-1]:
        on = np.load(tmp_path / f"{tag}.npz")
        assert len(on.files) > 100
        for k in on.files:
            assert np.array_equal(on[k], off[k], equal_nan=True), (tag, k)
