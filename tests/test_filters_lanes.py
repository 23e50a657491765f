"""The interleaved alpha-beta lanes (8 tracks at once; on CPUs with AVX-512
the 8 tracks share one vector register, with 8 x 8 transposes and aligned,
for big outputs non-temporal, stores) against the scalar per-track loop.

The lanes run only when no residuals are requested, so ``run(z)`` (lanes) is
compared with ``run(z, return_residuals=True)`` (one scalar loop per track):
docs/filtering.md promises the same arithmetic, so the states must be
**bit-identical**. Both are also checked against the independent NumPy
reference (tests/filterref.py) at the compliance tolerance (1e-12 of the
array's scale; float32: within 0.5 ulp + 1e-12 scale).

The cases cover row lengths around the vector width (rows start at every
alignment, heads and tails of 0..7 samples), group sizes that leave partial
groups, per-track gains, NaN patterns, float32/float64, strided rows of a
bigger array, streaming in chunks, and an output big enough (>= 64 MiB) for
the non-temporal stores.
"""

from __future__ import annotations

import zlib

import numpy as np
import pytest

import filterref as fr
from abkit import AlphaBetaFilter
from test_filters_compliance import assert_f32_rounded

RTOL = 1e-12


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
            z[i, : int(rng.integers(0, min(n, 20)))] = np.nan
    elif pattern == "all-nan":
        z[::5] = np.nan
    return z.astype(dtype)


def _check(f, z, **kw):
    lanes = f.run(z, **kw)
    scalar = f.run(z, return_residuals=True, **kw)
    assert np.array_equal(lanes.states, scalar.states, equal_nan=True)
    assert np.array_equal(lanes.state.x, scalar.state.x, equal_nan=True)
    return lanes


CASES = [
    (ntr, n, pat, dt)
    for ntr, n in [(8, 33), (8, 40), (9, 41), (16, 47), (17, 64), (24, 100), (40, 257), (8, 1000), (13, 4099)]
    for pat in ["none", "random", "runs", "leading", "all-nan"]
    for dt in [np.float64, np.float32]
]


@pytest.mark.parametrize("ntr,n,pattern,dtype", CASES)
def test_lanes_bit_identical_to_scalar_and_match_reference(ntr, n, pattern, dtype):
    rng = np.random.default_rng(ntr * 1000 + n)
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
def test_lanes_per_track_gains(dtype):
    rng = np.random.default_rng(5)
    ntr, n = 35, 301
    z = _z(rng, ntr, n, "random", dtype)
    a = rng.uniform(0.05, 0.95, ntr)
    b = rng.uniform(0.01, 0.5, ntr) * a
    T = rng.uniform(0.01, 5.0, ntr)
    _check(AlphaBetaFilter(a, b, T), z)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
@pytest.mark.parametrize("init", ["two-point", "first", "array"])
def test_lanes_inits_and_strided_rows(dtype, init):
    rng = np.random.default_rng(7)
    big = _z(rng, 30, 2 * 203, "runs", dtype)
    z = big[::3, 1::2]  # rows neither contiguous nor aligned
    zc = np.ascontiguousarray(z)
    iv = rng.normal(0, 3, (z.shape[0], 2)) if init == "array" else init
    f = AlphaBetaFilter(0.3, 0.05, 1.0)
    r = _check(f, zc, init=iv)
    r2 = f.run(z, init=iv)
    assert np.array_equal(r.states, r2.states, equal_nan=True)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_lanes_streaming_chunks_bit_identical(dtype):
    rng = np.random.default_rng(11)
    z = _z(rng, 19, 997, "random", dtype)
    f = AlphaBetaFilter(0.6, 0.25, 0.5)
    whole = f.run(z)
    parts, st = [], None
    for a, b in [(0, 5), (5, 77), (77, 120), (120, 600), (600, 997)]:
        r = f.run(z[:, a:b], state=st)
        parts.append(r.states)
        st = r.state
    assert np.array_equal(np.concatenate(parts, axis=2), whole.states, equal_nan=True)
    assert np.array_equal(st.x, whole.state.x, equal_nan=True)


@pytest.mark.parametrize("dtype,n", [(np.float64, 4200), (np.float32, 8400)])
def test_lanes_large_output_streamed(dtype, n):
    # 2 x 1000 x n outputs = 67.2 MB >= 64 MiB: non-temporal stores.
    rng = np.random.default_rng(3)
    z = _z(rng, 1000, n, "random", dtype)
    f = AlphaBetaFilter(0.4, 0.1, 1.0)
    lanes = f.run(z)
    # the scalar loop on a sample of tracks (and the reference on a few)
    idx = np.r_[0:9, 500:517, 990:1000]
    scalar = f.run(z[idx], return_residuals=True)
    assert np.array_equal(lanes.states[:, idx], scalar.states, equal_nan=True)
    out = np.empty_like(lanes.states)
    again = f.run(z, out=out)
    assert again.states is out and np.array_equal(out, lanes.states, equal_nan=True)


def test_vector_lanes_equal_scalar_lanes_bitwise(tmp_path):
    # The same batch in a process with the AVX-512 lanes switched off
    # (ABKIT_DISABLE_SIMD=1: the scalar lanes) gives the same bits.
    import os
    import subprocess
    import sys

    rng = np.random.default_rng(21)
    for dt in (np.float64, np.float32):
        z = _z(rng, 37, 531, "random", dt)
        np.save(tmp_path / f"z_{np.dtype(dt).name}.npy", z)
    code = (
        "import sys, numpy as np, abkit\n"
        "for n in ('float64', 'float32'):\n"
        "    z = np.load(sys.argv[1] + f'/z_{n}.npy')\n"
        "    np.save(sys.argv[1] + f'/s_{n}_' + sys.argv[2] + '.npy', abkit.AlphaBetaFilter(0.45, 0.12, 0.3).run(z).states)\n"
        "    np.save(sys.argv[1] + f'/g_{n}_' + sys.argv[2] + '.npy', abkit.AlphaBetaGammaFilter(0.45, 0.12, 0.01, 0.3).run(z).states)\n"
    )
    for tag, env in (("on", {}), ("off", {"ABKIT_DISABLE_SIMD": "1"})):
        e = dict(os.environ)
        e.pop("ABKIT_DISABLE_SIMD", None)
        e.update(env)
        subprocess.run([sys.executable, "-c", code, str(tmp_path), tag], check=True, env=e)
    for n in ("float64", "float32"):
        on = np.load(tmp_path / f"s_{n}_on.npy")
        off = np.load(tmp_path / f"s_{n}_off.npy")
        assert on.dtype == np.dtype(n)
        assert np.array_equal(on, off, equal_nan=True)
        on = np.load(tmp_path / f"g_{n}_on.npy")
        off = np.load(tmp_path / f"g_{n}_off.npy")
        assert on.shape[0] == 3 and np.array_equal(on, off, equal_nan=True)


# ---------------------------------------------------------------------------
# The general kernel's lanes (4 tracks; AVX2 vectors where available).
# ---------------------------------------------------------------------------
from test_filters_compliance import _cv2d, _singer, _singer_m1  # noqa: E402
from abkit import AlphaBetaGammaFilter, FixedGainFilter  # noqa: E402

GEN_MODELS = {
    "abg": lambda: (AlphaBetaGammaFilter(0.5, 0.3, 0.05, 0.5), fr.abg_model(0.5, 0.3, 0.05, 0.5), 1),
    "singer-m2": lambda: (lambda P, H, K, T: (FixedGainFilter(P, H, K, T), fr.general_model(P, H, K, T), 2))(*_singer()),
    "singer-m1": lambda: (lambda P, H, K, T: (FixedGainFilter(P, H, K, T), fr.general_model(P, H, K, T), 1))(*_singer_m1()),
    "cv2d": lambda: (lambda P, H, K, T: (FixedGainFilter(P, H, K, T), fr.general_model(P, H, K, T), 2))(*_cv2d()),
}
GEN_CASES = [
    (name, ntr, n, pat, dt)
    for name in GEN_MODELS
    for ntr, n in [(4, 17), (5, 31), (8, 100), (11, 1001)]
    for pat in ["none", "random", "runs", "mixed"]
    for dt in [np.float64, np.float32]
]


@pytest.mark.parametrize("name,ntr,n,pattern,dtype", GEN_CASES)
def test_general_lanes_bit_identical_to_scalar_and_match_reference(name, ntr, n, pattern, dtype):
    # a seed that is the same in every process (hash() of a str is salted)
    rng = np.random.default_rng(zlib.crc32(f"{name}-{ntr}-{n}-{pattern}".encode()))
    f, model, m = GEN_MODELS[name]()
    z = fr.with_nans(rng, fr.kinematic_z(rng, ntr, n, model.T if hasattr(model, "T") else 0.5, m=m), pattern)
    z = z.astype(dtype)
    init = "first" if m == 2 else "two-point"
    lanes = f.run(z, init=init)
    scalar = f.run(z, init=init, return_residuals=True)
    assert np.array_equal(lanes.states, scalar.states, equal_nan=True)
    assert np.array_equal(lanes.state.x, scalar.state.x, equal_nan=True)
    s, _, _ = fr.run_ref(z, model, init)
    if dtype == np.float64:
        # kinematic states (abg, Singer): a rate's scale is the position's
        # scale / T^c, as in the compliance test (a last-bit position
        # difference enters the rates through K / T^c and grows over coasts)
        fr.assert_states_close(lanes.states, s, RTOL, kin_T=model.T if name != "cv2d" else None)
    else:
        assert_f32_rounded(lanes.states, s)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_general_lanes_per_track_models_and_streaming(dtype):
    rng = np.random.default_rng(8)
    ntr, n = 9, 403
    a = rng.uniform(0.3, 0.8, ntr)
    b = rng.uniform(0.05, 0.3, ntr)
    g = rng.uniform(0.001, 0.02, ntr)
    f = AlphaBetaGammaFilter(a, b, g, rng.uniform(0.1, 2.0, ntr))
    z = fr.with_nans(rng, fr.kinematic_z(rng, ntr, n, 0.5), "random").astype(dtype)
    whole = f.run(z)
    assert np.array_equal(whole.states, f.run(z, return_residuals=True).states, equal_nan=True)
    parts, st = [], None
    for lo, hi in [(0, 3), (3, 50), (50, 51), (51, 403)]:
        r = f.run(z[:, lo:hi], state=st)
        parts.append(r.states)
        st = r.state
    assert np.array_equal(np.concatenate(parts, axis=2), whole.states, equal_nan=True)


def test_general_lanes_large_output_streamed():
    # 3 x 700 x 4000 float64 outputs = 67.2 MB >= 64 MiB: non-temporal stores.
    rng = np.random.default_rng(4)
    z = fr.with_nans(rng, fr.kinematic_z(rng, 700, 4000, 0.5), "random")
    f = AlphaBetaGammaFilter(0.5, 0.3, 0.05, 0.5)
    lanes = f.run(z)
    idx = np.r_[0:5, 301:313, 690:700]
    scalar = f.run(z[idx], return_residuals=True)
    assert np.array_equal(lanes.states[:, idx], scalar.states, equal_nan=True)
