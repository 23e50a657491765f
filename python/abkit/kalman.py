r"""The discrete Kalman filter recursion (Brown, paper 002).

Model: ``x_{k+1} = F x_k + w_k`` (``cov w = Q``), ``z_k = H x_k + v_k``
(``cov v = R``), prior ``x_0^- = x0`` with covariance ``P0``. The loop of the
paper's Fig. 5, for ``k = 0, 1, ...``:

.. code-block:: text

    K_k = P_k^- H^T (H P_k^- H^T + R)^-1               compute the gain
    x_k = x_k^- + K_k (z_k - H x_k^-)                   update the estimate
    P_k = (I - K_k H) P_k^- (I - K_k H)^T + K_k R K_k^T  update the covariance (Joseph form)
    x_{k+1}^- = F x_k,  P_{k+1}^- = F P_k F^T + Q       project ahead

A NaN measurement is a missed sample: no gain, no update (``P_k = P_k^-``).

Batched like the fixed-gain engine: when the tracks have no missed samples
the gain sequence does not depend on the data, so it is computed once and
applied to every track; once it has converged to the last bit the limiting
gain is used. Tracks with missed samples run their own covariance
recursion, in Rust.

Examples
--------
The paper's two examples. Random constant (``P0 = 4``, ``R = 0.25``):

>>> from abkit import kalman
>>> g = kalman.gain_sequence(1.0, 1.0, 0.0, 0.25, 4.0, 3)
>>> float(g.K[0, 0, 0]) == 16 / 17
True

Wiener process (``P0 = 0``, ``Q = 1``, ``R = 0.25``):

>>> g = kalman.gain_sequence(1.0, 1.0, 1.0, 0.25, 0.0, 3)
>>> float(g.K[0, 0, 0]), round(float(g.K[1, 0, 0]), 15)
(0.0, 0.8)
"""

from __future__ import annotations

from typing import Any, NamedTuple, Optional, Tuple

import numpy as np

from . import _abkit
from ._validate import aligned_state, as_float_array, as_matrix, check_tracks_finite
from .filters import fresh_output, planes_layout_ok, planes_view, prepare_z

__all__ = ["KalmanFilter", "KalmanResult", "GainSequence", "gain_sequence"]


class GainSequence(NamedTuple):
    """Gains and covariances of the first ``n`` steps.

    ``K`` (n, n_x, n_z): filter-form gains ``K_k``; ``P_prior`` and ``P_post``
    (n, n_x, n_x): ``P_k^-`` and ``P_k``.
    """

    K: np.ndarray
    P_prior: np.ndarray
    P_post: np.ndarray


def _matrix(name: str, value: Any, shape: Tuple[int, int], *, symmetric: bool = False, psd: bool = False, pd: bool = False) -> np.ndarray:
    return as_matrix(name, value, shape, symmetric=symmetric, psd=psd, pd=pd)


def _model(F: Any, H: Any, Q: Any, R: Any, P0: Any) -> Tuple[int, int, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    f = as_float_array("F", F)
    if f.ndim == 0:
        f = f.reshape(1, 1)
    if f.ndim != 2 or f.shape[0] != f.shape[1] or not 1 <= f.shape[0] <= 6:
        raise ValueError(f"F must be a square matrix with 1..6 rows, got shape {f.shape}")
    n = f.shape[0]
    h = as_float_array("H", H)
    if h.ndim == 0:
        h = h.reshape(1, 1)
    if h.ndim == 1:
        h = h.reshape(1, -1)
    if h.ndim != 2 or h.shape[1] != n or h.shape[0] not in (1, 2):
        raise ValueError(f"H must have shape (m, {n}) with m in (1, 2), got {h.shape}")
    m = h.shape[0]
    f = _matrix("F", f, (n, n))
    h = _matrix("H", h, (m, n))
    q = _matrix("Q", Q, (n, n), symmetric=True, psd=True)
    r = _matrix("R", R, (m, m), symmetric=True, pd=True)
    p0 = _matrix("P0", P0, (n, n), symmetric=True, psd=True)
    return n, m, f, h, q, r, p0


def gain_sequence(F: Any, H: Any, Q: Any, R: Any, P0: Any, n: int) -> GainSequence:
    """The data-independent gain and covariance sequence of the first ``n`` steps.

    Parameters
    ----------
    F, H, Q, R : array_like
        Model matrices (scalars allowed for one-state models).
    P0 : array_like
        Prior covariance of the state at step 0.
    n : int
        Number of steps.

    Returns
    -------
    GainSequence

    Notes
    -----
    As ``n`` grows, ``K_k`` converges to the limiting (steady-state) gain of the
    discrete algebraic Riccati equation (paper 004, Lemma 1) when the model is
    stabilisable and detectable; with ``Q = 0`` and a large ``P0`` the filter
    is the recursive average of paper 002, section 3 (``K_k -> 1/(k+1)``).
    """
    if not isinstance(n, (int, np.integer)) or isinstance(n, bool) or n < 0:
        raise ValueError(f"n must be a non-negative integer, got {n!r}")
    nx, nz, f, h, q, r, p0 = _model(F, H, Q, R, P0)
    k, pri, post = _abkit.kalman_gain_sequence(nx, nz, f.reshape(-1), h.reshape(-1), q.reshape(-1), r.reshape(-1), p0.reshape(-1), int(n))
    return GainSequence(np.asarray(k).reshape(n, nx, nz), np.asarray(pri).reshape(n, nx, nx), np.asarray(post).reshape(n, nx, nx))


class KalmanResult:
    """Output of :meth:`KalmanFilter.run`: ``states`` (n, *sample_shape),
    ``position``/``velocity`` views, optional ``residuals`` (``z - H x^-``) and
    ``P_final`` (each track's last filtered covariance)."""

    __slots__ = ("states", "residuals", "P_final")

    def __init__(self, states: np.ndarray, residuals: Optional[np.ndarray], P_final: np.ndarray):
        self.states = states
        self.residuals = residuals
        self.P_final = P_final

    @property
    def position(self) -> np.ndarray:
        return self.states[0]

    @property
    def velocity(self) -> np.ndarray:
        return self.states[1]


class KalmanFilter:
    r"""The time-varying Kalman filter, batched over tracks.

    Parameters
    ----------
    F, H, Q, R : array_like
        Model: ``F`` (n, n) with ``1 <= n <= 6``, ``H`` (m, n) with ``m`` in
        {1, 2}, ``Q`` (n, n) symmetric PSD, ``R`` (m, m) symmetric PD.
    x0 : array_like, optional
        Prior state at step 0, ``(n,)`` or ``(n_tracks, n)``; default zeros.
    P0 : array_like
        Prior covariance at step 0 (symmetric PSD).

    Examples
    --------
    A random constant measured with noise: the estimate is the running mean.

    >>> import numpy as np
    >>> from abkit.kalman import KalmanFilter
    >>> kf = KalmanFilter(1.0, 1.0, 0.0, 1.0, x0=[0.0], P0=1e12)
    >>> z = np.array([1.0, 2.0, 3.0, 4.0])
    >>> np.round(kf.run(z).position, 9).tolist()
    [1.0, 1.5, 2.0, 2.5]
    """

    def __init__(self, F: Any, H: Any, Q: Any, R: Any, x0: Any = None, P0: Any = None):
        if P0 is None:
            raise ValueError("P0 must be given (the prior covariance of the state at step 0)")
        self.n, self.m, self.F, self.H, self.Q, self.R, self.P0 = _model(F, H, Q, R, P0)
        if x0 is None:
            x = np.zeros((1, self.n))
        else:
            x = as_float_array("x0", x0)
            if x.ndim == 1:
                x = x[None]
            if x.ndim != 2 or x.shape[1] != self.n or not np.all(np.isfinite(x)):
                raise ValueError(f"x0 must be finite with shape ({self.n},) or (n_tracks, {self.n}), got {np.shape(x0)}")
        self.x0 = np.ascontiguousarray(x, dtype=np.float64)

    def __setstate__(self, state: dict) -> None:
        # unpickling (e.g. on a dask worker): arrays aligned for the kernels
        self.__dict__.update(aligned_state(state))

    def gain_sequence(self, n: int) -> GainSequence:
        """:func:`gain_sequence` of this filter's model."""
        return gain_sequence(self.F, self.H, self.Q, self.R, self.P0, n)

    def run(self, z: Any, *, out: Optional[np.ndarray] = None, return_residuals: bool = False, threads: Optional[int] = None) -> KalmanResult:
        """Filter measurements (same layouts, dtypes and NaN rule as the
        fixed-gain filters' ``run``)."""
        if threads is not None and (not isinstance(threads, (int, np.integer)) or isinstance(threads, bool) or threads < 1):
            raise ValueError(f"threads must be a positive integer or None, got {threads!r}")
        z3, (n_tracks, n_samples), single = prepare_z(z, self.m)
        if self.x0.shape[0] not in (1, n_tracks):
            raise ValueError(f"x0 has {self.x0.shape[0]} rows but z has {n_tracks} tracks")
        shape = (n_samples,) if single else (n_tracks, n_samples)
        want = (self.n,) + shape
        if out is None:
            o = fresh_output(want, z3.dtype, threads)
        else:
            if not isinstance(out, np.ndarray) or out.shape != want or out.dtype != z3.dtype:
                raise ValueError(f"out must be an array of shape {want} and dtype {z3.dtype}")
            if not planes_layout_ok(out) or not out.flags.writeable or np.shares_memory(out, z3):
                raise ValueError("out must be writeable, not overlap z, and C-contiguous or in the layout of abkit.empty_states")
            o = out
        res3 = np.empty((n_tracks, n_samples, self.m), dtype=z3.dtype) if return_residuals else None
        pf = np.empty((n_tracks, self.n, self.n))
        _abkit.kalman_run(
            z3, self.n, self.m, self.F.reshape(-1), self.H.reshape(-1), self.Q.reshape(-1), self.R.reshape(-1),
            self.x0.reshape(-1), self.P0.reshape(-1), planes_view(o, (self.n, n_tracks, n_samples)), pf, res3,
            None if threads is None else int(threads),
        )
        if n_samples:
            check_tracks_finite("z", z3, o.reshape((self.n, n_tracks, n_samples))[:, :, -1].T, np.ones(n_tracks, dtype=bool))
        residuals = None
        if res3 is not None:
            residuals = res3.reshape(shape + ((self.m,) if self.m > 1 else ()))
        return KalmanResult(o, residuals, pf[0] if single else pf)
