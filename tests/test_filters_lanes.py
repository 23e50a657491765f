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


@pytest.mark.parametrize(
    "dtype,ntr,n",
    [(np.float64, 1000, 4200), (np.float32, 1000, 8400), (np.float64, 1001, 4204), (np.float64, 1001, 4201)],
)
def test_lanes_large_output_streamed(dtype, ntr, n):
    # 2 x ntr x n outputs = 67.2 MB >= 64 MiB: non-temporal stores. With
    # 1001 x 4204 (4201) the v rows sit half a line (8 bytes) off the x
    # rows' line grid: x streamed, v stored plainly.
    rng = np.random.default_rng(3)
    z = _z(rng, ntr, n, "random", dtype)
    f = AlphaBetaFilter(0.4, 0.1, 1.0)
    lanes = f.run(z)
    # the scalar loop on a sample of tracks (and the reference on a few)
    idx = np.r_[0:9, 500:517, ntr - 10 : ntr]
    scalar = f.run(z[idx], return_residuals=True)
    assert np.array_equal(lanes.states[:, idx], scalar.states, equal_nan=True)
    out = np.empty_like(lanes.states)
    again = f.run(z, out=out)
    assert again.states is out and np.array_equal(out, lanes.states, equal_nan=True)


@pytest.mark.parametrize("dtype,ntr,n", [(np.float64, 603, 1024), (np.float32, 1203, 1024), (np.float64, 140, 4096)])
def test_power_of_two_rows_streamed(dtype, ntr, n):
    # Streamed outputs (>= 8 MiB) of rows a multiple of 2 KiB long run in the
    # flat kernel on AVX2 CPUs (the row lanes' stores alias modulo 4 KiB):
    # the same bits as the scalar loop, also when continuing with state=.
    rng = np.random.default_rng(5)
    z = _z(rng, ntr, n, "random", dtype)
    f = AlphaBetaFilter(0.4, 0.1, 1.0)
    whole = f.run(z)
    idx = np.r_[0:9, ntr // 2 : ntr // 2 + 17, ntr - 10 : ntr]
    scalar = f.run(z[idx], return_residuals=True)
    assert np.array_equal(whole.states[:, idx], scalar.states, equal_nan=True)
    assert np.array_equal(whole.state.x[idx], scalar.state.x, equal_nan=True)
    again = f.run(z, state=whole.state)
    ref = f.run(z, state=whole.state, return_residuals=True)
    assert np.array_equal(again.states, ref.states, equal_nan=True)
    assert np.array_equal(again.state.x, ref.state.x, equal_nan=True)


def test_vector_lanes_equal_scalar_lanes_bitwise(tmp_path):
    # The same batch in a process with the AVX-512 lanes switched off
    # (ABKIT_DISABLE_SIMD=1: the scalar lanes) gives the same bits.
    import os
    import subprocess
    import sys

    # Also one long track (split into segments run in the row lanes) and,
    # on an AMD Zen 4, ABKIT_ZEN4=0: float64 rows in the AVX-512 lanes
    # instead of the AVX2 lanes' Zen 4 form (the default there).
    rng = np.random.default_rng(21)
    for dt in (np.float64, np.float32):
        z = _z(rng, 37, 531, "random", dt)
        np.save(tmp_path / f"z_{np.dtype(dt).name}.npy", z)
        z1 = np.cumsum(rng.normal(size=150_001)).astype(dt)
        z1[rng.random(z1.size) < 0.01] = np.nan
        np.save(tmp_path / f"z1_{np.dtype(dt).name}.npy", z1)
    code = (
        "import sys, numpy as np, abkit\n"
        "for n in ('float64', 'float32'):\n"
        "    z = np.load(sys.argv[1] + f'/z_{n}.npy')\n"
        "    z1 = np.load(sys.argv[1] + f'/z1_{n}.npy')\n"
        "    np.save(sys.argv[1] + f'/s_{n}_' + sys.argv[2] + '.npy', abkit.AlphaBetaFilter(0.45, 0.12, 0.3).run(z).states)\n"
        "    np.save(sys.argv[1] + f'/l_{n}_' + sys.argv[2] + '.npy', abkit.AlphaBetaFilter(0.45, 0.12, 0.3).run(z1).states)\n"
        "    np.save(sys.argv[1] + f'/g_{n}_' + sys.argv[2] + '.npy', abkit.AlphaBetaGammaFilter(0.45, 0.12, 0.01, 0.3).run(z).states)\n"
    )
    runs = (("on", {}), ("nozen4", {"ABKIT_ZEN4": "0"}), ("off", {"ABKIT_DISABLE_SIMD": "1"}))
    for tag, env in runs:
        e = dict(os.environ)
        e.pop("ABKIT_DISABLE_SIMD", None)
        e.pop("ABKIT_ZEN4", None)
        e.update(env)
        subprocess.run([sys.executable, "-c", code, str(tmp_path), tag], check=True, env=e)
    for tag in ("on", "nozen4"):
        for n in ("float64", "float32"):
            for kind, comps in (("s", 2), ("l", 2), ("g", 3)):
                on = np.load(tmp_path / f"{kind}_{n}_{tag}.npy")
                off = np.load(tmp_path / f"{kind}_{n}_off.npy")
                assert on.dtype == np.dtype(n) and on.shape[0] == comps
                assert np.array_equal(on, off, equal_nan=True), (tag, kind, n)


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


@pytest.mark.parametrize("n", [100, 61])
def test_general_lanes_short_rows_streamed(n):
    # 3 x rows x n float64 outputs >= 64 MiB with short rows: every lane
    # steps to a line-aligned sample first (heads of 0-7 samples, different
    # per lane), then whole streamed lines, then tails; heads and tails run
    # as masked vector steps. The same bits as the per-track scalar loop
    # (residuals requested), on tracks from every position in a group of 4.
    rng = np.random.default_rng(40 + n)
    rows = -(-(64 << 20) // (3 * 8 * n)) + 5
    z = fr.with_nans(rng, fr.kinematic_z(rng, rows, n, 0.5), "random")
    f = AlphaBetaGammaFilter(0.5, 0.3, 0.05, 0.5)
    lanes = f.run(z)
    idx = np.r_[0:13, rows // 2 : rows // 2 + 9, rows - 11 : rows]
    scalar = f.run(z[idx], return_residuals=True)
    assert np.array_equal(lanes.states[:, idx], scalar.states, equal_nan=True)
    assert np.array_equal(lanes.state.x[idx], scalar.state.x, equal_nan=True)


# ---------------------------------------------------------------------------
# The general kernel's AVX-512 lanes (8 tracks per vector register, groups of
# 8 where the CPU has AVX-512, else groups of 4 / scalar): the same bits as
# the scalar per-track loop in process, and as a process with
# ABKIT_DISABLE_SIMD=1 (scalar lanes, groups of 4). By default the 8-lane
# kernel runs only float64 rows of >= 512 samples (>= 100 streamed; none on
# an AMD Zen 4) and float32 rows of >= 200; ABKIT_GEN_AVX512=1 (read
# once per process) runs it for every shape and dtype, so the child
# processes set it; on a CPU without AVX-512 they run the 4-lane AVX2
# path / scalar lanes, and the comparisons still hold.
# ---------------------------------------------------------------------------
def _run_child(code, args, env):
    import os
    import subprocess
    import sys

    e = dict(os.environ)
    e.pop("ABKIT_DISABLE_SIMD", None)
    e.pop("ABKIT_GEN_AVX512", None)
    e.update(env)
    subprocess.run([sys.executable, "-c", code, *args], check=True, env=e)


def _ab_fg(T=0.5, a=0.5, b=0.2):
    """The alpha-beta filter as a general 2-state, 1-measurement model."""
    return np.array([[1.0, T], [0.0, 1.0]]), np.array([[1.0, 0.0]]), np.array([[a], [b / T]]), T


GEN8_SHAPES = [(8, 23), (8, 24), (8, 25), (9, 33), (16, 47), (16, 48), (17, 49), (7, 64), (15, 65), (24, 100), (17, 129), (8, 257), (11, 1001)]
GEN8_PATTERNS = ["none", "random", "runs", "leading", "all-nan-tracks"]
# model name -> (n states, m components)
GEN8_MODELS = {"abg": (3, 1), "abg-per-track": (3, 1), "singer-m2": (3, 2), "ab-fg": (2, 1)}
_GEN8_CHILD = """
import sys, numpy as np, abkit
d = sys.argv[1]
spec = np.load(d + '/spec.npz')
out = {}
for key in spec['keys']:
    key = str(key)
    z = spec['z_' + key]
    model = key.split('|')[0]
    if model == 'abg':
        f = abkit.AlphaBetaGammaFilter(0.5, 0.3, 0.05, 0.5)
    elif model == 'abg-per-track':
        p = spec['p_' + key]
        f = abkit.AlphaBetaGammaFilter(p[0], p[1], p[2], p[3])
    else:
        f = abkit.FixedGainFilter(spec['P_' + model], spec['H_' + model], spec['K_' + model], float(spec['T_' + model]))
    init = 'first' if z.ndim == 3 else 'two-point'
    r = f.run(z, init=init)
    out['s_' + key] = r.states
    out['x_' + key] = r.state.x
    n = z.shape[1]
    parts, st = [], None
    for lo, hi in [(0, 3), (3, n // 2), (n // 2, n // 2 + 1), (n // 2 + 1, n)]:
        rr = f.run(z[:, lo:hi], state=st, init=init)
        parts.append(rr.states)
        st = rr.state
    out['c_' + key] = np.concatenate(parts, axis=2)
np.savez(d + '/out_' + sys.argv[2] + '.npz', **out)
"""


def _gen8_filter(spec, key):
    model = key.split("|")[0]
    if model == "abg":
        return AlphaBetaGammaFilter(0.5, 0.3, 0.05, 0.5)
    if model == "abg-per-track":
        p = spec["p_" + key]
        return AlphaBetaGammaFilter(p[0], p[1], p[2], p[3])
    return FixedGainFilter(spec["P_" + model], spec["H_" + model], spec["K_" + model], float(spec["T_" + model]))


def test_general_lanes8_equal_scalar_bitwise(tmp_path):
    spec = {}
    for model, P in (("singer-m2", _singer()), ("ab-fg", _ab_fg())):
        spec["P_" + model], spec["H_" + model], spec["K_" + model], spec["T_" + model] = P
    keys = []
    for model, (_, m) in GEN8_MODELS.items():
        for ntr, n in GEN8_SHAPES:
            for pat in GEN8_PATTERNS:
                for dt in (np.float64, np.float32):
                    key = f"{model}|{ntr}|{n}|{pat}|{np.dtype(dt).name}"
                    rng = np.random.default_rng(zlib.crc32(key.encode()))
                    z = fr.with_nans(rng, fr.kinematic_z(rng, ntr, n, 0.5, m=m), pat).astype(dt)
                    spec["z_" + key] = z
                    if model == "abg-per-track":
                        spec["p_" + key] = np.array(
                            [rng.uniform(0.3, 0.8, ntr), rng.uniform(0.05, 0.3, ntr), rng.uniform(0.001, 0.02, ntr), rng.uniform(0.1, 2.0, ntr)]
                        )
                    keys.append(key)
    spec["keys"] = np.array(keys)
    np.savez(tmp_path / "spec.npz", **spec)
    # "four": the 4-lane AVX2 kernel without its Zen 4 form (AVX-512VL) on
    # every shape; in this process (no override) float64 on a Zen 4 runs the
    # 4-lane kernel's Zen 4 form.
    runs = (
        ("on", {"ABKIT_GEN_AVX512": "1"}),
        ("four", {"ABKIT_GEN_AVX512": "0", "ABKIT_ZEN4": "0"}),
        ("off", {"ABKIT_DISABLE_SIMD": "1"}),
    )
    for tag, env in runs:
        _run_child(_GEN8_CHILD, [str(tmp_path), tag], env)
    on = np.load(tmp_path / "out_on.npz")
    four = np.load(tmp_path / "out_four.npz")
    off = np.load(tmp_path / "out_off.npz")
    loaded = np.load(tmp_path / "spec.npz")
    for key in keys:
        model = key.split("|")[0]
        N, m = GEN8_MODELS[model]
        s = on["s_" + key]
        z = loaded["z_" + key]
        assert s.shape == (N,) + z.shape[:2] and s.dtype == z.dtype, key
        assert np.array_equal(s, off["s_" + key], equal_nan=True), key
        assert np.array_equal(on["x_" + key], off["x_" + key], equal_nan=True), key
        assert np.array_equal(four["s_" + key], s, equal_nan=True), key
        assert np.array_equal(four["x_" + key], on["x_" + key], equal_nan=True), key
        assert np.array_equal(four["c_" + key], s, equal_nan=True), key
        # streaming in chunks: the same bits as one run, with and without SIMD
        assert np.array_equal(on["c_" + key], s, equal_nan=True), key
        assert np.array_equal(off["c_" + key], s, equal_nan=True), key
        # and the scalar per-track loop (residuals requested) in this process
        init = "first" if m == 2 else "two-point"
        scalar = _gen8_filter(loaded, key).run(z, init=init, return_residuals=True)
        assert np.array_equal(s, scalar.states, equal_nan=True), key
    # the rows really are filtered (not left as they were): close to the reference
    key = "abg|24|100|random|float64"
    s, _, _ = fr.run_ref(loaded["z_" + key], fr.abg_model(0.5, 0.3, 0.05, 0.5), "two-point")
    fr.assert_states_close(on["s_" + key], s, RTOL, kin_T=0.5)


def test_general_lanes_large_output_streamed_f32(tmp_path):
    # 3 x 1400 x 4000 float32 outputs = 67.2 MB >= 64 MiB: the 8-lane
    # kernel's non-temporal whole-line stores of float32 (in a child with the
    # 8-lane kernel switched on).
    rng = np.random.default_rng(5)
    z = fr.with_nans(rng, fr.kinematic_z(rng, 1400, 4000, 0.5), "random").astype(np.float32)
    np.save(tmp_path / "z.npy", z)
    code = (
        "import sys, numpy as np, abkit\n"
        "z = np.load(sys.argv[1] + '/z.npy')\n"
        "np.save(sys.argv[1] + '/s.npy', abkit.AlphaBetaGammaFilter(0.5, 0.3, 0.05, 0.5).run(z).states)\n"
    )
    _run_child(code, [str(tmp_path)], {"ABKIT_GEN_AVX512": "1"})
    lanes = np.load(tmp_path / "s.npy")
    assert lanes.shape == (3, 1400, 4000) and lanes.dtype == np.float32
    idx = np.r_[0:5, 301:313, 1390:1400]
    scalar = AlphaBetaGammaFilter(0.5, 0.3, 0.05, 0.5).run(z[idx], return_residuals=True)
    assert np.array_equal(lanes[:, idx], scalar.states, equal_nan=True)


@pytest.mark.parametrize(
    "shape, dtype",
    [
        ((16, 600), np.float64),  # f64 rows >= 512 samples: 8-lane kernel by default on AVX-512 (4 on a Zen 4)
        ((3000, 120), np.float64),  # 3 x 3000 x 120 f64 = 8.6 MB >= 8 MiB: streamed, >= 100 samples
        ((3000, 90), np.float64),  # streamed but shorter than 100: 4-lane kernel
        ((16, 250), np.float32),  # f32 rows >= 200 samples: 8-lane kernel (f32 transposes)
        ((3000, 250), np.float32),  # 3 x 3000 x 250 f32 = 9 MB: streamed, 8-lane kernel
        ((24, 199), np.float32),  # f32 rows < 200: 4-lane kernel
    ],
)
def test_general_default_route_equals_scalar_bitwise(shape, dtype):
    # The default choice between the 4- and 8-lane general kernels (in this
    # process, no environment override) against the scalar per-track loop
    # (residuals requested): the same bits whichever kernel runs.
    rng = np.random.default_rng(zlib.crc32(repr(shape).encode()))
    z = fr.with_nans(rng, fr.kinematic_z(rng, shape[0], shape[1], 0.5), "random").astype(dtype)
    f = AlphaBetaGammaFilter(0.5, 0.3, 0.05, 0.5)
    lanes = f.run(z)
    scalar = f.run(z, return_residuals=True)
    assert np.array_equal(lanes.states, scalar.states, equal_nan=True)
    assert np.array_equal(lanes.state.x, scalar.state.x, equal_nan=True)


@pytest.mark.parametrize("ntr,n", [(64, 8192), (40, 10_001), (200, 2048)])
def test_general_lanes_streamed_f64_lane_phases(ntr, n, tmp_path):
    # float64 3-state outputs of 12-14 MB (streamed): rows of 8,192 or 2,048
    # samples put every lane's lines on one parity, so the 8 AVX-512 lanes
    # take one more masked head block (lane phases); rows of 10,001 mostly
    # so. Every track equals the scalar per-track loop (residuals requested)
    # bit for bit, final states too: the default route in this process (on
    # a Zen 4 the 4-lane kernel's Zen 4 form) and the 8 lanes in a child
    # (ABKIT_GEN_AVX512=1).
    rng = np.random.default_rng(ntr + n)
    z = fr.with_nans(rng, fr.kinematic_z(rng, ntr, n, 0.5), "random")
    np.save(tmp_path / "z.npy", z)
    code = (
        "import sys, numpy as np, abkit\n"
        "z = np.load(sys.argv[1] + '/z.npy')\n"
        "r = abkit.AlphaBetaGammaFilter(0.5, 0.3, 0.05, 0.5).run(z, threads=1)\n"
        "np.save(sys.argv[1] + '/s.npy', r.states)\n"
        "np.save(sys.argv[1] + '/x.npy', r.state.x)\n"
    )
    _run_child(code, [str(tmp_path)], {"ABKIT_GEN_AVX512": "1"})
    f = AlphaBetaGammaFilter(0.5, 0.3, 0.05, 0.5)
    lanes = f.run(z, threads=1)
    scalar = f.run(z, return_residuals=True)
    assert np.array_equal(lanes.states, scalar.states, equal_nan=True)
    assert np.array_equal(lanes.state.x, scalar.state.x, equal_nan=True)
    assert np.array_equal(np.load(tmp_path / "s.npy"), scalar.states, equal_nan=True)
    assert np.array_equal(np.load(tmp_path / "x.npy"), scalar.state.x, equal_nan=True)
