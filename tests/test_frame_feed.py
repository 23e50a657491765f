"""frame.filter on a time-ordered feed (rows of many tracks interleaved,
ordered by time: an AIS/ADS-B dump as it arrives) runs the row kernel
(``abkit-core`` module ``feed``: per-track state tables, rows read and
written in order, nothing reordered).

docs/frame.md promises the same results as grouping the rows by track:
every estimate, residual, count and error is compared with

- each track run alone through ``filter.run(z, t=t)`` (bit-identical), and
- the grouped path of the same call (the rows reordered by track, the
  ragged kernel; bit-identical),

and the alpha-beta case also with the independent reference loop of
tests/test_frame.py (1e-12 relative to the track's scale).
"""

from __future__ import annotations

import numpy as np
import pytest

import abkit
from abkit import frame
from abkit import _tracks

pd = pytest.importorskip("pandas")
pl = pytest.importorskip("polars")
pytest.importorskip("pyarrow")

from test_frame import ab_irregular_ref  # noqa: E402

FILTERS = {
    "ab-fixed": lambda: abkit.AlphaBetaFilter(0.5, 0.2, 1.0),
    "ab-design": lambda: abkit.AlphaBetaFilter.from_noise(0.3, 2.0, 1.0),
    "abg-fixed": lambda: abkit.AlphaBetaGammaFilter(0.5, 0.3, 0.05, 1.0),
    "abg-design": lambda: abkit.AlphaBetaGammaFilter.from_noise(0.0, 0.0, 0.05, 4.0, 1.0),
    "singer": lambda: abkit.singer.tracking_filter(1.0, tau=20.0, sigma_m=0.5, sigma_pos=2.0),
}


def feed_frame(seed: int, n_tracks: int = 12, n: int = 600, dup: bool = False, nan: float = 0.1, same_t: bool = True):
    """A time-ordered feed: ``n`` reports of ``n_tracks`` interleaved
    tracks; some reports of different tracks share a timestamp, with
    ``dup`` some of one track too (a repeated report)."""
    rng = np.random.default_rng(seed)
    ids = rng.integers(0, n_tracks, n)
    steps = rng.exponential(0.7, n)
    if same_t:
        steps[rng.random(n) < 0.2] = 0.0  # reports at the same time
    t = np.cumsum(steps) + 100.0
    if not dup:
        # no repeated timestamp within a track: nudge the later ones
        last: dict = {}
        for r in range(n):
            i = int(ids[r])
            if i in last and t[r] <= last[i]:
                t[r:] += 1e-3
            last[i] = t[r]
    x = 5.0 * t + 40.0 * ids + rng.normal(0, 1.0, n)
    y = -2.0 * t + rng.normal(0, 3.0, n)
    x[rng.random(n) < nan] = np.nan
    y[rng.random(n) < nan] = np.nan
    names = np.array([f"ship{int(i) * 37 % 101}" for i in ids])
    return pd.DataFrame({"id": names, "t": t, "x": x, "y": y})


def assert_first_duplicate_in_time(df, msg):
    """``msg`` names the row of the earliest (in time, then row order)
    report whose timestamp repeats an earlier report of its track."""
    row = int(msg.split("row ")[1].split(":")[0])
    assert f"track id={df['id'][row]!r}" in msg
    order = np.lexsort((np.arange(len(df)), df["t"].to_numpy()))
    last = {}
    for r in order:
        tid = df["id"][r]
        if tid in last and df["t"][r] <= last[tid]:
            assert r == row, (r, row)
            return
        last[tid] = df["t"][r]
    raise AssertionError("no duplicate in the frame")


def grouped(df, **kw):
    """The same call through the grouped path (rows reordered by track)."""
    orig = frame.group
    frame.group = lambda codes, t, feed=False: orig(codes, t, False)  # type: ignore[assignment]
    try:
        return frame.filter(df, **kw)
    finally:
        frame.group = orig  # type: ignore[assignment]


def assert_frames_identical(a, b, cols):
    for c in cols:
        va = a[c].to_numpy() if hasattr(a, "iloc") else a.get_column(c).to_numpy()
        vb = b[c].to_numpy() if hasattr(b, "iloc") else b.get_column(c).to_numpy()
        assert va.dtype == vb.dtype, c
        assert np.array_equal(va, vb, equal_nan=True), c


@pytest.mark.parametrize("lib", ["pandas", "polars"])
@pytest.mark.parametrize("name", list(FILTERS))
@pytest.mark.parametrize("opts", [{}, {"max_gap": 2.0}, {"on_duplicate": "drop"}, {"init": "first", "max_gap": 1.5}])
def test_feed_equals_grouped_path_and_each_track_alone(lib, name, opts):
    f = FILTERS[name]()
    df = feed_frame(seed=len(name) + 7 * len(opts), dup="on_duplicate" in opts)
    src = df if lib == "pandas" else pl.from_pandas(df)
    kw = dict(id="id", time="t", columns=["x", "y"], filter=f, return_summary=True, **opts)
    out, s = frame.filter(src, **kw)
    ref, s_ref = grouped(src, **kw)
    assert s.sorted is False and s_ref.sorted is True  # the feed ran as it stands
    cols = [c for c in out.columns if c not in df.columns]
    assert list(out.columns) == list(ref.columns)
    assert_frames_identical(out, ref, cols)
    assert list(s.ids) == list(s_ref.ids)
    for k in ("n_rows", "n_dropped", "n_restarts"):
        assert np.array_equal(getattr(s, k), getattr(s_ref, k)), k
    if "max_gap" in opts:
        assert s.n_restarts.sum() > 0  # the case exercises restarts
    if "on_duplicate" in opts:
        assert s.n_dropped.sum() > 0
    # each track alone through run(z, t=t), in row order within the track
    run_kw = {k: v for k, v in opts.items()}
    for tid in df["id"].unique()[:4]:
        rows = np.flatnonzero(df["id"].to_numpy() == tid)
        for c in ("x", "y"):
            r = f.run(df[c].to_numpy()[rows], t=df["t"].to_numpy()[rows], return_residuals=True, **run_kw)
            got = np.stack([(out[f"{c}_{sfx}"].to_numpy() if lib == "pandas" else out.get_column(f"{c}_{sfx}").to_numpy())[rows]
                            for sfx in ["pos", "vel", "acc"][: f.n]])
            assert np.array_equal(got, r.states, equal_nan=True)


@pytest.mark.parametrize("lib", ["pandas", "polars"])
@pytest.mark.parametrize("name", ["ab-design", "abg-fixed", "singer"])
def test_shuffled_rows_sorted_by_time_then_fed(lib, name):
    """Rows in no order: sorted by time once and run as a feed; the same
    as the grouped path (which sorts by id and time), bit for bit, errors
    included."""
    f = FILTERS[name]()
    df = feed_frame(seed=21, dup=True).sample(frac=1.0, random_state=3).reset_index(drop=True)
    src = df if lib == "pandas" else pl.from_pandas(df)
    kw = dict(id="id", time="t", columns=["x", "y"], filter=f, return_summary=True, on_duplicate="drop", max_gap=3.0)
    out, s = frame.filter(src, **kw)
    ref, s_ref = grouped(src, **kw)
    assert s.sorted is True and s_ref.sorted is True
    assert_frames_identical(out, ref, [c for c in out.columns if c not in df.columns])
    for k in ("ids", "n_rows", "n_dropped", "n_restarts"):
        assert np.array_equal(getattr(s, k), getattr(s_ref, k)), k
    assert s.n_dropped.sum() > 0 and s.n_restarts.sum() > 0
    kw.pop("on_duplicate")
    with pytest.raises(ValueError) as e_feed:
        frame.filter(src, **kw)
    # the grouped path reports the first track with an error, the feed the
    # first error in time: both name a repeated report of its track
    assert_first_duplicate_in_time(df, str(e_feed.value))


def test_feed_against_independent_reference_loop():
    df = feed_frame(seed=3, n_tracks=5, n=800)
    out = frame.filter(df, id="id", time="t", columns="x", filter=abkit.AlphaBetaFilter(0.5, 0.2, 1.0))
    for tid in df["id"].unique():
        rows = np.flatnonzero(df["id"].to_numpy() == tid)
        pos, vel, res, _, _ = ab_irregular_ref(df["t"].to_numpy()[rows], df["x"].to_numpy()[rows], 0.5, 0.2)
        scale = np.nanmax(np.abs(df["x"].to_numpy()[rows]))
        for col, want in (("x_pos", pos), ("x_vel", vel), ("x_res", res)):
            np.testing.assert_allclose(out[col].to_numpy()[rows], want, rtol=1e-12, atol=1e-12 * scale)


@pytest.mark.parametrize("dtypes", [("float32", "float32"), ("float32", "float64"), ("float64", "float32")])
def test_feed_float32_and_mixed_column_dtypes(dtypes):
    df = feed_frame(seed=11)
    df["x"] = df["x"].astype(dtypes[0])
    df["y"] = df["y"].astype(dtypes[1])
    f = FILTERS["ab-design"]()
    kw = dict(id="id", time="t", columns=["x", "y"], filter=f)
    out, ref = frame.filter(df, **kw), grouped(df, **kw)
    assert list(out.columns) == list(ref.columns)
    assert out["x_pos"].dtype == np.dtype(dtypes[0]) and out["y_res"].dtype == np.dtype(dtypes[1])
    assert_frames_identical(out, ref, [c for c in out.columns if c not in df.columns])


def test_feed_errors_name_the_column_track_and_row():
    df = feed_frame(seed=5, dup=True)
    with pytest.raises(ValueError) as e_feed:
        frame.filter(df, id="id", time="t", columns=["x", "y"], filter=FILTERS["ab-fixed"]())
    assert "column 'x', track id=" in str(e_feed.value) and "on_duplicate='drop'" in str(e_feed.value)
    assert_first_duplicate_in_time(df, str(e_feed.value))
    # an Inf measurement: named by column, track and row
    df = feed_frame(seed=6)
    df.loc[300, "y"] = np.inf
    with pytest.raises(ValueError, match=r"column 'y', track id='.*', row 300: z must be finite"):
        frame.filter(df, id="id", time="t", columns=["x", "y"], filter=FILTERS["ab-fixed"]())


def test_feed_is_used_only_for_time_ordered_rows():
    codes = np.array([0, 1, 0, 1, 2, 0])
    g = frame.group(codes, np.array([0.0, 0.0, 1.0, 2.0, 2.0, 3.0]), feed=True)
    assert g.feed is not None and g.order is None
    assert g.row(0, 2) == 5 and g.row(1, 1) == 3
    # not ordered by time: one stable sort by time, then a feed
    g = frame.group(codes, np.array([0.0, 0.0, 1.0, 2.0, 2.0, 1.5]), feed=True)
    assert g.feed is not None and np.array_equal(g.order, [0, 1, 2, 5, 3, 4])
    assert np.array_equal(g.feed, codes[g.order])
    assert g.row(0, 2) == 5 and g.row(2, 0) == 4
    # without timestamps: grouped by the radix sort
    g = frame.group(codes, None, feed=True)
    assert g.feed is None and np.array_equal(g.order, [0, 2, 5, 1, 3, 4])
    # grouped and ordered: no feed, no order
    g = frame.group(np.array([0, 0, 1, 1]), np.array([0.0, 1.0, 0.0, 1.0]), feed=True)
    assert g.feed is None and g.order is None
    # without feed=True (the CLI's streaming path): sorted
    g = frame.group(codes, np.array([0.0, 0.0, 1.0, 2.0, 2.0, 3.0]))
    assert g.feed is None and g.order is not None


@pytest.mark.parametrize("threads", [None, 1, 2])
def test_run_feed_equals_ragged_kernel(threads):
    """The row kernel directly against run(z, t=, offsets=) on the grouped
    rows: states, residuals, counts, rows per track, first rows."""
    rng = np.random.default_rng(2)
    n, k = 3000, 40
    codes = rng.integers(0, k, n)
    t = np.cumsum(rng.exponential(0.5, n))
    t[rng.random(n) < 0.05] = 0  # placeholder, fixed below
    t = np.maximum.accumulate(np.where(t == 0, np.roll(t, 1), t))
    cols = [rng.normal(size=n).cumsum() for _ in range(3)]
    for c in cols:
        c[rng.random(n) < 0.1] = np.nan
    f = FILTERS["abg-design"]()
    out, res, counts, rows = _tracks.run_feed(f, cols, t, codes, k, max_gap=3.0, on_duplicate="drop", threads=threads)
    order = np.argsort(codes, kind="stable")
    off = np.concatenate([[0], np.cumsum(np.bincount(codes, minlength=k))])
    assert np.array_equal(rows[:, 0], np.diff(off))
    assert np.array_equal(rows[:, 1], order[off[:-1]])
    for j, z in enumerate(cols):
        r = f.run(z[order], t=t[order], offsets=off, max_gap=3.0, on_duplicate="drop", return_residuals=True)
        assert np.array_equal(out[j][:, order], r.states, equal_nan=True)
        assert np.array_equal(res[j][order], r.residuals, equal_nan=True)
        if j == 0:
            assert np.array_equal(counts[:, 0], r.n_dropped) and np.array_equal(counts[:, 1], r.n_restarts)
            assert counts.sum() > 0


def test_run_feed_bad_input():
    f = FILTERS["ab-fixed"]()
    z = np.zeros(4)
    with pytest.raises(ValueError, match="one dtype"):
        _tracks.run_feed(f, [z, z.astype(np.float32)], np.arange(4.0), np.zeros(4, np.int64), 1)
    with pytest.raises(ValueError, match="track code 3 outside"):
        _tracks.run_feed(f, [z], np.arange(4.0), np.array([0, 1, 3, 0]), 2)
    with pytest.raises(TypeError, match="float32 or float64"):
        _tracks.run_feed(f, [np.zeros(4, np.int64)], np.arange(4.0), np.zeros(4, np.int64), 1)
    with pytest.raises(ValueError, match="m = 1"):
        fv = abkit.FixedGainFilter(np.eye(2), np.eye(2), 0.5 * np.eye(2))
        _tracks.run_feed(fv, [z], None, np.zeros(4, np.int64), 1)


@pytest.mark.parametrize("threads", [None, 1, 2])
def test_time_order_is_numpys_stable_argsort(threads):
    """The Rust time sort behind shuffled frames against numpy's stable
    argsort: ties in row order, -0.0 == 0.0, +-inf, NaN last."""
    from abkit import _abkit

    rng = np.random.default_rng(5)
    cases = [
        rng.uniform(-1e6, 1e6, 100_000),
        np.round(rng.uniform(-5, 5, 50_000), 1),  # many ties
        np.array([np.nan, -0.0, 0.0, np.inf, -np.inf, np.nan, -0.0, 1.0, 1.0, -5e-324, 5e-324]),
        np.zeros(0),
        rng.uniform(0, 10, 2000)[::3],  # strided
    ]
    for t in cases:
        if t.size > 100:
            t[rng.random(t.size) < 0.02] = np.nan
            t[rng.random(t.size) < 0.02] = -0.0
            t[rng.random(t.size) < 0.01] = np.inf
        assert np.array_equal(_abkit.time_order(t, threads), np.argsort(t, kind="stable"))
