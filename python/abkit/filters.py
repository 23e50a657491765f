r"""Batched fixed-gain filtering: alpha-beta, alpha-beta-gamma and general filters.

A fixed-gain filter with transition ``Phi`` (n x n), measurement matrix ``H``
(m x n) and filter-form gain ``K`` (n x m) runs, for every track and sample,

.. code-block:: text

    x_p = Phi x          predict
    e   = z - H x_p      residual
    x   = x_p + K e      update (skipped for a missed sample)

over arrays of shape ``(n_samples,)`` or ``(n_tracks, n_samples)`` (scalar
measurements) or ``(..., m)`` (vector measurements), in float32 or float64,
in Rust with the GIL released, on rayon's thread pool.

Missed detections
-----------------
A NaN measurement (any NaN component) is a missed detection: the filter
coasts (prediction only) and the residual is NaN. NaN never propagates into
later valid samples. Before a track's first valid sample its estimates are
NaN; a track that is all NaN stays NaN.

Start-up (``init``)
-------------------
``"two-point"`` (kinematic filters; the standard tracker start): position
from the first valid sample (velocity NaN until the second), then position
and velocity from the first two valid samples, ``(z2 - z1) / (gap T)``;
filtering starts at the next sample. ``"first"``: the state from the first
valid measurement (``pinv(H) z``), rates zero, filtering from the next
sample. An array: explicit states just before the first sample, shape
``(n,)`` or ``(n_tracks, n)``.

Streaming
---------
``result.state`` is the final per-track state; ``f.run(z2, state=r1.state)``
continues exactly where ``r1`` stopped (bit-identical to one call over the
concatenated samples). :class:`Tracker` holds the state for real-time use.
"""

from __future__ import annotations

import math
import re
from typing import Any, Optional, Sequence, Tuple, Union

import numpy as np

from . import _abkit
from ._errors import perturbation_estimate, warn_accuracy
from ._validate import aligned_state, as_float_array, as_matrix, check_positive, check_representable, check_tracks_finite

__all__ = [
    "FixedGainFilter",
    "AlphaBetaFilter",
    "AlphaBetaGammaFilter",
    "FilterResult",
    "FilterState",
    "Tracker",
    "ABG_CONVENTIONS",
    "empty_states",
]

_W = int(_abkit.STATE_WIDTH)
_PAD_MIN_BYTES = int(_abkit.PAD_MIN_BYTES)
_NMAX = int(_abkit.MAX_STATES)
# A fresh track's packed state: zeros, phase 0, no timestamps known (NaN).
_FRESH = np.zeros(_W)
_FRESH[_NMAX + 2 :] = np.nan
_ACCEPTED = (np.dtype(np.float32), np.dtype(np.float64))

#: Alpha-beta-gamma gain conventions: the filter-form gain vector for
#: ``(alpha, beta, gamma)`` and period ``T``.
#:
#: - ``"standard"`` (Bar-Shalom, Kalata, tracklib): ``[alpha, beta/T, gamma/(2 T^2)]``
#: - ``"chen-chui"`` (paper 004): ``[alpha, beta/T, gamma/T^2]``
#: - ``"ghk"`` (FilterPy's g-h-k filter, ``k`` passed as ``gamma``): ``[g, h/T, 2k/T^2]``
ABG_CONVENTIONS = {
    "standard": 0.5,
    "chen-chui": 1.0,
    "ghk": 2.0,
}


class FilterState:
    """Per-track filter state for streaming (``result.state``).

    Attributes
    ----------
    x : ndarray, shape (n_tracks, n)
        The state estimate after the last sample.
    phase : ndarray of int, shape (n_tracks,)
        0: no valid sample yet; 1: one valid sample held (two-point start);
        2: running.
    t_last : ndarray, shape (n_tracks,)
        Timestamp of the last kept sample (runs with ``t``), NaN otherwise.
    axes : int or None
        The spatial axes of a run with ``axes=`` (rows are then
        ``track * axes + axis``).
    """

    __slots__ = ("_packed", "n", "single", "axes")

    def __init__(self, packed: np.ndarray, n: int, single: bool, axes: Optional[int] = None):
        self._packed = packed
        self.n = n
        self.single = single
        self.axes = axes

    @property
    def t_last(self) -> np.ndarray:
        t = self._packed[:, _NMAX + 2].copy()
        return t[0] if self.single and self.axes is None else t

    @property
    def n_tracks(self) -> int:
        return int(self._packed.shape[0])

    @property
    def x(self) -> np.ndarray:
        x = self._packed[:, : self.n].copy()
        return x[0] if self.single else x

    @property
    def phase(self) -> np.ndarray:
        p = self._packed[:, _NMAX].astype(np.int8)
        return p[0] if self.single else p

    def copy(self) -> "FilterState":
        return FilterState(self._packed.copy(), self.n, self.single, self.axes)

    def __repr__(self) -> str:
        return f"FilterState(n_tracks={self.n_tracks}, n={self.n})"


class FilterResult:
    """Output of :meth:`FixedGainFilter.run`.

    Attributes
    ----------
    states : ndarray, shape (n, *sample_shape)
        All estimates, component-major (each component contiguous);
        ``sample_shape`` is ``(n_samples,)`` or ``(n_tracks, n_samples)``.
    position, velocity, acceleration : ndarray, shape sample_shape
        ``states[0]``, ``states[1]``, ``states[2]`` (where the state has them).
    residuals : ndarray or None
        ``z - H x_p``, shaped like ``z``; NaN at missed samples and during
        start-up. Only with ``return_residuals=True``.
    state : FilterState
        Final per-track state, for ``run(..., state=...)``.
    offsets : ndarray of int64 or None
        The ``offsets`` of a ragged run (the layout of ``states``), else None.
    n_dropped, n_restarts : ndarray of int64, shape (n_tracks,)
        Per track: samples dropped as duplicates (``on_duplicate="drop"``)
        and restarts after a gap (``max_gap``); zeros when not applicable.
    t : ndarray or None
        The timestamps (float64) of a run with ``t``, else None.
    """

    __slots__ = ("states", "residuals", "state", "offsets", "_n_dropped", "_n_restarts", "t")

    def __init__(
        self,
        states: np.ndarray,
        residuals: Optional[np.ndarray],
        state: FilterState,
        *,
        offsets: Optional[np.ndarray] = None,
        n_dropped: Optional[np.ndarray] = None,
        n_restarts: Optional[np.ndarray] = None,
        t: Optional[np.ndarray] = None,
    ):
        self.states = states
        self.residuals = residuals
        self.state = state
        self.offsets = offsets
        # Zeros made on first access (most runs drop and restart nothing).
        self._n_dropped = n_dropped
        self._n_restarts = n_restarts
        self.t = t

    def _zeros(self) -> np.ndarray:
        return np.zeros(self.state._packed.shape[0] // (self.state.axes or 1), dtype=np.int64)

    @property
    def n_dropped(self) -> np.ndarray:
        if self._n_dropped is None:
            self._n_dropped = self._zeros()
        return self._n_dropped

    @property
    def n_restarts(self) -> np.ndarray:
        if self._n_restarts is None:
            self._n_restarts = self._zeros()
        return self._n_restarts

    @property
    def position(self) -> np.ndarray:
        return self.states[0]

    @property
    def velocity(self) -> np.ndarray:
        if self.states.shape[0] < 2:
            raise AttributeError("this filter has no velocity state")
        return self.states[1]

    @property
    def acceleration(self) -> np.ndarray:
        if self.states.shape[0] < 3:
            raise AttributeError("this filter has no acceleration state")
        return self.states[2]

    def __repr__(self) -> str:
        return f"FilterResult(states={self.states.shape} {self.states.dtype}, residuals={'yes' if self.residuals is not None else 'no'})"


#: Fresh outputs at least this big (the kernels' non-temporal-store
#: threshold) are faulted in before filtering; see :func:`fresh_output`.
_PREFAULT_BYTES = 64 << 20


def _line_elems(dtype: np.dtype) -> int:
    """Elements of ``dtype`` per 64-byte cache line."""
    return max(1, 64 // dtype.itemsize)


def _plane_stride(shape: Tuple[int, ...], dtype: np.dtype, flat: bool) -> int:
    """The padded layout's plane stride (elements) of an estimate array of
    ``shape``: rows of ``shape[-1]`` samples, or one flat sequence per plane
    (``flat``: the ragged kernel's outputs). One definition, in Rust
    (``abkit_core::planes::padded_stride``)."""
    per = math.prod(shape[1:])
    row = 0 if flat else int(shape[-1])
    return int(_abkit.plane_stride(int(shape[0]), per, row, dtype.itemsize))


def _empty_planes(shape: Tuple[int, ...], dtype: Any, flat: bool = False) -> Tuple[np.ndarray, np.ndarray]:
    """An uninitialised ``shape`` array in the padded plane layout, and the
    buffer it views (see :func:`empty_states`)."""
    dt = np.dtype(dtype)
    shape = tuple(int(d) for d in shape)
    n, per = shape[0], math.prod(shape[1:])
    # Below PAD_MIN_BYTES the stride is the plane size (padded_stride's
    # first case), without the call.
    pad = per if n * per * dt.itemsize < _PAD_MIN_BYTES else _plane_stride(shape, dt, flat)
    if n < 2 or pad == per:
        o = np.empty(shape, dtype=dt)
        return o, o
    line = _line_elems(dt)
    buf = np.empty((n - 1) * pad + per + line, dtype=dt)
    # Start the first plane on a 64-byte boundary (the others follow it).
    skip = (-buf.__array_interface__["data"][0] // dt.itemsize) % line
    inner = tuple(math.prod(shape[k + 1 :]) * dt.itemsize for k in range(1, len(shape)))
    o = np.ndarray(shape, dtype=dt, buffer=buf, offset=skip * dt.itemsize, strides=(pad * dt.itemsize,) + inner)
    return o, buf


def empty_states(shape: Tuple[int, ...], dtype: Any = np.float64, *, ragged: bool = False) -> np.ndarray:
    """A new, uninitialised estimate array for ``out=``, in the layout of
    abkit's own results.

    Parameters
    ----------
    shape : tuple of int
        ``(n_states,) + sample_shape``: the shape of a result's ``.states``
        (for example ``(2, n_tracks, n_samples)`` for alpha-beta).
    dtype : float32 or float64
        The measurements' dtype.
    ragged : bool, optional
        For ``run``/``smooth`` with ``offsets=`` (the ragged kernel, whose
        planes are one flat sequence each); default ``False``: rectangular
        batches, rows of ``shape[-1]`` samples.

    Returns
    -------
    numpy.ndarray
        An array of ``shape`` whose component planes ``a[i]`` are each
        C-contiguous. Of 8 MiB or more (the size from which the kernels
        stream their outputs past the caches), each plane starts at the
        same phase of a 64-byte cache line as ``a[0]``: the plane stride is
        the plane's size rounded up to whole lines and then, if need be,
        by a few more lines (less than 4 KiB in all) that keep the planes'
        rows written at once apart modulo 4 KiB. A C-contiguous array when
        that stride is the plane's size itself, and below 8 MiB.

    Raises
    ------
    TypeError
        ``dtype`` is not float32 or float64.
    ValueError
        ``shape`` is not a tuple of at least two non-negative integers.

    Notes
    -----
    The kernels stream the position plane from a cache-line boundary; the
    other planes are streamed too only when they share its line phase, which
    a C-contiguous ``(n_states, n_tracks, n_samples)`` array gives only when
    ``n_tracks * n_samples`` is a multiple of 8 (float64) or 16 (float32);
    off it, filtering ran 25-120 % slower. Planes whose rows in flight fall
    within 32 bytes of each other modulo 4 KiB ran 1.1-2.2x slower
    (``docs/benchmarks.md``, sessions 35 and 36). Every fresh result uses
    this layout; ``out=`` accepts it (so a result's ``.states`` can be
    passed back) as well as any C-contiguous array.

    Examples
    --------
    >>> import numpy as np, abkit
    >>> f = abkit.AlphaBetaFilter(0.5, 0.2, 1.0)
    >>> z = np.zeros((999, 1001))  # planes of 999,999 float64 (8 MB each)
    >>> out = abkit.empty_states((2,) + z.shape)
    >>> out.flags.c_contiguous, out[0].flags.c_contiguous, out[1].flags.c_contiguous
    (False, True, True)
    >>> out.strides[1:], out.strides[0] % 64, out.strides[0] > 999_999 * 8
    ((8008, 8), 0, True)
    >>> r = f.run(z, out=out)
    >>> r.states is out
    True
    >>> abkit.empty_states((2, 3, 5)).flags.c_contiguous  # small: back to back
    True
    """
    dt = np.dtype(dtype)
    if dt not in _ACCEPTED:
        raise TypeError(f"dtype must be float32 or float64, got {dt}")
    if not isinstance(shape, tuple) or len(shape) < 2 or any(isinstance(d, bool) or not isinstance(d, (int, np.integer)) or d < 0 for d in shape):
        raise ValueError(f"shape must be a tuple (n_states, ...) of at least two non-negative integers, got {shape!r}")
    return _empty_planes(shape, dt, bool(ragged))[0]


def planes_layout_ok(out: np.ndarray, flat: bool = False) -> bool:
    """Whether ``out`` has a layout the kernels write: C-contiguous, or the
    padded plane layout of :func:`empty_states` (``flat``: its ``ragged``)."""
    if out.flags.c_contiguous:
        return True
    if out.ndim < 2 or out.shape[0] < 2 or 0 in out.shape or not out[0].flags.c_contiguous:
        return False
    return out.strides[0] == _plane_stride(out.shape, out.dtype, flat) * out.itemsize


def planes_view(o: np.ndarray, shape: Tuple[int, ...]) -> np.ndarray:
    """``o`` (an estimate array of :func:`planes_layout_ok`) reshaped to
    ``shape`` as a view, never a copy (the kernels write into it)."""
    v = o.reshape(shape)
    if v.size and not np.may_share_memory(v, o):
        raise RuntimeError("internal error in abkit: the output would be copied")  # pragma: no cover
    return v


def fresh_output(shape: Tuple[int, ...], dtype: Any, threads: Optional[int] = None, flat: bool = False) -> np.ndarray:
    """A new output array for the kernels, in the padded plane layout of
    :func:`empty_states` (``flat``: its ``ragged``). Big outputs are written by the
    kernels with non-temporal stores, which are slow on pages that are not
    mapped yet (every first touch of a page is a fault in the middle of a
    streamed line): those pages are faulted in first, by touching one byte
    per 4 KiB page (the same cost as any first use of fresh memory), in Rust
    on rayon's pool with the call's ``threads`` (the kernel zeroing the new
    pages is the cost, and it runs on every core), so filtering without
    ``out=`` costs filtering with ``out=`` plus the allocation."""
    o, buf = _empty_planes(shape, dtype, flat)
    if buf.nbytes >= _PREFAULT_BYTES:
        _abkit.prefault(buf.reshape(-1).view(np.uint8), threads)
    return o


def prepare_z(z: Any, m: int, name: str = "z") -> Tuple[np.ndarray, Tuple[int, ...], bool]:
    """Validate measurements (named ``name`` in errors) and view them as (n_tracks, n_samples, m) without copying."""
    if not isinstance(z, np.ndarray):
        z = np.asarray(z)
        if z.dtype.kind in "iub":
            raise TypeError(f"{name} must be a float32 or float64 array, got {z.dtype}; convert it with np.asarray(z, float)")
    if z.dtype not in _ACCEPTED:
        if z.dtype.kind == "f" and z.dtype.itemsize in (4, 8) and not z.dtype.isnative:
            raise TypeError(f"{name} must be float32 or float64 in native byte order, got {z.dtype}; use {name}.astype({name}.dtype.newbyteorder('='))")
        raise TypeError(f"{name} must be a float32 or float64 array, got dtype {z.dtype}")
    if m == 1:
        if z.ndim == 1:
            z3, single = z[None, :, None], True
        elif z.ndim == 2:
            z3, single = z[:, :, None], False
        else:
            raise ValueError(f"{name} must have shape (n_samples,) or (n_tracks, n_samples) for scalar measurements, got {z.shape}")
    else:
        if z.ndim not in (2, 3) or z.shape[-1] != m:
            raise ValueError(f"{name} must have shape (n_samples, {m}) or (n_tracks, n_samples, {m}) for this filter (H has {m} rows), got {z.shape}")
        z3, single = (z[None] if z.ndim == 2 else z), z.ndim == 2
    st = z3.strides
    if not z3.flags.aligned or (st[0] | st[1] | st[2]) % z3.itemsize:
        z3 = np.ascontiguousarray(z3)  # unaligned memory: the one case that copies
    return z3, z3.shape[:2], single


class FixedGainFilter:
    r"""A general fixed-gain filter ``x = Phi x + K (z - H Phi x)``.

    Parameters
    ----------
    Phi : array_like, shape (n, n) or (n_tracks, n, n)
        State transition, ``1 <= n <= 6``.
    H : array_like, shape (m, n) or (n_tracks, m, n)
        Measurement matrix, ``m`` in {1, 2}.
    K : array_like, shape (n, m) or (n_tracks, n, m)
        Filter-form gain.
    T : float, optional
        Sampling period; used only by ``init="two-point"`` (velocity from two
        samples) for kinematic states ``[position, velocity, ...]``.
    allow_unstable : bool, optional
        Accept gains whose closed loop ``(I - K H) Phi`` has a spectral radius
        >= 1 (otherwise a ``ValueError``).
    transient : {None, "kalman"}, optional
        ``"kalman"``: exact start with the time-varying Kalman filter of the
        model ``(Q, R)`` from the prior ``(x0, P0)`` (default: zero and a
        diffuse ``1e12 R``); ``K`` must be its limiting gain (e.g. a Singer
        design from :func:`abkit.singer.steady_state`). See ``run``'s Notes.
    P0, Q, R, x0 : array_like, optional
        Prior and model for ``transient="kalman"``.

    Notes
    -----
    Per-track parameters (a leading ``n_tracks`` axis) give one design per
    track; ``run`` then needs exactly that many tracks.

    Examples
    --------
    >>> import numpy as np
    >>> from abkit import FixedGainFilter
    >>> f = FixedGainFilter([[1.0, 1.0], [0.0, 1.0]], [[1.0, 0.0]], [[0.5], [0.2]])
    >>> r = f.run(np.arange(6.0), init="first")
    >>> r.position.shape, r.states.shape
    ((6,), (2, 6))
    """

    _kinematic = False

    def __init__(
        self,
        Phi: Any,
        H: Any,
        K: Any,
        T: Any = 1.0,
        *,
        allow_unstable: bool = False,
        transient: Optional[str] = None,
        P0: Any = None,
        Q: Any = None,
        R: Any = None,
        x0: Any = None,
    ):
        phi = as_float_array("Phi", Phi)
        if phi.ndim not in (2, 3) or phi.shape[-1] != phi.shape[-2]:
            raise ValueError(f"Phi must have shape (n, n) or (n_tracks, n, n), got {phi.shape}")
        n = phi.shape[-1]
        if not 1 <= n <= _NMAX:
            raise ValueError(f"Phi: state dimension must be 1..{_NMAX}, got {n}")
        h = as_float_array("H", H)
        if h.ndim == 1:
            h = h[None, :]
        if h.ndim not in (2, 3) or h.shape[-1] != n or h.shape[-2] not in (1, 2):
            raise ValueError(f"H must have shape (m, {n}) with m in (1, 2), got {h.shape}")
        m = h.shape[-2]
        k = as_float_array("K", K)
        if k.ndim == 1 and m == 1:
            k = k[:, None]
        if k.ndim not in (2, 3) or k.shape[-2:] != (n, m):
            raise ValueError(f"K must have shape ({n}, {m}) or (n_tracks, {n}, {m}), got {k.shape}")
        lead = {a.shape[0] for a in (phi, h, k) if a.ndim == 3}
        if len(lead) > 1:
            raise ValueError(f"Phi, H, K have different numbers of per-track parameter sets: {sorted(lead)}")
        P = lead.pop() if lead else 1
        for name, a in (("Phi", phi), ("H", h), ("K", k)):
            if not np.all(np.isfinite(a)):
                raise ValueError(f"{name} must be finite")
        t = as_float_array("T", T)
        if t.ndim > 1 or (t.ndim == 1 and t.size not in (1, P)):
            raise ValueError(f"T must be a scalar or have shape ({P},) (one per parameter set), got shape {t.shape}")
        check_positive("T", t)
        self._phi = np.ascontiguousarray(np.broadcast_to(phi, (P, n, n)))
        self._h = np.ascontiguousarray(np.broadcast_to(h, (P, m, n)))
        self._k = np.ascontiguousarray(np.broadcast_to(k, (P, n, m)))
        self._t = np.ascontiguousarray(np.broadcast_to(t, (P,)), dtype=np.float64)
        self._hpinv = np.ascontiguousarray(np.linalg.pinv(self._h))
        self.n, self.m, self.n_params = n, m, P
        self.allow_unstable = allow_unstable
        rho = np.atleast_1d(self.spectral_radius)
        bad = ~(rho < 1.0)
        if bad.any() and not allow_unstable:
            i = int(np.argmax(bad))
            where = "" if P == 1 else f" (parameter set {i})"
            raise ValueError(
                f"K gives an unstable filter{where}: spectral radius of (I - K H) Phi is "
                f"{float(rho.reshape(-1)[i]):.6g} >= 1; pass allow_unstable=True to run it anyway"
            )
        if type(self) is FixedGainFilter:
            self._set_transient(transient, P0, Q, R, x0)
        elif transient is not None:
            raise ValueError("internal: subclasses configure transient themselves")

    def __setstate__(self, state: dict) -> None:
        # unpickling (e.g. on a dask worker): arrays aligned for the kernels
        self.__dict__.update(aligned_state(state))

    # -- model ---------------------------------------------------------------
    @property
    def Phi(self) -> np.ndarray:
        return self._phi[0] if self.n_params == 1 else self._phi.copy()

    @property
    def H(self) -> np.ndarray:
        return self._h[0] if self.n_params == 1 else self._h.copy()

    @property
    def K(self) -> np.ndarray:
        return self._k[0] if self.n_params == 1 else self._k.copy()

    @property
    def closed_loop(self) -> np.ndarray:
        """``(I - K H) Phi``, the filtered-state error transition."""
        eye = np.eye(self.n)
        a = (eye - self._k @ self._h) @ self._phi
        return a[0] if self.n_params == 1 else a

    @property
    def spectral_radius(self) -> Union[float, np.ndarray]:
        """Largest pole magnitude of the closed loop (< 1: stable)."""
        rho = np.max(np.abs(np.linalg.eigvals((np.eye(self.n) - self._k @ self._h) @ self._phi)), axis=-1)
        return float(rho[0]) if self.n_params == 1 else rho

    def covariances(self, Q: Any, R: Any) -> "SteadyStateCovariance":
        """Theoretical steady-state error covariances of this filter under the
        model ``x' = Phi x + w`` (``cov w = Q``), ``z = H x + v`` (``cov v = R``).

        Returns predicted, filtered and (RTS) smoothed covariances; see
        :class:`SteadyStateCovariance`.
        """
        q = as_matrix("Q", Q, (self.n, self.n))
        r = as_matrix("R", R, (self.m, self.m))
        if self.n_params != 1:
            raise ValueError("covariances() needs a filter with one parameter set")
        return _steady_covariance(self._phi[0], self._h[0], self._k[0], q, r)

    # -- running ---------------------------------------------------------------
    def _prepare_z(self, z: Any) -> Tuple[np.ndarray, Tuple[int, ...], bool]:
        return prepare_z(z, self.m)

    def _initial_state(self, init: Any, state: Optional[FilterState], n_tracks: int) -> Tuple[np.ndarray, str]:
        if state is not None:
            if not isinstance(state, FilterState):
                raise TypeError(f"state must be a FilterState (result.state), got {type(state).__name__}")
            if state.axes is not None:
                raise ValueError(f"state is from a run with axes={state.axes}; pass the same axes=")
            if state.n != self.n or state.n_tracks != n_tracks:
                raise ValueError(f"state is for {state.n_tracks} tracks of {state.n} states; z has {n_tracks} tracks and the filter {self.n} states")
            # a copy (the caller's state is never changed), float64 C order
            packed = np.array(state._packed, dtype=np.float64, order="C")
            if packed.shape != (n_tracks, _W):
                raise ValueError(f"state has a packed array of shape {packed.shape}; expected ({n_tracks}, {_W})")
        else:
            packed = _FRESH[None].repeat(n_tracks, 0)  # fresh tracks, no timestamps known
        if isinstance(init, str):
            if init not in ("two-point", "first"):
                raise ValueError(f"init must be 'two-point', 'first' or an array of initial states, got {init!r}")
            if init == "two-point" and not self._kinematic:
                if not (self.m == 1 and self._kinematic_like()):
                    raise ValueError("init='two-point' needs a kinematic state [position, velocity, ...] measured in position; use init='first' or explicit states")
            return packed, init
        x0 = as_float_array("init", init)
        if x0.shape not in ((self.n,), (n_tracks, self.n)):
            raise ValueError(f"init array must have shape ({self.n},) or ({n_tracks}, {self.n}), got {x0.shape}")
        if not np.all(np.isfinite(x0)):
            raise ValueError("init must be finite")
        if state is None:
            packed[:, : self.n] = x0
            packed[:, _NMAX] = 2
        return packed, "first"

    #: Gain law of the time-varying kernel: (kind, parameter rows) or None
    #: (a filter that cannot build ``Phi(dt)``).
    _tv_law: Optional[Tuple[str, np.ndarray]] = None

    @property
    def gain_schedule(self) -> str:
        """``"design"``: with timestamps, the steady-state design for each
        step ``dt`` (filters built from noise statistics); ``"fixed"``: the
        gains stay fixed, the prediction and rate gains use ``dt``."""
        law = self._tv_law
        return "design" if law is not None and law[0] in ("ab-design", "abg-design", "singer") else "fixed"

    def _time_law(self) -> Tuple[str, np.ndarray]:
        if self._tv_law is None:
            raise ValueError(
                f"t= needs a filter that knows its continuous model to build Phi(dt): "
                f"AlphaBetaFilter, AlphaBetaGammaFilter or abkit.singer.filter(...); "
                f"this {type(self).__name__} has an arbitrary Phi"
            )
        return self._tv_law

    def _kinematic_like(self) -> bool:
        h = self._h
        return bool(np.all(h[:, 0, 0] == 1) and np.all(h[:, 0, 1:] == 0) and self.n >= 2)

    def _check_params(self, n_tracks: int) -> None:
        if self.n_params not in (1, n_tracks):
            raise ValueError(f"the filter has {self.n_params} per-track parameter sets but z has {n_tracks} tracks")

    def _out(self, out: Any, z: np.ndarray, z3: np.ndarray, shape: Tuple[int, ...], threads: Optional[int] = None, flat: bool = False) -> np.ndarray:
        want = (self.n,) + shape
        if out is None:
            return fresh_output(want, z.dtype, threads, flat)
        if not isinstance(out, np.ndarray):
            raise TypeError(f"out must be a numpy array, got {type(out).__name__}")
        if out.shape != want or out.dtype != z.dtype:
            raise ValueError(f"out must have shape {want} and dtype {z.dtype}, got {out.shape} {out.dtype}")
        if not planes_layout_ok(out, flat) or not out.flags.writeable:
            how = "abkit.empty_states(shape, dtype, ragged=True) (a ragged result's .states)" if flat else "abkit.empty_states (a result's .states)"
            raise ValueError(f"out must be writeable and C-contiguous or in the layout of {how}")
        if np.shares_memory(out, z):
            raise ValueError("out overlaps z")
        return out

    def _kernel(self, z3: np.ndarray, packed: np.ndarray, init: str, out3: np.ndarray, res3: Optional[np.ndarray], threads: Optional[int], sgain: Optional[np.ndarray] = None, lag: Optional[int] = None) -> Optional[bool]:
        """Run the batch kernel; ``True`` if some started track's final
        state is not finite (``None``: not known, check)."""
        return _abkit.filter_fixed_gain(
            z3, self.n, self.m, self._phi.reshape(-1), self._h.reshape(-1), self._k.reshape(-1),
            self._hpinv.reshape(-1), self._t, init, packed, out3, res3, threads, sgain, lag,
        )

    _transient: Optional[Tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = None

    def _default_model(self) -> Tuple[np.ndarray, np.ndarray]:
        raise ValueError(f"transient='kalman' for {type(self).__name__} needs the noise model: pass Q and R")

    def _set_transient(self, transient: Optional[str], P0: Any, Q: Any, R: Any, x0: Any) -> None:
        """Configure the exact Kalman start (see ``transient`` in the class docs)."""
        if transient is None:
            if any(v is not None for v in (P0, Q, R, x0)):
                raise ValueError("P0, Q, R and x0 apply only with transient='kalman'")
            self._transient = None
            return
        if transient != "kalman":
            raise ValueError(f"transient must be None or 'kalman', got {transient!r}")
        if self.n_params != 1:
            raise ValueError("transient='kalman' needs one parameter set for all tracks")
        from . import kalman as _kalman

        if Q is None and R is None:
            q, r = self._default_model()
        elif Q is None or R is None:
            raise ValueError("give both Q and R (or neither, for an alpha-beta filter's Kalman-equivalent model)")
        else:
            q, r = np.asarray(Q, dtype=float), np.asarray(R, dtype=float)
        r_scale = float(np.max(np.abs(np.atleast_2d(r))))
        p0 = np.eye(self.n) * 1e12 * r_scale if P0 is None else P0
        x = np.zeros(self.n) if x0 is None else x0
        kf = _kalman.KalmanFilter(self._phi[0], self._h[0], q, r, x0=x, P0=p0)
        # The Kalman gains must converge to this filter's gains.
        g = kf.gain_sequence(20000)
        k_inf = g.K[-1]
        err = float(np.max(np.abs(k_inf - self._k[0])) / max(1e-300, float(np.max(np.abs(self._k[0])))))
        if not err < 1e-6:
            raise ValueError(
                f"transient='kalman': the filter's gains are not the limiting Kalman gains of the model "
                f"(relative difference {err:.3g}); pass the Q and R the gains were designed for"
            )
        self._transient = (kf.F, kf.Q, kf.R, kf.P0)
        self._transient_filter = kf

    def run(
        self,
        z: Any,
        *,
        t: Any = None,
        offsets: Any = None,
        axes: Optional[int] = None,
        max_gap: Optional[float] = None,
        on_duplicate: str = "raise",
        init: Any = "two-point",
        state: Optional[FilterState] = None,
        out: Optional[np.ndarray] = None,
        return_residuals: bool = False,
        threads: Optional[int] = None,
    ) -> FilterResult:
        """Filter measurements.

        Parameters
        ----------
        z : ndarray
            ``(n_samples,)`` or ``(n_tracks, n_samples)`` (scalar measurements),
            ``(n_samples, m)`` or ``(n_tracks, n_samples, m)`` (vector);
            float32 or float64 (kept), any strides; NaN = missed detection.
            With ``offsets``: flat, ``(N,)`` or ``(N, m)``. With ``axes``:
            a trailing spatial axis of that length (before ``m``).
        t : array_like, optional
            Timestamps (float64; float32 and integers are converted) of the
            sample shape of ``z`` (a shared ``(n_samples,)`` vector is
            accepted for ``(n_tracks, n_samples)``). The step
            ``dt_k = t_k - t_{k-1}`` replaces ``T``: filters designed from
            noise (``gain_schedule == "design"``) use the steady-state
            design for each ``dt_k``; filters given gains keep them and
            scale the prediction and rate gains by ``dt_k``. A general
            :class:`FixedGainFilter` cannot build ``Phi(dt)`` (ValueError).
            See ``docs/tracks.md``.
        offsets : array_like of int, optional
            Ragged batch (Arrow list layout): ``n_tracks + 1`` offsets,
            ``offsets[0] == 0``, non-decreasing, ``offsets[-1] == N``;
            track ``i`` is ``z[offsets[i]:offsets[i+1]]``. Estimates are in
            the same flat layout, ``(n, N)``. Equal to running each track
            alone.
        axes : {2, 3}, optional
            Spatial axes, each filtered independently with the same design;
            estimates get the same trailing axis.
        max_gap : float, optional
            Restart a track (re-initialise it by ``init`` at the sample)
            after a step ``t_k - t_{k-1} > max_gap``. Needs ``t``.
        on_duplicate : {"raise", "drop"}, optional
            A timestamp not after the last kept one: ``"raise"`` a
            ValueError naming the track and sample, or ``"drop"`` the sample
            (NaN estimates and residual; counted in ``result.n_dropped``).
        init : {"two-point", "first"} or array_like, optional
            Start-up (see the module docs). Ignored for tracks already running
            in ``state``.
        state : FilterState, optional
            Continue from a previous result's ``state``.
        out : ndarray, optional
            Preallocated C-contiguous estimate array of shape
            ``(n, *sample_shape)`` and the dtype of ``z``, filled in place.
        return_residuals : bool, optional
            Also return the residuals ``z - H x_p``.
        threads : int, optional
            ``None``: rayon's global pool; ``1``: the calling thread; ``k``:
            a pool of ``k`` threads (kept for reuse). Results are
            bit-identical for any value.

        Returns
        -------
        FilterResult

        Notes
        -----
        A filter made with ``transient="kalman"`` runs the exact
        time-varying Kalman filter (:mod:`abkit.kalman`) from its prior
        ``(x0, P0)``: the gain sequence is computed once for all tracks and,
        once it has converged to the last bit, the limiting gain (this
        filter's gain) is used, so the optimal transient costs no more than
        fixed-gain filtering. ``init`` is then not used (the prior replaces
        the start-up), and ``state=`` streaming is not available.

        Raises
        ------
        TypeError
            ``z`` not float32/float64; ``out`` not an array.
        ValueError
            Wrong shapes, ``out`` of wrong shape/dtype or overlapping ``z``,
            bad ``init``/``state``/``threads``.
        """
        if t is not None or offsets is not None or axes is not None or max_gap is not None or on_duplicate != "raise":
            if self._transient is not None:
                raise ValueError("transient='kalman' does not support t, offsets, axes, max_gap or on_duplicate")
            if (
                getattr(self, "float32_arithmetic", False)
                and getattr(z, "dtype", None) == np.float32
                and (t is not None or max_gap is not None or on_duplicate != "raise")
            ):
                self._no_float32("run with t, max_gap or on_duplicate")
            from . import _tracks

            kw = dict(t=t, offsets=offsets, max_gap=max_gap, on_duplicate=on_duplicate, init=init, state=state, out=out, return_residuals=return_residuals, threads=threads)
            if axes is not None:
                return _tracks.run_axes(self, z, axes, **kw)  # type: ignore[arg-type]
            return _tracks.run_tracks(self, z, **kw)  # type: ignore[arg-type]
        if self._transient is not None:
            if state is not None:
                raise ValueError("transient='kalman' runs whole tracks; streaming with state= is not supported")
            kres = self._transient_filter.run(z, out=out, return_residuals=return_residuals, threads=threads)
            z3, (n_tracks, _), single = self._prepare_z(z)
            packed = np.zeros((n_tracks, _W))
            packed[:, _NMAX + 2 :] = np.nan
            last = kres.states[..., -1] if kres.states.shape[-1] else np.zeros((self.n,) + ((n_tracks,) if not single else ()))
            packed[:, : self.n] = np.asarray(last).reshape(self.n, n_tracks).T
            packed[:, _NMAX] = 2
            return FilterResult(kres.states, kres.residuals, FilterState(packed, self.n, single))
        return self._run(z, init, state, out, return_residuals, threads, None, None, 1)

    def _run(self, z: Any, init: Any, state: Optional[FilterState], out: Optional[np.ndarray], return_residuals: bool, threads: Optional[int], sgain: Optional[np.ndarray], lag: Optional[int], n_sgain: int) -> FilterResult:
        if threads is not None and (not isinstance(threads, (int, np.integer)) or isinstance(threads, bool) or threads < 1):
            raise ValueError(f"threads must be a positive integer or None, got {threads!r}")
        z3, (n_tracks, n_samples), single = self._prepare_z(z)
        self._check_params(n_tracks)
        if n_sgain not in (1, n_tracks):
            raise ValueError(f"smoother_gain has {n_sgain} gains for {n_tracks} tracks")
        packed, init_mode = self._initial_state(init, state, n_tracks)
        zarr = z if isinstance(z, np.ndarray) else z3
        shape = (n_samples,) if single else (n_tracks, n_samples)
        o = self._out(out, zarr, z3, shape, threads)
        out3 = planes_view(o, (self.n, n_tracks, n_samples))
        res3 = None
        if return_residuals:
            res3 = np.empty((n_tracks, n_samples, self.m), dtype=z3.dtype)
        suspect = self._kernel(z3, packed, init_mode, out3, res3, None if threads is None else int(threads), sgain, None if lag is None else int(lag))
        if not self.allow_unstable and suspect is not False:
            ph = packed[:, _NMAX]
            # One cheap reduction first (NaN/Inf propagate through the sum; a
            # half-started track's state is its position alone); the exact
            # check only if some sum is not finite (also when finite values
            # overflow the sum).
            with np.errstate(over="ignore", invalid="ignore"):
                s = np.where(ph == 1, packed[:, 0], packed[:, : self.n].sum(axis=1))
            if not np.isfinite(s[ph > 0]).all():
                check_tracks_finite("z", z3, np.where((ph == 1)[:, None], packed[:, :1], packed[:, : self.n]), ph > 0)
        residuals = None
        if res3 is not None:
            rshape = shape + ((self.m,) if self.m > 1 else ())
            residuals = res3.reshape(rshape)
        return FilterResult(o, residuals, FilterState(packed, self.n, single))

    def _default_smoother_gain(self) -> np.ndarray:
        raise ValueError(f"{type(self).__name__}.smooth needs the noise model: pass Q and R (or smoother_gain)")

    def _no_float32(self, what: str) -> None:
        raise ValueError(
            f"float32_arithmetic=True: {what} is not available in float32 arithmetic yet; pass float64 "
            "measurements or use a filter without float32_arithmetic (float32 data filtered in float64)"
        )

    def smoother_gain(self, Q: Any = None, R: Any = None) -> np.ndarray:
        """Backward gain ``A = P_filt Phi^T P_pred^-1`` of the steady-state
        RTS smoother for the model (Q, R); for an alpha-beta or (near-optimal)
        alpha-beta-gamma filter without (Q, R), that of its Kalman-equivalent
        model."""
        if Q is None and R is None:
            return self._default_smoother_gain()
        if Q is None or R is None:
            raise ValueError("give both Q and R")
        if self.n_params != 1:
            raise ValueError("per-track filters need smoother_gain= (one gain per track) instead of Q and R")
        a = self.covariances(Q, R).smoother_gain
        if a is None:
            raise np.linalg.LinAlgError("the predicted covariance is singular: no RTS smoother gain")
        return a[None]

    def smooth(
        self,
        z: Any,
        *,
        t: Any = None,
        offsets: Any = None,
        axes: Optional[int] = None,
        max_gap: Optional[float] = None,
        on_duplicate: str = "raise",
        lag: Optional[int] = None,
        Q: Any = None,
        R: Any = None,
        smoother_gain: Any = None,
        init: Any = "two-point",
        out: Optional[np.ndarray] = None,
        return_residuals: bool = False,
        threads: Optional[int] = None,
    ) -> FilterResult:
        r"""Filter, then smooth with the steady-state RTS smoother.

        ``x_s[k] = x_f[k] + A (x_s[k+1] - Phi x_f[k])`` with the constant
        backward gain ``A = P_filt Phi^T P_pred^-1`` (paper 001, eq (22)),
        over the whole track (``lag=None``) or as the fixed-lag smoother
        ``x_{k|k+lag}``. Same layouts, NaN rules and options as :meth:`run`;
        samples whose filtered estimate is NaN (start-up) stay as filtered.
        Each track is smoothed right after it is filtered, in the same pass.

        Parameters
        ----------
        lag : int, optional
            Fixed lag ``L >= 0`` (``0`` returns the filtered estimates).
        Q, R : array_like, optional
            Noise model for the backward gain. Alpha-beta and near-optimal
            alpha-beta-gamma filters default to their Kalman-equivalent
            model.
        smoother_gain : array_like, optional
            The backward gain ``A`` itself, shape ``(n, n)`` or
            ``(n_tracks, n, n)``.
        t, offsets, axes, max_gap, on_duplicate
            As for :meth:`run`. With ``t`` the backward step from sample
            ``k`` to the next kept sample uses the backward gain of the
            interval between them, ``A(dt) = P_filt Phi(dt)^T P_pred^-1``
            of the steady-state design at that ``dt`` (``gain_schedule ==
            "design"``: alpha-beta, alpha-beta-gamma ``from_noise`` and
            the Singer filter, the backward gains cached per distinct
            ``dt``) or, for fixed gains, the constant normalised gain of
            the Kalman-equivalent model scaled by ``dt``; dropped samples
            are skipped and the recursion restarts at ``max_gap`` gaps.
            Every filter that accepts ``run(t=...)`` accepts it (a general
            :class:`FixedGainFilter` with an arbitrary ``Phi`` does not:
            ValueError).

        Raises
        ------
        ValueError
            As for :meth:`run`; ``Q``/``R``/``smoother_gain`` together with
            ``t`` (the backward gain then follows ``dt``); fixed gains
            without a Kalman-equivalent model (alpha-beta ``alpha >= 1``,
            alpha-beta-gamma gains that are not near-optimal) with ``t`` or
            without ``Q``/``R``; a design with no stabilising steady state at
            some ``dt`` (the track and sample are named).
        """
        if getattr(self, "float32_arithmetic", False) and getattr(z, "dtype", None) == np.float32:
            self._no_float32("smooth")
        if lag is not None and (not isinstance(lag, (int, np.integer)) or isinstance(lag, bool) or lag < 0):
            raise ValueError(f"lag must be a non-negative integer or None, got {lag!r}")
        if t is not None or offsets is not None or axes is not None or max_gap is not None or on_duplicate != "raise":
            from . import _tracks

            if self._transient is not None:
                raise ValueError("transient='kalman' does not support t, offsets, axes, max_gap or on_duplicate")
            if t is not None:
                if Q is not None or R is not None or smoother_gain is not None:
                    raise ValueError("with t the backward gain follows dt (the per-dt design); Q, R and smoother_gain apply without t")
                kind, sparams = self._time_smoother()
            else:
                if smoother_gain is not None:
                    a0 = as_float_array("smoother_gain", smoother_gain)
                    a0 = a0[None] if a0.ndim == 2 else a0
                    if a0.ndim != 3 or a0.shape[1:] != (self.n, self.n) or not np.all(np.isfinite(a0)):
                        raise ValueError(f"smoother_gain must be finite with shape ({self.n}, {self.n}) or (n_tracks, {self.n}, {self.n}), got {np.shape(smoother_gain)}")
                    if Q is not None or R is not None:
                        raise ValueError("give smoother_gain or (Q, R), not both")
                else:
                    a0 = self.smoother_gain(Q, R)
                P = max(a0.shape[0], self.n_params)
                phi = np.broadcast_to(self._phi, (P, self.n, self.n)) if self.n_params in (1, P) else None
                if phi is None or a0.shape[0] not in (1, P):
                    raise ValueError(f"smoother_gain has {a0.shape[0]} gains for {self.n_params} parameter sets")
                aa = np.broadcast_to(a0, (P, self.n, self.n))
                kind, sparams = "const", np.concatenate([phi.reshape(P, -1), aa.reshape(P, -1)], axis=1)
            kw = dict(
                t=t, offsets=offsets, max_gap=max_gap, on_duplicate=on_duplicate, init=init, state=None, out=out,
                return_residuals=return_residuals, threads=threads,
                smoother=kind, smoother_params=np.ascontiguousarray(sparams, dtype=np.float64).reshape(-1),
                lag=None if lag is None else int(lag),
            )
            if axes is not None:
                return _tracks.run_axes(self, z, axes, **kw)  # type: ignore[arg-type]
            return _tracks.run_tracks(self, z, **kw)  # type: ignore[arg-type]
        if smoother_gain is not None:
            if Q is not None or R is not None:
                raise ValueError("give smoother_gain or (Q, R), not both")
            a = as_float_array("smoother_gain", smoother_gain)
            if a.ndim == 2:
                a = a[None]
            if a.ndim != 3 or a.shape[1:] != (self.n, self.n) or not np.all(np.isfinite(a)):
                raise ValueError(f"smoother_gain must be finite with shape ({self.n}, {self.n}) or (n_tracks, {self.n}, {self.n}), got {np.shape(smoother_gain)}")
        else:
            a = self.smoother_gain(Q, R)
        a = np.ascontiguousarray(a, dtype=np.float64)
        return self._run(z, init, None, out, return_residuals, threads, a.reshape(-1), lag, a.shape[0])

    def _time_smoother(self) -> Tuple[str, np.ndarray]:
        """Smoother of the track kernel with timestamps: ``("kin3", rows)``
        for the 3-state kinematic laws (rows of 10: kind 0 alpha-beta-gamma
        design + noise, 1 Singer design + (tau, q, sigma_pos), 2 fixed
        normalised backward gain ``A_N``)."""
        kind, params = self._time_law()
        params = np.atleast_2d(np.asarray(params, dtype=np.float64))
        if kind in ("abg-design", "singer"):
            rows = np.zeros((params.shape[0], 10))
            rows[:, 0] = 0.0 if kind == "abg-design" else 1.0
            rows[:, 1 : 1 + params.shape[1]] = params
            return "kin3", rows
        if kind == "abg-fixed":
            # The Kalman-equivalent model's backward gain at T, normalised
            # (x_N = D x, D = diag(1, T, T^2)); the kernel scales it to each dt.
            a = self._default_smoother_gain()
            d = np.stack([np.ones_like(self._t), self._t, self._t * self._t], axis=-1)
            an = a * d[:, :, None] / d[:, None, :]
            rows = np.zeros((an.shape[0], 10))
            rows[:, 0] = 2.0
            rows[:, 1:] = an.reshape(an.shape[0], 9)
            return "kin3", rows
        raise NotImplementedError(f"{type(self).__name__}.smooth(t=...) is not implemented for the gain law {kind!r}")

    def tracker(self, n_tracks: Optional[int] = None, init: Any = "two-point") -> "Tracker":
        """A :class:`Tracker` that holds this filter's state between chunks
        (``n_tracks``, ``init``: as for :class:`Tracker`)."""
        return Tracker(self, n_tracks=n_tracks, init=init)

    def __repr__(self) -> str:
        return f"{type(self).__name__}(n={self.n}, m={self.m}, n_params={self.n_params})"


class AlphaBetaFilter(FixedGainFilter):
    r"""The alpha-beta filter (state ``[position, velocity]``).

    Parameters
    ----------
    alpha, beta : float or array_like of shape (n_tracks,)
        Gains; the physical gains are ``(alpha, beta / T)``.
    T : float or array_like of shape (n_tracks,)
        Sampling period.
    allow_unstable : bool, optional
        Accept gains outside the stable region ``alpha > 0, beta > 0,
        2 alpha + beta < 4``.
    transient : {None, "kalman"}, optional
        ``"kalman"``: exact start — run the time-varying Kalman filter from
        the prior ``(x0, P0)`` until its gain has converged to these gains,
        then these fixed gains (see ``run``'s Notes). The model is ``(Q, R)``
        or, by default, the Kalman-equivalent white-acceleration model of
        these (Kalman-optimal) gains with ``R = 1``, so ``P0`` is then in
        units of the measurement variance; default ``P0`` is diffuse
        (``1e12 R``), ``x0`` zero.
    P0, Q, R, x0 : array_like, optional
        Prior and model for ``transient="kalman"``.
    float32_arithmetic : bool, optional
        Filter float32 measurements in float32 arithmetic (float64
        measurements are always filtered in float64). By default float32
        data are filtered in float64 and each estimate is rounded once
        (0.5 ulp of the float64 result); in float32 arithmetic every step
        rounds, and the estimates drift from the float64 ones by about
        ``0.3 / alpha`` float32 epsilons of the data's scale, plus up to
        ``G / 2`` after a run of ``G`` missed samples
        (``docs/filtering.md``), in exchange for up to twice the throughput
        on batches of many tracks on CPUs without AVX-512 (with AVX-512 the
        default kernels are about as fast; rows shorter than about 50
        samples run slower in this mode). Results stay bit-identical across
        thread counts, chunked streaming (``state=``) and batch layouts,
        except that a long single track is split into segments as in the
        default kernels (then within float32 rounding of the unsplit run).
        Available for :meth:`run` on regular batches and with ``offsets``
        and ``axes`` (ragged batches: each track gives the bits of that
        track run alone), not with ``t``, ``max_gap``, ``on_duplicate``, nor
        for :meth:`smooth`, ``transient`` or :class:`abkit.FeedTracker`:
        those raise a ValueError on float32 data.

    Examples
    --------
    >>> import numpy as np
    >>> from abkit import AlphaBetaFilter, alphabeta
    >>> f = AlphaBetaFilter.from_design(alphabeta.from_snr(0.1), T=0.5)
    >>> z = 2.0 * np.arange(10.0)           # constant velocity 4 per second
    >>> r = f.run(z)
    >>> bool(np.allclose(r.velocity[1:], 4.0))
    True
    """

    _kinematic = True

    def __init__(
        self,
        alpha: Any,
        beta: Any,
        T: Any,
        *,
        allow_unstable: bool = False,
        transient: Optional[str] = None,
        P0: Any = None,
        Q: Any = None,
        R: Any = None,
        x0: Any = None,
        float32_arithmetic: bool = False,
    ):
        if not isinstance(float32_arithmetic, (bool, np.bool_)):
            raise TypeError(f"float32_arithmetic must be True or False, got {float32_arithmetic!r}")
        if float32_arithmetic and transient is not None:
            raise ValueError("float32_arithmetic=True does not support transient='kalman'")
        a, b, t = (as_float_array(n, v) for n, v in (("alpha", alpha), ("beta", beta), ("T", T)))
        for name, v in (("alpha", a), ("beta", b), ("T", t)):
            if v.ndim > 1:
                raise ValueError(f"{name} must be a scalar or a 1-D array (one per track), got shape {v.shape}")
        check_positive("T", t)
        for name, v in (("alpha", a), ("beta", b)):
            if not np.all(np.isfinite(v)):
                raise ValueError(f"{name} must be finite")
        try:
            a, b, t = np.broadcast_arrays(a, b, t)
        except ValueError:
            raise ValueError(f"alpha {a.shape}, beta {b.shape} and T {t.shape} do not broadcast") from None
        P = a.size if a.ndim else 1
        a, b, t = a.reshape(P), b.reshape(P), t.reshape(P)
        stable = (a > 0) & (b > 0) & (2 * a + b < 4)
        if not stable.all() and not allow_unstable:
            i = int(np.argmin(stable))
            raise ValueError(
                f"alpha={a[i]!r}, beta={b[i]!r} give an unstable filter (need alpha > 0, beta > 0, "
                f"2*alpha + beta < 4); pass allow_unstable=True to run it anyway"
            )
        phi = np.zeros((P, 2, 2))
        phi[:, 0, 0] = phi[:, 1, 1] = 1.0
        phi[:, 0, 1] = t
        k = np.stack([a, b / t], axis=-1)[:, :, None]
        super().__init__(phi, np.array([[1.0, 0.0]]), k, t, allow_unstable=True)
        self.allow_unstable = allow_unstable
        self._params = np.ascontiguousarray(np.stack([a, b, t], axis=-1))
        self._tv_law = ("ab-fixed", np.stack([a, b], axis=-1))
        self.alpha = a[0] if P == 1 else a
        self.beta = b[0] if P == 1 else b
        self.T = t[0] if P == 1 else t
        self.float32_arithmetic = bool(float32_arithmetic)
        self._set_transient(transient, P0, Q, R, x0)

    def _default_model(self) -> Tuple[np.ndarray, np.ndarray]:
        """Kalman-equivalent model (R = 1): the white-acceleration model of
        paper 000 at the SNR r whose Kalman design has this alpha."""
        from . import alphabeta as _ab

        if not _ab.analyze(self.alpha, self.beta).kalman_optimal:
            raise ValueError("transient='kalman' without Q and R needs Kalman-optimal gains (see abkit.alphabeta.analyze)")
        r = _ab.analyze(self.alpha, self.beta).r
        t = float(self.T)
        sigma_w = 2.0 * np.sqrt(r) / (t * t)
        d = np.array([[t * t / 2.0], [t]])
        return sigma_w**2 * (d @ d.T), np.eye(1)

    @classmethod
    def from_design(cls, design: Any, T: Optional[Any] = None, **kw: Any) -> "AlphaBetaFilter":
        """Filter from an :class:`abkit.AlphaBeta` design (scalar or 1-D).

        A Kalman design (``design.kalman_optimal``) keeps its noise model:
        with timestamps the filter uses the Kalman design at each step
        (``gain_schedule == "design"``, tracking index
        ``lambda = 2 sqrt(r) (dt / T)^2``).
        """
        if T is None:
            T = design.T
            if T is None:
                raise ValueError("T must be given: the design was made without a sampling period")
        f = cls(design.alpha, design.beta, T, **kw)
        if bool(np.all(design.kalman_optimal)):
            lam = 2.0 * np.sqrt(np.atleast_1d(np.asarray(design.r, dtype=float)))
            t = np.atleast_1d(np.asarray(T, dtype=float))
            with np.errstate(over="ignore", under="ignore", divide="ignore", invalid="ignore"):
                ratio = np.broadcast_to(lam / t / t, (f.n_params,))
            _check_rate("the design's tracking-index rate lambda / T^2", ratio, ("T",), (t,))
            f._tv_law = ("ab-design", np.ascontiguousarray(ratio)[:, None])
        return f

    @classmethod
    def from_noise(cls, sigma_w: Any, sigma_v: Any, T: Any, **kw: Any) -> "AlphaBetaFilter":
        r"""The steady-state Kalman filter of the white-acceleration model.

        Gains from :func:`abkit.alphabeta.from_noise` (SNR
        ``r = ((sigma_w T^2 / 2) / sigma_v)^2``). With timestamps ``t`` the
        filter uses, at every step, the design for that ``dt_k``
        (``gain_schedule == "design"``; see ``docs/tracks.md``).

        Parameters
        ----------
        sigma_w : float or array_like
            Rms acceleration noise (> 0).
        sigma_v : float or array_like
            Rms measurement noise (> 0).
        T : float or array_like
            Nominal sampling period (> 0).
        **kw
            Passed to the constructor (``allow_unstable``, ``transient``, ...).

        Examples
        --------
        >>> import numpy as np
        >>> from abkit import AlphaBetaFilter
        >>> f = AlphaBetaFilter.from_noise(3.2, 32.0, 0.1)
        >>> f.gain_schedule
        'design'
        >>> r = f.run(np.array([0.0, 1.0, 2.5, 3.0]), t=[0.0, 0.1, 0.25, 0.3])
        >>> r.position.shape
        (4,)
        """
        from . import alphabeta as _ab

        for name, v in (("sigma_w", sigma_w), ("sigma_v", sigma_v), ("T", T)):
            if np.ndim(v) > 1:
                raise ValueError(f"{name} must be a scalar or a 1-D array (one per track), got shape {np.shape(v)}")
        d = _ab.from_noise(sigma_w, sigma_v, T)
        f = cls(d.alpha, d.beta, T, **kw)
        sw, sv = (np.atleast_1d(as_float_array(n, v)) for n, v in (("sigma_w", sigma_w), ("sigma_v", sigma_v)))
        with np.errstate(over="ignore", under="ignore", divide="ignore", invalid="ignore"):
            ratio = np.broadcast_to(sw / sv, (f.n_params,))
        _check_rate("the noise ratio sigma_w / sigma_v", ratio, ("sigma_w", "sigma_v"), (sw, sv))
        f._tv_law = ("ab-design", np.ascontiguousarray(ratio)[:, None])
        return f

    def _kernel(self, z3: np.ndarray, packed: np.ndarray, init: str, out3: np.ndarray, res3: Optional[np.ndarray], threads: Optional[int], sgain: Optional[np.ndarray] = None, lag: Optional[int] = None) -> Optional[bool]:
        f32 = self.float32_arithmetic and z3.dtype == np.float32
        if f32 and sgain is not None:
            self._no_float32("smooth")
        return _abkit.filter_alphabeta(z3, self._params, init, packed, out3, res3, threads, sgain, lag, f32)

    def _default_smoother_gain(self) -> np.ndarray:
        """Backward gain of the Kalman-equivalent model: the SNR r whose
        Kalman design has this alpha (abkit.alphabeta.analyze), with the
        covariances of these gains at that r."""
        from . import alphabeta as _ab

        a = np.atleast_1d(self.alpha)
        b = np.atleast_1d(self.beta)
        t = np.atleast_1d(self.T)
        if np.any(a >= 1):
            raise ValueError("alpha >= 1 has no Kalman-equivalent model; pass Q and R (or smoother_gain) to smooth()")
        d = _ab.analyze(a, b)
        nn = np.zeros((a.size, 2, 2))
        nn[:, 0, 0] = 1.0
        nn[:, 1, 1] = 1.0 / t
        p = nn @ d.covariance_filtered @ nn
        m = nn @ d.covariance_predicted @ nn
        return p @ np.transpose(self._phi, (0, 2, 1)) @ np.linalg.inv(m)

    def _time_smoother(self) -> Tuple[str, np.ndarray]:
        law = self._tv_law
        assert law is not None
        P = self.n_params
        rows = np.zeros((P, 5))
        if law[0] == "ab-design":
            rows[:, 1] = np.broadcast_to(law[1][:, 0], (P,))
        else:
            a = self._default_smoother_gain()  # physical, at T
            t = self._t
            rows[:, 0] = 1.0
            rows[:, 1] = a[:, 0, 0]
            rows[:, 2] = a[:, 0, 1] / t
            rows[:, 3] = a[:, 1, 0] * t
            rows[:, 4] = a[:, 1, 1]
        return "ab", rows

    def covariances(self, Q: Any = None, R: Any = None, *, sigma_w: Optional[float] = None, sigma_v: Optional[float] = None) -> "SteadyStateCovariance":
        """Theoretical steady-state covariances (see :meth:`FixedGainFilter.covariances`).

        Give ``Q`` and ``R``, or the white-acceleration model of paper 000
        through ``sigma_w`` and ``sigma_v`` (``Q = sigma_w^2 d d^T``,
        ``d = [T^2/2, T]``, ``R = sigma_v^2``).
        """
        if sigma_w is not None or sigma_v is not None:
            if sigma_w is None or sigma_v is None or Q is not None or R is not None:
                raise ValueError("give either Q and R, or sigma_w and sigma_v")
            if self.n_params != 1:
                raise ValueError("covariances() needs a filter with one parameter set")
            t = float(self._t[0])
            d = np.array([[t * t / 2], [t]])
            Q = float(sigma_w) ** 2 * (d @ d.T)
            R = [[float(sigma_v) ** 2]]
        return super().covariances(Q, R)


class AlphaBetaGammaFilter(FixedGainFilter):
    r"""The alpha-beta-gamma filter (state ``[position, velocity, acceleration]``).

    Parameters
    ----------
    alpha, beta, gamma : float or array_like of shape (n_tracks,)
        Gains in the chosen convention.
    T : float or array_like
        Sampling period.
    convention : {"standard", "chen-chui", "ghk"}
        How ``gamma`` maps to the acceleration gain (see
        :data:`ABG_CONVENTIONS`): ``gamma/(2T^2)`` (Bar-Shalom, the default),
        ``gamma/T^2`` (Chen & Chui, paper 004) or ``2 gamma/T^2`` (FilterPy's
        ``k``).
    allow_unstable : bool, optional
    """

    _kinematic = True

    def __init__(
        self,
        alpha: Any,
        beta: Any,
        gamma: Any,
        T: Any,
        *,
        convention: str = "standard",
        allow_unstable: bool = False,
        transient: Optional[str] = None,
        P0: Any = None,
        Q: Any = None,
        R: Any = None,
        x0: Any = None,
    ):
        if convention not in ABG_CONVENTIONS:
            raise ValueError(f"convention must be one of {sorted(ABG_CONVENTIONS)}, got {convention!r}")
        arrs = [as_float_array(n, v) for n, v in (("alpha", alpha), ("beta", beta), ("gamma", gamma), ("T", T))]
        for name, v in zip(("alpha", "beta", "gamma", "T"), arrs):
            if v.ndim > 1:
                raise ValueError(f"{name} must be a scalar or a 1-D array (one per track), got shape {v.shape}")
            if not np.all(np.isfinite(v)):
                raise ValueError(f"{name} must be finite")
        check_positive("T", arrs[3])
        try:
            a, b, g, t = np.broadcast_arrays(*arrs)
        except ValueError:
            raise ValueError("alpha, beta, gamma and T do not broadcast") from None
        P = a.size if a.ndim else 1
        a, b, g, t = (x.reshape(P) for x in (a, b, g, t))
        c = ABG_CONVENTIONS[convention]
        with np.errstate(over="ignore", under="ignore"):
            scale = np.maximum.reduce([t * t, np.abs(b) / t, np.abs(c * g) / (t * t)])
        check_representable("the transition and gains", scale, ("alpha", "beta", "gamma", "T"), (a, b, g, t))
        phi = np.zeros((P, 3, 3))
        phi[:, 0, 0] = phi[:, 1, 1] = phi[:, 2, 2] = 1.0
        phi[:, 0, 1] = phi[:, 1, 2] = t
        phi[:, 0, 2] = t * t / 2
        k = np.stack([a, b / t, c * g / (t * t)], axis=-1)[:, :, None]
        super().__init__(phi, np.array([[1.0, 0.0, 0.0]]), k, t, allow_unstable=True)
        self.allow_unstable = allow_unstable
        rho = np.atleast_1d(self.spectral_radius)
        if not allow_unstable and not np.all(rho < 1.0):
            i = int(np.argmax(~(rho < 1.0)))
            raise ValueError(
                f"alpha={a[i]!r}, beta={b[i]!r}, gamma={g[i]!r} ({convention!r} convention) give an unstable filter: "
                f"spectral radius of (I - K H) Phi is {float(rho[i]):.6g} >= 1; pass allow_unstable=True to run it anyway"
            )
        self.convention = convention
        self._tv_law = ("abg-fixed", np.stack([a, b, c * g], axis=-1))
        self.alpha = a[0] if P == 1 else a
        self.beta = b[0] if P == 1 else b
        self.gamma = g[0] if P == 1 else g
        self.T = t[0] if P == 1 else t
        self._set_transient(transient, P0, Q, R, x0)

    def _default_smoother_gain(self) -> np.ndarray:
        """Backward gain of the Kalman-equivalent model: for a
        :meth:`from_noise` design, that of its noise at ``h = T``, computed
        from the noise itself; for fixed gains, the noise of Chen & Chui's
        Corollary for which these gains are near-optimal
        (:func:`abkit.abg.noise_ratios`; ValueError naming the gain if there
        is none), from the gains as exact. Both in double-double (docs/abg.md,
        "Backward (smoother) gains"), physical units at ``T``."""
        from . import abg as _abg

        t = np.atleast_1d(np.asarray(self.T, dtype=float))
        law = self._tv_law
        if law is not None and law[0] == "abg-design":
            sp, sv, sa, sm = (np.ascontiguousarray(np.broadcast_to(law[1][:, i], t.shape), dtype=np.float64) for i in range(4))
            an = _abkit.abg_backward_gain_noise(sp, sv, sa, sm, np.ascontiguousarray(t))
        else:
            c = ABG_CONVENTIONS[self.convention]
            a, b, g, t = (np.atleast_1d(np.asarray(v, dtype=float)) for v in (self.alpha, self.beta, self.gamma, self.T))
            a, b, g, t = np.broadcast_arrays(a, b, g, t)
            try:
                _abg.noise_ratios(a, b, g * c, convention="chen-chui")
            except ValueError as exc:
                raise ValueError(
                    f"the gains have no Kalman-equivalent model ({exc}); pass Q and R (or smoother_gain) to smooth()"
                ) from None
            try:
                an = _abkit.abg_backward_gain(*(np.ascontiguousarray(v, dtype=np.float64).reshape(-1) for v in (a, b, g * c)))
            except np.linalg.LinAlgError as exc:
                raise ValueError(
                    f"the gains have no Kalman-equivalent model ({exc}); pass Q and R (or smoother_gain) to smooth()"
                ) from None
            t = np.ascontiguousarray(t, dtype=np.float64).reshape(-1)
        # A = D^-1 A_N D, D = diag(1, T, T^2) (x_N = D x).
        d = np.stack([np.ones_like(t), t, t * t], axis=-1)
        return np.asarray(an).reshape(-1, 3, 3) * d[:, None, :] / d[:, :, None]


    @classmethod
    def from_noise(
        cls, sigma_p: float, sigma_v: float, sigma_a: float, sigma_m: float, T: float, *, convention: str = "standard", **kw: Any
    ) -> "AlphaBetaGammaFilter":
        r"""The limiting Kalman alpha-beta-gamma filter of Chen & Chui's noise model.

        Gains from :func:`abkit.abg.from_noise` (process noise variances
        ``Q = diag(sigma_p, sigma_v, sigma_a)`` per step, measurement
        variance ``sigma_m``) at period ``T``. With timestamps ``t`` the
        filter uses, at every step, the design at ``h = dt_k``
        (``gain_schedule == "design"``; see ``docs/tracks.md``).

        Parameters
        ----------
        sigma_p, sigma_v, sigma_a : float
            Process noise variances (>= 0; ``sigma_a > 0``).
        sigma_m : float
            Measurement noise variance (> 0).
        T : float
            Nominal sampling period (> 0).
        convention : {"standard", "chen-chui", "ghk"}
            Convention of the stored gains (the filter is the same).

        Examples
        --------
        >>> from abkit import AlphaBetaGammaFilter
        >>> f = AlphaBetaGammaFilter.from_noise(0.0, 0.0, 0.1, 1.0, 1.0)
        >>> f.gain_schedule, f.convention
        ('design', 'standard')
        """
        from . import abg as _abg

        for name, v in (("sigma_p", sigma_p), ("sigma_v", sigma_v), ("sigma_a", sigma_a), ("sigma_m", sigma_m), ("T", T)):
            if np.ndim(v) != 0:
                raise ValueError(f"{name} must be a scalar")
        check_positive("T", as_float_array("T", T))
        try:
            d = _abg.from_noise(sigma_p, sigma_v, sigma_a, sigma_m, h=T, convention=convention)
            f = cls(d.alpha, d.beta, d.gamma, T, convention=convention, **kw)
        except ValueError as exc:
            if re.match(r"(sigma_[pvam]|convention) ", str(exc)):  # plain domain errors name their argument
                raise
            # the design's own message speaks of its internals (h, lam, the
            # gains); say which inputs of this call give no usable filter
            raise ValueError(
                f"sigma_p={float(sigma_p):.6g}, sigma_v={float(sigma_v):.6g}, sigma_a={float(sigma_a):.6g}, "
                f"sigma_m={float(sigma_m):.6g}, T={float(T):.6g} give no usable steady-state filter "
                f"(h is T): {exc}"
            ) from None
        f._tv_law = ("abg-design", np.array([[float(sigma_p), float(sigma_v), float(sigma_a), float(sigma_m)]]))
        return f


def _check_rate(what: str, ratio: np.ndarray, names: Tuple[str, ...], arrays: Tuple[np.ndarray, ...]) -> None:
    """ValueError (naming the inputs) unless the positive rate of a
    ``"design"`` gain schedule is finite and > 0 (not over- or underflowed):
    a filter whose timestamped design would silently be Inf/NaN or zero."""
    check_representable(what, np.where(ratio > 0, ratio, np.nan), names, arrays)


class Tracker:
    """Real-time wrapper: holds a filter's state between chunks.

    Parameters
    ----------
    filt : FixedGainFilter
        The filter (any abkit filter).
    n_tracks : int, optional
        Number of tracks of every chunk. Given, the first chunk must have
        that many (a ``ValueError`` naming ``z_chunk`` otherwise); None
        (default): taken from the first chunk. Later chunks must match the
        first (the state is per track).
    init : {"two-point", "first"} or array_like, optional
        Start of the tracks (as in :meth:`FixedGainFilter.run`).

    Attributes
    ----------
    state : FilterState or None
        The tracks' state after the last chunk (None before the first).
    n_tracks : int or None
        Tracks per chunk (None until the first chunk if not given).
    samples : int
        Samples per track filtered so far.

    Examples
    --------
    >>> import numpy as np
    >>> from abkit import AlphaBetaFilter, Tracker
    >>> trk = Tracker(AlphaBetaFilter(0.5, 0.2, 1.0))
    >>> a = trk.update([0.0, 1.0, 2.0])
    >>> b = trk.update([3.0, 4.0])
    >>> b.position.shape
    (2,)
    >>> trk.update(5.0).position.shape  # one number: one sample
    (1,)
    """

    def __init__(self, filt: FixedGainFilter, n_tracks: Optional[int] = None, init: Any = "two-point"):
        if not isinstance(filt, FixedGainFilter):
            raise TypeError("filt must be an abkit filter")
        if n_tracks is not None and (not isinstance(n_tracks, (int, np.integer)) or isinstance(n_tracks, bool) or n_tracks < 1):
            raise ValueError(f"n_tracks must be a positive integer or None, got {n_tracks!r}")
        self.filter = filt
        self.init = init
        self._n_given = None if n_tracks is None else int(n_tracks)
        self.n_tracks: Optional[int] = self._n_given
        self.state: Optional[FilterState] = None
        self.samples = 0

    def update(self, z_chunk: Any, **kw: Any) -> FilterResult:
        """Filter the next chunk (same layout as ``run``) and keep the state.

        A single number (or 0-d array) is one sample of a one-track tracker
        with scalar measurements."""
        z = np.asarray(z_chunk) if not isinstance(z_chunk, np.ndarray) else z_chunk
        if z.dtype.kind in "iub":
            z = z.astype(np.float64)
        if z.ndim == 0 and self.n_tracks in (None, 1) and self.filter.m == 1:
            z = z.reshape(1)
        try:
            res = self.filter.run(z, init=self.init, state=self.state, **kw)
        except (ValueError, TypeError) as exc:  # name the argument as the caller spelled it
            msg = str(exc)
            if msg.startswith("z "):
                raise type(exc)("z_chunk" + msg[1:]) from None
            raise
        got = res.state.n_tracks // (res.state.axes or 1)
        if self.state is None:
            if self.n_tracks is not None and got != self.n_tracks:
                raise ValueError(f"z_chunk has {got} track{'s' if got != 1 else ''}; this tracker was made "
                                 f"with n_tracks={self.n_tracks}")
            self.n_tracks = got
        self.state = res.state
        self.samples += res.states.shape[-1] if res.state.axes is None else res.states.shape[-2]
        return res

    def reset(self) -> None:
        """Forget the state (the next chunk starts new tracks, as many as
        ``n_tracks`` was given, else any number)."""
        self.state = None
        self.samples = 0
        self.n_tracks = self._n_given


class SteadyStateCovariance:
    """Theoretical steady-state error covariances of a fixed-gain filter.

    Attributes
    ----------
    predicted : ndarray (n, n)
        One-step prediction error covariance ``M``.
    filtered : ndarray (n, n)
        Filtered error covariance ``P``.
    smoothed : ndarray (n, n) or None
        Steady-state fixed-interval (RTS) smoother covariance with the
        constant backward gain ``A = P Phi^T M^-1`` (paper 001 eq (22));
        exact when the filter's gain is the Kalman gain of (Q, R). ``None``
        when no steady state exists (the backward gain is not contracting,
        e.g. ``Q = 0``, where ``A = Phi^-1``).
    smoother_gain : ndarray (n, n) or None
    """

    __slots__ = ("predicted", "filtered", "smoothed", "smoother_gain")

    def __init__(self, predicted: np.ndarray, filtered: np.ndarray, smoothed: Optional[np.ndarray], smoother_gain: Optional[np.ndarray]):
        self.predicted = predicted
        self.filtered = filtered
        self.smoothed = smoothed
        self.smoother_gain = smoother_gain

    def __repr__(self) -> str:
        return f"SteadyStateCovariance(filtered=\n{self.filtered},\npredicted=\n{self.predicted})"


def _dlyap(a: np.ndarray, q: np.ndarray, check: bool = True) -> np.ndarray:
    """Solve X = A X A^T + Q for small n (Kronecker form)."""
    n = a.shape[0]
    lhs = np.eye(n * n) - np.kron(a, a)
    x = np.linalg.solve(lhs, q.reshape(-1)).reshape(n, n)
    if check:  # a second solve on perturbed data estimates the conditioning
        from .riccati import _perturbed

        ap, qp = _perturbed((a, q))
        xp = _dlyap(ap, qp, check=False)
        warn_accuracy(
            "covariances", float(perturbation_estimate(x, xp)),
            f"loop spectral radius {float(np.max(np.abs(np.linalg.eigvals(a)))):.15g}: the Lyapunov equation is ill-conditioned",
            stacklevel=4,
        )
    return 0.5 * (x + x.T)


def _steady_covariance(phi: np.ndarray, h: np.ndarray, k: np.ndarray, q: np.ndarray, r: np.ndarray) -> SteadyStateCovariance:
    n = phi.shape[0]
    ikh = np.eye(n) - k @ h
    a = phi @ ikh  # predicted-error transition
    if np.max(np.abs(np.linalg.eigvals(a))) >= 1:
        raise ValueError("the filter is unstable: no steady-state covariance exists")
    # M = Phi [(I-KH) M (I-KH)^T + K R K^T] Phi^T + Q
    m = _dlyap(a, phi @ k @ r @ k.T @ phi.T + q)
    p = ikh @ m @ ikh.T + k @ r @ k.T
    p = 0.5 * (p + p.T)
    smoothed = gain = None
    try:
        gain = p @ phi.T @ np.linalg.inv(m)
        # P_s = P + A (P_s - M) A^T  <=>  P_s = A P_s A^T + (P - A M A^T);
        # a steady state exists only if the backward gain is contracting
        # (it is not, e.g., without process noise: A = Phi^-1).
        if np.max(np.abs(np.linalg.eigvals(gain))) < 1.0 - 1e-9:
            smoothed = _dlyap(gain, p - gain @ m @ gain.T)
    except np.linalg.LinAlgError:
        pass
    return SteadyStateCovariance(m, p, smoothed, gain)
