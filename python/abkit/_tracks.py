"""Real-world tracks: timestamps, gaps, duplicates, ragged batches and
spatial axes for every filter's ``run`` (the machinery behind the keywords
``t``, ``offsets``, ``axes``, ``max_gap`` and ``on_duplicate``; see
``docs/tracks.md``).

The filtering itself is the Rust track kernel (``abkit-core`` modules
``ragged`` and ``irregular``); this module validates the arguments, views
the measurements and timestamps without copying them and assembles the
result.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Optional, Tuple

import numpy as np

from . import _abkit

if TYPE_CHECKING:  # pragma: no cover
    from .filters import FilterResult, FilterState, FixedGainFilter

_W = int(_abkit.STATE_WIDTH)
_NMAX = int(_abkit.MAX_STATES)
#: Column of the last timestamp in a packed state row.
T_LAST = _NMAX + 2
#: Column of the held timestamp (two-point start) in a packed state row.
T_HELD = _NMAX + 3
ON_DUPLICATE = ("raise", "drop")


def check_offsets(offsets: Any, n_total: int) -> np.ndarray:
    """Validate Arrow-style offsets; returns them as contiguous int64."""
    a = np.asarray(offsets)
    if a.dtype.kind not in "iu" or a.dtype == np.bool_:
        raise TypeError(f"offsets must be an integer array, got dtype {a.dtype}")
    if a.ndim != 1 or a.size < 1:
        raise ValueError(f"offsets must be a 1-D array of n_tracks + 1 integers, got shape {a.shape}")
    if a.dtype.kind == "u" and a.size and int(a.max()) > np.iinfo(np.int64).max:
        raise ValueError("offsets do not fit in int64")
    a = np.ascontiguousarray(a, dtype=np.int64)
    if a[0] != 0:
        raise ValueError(f"offsets must start at 0, got offsets[0] = {int(a[0])}")
    d = np.diff(a)
    if d.size and (d < 0).any():
        i = int(np.argmax(d < 0)) + 1
        raise ValueError(f"offsets must be non-decreasing: offsets[{i}] = {int(a[i])} < offsets[{i - 1}] = {int(a[i - 1])}")
    if a[-1] != n_total:
        raise ValueError(f"offsets must end at the number of samples of z ({n_total}), got offsets[-1] = {int(a[-1])}")
    return a


def check_t(t: Any, shape: Tuple[int, ...]) -> np.ndarray:
    """Timestamps as float64 of the sample shape (float32/integers are
    converted, float64 is used as is; a shared ``(n_samples,)`` vector is
    broadcast to all tracks without a copy)."""
    a = t if isinstance(t, np.ndarray) else np.asarray(t)
    if a.dtype.kind not in "iuf" or a.dtype == np.bool_:
        raise TypeError(f"t must be a real (float64) array of timestamps, got dtype {a.dtype}")
    if a.dtype != np.float64:
        a = a.astype(np.float64)
    if a.shape != shape:
        if len(shape) == 2 and a.shape == shape[1:]:
            a = np.broadcast_to(a, shape)
        else:
            raise ValueError(f"t must have the sample shape of z {shape}, got {a.shape}")
    return a


def check_max_gap(max_gap: Any, has_t: bool) -> Optional[float]:
    if max_gap is None:
        return None
    if not has_t:
        raise ValueError("max_gap needs timestamps t")
    if isinstance(max_gap, (bool, np.bool_)) or not isinstance(max_gap, (int, float, np.integer, np.floating)):
        raise TypeError(f"max_gap must be a number, got {type(max_gap).__name__}")
    g = float(max_gap)
    if not g > 0:
        raise ValueError(f"max_gap must be > 0, got {max_gap!r}")
    return g


def check_steady_state(f: "FixedGainFilter", who: str) -> None:
    """``ValueError`` for a filter with ``transient="kalman"`` in a path that
    runs only the steady-state filter (``who`` names the path)."""
    if f._transient is not None:
        raise ValueError(f"{who} runs the steady-state filter: a filter with transient='kalman' is not "
                         "supported (its exact Kalman start runs in filter.run(z) on whole tracks)")


def check_on_duplicate(on_duplicate: Any) -> bool:
    if on_duplicate not in ON_DUPLICATE:
        raise ValueError(f"on_duplicate must be 'raise' or 'drop', got {on_duplicate!r}")
    return on_duplicate == "drop"


def _z_dtype(z: Any) -> np.ndarray:
    from .filters import _ACCEPTED

    if not isinstance(z, np.ndarray):
        z = np.asarray(z)
        if z.dtype.kind in "iub":
            raise TypeError(f"z must be a float32 or float64 array, got {z.dtype}; convert it with np.asarray(z, float)")
    if z.dtype not in _ACCEPTED:
        raise TypeError(f"z must be a float32 or float64 array (native byte order), got dtype {z.dtype}")
    return z


def _aligned(a: np.ndarray) -> np.ndarray:
    if not a.flags.aligned or any(s % a.itemsize for s in a.strides):
        return np.ascontiguousarray(a)  # unaligned memory: the one case that copies
    return a


def check_no_inf(z3: np.ndarray, off: np.ndarray) -> None:
    """ValueError naming the track and sample of the first +-Inf of ``z3``
    (``(n_tracks, n_samples, m)`` with track starts ``off`` in the flat sample
    order, or ``(1, N, m)`` of a ragged batch); NaN is a missed detection.
    Scanned in blocks: no temporary of the size of ``z``."""
    n0, n1 = z3.shape[0], z3.shape[1]
    block = 1 << 16
    if z3.flags.c_contiguous:
        # Flat blocks (a trailing axis of length 1 makes np.isinf slow).
        flat = z3.reshape(-1)
        for g0 in range(0, flat.size, block):
            if np.isinf(flat[g0 : g0 + block]).any():
                break
        else:
            return
    per = max(1, block // max(n1, 1))
    for i0 in range(0, n0, per):
        for j0 in range(0, n1, block):
            blk = z3[i0 : i0 + per, j0 : j0 + block]
            bad = np.isinf(blk)
            if bad.any():
                a, b = (int(x) for x in np.argwhere(bad)[0][:2])
                r = (i0 + a) * n1 + j0 + b
                track = int(np.searchsorted(off, r, side="right")) - 1
                val = float(blk[a, b][np.isinf(blk[a, b])][0])
                raise ValueError(f"track {track}, sample {r - int(off[track])}: z must be finite or NaN (a missed detection), got {val!r}")


def check_no_inf_after(f: "FixedGainFilter", z3: np.ndarray, off: np.ndarray, packed: np.ndarray) -> None:
    """After a run without timestamps (no restarts): the ``check_no_inf``
    error, found from the final states. A ``+-Inf`` measurement leaves its
    track's state non-finite to the end of the track (it enters every
    later estimate: NaN measurements are missed detections and never do),
    so only tracks whose final state is not finite are scanned; O(n_tracks)
    otherwise. Also the overflow error of the row kernels
    (``check_tracks_finite``) unless ``f.allow_unstable``."""
    ph = packed[:, _NMAX]
    # s: position (phase 1) or the sum of the state (running); column by
    # column (a sum over the short trailing axis is slower).
    with np.errstate(over="ignore", invalid="ignore"):
        s = packed[:, 0].copy()
        run = ph != 1
        for c in range(1, f.n):
            s += np.where(run, packed[:, c], 0.0)
    sus = (ph > 0) & ~np.isfinite(s)
    if not sus.any():
        return
    x = np.where((ph == 1)[:, None], packed[:, :1], packed[:, : f.n])
    bad = np.flatnonzero(sus & ~np.all(np.isfinite(x), axis=1))
    flat = z3.shape[0] != len(off) - 1  # a ragged (1, N, m) batch
    for i in bad:
        seg = z3[0, int(off[i]) : int(off[i + 1])] if flat else z3[i]
        inf = np.argwhere(np.isinf(seg))
        if inf.size:
            k = int(inf[0][0])
            val = float(seg[tuple(inf[0])])
            raise ValueError(f"track {int(i)}, sample {k}: z must be finite or NaN (a missed detection), got {val!r}")
    if bad.size and not f.allow_unstable:
        j = int(bad[0])
        seg = z3[0, int(off[j]) : int(off[j + 1])] if flat else z3[j]
        big = float(np.nanmax(np.abs(seg))) if seg.size else float("nan")
        raise ValueError(
            f"the estimates of track {j} overflowed float64: z values up to {big:.3g} are too large "
            "for this filter; rescale z"
        )


def _kernel_law(f: "FixedGainFilter", timed: bool, what: str) -> Tuple[str, np.ndarray, np.ndarray]:
    """The track kernel's gain law and parameter rows for ``f`` (with
    timestamps: the filter's law of ``dt``; without: its own gains at
    ``T``, by the alpha-beta fast path where it applies) and the period
    ``T`` (one for all tracks: ``what`` starts the error otherwise)."""
    if timed:
        law, params = f._time_law()
    elif f._tv_law is not None and f._tv_law[0] in ("ab-fixed", "ab-design"):
        law, params = "ab-fixed", f._params[:, :2]  # type: ignore[attr-defined]
    else:
        law = "constant"
        params = np.concatenate([f._phi.reshape(f.n_params, -1), f._k.reshape(f.n_params, -1)], axis=1)
    tn = f._t
    if not np.all(tn == tn[0]):
        raise ValueError(f"{what} one sampling period T for all tracks (the filter has per-track T)")
    return law, params, tn


def run_tracks(
    f: "FixedGainFilter",
    z: Any,
    *,
    t: Any,
    offsets: Any,
    max_gap: Any,
    on_duplicate: Any,
    init: Any,
    state: Optional["FilterState"],
    out: Optional[np.ndarray],
    return_residuals: bool,
    threads: Optional[int],
    smoother: Optional[str] = None,
    smoother_params: Optional[np.ndarray] = None,
    lag: Optional[int] = None,
) -> "FilterResult":
    """One spatial axis (or none) through the track kernel."""
    from .filters import FilterResult, FilterState, planes_view

    if threads is not None and (not isinstance(threads, (int, np.integer)) or isinstance(threads, bool) or threads < 1):
        raise ValueError(f"threads must be a positive integer or None, got {threads!r}")
    drop = check_on_duplicate(on_duplicate)
    gap = check_max_gap(max_gap, t is not None)
    z = _z_dtype(z)
    m = f.m
    if offsets is not None:
        want = 1 if m == 1 else 2
        if z.ndim != want or (m > 1 and z.shape[-1] != m):
            raise ValueError(f"with offsets, z must have shape (N,){'' if m == 1 else f' or (N, {m})'} for this filter, got {z.shape}")
        n_total = z.shape[0]
        off = check_offsets(offsets, n_total)
        n_tracks = off.size - 1
        z3 = z[None, :, None] if m == 1 else z[None]
        sample_shape: Tuple[int, ...] = (n_total,)
        single = False
    else:
        from .filters import prepare_z

        z3, (n_tracks, n_samples), single = prepare_z(z, m)
        n_total = n_tracks * n_samples
        off = np.arange(n_tracks + 1, dtype=np.int64) * n_samples
        sample_shape = (n_samples,) if single else (n_tracks, n_samples)
    z3 = _aligned(z3)
    if gap is not None:
        # A track may restart (max_gap) and forget an Inf: scan z first.
        # Otherwise an Inf stays in its track's state to the end and is
        # found from the final states after the run (no pass over z).
        check_no_inf(z3, off)
    f._check_params(n_tracks)
    t_arr = None
    t2 = None
    if t is not None:
        t_arr = check_t(t, sample_shape)
        t2 = t_arr.reshape(z3.shape[:2]) if t_arr.ndim == 1 else t_arr
        t2 = _aligned(t2)
    law, params, tn = _kernel_law(f, t is not None, "t and offsets need")
    # Fresh states (state=None) have no timestamps (NaN T_LAST, T_HELD).
    packed, init_mode = f._initial_state(init, state, n_tracks)
    zarr = z
    shape = sample_shape
    o = f._out(out, zarr, z3, shape, threads, flat=True)
    out2 = planes_view(o, (f.n, n_total))
    res2 = np.empty((n_total, m), dtype=z3.dtype) if return_residuals else None
    counts = np.zeros((n_tracks, 2), dtype=np.int64)
    from .filters import AlphaBetaFilter

    if isinstance(f, AlphaBetaFilter) and f.float32_arithmetic and z3.dtype == np.float32:
        # AlphaBetaFilter(float32_arithmetic=True): without timestamps,
        # restarts, drops or smoothing (the callers raise for those).
        if t is not None or gap is not None or drop or smoother is not None:
            f._no_float32("t, max_gap, on_duplicate or smoothing")
        suspect = _abkit.filter_tracks_f32(
            z3, off, f._params, init_mode, packed, out2, res2, None if threads is None else int(threads)
        )
    else:
        suspect = _abkit.filter_tracks(
            z3, t2, off, f.n, m, law, np.ascontiguousarray(params, dtype=np.float64).reshape(-1),
            np.ascontiguousarray(f._h[0]).reshape(-1), np.ascontiguousarray(f._hpinv[0]).reshape(-1),
            float(tn[0]), init_mode, gap, drop, packed, out2, counts, res2,
            None if threads is None else int(threads), smoother, smoother_params, lag,
        )
    if gap is None and suspect:
        # Some started track's final state is not finite (the kernel's
        # check, O(n_tracks) in Rust): find the Inf or the overflow.
        check_no_inf_after(f, z3, off, packed)
    residuals = None
    if res2 is not None:
        residuals = res2.reshape(shape + ((m,) if m > 1 else ()))
    return FilterResult(
        o, residuals, FilterState(packed, f.n, single),
        offsets=None if offsets is None else off,
        n_dropped=counts[:, 0].copy(), n_restarts=counts[:, 1].copy(),
        t=t_arr if t is not None else None,
    )


def run_axes(f: "FixedGainFilter", z: Any, axes: Any, *, t: Any, offsets: Any, state: Optional["FilterState"], out: Optional[np.ndarray], **kw: Any) -> "FilterResult":
    """Each spatial axis through :func:`run_tracks` (strided views of ``z``,
    no copy), results stacked on a trailing axis."""
    from .filters import FilterResult, FilterState

    if isinstance(axes, bool) or not isinstance(axes, (int, np.integer)) or axes not in (2, 3):
        raise ValueError(f"axes must be 2, 3 or None, got {axes!r}")
    d = int(axes)
    z = _z_dtype(z)
    ax = -1 if f.m == 1 else -2
    if z.ndim < (2 if f.m == 1 else 3) or z.shape[ax] != d:
        tail = f"({d},)" if f.m == 1 else f"({d}, {f.m})"
        raise ValueError(f"with axes={d}, z must end with the spatial axis {tail}, got shape {z.shape}")
    views = [z[..., a] if f.m == 1 else z[..., a, :] for a in range(d)]
    sub_states = None
    if state is not None:
        from .filters import FilterState as _FS

        if not isinstance(state, _FS):
            raise TypeError(f"state must be a FilterState (result.state), got {type(state).__name__}")
        if state.axes != d:
            raise ValueError(f"state is for axes={state.axes}, the call has axes={d}")
        sub_states = [FilterState(np.ascontiguousarray(state._packed[a::d]), state.n, state.single) for a in range(d)]
    results = [
        run_tracks(f, views[a], t=t, offsets=offsets, state=None if sub_states is None else sub_states[a], out=None, **kw)
        for a in range(d)
    ]
    r0 = results[0]
    shape = r0.states.shape + (d,)
    if out is not None:
        o = f._out(out, z, z, shape[1:])
    else:
        o = np.empty(shape, dtype=r0.states.dtype)
    for a, r in enumerate(results):
        o[..., a] = r.states
    residuals = None
    if r0.residuals is not None:
        residuals = np.stack([r.residuals for r in results if r.residuals is not None], axis=-1 if f.m == 1 else -2)
    nt = r0.state._packed.shape[0]
    packed = np.empty((nt * d, _W))
    for a, r in enumerate(results):
        packed[a::d] = r.state._packed
    st = FilterState(packed, f.n, r0.state.single, axes=d)
    return FilterResult(
        o, residuals, st, offsets=r0.offsets,
        n_dropped=r0.n_dropped,
        n_restarts=r0.n_restarts,
        t=r0.t,
    )


def run_feed(
    f: "FixedGainFilter",
    zs: Any,
    t: Optional[np.ndarray],
    codes: np.ndarray,
    n_tracks: int,
    *,
    max_gap: Any = None,
    on_duplicate: Any = "raise",
    init: Any = "two-point",
    return_residuals: bool = True,
    threads: Optional[int] = None,
    state: Optional[np.ndarray] = None,
) -> Tuple[np.ndarray, Optional[np.ndarray], np.ndarray, np.ndarray]:
    """A feed of reports in arrival order (rows of many tracks interleaved)
    through the row kernel (``abkit-core`` module ``feed``): row ``r`` is a
    report of track ``codes[r]`` (``0 <= code < n_tracks``) with the values
    ``zs[c][r]`` of scalar-measurement columns ``c`` (one dtype) at time
    ``t[r]``. Equal, bit for bit, to running the rows grouped by track (in
    row order within each track) through :func:`run_tracks`, without
    reordering anything: estimates and residuals come out in row order.

    Returns ``(states (n_columns, n, n_rows), residuals (n_columns, n_rows)
    or None, counts (n_tracks, 2) [n_dropped, n_restarts] of column 0,
    rows (n_tracks, 2) [n_rows, first row])``. ``state``: the per-track
    state tables of an earlier call (``(n_columns * n_tracks, STATE_WIDTH)``
    float64, updated in place; a string ``init`` applies to tracks still
    in phase 0), else fresh tables. A data error raises
    ``ValueError`` whose message starts ``column c: track i, sample k``
    (``k``: the sample within the track)."""
    if f.m != 1:
        raise ValueError("the feed kernel runs scalar-measurement filters (m = 1)")
    check_steady_state(f, "the feed kernel")
    if threads is not None and (not isinstance(threads, (int, np.integer)) or isinstance(threads, bool) or threads < 1):
        raise ValueError(f"threads must be a positive integer or None, got {threads!r}")
    drop = check_on_duplicate(on_duplicate)
    gap = check_max_gap(max_gap, t is not None)
    cols = [_aligned(_z_dtype(z)) for z in zs]
    codes = np.ascontiguousarray(codes, dtype=np.int64)
    n_rows = codes.size
    if not cols or any(z.ndim != 1 or z.size != n_rows for z in cols) or len({z.dtype for z in cols}) != 1:
        raise ValueError("zs must be 1-D columns of one dtype, one value per row")
    dt = cols[0].dtype
    for c, z in enumerate(cols):
        # (a restart after a gap forgets an Inf: scan for it first)
        one = z[None, :, None]
        try:
            check_no_inf(one, np.array([0, n_rows]))
        except ValueError:
            r = int(np.flatnonzero(np.isinf(z))[0])
            i = int(codes[r])
            k = int(np.count_nonzero(codes[:r] == i))
            raise ValueError(f"column {c}: track {i}, sample {k}: z must be finite or NaN (a missed detection), got {float(z[r])!r}") from None
    f._check_params(n_tracks)
    if t is not None:
        t = _aligned(check_t(t, (n_rows,)))
    law, params, tn = _kernel_law(f, t is not None, "a feed needs")
    if state is None:
        packed, init_mode = f._initial_state(init, None, n_tracks)
        state = np.tile(packed, (len(cols), 1))  # fresh: no timestamps known
    else:
        if not isinstance(init, str):
            raise ValueError("init must be 'two-point' or 'first' when state tables are given")
        _, init_mode = f._initial_state(init, None, 0)
        if state.shape != (len(cols) * n_tracks, _W) or state.dtype != np.float64 or not state.flags.c_contiguous:
            raise ValueError(f"state must be C-contiguous float64 of shape ({len(cols) * n_tracks}, {_W})")
    out = np.empty((len(cols), f.n, n_rows), dtype=dt)
    res = np.empty((len(cols), n_rows), dtype=dt) if return_residuals else None
    counts = np.zeros((n_tracks, 2), dtype=np.int64)
    rows = np.zeros((n_tracks, 2), dtype=np.int64)
    _abkit.filter_feed(
        cols, t, codes, f.n, law, np.ascontiguousarray(params, dtype=np.float64).reshape(-1),
        np.ascontiguousarray(f._h[0]).reshape(-1), np.ascontiguousarray(f._hpinv[0]).reshape(-1),
        float(tn[0]), init_mode, gap, drop, state, out, counts, rows, res,
        None if threads is None else int(threads),
    )
    return out, res, counts, rows
