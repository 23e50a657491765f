"""Filter long-format DataFrames (pandas, polars): one row per report.

:func:`filter` groups the rows by track id and orders them by time (a stable
sort, skipped when the frame is already grouped and time-ordered), builds the
ragged ``offsets`` layout and runs the filter's ragged kernel with the
timestamps, then returns the frame with estimate columns, rows in the
original order. pandas needs ``abkit[frame]`` (or just pandas); polars is
optional. See ``docs/frame.md``.
"""

from __future__ import annotations

import re
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np

from . import _abkit
from .filters import FilterResult, FilterState, FixedGainFilter
from ._tracks import check_max_gap, check_on_duplicate, check_steady_state

__all__ = ["filter", "FrameSummary"]

_ADVICE = "install abkit[frame] (pandas, polars, pyarrow)"
_WHERE = re.compile(r"track (\d+), sample (\d+)")


class FrameSummary:
    """What :func:`filter` did, per track and in total.

    Attributes
    ----------
    ids : ndarray
        Track ids, in order of first appearance in the frame (polars
        without pyarrow: sorted).
    n_rows, n_dropped, n_restarts : ndarray of int64, shape (n_tracks,)
        Rows of each track, reports dropped as duplicates
        (``on_duplicate="drop"``), and restarts after gaps (``max_gap``).
    sorted : bool
        Whether the rows had to be reordered (``False``: already grouped by
        id and ordered by time, or a time-ordered feed run row by row;
        nothing was copied to sort).
    """

    __slots__ = ("ids", "n_rows", "n_dropped", "n_restarts", "sorted")

    def __init__(self, ids: np.ndarray, n_rows: np.ndarray, n_dropped: np.ndarray, n_restarts: np.ndarray, sorted: bool):
        self.ids = ids
        self.n_rows = n_rows
        self.n_dropped = n_dropped
        self.n_restarts = n_restarts
        self.sorted = sorted

    @property
    def n_tracks(self) -> int:
        return int(self.n_rows.size)

    def totals(self) -> Dict[str, int]:
        """``{"n_tracks", "n_rows", "n_dropped", "n_restarts"}`` summed over tracks."""
        return {"n_tracks": self.n_tracks, "n_rows": int(self.n_rows.sum()),
                "n_dropped": int(self.n_dropped.sum()), "n_restarts": int(self.n_restarts.sum())}

    def __repr__(self) -> str:
        t = self.totals()
        return (f"FrameSummary(n_tracks={t['n_tracks']}, n_rows={t['n_rows']}, n_dropped={t['n_dropped']}, "
                f"n_restarts={t['n_restarts']}, sorted={self.sorted})")


# -- the numpy core (shared with the CLI) ------------------------------------------------
class Grouping:
    """Rows grouped by track and ordered by time: ``order`` (None when the
    input already is) and the ragged ``offsets`` in that order."""

    __slots__ = ("order", "offsets", "n", "feed")

    def __init__(self, order: Optional[np.ndarray], offsets: np.ndarray, n: int, feed: Optional[np.ndarray] = None):
        self.order = order
        self.offsets = offsets
        self.n = n
        #: The track codes when the rows are run as a feed in row order
        #: (:func:`group` with ``feed=True``; ``order`` and ``offsets`` unused).
        self.feed = feed

    def take(self, a: np.ndarray) -> np.ndarray:
        return a if self.order is None else a[self.order]

    def put(self, a: np.ndarray) -> np.ndarray:
        """Values in run order back to the original row order (last axis)."""
        if self.order is None:
            return a
        out = np.empty_like(a)
        if a.ndim == 1:
            out[self.order] = a
        else:
            for k in range(a.shape[0]):  # one 1-D scatter per row is much faster than a 2-D one
                out[k][self.order] = a[k]
        return out

    def row(self, track: int, sample: int) -> int:
        if self.feed is not None:
            i = int(np.flatnonzero(self.feed == track)[sample])
            return i if self.order is None else int(self.order[i])
        i = int(self.offsets[track]) + sample
        return i if self.order is None else int(self.order[i])


def _stable_order(codes: np.ndarray, k: int) -> np.ndarray:
    """Stable argsort of integer codes in ``[0, k)``: LSD radix passes over
    16-bit digits (numpy's stable sort is a radix sort for 16-bit integers),
    linear in the number of rows."""
    if k <= 1:
        return np.arange(codes.size)
    order = np.argsort((codes & 0xFFFF).astype(np.uint16), kind="stable")
    shift = 16
    while (k - 1) >> shift:
        digit = ((codes[order] >> shift) & 0xFFFF).astype(np.uint16)
        order = order[np.argsort(digit, kind="stable")]
        shift += 16
    return order


def group(codes: np.ndarray, t: Optional[np.ndarray], feed: bool = False) -> Grouping:
    """Group rows by non-negative integer track ``codes`` (any injective
    coding of the ids) and order them by ``t`` within a track (stable: ties
    keep the row order). No permutation when the rows are already grouped
    and ordered; a linear-time radix sort when only the grouping is
    missing (e.g. a feed ordered by time, tracks interleaved). With
    ``feed=True`` rows that are not grouped but ordered by ``t`` are left
    as they are, for the row kernel (``Grouping.feed`` holds the codes)."""
    n = int(codes.size)
    if n == 0:
        return Grouping(None, np.zeros(1, dtype=np.int64), 0)
    codes = codes.astype(np.int64, copy=False)
    k = int(codes.max()) + 1
    change = codes[1:] != codes[:-1]
    n_runs = 1 + int(np.count_nonzero(change))
    n_ids = int(np.count_nonzero(np.bincount(codes, minlength=k))) if n_runs > 1 else 1
    ok = n_runs == n_ids
    if ok and t is not None and n > 1:
        ok = not bool(np.any((np.diff(t) < 0) & ~change))
    if ok:
        return Grouping(None, np.concatenate([[0], np.flatnonzero(change) + 1, [n]]).astype(np.int64), n)
    if feed and t is not None:
        if bool(np.all(t[1:] >= t[:-1])):
            # a time-ordered feed: each track's rows are in time order as
            # they stand (ties in row order, as the stable sort keeps them)
            return Grouping(None, np.zeros(k + 1, dtype=np.int64), n, feed=codes)
        # any other order: one stable sort by time makes it a feed (the
        # same order within each track as grouping would give)
        by_t = _abkit.time_order(np.ascontiguousarray(t, dtype=np.float64))  # = np.argsort(t, kind="stable")
        return Grouping(by_t, np.zeros(k + 1, dtype=np.int64), n, feed=codes[by_t])
    order = _stable_order(codes, k)
    cs = codes[order]
    same = cs[1:] == cs[:-1]
    if t is not None and np.any((np.diff(t[order]) < 0) & same):
        by_t = np.argsort(t, kind="stable")
        order = by_t[_stable_order(codes[by_t], k)]
        cs = codes[order]
        same = cs[1:] == cs[:-1]
    offsets = np.concatenate([[0], np.flatnonzero(~same) + 1, [n]]).astype(np.int64)
    return Grouping(order, offsets, n)


def run_grouped(filt: FixedGainFilter, g: Grouping, zs: Sequence[np.ndarray], t: Optional[np.ndarray], *,
                init: Any = "two-point", return_residuals: bool = True, kw: Optional[Dict[str, Any]] = None,
                first_state: Optional[Sequence[Optional[FilterState]]] = None,
                where: Any = None, names: Optional[Sequence[str]] = None) -> List[FilterResult]:
    """Run ``filt`` on each column of ``zs`` (original row order) in the
    grouping's ragged layout; results in run order. ``first_state[c]``: the
    state of the first track for column ``c`` (streaming), or None.
    ``where(track, sample) -> str`` restates a kernel error's place;
    ``names``: the columns of ``zs`` (an error then names its column)."""
    kw = dict(kw or {})
    ts = None if t is None else g.take(t)
    out: List[FilterResult] = []
    for c, z in enumerate(zs):
        zr = g.take(z)
        st0 = None if first_state is None else first_state[c]
        try:
            if st0 is None:
                out.append(_ragged(filt, zr, ts, g.offsets, init, return_residuals, kw, None))
            else:
                out.append(_two_part(filt, zr, ts, g.offsets, init, return_residuals, kw, st0))
        except ValueError as exc:
            m = _WHERE.search(str(exc))
            if m is None or where is None:
                raise
            msg = str(exc)
            col = "" if names is None else f"column {names[c]!r}, "
            raise ValueError(f"{col}{where(int(m.group(1)), int(m.group(2)))}: {msg[m.end():].lstrip(': ')}") from None
    return out


def _ragged(filt: FixedGainFilter, z: np.ndarray, t: Optional[np.ndarray], offsets: np.ndarray, init: Any,
            rr: bool, kw: Dict[str, Any], state: Optional[FilterState]) -> FilterResult:
    extra = dict(kw)
    if t is not None:
        extra["t"] = t
    return filt.run(z, offsets=offsets, init=init, state=state, return_residuals=rr, **extra)  # type: ignore[call-arg]


def _two_part(filt: FixedGainFilter, z: np.ndarray, t: Optional[np.ndarray], offsets: np.ndarray, init: Any,
              rr: bool, kw: Dict[str, Any], st0: FilterState) -> FilterResult:
    """First track continued from ``st0``, the others started fresh; joined."""
    from .dask import _concat_states

    k = int(offsets[1])
    a = _ragged(filt, z[:k], None if t is None else t[:k], np.array([0, k], dtype=np.int64), init, rr, kw, st0)
    if offsets.size == 2:
        return a
    b = _ragged(filt, z[k:], None if t is None else t[k:], offsets[1:] - k, init, rr, kw, None)
    res = None if not rr else np.concatenate([a.residuals, b.residuals])
    return FilterResult(np.concatenate([a.states, b.states], axis=-1), res, _concat_states([a.state, b.state]),  # type: ignore[call-arg]
                        offsets=offsets, n_dropped=np.concatenate([a.n_dropped, b.n_dropped]),
                        n_restarts=np.concatenate([a.n_restarts, b.n_restarts]), t=t)


def _run_feed(filt: FixedGainFilter, codes: np.ndarray, n_tracks: int, zs: Sequence[np.ndarray], t: Optional[np.ndarray],
              cols: Sequence[str], names: Sequence[Sequence[str]], new: Dict[str, np.ndarray], *, init: Any,
              return_residuals: bool, kw: Dict[str, Any], where: Any) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A time-ordered feed through the row kernel (no reordering; see
    :func:`abkit._tracks.run_feed`), one call per column dtype. Fills
    ``new`` with the estimate columns; returns the per-track dropped and
    restart counts and the first row of each track."""
    from ._tracks import run_feed

    n = filt.n
    counts = rows = None
    got: Dict[str, np.ndarray] = {}
    for dt in dict.fromkeys(z.dtype for z in zs):
        idx = [c for c, z in enumerate(zs) if z.dtype == dt]
        try:
            out, res, ct, rw = run_feed(filt, [zs[c] for c in idx], t, codes, n_tracks, init=init,
                                        return_residuals=return_residuals, **kw)
        except ValueError as exc:
            m = re.match(r"column (\d+): track (\d+), sample (\d+)", str(exc))
            if m is None:
                raise
            msg = str(exc)
            c = idx[int(m.group(1))]
            raise ValueError(f"column {cols[c]!r}, {where(int(m.group(2)), int(m.group(3)))}: {msg[m.end():].lstrip(': ')}") from None
        if counts is None or idx[0] == 0:
            counts, rows = ct, rw
        for j, c in enumerate(idx):
            for k in range(n):
                got[names[c][k]] = out[j, k]
            if res is not None:
                got[names[c][n]] = res[j]
    for row in names:  # the columns' order, whatever their dtypes
        for nm in row:
            new[nm] = got[nm]
    assert counts is not None and rows is not None
    return counts[:, 0], counts[:, 1], rows[:, 1]


# -- DataFrame front end -----------------------------------------------------------------
def _library(df: Any) -> str:
    mod = type(df).__module__
    if mod.startswith("pandas") and type(df).__name__ == "DataFrame":
        return "pandas"
    if mod.startswith("polars"):
        if type(df).__name__ == "LazyFrame":
            raise TypeError("df is a polars LazyFrame: call .collect() first")
        if type(df).__name__ == "DataFrame":
            return "polars"
    raise TypeError(f"df must be a pandas or polars DataFrame, got {type(df).__module__}.{type(df).__name__}")


def _check_columns(df: Any, lib: str, names: Sequence[Tuple[str, Any]]) -> None:
    have = list(df.columns)
    for what, c in names:
        if c is not None and c not in have:
            shown = ", ".join(map(repr, have[:20])) + (", ..." if len(have) > 20 else "")
            raise ValueError(f"{what}: no column {c!r} in the DataFrame (columns: {shown})")


def _codes(df: Any, lib: str, id: str) -> np.ndarray:
    if lib == "pandas":
        import pandas as pd

        col = df[id]
        if isinstance(col.dtype, np.dtype) and col.dtype.kind in "iu":
            codes = _arrow_codes(col.to_numpy())  # no missing values possible
            if codes is not None:
                return codes
        codes, _ = pd.factorize(col, sort=False, use_na_sentinel=True)
        if codes.size and codes.min() < 0:
            raise ValueError(f"id column {id!r}: missing id at row {int(np.argmin(codes))}")
        return codes
    s = df.get_column(id)
    if s.null_count():
        raise ValueError(f"id column {id!r}: missing id at row {int(s.is_null().arg_max())}")
    try:
        arr = s.rechunk().to_arrow()
    except Exception:  # pragma: no cover - no pyarrow
        arr = None
    codes = None if arr is None else _arrow_codes(arr)
    if codes is None:  # no pyarrow, or a type it cannot encode: a sort
        return s.rank("dense").to_numpy().astype(np.int64) - 1
    return codes


def _arrow_codes(values: Any) -> Optional[np.ndarray]:
    """Track codes in order of first appearance (as ``pandas.factorize``)
    by pyarrow's hash-based ``dictionary_encode`` (a few times faster than
    factorize on interleaved ids, no sort); None without pyarrow or for a
    type it cannot encode."""
    try:
        import pyarrow as pa
        import pyarrow.compute as pc

        arr = values if isinstance(values, (pa.Array, pa.ChunkedArray)) else pa.array(values)
        if isinstance(arr, pa.ChunkedArray):
            arr = arr.combine_chunks()
        enc = pc.dictionary_encode(arr)
        return np.asarray(enc.indices.to_numpy(zero_copy_only=False), dtype=np.int64)
    except Exception:
        return None


def _float_values(df: Any, lib: str, name: str) -> np.ndarray:
    """A measurement column as a float array, NaN for nulls (missed
    detections); float32/float64 without nulls are not copied."""
    if lib == "pandas":
        s = df[name]
        dt = s.dtype
        if isinstance(dt, np.dtype):
            if dt.kind == "f" and dt.itemsize in (4, 8):
                return s.to_numpy(copy=False)
            if dt.kind in "iu":
                return s.to_numpy(dtype=np.float64)
            raise TypeError(f"column {name!r}: expected numbers, got dtype {dt}")
        arrow = getattr(s, "array", None)
        pa_arr = getattr(arrow, "_pa_array", None)
        if pa_arr is not None:
            return _arrow_float(pa_arr, name)
        if getattr(dt, "kind", "") in "fiu":  # pandas nullable Float64/Int64
            return s.to_numpy(dtype=np.float64, na_value=np.nan)
        raise TypeError(f"column {name!r}: expected numbers, got dtype {dt}")
    import polars as pl

    s = df.get_column(name)
    if s.dtype in (pl.Float32, pl.Float64):
        return s.to_numpy()  # zero-copy for one chunk without nulls; nulls -> NaN
    if s.dtype.is_integer():
        return s.cast(pl.Float64).to_numpy()
    raise TypeError(f"column {name!r}: expected numbers, got dtype {s.dtype}")


def _arrow_float(arr: Any, name: str) -> np.ndarray:
    import pyarrow as pa

    typ = arr.type
    if pa.types.is_floating(typ) and typ.bit_width in (32, 64):
        if isinstance(arr, pa.ChunkedArray):
            arr = arr.chunk(0) if arr.num_chunks == 1 else arr.combine_chunks()
        if arr.null_count == 0:
            return arr.to_numpy(zero_copy_only=True)
        return arr.fill_null(float("nan")).to_numpy(zero_copy_only=False)
    if pa.types.is_integer(typ) or pa.types.is_decimal(typ) or pa.types.is_floating(typ):
        return arr.cast(pa.float64()).fill_null(float("nan")).to_numpy(zero_copy_only=False)
    raise TypeError(f"column {name!r}: expected numbers, got Arrow type {typ}")


def _seconds(df: Any, lib: str, name: str) -> np.ndarray:
    """The time column as float64 seconds (datetimes: since the epoch, UTC);
    missing or non-finite timestamps are an error naming the row."""
    if lib == "pandas":
        import pandas as pd

        s = df[name]
        if isinstance(s.dtype, pd.DatetimeTZDtype) or (isinstance(s.dtype, np.dtype) and s.dtype.kind == "M"):
            if s.isna().any():
                raise ValueError(f"time column {name!r}: missing timestamp at row {int(np.argmax(s.isna().to_numpy()))}")
            ns = s.to_numpy(dtype="datetime64[ns]") if s.dtype.kind == "M" else s.dt.tz_convert("UTC").dt.tz_localize(None).to_numpy(dtype="datetime64[ns]")
            t = ns.view(np.int64) / 1e9
        else:
            pa_arr = getattr(getattr(s, "array", None), "_pa_array", None)
            if pa_arr is not None and _is_arrow_time(pa_arr.type):
                import pyarrow as pa

                ints = pa_arr.cast(pa.timestamp("ns", tz=getattr(pa_arr.type, "tz", None))).cast(pa.int64())
                t = ints.to_numpy().astype(np.float64) / 1e9 if ints.null_count == 0 else ints.cast(pa.float64()).fill_null(float("nan")).to_numpy() / 1e9
            else:
                try:
                    t = np.asarray(_float_values(df, lib, name), dtype=np.float64)
                except TypeError:
                    raise TypeError(f"time column {name!r}: expected numbers (seconds) or datetimes, got dtype {s.dtype}") from None
    else:
        import polars as pl

        s = df.get_column(name)
        if s.dtype == pl.Date or isinstance(s.dtype, pl.Datetime):
            if s.null_count():
                raise ValueError(f"time column {name!r}: missing timestamp at row {int(s.is_null().arg_max())}")
            t = s.cast(pl.Datetime("ns")).dt.epoch("ns").to_numpy().astype(np.float64) / 1e9
        else:
            try:
                t = np.asarray(_float_values(df, lib, name), dtype=np.float64)
            except TypeError:
                raise TypeError(f"time column {name!r}: expected numbers (seconds) or datetimes, got dtype {s.dtype}") from None
    bad = ~np.isfinite(t)
    if bad.any():
        i = int(np.argmax(bad))
        raise ValueError(f"time column {name!r}: timestamp at row {i} is " + ("missing" if np.isnan(t[i]) else repr(float(t[i]))))
    return t


def _is_arrow_time(typ: Any) -> bool:
    import pyarrow as pa

    return bool(pa.types.is_timestamp(typ) or pa.types.is_date(typ))


def filter(
    df: Any,
    *,
    id: str,
    columns: Union[str, Sequence[str]],
    filter: FixedGainFilter,
    time: Optional[str] = None,
    max_gap: Optional[float] = None,
    on_duplicate: str = "raise",
    init: Any = "two-point",
    return_residuals: bool = True,
    suffixes: Optional[Sequence[str]] = None,
    return_summary: bool = False,
) -> Any:
    """Filter every track of a long-format DataFrame (one row per report).

    Parameters
    ----------
    df : pandas.DataFrame or polars.DataFrame
        One row per report; not modified.
    id : str
        Track id column (any type: integers, strings, categoricals).
    columns : str or sequence of str
        Measurement columns (e.g. ``["x", "y"]``), each filtered
        independently with the same filter (one spatial axis each). Nulls
        and NaN are missed detections. float32 columns give float32
        estimates; integers are converted to float64.
    filter : FixedGainFilter
        A filter with scalar measurements (``AlphaBetaFilter``,
        ``AlphaBetaGammaFilter``, a Singer filter, ...).
    time : str, optional
        Timestamp column: numbers (seconds) or datetimes (converted to
        seconds since the epoch, UTC). Without it, each track's rows are
        taken in frame order, spaced by the filter's ``T``.
    max_gap, on_duplicate, init
        As in :meth:`FixedGainFilter.run` (``max_gap`` and
        ``on_duplicate="drop"`` need ``time``).
    return_residuals : bool, optional
        Add the residual columns (default True).
    suffixes : sequence of str, optional
        Names of the state columns; default ``("pos", "vel")`` for two
        states, ``("pos", "vel", "acc")`` for three, ``x0, x1, ...`` beyond.
    return_summary : bool, optional
        Also return a :class:`FrameSummary`.

    Returns
    -------
    DataFrame (same library as ``df``) or (DataFrame, FrameSummary)
        ``df``'s columns, rows in the original order, plus for each
        measurement column ``c``: ``c_pos``, ``c_vel`` (``c_acc``) and
        ``c_res``. For pandas, ``result.attrs["abkit"]`` holds the totals
        ``{"n_tracks", "n_rows", "n_dropped", "n_restarts"}``.

    Raises
    ------
    TypeError
        ``df`` not a pandas/polars DataFrame (a polars LazyFrame: collect it
        first); a measurement or time column that is not numeric.
    ValueError
        A column name not in ``df`` (naming it); a missing id or timestamp
        (naming the row); a non-increasing timestamp with
        ``on_duplicate="raise"`` (naming the track id and row); an estimate
        column name that already exists; a filter with vector measurements
        or with ``transient="kalman"``.
    ImportError
        polars/pandas/pyarrow features used without the package
        (``abkit[frame]``).

    Notes
    -----
    Rows are grouped by id and ordered by time with one stable sort (ties
    keep their row order: with ``on_duplicate="drop"`` the first row at a
    timestamp is kept). A frame already grouped by id (in any id order) and
    ordered by time within each track is not reordered; nor is a
    time-ordered feed (rows ordered by time, tracks interleaved), which runs
    row by row with one filter state per track (the same results, bit for
    bit). float64 columns without nulls (numpy, Arrow or polars backed) are
    handed to the kernel without a copy. Rows dropped as duplicates have NaN
    estimates.

    Examples
    --------
    >>> import pandas as pd
    >>> from abkit import AlphaBetaFilter, frame
    >>> df = pd.DataFrame({"ship": [7, 3, 7, 3, 7], "t": [0.0, 0.0, 1.0, 2.0, 2.5],
    ...                    "x": [0.0, 10.0, 1.0, 12.0, 1.5]})
    >>> out = frame.filter(df, id="ship", time="t", columns="x", filter=AlphaBetaFilter(0.5, 0.2, 1.0))
    >>> out[["ship", "x_pos", "x_vel"]].round(3).values.tolist()
    [[7.0, 0.0, nan], [3.0, 10.0, nan], [7.0, 1.0, 1.0], [3.0, 12.0, 1.0], [7.0, 2.0, 0.867]]
    >>> out.attrs["abkit"]
    {'n_tracks': 2, 'n_rows': 5, 'n_dropped': 0, 'n_restarts': 0}
    """
    lib = _library(df)
    if lib == "polars":
        try:
            import polars as pl  # noqa: F401
        except ImportError:  # pragma: no cover
            raise ImportError(f"abkit.frame with polars needs polars: {_ADVICE}") from None
    if not isinstance(filter, FixedGainFilter):
        raise TypeError(f"filter must be an abkit filter, got {type(filter).__name__}")
    if filter.m != 1:
        raise ValueError(f"filter has {filter.m} measurements per sample; abkit.frame.filter runs scalar-measurement filters (one per column)")
    check_steady_state(filter, "abkit.frame.filter")
    for what, c in (("id", id), ("time", time)):
        if not isinstance(c, str) and not (what == "time" and c is None):
            raise TypeError(f"{what} must be a column name (str){'' if what == 'id' else ' or None'}, got {type(c).__name__}")
    if isinstance(columns, str):
        cols = [columns]
    elif hasattr(columns, "__iter__") and not isinstance(columns, (dict, set, bytes)) and all(isinstance(c, str) for c in list(columns)):
        cols = list(columns)
    else:
        raise TypeError(f"columns must be a column name or a list of column names (str), got {columns!r}")
    if not cols:
        raise ValueError("columns must name at least one measurement column")
    if len(set(cols)) != len(cols):
        raise ValueError(f"columns has repeated names: {cols}")
    _check_columns(df, lib, [("id", id), ("time", time)] + [("columns", c) for c in cols])
    if id in cols or (time is not None and (time in cols or time == id)):
        raise ValueError("id, time and the measurement columns must be different columns")
    if (max_gap is not None or on_duplicate != "raise") and time is None:
        raise ValueError("max_gap and on_duplicate='drop' need timestamps (time=)")
    check_on_duplicate(on_duplicate)  # up front: also for an empty frame (dask's metadata)
    check_max_gap(max_gap, True)
    n = filter.n
    sfx = list(suffixes) if suffixes is not None else (["pos", "vel", "acc"][:n] if n <= 3 else [f"x{i}" for i in range(n)])
    if len(sfx) != n:
        raise ValueError(f"suffixes must have {n} names (one per state), got {len(sfx)}")
    names = [[f"{c}_{s}" for s in sfx] + ([f"{c}_res"] if return_residuals else []) for c in cols]
    for row in names:
        for nm in row:
            if nm in df.columns:
                raise ValueError(f"estimate column {nm!r} already exists in the DataFrame; rename it or pass suffixes=")

    codes = _codes(df, lib, id)
    t = None if time is None else _seconds(df, lib, time)
    zs = [_float_values(df, lib, c) for c in cols]
    g = group(codes, t, feed=True)
    kw: Dict[str, Any] = {}
    if max_gap is not None:
        kw["max_gap"] = max_gap
    if on_duplicate != "raise":
        kw["on_duplicate"] = on_duplicate

    id_values = df[id] if lib == "pandas" else df.get_column(id)

    def where(track: int, sample: int) -> str:
        r = g.row(track, sample)
        v = id_values.iloc[r] if lib == "pandas" else id_values[r]
        v = v.item() if isinstance(v, np.generic) else v
        return f"track {id}={v!r}, row {r}"

    new: Dict[str, np.ndarray] = {}
    n_tracks = g.offsets.size - 1
    dropped = np.zeros(n_tracks, dtype=np.int64)
    restarts = np.zeros(n_tracks, dtype=np.int64)
    if g.n and g.feed is not None:
        dropped, restarts, first = _run_feed(filter, g.feed, n_tracks, [g.take(z) for z in zs], None if t is None else g.take(t),
                                             cols, names, new, init=init, return_residuals=return_residuals, kw=kw, where=where)
        if g.order is not None:  # sorted by time for the run: back to the frame's order
            first = g.order[first]
            for nm in list(new):
                new[nm] = g.put(new[nm])
    elif g.n:
        results = run_grouped(filter, g, zs, t, init=init, return_residuals=return_residuals, kw=kw, where=where, names=cols)
        dropped, restarts = results[0].n_dropped, results[0].n_restarts
        for row, r in zip(names, results):
            states = g.put(r.states)
            for k in range(n):
                new[row[k]] = states[k]
            if r.residuals is not None:
                new[row[n]] = g.put(r.residuals)
    else:
        for row, z in zip(names, zs):
            for nm in row:
                new[nm] = np.empty(0, dtype=z.dtype)
    if g.feed is None:
        first = g.offsets[:-1] if g.order is None else g.order[g.offsets[:-1]]
        n_rows = np.diff(g.offsets)
    else:
        n_rows = np.bincount(g.feed, minlength=n_tracks)
    ids = np.asarray(id_values.iloc[first] if lib == "pandas" else id_values.gather(first).to_numpy())
    summary = FrameSummary(ids, n_rows, np.asarray(dropped, dtype=np.int64),
                           np.asarray(restarts, dtype=np.int64), g.order is not None)
    if lib == "pandas":
        import pandas as pd

        # the estimate arrays are ours: hand them to pandas without a copy
        est = pd.DataFrame(new, index=df.index, copy=False)
        # (pandas >= 3 copies lazily and deprecates concat's copy=; older pandas needs copy=False)
        ckw = {} if int(pd.__version__.split(".")[0]) >= 3 else {"copy": False}
        out = pd.concat([df, est], axis=1, **ckw) if len(df.columns) else est
        out.attrs = dict(df.attrs)
        out.attrs["abkit"] = summary.totals()
    else:
        import polars as pl

        out = df.with_columns([pl.Series(k, v) for k, v in new.items()])
    return (out, summary) if return_summary else out
