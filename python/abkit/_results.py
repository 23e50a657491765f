"""Shared machinery of the array-backed result types (``AlphaBeta``,
``ABG``): Rust returns one row of named float64 fields per element; the
result keeps the rows and hands fields out in the broadcast input shape.
Also the one place that restates a Rust element index in that shape."""

from __future__ import annotations

import re
from typing import Any, ClassVar, Dict, Tuple, Union

import numpy as np

FloatOrArray = Union[float, np.ndarray]

_FLAT_INDEX = re.compile(r" \(at flat index (\d+)\)$")


def out_value(x: np.ndarray) -> FloatOrArray:
    """A 0-d array as a Python float, anything else unchanged."""
    return x.item() if x.ndim == 0 else x


def call_binding(func: Any, shape: Tuple[int, ...], *flat: Any) -> np.ndarray:
    """Call a Rust binding on flattened inputs; an error naming a flat element
    index is re-raised (same type) naming the index in ``shape``."""
    try:
        return np.asarray(func(*flat))
    except (ValueError, np.linalg.LinAlgError) as exc:
        msg = str(exc)
        m = _FLAT_INDEX.search(msg)
        if m is None:
            raise
        where = "" if shape == () else f" (at index {tuple(int(i) for i in np.unravel_index(int(m.group(1)), shape))})"
        raise type(exc)(msg[: m.start()] + where) from None


class RowResult:
    """Base of results stored as Rust rows: ``rows`` is ``(n, n_fields)`` in
    the order of the class's ``_IDX`` (field name -> column)."""

    __slots__ = ("_rows", "_shape")
    _IDX: ClassVar[Dict[str, int]] = {}

    def __init__(self, rows: np.ndarray, shape: Tuple[int, ...]):
        self._rows = rows
        self._shape = shape

    def _raw(self, name: str) -> np.ndarray:
        return self._rows[:, self._IDX[name]].reshape(self._shape)

    def _get(self, name: str) -> FloatOrArray:
        return out_value(self._raw(name).copy())

    def _flag(self, name: str) -> Union[bool, np.ndarray]:
        x = self._raw(name) != 0.0
        return bool(x) if x.ndim == 0 else x

    @property
    def shape(self) -> Tuple[int, ...]:
        """Broadcast shape of the inputs (``()`` for scalars)."""
        return self._shape
