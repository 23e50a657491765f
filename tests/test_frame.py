"""abkit.frame.filter on pandas and polars DataFrames (long format).

Expected values: each track run alone through ``filter.run`` with numpy
arrays (the frame path must equal that exactly: same kernel, same samples),
and an independent plain-Python alpha-beta loop with irregular timestamps,
gap restarts and duplicate dropping written here from the documented
semantics (relative tolerance 1e-12)."""

from __future__ import annotations

import math

import numpy as np
import pytest

import abkit
from abkit import alphabeta, frame

pd = pytest.importorskip("pandas")
pl = pytest.importorskip("polars")
pa = pytest.importorskip("pyarrow")

F = abkit.AlphaBetaFilter(0.5, 0.2, 1.0)


def ab_irregular_ref(t, z, alpha, beta, max_gap=None, drop=False):
    """Fixed-gain alpha-beta, two-point start, timestamps t (one track).
    Returns pos, vel, res, n_dropped, n_restarts."""
    n = len(z)
    pos, vel, res = (np.full(n, math.nan) for _ in range(3))
    phase, x, v, z1, t1, tl = 0, 0.0, 0.0, 0.0, 0.0, None
    dropped = restarts = 0
    for k in range(n):
        tk, zk = float(t[k]), float(z[k])
        if tl is not None and tk <= tl:
            assert drop, "duplicate in a reference run without drop"
            dropped += 1
            continue
        if tl is not None and max_gap is not None and tk - tl > max_gap:
            phase = 0
            restarts += 1
        dt = None if tl is None else tk - tl
        tl = tk
        valid = zk == zk
        if phase == 2:
            xp = x + dt * v
            if valid:
                e = zk - xp
                res[k] = e
                x, v = xp + alpha * e, v + beta / dt * e
            else:
                x = xp
            pos[k], vel[k] = x, v
        elif phase == 1:
            if valid:
                x, v, phase = zk, (zk - z1) / (tk - t1), 2
                pos[k], vel[k] = x, v
            else:
                pos[k] = z1
        elif valid:
            z1, t1, phase = zk, tk, 1
            pos[k] = zk
    return pos, vel, res, dropped, restarts


def make_long(seed=0, n_tracks=6, lengths=(1, 2, 5, 40, 200), missed=0.1, shuffle=True, dup=False):
    rng = np.random.default_rng(seed)
    rows = []
    for i in range(n_tracks):
        n = int(lengths[i % len(lengths)])
        t = np.cumsum(rng.uniform(0.2, 3.0, n)) + rng.uniform(0, 10)
        if dup and n > 3:
            t[2] = t[1]  # a repeated report
        x = np.cumsum(rng.normal(size=n)) * 10
        y = np.cumsum(rng.normal(size=n))
        x[rng.random(n) < missed] = np.nan
        for k in range(n):
            rows.append((f"trk{i * 7 % n_tracks}", t[k], x[k], y[k]))
    df = pd.DataFrame(rows, columns=["id", "t", "x", "y"])
    if shuffle:
        df = df.sample(frac=1.0, random_state=seed).reset_index(drop=True)
    return df


def per_track_expected(df, f, cols=("x", "y"), **kw):
    """Each track alone through filter.run (numpy), scattered to df's rows."""
    out = {f"{c}_{s}": np.full(len(df), np.nan) for c in cols for s in ("pos", "vel", "res")}
    for _, g in df.groupby("id", sort=False):
        g = g.sort_values("t", kind="stable")
        idx = g.index.to_numpy()
        for c in cols:
            r = f.run(g[c].to_numpy(dtype=float), t=g["t"].to_numpy(dtype=float), return_residuals=True, **kw)
            out[f"{c}_pos"][idx] = r.position
            out[f"{c}_vel"][idx] = r.velocity
            out[f"{c}_res"][idx] = r.residuals
    return out


def _eq(a, b) -> bool:
    return np.array_equal(np.asarray(a, dtype=float), np.asarray(b, dtype=float), equal_nan=True)


def _col(out, name):
    return out[name].to_numpy() if isinstance(out, pd.DataFrame) else out.get_column(name).to_numpy()


@pytest.mark.parametrize("lib", ["pandas", "polars"])
@pytest.mark.parametrize("shuffle", [False, True])
def test_equals_each_track_alone(lib, shuffle) -> None:
    df = make_long(seed=1, shuffle=shuffle)
    want = per_track_expected(df, F)
    src = df if lib == "pandas" else pl.from_pandas(df)
    out, summary = frame.filter(src, id="id", time="t", columns=["x", "y"], filter=F, return_summary=True)
    assert type(out) is type(src)
    assert list(out.columns) == ["id", "t", "x", "y", "x_pos", "x_vel", "x_res", "y_pos", "y_vel", "y_res"]
    for k, v in want.items():
        assert _eq(_col(out, k), v), k
    assert _eq(_col(out, "x"), df["x"])  # original rows, original order
    assert summary.n_tracks == df["id"].nunique() and summary.n_rows.sum() == len(df)
    assert summary.sorted is shuffle or not shuffle and summary.sorted is False
    assert set(summary.ids.tolist()) == set(df["id"])
    assert summary.totals()["n_dropped"] == 0


def test_against_independent_reference_loop() -> None:
    df = make_long(seed=2, lengths=(3, 50, 120))
    out = frame.filter(df, id="id", time="t", columns="x", filter=F)
    for _, g in df.groupby("id"):
        g = g.sort_values("t", kind="stable")
        pos, vel, res, _, _ = ab_irregular_ref(g["t"].to_numpy(), g["x"].to_numpy(), 0.5, 0.2)
        idx = g.index.to_numpy()
        scale = np.nanmax(np.abs(g["x"]))
        np.testing.assert_allclose(out["x_pos"].to_numpy()[idx], pos, rtol=1e-12, atol=1e-12 * scale)
        np.testing.assert_allclose(out["x_vel"].to_numpy()[idx], vel, rtol=1e-12, atol=1e-12 * scale)
        np.testing.assert_allclose(out["x_res"].to_numpy()[idx], res, rtol=1e-12, atol=1e-12 * scale)


def test_sorted_input_is_not_reordered_or_copied() -> None:
    df = make_long(seed=3, shuffle=False)
    out, s = frame.filter(df, id="id", time="t", columns=["x"], filter=F, return_summary=True)
    assert s.sorted is False
    # grouped by id in any id order is fine: reverse the track order, keep time order
    order = np.concatenate([g.index.to_numpy() for _, g in reversed(list(df.groupby("id", sort=False)))])
    df2 = df.loc[order].reset_index(drop=True)
    _, s2 = frame.filter(df2, id="id", time="t", columns=["x"], filter=F, return_summary=True)
    assert s2.sorted is False
    # the kernel sees the frame's own buffer (no copy) for a float64 column without nulls
    z = frame._float_values(df2, "pandas", "y")
    assert np.shares_memory(z, df2["y"].to_numpy())


def test_duplicates_raise_naming_track_and_row() -> None:
    df = make_long(seed=4, dup=True, shuffle=False, missed=0.0)
    with pytest.raises(ValueError, match=r"track id='trk\d+', row \d+.*not after"):
        frame.filter(df, id="id", time="t", columns="x", filter=F)


def test_duplicates_dropped_and_counted() -> None:
    df = make_long(seed=5, dup=True, missed=0.0)
    out, s = frame.filter(df, id="id", time="t", columns=["x"], filter=F, on_duplicate="drop", return_summary=True)
    n_dup = sum(1 for n in (1, 2, 5, 40, 200, 1) if n > 3)
    assert s.n_dropped.sum() == n_dup == out.attrs["abkit"]["n_dropped"]
    for _, g in df.groupby("id"):
        g = g.sort_values("t", kind="stable")
        pos, vel, res, dropped, _ = ab_irregular_ref(g["t"].to_numpy(), g["x"].to_numpy(), 0.5, 0.2, drop=True)
        idx = g.index.to_numpy()
        np.testing.assert_allclose(out["x_pos"].to_numpy()[idx], pos, rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose(out["x_vel"].to_numpy()[idx], vel, rtol=1e-12, atol=1e-9)


def test_gaps_restart_and_are_counted() -> None:
    rng = np.random.default_rng(6)
    t = np.concatenate([np.arange(10.0), 100 + np.arange(10.0), 300 + np.arange(5.0)])
    x = 3.0 * t + rng.normal(size=t.size)
    df = pd.DataFrame({"id": 1, "t": t, "x": x})
    out, s = frame.filter(df, id="id", time="t", columns="x", filter=F, max_gap=10.0, return_summary=True)
    assert s.n_restarts.tolist() == [2] and out.attrs["abkit"]["n_restarts"] == 2
    pos, vel, res, _, restarts = ab_irregular_ref(t, x, 0.5, 0.2, max_gap=10.0)
    assert restarts == 2
    np.testing.assert_allclose(out["x_vel"].to_numpy(), vel, rtol=1e-12, atol=1e-9)
    assert np.isnan(out["x_vel"].to_numpy()[[0, 10, 20]]).all()


def test_mixed_lengths_design_schedule_and_float32() -> None:
    f = abkit.AlphaBetaFilter.from_design(alphabeta.from_noise(0.5, 2.0, 1.0))
    df = make_long(seed=7, n_tracks=9, lengths=(1, 3, 10, 1000, 57))
    df["y"] = df["y"].astype(np.float32)
    out = frame.filter(df, id="id", time="t", columns=["x", "y"], filter=f)
    assert out["y_pos"].dtype == np.float32 and out["x_pos"].dtype == np.float64
    want = per_track_expected(df.assign(y=df["y"].astype(np.float64)), f, cols=("x",))
    for k, v in want.items():
        assert _eq(out[k], v), k
    for _, g in df.groupby("id"):
        g = g.sort_values("t", kind="stable")
        r = f.run(g["y"].to_numpy(), t=g["t"].to_numpy(), return_residuals=True)
        assert _eq(out["y_vel"].to_numpy()[g.index.to_numpy()], r.velocity)


def test_without_time_uses_row_order_and_T() -> None:
    # the ragged kernel and the rectangular one round differently in the last bit
    df = make_long(seed=8)
    out = frame.filter(df, id="id", columns="x", filter=F)
    for _, g in df.groupby("id"):
        r = F.run(g["x"].to_numpy())
        np.testing.assert_allclose(out["x_vel"].to_numpy()[g.index.to_numpy()], r.velocity, rtol=1e-12,
                                   atol=1e-12 * np.nanmax(np.abs(g["x"])))


def test_abg_has_acceleration_columns() -> None:
    f = abkit.AlphaBetaGammaFilter(0.5, 0.3, 0.05, 1.0)
    df = make_long(seed=9)
    out = frame.filter(pl.from_pandas(df), id="id", time="t", columns="y", filter=f, return_residuals=False)
    assert out.columns[-3:] == ["y_pos", "y_vel", "y_acc"]


def test_arrow_dtypes_pandas_zero_copy_and_nulls() -> None:
    df = make_long(seed=10, shuffle=False, missed=0.0)
    want = per_track_expected(df, F)
    adf = df.astype({"x": pd.ArrowDtype(pa.float64()), "y": pd.ArrowDtype(pa.float64()),
                     "t": pd.ArrowDtype(pa.float64()), "id": pd.ArrowDtype(pa.string())})
    z = frame._float_values(adf, "pandas", "x")
    buf = adf["x"].array._pa_array.chunk(0).buffers()[1]
    assert z.ctypes.data == buf.address  # handed over without a copy
    out = frame.filter(adf, id="id", time="t", columns=["x", "y"], filter=F)
    for k, v in want.items():
        assert _eq(out[k], v), k
    # nulls are missed detections, like NaN
    xn = df["x"].copy()
    xn.iloc[[3, 50]] = np.nan
    nulls = adf.assign(x=pd.array([None if np.isnan(v) else v for v in xn], dtype=pd.ArrowDtype(pa.float64())))
    want2 = per_track_expected(df.assign(x=xn), F, cols=("x",))
    out2 = frame.filter(nulls, id="id", time="t", columns="x", filter=F)
    assert _eq(out2["x_vel"], want2["x_vel"])


def test_polars_zero_copy_nulls_and_datetimes() -> None:
    df = make_long(seed=11, shuffle=False, missed=0.0)
    p = pl.from_pandas(df)
    z = frame._float_values(p, "polars", "x")
    assert np.shares_memory(z, p.get_column("x").to_numpy())
    xs = p.get_column("x").to_list()
    xs[4] = None
    us = 1_600_000_000_000_000 + np.round(df["t"].to_numpy() * 1e6).astype(np.int64)
    p2 = p.with_columns(pl.Series("x", xs, dtype=pl.Float64), pl.Series("ts", us).cast(pl.Datetime("us")))
    # expected: the same instants as float seconds since the epoch
    want = per_track_expected(df.assign(x=[np.nan if v is None else v for v in xs], t=us * 1e3 / 1e9), F, cols=("x",))
    out = frame.filter(p2.drop("t"), id="id", time="ts", columns="x", filter=F)
    assert _eq(out.get_column("x_vel").to_numpy(), want["x_vel"])


def test_integer_and_nullable_columns_are_numbers_with_nulls_missed() -> None:
    # pandas nullable Float64/Int64, Arrow-backed int64 and polars Int64
    # columns (integers converted to float64, nulls = missed detections)
    # give the estimates of the float64 column with NaN for the nulls.
    df = make_long(seed=16, shuffle=False, missed=0.0)
    xi = np.round(df["x"].to_numpy() * 10).astype(np.int64)
    null = np.zeros(len(df), bool)
    null[[2, 30, 31]] = True
    want = per_track_expected(df.assign(x=np.where(null, np.nan, xi.astype(np.float64))), F, cols=("x",))
    vals = [None if n else int(v) for v, n in zip(xi, null)]
    for col in (pd.array(vals, dtype="Int64"), pd.array(vals, dtype="Float64"),
                pd.array(vals, dtype=pd.ArrowDtype(pa.int64()))):
        out = frame.filter(df.assign(x=col), id="id", time="t", columns="x", filter=F)
        assert _eq(np.asarray(out["x_vel"], dtype=np.float64), want["x_vel"]), col.dtype
    p = pl.from_pandas(df).with_columns(pl.Series("x", vals, dtype=pl.Int64))
    out = frame.filter(p, id="id", time="t", columns="x", filter=F)
    assert _eq(out.get_column("x_vel").to_numpy(), want["x_vel"])


@pytest.mark.parametrize("lib", ["pandas", "polars"])
def test_missing_datetime_names_the_row(lib) -> None:
    df = make_long(seed=17)
    ts = pd.Timestamp("2024-01-01") + pd.to_timedelta(df["t"], unit="s")
    ts.iloc[5] = pd.NaT
    src = df.assign(ts=ts)
    src = src if lib == "pandas" else pl.from_pandas(src)
    with pytest.raises(ValueError, match="time column 'ts': missing timestamp at row 5"):
        frame.filter(src, id="id", time="ts", columns="x", filter=F)


def test_pandas_datetimes() -> None:
    df = make_long(seed=12)
    ts = pd.Timestamp("2024-01-01", tz="Europe/Paris") + pd.to_timedelta(df["t"], unit="s")
    out = frame.filter(df.assign(ts=ts).drop(columns="t"), id="id", time="ts", columns="x", filter=F)
    ns = ts.dt.tz_convert("UTC").dt.tz_localize(None).to_numpy(dtype="datetime64[ns]").astype(np.int64)
    assert ns[0] > 1.7e18  # 2024 since the epoch, in nanoseconds
    want = per_track_expected(df.assign(t=ns / 1e9), F, cols=("x",))
    assert _eq(out["x_vel"].to_numpy(), want["x_vel"])


def test_input_not_modified_and_attrs_kept() -> None:
    df = make_long(seed=13)
    df.attrs["source"] = "test"
    before = df.copy()
    out = frame.filter(df, id="id", time="t", columns=["x"], filter=F)
    pd.testing.assert_frame_equal(df, before)
    assert out.attrs["source"] == "test" and "abkit" not in df.attrs


def test_empty_frame() -> None:
    df = make_long(seed=14).iloc[:0]
    out = frame.filter(df, id="id", time="t", columns=["x", "y"], filter=F)
    assert len(out) == 0 and "y_res" in out.columns
    assert frame.filter(pl.from_pandas(df), id="id", time="t", columns="x", filter=F).columns[-1] == "x_res"


@pytest.mark.parametrize("lib", ["pandas", "polars"])
def test_bad_input(lib) -> None:
    df = make_long(seed=15)
    src = df if lib == "pandas" else pl.from_pandas(df)
    with pytest.raises(ValueError, match="columns: no column 'z'"):
        frame.filter(src, id="id", time="t", columns=["x", "z"], filter=F)
    with pytest.raises(ValueError, match="id: no column 'track'"):
        frame.filter(src, id="track", time="t", columns="x", filter=F)
    with pytest.raises(ValueError, match="time: no column 'time'"):
        frame.filter(src, id="id", time="time", columns="x", filter=F)
    with pytest.raises(ValueError, match="need timestamps"):
        frame.filter(src, id="id", columns="x", filter=F, max_gap=3.0)
    with pytest.raises(TypeError, match="column 'id': expected numbers"):
        frame.filter(src, id="t", columns="id", filter=F)
    with pytest.raises(TypeError, match="filter"):
        frame.filter(src, id="id", columns="x", filter="ab")
    renamed = df.rename(columns={"y": "x_pos"})
    with pytest.raises(ValueError, match="'x_pos' already exists"):
        frame.filter(renamed if lib == "pandas" else pl.from_pandas(renamed), id="id", columns="x", filter=F)
    tn = df.copy()
    tn.loc[7, "t"] = np.nan
    with pytest.raises(ValueError, match="time column 't': timestamp at row 7 is missing"):
        frame.filter(tn if lib == "pandas" else pl.from_pandas(tn), id="id", time="t", columns="x", filter=F)


def test_not_a_dataframe() -> None:
    with pytest.raises(TypeError, match="pandas or polars DataFrame"):
        frame.filter({"x": [1.0]}, id="id", columns="x", filter=F)
    with pytest.raises(TypeError, match="LazyFrame"):
        frame.filter(pl.DataFrame({"id": [1], "x": [1.0]}).lazy(), id="id", columns="x", filter=F)


def test_doctests() -> None:
    import doctest

    res = doctest.testmod(frame, optionflags=doctest.NORMALIZE_WHITESPACE | doctest.ELLIPSIS)
    assert res.failed == 0 and res.attempted > 0


@pytest.mark.parametrize("k", [1, 3, 300, 70_000, 5_000_000])
def test_group_order_equals_stable_lexsort(k) -> None:
    # the radix grouping (with or without the time sort) against numpy's stable lexsort
    rng = np.random.default_rng(k)
    n = 200_000
    codes = rng.integers(0, k, n)
    t_feed = np.sort(rng.uniform(0, 100, n))  # a time-ordered feed, tracks interleaved
    t_rand = np.round(rng.uniform(0, 100, n), 1)  # ties included
    for t in (t_feed, t_rand, None):
        g = frame.group(codes, t)
        want = np.lexsort((t, codes)) if t is not None else np.argsort(codes, kind="stable")
        if g.order is None:
            assert np.array_equal(want, np.arange(n))
        else:
            assert np.array_equal(g.order, want)
        cs = codes[want]
        starts = np.flatnonzero(np.diff(cs)) + 1
        assert g.offsets.tolist() == [0] + starts.tolist() + [n]
