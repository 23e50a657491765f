"""abkit: design, analyse and run fixed-gain tracking filters.

Alpha-beta, alpha-beta-gamma and the steady-state Kalman filters they are
the limits of, with a Rust core.

Modules
-------
alphabeta
    Alpha-beta design (Kalman and deterministic) and analysis.
riccati
    Discrete algebraic Riccati equation (checked, stabilising) and the
    steady-state Kalman filter.
singer
    The Singer (exponentially correlated acceleration) model and the steady
    state of its Kalman filter (Yoon & Hong).
plot
    Figures (the design nomograph); needs ``abkit[plot]``.
"""

from . import alphabeta, riccati, singer
from ._abkit import __version__
from .alphabeta import AlphaBeta

__all__ = ["alphabeta", "riccati", "singer", "AlphaBeta", "__version__"]
