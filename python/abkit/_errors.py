"""abkit's exception and warning classes, declared once here.

Errors use the standard types (the library's contract): ``TypeError`` for
non-real or wrongly typed input, ``ValueError`` naming the argument for bad
values and shapes, :class:`numpy.linalg.LinAlgError` (a ``ValueError``) when
a well-formed problem has no solution that can be computed reliably, and
``RuntimeError`` for an internal error (a caught Rust panic: a bug).

:class:`AccuracyWarning` is raised where a result is returned but its
accuracy has degraded beyond abkit's stated tolerance; its message carries
the estimated relative error.
"""

from __future__ import annotations

import warnings
from typing import Optional

__all__ = ["AccuracyWarning", "ACCURACY_RTOL", "PERTURBATION", "perturbation_estimate", "warn_accuracy"]

#: Estimated relative errors above this raise :class:`AccuracyWarning`.
ACCURACY_RTOL = 1e-6


#: Relative size of the data perturbation used to estimate conditioning.
PERTURBATION = 1e-10

import numpy as _np  # noqa: E402


def perturbation_estimate(x: "_np.ndarray", x_perturbed: "_np.ndarray", delta: float = PERTURBATION) -> "_np.ndarray":
    """Estimated relative error of ``x`` from a second solve on data perturbed
    by relative ``delta``: the measured condition number ``kappa =
    (||dx|| / ||x||) / delta`` times the rounding of the data (8 eps), or
    ``inf`` when the perturbed problem failed (``x_perturbed`` non-finite).
    A backward-stable solver (doubling, LU) then errs by about this much;
    norms over the last two axes (stacks allowed)."""
    x = _np.asarray(x, dtype=_np.float64)
    xp = _np.asarray(x_perturbed, dtype=_np.float64)
    num = _np.sqrt(_np.sum((xp - x) ** 2, axis=(-2, -1)))
    den = _np.sqrt(_np.sum(x * x, axis=(-2, -1)))
    with _np.errstate(divide="ignore", invalid="ignore"):
        kappa = _np.where(den > 0, num / den, _np.where(num > 0, _np.inf, 0.0)) / delta
    est = kappa * 8 * _np.finfo(_np.float64).eps
    return _np.where(_np.isfinite(est), est, _np.inf)


class AccuracyWarning(UserWarning):
    """A returned result may be less accurate than abkit's tolerance
    (``ACCURACY_RTOL``, 1e-6 relative): the problem is ill-conditioned
    (e.g. closed-loop eigenvalues near the unit circle). The message gives
    the estimated relative error."""


def warn_accuracy(what: str, estimate: float, cause: str, stacklevel: int = 3, tol: Optional[float] = None) -> bool:
    """Warn (and return True) when ``estimate`` exceeds the tolerance."""
    tol = ACCURACY_RTOL if tol is None else tol
    if not estimate <= tol:  # also NaN
        warnings.warn(
            f"{what}: estimated relative error {estimate:.1e} exceeds {tol:.0e} ({cause})",
            AccuracyWarning,
            stacklevel=stacklevel,
        )
        return True
    return False
