"""The estimate arrays' layout (``abkit.empty_states``, ``out=``).

Fresh results of 8 MiB or more put each component plane on the same
64-byte line phase as the first (plane stride = plane size rounded up to 8
float64 / 16 float32 elements, then by more lines until the planes' rows
in flight are 64 bytes apart modulo 4 KiB; smaller ones are C-contiguous);
``out=`` takes that layout or a C-contiguous array. Checked
here: the layout itself (strides, alignment), that the kernels write the
same values into either layout as into a C-contiguous array (exactly: the
same kernel runs; the values themselves are checked against independent
references in the compliance tests, and against a plain loop below), that
the padding between planes is never written, and that other strided
``out=`` arrays are refused with a ``ValueError`` naming ``out``.
"""

from __future__ import annotations

import numpy as np
import pytest

import abkit

SENTINEL = 12345.5  # exactly representable in float32 and float64

PHI3 = np.array([[1.0, 1.0, 0.5], [0.0, 1.0, 1.0], [0.0, 0.0, 1.0]])
H3 = np.array([[1.0, 0.0, 0.0]])
K3 = np.array([[0.5], [0.2], [0.05]])


def _filters():
    return {
        "ab": abkit.AlphaBetaFilter(0.5, 0.2, 1.0),
        "abg": abkit.AlphaBetaGammaFilter(0.5, 0.2, 0.02, 1.0),
        "general3": abkit.FixedGainFilter(PHI3, H3, K3),
        "ab_f32arith": abkit.AlphaBetaFilter(0.5, 0.2, 1.0, float32_arithmetic=True),
    }


# Plane sizes off and on the line (f64: 8 elements, f32: 16), single and
# batched: small ones (back to back, not streamed) and ones of 8 MiB and
# more in all (padded, streamed stores; float32 too; (601, 1501) float64
# and (701, 1999) float32 3-state moved further by the 4 KiB rule).
SHAPES = [(3, 5), (7, 13), (101,), (16, 8), (999, 101), (1001, 1201), (1000, 1200), (701, 1999), (601, 1501), (1_100_003,), (4, 300_001)]


def _ref_stride(n, per, row, itemsize):
    """The padded layout's plane stride by its definition, brute force: the
    first whole number of 64-byte lines from ``per`` on at which every row
    in flight (up to 4 rows of each plane) starts at least 64 bytes (modulo
    4 KiB) from every other plane's, else the best separated within 64
    lines of padding; the planes back to back under 8 MiB in all."""
    if n < 2 or n * per * itemsize < 8 << 20:  # not streamed: back to back
        return per
    line = 64 // itemsize
    base = -(-per // line) * line
    rows = 1 if row == 0 else min(max(per // row, 1), 4)
    best = (-1, base)
    for k in range(64):
        s = base + k * line
        starts = [[(c * s + j * row) * itemsize % 4096 for j in range(rows)] for c in range(n)]
        sep = min(
            min((a - b) % 4096, (b - a) % 4096)
            for c1 in range(n) for c2 in range(c1 + 1, n) for a in starts[c1] for b in starts[c2]
        )
        if sep >= 64:
            return s
        if sep > best[0]:
            best = (sep, s)
    return best[1]


def _padded_out(shape, dtype, n, flat=False):
    """The padded layout built here independently of abkit (a buffer of
    sentinels), with the buffer for checking the padding."""
    dt = np.dtype(dtype)
    per = int(np.prod(shape))
    pad = _ref_stride(n, per, 0 if flat else shape[-1], dt.itemsize)
    buf = np.full((n - 1) * pad + per, SENTINEL, dtype=dt)
    o = np.lib.stride_tricks.as_strided(buf, (n,) + shape, (pad * dt.itemsize,) + tuple(int(np.prod(shape[k + 1 :])) * dt.itemsize for k in range(len(shape))))
    return o, buf, per, pad


@pytest.mark.parametrize("itemsize", [4, 8])
@pytest.mark.parametrize("n", [2, 3, 6])
def test_plane_stride_matches_its_definition(n, itemsize):
    """The Rust rule (abkit_core::planes::padded_stride) against the brute
    force above, over plane sizes and rows around the measured collisions."""
    from abkit import _abkit

    rng = np.random.default_rng(n * itemsize)
    cases = [(999 * 10_004, 10_004), (1000 * 10_000, 10_000), (99_999 * 101, 101), (13, 13), (1024, 0), (1 << 20, 0), (699_049, 1), (699_051, 1), (0, 0), (5, 1)]
    cases += [(int(nt) * int(ns), int(ns)) for nt, ns in zip(rng.integers(1, 3000, 40), rng.integers(1, 5000, 40))]
    cases += [(int(p), 0) for p in rng.integers(1, 10**7, 20)]
    for per, row in cases:
        assert _abkit.plane_stride(n, per, row, itemsize) == _ref_stride(n, per, row, itemsize), (n, per, row, itemsize)


def _padding_untouched(buf, n, per, pad):
    gaps = [buf[c * pad + per : (c + 1) * pad] for c in range(n - 1)]
    return all((g == SENTINEL).all() for g in gaps)


def _z(shape, dtype, seed=0):
    rng = np.random.default_rng(seed)
    z = (np.cumsum(rng.normal(0, 1, shape), axis=-1) + rng.normal(0, 1, shape)).astype(dtype)
    if z.shape[-1] > 6:
        z[..., 3:5] = np.nan  # missed detections
    return z


@pytest.mark.parametrize("n", [2, 3])
@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_shapes_cover_both_layouts(dtype, n):
    """The shape table exercises padded planes (off the lines and moved
    by the 4 KiB rule) as well as back-to-back ones, for every dtype."""
    isz = np.dtype(dtype).itemsize
    pads = [_ref_stride(n, int(np.prod(s)), s[-1], isz) - int(np.prod(s)) for s in SHAPES]
    assert sum(p > 0 for p in pads) >= 3 and sum(p == 0 for p in pads) >= 3, pads


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
@pytest.mark.parametrize("shape", SHAPES)
def test_fresh_results_are_in_the_padded_layout(shape, dtype):
    f = abkit.AlphaBetaFilter(0.5, 0.2, 1.0)
    s = f.run(_z(shape, dtype)).states
    isz = np.dtype(dtype).itemsize
    line = 64 // isz
    per = int(np.prod(shape))
    assert s.shape == (2,) + shape and s.dtype == dtype
    assert all(s[c].flags.c_contiguous for c in range(2))
    stride = _ref_stride(2, per, shape[-1], isz)
    if 2 * per * isz < 8 << 20:
        assert stride == per  # not streamed: back to back
    else:
        assert stride % line == 0 and per <= stride < per + line + 64 * line
    assert s.strides[0] == stride * isz
    assert s.flags.c_contiguous == (stride == per)
    if not s.flags.c_contiguous:
        assert s.ctypes.data % 64 == 0  # the first plane on a line boundary
    rr = f.run(_z(shape, dtype).reshape(-1), offsets=[0, per // 2, per]).states
    assert rr.strides[0] == _ref_stride(2, per, 0, isz) * isz


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
@pytest.mark.parametrize("shape", SHAPES)
@pytest.mark.parametrize("name", ["ab", "abg", "general3", "ab_f32arith"])
def test_layouts_give_the_same_values_and_padding_is_untouched(name, shape, dtype):
    f = _filters()[name]
    z = _z(shape, dtype)
    ref = f.run(z, out=np.empty((f.n,) + shape, dtype)).states  # C-contiguous
    fresh = f.run(z)
    np.testing.assert_array_equal(fresh.states, ref)
    o, buf, per, pad = _padded_out(shape, dtype, f.n)
    r = f.run(z, out=o)
    assert np.shares_memory(r.states, buf)
    np.testing.assert_array_equal(r.states, ref)
    assert _padding_untouched(buf, f.n, per, pad)
    # A result's .states passed back (the reuse pattern) and empty_states.
    again = f.run(z, out=fresh.states)
    assert again.states is fresh.states
    np.testing.assert_array_equal(again.states, ref)
    e = abkit.empty_states((f.n,) + shape, dtype)
    np.testing.assert_array_equal(f.run(z, out=e).states, ref)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
@pytest.mark.parametrize("name", ["ab", "abg", "general3", "ab_f32arith"])
def test_ragged_layouts(name, dtype):
    f = _filters()[name]
    z = _z((1_100_003,), dtype)
    off = np.array([0, 5, 1000, 1003, 600_000, 1_100_003])
    ref = f.run(z, offsets=off, out=np.empty((f.n, z.size), dtype)).states
    o, buf, per, pad = _padded_out(z.shape, dtype, f.n, flat=True)
    r = f.run(z, offsets=off, out=o)
    np.testing.assert_array_equal(r.states, ref)
    np.testing.assert_array_equal(f.run(z, offsets=off).states, ref)
    assert _padding_untouched(buf, f.n, per, pad)
    e = abkit.empty_states((f.n, z.size), dtype, ragged=True)
    np.testing.assert_array_equal(f.run(z, offsets=off, out=e).states, ref)
    if name in ("ab", "abg"):  # timestamps (the time-varying design laws)
        t = np.cumsum(np.random.default_rng(1).uniform(0.8, 1.2, z.size))
        ref_t = f.run(z, t=t, offsets=off, out=np.empty((f.n, z.size), dtype)).states
        o, buf, per, pad = _padded_out(z.shape, dtype, f.n, flat=True)
        np.testing.assert_array_equal(f.run(z, t=t, offsets=off, out=o).states, ref_t)
        assert _padding_untouched(buf, f.n, per, pad)
        np.testing.assert_array_equal(f.run(z, t=t, offsets=off).states, ref_t)


def test_single_long_track_split_with_timestamps():
    """A single long track with timestamps goes through the two-pass split
    (ragged_split), which writes its corrections by plane offset."""
    f = abkit.AlphaBetaFilter(0.5, 0.2, 1.0)
    z = _z((600_003,), np.float64)
    t = np.cumsum(np.random.default_rng(2).uniform(0.8, 1.2, z.size))
    off = np.array([0, z.size])
    ref = f.run(z, t=t, offsets=off, out=np.empty((2, z.size))).states
    o, buf, per, pad = _padded_out(z.shape, np.float64, 2, flat=True)
    np.testing.assert_array_equal(f.run(z, t=t, offsets=off, out=o).states, ref)
    assert _padding_untouched(buf, 2, per, pad)


def test_padded_layout_against_a_plain_loop():
    """Values in the padded layout against an independent alpha-beta loop
    (two-point start), float64, 1e-12 relative to the data's scale."""
    a, b, T = 0.5, 0.2, 1.0
    f = abkit.AlphaBetaFilter(a, b, T)
    z = _z((1001, 1201), np.float64, seed=3)
    r = f.run(z)
    assert not r.states.flags.c_contiguous
    for i in (0, 500, 1000):
        x = np.full((2, z.shape[1]), np.nan)
        valid = [k for k in range(z.shape[1]) if not np.isnan(z[i, k])]
        k1, k2 = valid[0], valid[1]
        x[0, k1] = z[i, k1]
        xp, vp = z[i, k2], (z[i, k2] - z[i, k1]) / ((k2 - k1) * T)
        x[:, k2] = xp, vp
        for k in range(k1 + 1, k2):
            x[0, k] = z[i, k1]
        for k in range(k2 + 1, z.shape[1]):
            xp, vp = xp + T * vp, vp
            if not np.isnan(z[i, k]):
                e = z[i, k] - xp
                xp, vp = xp + a * e, vp + b / T * e
            x[:, k] = xp, vp
        scale = np.nanmax(np.abs(z[i]))
        np.testing.assert_allclose(r.states[:, i, k2:], x[:, k2:], rtol=0, atol=1e-12 * scale)


def test_streaming_into_padded_outputs():
    f = abkit.AlphaBetaGammaFilter(0.5, 0.2, 0.02, 1.0)
    z = _z((1001, 1201), np.float64)
    whole = f.run(z, out=np.empty((3, 1001, 1201))).states
    r1 = f.run(z[:, :603])  # planes of 603,603 and 598,598 elements: both padded
    r2 = f.run(z[:, 603:], state=r1.state)
    assert not r1.states.flags.c_contiguous and not r2.states.flags.c_contiguous
    np.testing.assert_array_equal(np.concatenate([r1.states, r2.states], axis=-1), whole)


def test_smoother_and_kalman_layouts():
    ab = abkit.AlphaBetaFilter(0.5, 0.2, 1.0)
    z = _z((700, 1301), np.float64)
    ref = ab.smooth(z, out=np.empty((2, 700, 1301))).states
    o, buf, per, pad = _padded_out((700, 1301), np.float64, 2)
    assert pad > per
    np.testing.assert_array_equal(ab.smooth(z, out=o).states, ref)
    assert _padding_untouched(buf, 2, per, pad)
    np.testing.assert_array_equal(ab.smooth(z).states, ref)
    kf = abkit.KalmanFilter(PHI3, H3, 0.01 * np.eye(3), np.eye(1), P0=10 * np.eye(3))
    ref = kf.run(z, out=np.empty((3, 700, 1301))).states
    o, buf, per, pad = _padded_out((700, 1301), np.float64, 3)
    assert pad > per
    np.testing.assert_array_equal(kf.run(z, out=o).states, ref)
    assert _padding_untouched(buf, 3, per, pad)
    fresh = kf.run(z)
    np.testing.assert_array_equal(fresh.states, ref)
    assert kf.run(z, out=fresh.states).states is fresh.states


@pytest.mark.parametrize(
    "make",
    [
        lambda: np.empty((2, 7, 26))[:, :, ::2],  # strided samples
        lambda: np.empty((2, 7, 14))[:, :, :13],  # rows padded, not planes
        lambda: np.empty((2, 8, 13))[:, :7],  # plane stride 104, not 96 or 91
        lambda: np.empty((7, 13, 2)).transpose(2, 0, 1),  # component-minor
        lambda: np.empty((2, 7, 13))[::-1],  # planes in reverse
    ],
    ids=["strided-samples", "padded-rows", "other-plane-stride", "component-minor", "reversed"],
)
def test_other_strided_out_is_refused(make):
    f = abkit.AlphaBetaFilter(0.5, 0.2, 1.0)
    z = _z((7, 13), np.float64)
    o = make()
    before = o.copy()
    with pytest.raises(ValueError, match="out must be"):
        f.run(z, out=o)
    assert np.array_equal(o, before, equal_nan=True)  # not written
    kf = abkit.KalmanFilter(PHI3[:2, :2], H3[:, :2], 0.01 * np.eye(2), np.eye(1), P0=np.eye(2))
    with pytest.raises(ValueError, match="out must be"):
        kf.run(z, out=make())


def test_empty_states_validation():
    with pytest.raises(TypeError, match="dtype"):
        abkit.empty_states((2, 3), np.int64)
    for bad in [(2,), [2, 3], (2, -1), (2, 3.0), (True, 3)]:
        with pytest.raises(ValueError, match="shape"):
            abkit.empty_states(bad)  # type: ignore[arg-type]
    e = abkit.empty_states((2, 0, 5), np.float32)
    assert e.shape == (2, 0, 5) and e.dtype == np.float32
    e = abkit.empty_states((1, 7))
    assert e.flags.c_contiguous
    assert abkit.empty_states((2, 7, 13)).flags.c_contiguous  # small: back to back
    e = abkit.empty_states((2, 1001, 1201), np.float32)
    assert not e.flags.c_contiguous and e.strides[0] % 64 == 0 and e[1].flags.c_contiguous
