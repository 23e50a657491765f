"""Independent plain-Python reference for irregular / ragged tracks.

Nothing here imports abkit. One track, scalar position measurement,
kinematic state ``[position, velocity, ...]``, float64, one sample at a time,
following the documented semantics (``docs/tracks.md``):

* with timestamps, a sample whose timestamp is not after the last kept one is
  an error, or dropped (NaN output, state untouched);
* ``dt = t_k - t_last``; a started track restarts (counted) when
  ``dt > max_gap``;
* start-up: ``"first"``: state ``[z, 0, ...]``; ``"two-point"``: hold ``z1``
  (velocity NaN) until the next valid ``z2``, then ``[z2, (z2 - z1) /
  (t2 - t1), 0, ...]``;
* running: ``x_p = Phi(dt) x``, ``e = z - x_p[0]``, ``x = x_p + K(dt) e`` or
  ``x = x_p`` for a NaN ``z``.

``law(dt)`` returns ``(Phi, K)`` as NumPy arrays.
"""

from __future__ import annotations

import math
from typing import Callable, Optional, Tuple

import numpy as np


def cv_phi(dt: float) -> np.ndarray:
    return np.array([[1.0, dt], [0.0, 1.0]])


def ca_phi(dt: float) -> np.ndarray:
    return np.array([[1.0, dt, dt * dt / 2], [0.0, 1.0, dt], [0.0, 0.0, 1.0]])


class TrackError(Exception):
    def __init__(self, sample: int):
        super().__init__(sample)
        self.sample = sample


def run_track(
    z: np.ndarray,
    t: Optional[np.ndarray],
    law: Callable[[float], Tuple[np.ndarray, np.ndarray]],
    n: int,
    *,
    init: str = "two-point",
    max_gap: Optional[float] = None,
    drop: bool = False,
    T: float = 1.0,
):
    """Returns (states (n, len), residuals (len,), n_dropped, n_restarts)."""
    L = len(z)
    out = np.full((n, L), np.nan)
    res = np.full(L, np.nan)
    x = np.zeros(n)
    phase = 0
    t_last = None
    held = held_t = None
    since = 0
    dropped = restarts = 0
    for k in range(L):
        zk = float(z[k])
        valid = not math.isnan(zk)
        dt = T
        tk = None
        if t is not None:
            tk = float(t[k])
            if math.isnan(tk):
                raise TrackError(k)
            if t_last is not None:
                if not tk > t_last:
                    if drop:
                        dropped += 1
                        continue
                    raise TrackError(k)
                dt = tk - t_last
                if max_gap is not None and dt > max_gap and phase > 0:
                    phase = 0
                    restarts += 1
            t_last = tk
        if phase == 2:
            phi, K = law(dt)
            xp = phi @ x
            e = zk - xp[0]
            x = xp + K * e if valid else xp
            out[:, k] = x
            if valid:
                res[k] = e
        elif phase == 0:
            if valid:
                if init == "first":
                    x = np.zeros(n)
                    x[0] = zk
                    phase = 2
                    out[:, k] = x
                else:
                    phase, held, held_t, since = 1, zk, tk, 0
                    out[0, k] = zk
        else:
            if not valid:
                since += 1
                out[0, k] = held
            else:
                gap = (tk - held_t) if t is not None else (since + 1) * T
                x = np.zeros(n)
                x[0] = zk
                x[1] = (zk - held) / gap
                phase = 2
                out[:, k] = x
    return out, res, dropped, restarts
