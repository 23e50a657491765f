"""``abkit run``: every format round trip, chunked streaming equal to the
whole-file computation, bad flags (exit 2), bad data (exit 1, message naming
file, row and column), through a subprocess and through ``abkit.cli.main``.

Expected estimates: the in-memory ``filter.run`` of the same data (the CLI's
claim is to write exactly those), and for one case the independent scalar
reference loop of ``filterref`` (relative tolerance 1e-12)."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

import abkit
from abkit import alphabeta
from abkit.cli import main

from filterref import ab_scalar_ref

pa = pytest.importorskip("pyarrow")
pcsv = pytest.importorskip("pyarrow.csv")
pq = pytest.importorskip("pyarrow.parquet")

AB = ["--alpha", "0.5", "--beta", "0.2", "-T", "0.5"]


def cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "abkit", "run", *args], capture_output=True, text=True)


def _eq(a, b) -> bool:
    return np.shape(a) == np.shape(b) and np.array_equal(np.asarray(a, dtype=float), np.asarray(b, dtype=float), equal_nan=True)


@pytest.fixture
def z():
    rng = np.random.default_rng(0)
    z = np.cumsum(rng.normal(size=(5, 403)), axis=1)
    z[rng.random(z.shape) < 0.05] = np.nan
    return z


F = abkit.AlphaBetaFilter(0.5, 0.2, 0.5)


# -- arrays --------------------------------------------------------------------------------
@pytest.mark.parametrize("chunk", ["7", "403", "1000", "2000", "1000000"])
def test_npy_round_trip_chunked_equals_whole(tmp_path, z, chunk) -> None:
    np.save(tmp_path / "z.npy", z)
    assert main(["run", str(tmp_path / "z.npy"), "-o", str(tmp_path / "o.npy"), *AB, "--chunk-rows", chunk, "-q"]) == 0
    assert _eq(np.load(tmp_path / "o.npy"), F.run(z).states)


def test_npy_single_track_against_reference_loop(tmp_path, z) -> None:
    np.save(tmp_path / "z.npy", z[2])
    out = cli(str(tmp_path / "z.npy"), "-o", str(tmp_path / "o.npy"), *AB, "--chunk-rows", "50")
    assert out.returncode == 0, out.stderr
    assert out.stderr == ""  # no progress bar when stderr is not a terminal
    got = np.load(tmp_path / "o.npy")
    pos, vel = ab_scalar_ref(z[2], 0.5, 0.2, 0.5)
    np.testing.assert_allclose(got[0], pos, rtol=1e-12)
    np.testing.assert_allclose(got[1], vel, rtol=1e-12)


@pytest.mark.parametrize("compressed", [False, True])
@pytest.mark.parametrize("chunk", ["13", "1000000"])
def test_npz_round_trip(tmp_path, z, compressed, chunk) -> None:
    (np.savez_compressed if compressed else np.savez)(tmp_path / "z.npz", z=z, other=np.arange(3))
    assert main(["run", str(tmp_path / "z.npz"), "-o", str(tmp_path / "o.npz"), *AB, "--chunk-rows", chunk, "-q"]) == 0
    want = F.run(z, return_residuals=True)
    with np.load(tmp_path / "o.npz") as o:
        assert sorted(o) == ["position", "residual", "velocity"]
        assert _eq(o["position"], want.position) and _eq(o["velocity"], want.velocity)
        assert _eq(o["residual"], want.residuals)


def test_npz_key_and_float32_and_int(tmp_path, z) -> None:
    np.savez(tmp_path / "a.npz", meas=z.astype(np.float32), ints=np.arange(40).reshape(2, 20))
    assert main(["run", str(tmp_path / "a.npz"), "-o", str(tmp_path / "o.npz"), *AB, "--key", "meas", "-q"]) == 0
    with np.load(tmp_path / "o.npz") as o:
        assert o["position"].dtype == np.float32
        assert _eq(o["position"], F.run(z.astype(np.float32)).position)
    assert main(["run", str(tmp_path / "a.npz"), "-o", str(tmp_path / "o.npz"), *AB, "--key", "ints", "-q"]) == 0
    with np.load(tmp_path / "o.npz") as o:
        assert _eq(o["velocity"], F.run(np.arange(40.0).reshape(2, 20)).velocity)


def test_abg_and_singer_filters(tmp_path, z) -> None:
    from abkit import abg, singer

    np.save(tmp_path / "z.npy", z)
    assert main(["run", str(tmp_path / "z.npy"), "-o", str(tmp_path / "o.npy"), "--filter", "abg",
                 "--tracking-index", "0.1", "-T", "0.5", "--chunk-rows", "100", "-q"]) == 0
    want = abg.from_tracking_index(0.1).filter(0.5).run(z).states
    assert _eq(np.load(tmp_path / "o.npy"), want)
    assert main(["run", str(tmp_path / "z.npy"), "-o", str(tmp_path / "o.npy"), "--filter", "singer", "-T", "0.5",
                 "--tau", "10", "--sigma-m", "2", "--sigma-pos", "5", "--chunk-rows", "100", "-q"]) == 0
    assert _eq(np.load(tmp_path / "o.npy"), singer.tracking_filter(0.5, 10.0, 2.0, 5.0).run(z).states)


def test_design_from_noise(tmp_path, z) -> None:
    np.save(tmp_path / "z.npy", z)
    assert main(["run", str(tmp_path / "z.npy"), "-o", str(tmp_path / "o.npy"), "--sigma-w", "1", "--sigma-v", "3",
                 "-T", "0.5", "-q"]) == 0
    f = abkit.AlphaBetaFilter.from_design(alphabeta.from_noise(1.0, 3.0, 0.5))
    assert _eq(np.load(tmp_path / "o.npy"), f.run(z).states)


# -- wide tables ---------------------------------------------------------------------------
def _wide_table(z):
    return pa.table({"x": z[0], "label": [f"r{i}" for i in range(z.shape[1])], "y": z[1], "k": np.arange(z.shape[1])})


@pytest.mark.parametrize("fmt", ["csv", "parquet"])
@pytest.mark.parametrize("chunk", ["1", "50", "1000000"])
def test_wide_round_trip(tmp_path, z, fmt, chunk) -> None:
    src, dst = tmp_path / f"w.{fmt}", tmp_path / f"o.{fmt}"
    tab = _wide_table(z)
    (pcsv.write_csv if fmt == "csv" else pq.write_table)(tab, src)
    assert main(["run", str(src), "-o", str(dst), *AB, "--columns", "x,y", "--chunk-rows", chunk, "-q"]) == 0
    out = pcsv.read_csv(dst) if fmt == "csv" else pq.read_table(dst)
    assert out.column_names == ["x", "label", "y", "k", "x_pos", "x_vel", "x_res", "y_pos", "y_vel", "y_res"]
    want = F.run(z[:2], return_residuals=True)
    for i, c in enumerate("xy"):
        assert _eq(out[f"{c}_pos"].to_numpy(), want.position[i])
        assert _eq(out[f"{c}_vel"].to_numpy(), want.velocity[i])
        assert _eq(out[f"{c}_res"].to_numpy(), want.residuals[i])
        assert _eq(out[c].to_numpy(), z[i])  # passed through (nulls written for NaN)
    assert out["label"].to_pylist() == tab["label"].to_pylist()


def test_wide_default_columns_are_the_numeric_ones(tmp_path, z) -> None:
    pq.write_table(_wide_table(z), tmp_path / "w.parquet")
    assert main(["run", str(tmp_path / "w.parquet"), "-o", str(tmp_path / "o.parquet"), *AB, "-q"]) == 0
    out = pq.read_table(tmp_path / "o.parquet")
    assert [c for c in out.column_names if c.endswith("_pos")] == ["x_pos", "y_pos", "k_pos"]
    assert _eq(out["k_vel"].to_numpy(), F.run(np.arange(z.shape[1], dtype=float)).velocity)


def test_empty_table(tmp_path) -> None:
    (tmp_path / "e.csv").write_text("x,y\n")
    assert main(["run", str(tmp_path / "e.csv"), "-o", str(tmp_path / "o.csv"), *AB, "--columns", "x,y", "-q"]) == 0
    assert (tmp_path / "o.csv").read_text().splitlines()[0].replace('"', "") == "x,y,x_pos,x_vel,x_res,y_pos,y_vel,y_res"


# -- progress ------------------------------------------------------------------------------
def test_progress_bar_draws_and_finishes() -> None:
    import io

    from abkit._cli_run import Progress

    s = io.StringIO()
    p = Progress(1000, "rows", True, stream=s)
    p.update(500, force=True)
    p.close()
    text = s.getvalue()
    assert "50.0%" in text and "100.0%" in text and text.endswith("\n")
    s2 = io.StringIO()
    q = Progress(1000, "rows", False, stream=s2)
    q.update(500, force=True)
    q.close()
    assert s2.getvalue() == ""


# -- usage errors (exit 2) ------------------------------------------------------------------
@pytest.mark.parametrize(
    "args, msg",
    [
        (["o.npy", "--alpha", "0.5", "--beta", "0.2", "-T", "1"], "required: -o"),
        (["-o", "o.npy", "--alpha", "0.5"], "design source"),
        (["-o", "o.npy", "--alpha", "0.5", "--beta", "0.2"], "-T"),
        (["-o", "o.npy", *AB, "--tau", "3"], "--tau does not apply to --filter alphabeta"),
        (["-o", "o.npy", "--filter", "singer", "-T", "1"], "--filter singer needs"),
        (["-o", "o.npy", "--filter", "abg", "--alpha", "0.5"], "--alpha, --beta and --gamma go together"),
        (["-o", "o.csv", *AB], "input's format"),
        (["-o", "o.npy", *AB, "--max-gap", "3"], "need timestamps"),
        (["-o", "o.npy", *AB, "--max-gap", "-3", "--time", "t"], "positive number"),
        (["-o", "o.npy", *AB, "--chunk-rows", "0"], "positive integer"),
        (["-o", "o.npy", *AB, "--id", "track"], "apply to tables"),
        (["-o", "o.npy", *AB, "--key", "z"], ".npz"),
        (["-o", "o.npy", *AB, "--filter", "kalman"], "invalid choice"),
        (["-o", "o.npy", *AB, "--bogus"], "unrecognized"),
        (["-o", "o.npy", "--alpha", "3", "--beta", "3", "-T", "1"], "unstable"),
    ],
)
def test_usage_errors_exit_2(tmp_path, z, args, msg) -> None:
    np.save(tmp_path / "z.npy", z)
    args = [a if a not in ("o.npy", "o.csv") else str(tmp_path / a) for a in args]
    out = cli(str(tmp_path / "z.npy"), *args)
    assert out.returncode == 2, (out.returncode, out.stderr)
    assert msg in out.stderr and "Traceback" not in out.stderr
    assert not (tmp_path / "o.npy").exists()


def test_unknown_extension_and_same_file(tmp_path) -> None:
    (tmp_path / "data.txt").write_text("1\n")
    out = cli(str(tmp_path / "data.txt"), "-o", str(tmp_path / "o.txt"), *AB)
    assert out.returncode == 2 and "--format" in out.stderr
    out = cli(str(tmp_path / "data.txt"), "-o", str(tmp_path / "data.txt"), *AB, "--format", "csv")
    assert out.returncode == 2 and "differ" in out.stderr


def test_main_usage_error_raises_system_exit_2(tmp_path) -> None:
    with pytest.raises(SystemExit) as e:
        main(["run", str(tmp_path / "z.npy"), "-o", str(tmp_path / "o.npy"), "--alpha", "0.5"])
    assert e.value.code == 2


# -- bad data (exit 1) ----------------------------------------------------------------------
def test_bad_csv_value_names_file_row_and_column(tmp_path) -> None:
    lines = ["t,x,y"] + [f"{i},{i}.5,{2 * i}" for i in range(3000)]
    lines[2001] = "2000,oops,4000"
    (tmp_path / "bad.csv").write_text("\n".join(lines) + "\n")
    for cols in (["--columns", "x,y"], []):
        out = cli(str(tmp_path / "bad.csv"), "-o", str(tmp_path / "o.csv"), *AB, "--time", "t", *cols, "--chunk-rows", "100")
        if not cols and out.returncode == 0:
            continue  # without --columns x may be inferred as text (not numeric) and skipped
        assert out.returncode == 1, out.stderr
        assert "bad.csv, row 2001 (line 2002), column 'x': not a number: 'oops'" in out.stderr
        assert "Traceback" not in out.stderr
        assert not (tmp_path / "o.csv").exists()


def test_bad_csv_value_while_reading_ahead_exits_cleanly(tmp_path) -> None:
    # Regression (CI, session 10): Arrow's CSV read-ahead thread read a Python
    # file object, and when a bad value ended the process while that thread was
    # still reading, it was killed taking the GIL during interpreter shutdown:
    # "terminate called without an active exception", exit -6 instead of 1.
    # Before the fix one run in five aborted on this 23 MB file (the error near
    # the start, blocks still being read behind it); 15 runs miss it with
    # probability 0.8**15 = 3.5 %.
    lines = ["t,x,y"] + [f"{i},{i}.5,{2 * i}" for i in range(1_000_000)]
    lines[2001] = "2000,oops,4000"
    (tmp_path / "big.csv").write_text("\n".join(lines) + "\n")
    for _ in range(15):
        out = cli(str(tmp_path / "big.csv"), "-o", str(tmp_path / "o.csv"), *AB, "--time", "t", "--columns", "x,y", "--chunk-rows", "100")
        assert out.returncode == 1, (out.returncode, out.stderr)
        assert "row 2001 (line 2002), column 'x': not a number: 'oops'" in out.stderr
        assert "terminate" not in out.stderr


@pytest.mark.parametrize(
    "setup, msg",
    [
        (lambda d: np.save(d / "in.npy", np.array(["a", "b"])), "must be numeric"),
        (lambda d: np.save(d / "in.npy", np.zeros((2, 3, 4))), "must have shape"),
        (lambda d: (d / "in.npy").write_bytes(b"not an npy file"), "not a readable .npy"),
        (lambda d: np.savez(d / "in.npz", a=np.zeros(3), b=np.zeros(3)), "none named 'z'"),
        (lambda d: (d / "in.npz").write_bytes(b"junk"), "not a readable .npz"),
        (lambda d: (d / "in.csv").write_text(""), "empty file"),
        (lambda d: (d / "in.csv").write_text("a,b\n1,2\n"), "no column 'x' (--columns); columns are a, b"),
        (lambda d: (d / "in.parquet").write_bytes(b"junk"), "not a readable Parquet"),
        (lambda d: pq.write_table(pa.table({"x": ["u", "v"]}), d / "in.parquet"), "column 'x': expected numbers"),
        (lambda d: pq.write_table(pa.table({"x": [1.0, 2.0], "x_pos": [0.0, 0.0]}), d / "in.parquet"), "'x_pos' already exists"),
        (lambda d: pq.write_table(pa.table({"s": ["u", "v"]}), d / "in.parquet"), "no numeric measurement columns"),
    ],
)
def test_bad_data_exit_1(tmp_path, setup, msg) -> None:
    setup(tmp_path)
    src = next(tmp_path.glob("in.*"))
    cols = ["--columns", "x"] if "--columns" in msg or "expected numbers" in msg or "already" in msg else []
    out = cli(str(src), "-o", str(tmp_path / ("out" + src.suffix)), *AB, *cols)
    assert out.returncode == 1, (out.returncode, out.stderr)
    assert msg in out.stderr, out.stderr
    assert str(src.name) in out.stderr and "Traceback" not in out.stderr


def test_missing_input_file(tmp_path) -> None:
    out = cli(str(tmp_path / "nope.npy"), "-o", str(tmp_path / "o.npy"), *AB)
    assert out.returncode == 1 and "no such file" in out.stderr


def test_missing_pyarrow_gives_install_advice(tmp_path) -> None:
    (tmp_path / "w.csv").write_text("x\n1\n2\n")
    code = (
        "import sys; sys.modules['pyarrow'] = None\n"
        "from abkit.cli import main\n"
        f"sys.exit(main(['run', {str(tmp_path / 'w.csv')!r}, '-o', {str(tmp_path / 'o.csv')!r}, '--alpha', '0.5', '--beta', '0.2', '-T', '1']))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 1, out.stderr
    assert "install abkit[frame]" in out.stderr and "Traceback" not in out.stderr


# -- long tables ---------------------------------------------------------------------------
def _long_df(seed=0, n_tracks=15, shuffle=False, dup=False):
    pd = pytest.importorskip("pandas")
    rng = np.random.default_rng(seed)
    parts = []
    for i in range(n_tracks):
        n = int(rng.integers(1, 90))
        t = np.round(np.cumsum(rng.uniform(0.5, 2.0, n)), 3)
        if dup and n > 4:
            t[3] = t[2]
        x = np.cumsum(rng.normal(size=n))
        x[rng.random(n) < 0.1] = np.nan
        parts.append(pd.DataFrame({"ship": f"v{i}", "t": t, "x": x, "y": rng.normal(size=n), "note": "a,b"}))
    df = pd.concat(parts, ignore_index=True)
    if shuffle:
        df = df.sample(frac=1.0, random_state=seed).reset_index(drop=True)
    return df


def _expected_long(df, f, cols=("x", "y"), **kw):
    from abkit import frame

    return frame.filter(df, id="ship", time="t", columns=list(cols), filter=f, **kw)


LONG = ["--id", "ship", "--time", "t", "--columns", "x,y", *AB]


def _read(path, fmt):
    import pandas as pd

    return pd.read_csv(path, keep_default_na=True) if fmt == "csv" else pd.read_parquet(path)


@pytest.mark.parametrize("fmt", ["csv", "parquet"])
@pytest.mark.parametrize("chunk", ["1", "7", "64", "1000000"])
def test_long_streaming_equals_whole_and_frame(tmp_path, fmt, chunk) -> None:
    df = _long_df(1)
    src, dst = tmp_path / f"l.{fmt}", tmp_path / f"o.{fmt}"
    df.to_csv(src, index=False) if fmt == "csv" else df.to_parquet(src)
    out = cli(str(src), "-o", str(dst), *LONG, "--chunk-rows", chunk)
    assert out.returncode == 0, out.stderr
    assert "warning" not in out.stderr
    got = _read(dst, fmt)
    want = _expected_long(df, abkit.AlphaBetaFilter(0.5, 0.2, 0.5))
    assert list(got.columns) == list(want.columns)
    assert got["note"].tolist() == df["note"].tolist()
    for c in want.columns:
        if c.endswith(("_pos", "_vel", "_res")):
            assert _eq(got[c], want[c]), c


@pytest.mark.parametrize("fmt", ["csv", "parquet"])
def test_long_not_grouped_is_loaded_whole_with_a_warning(tmp_path, fmt) -> None:
    df = _long_df(2, shuffle=True)
    src, dst = tmp_path / f"l.{fmt}", tmp_path / f"o.{fmt}"
    df.to_csv(src, index=False) if fmt == "csv" else df.to_parquet(src)
    out = cli(str(src), "-o", str(dst), *LONG, "--chunk-rows", "10")
    assert out.returncode == 0, out.stderr
    assert "not grouped by 'ship'" in out.stderr and "loading the whole file" in out.stderr
    got = _read(dst, fmt)
    want = _expected_long(df, abkit.AlphaBetaFilter(0.5, 0.2, 0.5))
    assert got["ship"].tolist() == df["ship"].tolist()  # rows in the file's order
    for c in ("x_pos", "x_vel", "y_res"):
        assert _eq(got[c], want[c]), c


@pytest.mark.parametrize("fmt", ["csv", "parquet"])
@pytest.mark.parametrize("chunk", ["1", "13", "1000000"])
def test_long_time_ordered_feed_streams(tmp_path, fmt, chunk) -> None:
    """Rows ordered by time, tracks interleaved (an AIS dump): streamed
    through per-id state tables, no warning, the same estimates as
    abkit.frame.filter on the whole frame; a time going back in the file
    falls back to loading it whole."""
    df = _long_df(7).sort_values("t", kind="stable").reset_index(drop=True)
    src, dst = tmp_path / f"l.{fmt}", tmp_path / f"o.{fmt}"
    df.to_csv(src, index=False) if fmt == "csv" else df.to_parquet(src)
    args = [*LONG, "--chunk-rows", chunk, "--max-gap", "1.5"]
    out = cli(str(src), "-o", str(dst), *args)
    assert out.returncode == 0, out.stderr
    assert "warning" not in out.stderr
    got = _read(dst, fmt)
    want = _expected_long(df, abkit.AlphaBetaFilter(0.5, 0.2, 0.5), max_gap=1.5)
    assert want.attrs["abkit"]["n_restarts"] > 0
    assert list(got.columns) == list(want.columns) and got["note"].tolist() == df["note"].tolist()
    for c in want.columns:
        if c.endswith(("_pos", "_vel", "_res")):
            assert _eq(got[c], want[c]), c
    # not ordered by time either: loaded whole with the warning
    df2 = df.copy()
    df2.loc[[3, 40]] = df2.loc[[40, 3]].to_numpy()
    df2.to_parquet(tmp_path / "l2.parquet")
    out = cli(str(tmp_path / "l2.parquet"), "-o", str(tmp_path / "o2.parquet"), *args)
    assert out.returncode == 0 and "loading the whole file" in out.stderr
    want2 = _expected_long(df2, abkit.AlphaBetaFilter(0.5, 0.2, 0.5), max_gap=1.5)
    assert _eq(_read(tmp_path / "o2.parquet", "parquet")["x_vel"], want2["x_vel"])


def test_long_feed_duplicates_raise_naming_file_row_and_column(tmp_path) -> None:
    df = _long_df(8).sort_values("t", kind="stable").reset_index(drop=True)
    r = int(np.flatnonzero((df["ship"] == "v1").to_numpy())[4])
    prev = int(np.flatnonzero((df["ship"] == "v1").to_numpy())[3])
    df.loc[r, "t"] = df.loc[prev, "t"]  # a repeated report, still in time order
    df = df.sort_values("t", kind="stable").reset_index(drop=True)
    df.to_csv(tmp_path / "l.csv", index=False)
    out = cli(str(tmp_path / "l.csv"), "-o", str(tmp_path / "o.csv"), *LONG, "--chunk-rows", "20")
    assert out.returncode == 1, out.stderr
    rows = np.flatnonzero((df["ship"] == "v1").to_numpy())
    assert f"l.csv, row {rows[4] + 1} (ship 'v1'), column 't': t=" in out.stderr, out.stderr
    assert "Traceback" not in out.stderr and not (tmp_path / "o.csv").exists()


def test_long_times_going_back_within_a_track_fall_back(tmp_path) -> None:
    df = _long_df(3)
    i = int(np.flatnonzero((df["ship"] == df["ship"].shift()).to_numpy())[5])
    df.loc[[i - 1, i]] = df.loc[[i, i - 1]].to_numpy()  # swap two reports of one track
    df.to_parquet(tmp_path / "l.parquet")
    out = cli(str(tmp_path / "l.parquet"), "-o", str(tmp_path / "o.parquet"), *LONG, "--chunk-rows", "16")
    assert out.returncode == 0 and "times of a track go back" in out.stderr
    got = _read(tmp_path / "o.parquet", "parquet")
    want = _expected_long(df, abkit.AlphaBetaFilter(0.5, 0.2, 0.5))
    assert _eq(got["x_vel"], want["x_vel"])


def test_long_duplicates_raise_naming_file_row_and_column(tmp_path) -> None:
    df = _long_df(4, dup=True)
    df.to_csv(tmp_path / "l.csv", index=False)
    out = cli(str(tmp_path / "l.csv"), "-o", str(tmp_path / "o.csv"), *LONG, "--chunk-rows", "50")
    assert out.returncode == 1, out.stderr
    first = next(g for _, g in df.groupby("ship", sort=False) if len(g) > 4)
    row = int(first.index[3]) + 1
    assert f"l.csv, row {row} (ship '{first['ship'].iloc[0]}'), column 't': " in out.stderr, out.stderr
    assert "Traceback" not in out.stderr and not (tmp_path / "o.csv").exists()


@pytest.mark.parametrize("chunk", ["5", "1000000"])
def test_long_drop_duplicates_and_max_gap_design_filter(tmp_path, chunk) -> None:
    df = _long_df(5, dup=True)
    df.to_parquet(tmp_path / "l.parquet")
    args = ["--id", "ship", "--time", "t", "--columns", "x", "--sigma-w", "0.5", "--sigma-v", "1", "-T", "1",
            "--on-duplicate", "drop", "--max-gap", "1.5", "--chunk-rows", chunk]
    assert main(["run", str(tmp_path / "l.parquet"), "-o", str(tmp_path / "o.parquet"), *args, "-q"]) == 0
    got = _read(tmp_path / "o.parquet", "parquet")
    f = abkit.AlphaBetaFilter.from_noise(0.5, 1.0, 1.0)
    want = _expected_long(df, f, cols=("x",), on_duplicate="drop", max_gap=1.5)
    assert want.attrs["abkit"]["n_dropped"] > 0 and want.attrs["abkit"]["n_restarts"] > 0
    for c in ("x_pos", "x_vel", "x_res"):
        assert _eq(got[c], want[c]), c


# -- ragged .npz ---------------------------------------------------------------------------
@pytest.mark.parametrize("chunk", ["1", "9", "1000000"])
def test_ragged_npz_streaming_equals_in_memory(tmp_path, chunk) -> None:
    rng = np.random.default_rng(6)
    lens = np.array([0, 5, 1, 0, 0, 40, 3, 17, 0])
    offsets = np.concatenate([[0], np.cumsum(lens)])
    z = np.cumsum(rng.normal(size=offsets[-1]))
    t = np.concatenate([np.cumsum(rng.uniform(0.5, 2, n)) for n in lens])
    t[8] = t[7]  # a duplicate in the 40-sample track
    np.savez(tmp_path / "r.npz", z=z, t=t, off=offsets)
    out = cli(str(tmp_path / "r.npz"), "-o", str(tmp_path / "o.npz"), *AB, "--time", "t", "--offsets", "off",
              "--on-duplicate", "drop", "--max-gap", "1.8", "--chunk-rows", chunk)
    assert out.returncode == 0, out.stderr
    want = F.run(z, t=t, offsets=offsets, on_duplicate="drop", max_gap=1.8, return_residuals=True)
    with np.load(tmp_path / "o.npz") as o:
        assert _eq(o["position"], want.position) and _eq(o["velocity"], want.velocity)
        assert _eq(o["residual"], want.residuals)
        assert o["n_dropped"].tolist() == want.n_dropped.tolist() and o["n_dropped"].sum() == 1
        assert o["n_restarts"].tolist() == want.n_restarts.tolist()
        assert o["offsets"].tolist() == offsets.tolist()


def test_ragged_npz_bad_offsets(tmp_path) -> None:
    np.savez(tmp_path / "r.npz", z=np.zeros(5), off=np.array([0, 3, 2, 5]))
    out = cli(str(tmp_path / "r.npz"), "-o", str(tmp_path / "o.npz"), *AB, "--offsets", "off")
    assert out.returncode == 1 and "offsets must be" in out.stderr


def test_npz_timestamps_rectangular(tmp_path, z) -> None:
    t = np.cumsum(np.random.default_rng(7).uniform(0.5, 2, z.shape), axis=1)
    np.savez(tmp_path / "a.npz", z=z, t=t)
    assert main(["run", str(tmp_path / "a.npz"), "-o", str(tmp_path / "o.npz"), *AB, "--time", "t", "--chunk-rows", "100", "-q"]) == 0
    want = F.run(z, t=t, return_residuals=True)
    with np.load(tmp_path / "o.npz") as o:
        assert _eq(o["velocity"], want.velocity) and _eq(o["residual"], want.residuals)
        assert o["n_dropped"].shape == (5,)


def test_progress_bar_on_a_terminal_and_quiet(tmp_path) -> None:
    import os
    import select

    df = _long_df(8)
    df.to_parquet(tmp_path / "l.parquet")
    master, slave = os.openpty()
    try:
        for quiet in (False, True):
            p = subprocess.Popen([sys.executable, "-m", "abkit", "run", str(tmp_path / "l.parquet"), "-o",
                                  str(tmp_path / "o.parquet"), *LONG, "--chunk-rows", "50"] + (["-q"] if quiet else []),
                                 stderr=slave, stdout=subprocess.PIPE)
            assert p.wait(timeout=120) == 0
            text = b""
            while select.select([master], [], [], 0.2)[0]:
                text += os.read(master, 65536)
            text = text.decode()
            if quiet:
                assert text == ""
            else:
                assert "100.0%" in text and "rows" in text
                assert f"{df['ship'].nunique()} tracks, {len(df)} rows, 0 dropped" in text
    finally:
        os.close(master)
        os.close(slave)
