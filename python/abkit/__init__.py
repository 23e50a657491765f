"""abkit: design, analyse and run fixed-gain tracking filters.

Alpha-beta, alpha-beta-gamma and the steady-state Kalman filters they are
the limits of, with a Rust core.

Modules
-------
frame
    Filter long-format pandas/polars DataFrames (one row per report);
    needs ``abkit[frame]``.
dask
    Scale-out on Dask: dask arrays and Dask DataFrames; needs
    ``abkit[dask]``.
abg
    Near-optimal alpha-beta-gamma filters (Chen & Chui): gains from noise
    and back, coloured measurement noise, decoupled recursive forms.
alphabeta
    Alpha-beta design (Kalman and deterministic) and analysis.
kalman
    The time-varying Kalman filter recursion (paper 002), batched.
filters
    Batched filtering: AlphaBetaFilter, AlphaBetaGammaFilter, FixedGainFilter, Tracker.
feed
    FeedTracker: a live feed of reports from many tracks, batch by batch.
riccati
    Discrete algebraic Riccati equation (checked, stabilising) and the
    steady-state Kalman filter.
singer
    The Singer (exponentially correlated acceleration) model and the steady
    state of its Kalman filter (Yoon & Hong).
plot
    Figures (design nomograph, Singer error curves, frequency response,
    pole-zero map, Kalman gain convergence, track view); needs
    ``abkit[plot]``.
"""

from . import abg, alphabeta, feed, filters, kalman, riccati, singer
from . import dask, frame  # light: pandas, polars and dask are imported when used
from ._abkit import __version__
from ._errors import AccuracyWarning
from .alphabeta import AlphaBeta
from .feed import FeedTracker
from .filters import (
    AlphaBetaFilter,
    AlphaBetaGammaFilter,
    FilterResult,
    FilterState,
    FixedGainFilter,
    Tracker,
    empty_states,
)
from .kalman import KalmanFilter

__all__ = [
    "abg",
    "alphabeta",
    "dask",
    "feed",
    "filters",
    "frame",
    "kalman",
    "riccati",
    "singer",
    "AccuracyWarning",
    "AlphaBeta",
    "AlphaBetaFilter",
    "AlphaBetaGammaFilter",
    "FeedTracker",
    "FilterResult",
    "FilterState",
    "FixedGainFilter",
    "KalmanFilter",
    "Tracker",
    "__version__",
    "empty_states",
]
