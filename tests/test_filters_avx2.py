"""The alpha-beta row lanes on CPUs with AVX2 + FMA but no AVX-512.

There the 8 tracks of a lane group run as two 4-wide AVX2 registers (lanes
0-3 and 4-7; rust/abkit-core/src/filter_avx2.rs) for rows of at least 256
samples; on AVX-512 CPUs the same tests exercise the AVX-512 lanes, and on
CPUs with neither the scalar lanes. The vector lanes promise the scalar
arithmetic exactly (docs/filtering.md), so ``run(z)`` (lanes) must be
**bit-identical** to ``run(z, return_residuals=True)`` (one scalar loop per
track) and to a process with ``ABKIT_DISABLE_SIMD=1`` (scalar lanes), and
match the independent NumPy reference (tests/filterref.py) at the compliance
tolerance (1e-12 of the array's scale; float32: within 0.5 ulp + 1e-12
scale).

Cases: row lengths around 256 and the 8/16-sample blocks (256..300), 1000,
4099; track counts not multiples of 8; rows and outputs at every element
alignment (offset and strided views, ``out=`` at an offset), per-track
gains, NaN patterns (random, runs, leading, all-NaN rows), streaming in
chunks, threads 1 and 2, outputs >= 64 MiB (non-temporal stores), and the
split single long track (which runs lane groups too).
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


def _cpu_flags() -> set:
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("flags"):
                    return set(line.split(":", 1)[1].split())
    except OSError:
        pass
    return set()


FLAGS = _cpu_flags()
AVX2_ONLY = {"avx2", "fma"} <= FLAGS and "avx512f" not in FLAGS


def _z(rng, ntr, n, pattern, dtype):
    t = np.arange(n)
    z = 3.0 + 0.7 * t + rng.normal(0, 2.0, (ntr, n))
    if pattern == "random":
        z[rng.random((ntr, n)) < 0.1] = np.nan
    elif pattern == "runs":
        for i in range(ntr):
            a = int(rng.integers(0, n))
            z[i, a : a + int(rng.integers(1, 40))] = np.nan
    elif pattern == "leading":
        for i in range(ntr):
            z[i, : int(rng.integers(0, min(n, 40)))] = np.nan
    elif pattern == "all-nan":
        z[::5] = np.nan
    return z.astype(dtype)


def _same(a, b):
    return np.array_equal(a, b, equal_nan=True)


def _check(f, z, **kw):
    lanes = f.run(z, **kw)
    scalar = f.run(z, return_residuals=True, **kw)
    assert _same(lanes.states, scalar.states)
    assert _same(lanes.state.x, scalar.state.x)
    return lanes


def test_cpu_report():
    # Not a check: records in the test log which vector lanes ran here.
    print("AVX2 without AVX-512:", AVX2_ONLY)


CASES = [
    (ntr, n, pat, dt)
    for ntr, n in [(8, 256), (9, 257), (11, 263), (8, 264), (13, 271), (16, 272), (17, 279), (23, 288), (8, 300), (21, 1000), (13, 4099)]
    for pat in ["none", "random", "runs", "leading", "all-nan"]
    for dt in [np.float64, np.float32]
]


@pytest.mark.parametrize("ntr,n,pattern,dtype", CASES)
def test_avx2_lanes_bit_identical_and_match_reference(ntr, n, pattern, dtype):
    rng = np.random.default_rng(ntr * 10007 + n)
    z = _z(rng, ntr, n, pattern, dtype)
    a, b = 0.45, 0.2
    f = AlphaBetaFilter(a, b, 0.1)
    r = _check(f, z)
    s, _, _ = fr.run_ref(z, fr.ab_model(a, b, 0.1), "two-point")
    if dtype == np.float64:
        fr.assert_states_close(r.states, s, RTOL)
    else:
        assert_f32_rounded(r.states, s)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_avx2_every_alignment_of_rows_and_outputs(dtype):
    # Rows of z start at every element offset (a row length that is not a
    # multiple of 16 in a contiguous array, plus an offset into a bigger
    # buffer), and so do the x and v output rows (out= at an offset).
    rng = np.random.default_rng(17)
    ntr, n = 19, 261
    f = AlphaBetaFilter(0.35, 0.08, 0.25)
    z0 = _z(rng, ntr, n, "random", dtype)
    want = f.run(z0, return_residuals=True).states
    for off in range(16):
        buf = np.full(ntr * n + 16, np.nan, dtype)
        z = buf[off : off + ntr * n].reshape(ntr, n)
        z[...] = z0
        obuf = np.full(2 * ntr * n + 16, -1.0, dtype)
        out = obuf[off : off + 2 * ntr * n].reshape(2, ntr, n)
        r = f.run(z, out=out)
        assert r.states is out
        assert _same(out, want), off
        # nothing written outside out
        assert np.all(obuf[:off] == -1.0) and np.all(obuf[off + 2 * ntr * n :] == -1.0)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_avx2_strided_views(dtype):
    rng = np.random.default_rng(19)
    big = _z(rng, 3 * 12, 2 * 290 + 3, "runs", dtype)
    for z in (big[::3, 1::2], big[1::3, 3:293], big[:, 5:300]):
        f = AlphaBetaFilter(0.3, 0.05, 1.0)
        r = _check(f, np.ascontiguousarray(z))
        assert _same(f.run(z).states, r.states)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
@pytest.mark.parametrize("init", ["two-point", "first", "array"])
def test_avx2_per_track_gains_and_inits(dtype, init):
    rng = np.random.default_rng(23)
    ntr, n = 29, 333
    z = _z(rng, ntr, n, "random", dtype)
    a = rng.uniform(0.05, 0.95, ntr)
    b = rng.uniform(0.01, 0.5, ntr) * a
    T = rng.uniform(0.01, 5.0, ntr)
    iv = rng.normal(0, 3, (ntr, 2)) if init == "array" else init
    f = AlphaBetaFilter(a, b, T)
    r = _check(f, z, init=iv)
    s, _, _ = fr.run_ref(z, fr.ab_model(a, b, T), iv if init == "array" else init)
    if dtype == np.float64:
        fr.assert_states_close(r.states, s, RTOL)
    else:
        assert_f32_rounded(r.states, s)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_avx2_streaming_chunks_and_threads(dtype):
    rng = np.random.default_rng(29)
    z = _z(rng, 27, 2100, "random", dtype)
    f = AlphaBetaFilter(0.6, 0.25, 0.5)
    whole = f.run(z, threads=1)
    assert _same(whole.states, f.run(z, return_residuals=True, threads=1).states)
    two = f.run(z, threads=2)
    assert _same(two.states, whole.states) and _same(two.state.x, whole.state.x)
    parts, st = [], None
    for a, b in [(0, 5), (5, 300), (300, 301), (301, 600), (600, 1700), (1700, 2100)]:
        r = f.run(z[:, a:b], state=st, threads=2)
        parts.append(r.states)
        st = r.state
    assert _same(np.concatenate(parts, axis=2), whole.states)
    assert _same(st.x, whole.state.x)


@pytest.mark.parametrize("dtype,n,off", [(np.float64, 4200, 0), (np.float64, 4203, 3), (np.float32, 8400, 0), (np.float32, 8405, 5)])
def test_avx2_large_output_streamed(dtype, n, off):
    # 2 x 1000 x n outputs >= 64 MiB: non-temporal stores (rows at
    # different alignments when n is not a multiple of the line).
    rng = np.random.default_rng(31)
    z = _z(rng, 1000, n, "random", dtype)
    f = AlphaBetaFilter(0.4, 0.1, 1.0)
    obuf = np.empty(2 * 1000 * n + off, dtype)
    out = obuf[off:].reshape(2, 1000, n)
    lanes = f.run(z, out=out, threads=1)
    assert lanes.states is out
    idx = np.r_[0:9, 500:517, 990:1000]
    scalar = f.run(z[idx], return_residuals=True)
    assert _same(out[:, idx], scalar.states)
    s, _, _ = fr.run_ref(z[990:1000], fr.ab_model(0.4, 0.1, 1.0), "two-point")
    if dtype == np.float64:
        fr.assert_states_close(out[:, 990:1000], s, RTOL)
    else:
        assert_f32_rounded(out[:, 990:1000], s)


def test_avx2_lanes_equal_scalar_lanes_in_another_process(tmp_path):
    # The same batches in a process with the vector lanes switched off
    # (ABKIT_DISABLE_SIMD=1: scalar lanes and scalar split segments) give
    # the same bits; includes a single long track (split into lane groups)
    # and threads 1 and 2.
    rng = np.random.default_rng(37)
    names = []
    for dt in (np.float64, np.float32):
        for tag, (ntr, n) in {"a": (37, 531), "b": (9, 4099), "c": (1, 300_001)}.items():
            z = _z(rng, ntr, n, "random", dt)
            name = f"{tag}_{np.dtype(dt).name}"
            np.save(tmp_path / f"z_{name}.npy", z)
            names.append(name)
    code = (
        "import sys, numpy as np, abkit\n"
        "d, tag = sys.argv[1], sys.argv[2]\n"
        "for name in sys.argv[3:]:\n"
        "    z = np.load(f'{d}/z_{name}.npy')\n"
        "    for th in (1, 2):\n"
        "        r = abkit.AlphaBetaFilter(0.45, 0.12, 0.3).run(z, threads=th)\n"
        "        np.save(f'{d}/s_{name}_{th}_{tag}.npy', r.states)\n"
        "        np.save(f'{d}/x_{name}_{th}_{tag}.npy', r.state.x)\n"
    )
    for tag, env in (("on", {}), ("off", {"ABKIT_DISABLE_SIMD": "1"})):
        e = dict(os.environ)
        e.pop("ABKIT_DISABLE_SIMD", None)
        e.update(env)
        subprocess.run([sys.executable, "-c", code, str(tmp_path), tag, *names], check=True, env=e)
    for name in names:
        for th in (1, 2):
            for what in ("s", "x"):
                on = np.load(tmp_path / f"{what}_{name}_{th}_on.npy")
                off = np.load(tmp_path / f"{what}_{name}_{th}_off.npy")
                assert _same(on, off), (name, th, what)
