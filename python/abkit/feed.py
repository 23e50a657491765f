"""Real-time filtering of a report feed: many tracks, reports interleaved.

A radar, AIS receiver or ADS-B decoder delivers reports one batch at a time,
in time order, with the tracks interleaved and new tracks appearing at any
moment. :class:`FeedTracker` keeps one filter state per track id and runs
each batch of reports through the row kernel (``abkit-core`` module
``feed``): the reports are read and the estimates written in arrival order,
each report updating the state of its track. The estimates equal those of
running every track alone over all its reports (bit for bit), whatever the
batching.
"""

from __future__ import annotations

from typing import Any, Dict, List, Optional

import numpy as np

from . import _tracks
from .filters import _ACCEPTED, _FRESH, FixedGainFilter

__all__ = ["FeedTracker", "FeedResult"]


class FeedResult:
    """Estimates of one :meth:`FeedTracker.update`, one per report.

    Attributes
    ----------
    states : ndarray, shape (n, n_reports) or (n, n_reports, d)
        The filtered state after each report (component-major: position,
        velocity, ...), per spatial axis when ``d > 1``. NaN where a track
        has not started (two-point start) or the report was dropped.
    residuals : ndarray, shape (n_reports,) or (n_reports, d), or None
        ``z - H x_p`` (NaN at missed measurements, start-up and drops).
    tracks : ndarray of int64, shape (n_reports,)
        Index of each report's track in :attr:`FeedTracker.ids`.
    """

    __slots__ = ("states", "residuals", "tracks")

    def __init__(self, states: np.ndarray, residuals: Optional[np.ndarray], tracks: np.ndarray):
        self.states = states
        self.residuals = residuals
        self.tracks = tracks

    @property
    def position(self) -> np.ndarray:
        return self.states[0]

    @property
    def velocity(self) -> np.ndarray:
        return self.states[1]

    @property
    def acceleration(self) -> np.ndarray:
        if self.states.shape[0] < 3:
            raise AttributeError("this filter has no acceleration state")
        return self.states[2]


class FeedTracker:
    r"""Filter a live feed of reports from many tracks, batch by batch.

    Parameters
    ----------
    filt : FixedGainFilter
        A scalar-measurement filter (``AlphaBetaFilter``,
        ``AlphaBetaGammaFilter``, a Singer ``tracking_filter``, ...; not
        one with ``transient="kalman"``: a ``ValueError``). With
        timestamps, filters designed from noise use the steady-state gains
        of each step (see ``docs/tracks.md``).
    axes : int, optional
        Spatial axes per report ``d`` (default 1): ``z`` of shape
        ``(n_reports, d)``, each axis filtered with ``filt``.
    init : {"two-point", "first"}
        Start-up of a new track (and of a track restarted after a gap).
    max_gap : float, optional
        Restart a track after a silence longer than this (needs ``t``).
    on_duplicate : {"raise", "drop"}
        A report not after its track's previous one: ``ValueError``
        (naming the batch row and the track id), or dropped (NaN estimates,
        counted in :attr:`n_dropped`).
    return_residuals : bool
        Return the residuals (default True).

    Notes
    -----
    Every report goes through the same per-sample code as the ragged
    kernel (``run(z, t=t, offsets=...)``), so the estimates of a track are
    those of running it alone over all its reports, bit for bit, whatever
    the batches and the interleaving (``tests/test_feed_tracker.py``). The
    state table grows with the number of track ids seen (80 bytes per track
    and axis); :meth:`forget` drops tracks that ended.

    Examples
    --------
    >>> import numpy as np
    >>> from abkit import AlphaBetaFilter, FeedTracker
    >>> trk = FeedTracker(AlphaBetaFilter.from_noise(0.5, 2.0, 1.0))
    >>> r = trk.update(["a", "b", "a", "b"], [0.0, 0.5, 1.0, 1.5], [10.0, 50.0, 11.0, 48.0])
    >>> r.velocity[2:].round(3)
    array([ 1., -2.])
    >>> r = trk.update(["c", "a"], [2.0, 2.0], [0.0, 12.1])
    >>> trk.ids, trk.n_tracks
    (['a', 'b', 'c'], 3)
    """

    def __init__(self, filt: FixedGainFilter, *, axes: int = 1, init: str = "two-point", max_gap: Optional[float] = None,
                 on_duplicate: str = "raise", return_residuals: bool = True):
        if not isinstance(filt, FixedGainFilter):
            raise TypeError(f"filt must be an abkit filter, got {type(filt).__name__}")
        if filt.m != 1:
            raise ValueError(f"filt has {filt.m} measurements per sample; FeedTracker runs scalar-measurement filters (one per axis)")
        if not isinstance(axes, (int, np.integer)) or isinstance(axes, bool) or axes < 1:
            raise ValueError(f"axes must be a positive integer, got {axes!r}")
        if not isinstance(init, str) or init not in ("two-point", "first"):
            raise ValueError(f"init must be 'two-point' or 'first', got {init!r}")
        _tracks.check_steady_state(filt, "FeedTracker")
        _tracks.check_on_duplicate(on_duplicate)
        _tracks.check_max_gap(max_gap, True)
        filt._check_params(1)  # one parameter set: tracks come and go
        self.filter = filt
        self.axes = int(axes)
        self.init = init
        self.max_gap = max_gap
        self.on_duplicate = on_duplicate
        self.return_residuals = bool(return_residuals)
        self._code: Dict[Any, int] = {}
        self._ids: List[Any] = []
        self._tables = np.empty((0, _tracks._W))  # (axes, capacity, W) flattened per axis
        self._cap = 0
        self._counts = np.zeros((0, 2), dtype=np.int64)
        self._dtype: Optional[np.dtype] = None

    @property
    def ids(self) -> List[Any]:
        """Track ids seen so far, in order of first appearance."""
        return list(self._ids)

    @property
    def n_tracks(self) -> int:
        return len(self._ids)

    @property
    def n_dropped(self) -> np.ndarray:
        """Reports dropped as duplicates, per track (order of :attr:`ids`)."""
        return self._counts[: self.n_tracks, 0].copy()

    @property
    def n_restarts(self) -> np.ndarray:
        """Restarts after gaps (``max_gap``), per track."""
        return self._counts[: self.n_tracks, 1].copy()

    def estimate(self, id: Any) -> np.ndarray:
        """The current state estimate of track ``id``: shape ``(n,)``, or
        ``(d, n)`` with ``axes=d > 1``; NaN components before the track has
        started (its first valid measurements)."""
        if id not in self._code:
            raise KeyError(f"no track with id {id!r}")
        i = self._code[id]
        x = self._table_view()[:, i, : self.filter.n].copy()
        phase = self._table_view()[:, i, _tracks._NMAX]
        x[phase < 2] = np.nan
        if self.filter.n >= 2:
            x[phase == 1, 0] = self._table_view()[phase == 1, i, 0]
        return x[0] if self.axes == 1 else x

    def _table_view(self) -> np.ndarray:
        return self._tables.reshape(self.axes, self._cap, _tracks._W)

    def _codes(self, ids: Any, n: int) -> np.ndarray:
        """Codes of the batch's ids, registering new ids (first appearance)."""
        arr = np.asarray(ids)
        if arr.ndim != 1 or arr.shape[0] != n:
            raise ValueError(f"ids must be a 1-D sequence of one id per report ({n}), got shape {arr.shape}")
        if arr.dtype.kind == "f":
            bad = ~np.isfinite(arr)
            if bad.any():
                raise ValueError(f"ids: row {int(np.argmax(bad))} has the missing id {arr[bad][0]!r}")
        if arr.dtype == object and any(v is None for v in arr):
            raise ValueError(f"ids: row {[v is None for v in arr].index(True)} has no id (None)")
        uniq, first, inv = np.unique(arr, return_index=True, return_inverse=True)
        lut = np.empty(uniq.size, dtype=np.int64)
        for j in np.argsort(first, kind="stable"):  # new ids in order of appearance
            key = uniq[j].item() if isinstance(uniq[j], np.generic) else uniq[j]
            c = self._code.get(key)
            if c is None:
                c = self._code[key] = len(self._ids)
                self._ids.append(key)
            lut[j] = c
        return lut[inv.reshape(-1)]

    def _grow(self, n_tracks: int) -> None:
        if n_tracks <= self._cap:
            return
        cap = max(n_tracks, 2 * self._cap, 64)
        new = np.tile(_FRESH, (self.axes, cap, 1))  # fresh: no timestamps known
        if self._cap:
            new[:, : self._cap] = self._table_view()
        self._tables = np.ascontiguousarray(new.reshape(self.axes * cap, _tracks._W))
        counts = np.zeros((cap, 2), dtype=np.int64)
        counts[: self._counts.shape[0]] = self._counts
        self._counts = counts
        self._cap = cap

    def update(self, ids: Any, t: Any, z: Any) -> FeedResult:
        """Filter the next batch of reports.

        Parameters
        ----------
        ids : array_like, shape (n_reports,)
            Track id of each report (any hashable values numpy can sort:
            integers, strings).
        t : array_like of float, shape (n_reports,), or None
            Report times, non-decreasing within each track across batches
            (a report at its track's previous time is a duplicate, see
            ``on_duplicate``). None: each report one period ``T`` after its
            track's previous one.
        z : array_like, shape (n_reports,) or (n_reports, d)
            Measurements (float32 or float64, kept in that precision); NaN
            is a missed detection.

        Returns
        -------
        FeedResult

        Raises
        ------
        ValueError
            Shapes that do not match, an id, time or measurement that is
            missing or not finite, a time not after its track's previous one
            (``on_duplicate="raise"``), naming the batch row and the id.
            A failing batch changes nothing (the tracker is as before it).
        """
        zc = z if isinstance(z, np.ndarray) else np.asarray(z)
        if zc.dtype.kind in "iub":
            zc = zc.astype(np.float64)
        if zc.dtype not in _ACCEPTED:
            raise TypeError(f"z must be float32 or float64, got dtype {zc.dtype}")
        want = (1, 2) if self.axes == 1 else (2,)
        if zc.ndim not in want or (zc.ndim == 2 and zc.shape[1] != self.axes):
            raise ValueError(f"z must have shape (n_reports,){'' if self.axes > 1 else ' or (n_reports, 1)'}"
                             f"{f' or (n_reports, {self.axes})' if self.axes > 1 else ''}, got {zc.shape}")
        if getattr(self.filter, "float32_arithmetic", False) and zc.dtype == np.float32:
            self.filter._no_float32("FeedTracker")
        if self._dtype is not None and zc.dtype != self._dtype:
            raise TypeError(f"z has dtype {zc.dtype}; this tracker runs {self._dtype} (the first batch's)")
        n = zc.shape[0]
        n_known = self.n_tracks
        codes = self._codes(ids, n)
        try:
            tt = None if t is None else _tracks.check_t(t, (n,))
            if tt is not None and np.isnan(tt).any():
                r = int(np.flatnonzero(np.isnan(tt))[0])
                raise ValueError(f"t: row {r} (id {self._ids[int(codes[r])]!r}) is NaN")
            self._grow(self.n_tracks)
        except Exception:
            self._unregister(n_known)
            raise
        cols = [zc] if zc.ndim == 1 else [zc[:, j] for j in range(zc.shape[1])]
        touched = np.unique(codes)
        saved = self._table_view()[:, touched].copy()  # the batch is all or nothing
        try:
            out, res, counts, _ = _tracks.run_feed(
                self.filter, cols, tt, codes, self._cap, max_gap=self.max_gap, on_duplicate=self.on_duplicate,
                init=self.init, return_residuals=self.return_residuals, state=self._tables)
        except Exception as exc:
            self._table_view()[:, touched] = saved
            self._unregister(n_known)
            import re

            m = re.match(r"column (\d+): track (\d+), sample (\d+): ", str(exc))
            if m is None or not isinstance(exc, ValueError):
                raise
            i, k = int(m.group(2)), int(m.group(3))
            r = int(np.flatnonzero(codes == i)[k])
            axis = f", axis {m.group(1)}" if self.axes > 1 else ""
            raise ValueError(f"row {r} (id {ids_at(ids, r)!r}{axis}): {str(exc)[m.end():]}") from None
        self._dtype = zc.dtype
        self._counts[: counts.shape[0]] += counts
        # out: (d, n, n_reports) -> states (n, n_reports[, d])
        states = out[0] if self.axes == 1 else np.moveaxis(out, 0, -1)
        resid = None if res is None else (res[0] if self.axes == 1 else res.T)
        if zc.ndim == 2 and self.axes == 1:
            states = states[..., None]
            resid = None if resid is None else resid[:, None]
        return FeedResult(states, resid, codes)

    def _unregister(self, n_known: int) -> None:
        """Forget the ids registered by a failed batch."""
        for v in self._ids[n_known:]:
            del self._code[v]
        del self._ids[n_known:]

    def forget(self, ids: Any) -> None:
        """Drop the state of tracks that ended (their ids may come back as
        new tracks). The table keeps its capacity; codes are reused."""
        gone = [v.item() if isinstance(v, np.generic) else v for v in np.atleast_1d(np.asarray(ids, dtype=object))]
        missing = [v for v in gone if v not in self._code]
        if missing:
            raise KeyError(f"no track with id {missing[0]!r}")
        keep = [v for v in self._ids if v not in set(gone)]
        old = [self._code[v] for v in keep]
        view = self._table_view()
        tables = view[:, old].copy()
        counts = self._counts[old].copy()
        self._code = {v: c for c, v in enumerate(keep)}
        self._ids = keep
        view[:, : len(keep)] = tables
        view[:, len(keep):] = _FRESH
        self._counts[: len(keep)] = counts
        self._counts[len(keep):] = 0


def ids_at(ids: Any, r: int) -> Any:
    v = np.asarray(ids)[r]
    return v.item() if isinstance(v, np.generic) else v
