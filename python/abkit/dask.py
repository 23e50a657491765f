"""Scale-out on Dask: filter dask arrays and Dask DataFrames on a cluster.

Needs the optional extra ``abkit[dask]`` (``dask[array,dataframe]`` and
``distributed``). Every worker needs abkit installed (the filtering runs
there, in Rust).

Functions
---------
run
    Filter a dask array of measurements chunked along tracks and along time:
    each block is filtered on a worker, the time blocks of a track chunk in
    order with the filter state carried from block to block, so the result
    equals ``filter.run(z.compute())`` bit for bit.
filter_frame
    :func:`abkit.frame.filter` on every partition of a Dask DataFrame
    partitioned by track id.

See ``docs/dask.md``.
"""

from __future__ import annotations

import operator
from functools import partial
from typing import Any, List, Optional, Sequence, Tuple

import numpy as np

from .filters import FilterResult, FilterState, FixedGainFilter

__all__ = ["run", "filter_frame", "DaskFilterResult"]

_ADVICE = "abkit.dask needs dask: install abkit[dask] (dask[array,dataframe] and distributed)"


def _import_dask() -> Any:
    try:
        import dask
        import dask.array  # noqa: F401
    except ImportError as exc:  # pragma: no cover - exercised without dask only
        raise ImportError(f"{_ADVICE} ({exc})") from None
    return dask


# -- FilterState pieces ----------------------------------------------------------------
def _slots(obj: Any) -> List[str]:
    names: List[str] = []
    for cls in type(obj).__mro__:
        for s in getattr(cls, "__slots__", ()):
            if s not in names and s != "__weakref__":
                names.append(s)
    return names


def _rows_per_track(state: FilterState) -> int:
    axes = getattr(state, "axes", None)  # a run with axes= keeps one row per track and axis
    return int(axes) if axes else 1


def _state_rows(state: FilterState, lo: int, hi: int) -> FilterState:
    """Tracks ``lo:hi`` of a state (per-track arrays sliced, the rest shared)."""
    k = _rows_per_track(state)
    rows = state._packed.shape[0]
    new = object.__new__(type(state))
    for s in _slots(state):
        v = getattr(state, s)
        if isinstance(v, np.ndarray) and v.ndim >= 1 and v.shape[0] == rows:
            v = v[lo * k:hi * k].copy()
        setattr(new, s, v)
    return new


def _concat_states(states: Sequence[FilterState]) -> FilterState:
    """The per-track-chunk states joined back into one (inverse of ``_state_rows``)."""
    if len(states) == 1:
        return states[0]
    first = states[0]
    rows = first._packed.shape[0]
    new = object.__new__(type(first))
    for s in _slots(first):
        vals = [getattr(st, s) for st in states]
        v0 = vals[0]
        if isinstance(v0, np.ndarray) and v0.ndim >= 1 and v0.shape[0] == rows:
            setattr(new, s, np.concatenate(vals, axis=0))
        else:
            setattr(new, s, v0)
    return new


def _init_rows(init: Any, lo: int, hi: int) -> Any:
    a = np.asarray(init, dtype=float)
    return a[lo:hi] if a.ndim == 2 else a


# -- run ------------------------------------------------------------------------------
def _step(filt: FixedGainFilter, zb: np.ndarray, tb: Optional[np.ndarray], prev: Any, *, init: Any,
          return_residuals: bool, kw: dict) -> Tuple[np.ndarray, Optional[np.ndarray], FilterState]:
    if isinstance(prev, tuple):  # the previous time block's (states, residuals, state)
        prev = prev[2]
    extra = dict(kw)
    if tb is not None:
        extra["t"] = tb
    r = filt.run(zb, init=init, state=prev, return_residuals=return_residuals, **extra)
    return r.states, r.residuals, r.state


def _final_state(results: Sequence[Tuple[Any, Any, FilterState]]) -> FilterState:
    return _concat_states([r[2] for r in results])


class DaskFilterResult:
    """Output of :func:`run`: lazy dask arrays and the lazy final state.

    Attributes
    ----------
    states : dask.array.Array, shape (n, *sample_shape[, axes])
        All estimates, as ``FilterResult.states``; chunked like ``z`` along
        the tracks and samples (one chunk along ``n``).
    residuals : dask.array.Array or None
        Shaped like ``z`` (only with ``return_residuals=True``).
    state : dask.delayed.Delayed
        The final :class:`abkit.FilterState` of every track (for
        ``run(..., state=...)`` on the next stretch of samples).

    Notes
    -----
    The estimates, residuals and state of a block come from one task;
    compute them together (:meth:`compute`, or ``dask.compute(r.states,
    r.state)``) so that every block is filtered once. Computing them
    separately filters twice.
    """

    __slots__ = ("states", "residuals", "state")

    def __init__(self, states: Any, residuals: Any, state: Any):
        self.states = states
        self.residuals = residuals
        self.state = state

    @property
    def position(self) -> Any:
        return self.states[0]

    @property
    def velocity(self) -> Any:
        if self.states.shape[0] < 2:
            raise AttributeError("this filter has no velocity state")
        return self.states[1]

    @property
    def acceleration(self) -> Any:
        if self.states.shape[0] < 3:
            raise AttributeError("this filter has no acceleration state")
        return self.states[2]

    def compute(self, **kwargs: Any) -> FilterResult:
        """Compute everything in one pass and return an in-memory
        :class:`abkit.FilterResult` (keyword arguments go to ``dask.compute``)."""
        dask = _import_dask()
        if self.residuals is None:
            states, state = dask.compute(self.states, self.state, **kwargs)
            residuals = None
        else:
            states, residuals, state = dask.compute(self.states, self.residuals, self.state, **kwargs)
        return FilterResult(np.ascontiguousarray(states), residuals, state)

    def __repr__(self) -> str:
        return f"DaskFilterResult(states={self.states!r}, residuals={'yes' if self.residuals is not None else 'no'})"


def run(
    filter: FixedGainFilter,
    z: Any,
    *,
    init: Any = "two-point",
    state: Optional[FilterState] = None,
    return_residuals: bool = False,
    t: Any = None,
    **kw: Any,
) -> DaskFilterResult:
    """Filter a dask array of measurements, block by block on the workers.

    Parameters
    ----------
    filter : FixedGainFilter
        Any abkit filter (it is pickled to the workers). A filter with
        per-track parameters needs ``z`` in one chunk along the tracks.
    z : dask.array.Array or array_like
        Measurements in any layout of :meth:`FixedGainFilter.run`
        (``(n_samples,)``, ``(n_tracks, n_samples)``, with a trailing
        ``axes`` and/or measurement axis). Chunks along tracks are filtered
        in parallel; chunks along samples (time) are filtered in order, the
        state carried from one to the next. Trailing axes are rechunked to
        one chunk.
    init : {"two-point", "first"} or array_like, optional
        As in :meth:`FixedGainFilter.run` (an array of shape
        ``(n_tracks, n)`` is split with the track chunks).
    state : FilterState, optional
        Continue from an earlier result's final state (all tracks).
    return_residuals : bool, optional
        Also return the residuals (a dask array shaped like ``z``).
    t : dask.array.Array or array_like, optional
        Timestamps, shaped like the sample axes of ``z`` (rechunked to
        ``z``'s chunks); see :meth:`FixedGainFilter.run`.
    **kw
        Further keywords of :meth:`FixedGainFilter.run` (``axes``,
        ``max_gap``, ``on_duplicate``, ``threads``), passed to every block.

    Returns
    -------
    DaskFilterResult
        Lazy ``states``, ``residuals`` and final ``state``; ``.compute()``
        gives a :class:`abkit.FilterResult`.

    Raises
    ------
    TypeError
        ``filter`` is not an abkit filter; ``z`` not float32/float64.
    ValueError
        Bad layout (checked on a one-sample probe before anything is
        scheduled), ``out=`` or ``offsets=`` given (not supported here: use
        :func:`filter_frame` for ragged tracks), ``t`` of the wrong shape.

    Examples
    --------
    >>> import numpy as np, dask.array as da
    >>> from abkit import AlphaBetaFilter
    >>> f = AlphaBetaFilter(0.5, 0.2, 1.0)
    >>> z = np.random.default_rng(0).normal(size=(6, 100))
    >>> r = run(f, da.from_array(z, chunks=(3, 40)))
    >>> res = r.compute()
    >>> bool(np.array_equal(res.states, f.run(z).states, equal_nan=True))
    True
    """
    _import_dask()
    import dask.array as da
    from dask.delayed import Delayed
    from dask.highlevelgraph import HighLevelGraph, MaterializedLayer
    from dask.base import tokenize

    if not isinstance(filter, FixedGainFilter):
        raise TypeError(f"filter must be an abkit filter (FixedGainFilter or a subclass), got {type(filter).__name__}")
    for bad in ("out", "offsets"):
        if bad in kw:
            raise ValueError(f"{bad}= is not supported by abkit.dask.run" + (
                "; for ragged tracks use abkit.dask.filter_frame" if bad == "offsets" else ""))
    z = z if isinstance(z, da.Array) else da.asarray(z)
    if z.dtype not in (np.dtype(np.float32), np.dtype(np.float64)):
        raise TypeError(f"z must be a float32 or float64 array, got dtype {z.dtype}")
    axes = kw.get("axes")
    n_tail = (1 if filter.m > 1 else 0) + (1 if axes is not None else 0)
    n_sample = z.ndim - n_tail
    if n_sample not in (1, 2):
        raise ValueError(f"z has shape {z.shape}: expected 1 or 2 sample axes (tracks, samples) before "
                         f"{n_tail} trailing axes for this filter and axes={axes!r}")
    if n_tail:
        z = z.rechunk({ax: -1 for ax in range(n_sample, z.ndim)})
    tail = tuple(z.shape[n_sample:])
    td = None
    if t is not None:
        t_in = t if isinstance(t, da.Array) else np.asarray(t)
        if t_in.dtype.kind not in "iuf":  # as FixedGainFilter.run: real timestamps (not bool)
            raise TypeError(f"t must be a real (float64) array of timestamps, got dtype {t_in.dtype}")
        td = t_in if isinstance(t_in, da.Array) else da.asarray(t_in)
        if td.shape != z.shape[:n_sample]:
            raise ValueError(f"t must have the shape of z's sample axes {z.shape[:n_sample]}, got {td.shape}")
        td = td.rechunk(z.chunks[:n_sample])
    n_tracks = z.shape[0] if n_sample == 2 else 1
    if state is not None:
        if not isinstance(state, FilterState):
            raise TypeError(f"state must be a FilterState (result.state), got {type(state).__name__}")
        have = state._packed.shape[0] // _rows_per_track(state)
        if have != n_tracks:
            raise ValueError(f"state is for {have} tracks; z has {n_tracks}")
    track_chunks = z.chunks[0] if n_sample == 2 else (1,)
    if filter.n_params > 1 and len(track_chunks) > 1:
        raise ValueError("a filter with per-track parameters needs z in one chunk along the tracks "
                         f"(z.rechunk({{0: -1}})); z has {len(track_chunks)} track chunks")
    # Check everything the filter checks (layout, keywords, init, state) on a
    # one-sample probe of the first track chunk, before anything is scheduled.
    if z.size:
        k0 = track_chunks[0]
        probe_shape = ((k0,) if n_sample == 2 else ()) + (1,) + tail
        probe_state = None if state is None else _state_rows(state, 0, k0) if n_sample == 2 else state
        probe_init = init if isinstance(init, str) else _init_rows(init, 0, k0)
        pt = None if td is None else np.zeros(probe_shape[:n_sample])
        _step(filter, np.zeros(probe_shape, dtype=z.dtype), pt, probe_state, init=probe_init,
              return_residuals=return_residuals, kw=kw)

    token = tokenize(filter, z, td, init, state, return_residuals, sorted(kw.items()), "abkit-dask-run")
    step_name = "abkit-step-" + token
    est_name, res_name, fin_name = "abkit-estimates-" + token, "abkit-residuals-" + token, "abkit-final-state-" + token
    time_chunks = z.chunks[n_sample - 1]
    nt, nj = len(track_chunks), len(time_chunks)
    bounds = np.concatenate([[0], np.cumsum(track_chunks)]).astype(int)
    zero_tail = (0,) * len(tail)
    filt_key = ("abkit-filter-" + token,)
    step_layer: dict = {filt_key[0]: filter}
    est_layer: dict = {}
    res_layer: dict = {}
    for i in range(nt):
        lo, hi = int(bounds[i]), int(bounds[i + 1])
        init_i = init if isinstance(init, str) else _init_rows(init, lo, hi)
        prev: Any = None
        if state is not None:
            prev = _state_rows(state, lo, hi) if n_sample == 2 else state
        fn = partial(_step, init=init_i, return_residuals=return_residuals, kw=dict(kw))
        for j in range(nj):
            bidx = (i, j) if n_sample == 2 else (j,)
            zkey = (z.name,) + bidx + zero_tail
            tkey = None if td is None else (td.name,) + bidx
            skey = (step_name, i, j)
            step_layer[skey] = (fn, filt_key[0], zkey, tkey, prev)
            prev = skey
            est_tail = zero_tail[: len(tail) - (1 if filter.m > 1 else 0)]
            est_layer[(est_name, 0) + bidx + est_tail] = (operator.getitem, skey, 0)
            if return_residuals:
                res_layer[(res_name,) + bidx + zero_tail] = (operator.getitem, skey, 1)
    fin_layer = {fin_name: (_final_state, [(step_name, i, nj - 1) for i in range(nt)])}

    base = HighLevelGraph.from_collections(step_name, step_layer, dependencies=[z] + ([td] if td is not None else []))
    layers = dict(base.layers)
    deps = {k: set(v) for k, v in base.dependencies.items()}
    for name, layer in ((est_name, est_layer), (res_name, res_layer), (fin_name, fin_layer)):
        if layer:
            layers[name] = MaterializedLayer(layer)
            deps[name] = {step_name}
    hlg = HighLevelGraph(layers, deps)

    est_tail_shape = tail[:-1] if filter.m > 1 else tail
    est_chunks = ((filter.n,),) + tuple(z.chunks[:n_sample]) + tuple((d,) for d in est_tail_shape)
    states = da.Array(hlg, est_name, chunks=est_chunks, dtype=z.dtype)
    residuals = None
    if return_residuals:
        residuals = da.Array(hlg, res_name, chunks=z.chunks, dtype=z.dtype)
    return DaskFilterResult(states, residuals, Delayed(fin_name, hlg))


# -- DataFrames -----------------------------------------------------------------------
def _frame_partition(pdf: Any, *, id: str, index_is_id: bool, kw: dict) -> Any:
    from . import frame

    if index_is_id:
        name = pdf.index.name
        out = frame.filter(pdf.reset_index(), id=id, **kw)
        return out.set_index(name)
    return frame.filter(pdf, id=id, **kw)


def _partition_ids(pdf: Any, id: str, index_is_id: bool) -> Any:
    s = pdf.index.to_series() if index_is_id else pdf[id]
    return s.drop_duplicates().to_numpy()


def _check_ids(parts: Sequence[Any], id: str) -> None:
    seen: dict = {}
    for i, ids in enumerate(parts):
        for v in ids.tolist():
            j = seen.setdefault(v, i)
            if j != i:
                raise ValueError(
                    f"track {id}={v!r} is in partitions {j} and {i}: filter_frame needs every track within one "
                    f"partition; repartition by id first, e.g. ddf = ddf.shuffle(on={id!r}) or "
                    f"ddf = ddf.set_index({id!r})"
                )


def filter_frame(ddf: Any, *, id: str, check: bool = True, **kw: Any) -> Any:
    """:func:`abkit.frame.filter` on every partition of a Dask DataFrame.

    Parameters
    ----------
    ddf : dask.dataframe.DataFrame
        Long format (one row per report), partitioned by track id: every
        track's rows within one partition (e.g. after ``ddf.shuffle(on=id)``
        or ``ddf.set_index(id)``; with ``set_index`` the id is the index).
    id : str
        The track id column (or the index name after ``set_index``).
    check : bool, optional
        Check that no track spans two partitions (default). The check is
        part of the graph (it reads the id column of every partition once)
        and raises ``ValueError`` when the result is computed. When the id is
        the index with known divisions, no check is needed and none is made.
    **kw
        ``columns``, ``filter``, ``time``, ``max_gap``, ``on_duplicate``,
        ``init``, ``return_residuals``, ``suffixes`` of
        :func:`abkit.frame.filter`.

    Returns
    -------
    dask.dataframe.DataFrame
        Lazy: the partitions with the estimate columns added (rows in each
        partition's order). The ``attrs`` totals of the pandas path are not
        carried (partitions are separate frames).

    Raises
    ------
    ValueError
        Unknown columns (checked on the metadata up front); at compute time,
        a track found in two partitions.

    Examples
    --------
    >>> import pandas as pd, dask.dataframe as dd
    >>> from abkit import AlphaBetaFilter
    >>> df = pd.DataFrame({"id": [1, 1, 2, 2, 1], "t": [0.0, 1.0, 0.0, 1.0, 2.0], "x": [0.0, 1.0, 5.0, 7.0, 2.0]})
    >>> ddf = dd.from_pandas(df, npartitions=2).shuffle(on="id")
    >>> out = filter_frame(ddf, id="id", time="t", columns="x", filter=AlphaBetaFilter(0.5, 0.2, 1.0))
    >>> got = out.compute().sort_values(["id", "t"])
    >>> got["x_vel"].round(6).tolist()
    [nan, 1.0, 1.0, nan, 2.0]
    """
    _import_dask()
    import dask.dataframe as dd
    from dask import delayed

    from . import frame

    if "filter" not in kw:
        raise TypeError("filter_frame() missing the keyword argument 'filter'")
    if "return_summary" in kw:
        raise ValueError("return_summary is not available with Dask (partitions are separate frames)")
    meta = ddf._meta
    index_is_id = id not in meta.columns and meta.index.name == id
    if not index_is_id and id not in meta.columns:
        raise ValueError(f"id: no column {id!r} in the DataFrame (columns: {', '.join(map(repr, meta.columns))})")
    # the metadata of the result: the filter run on the empty frame (checks columns and options)
    meta_out = _frame_partition(meta, id=id, index_is_id=index_is_id, kw=kw)
    need_check = check and not (index_is_id and ddf.known_divisions)
    args: List[Any] = []
    if need_check:
        ids = [delayed(_partition_ids)(p, id, index_is_id) for p in ddf.to_delayed()]
        args.append(delayed(_check_ids)(ids, id))

    def part(pdf: Any, *ok: Any) -> Any:
        return _frame_partition(pdf, id=id, index_is_id=index_is_id, kw=kw)

    del frame, dd
    return ddf.map_partitions(part, *args, meta=meta_out, align_dataframes=False)
