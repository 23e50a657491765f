"""Vector lanes of the irregular-timestamp alpha-beta track kernel
(rust/abkit-core/src/ragged_simd.rs: 8 tracks per AVX-512 register, 4 per
AVX2 register; each slot walks its own track, blocks of plain running steps
in vectors, everything else in the scalar lanes).

The vector slots do the scalar lane step's arithmetic (same operations, same
fused multiply-adds, same order, both gain laws), so results must be
**bit-identical** to

* each track run alone (one track: the scalar lane code),
* the same batch in another process with ``ABKIT_DISABLE_SIMD=1`` (scalar
  lanes only),
* one call vs the same samples streamed in chunks (``state=``),

and match the independent plain-Python reference ``tests/tracksref.py`` at
its stated tolerance (``assert_close`` of test_tracks_irregular: 1e-10
relative to the value plus 1e-2 of the component's scale; residuals 1e-8).

Cases: both gain schedules ("design": per-dt closed form, with steps on
both sides of the closed form's branch ``lambda = 1`` and mixed in one
block; "fixed"), float64/float32, ragged lengths 0..40 and long tracks,
NaN patterns (sparse, dense, runs, NaN-led, all-NaN), ``max_gap`` restarts,
duplicate timestamps dropped, per-track gains, residuals on and off,
rectangular batches with a shared time vector, strided (non-contiguous)
inputs.
"""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from abkit import AlphaBetaFilter
from tracksref import run_track
from test_tracks_irregular import ab_design_law, ab_fixed_law, assert_close

SW, SV = 3.2, 32.0  # ratio 0.1: lambda = 0.1 dt^2


def _filter(kind, per_track=0):
    if per_track:
        rng = np.random.default_rng(99)
        if kind == "design":
            return AlphaBetaFilter.from_noise(rng.uniform(1.0, 5.0, per_track), SV, 0.1)
        return AlphaBetaFilter(rng.uniform(0.2, 0.8, per_track), rng.uniform(0.02, 0.3, per_track), 0.1)
    if kind == "design":
        return AlphaBetaFilter.from_noise(SW, SV, 0.1)
    return AlphaBetaFilter(0.45, 0.12, 0.1)


def _data(seed, lens, *, pattern="random", dtype=np.float64, wide=False, dup=0.0, gaps=0.0):
    """Flat z, t and offsets for tracks of the given lengths."""
    rng = np.random.default_rng(seed)
    lens = np.asarray(lens, dtype=np.int64)
    off = np.concatenate([[0], np.cumsum(lens)]).astype(np.int64)
    n = int(off[-1])
    # regular-ish steps, or (wide) steps over 10^-2..10^1.5 so that lambda
    # = 0.1 dt^2 falls on both sides of 1, often within one block
    dt = 10.0 ** rng.uniform(-2, 1.5, n) if wide else rng.uniform(0.05, 0.15, n)
    if gaps:
        dt = np.where(rng.random(n) < gaps, 50.0, dt)
    if dup:
        u = rng.random(n)
        dt = np.where(u < dup, 0.0, dt)  # repeated timestamp
        dt = np.where((u >= dup) & (u < 1.5 * dup), -0.01, dt)  # out of order
    t = np.empty(n)
    z = np.empty(n)
    for i in range(len(lens)):
        a, b = off[i], off[i + 1]
        ti = rng.uniform(-100, 100) + np.cumsum(dt[a:b])
        t[a:b] = ti
        z[a:b] = 5.0 + 2.0 * (ti - ti[:1].sum()) + 0.01 * (ti - ti[:1].sum()) ** 2 + rng.normal(0, 1.0, b - a)
    if pattern == "random":
        z[rng.random(n) < 0.1] = np.nan
    elif pattern == "dense":
        z[rng.random(n) < 0.7] = np.nan
    elif pattern == "runs":
        for _ in range(max(1, n // 50)):
            a = int(rng.integers(0, max(n, 1)))
            z[a : a + int(rng.integers(1, 30))] = np.nan
    elif pattern == "led":  # NaN-led tracks, some all-NaN
        for i in range(len(lens)):
            a, b = off[i], off[i + 1]
            z[a : a + int(rng.integers(0, max(b - a, 1) + 1))] = np.nan
    return z.astype(dtype), t, off


def _same(r1, r2):
    assert r1.states.dtype == r2.states.dtype
    assert np.array_equal(r1.states, r2.states, equal_nan=True)
    if r1.residuals is not None or r2.residuals is not None:
        assert np.array_equal(r1.residuals, r2.residuals, equal_nan=True)
    assert np.array_equal(r1.state.x, r2.state.x, equal_nan=True)
    assert np.array_equal(r1.state.t_last, r2.state.t_last, equal_nan=True)
    assert np.array_equal(r1.n_dropped, r2.n_dropped)
    assert np.array_equal(r1.n_restarts, r2.n_restarts)


RAGGED = [list(range(0, 41)) * 2, [3000, 7, 2500, 0, 1, 2048, 40, 999, 1500, 33, 2, 1200]]


@pytest.mark.parametrize("kind", ["design", "fixed"])
@pytest.mark.parametrize("dtype", [np.float64, np.float32])
@pytest.mark.parametrize("pattern", ["none", "random", "dense", "runs", "led"])
@pytest.mark.parametrize("lens", [0, 1], ids=["short", "long"])
@pytest.mark.parametrize("resid", [False, True])
def test_lanes_bit_identical_to_tracks_alone(kind, dtype, pattern, lens, resid):
    lens = RAGGED[lens]
    seed = [0, 1][RAGGED.index(lens)] * 100 + ["none", "random", "dense", "runs", "led"].index(pattern)
    z, t, off = _data(seed, lens, pattern=pattern, dtype=dtype, wide=(kind == "design"))
    f = _filter(kind)
    r = f.run(z, t=t, offsets=off, return_residuals=resid)
    for i in range(len(lens)):
        a, b = off[i], off[i + 1]
        one = f.run(z[a:b], t=t[a:b], return_residuals=resid)
        assert np.array_equal(r.states[:, a:b], one.states, equal_nan=True), i
        if resid:
            assert np.array_equal(r.residuals[a:b], one.residuals, equal_nan=True), i
        assert np.array_equal(r.state.x[i], np.ravel(one.state.x), equal_nan=True), i
        assert np.array_equal(r.state.t_last[i], np.ravel(one.state.t_last)[0], equal_nan=True), i


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
@pytest.mark.parametrize("sw", [SW, 3000.0], ids=["small-lambda", "large-lambda"])
@pytest.mark.parametrize("opts", [{}, dict(max_gap=1.5)], ids=["plain", "restarts"])
def test_grid_timestamps_bit_identical_to_tracks_alone(dtype, sw, opts):
    # Timestamps on a grid (whole seconds, 2 % of the reports missed): the
    # vector lanes reuse the design law's gains while every slot's dt
    # repeats, and recompute them when one changes. Tracks on the grid mixed
    # with irregular ones (so some blocks have equal dt in some slots only),
    # missed measurements, restarts at the 2 s gaps (max_gap=1.5); both
    # branches of the design law (lambda = (sw / SV) dt^2 / ... small and
    # large). Bit-identical to each track run alone (the scalar lane code,
    # which computes the gains at every step).
    rng = np.random.default_rng(77)
    lens = [3000, 17, 2500, 1, 0, 2048, 999, 1500, 33, 1200, 700, 64]
    off = np.concatenate([[0], np.cumsum(lens)]).astype(np.int64)
    n = int(off[-1])
    t = np.empty(n)
    for i in range(len(lens)):
        a, b = off[i], off[i + 1]
        if i % 3 == 2:
            dt = rng.uniform(0.5, 1.5, b - a)
        else:
            dt = 1.0 + (rng.random(b - a) < 0.02)
        t[a:b] = float(rng.integers(0, 1000)) + np.cumsum(dt)
    z = 3.0 + 2.0 * t + rng.normal(0, 1.0, n)
    z[rng.random(n) < 0.05] = np.nan
    z = z.astype(dtype)
    f = AlphaBetaFilter.from_noise(sw, SV, 1.0)
    r = f.run(z, t=t, offsets=off, **opts)
    for i in range(len(lens)):
        a, b = off[i], off[i + 1]
        one = f.run(z[a:b], t=t[a:b], **opts)
        assert np.array_equal(r.states[:, a:b], one.states, equal_nan=True), i
        assert np.array_equal(r.state.x[i], np.ravel(one.state.x), equal_nan=True), i
    if opts:
        assert r.n_restarts.sum() > 0


@pytest.mark.parametrize("kind", ["design", "fixed"])
@pytest.mark.parametrize("opts", [dict(max_gap=20.0), dict(on_duplicate="drop"), dict(max_gap=20.0, on_duplicate="drop", init="first")])
def test_restarts_and_drops_bit_identical_to_tracks_alone(kind, opts):
    lens = [500, 17, 1000, 64, 3, 700, 300, 129, 999, 40]
    z, t, off = _data(7, lens, pattern="random", dup=0.01 if "on_duplicate" in opts else 0.0, gaps=0.01)
    f = _filter(kind)
    r = f.run(z, t=t, offsets=off, return_residuals=True, **opts)
    if "max_gap" in opts:
        assert r.n_restarts.sum() > 0
    if "on_duplicate" in opts:
        assert r.n_dropped.sum() > 0
    for i in range(len(lens)):
        a, b = off[i], off[i + 1]
        one = f.run(z[a:b], t=t[a:b], return_residuals=True, **opts)
        assert np.array_equal(r.states[:, a:b], one.states, equal_nan=True), i
        assert np.array_equal(r.residuals[a:b], one.residuals, equal_nan=True), i
        assert r.n_restarts[i] == np.ravel(one.n_restarts)[0] and r.n_dropped[i] == np.ravel(one.n_dropped)[0]


@pytest.mark.parametrize("kind", ["design", "fixed"])
def test_per_track_gains_bit_identical_to_tracks_alone(kind):
    lens = [300, 0, 45, 800, 9, 260, 1000, 31, 512, 77, 640]
    z, t, off = _data(11, lens, wide=(kind == "design"))
    f = _filter(kind, per_track=len(lens))
    r = f.run(z, t=t, offsets=off, return_residuals=True)
    rng = np.random.default_rng(99)
    if kind == "design":
        sw = rng.uniform(1.0, 5.0, len(lens))
    else:
        al, be = rng.uniform(0.2, 0.8, len(lens)), rng.uniform(0.02, 0.3, len(lens))
    for i in range(len(lens)):
        a, b = off[i], off[i + 1]
        fi = AlphaBetaFilter.from_noise(sw[i], SV, 0.1) if kind == "design" else AlphaBetaFilter(al[i], be[i], 0.1)
        one = fi.run(z[a:b], t=t[a:b], return_residuals=True)
        assert np.array_equal(r.states[:, a:b], one.states, equal_nan=True), i
        assert np.array_equal(r.residuals[a:b], one.residuals, equal_nan=True), i
        if b - a > 200 and i in (3, 6):
            law = ab_design_law(sw[i], SV) if kind == "design" else ab_fixed_law(al[i], be[i])
            ref, res, _, _ = run_track(z[a:b], t[a:b], law, 2)
            assert_close(one.states, ref)


@pytest.mark.parametrize("kind", ["design", "fixed"])
@pytest.mark.parametrize("opts", [dict(), dict(max_gap=20.0, on_duplicate="drop")])
def test_lanes_match_reference(kind, opts):
    lens = [400, 13, 600, 250, 1, 333, 520, 90, 410]
    drop = "on_duplicate" in opts
    z, t, off = _data(5, lens, pattern="random", wide=(kind == "design"), dup=0.01 if drop else 0.0, gaps=0.01)
    f = _filter(kind)
    r = f.run(z, t=t, offsets=off, return_residuals=True, **opts)
    law = ab_design_law() if kind == "design" else ab_fixed_law(0.45, 0.12)
    for i in (0, 2, 6):
        a, b = off[i], off[i + 1]
        ref, res, nd, nr = run_track(z[a:b], t[a:b], law, 2, max_gap=opts.get("max_gap"), drop=drop)
        assert_close(r.states[:, a:b], ref)
        assert_close(r.residuals[None, a:b], res[None], rtol=1e-8)
        assert (r.n_dropped[i], r.n_restarts[i]) == (nd, nr)


@pytest.mark.parametrize("kind", ["design", "fixed"])
def test_rectangular_shared_t_and_strided_inputs(kind):
    rng = np.random.default_rng(3)
    n_tracks, n = 13, 700
    t = np.cumsum(rng.uniform(0.05, 3.0, n))
    z = 2.0 * t + rng.normal(0, 1, (n_tracks, n))
    z[rng.random(z.shape) < 0.05] = np.nan
    f = _filter(kind)
    r = f.run(z, t=t, return_residuals=True)
    for i in (0, 5, 12):
        one = f.run(z[i], t=t, return_residuals=True)
        assert np.array_equal(r.states[:, i], one.states, equal_nan=True)
        assert np.array_equal(r.residuals[i], one.residuals, equal_nan=True)
    # strided views (scalar lanes) give the same bits
    zz = np.repeat(z, 2, axis=1)[:, ::2]
    tt = np.repeat(t, 2)[::2]
    s = f.run(zz, t=tt, return_residuals=True)
    _same(r, s)


@pytest.mark.parametrize("kind", ["design", "fixed"])
def test_streaming_chunks_equal_one_call(kind):
    lens = [900, 0, 35, 1200, 640, 2, 777, 1000]
    z, t, off = _data(9, lens, pattern="runs", wide=(kind == "design"), dup=0.005, gaps=0.005)
    f = _filter(kind)
    opts = dict(max_gap=20.0, on_duplicate="drop")
    full = f.run(z, t=t, offsets=off, return_residuals=True, **opts)
    cuts = [0, 1, 37, 38, 301, 640, 641, 2000]
    st = None
    parts, rparts = [], []
    for a, b in zip(cuts[:-1], cuts[1:]):
        # chunk c of every track: samples a..b of each track (clipped)
        zc, tc, oc = [], [], [0]
        for i in range(len(lens)):
            lo, hi = off[i] + min(a, lens[i]), off[i] + min(b, lens[i])
            zc.append(z[lo:hi])
            tc.append(t[lo:hi])
            oc.append(oc[-1] + hi - lo)
        r = f.run(np.concatenate(zc), t=np.concatenate(tc), offsets=oc, state=st, return_residuals=True, **opts)
        st = r.state
        parts.append(np.split(r.states, oc[1:-1], axis=1))
        rparts.append(np.split(r.residuals, oc[1:-1]))
    for i in range(len(lens)):
        a, b = off[i], off[i + 1]
        got = np.concatenate([p[i] for p in parts], axis=1)
        assert np.array_equal(got, full.states[:, a:b], equal_nan=True), i
        got_r = np.concatenate([p[i] for p in rparts])
        assert np.array_equal(got_r, full.residuals[a:b], equal_nan=True), i
    assert np.array_equal(st.x, full.state.x, equal_nan=True)
    assert np.array_equal(st.t_last, full.state.t_last, equal_nan=True)


def _on_off(code, tmp_path, on_envs):
    """Run `code` (writes its arrays to argv[1]/argv[2].npz) in child
    processes: once with each environment of `on_envs` (vector lanes) and
    once with ABKIT_DISABLE_SIMD=1 (scalar lanes); the archives of the
    former (in order) and the latter."""
    here = os.path.dirname(os.path.abspath(__file__))
    runs = [(f"on{i}", env) for i, env in enumerate(on_envs)] + [("off", {"ABKIT_DISABLE_SIMD": "1"})]
    for tag, env in runs:
        e = dict(os.environ)
        e.pop("ABKIT_DISABLE_SIMD", None)
        e.pop("ABKIT_TRACKS_AVX512", None)
        e.pop("ABKIT_ZEN4", None)
        e.update(env)
        subprocess.run([sys.executable, "-c", code, str(tmp_path), tag, here], check=True, env=e, cwd=here)
    ons = [np.load(tmp_path / f"{tag}.npz") for tag, _ in runs[:-1]]
    return ons, np.load(tmp_path / "off.npz")


def test_vector_lanes_equal_scalar_lanes_in_another_process(tmp_path):
    # Every case in two processes: vector lanes on (if the CPU has them) and
    # ABKIT_DISABLE_SIMD=1 (scalar lanes only): the same bits.
    code = r"""
import sys, numpy as np
sys.path.insert(0, sys.argv[3])
from test_tracks_lanes import _data, _filter
out = {}
for kind in ("design", "fixed"):
    for dtype in (np.float64, np.float32):
        for case, kw in (("a", dict()), ("b", dict(max_gap=20.0, on_duplicate="drop"))):
            lens = [3000, 7, 2500, 0, 1, 2048, 40, 999, 1500, 33, 2, 1200] + list(range(41))
            z, t, off = _data(13, lens, dtype=dtype, wide=(kind == "design"),
                              dup=0.003 if case == "b" else 0.0, gaps=0.003)
            f = _filter(kind)
            for resid in (False, True):
                r = f.run(z, t=t, offsets=off, return_residuals=resid, **kw)
                key = f"{kind}_{np.dtype(dtype).name}_{case}_{int(resid)}"
                out[key + "_s"] = r.states
                out[key + "_x"] = r.state.x
                out[key + "_t"] = r.state.t_last
                out[key + "_c"] = np.stack([r.n_dropped, r.n_restarts])
                if resid:
                    out[key + "_r"] = r.residuals
            rect = f.run(z[:5000].reshape(5, 1000), t=t[:1000], return_residuals=True, **kw)
            out[f"{kind}_{np.dtype(dtype).name}_{case}_rect"] = rect.states
np.savez(sys.argv[1] + "/" + sys.argv[2] + ".npz", **out)
"""
    # "on": the default lanes, the 8-lane AVX-512 build where the CPU has
    # it (opt-in; the default there is the 4-lane one, in its Zen 4 form on
    # AMD family 19h), and on a Zen 4 the 4 lanes' other form
    # (ABKIT_ZEN4=0), so that an AVX-512 machine checks them all
    on_envs = ({}, {"ABKIT_TRACKS_AVX512": "1"}, {"ABKIT_ZEN4": "0"})
    ons, off = _on_off(code, tmp_path, on_envs)
    for on_env, on in zip(on_envs, ons):
        assert sorted(on.files) == sorted(off.files) and len(on.files) > 40
        for k in on.files:
            assert on[k].dtype == off[k].dtype, (on_env, k)
            assert np.array_equal(on[k], off[k], equal_nan=True), (on_env, k)


@pytest.mark.parametrize("sw, T, lo, hi", [(1e-140, 0.1, -2, 1.5), (1e290, 1e-150, 3, 7)], ids=["tiny", "huge"])
def test_design_lanes_at_extreme_tracking_index(sw, T, lo, hi):
    """Tracking index lambda = (sw / sv) dt^2 far from 1: tiny (lambda
    underflows to 0 while sqrt(lambda) does not), and 1e296 .. 1e304, where
    the gains switch to the limit (1, 2 / dt) at 1e300 inside a block: the
    vector slots blend it in exactly as the scalar code branches."""
    lens = [1000, 5, 999, 640, 1001, 77, 800]
    z, t, off = _data(21, lens, pattern="random")
    rng = np.random.default_rng(5)
    for i in range(len(lens)):
        a, b = off[i], off[i + 1]
        t[a:b] = np.cumsum(10.0 ** rng.uniform(lo, hi, b - a))
    f = AlphaBetaFilter.from_noise(sw, 1.0, T)
    r = f.run(z, t=t, offsets=off, return_residuals=True)
    assert np.all(np.isfinite(r.states[0, ~np.isnan(z)]))
    for i in range(len(lens)):
        a, b = off[i], off[i + 1]
        one = f.run(z[a:b], t=t[a:b], return_residuals=True)
        assert np.array_equal(r.states[:, a:b], one.states, equal_nan=True), i
        assert np.array_equal(r.residuals[a:b], one.residuals, equal_nan=True), i


def test_fixed_gain_lanes_streamed_lines_equal_scalar_lanes(tmp_path):
    """Outputs of 8 MiB and more: the four AVX2 lanes with fixed gains write
    their float64 rows in whole streamed lines, each 64-byte line put
    together from two blocks (rows at every offset modulo 4 and 8 samples,
    the first and last part lines with ordinary stores). The same bits as
    the scalar lanes (ABKIT_DISABLE_SIMD=1, another process), ragged and
    rectangular (rows longer than the 2,048-step stretches streamed), with
    NaN and gaps (blocks the vector lanes stop at). (On an AMD Zen 4 the
    lanes store without streaming by default: both forms are checked.)"""
    code = r"""
import sys, numpy as np
sys.path.insert(0, sys.argv[3])
from test_tracks_lanes import _data, _filter
out = {}
f = _filter("fixed")
rng = np.random.default_rng(7)
lens = [int(v) for v in rng.integers(1, 9000, 150)] + [0, 1, 2, 3, 5, 8, 13, 64, 65, 1001]
for case, kw, gaps in (("a", dict(), 0.0), ("b", dict(max_gap=20.0), 0.002)):
    z, t, off = _data(31, lens, gaps=gaps)
    z[rng.random(z.size) < 0.002] = np.nan
    assert 16 * z.size >= 8 << 20
    r = f.run(z, t=t, offsets=off, **kw)
    out[case + "_s"] = r.states
    out[case + "_x"] = r.state.x
    zr = z[: 150 * 4001].reshape(150, 4001)
    tr = np.cumsum(np.random.default_rng(3).uniform(0.05, 0.15, (150, 4001)), axis=1)
    rect = f.run(zr, t=tr, **kw)
    out[case + "_rect"] = rect.states
    out[case + "_rect_x"] = rect.state.x
np.savez(sys.argv[1] + "/" + sys.argv[2] + ".npz", **out)
"""
    # ABKIT_ZEN4=0: on a Zen 4 the four lanes write ordinary stores by
    # default; this keeps their streamed lines checked there too
    on_envs = ({}, {"ABKIT_ZEN4": "0"})
    ons, off = _on_off(code, tmp_path, on_envs)
    for on_env, on in zip(on_envs, ons):
        assert sorted(on.files) == sorted(off.files) and len(on.files) == 8
        for k in on.files:
            assert np.array_equal(on[k], off[k], equal_nan=True), (on_env, k)
