"""Argument validation shared by every public function.

Messages always name the argument, say what is allowed, and show the
offending value (and its index for arrays).
"""

from __future__ import annotations

from typing import Any, Optional, Sequence, Tuple

import numpy as np

__all__ = [
    "as_float_array",
    "as_matrix",
    "broadcast",
    "check_positive",
    "check_open_interval",
    "check_shape",
    "check_symmetric",
    "check_representable",
    "broadcast_shape",
    "check_tracks_finite",
    "aligned_state",
]


def as_float_array(name: str, value: Any) -> np.ndarray:
    """Convert ``value`` to a float64 array, rejecting non-real input.

    Raises
    ------
    TypeError
        If ``value`` is not a real number or an array of real numbers
        (bool, integer and floating dtypes are accepted; complex, object,
        string and datetime are not).
    """
    if isinstance(value, (str, bytes)):
        raise TypeError(f"{name} must be a real number or array of real numbers, got {type(value).__name__}")
    try:
        arr = np.asarray(value)
    except Exception as exc:  # pragma: no cover - numpy raises for ragged input
        raise TypeError(f"{name} must be a real number or array of real numbers: {exc}") from None
    if arr.dtype.kind not in "biuf":
        raise TypeError(
            f"{name} must be a real number or array of real numbers "
            f"(bool, integer or float dtype), got dtype {arr.dtype}"
        )
    return arr.astype(np.float64, copy=False)


def _where(arr: np.ndarray, bad: np.ndarray) -> str:
    if arr.ndim == 0:
        return f"got {arr.item()!r}"
    idx = tuple(int(i) for i in np.argwhere(bad)[0])
    n = int(bad.sum())
    more = f" (and {n - 1} more)" if n > 1 else ""
    return f"got {arr[idx]!r} at index {idx}{more}"


def check_positive(name: str, arr: np.ndarray) -> None:
    """Raise ``ValueError`` unless every element is finite and > 0."""
    bad = ~(np.isfinite(arr) & (arr > 0))
    if bad.any():
        raise ValueError(f"{name} must be finite and > 0, {_where(arr, bad)}")


def check_nonnegative(name: str, arr: np.ndarray) -> None:
    """Raise ``ValueError`` unless every element is finite and >= 0."""
    bad = ~(np.isfinite(arr) & (arr >= 0))
    if bad.any():
        raise ValueError(f"{name} must be finite and >= 0, {_where(arr, bad)}")


def check_open_interval(name: str, arr: np.ndarray, lo: float, hi: float) -> None:
    """Raise ``ValueError`` unless ``lo < arr < hi`` element-wise."""
    bad = ~((arr > lo) & (arr < hi))
    if bad.any():
        raise ValueError(f"{name} must be in the open interval ({lo:g}, {hi:g}), {_where(arr, bad)}")


def broadcast(names: Sequence[str], arrays: Sequence[np.ndarray]) -> Tuple[Tuple[int, ...], list]:
    """Broadcast ``arrays`` together; return the shape and flat contiguous copies.

    Raises
    ------
    ValueError
        If the shapes do not broadcast; the message lists every argument's shape.
    """
    try:
        b = np.broadcast_arrays(*arrays)
    except ValueError:
        shapes = ", ".join(f"{n} {a.shape}" for n, a in zip(names, arrays))
        raise ValueError(f"arguments do not broadcast together: {shapes}") from None
    shape = b[0].shape if b else ()
    return shape, [np.ascontiguousarray(x, dtype=np.float64).reshape(-1) for x in b]


def as_matrix(
    name: str,
    value: Any,
    shape: Optional[Tuple[int, int]] = None,
    *,
    symmetric: bool = False,
    psd: bool = False,
    pd: bool = False,
) -> np.ndarray:
    """A real, finite 2-D float64 matrix (C-contiguous): the one matrix check
    of every entry point.

    Without ``shape``: scalars become 1x1, other ranks and empty matrices are
    rejected. With ``shape``: scalars (for 1x1) and vectors (for one row)
    are reshaped, any other shape is rejected. ``symmetric``, ``psd``,
    ``pd`` add those checks (relative tolerances ``1e-12``).

    Raises ``TypeError`` for non-real input, ``ValueError`` (naming
    ``name``) for the wrong rank or shape, an empty matrix, NaN/Inf entries,
    asymmetry or a negative (non-positive for ``pd``) eigenvalue.
    """
    arr = as_float_array(name, value)
    if shape is None:
        if arr.ndim == 0:
            arr = arr.reshape(1, 1)
        if arr.ndim != 2:
            raise ValueError(f"{name} must be a 2-D matrix, got an array of shape {arr.shape}")
        if arr.size == 0:
            raise ValueError(f"{name} must not be empty (n = 0), got shape {arr.shape}")
    else:
        if arr.ndim < 2 and shape == (1, 1) and arr.size == 1:
            arr = arr.reshape(1, 1)
        if arr.ndim == 1 and shape[0] == 1:
            arr = arr.reshape(1, -1)
        if arr.shape != tuple(shape):
            raise ValueError(f"{name} must have shape {tuple(shape)}, got {arr.shape}")
    bad = ~np.isfinite(arr)
    if bad.any():
        raise ValueError(f"{name} must be finite (no NaN or Inf entries), {_where(arr, bad)}")
    if symmetric and not np.allclose(arr, arr.T, rtol=1e-12, atol=1e-14 * max(1.0, float(np.max(np.abs(arr))))):
        raise ValueError(f"{name} must be symmetric, got max |{name} - {name}.T| = {float(np.max(np.abs(arr - arr.T))):.3g}")
    if psd or pd:
        w = np.linalg.eigvalsh(0.5 * (arr + arr.T))
        tol = 1e-12 * max(1.0, float(np.max(np.abs(w))))
        if pd and not np.all(w > 0):
            raise ValueError(f"{name} must be positive definite (smallest eigenvalue {float(w.min()):.3g})")
        if psd and np.any(w < -tol):
            raise ValueError(f"{name} must be positive semi-definite (smallest eigenvalue {float(w.min()):.3g})")
    return np.ascontiguousarray(arr, dtype=np.float64)


def check_shape(name: str, arr: np.ndarray, shape: Tuple[int, int]) -> None:
    """Raise ``ValueError`` unless ``arr.shape == shape``."""
    if arr.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {arr.shape}")


def check_symmetric(name: str, arr: np.ndarray, rtol: float = 1e-10) -> None:
    """Raise ``ValueError`` unless ``arr`` is symmetric to ``rtol`` of its largest entry."""
    asym = float(np.max(np.abs(arr - arr.T))) if arr.size else 0.0
    if asym > rtol * float(np.max(np.abs(arr))):
        raise ValueError(f"{name} must be symmetric, got max |{name} - {name}.T| = {asym:.3g}")


def broadcast_shape(names: Sequence[str], arrays: Sequence[np.ndarray]) -> Tuple[int, ...]:
    """The broadcast shape of ``arrays``; ``ValueError`` listing every argument's shape if none."""
    try:
        return tuple(np.broadcast_shapes(*(a.shape for a in arrays)))
    except ValueError:
        shapes = ", ".join(f"{n} {a.shape}" for n, a in zip(names, arrays))
        raise ValueError(f"arguments do not broadcast together: {shapes}") from None


def check_representable(what: str, result: np.ndarray, names: Sequence[str], arrays: Sequence[np.ndarray]) -> None:
    """Raise ``ValueError`` if ``result`` (computed from finite inputs) has
    non-finite entries: the inputs are at scales where float64 overflows or
    underflows. The message names the inputs and their values at the first
    bad element (``result`` has the broadcast shape of the inputs in front)."""
    bad = ~np.isfinite(result)
    if not bad.any():
        return
    idx = tuple(int(i) for i in np.argwhere(bad)[0])
    vals = []
    for n, a in zip(names, arrays):
        a = np.asarray(a, dtype=np.float64)
        try:
            v = float(np.broadcast_to(a, result.shape)[idx])
        except ValueError:
            v = float(a.reshape(-1)[0]) if a.size else float("nan")
        vals.append(f"{n}={v:.6g}")
    raise ValueError(
        f"{what} is not representable in float64 (overflow or underflow) for {', '.join(vals)}"
        f"{'' if result.ndim == 0 else f' (at index {idx})'}; rescale the inputs"
    )


def check_tracks_finite(name: str, z3: np.ndarray, x: np.ndarray, started: np.ndarray) -> None:
    """After filtering: raise ``ValueError`` if a started track's final
    estimate ``x[i]`` is not finite. NaN measurements are missed detections
    and never reach the estimates, so the cause is a ``±Inf`` measurement
    (named with its track and sample) or values so large that the
    recursion overflowed float64. ``z3`` is ``(n_tracks, n_samples, m)``;
    O(n_tracks) unless a track is bad."""
    bad = started & ~np.all(np.isfinite(x), axis=-1)
    if not bad.any():
        return
    i = int(np.argmax(bad))
    inf = np.argwhere(np.isinf(z3[i]))
    if inf.size:
        k = int(inf[0][0])
        val = z3[i][tuple(inf[0])]
        raise ValueError(f"{name} must be finite or NaN (a missed detection), got {val!r} at track {i}, sample {k}")
    big = float(np.nanmax(np.abs(z3[i]))) if z3[i].size else float("nan")
    raise ValueError(
        f"the estimates of track {i} overflowed float64: {name} values up to {big:.3g} are too large "
        f"for this filter; rescale {name}"
    )
def aligned_state(state: dict) -> dict:
    """An object's pickled ``__dict__`` with every array C-contiguous and
    aligned (``__setstate__`` helper): arrays rebuilt from out-of-band pickle
    buffers, as dask.distributed sends them, may be misaligned, and the Rust
    bindings take aligned contiguous arrays only."""
    return {k: np.require(v, requirements=("C", "A")) if isinstance(v, np.ndarray) else v for k, v in state.items()}
