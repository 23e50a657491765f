r"""The discrete algebraic Riccati equation and the steady-state Kalman filter.

:func:`solve_dare` solves, with the meaning of
``scipy.linalg.solve_discrete_are(a, b, q, r, s=s)``,

.. math::

    A^T X A - X - (A^T X B + S)(R + B^T X B)^{-1}(B^T X A + S^T) + Q = 0

for its stabilising solution, and :func:`kalman_steady_state` gives the
steady-state Kalman filter of ``x[k+1] = F x[k] + w``, ``z = H x + v``
(prediction covariance, filter-form and predictor-form gains, filtered
covariance).

Differences from scipy
----------------------
* Every returned ``X`` has been checked: its relative residual is below
  ``1e-8`` and the closed loop ``A - B K`` has spectral radius below 1.
  Where no stabilising solution exists -- e.g. a mode on the unit circle
  that ``Q`` does not weight, for which scipy silently returns a
  non-stabilising ``X`` -- :class:`numpy.linalg.LinAlgError` is raised.
* ``R`` may be singular as long as ``R + B^T X B`` is not.
* Real matrices only (complex input raises ``TypeError``).

Algorithm
---------
The structure-preserving doubling algorithm (SDA) of Chu, Fan & Lin, in
Rust, O(n^3) per step with quadratic convergence; a singular ``R`` is
handled by an exact shift ``X = c I + Z``. See ``rust/abkit-core/src/riccati.rs``.

References
----------
.. [1] E. K.-W. Chu, H.-Y. Fan, W.-W. Lin, "A structure-preserving doubling
   algorithm for discrete-time algebraic Riccati equations", Linear
   Algebra Appl. 396, 55-80, 2005.
.. [2] P. Benner, A. J. Laub, V. Mehrmann, "A collection of benchmark
   examples for the numerical solution of algebraic Riccati equations II:
   discrete-time case", Tech. Rep. SPC 95_23, TU Chemnitz, 1995.
"""

from __future__ import annotations

from typing import Any, NamedTuple, Optional

import numpy as np

from . import _abkit
from ._errors import PERTURBATION, perturbation_estimate, warn_accuracy
from ._validate import as_matrix, check_shape, check_symmetric

__all__ = ["DareSolution", "KalmanSteadyState", "solve_dare", "solve_dare_info", "kalman_steady_state"]

ArrayLike = Any


class DareSolution(NamedTuple):
    """A checked stabilising DARE solution.

    Attributes
    ----------
    X : ndarray, shape (n, n)
        The stabilising solution (symmetric).
    K : ndarray, shape (m, n)
        ``(R + B^T X B)^{-1} (B^T X A + S^T)``; ``A - B K`` is stable.
    spectral_radius : float
        Spectral radius of ``A - B K`` (< 1).
    residual : float
        Relative residual ``||res||_F / (||A^T X A||_F + ||X||_F + ||Q||_F + ||(A^T X B + S) K||_F)``.
    iterations : int
        Doubling steps taken.
    """

    X: np.ndarray
    K: np.ndarray
    spectral_radius: float
    residual: float
    iterations: int


class KalmanSteadyState(NamedTuple):
    """Steady-state Kalman filter of ``x[k+1] = F x[k] + w``, ``z[k] = H x[k] + v``.

    Attributes
    ----------
    P_pred : ndarray, shape (n, n)
        Prediction (a priori) error covariance, the DARE solution.
    K : ndarray, shape (n, p)
        Filter-form gain ``P_pred H^T (H P_pred H^T + R)^{-1}``: the update is
        ``x_filt = x_pred + K (z - H x_pred)``.
    K_pred : ndarray, shape (n, p)
        Predictor-form gain ``F K`` (what ``python-control``'s ``dlqe``-style
        predictor and MATLAB's ``kalman`` call ``L``): the one-step predictor is
        ``x_pred[k+1] = F x_pred[k] + K_pred (z[k] - H x_pred[k])``.
    P_filt : ndarray, shape (n, n)
        Filtered (a posteriori) covariance, Joseph form
        ``(I - K H) P_pred (I - K H)^T + K R K^T``.
    S : ndarray, shape (p, p)
        Innovation covariance ``H P_pred H^T + R``.
    spectral_radius : float
        Spectral radius of the predictor ``F - K_pred H`` (< 1).
    """

    P_pred: np.ndarray
    K: np.ndarray
    K_pred: np.ndarray
    P_filt: np.ndarray
    S: np.ndarray
    spectral_radius: float


def _square_and_coupling(
    names: tuple, A: ArrayLike, B: ArrayLike, Q: ArrayLike, R: ArrayLike, b_is_input: bool
) -> tuple:
    """Validate (A, B, Q, R) of a DARE (``b_is_input``: B is n x m) or
    (F, H, Q, R) of a Kalman filter (H is p x n), naming each argument."""
    na, nb, nq, nr = names
    a = as_matrix(na, A)
    n = a.shape[0]
    check_shape(na, a, (n, n))
    b = as_matrix(nb, B)
    if b_is_input and b.shape[0] != n:
        raise ValueError(f"{nb} must have {n} rows ({na} is {n}x{n}), got shape {b.shape}")
    if not b_is_input and b.shape[1] != n:
        raise ValueError(f"{nb} must have {n} columns ({na} is {n}x{n}), got shape {b.shape}")
    m = b.shape[1] if b_is_input else b.shape[0]
    q = as_matrix(nq, Q)
    check_shape(nq, q, (n, n))
    r = as_matrix(nr, R)
    if r.shape != (m, m):
        raise ValueError(f"{nr} must have shape ({m}, {m}) to match {nb} of shape {b.shape}, got {r.shape}")
    check_symmetric(nq, q)
    check_symmetric(nr, r)
    return a, b, q, r


def _dare_args(A: ArrayLike, B: ArrayLike, Q: ArrayLike, R: ArrayLike, S: Optional[ArrayLike]) -> tuple:
    a, b, q, r = _square_and_coupling(("A", "B", "Q", "R"), A, B, Q, R, True)
    s = None
    if S is not None:
        s = as_matrix("S", S)
        check_shape("S", s, b.shape)
    return a, b, q, r, s


def _perturbed(args: tuple, seed: int = 8) -> list:
    """The arguments times ``1 + PERTURBATION * (random signs)``, symmetric
    matrices kept symmetric (deterministic)."""
    rng = np.random.default_rng(seed)
    out: list = []
    for a in args:
        if a is None:
            out.append(None)
            continue
        e = rng.choice([-1.0, 1.0], size=a.shape)
        if a.ndim >= 2 and a.shape[-1] == a.shape[-2] and np.array_equal(a, np.swapaxes(a, -1, -2)):
            e = np.triu(e) + np.swapaxes(np.triu(e, 1), -1, -2)
        out.append(a * (1.0 + PERTURBATION * e))
    return out


def _check_accuracy(what: str, solve: Any, args: tuple, X: np.ndarray, rho: float) -> None:
    """AccuracyWarning when a second solve on data perturbed at 1e-10 shows a
    condition number that puts the error above ``ACCURACY_RTOL``."""
    try:
        Xp = solve(*_perturbed(args))
    except (np.linalg.LinAlgError, ValueError):
        Xp = np.full_like(X, np.nan)
    warn_accuracy(
        what, float(perturbation_estimate(X, Xp)),
        f"closed-loop spectral radius {rho:.15g}: the Riccati equation is ill-conditioned",
        stacklevel=4,
    )


def solve_dare_info(A: ArrayLike, B: ArrayLike, Q: ArrayLike, R: ArrayLike, S: Optional[ArrayLike] = None) -> DareSolution:
    """Like :func:`solve_dare`, returning the solution with its gain and checks.

    Examples
    --------
    >>> from abkit.riccati import solve_dare_info
    >>> sol = solve_dare_info([[2.0]], [[1.0]], [[1.0]], [[1.0]])
    >>> round(float(sol.X[0, 0]), 12), round(sol.spectral_radius, 12)
    (4.2360679775, 0.38196601125)
    """
    a, b, q, r, s = _dare_args(A, B, Q, R, S)
    X, K, rho, res, it = _abkit.riccati_solve_dare(a, b, q, r, s)
    _check_accuracy("solve_dare: X", lambda *p: _abkit.riccati_solve_dare(*p)[0], (a, b, q, r, s), X, rho)
    return DareSolution(X, K, rho, res, it)


def solve_dare(A: ArrayLike, B: ArrayLike, Q: ArrayLike, R: ArrayLike, S: Optional[ArrayLike] = None) -> np.ndarray:
    """Stabilising solution of the discrete algebraic Riccati equation.

    Solves ``A^T X A - X - (A^T X B + S)(R + B^T X B)^{-1}(B^T X A + S^T) + Q = 0``
    with the signature and meaning of :func:`scipy.linalg.solve_discrete_are`
    (``S`` is scipy's ``s``).

    Parameters
    ----------
    A : array_like, shape (n, n)
    B : array_like, shape (n, m)
    Q : array_like, shape (n, n)
        Symmetric (need not be positive semi-definite).
    R : array_like, shape (m, m)
        Symmetric; may be singular if ``R + B^T X B`` is not.
    S : array_like, shape (n, m), optional
        Cross-weighting term; zero by default.

    Returns
    -------
    X : ndarray, shape (n, n)
        The symmetric stabilising solution: ``A - B K`` with
        ``K = (R + B^T X B)^{-1}(B^T X A + S^T)`` has spectral radius < 1.

    Raises
    ------
    ValueError
        Wrong shapes, non-symmetric ``Q`` or ``R``, NaN/Inf entries, ``n = 0``
        (the message names the argument).
    TypeError
        Non-real input.
    numpy.linalg.LinAlgError
        No stabilising solution exists (an unstabilisable or undetectable
        mode on or outside the unit circle), ``R + B^T X B`` is singular,
        or the result fails its residual check.

    Warns
    -----
    abkit.AccuracyWarning
        The estimated relative error of ``X`` exceeds ``1e-6`` (a second
        solve on data perturbed by ``1e-10`` measures the conditioning; the
        message gives the estimate). Typical cause: closed-loop eigenvalues
        very close to the unit circle.

    Notes
    -----
    Structure-preserving doubling (see the module docstring); every result is
    checked for its residual and closed-loop stability before it is returned.

    Examples
    --------
    Scalar ``a = 2, b = q = r = 1``: ``x^2 - 4x - 1 = 0``, so ``x = 2 + sqrt(5)``.

    >>> import numpy as np
    >>> from abkit.riccati import solve_dare
    >>> float(solve_dare([[2.0]], [[1.0]], [[1.0]], [[1.0]])[0, 0])
    4.23606797749979

    A unit-circle mode that ``Q`` does not weight has no stabilising solution:

    >>> solve_dare([[1.0]], [[1.0]], [[0.0]], [[1.0]])
    Traceback (most recent call last):
    ...
    numpy.linalg.LinAlgError: no stabilising solution: closed-loop spectral radius 1 >= 1 ...
    """
    return solve_dare_info(A, B, Q, R, S).X


def kalman_steady_state(F: ArrayLike, H: ArrayLike, Q: ArrayLike, R: ArrayLike) -> KalmanSteadyState:
    """Steady-state Kalman filter of ``x[k+1] = F x[k] + w[k]``, ``z[k] = H x[k] + v[k]``.

    Parameters
    ----------
    F : array_like, shape (n, n)
        State transition matrix.
    H : array_like, shape (p, n)
        Measurement matrix.
    Q : array_like, shape (n, n)
        Process noise covariance ``cov(w)`` (symmetric).
    R : array_like, shape (p, p)
        Measurement noise covariance ``cov(v)`` (symmetric; may be singular
        where a solution exists).

    Returns
    -------
    KalmanSteadyState
        ``P_pred`` (the DARE solution with ``A = F^T``, ``B = H^T``), the
        filter-form gain ``K``, the predictor-form gain ``K_pred = F K``, the
        filtered covariance ``P_filt``, the innovation covariance ``S`` and the
        predictor's spectral radius.

    Raises
    ------
    ValueError, TypeError, numpy.linalg.LinAlgError
        As :func:`solve_dare` (arguments named ``F``, ``H``, ``Q``, ``R``).

    Warns
    -----
    abkit.AccuracyWarning
        As :func:`solve_dare`, for ``P_pred``.

    Examples
    --------
    Random walk observed in unit noise with unit process noise: the
    prediction variance is the golden ratio.

    >>> from abkit.riccati import kalman_steady_state
    >>> ks = kalman_steady_state([[1.0]], [[1.0]], [[1.0]], [[1.0]])
    >>> round(float(ks.P_pred[0, 0]), 12), round(float(ks.K[0, 0]), 12)
    (1.61803398875, 0.61803398875)
    """
    f, h, q, r = _square_and_coupling(("F", "H", "Q", "R"), F, H, Q, R, False)
    P, K, Kp, Pf, S, rho = _abkit.riccati_kalman_steady_state(f, h, q, r)
    _check_accuracy("kalman_steady_state: P_pred", lambda *p: _abkit.riccati_kalman_steady_state(*p)[0], (f, h, q, r), P, rho)
    return KalmanSteadyState(P, K, Kp, Pf, S, rho)
