"""The validation table (issue 8): every public entry point against every kind
of awkward input.

``ENTRIES`` lists each public entry point with clean arguments and the *role*
of each array argument; ``CASES`` lists the awkward inputs; ``expected`` says,
per role and case, what must happen (documented in docs/reliability.md):

``same``
    accepted, and the result equals (bit for bit, NaN where NaN) the result of
    the same call on a clean, C-contiguous, writeable float64 copy of the
    perturbed argument, which must itself succeed;
``ValueError`` / ``TypeError``
    that exception, with a message naming the argument;
``scaled``
    (measurements at 2**+-996, i.e. about 1e+-300) accepted, and equal to the
    clean result times the scale: the filters are linear, and a power-of-two
    scale is exact in floating point unless something overflows or
    underflows;
``finite-or-ValueError``
    (parameters at 1e+-300) either a ``ValueError`` naming the argument, or
    accepted with every floating-point output finite: never a silent
    Inf/NaN.

``test_every_public_entry_point_is_in_the_table`` enumerates ``abkit.__all__``,
every public submodule's ``__all__`` and the public methods of every public
class, and fails when one is neither in ``ENTRIES`` nor in ``NO_ARRAY_INPUT``
(callables that take no array argument), so new entry points must join.
"""

from __future__ import annotations

import importlib
import inspect
import re
import warnings
from dataclasses import dataclass, field
from typing import Any, Callable, Dict, List, Optional, Tuple

import numpy as np
import pytest

import abkit
from abkit import abg, alphabeta, filters, kalman, riccati, singer
from abkit._results import RowResult

PARAM = "param"  # real scalar or array, broadcast element-wise with the others
PARAM1D = "param1d"  # real scalar or 1-D (one value per track)
MATRIX = "matrix"  # real matrix of a fixed shape (or a stack of them)
DATA = "data"  # measurements: float32/float64 only, NaN = missed detection
SCALAR = "scalar"  # a real scalar (0-d) parameter
TIME = "time"  # timestamps t= of a run: real, finite, of the sample shape of z
OFFSETS = "offsets"  # offsets= of a ragged run: 1-D integers, 0 .. N, non-decreasing

SCALE = 2.0**996  # about 6.7e299; its reciprocal about 1.5e-300


@dataclass
class Entry:
    name: str
    call: Callable[..., Any]
    args: Dict[str, Any]
    roles: Dict[str, str]
    out: Optional[Callable[[Any], Tuple[int, ...]]] = None  # z -> shape of a valid out=
    # extremes (1e+-300) of an analysis of arbitrary gains: accepted, with
    # results beyond float64's range as +-inf and model fields that do not
    # exist for such gains as NaN (as each function documents)
    analysis: bool = False
    # per-(argument, case) overrides of the expected outcome
    override: Dict[Tuple[str, str], str] = field(default_factory=dict)


def _v(*x: float) -> np.ndarray:
    return np.array(x, dtype=np.float64)


Z2 = np.cumsum(np.random.default_rng(5).normal(size=(3, 40)), axis=-1)  # (n_tracks, n_samples)
Z2[1, 7] = np.nan
Z3 = np.stack([Z2, 0.5 * Z2], axis=-1)  # (n_tracks, n_samples, 2)
PHI2 = np.array([[1.0, 1.0], [0.0, 1.0]])
H2 = np.array([[1.0, 0.0]])
K2 = np.array([[0.5], [0.2]])
Q2 = np.array([[0.25, 0.5], [0.5, 1.0]]) * 1e-2
R1 = np.array([[1.0]])
TT = np.cumsum(np.random.default_rng(6).uniform(0.5, 1.5, size=Z2.shape), axis=-1)  # timestamps of Z2
OFF = np.array([0, 40, 65, 120])  # a ragged batch of Z2's 120 samples, flat
ZF = Z2.reshape(-1).copy()
TF = np.concatenate([np.cumsum(np.random.default_rng(7).uniform(0.5, 1.5, size=k)) for k in np.diff(OFF)])  # increasing per track
AB = abkit.AlphaBetaFilter(0.5, 0.2, 1.0)
ABG3 = abkit.AlphaBetaGammaFilter(0.5, 0.2, 0.02, 1.0)
FG = abkit.FixedGainFilter(PHI2, H2, K2)
FG2 = abkit.FixedGainFilter(PHI2, np.eye(2), np.array([[0.5, 0.0], [0.0, 0.4]]))
KF = kalman.KalmanFilter(PHI2, H2, Q2, R1, P0=np.eye(2) * 100.0)
DESIGN = alphabeta.from_snr(_v(0.1, 1.0))
ABGD = abg.from_noise(1.0, 1.0, 1.0, 1.0)

# near-optimal gains (abg.from_noise of sigma_p, sigma_v, sigma_a, sigma_m = (1,1,0.1,1), (2,1,1,5), (3,2,1,10), (4,2,3,2))
ABG_GAINS = dict(alpha=_v(0.8638063, 0.82532451, 0.7940065, 0.93029738), beta=_v(0.58121394, 0.58605188, 0.5187657, 0.81934255), gamma=_v(0.11670206, 0.18690933, 0.14352474, 0.323348))
COL = dict(theta=_v(0.1, 0.2, 0.3, 0.4), r=_v(0.5, 0.3, -0.2, 0.8))


def _entries() -> List[Entry]:
    P = PARAM
    M = MATRIX
    E: List[Entry] = []
    add = E.append
    # -- alphabeta ------------------------------------------------------------
    add(Entry("alphabeta.from_snr", alphabeta.from_snr, dict(r=_v(0.01, 0.1, 1.0, 10.0)), dict(r=P)))
    add(Entry("alphabeta.from_noise", alphabeta.from_noise, dict(sigma_w=_v(1, 2, 3, 4), sigma_v=_v(10, 20, 5, 1), T=_v(0.1, 0.2, 0.5, 1)), dict(sigma_w=P, sigma_v=P, T=P)))
    add(Entry("alphabeta.from_tracking_index", alphabeta.from_tracking_index, dict(lam=_v(0.01, 0.1, 1.0, 10.0)), dict(lam=P)))
    add(Entry("alphabeta.from_tracking_error", alphabeta.from_tracking_error, dict(ratio=_v(0.1, 0.3, 0.5, 0.9)), dict(ratio=P)))
    add(Entry("alphabeta.from_bandwidth", alphabeta.from_bandwidth, dict(bn_t=_v(0.01, 0.05, 0.1, 0.2), damping=_v(0.5, 0.7, 1.0, 0.8)), dict(bn_t=P, damping=P)))
    add(Entry("alphabeta.from_natural_frequency", alphabeta.from_natural_frequency, dict(omega_n=_v(0.1, 0.5, 1.0, 2.0), T=_v(0.1, 0.1, 0.2, 0.1), damping=_v(0.5, 0.7, 1.0, 0.8)), dict(omega_n=P, T=P, damping=P)))
    add(Entry("alphabeta.analyze", alphabeta.analyze, dict(alpha=_v(0.5, 0.6, 0.3, 0.1), beta=_v(0.2, 0.3, 0.05, 0.01)), dict(alpha=P, beta=P), analysis=True))
    add(Entry("alphabeta.error_covariance", alphabeta.error_covariance, dict(alpha=_v(0.5, 0.6, 0.3, 0.1), beta=_v(0.2, 0.3, 0.05, 0.01), r_true=_v(0.1, 1, 10, 0.5)), dict(alpha=P, beta=P, r_true=P)))
    add(Entry("alphabeta.AlphaBeta.gains", lambda T: DESIGN.gains(T), dict(T=_v(0.1, 0.5)), dict(T=P)))
    add(Entry("alphabeta.AlphaBeta.continuous", lambda T: DESIGN.continuous(T), dict(T=_v(0.1, 0.5)), dict(T=P)))
    add(Entry("alphabeta.AlphaBeta.scaled_covariance", lambda sigma_v, T: DESIGN.scaled_covariance(sigma_v, T), dict(sigma_v=_v(1.0, 3.0), T=_v(0.1, 0.5)), dict(sigma_v=P, T=P)))
    add(Entry("alphabeta.AlphaBeta.error_covariance", lambda r_true: DESIGN.error_covariance(r_true), dict(r_true=_v(0.5, 2.0)), dict(r_true=P)))
    # -- abg --------------------------------------------------------------------
    g3 = dict(alpha=P, beta=P, gamma=P)
    add(Entry("abg.convert", abg.convert, dict(ABG_GAINS), g3))
    add(Entry("abg.to_predictor", abg.to_predictor, dict(ABG_GAINS, h=_v(1, 2, 0.5, 0.1)), dict(g3, h=P)))
    add(Entry("abg.from_predictor", abg.from_predictor, dict(K=abg.to_predictor(**ABG_GAINS), h=_v(1.0)), dict(K=M, h=P), override={("K", "ndim"): "same", ("K", "zero-size"): "ValueError"}, analysis=True))
    add(Entry("abg.from_noise", abg.from_noise, dict(sigma_p=_v(1, 2, 3, 4), sigma_v=_v(1, 1, 2, 2), sigma_a=_v(0.1, 1, 1, 3), sigma_m=_v(1, 5, 10, 2), h=_v(1, 0.5, 0.1, 2)), dict(sigma_p=P, sigma_v=P, sigma_a=P, sigma_m=P, h=P), analysis=True))
    add(Entry("abg.from_tracking_index", abg.from_tracking_index, dict(lam=_v(0.01, 0.1, 1.0, 10.0)), dict(lam=P)))
    add(Entry("abg.analyze", abg.analyze, dict(ABG_GAINS), g3, analysis=True))
    add(Entry("abg.noise_ratios", abg.noise_ratios, dict(ABG_GAINS, h=_v(1, 2, 0.5, 0.1)), dict(g3, h=P), analysis=True))
    add(Entry("abg.is_near_optimal", abg.is_near_optimal, dict(ABG_GAINS), g3))
    add(Entry("abg.stability_region", abg.stability_region, dict(ABG_GAINS), g3, analysis=True))
    add(Entry("abg.coloured", abg.coloured, dict(ABG_GAINS, **COL, h=_v(1, 1, 0.5, 2)), dict(g3, theta=P, r=P, h=P), analysis=True))
    add(Entry("abg.coloured_from_noise", abg.coloured_from_noise, dict(sigma_p=_v(1, 2, 3, 4), sigma_v=_v(1, 1, 2, 2), sigma_a=_v(0.1, 1, 1, 3), sigma_m=_v(1, 5, 10, 2), r=_v(0.5, 0.3, -0.2, 0.8), h=_v(1, 0.5, 0.1, 2)), dict(sigma_p=P, sigma_v=P, sigma_a=P, sigma_m=P, r=P, h=P)))
    add(Entry("abg.decoupled", abg.decoupled, dict(ABG_GAINS, **COL, h=_v(1, 1, 0.5, 2)), dict(g3, theta=P, r=P, h=P), analysis=True))
    add(Entry("abg.ABG.filter", lambda h: ABGD.filter(h), dict(h=_v(0.5)), dict(h=PARAM1D), override={("h", "zero-size"): "same"}))
    # -- singer -----------------------------------------------------------------
    s_ov = {("tau", "inf"): "same"}  # tau = inf is the constant-acceleration limit
    add(Entry("singer.model", singer.model, dict(T=_v(0.1, 1, 2, 0.5), tau=_v(1, 10, 5, 20), sigma_m=_v(1, 2, 3, 4)), dict(T=P, tau=P, sigma_m=P), override=s_ov))
    add(Entry("singer.steady_state", singer.steady_state, dict(T=_v(0.1, 1, 2, 0.5), tau=_v(1, 10, 5, 20), sigma_m=_v(1, 2, 3, 4), sigma_pos=_v(1, 1, 10, 0.5)), dict(T=P, tau=P, sigma_m=P, sigma_pos=P), override=s_ov))
    add(Entry("singer.tracking_filter", singer.tracking_filter, dict(T=1.0, tau=20.0, sigma_m=1.0, sigma_pos=10.0),
              dict(T=SCALAR, tau=SCALAR, sigma_m=SCALAR, sigma_pos=SCALAR), override=s_ov))
    # -- riccati ----------------------------------------------------------------
    m4 = dict(A=M, B=M, Q=M, R=M)
    add(Entry("riccati.solve_dare", riccati.solve_dare, dict(A=PHI2.T.copy(), B=H2.T.copy(), Q=Q2, R=R1), m4))
    add(Entry("riccati.solve_dare_info", riccati.solve_dare_info, dict(A=PHI2.T.copy(), B=H2.T.copy(), Q=Q2, R=R1), m4))
    add(Entry("riccati.kalman_steady_state", riccati.kalman_steady_state, dict(F=PHI2, H=H2, Q=Q2, R=R1), dict(F=M, H=M, Q=M, R=M)))
    # -- kalman -----------------------------------------------------------------
    km = dict(F=M, H=M, Q=M, R=M, P0=M)
    add(Entry("kalman.gain_sequence", lambda F, H, Q, R, P0: kalman.gain_sequence(F, H, Q, R, P0, 5), dict(F=PHI2, H=H2, Q=Q2, R=R1, P0=np.eye(2)), km))
    add(Entry("kalman.KalmanFilter", kalman.KalmanFilter, dict(F=PHI2, H=H2, Q=Q2, R=R1, P0=np.eye(2), x0=_v(1.0, 0.5)), dict(km, x0=M)))
    add(Entry("kalman.KalmanFilter.gain_sequence", KF.gain_sequence, dict(n=3), {}))
    add(Entry("kalman.KalmanFilter.run", KF.run, dict(z=Z2), dict(z=DATA), out=lambda z: (2,) + z.shape))
    # -- filters ----------------------------------------------------------------
    add(Entry("filters.FixedGainFilter", filters.FixedGainFilter, dict(Phi=PHI2, H=H2, K=K2, T=_v(1.0)), dict(Phi=M, H=M, K=M, T=PARAM1D),
              # a leading axis of length 1 is one parameter set per track (here: one track)
              override={("T", "zero-size"): "ValueError", ("Phi", "ndim"): "same", ("H", "ndim"): "same", ("K", "ndim"): "same"}))
    add(Entry("filters.AlphaBetaFilter", filters.AlphaBetaFilter, dict(alpha=_v(0.5, 0.3, 0.6), beta=_v(0.2, 0.1, 0.3), T=_v(1, 0.5, 2)), dict(alpha=PARAM1D, beta=PARAM1D, T=PARAM1D)))
    add(Entry("filters.AlphaBetaGammaFilter", filters.AlphaBetaGammaFilter, dict(alpha=_v(0.5, 0.3, 0.6), beta=_v(0.2, 0.1, 0.3), gamma=_v(0.02, 0.01, 0.03), T=_v(1, 0.5, 2)), dict(alpha=PARAM1D, beta=PARAM1D, gamma=PARAM1D, T=PARAM1D)))
    add(Entry("filters.AlphaBetaFilter.from_design", lambda T: abkit.AlphaBetaFilter.from_design(DESIGN, T=T), dict(T=_v(1.0, 0.5)), dict(T=PARAM1D)))
    add(Entry("filters.AlphaBetaFilter.from_noise", filters.AlphaBetaFilter.from_noise, dict(sigma_w=_v(1.0, 3.2), sigma_v=_v(10.0, 32.0), T=_v(1.0, 0.1)), dict(sigma_w=PARAM1D, sigma_v=PARAM1D, T=PARAM1D)))
    add(Entry("filters.AlphaBetaGammaFilter.from_noise", filters.AlphaBetaGammaFilter.from_noise, dict(sigma_p=0.5, sigma_v=0.2, sigma_a=0.1, sigma_m=1.0, T=1.0),
              dict(sigma_p=SCALAR, sigma_v=SCALAR, sigma_a=SCALAR, sigma_m=SCALAR, T=SCALAR)))
    for cls, f in (("FixedGainFilter", FG), ("AlphaBetaFilter", AB), ("AlphaBetaGammaFilter", ABG3)):
        n = f.n
        add(Entry(f"filters.{cls}.run", f.run, dict(z=Z2), dict(z=DATA), out=lambda z, n=n: (n,) + z.shape))
        qm = Q2 if n == 2 else np.diag([1e-4, 1e-3, 1e-2])
        add(Entry(f"filters.{cls}.smooth", lambda z, f=f, qm=qm, **kw: f.smooth(z, Q=qm, R=R1, **kw), dict(z=Z2), dict(z=DATA), out=lambda z, n=n: (n,) + z.shape))
        add(Entry(f"filters.{cls}.covariances", f.covariances, dict(Q=qm, R=R1), dict(Q=M, R=M)))
        add(Entry(f"filters.{cls}.smoother_gain", f.smoother_gain, dict(Q=qm, R=R1), dict(Q=M, R=M)))
        add(Entry(f"filters.{cls}.tracker", f.tracker, dict(n_tracks=2), {}))
    # the run keywords of docs/tracks.md: timestamps (gains kept and scaled by dt, or the
    # design at each dt), ragged offsets, both together, smoothing with timestamps
    ABD = abkit.AlphaBetaFilter.from_noise(1.0, 10.0, 1.0)
    ABGD3 = abkit.AlphaBetaGammaFilter.from_noise(0.0, 0.0, 0.1, 1.0, 1.0)
    for tag, f in (("AlphaBetaFilter", AB), ("AlphaBetaGammaFilter", ABG3), ("AlphaBetaFilter[design]", ABD), ("AlphaBetaGammaFilter[design]", ABGD3)):
        cls, _, design = tag.partition("[")
        sfx = "design," if design else ""
        n = f.n
        add(Entry(f"filters.{cls}.run[{sfx}t]", lambda z, t=TT, f=f, **kw: f.run(z, t=t, **kw), dict(z=Z2, t=TT), dict(z=DATA, t=TIME), out=lambda z, n=n: (n,) + z.shape))
        add(Entry(f"filters.{cls}.run[{sfx}offsets,t]", lambda z, offsets=OFF, t=TF, f=f, **kw: f.run(z, offsets=offsets, t=t, **kw), dict(z=ZF, offsets=OFF, t=TF), dict(z=DATA, offsets=OFFSETS, t=TIME),
                  out=lambda z, n=n: (n,) + z.shape))
    for cls, f in (("FixedGainFilter", FG), ("AlphaBetaFilter", AB)):
        add(Entry(f"filters.{cls}.run[offsets]", lambda z, offsets=OFF, f=f, **kw: f.run(z, offsets=offsets, **kw), dict(z=ZF, offsets=OFF), dict(z=DATA, offsets=OFFSETS), out=lambda z, n=f.n: (n,) + z.shape))
    for tag, f in (("", AB), ("design,", ABD)):
        add(Entry(f"filters.AlphaBetaFilter.smooth[{tag}t]", lambda z, t=TT, f=f, **kw: f.smooth(z, t=t, **kw), dict(z=Z2, t=TT), dict(z=DATA, t=TIME), out=lambda z: (2,) + z.shape))
        add(Entry(f"filters.AlphaBetaFilter.smooth[{tag}offsets,t]", lambda z, offsets=OFF, t=TF, f=f, **kw: f.smooth(z, offsets=offsets, t=t, **kw), dict(z=ZF, offsets=OFF, t=TF),
                  dict(z=DATA, offsets=OFFSETS, t=TIME), out=lambda z: (2,) + z.shape))
    add(Entry("filters.FixedGainFilter.run[m=2]", lambda z, **kw: FG2.run(z, init="first", **kw), dict(z=Z3), dict(z=DATA), out=lambda z: (2,) + z.shape[:-1]))
    add(Entry("filters.Tracker", lambda n_tracks: abkit.Tracker(AB, n_tracks=n_tracks), dict(n_tracks=3), {}))
    add(Entry("filters.Tracker.update", lambda z_chunk: abkit.Tracker(AB, n_tracks=3).update(z_chunk), dict(z_chunk=Z2), dict(z_chunk=DATA),
              # a convenience for real-time feeds: integer and bool samples are converted to float64
              override={("z_chunk", "bool"): "same", ("z_chunk", "int"): "same"}))
    add(Entry("filters.Tracker.reset", lambda: abkit.Tracker(AB).reset(), {}, {}))
    # -- a live feed: reports of many tracks interleaved (ids are labels, not arrays of numbers)
    add(Entry("feed.FeedTracker", lambda axes: abkit.FeedTracker(AB, axes=axes), dict(axes=2), {}))
    add(Entry("feed.FeedTracker.update",
              lambda z, t=TT[0]: abkit.FeedTracker(ABD).update(np.arange(np.shape(z)[0] if np.ndim(z) else 1) % 3, t, z),
              dict(z=Z2[0], t=TT[0]), dict(z=DATA, t=TIME),
              # like Tracker.update: integer and bool samples are converted to float64
              override={("z", "bool"): "same", ("z", "int"): "same"}))
    # -- dask (dask's local threaded scheduler: no cluster is started) ---------------
    add(Entry("dask.run", lambda z: _dask().run(AB, _dask_array(z)).compute(), dict(z=Z2), dict(z=DATA)))
    add(Entry("dask.run[t]", lambda z, t=TT: _dask().run(ABD, _dask_array(z), t=t).compute(), dict(z=Z2, t=TT), dict(z=DATA, t=TIME)))
    # a dask DataFrame of frame.filter's input; the per-partition validation is frame.filter's
    # (FRAME_CASES below; test_dask_filter_frame_delegates_validation shows it reaches the caller)
    add(Entry("dask.filter_frame", lambda: _dask().filter_frame(_dd().from_pandas(_long_frame().sort_values("id", kind="stable"), npartitions=3, sort=False), id="id", time="t", columns=["x", "y"], filter=AB).compute(), {}, {}))
    # -- frame (DataFrame input: the DataFrame-specific cases are FRAME_CASES below) ----------
    add(Entry("frame.filter", lambda: _frame().filter(_long_frame(), id="id", time="t", columns=["x", "y"], filter=AB), {}, {}))
    # -- plot (needs matplotlib) -----------------------------------------------------
    add(Entry("plot.singer_tau_over_T", lambda p2: _plot().singer_tau_over_T(p2), dict(p2=_v(0.01, 0.1, 1.0, 10.0)), dict(p2=P)))
    add(Entry("plot.singer_errors", lambda p2: _closefig(_plot().singer_errors(p2=p2)), dict(p2=_v(0.1, 1.0)), dict(p2=P), override={("p2", "zero-size"): "ValueError"}))
    add(Entry("plot.nomograph", lambda n: _closefig(_plot().nomograph(n=n)), dict(n=50), {}))
    add(Entry("plot.transfer_response", lambda w: _plot().transfer_response(AB, w), dict(w=_v(0.01, 0.1, 1.0, 3.0)), dict(w=P)))
    add(Entry("plot.frequency_response", lambda n: _closefig(_plot().frequency_response(AB, n=n)), dict(n=32), {}))
    add(Entry("plot.transfer_zeros", lambda state: _plot().transfer_zeros(ABG3, state), dict(state=1), {}))
    add(Entry("plot.pole_zero", lambda: _closefig(_plot().pole_zero(ABG3)), {}, {}))
    add(Entry("plot.gain_convergence", lambda n: _closefig(_plot().gain_convergence(KF, n=n)), dict(n=20), {}))
    # a figure of a result and the measurements it was computed from (drawn as given)
    add(Entry("plot.track", lambda: _closefig(_plot().track(AB.run(Z2), Z2)), {}, {}))
    return E


def _plot() -> Any:
    pytest.importorskip("matplotlib")
    return importlib.import_module("abkit.plot")


def _dask() -> Any:
    pytest.importorskip("dask.array")
    return importlib.import_module("abkit.dask")


def _dask_array(v: np.ndarray) -> Any:
    """``v`` as a dask array in two chunks along each axis (explicit chunks:
    dask cannot size object arrays itself)."""
    da = pytest.importorskip("dask.array")
    if not isinstance(v, np.ndarray):
        return v  # not an array (None, a string, a list): abkit.dask.run gets it as is
    return da.from_array(v, chunks=tuple(max(1, s // 2) for s in v.shape))


def _dd() -> Any:
    return pytest.importorskip("dask.dataframe")


def _frame() -> Any:
    pytest.importorskip("pandas")
    return importlib.import_module("abkit.frame")


def _long_frame() -> Any:
    """Z2's three tracks as a long-format pandas DataFrame (one row per report),
    reports of the tracks interleaved in time order."""
    pd = pytest.importorskip("pandas")
    ids = np.repeat(np.array([3, 7, 11]), Z2.shape[1])
    order = np.argsort(TT.reshape(-1), kind="stable")
    return pd.DataFrame({"id": ids[order], "t": TT.reshape(-1)[order], "x": Z2.reshape(-1)[order], "y": 2.0 * Z2.reshape(-1)[order]}).reset_index(drop=True)


def _closefig(obj: Any) -> None:
    import matplotlib.pyplot as plt

    plt.close("all")
    return None


ENTRIES = _entries()
BY_NAME = {e.name: e for e in ENTRIES}
#: Rows that draw a matplotlib figure (slow; left out of the endurance loop and the fuzzer).
FIGURES = {"plot.nomograph", "plot.singer_errors", "plot.frequency_response", "plot.pole_zero", "plot.gain_convergence", "plot.track"}

#: Public callables without an array input (nothing to validate beyond their own tests).
NO_ARRAY_INPUT = {
    "alphabeta.AlphaBeta.to_dict", "alphabeta.AlphaBeta.table",
    "abg.ABG.to_dict", "abg.ABG.table",
    "filters.FilterState.copy",
    "dask.DaskFilterResult.compute",  # computes a result's lazy arrays (keywords go to dask)
    "frame.FrameSummary.totals",
    "feed.FeedTracker.estimate", "feed.FeedTracker.forget",  # track ids only
    "filters.empty_states",  # a shape and a dtype (their errors: test_output_layout.py)
}
#: Result types: constructed by abkit, not by users (their fields are outputs).
RESULT_TYPES = {
    "alphabeta.AlphaBeta", "alphabeta.ErrorCovariance", "alphabeta.Lag", "alphabeta.VarianceReduction",
    "abg.ABG", "abg.Coloured", "abg.ColouredGains", "abg.Decoupled", "abg.Gains", "abg.NoiseRatios", "abg.StabilityMargins",
    "singer.SingerSteadyState", "riccati.DareSolution", "riccati.KalmanSteadyState",
    "kalman.KalmanResult", "kalman.GainSequence", "filters.FilterResult", "filters.FilterState",
    "plot.FrequencyResponse", "plot.PoleZero", "plot.GainConvergence",
    "dask.DaskFilterResult", "frame.FrameSummary", "feed.FeedResult",
}
SUBMODULES = ("alphabeta", "abg", "filters", "kalman", "riccati", "singer", "plot", "feed")


def _public_callables() -> List[str]:
    names = []
    mods = list(SUBMODULES) + [m for m in abkit.__all__ if inspect.ismodule(getattr(abkit, m, None)) and m not in SUBMODULES]
    for modname in mods:
        try:
            mod = importlib.import_module(f"abkit.{modname}")
        except ImportError:  # pragma: no cover - optional dependency missing
            continue
        for n in getattr(mod, "__all__", []):
            obj = getattr(mod, n)
            if not callable(obj):
                continue
            names.append(f"{modname}.{n}")
            if inspect.isclass(obj):
                base = tuple if issubclass(obj, tuple) else object
                for mn, _ in inspect.getmembers(obj):
                    if mn.startswith("_") or hasattr(base, mn):
                        continue
                    raw = inspect.getattr_static(obj, mn)
                    if isinstance(raw, (staticmethod, classmethod)) or inspect.isfunction(raw):
                        names.append(f"{modname}.{n}.{mn}")
    for n in abkit.__all__:  # top-level re-exports must be one of the above
        obj = getattr(abkit, n)
        if inspect.isclass(obj) and issubclass(obj, BaseException):
            continue  # abkit.AccuracyWarning: a warning class, no input
        if callable(obj) and not inspect.ismodule(obj):
            assert any(getattr(importlib.import_module(f"abkit.{m}"), n, None) is obj for m in SUBMODULES), n
    return sorted(set(names))


def test_every_public_entry_point_is_in_the_table() -> None:
    covered = {e.name.split("[")[0] for e in ENTRIES} | NO_ARRAY_INPUT | RESULT_TYPES
    missing = [n for n in _public_callables() if n not in covered]
    assert not missing, f"public entry points missing from the validation table (add them to ENTRIES): {missing}"
    stale = sorted(n for n in covered if n not in set(_public_callables()))
    assert not stale, f"table rows for entry points that no longer exist: {stale}"


@pytest.mark.parametrize("name", [e.name for e in ENTRIES])
def test_clean_arguments_succeed(name: str) -> None:
    """Every row's clean arguments are valid, so its 'same' cases compare results."""
    e = BY_NAME[name]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        e.call(**e.args)


# -- cases ------------------------------------------------------------------------

def _negative(v: np.ndarray) -> np.ndarray:
    idx = (slice(None, None, -1),) * v.ndim
    return v[idx].copy()[idx]


def _noncontig(v: np.ndarray) -> np.ndarray:
    if v.ndim == 0:
        return v
    big = np.full(v.shape[:-1] + (2 * v.shape[-1],), -7.0, dtype=v.dtype)
    big[..., ::2] = v
    return big[..., ::2]


def _readonly(v: np.ndarray) -> np.ndarray:
    c = v.copy()
    c.flags.writeable = False
    return c


def _first(v: np.ndarray, x: float) -> np.ndarray:
    c = np.array(v, dtype=np.float64, copy=True)
    if c.size:
        c.reshape(-1)[0] = x
    return c


def _wrong_shape(v: np.ndarray, role: str) -> np.ndarray:
    if role == OFFSETS:
        return v[:-1]  # one track short: does not end at N
    if role == DATA:
        return np.zeros(v.shape[:2] + (3,))
    if role == MATRIX:
        return np.ones(v.shape[:-1] + (v.shape[-1] + 1,)) if v.ndim else np.ones((2, 3))
    return np.ones(max(v.size, 1) + 1)


#: case -> how the argument is perturbed
CASES: Dict[str, Callable[[np.ndarray, str], Any]] = {
    "bool": lambda v, r: v.astype(bool),
    "int": lambda v, r: v.astype(np.int32) if r == OFFSETS else np.round(v * 4).astype(np.int64) + (r == PARAM),
    "complex": lambda v, r: v.astype(np.complex128),
    "object": lambda v, r: v.astype(object),
    "big-endian": lambda v, r: v.astype(">f8"),
    "float16": lambda v, r: v.astype(np.float16),
    "float32": lambda v, r: v.astype(np.float32),
    "ndim": lambda v, r: v.reshape((1,) * (4 - v.ndim if r == DATA else 3 - min(v.ndim, 2)) + v.shape),
    "shape": _wrong_shape,
    "negative-stride": lambda v, r: _negative(v),
    "broadcast-view": lambda v, r: np.broadcast_to(v.reshape(-1)[:1].reshape((1,) * v.ndim), v.shape),
    "non-contiguous": lambda v, r: _noncontig(v),
    "fortran": lambda v, r: np.asfortranarray(v),
    "read-only": lambda v, r: _readonly(v),
    "zero-size": lambda v, r: np.zeros(v.shape[:-1] + (0,), dtype=np.int64 if r == OFFSETS else np.float64) if v.ndim else np.zeros(0),
    "nan": lambda v, r: _first(v, np.nan),
    "inf": lambda v, r: _first(v, np.inf),
    "-inf": lambda v, r: _first(v, -np.inf),
    # timestamps: steps dt of about 1e+-300; offsets: beyond int64 as uint64, and negative
    "huge": lambda v, r: (np.array([0] + [2**64 - 1] * (v.size - 1), dtype=np.uint64) if r == OFFSETS
                          else v * SCALE if r in (DATA, TIME) else np.full_like(v, 1e300)),
    "tiny": lambda v, r: v - 1 if r == OFFSETS else v / SCALE if r in (DATA, TIME) else np.full_like(v, 1e-300),
}

#: role -> case -> expected outcome (see the module docstring)
EXPECTED: Dict[str, Dict[str, str]] = {
    PARAM: {
        "bool": "same", "int": "same", "complex": "TypeError", "object": "TypeError", "big-endian": "same",
        "float16": "same", "float32": "same", "ndim": "same", "shape": "ValueError", "negative-stride": "same",
        "broadcast-view": "same", "non-contiguous": "same", "fortran": "same", "read-only": "same", "zero-size": "same",
        "nan": "ValueError", "inf": "ValueError", "-inf": "ValueError", "huge": "finite-or-ValueError", "tiny": "finite-or-ValueError",
    },
    MATRIX: {
        "bool": "same", "int": "same", "complex": "TypeError", "object": "TypeError", "big-endian": "same",
        "float16": "same", "float32": "same", "ndim": "ValueError", "shape": "ValueError", "negative-stride": "same",
        "broadcast-view": "same", "non-contiguous": "same", "fortran": "same", "read-only": "same", "zero-size": "ValueError",
        "nan": "ValueError", "inf": "ValueError", "-inf": "ValueError", "huge": "finite-or-ValueError", "tiny": "finite-or-ValueError",
    },
    DATA: {
        "bool": "TypeError", "int": "TypeError", "complex": "TypeError", "object": "TypeError", "big-endian": "TypeError",
        "float16": "TypeError", "float32": "same-float32", "ndim": "ValueError", "shape": "ValueError", "negative-stride": "same",
        "broadcast-view": "same", "non-contiguous": "same", "fortran": "same", "read-only": "same", "zero-size": "same",
        "nan": "same", "inf": "ValueError", "-inf": "ValueError", "huge": "scaled", "tiny": "scaled",
    },
}
EXPECTED[PARAM1D] = dict(EXPECTED[PARAM], ndim="ValueError", shape="ValueError")
EXPECTED[SCALAR] = dict(EXPECTED[PARAM1D], **{"zero-size": "ValueError"})
# timestamps: real numbers converted to float64 (bool is not a time); a wrong shape, a
# missing or infinite timestamp is an error naming t; steps dt of about 1e+-300 give
# estimates finite wherever those of the clean timestamps are, or a ValueError naming t
EXPECTED[TIME] = dict(EXPECTED[PARAM], bool="TypeError", ndim="ValueError", shape="ValueError", **{"zero-size": "ValueError"},
                      huge="finite-where-clean-or-ValueError", tiny="finite-where-clean-or-ValueError")
# offsets: integers only (any integer dtype; floats, even integral ones, are refused)
EXPECTED[OFFSETS] = {
    "bool": "TypeError", "int": "same", "complex": "TypeError", "object": "TypeError", "big-endian": "TypeError",
    "float16": "TypeError", "float32": "TypeError", "ndim": "ValueError", "shape": "ValueError", "negative-stride": "same",
    "broadcast-view": "ValueError", "non-contiguous": "same", "fortran": "same", "read-only": "same", "zero-size": "ValueError",
    "nan": "TypeError", "inf": "TypeError", "-inf": "TypeError", "huge": "ValueError", "tiny": "ValueError",
}


def _expected(e: Entry, arg: str, case: str) -> str:
    if (arg, case) in e.override:
        return e.override[(arg, case)]
    exp = EXPECTED[e.roles[arg]][case]
    if e.analysis and exp == "finite-or-ValueError":
        return "accepted-analysis"
    if case == "shape" and e.roles[arg] in (PARAM, PARAM1D) and sum(r in (PARAM, PARAM1D) for r in e.roles.values()) == 1:
        exp = "same" if e.roles[arg] == PARAM else exp  # a lone argument broadcasts with nothing
    if case == "shape" and e.roles[arg] == PARAM1D and sum(r in (PARAM, PARAM1D) for r in e.roles.values()) == 1:
        exp = "same" if np.ndim(e.args[arg]) <= 1 else exp
    return exp


def _leaves(obj: Any) -> List[Any]:
    if obj is None or isinstance(obj, (str, bool)):
        return [obj]
    if isinstance(obj, (int, float, complex, np.generic)):
        return [np.asarray(obj)]
    if isinstance(obj, np.ndarray):
        return [obj]
    if isinstance(obj, (tuple, list)):
        return [x for o in obj for x in _leaves(o)]
    if isinstance(obj, dict):
        return [x for k in sorted(obj) for x in _leaves(obj[k])]
    if isinstance(obj, RowResult):
        return [obj._rows, obj.shape]
    slots = [s for c in type(obj).__mro__ for s in getattr(c, "__slots__", ())]
    vals = [getattr(obj, s) for s in slots if hasattr(obj, s)]
    if hasattr(obj, "__dict__"):
        vals += [vars(obj)[k] for k in sorted(vars(obj))]
    return [x for v in vals for x in _leaves(v)]


def _equal(a: Any, b: Any) -> bool:
    la, lb = _leaves(a), _leaves(b)
    if len(la) != len(lb):
        return False
    for x, y in zip(la, lb):
        if isinstance(x, np.ndarray) and isinstance(y, np.ndarray):
            if x.shape != y.shape or x.dtype != y.dtype:
                return False
            if not np.array_equal(x, y, equal_nan=x.dtype.kind in "fc"):
                return False
        elif isinstance(x, np.ndarray) or isinstance(y, np.ndarray):
            return False
        elif x != y:
            return False
    return True


def _clean(v: Any, role: str = PARAM) -> Any:
    return np.array(v, dtype=np.int64 if role == OFFSETS else np.float64, copy=True, order="C")


def _names(arg: str, msg: str) -> bool:
    return re.search(rf"(?<![A-Za-z0-9_]){re.escape(arg)}(?![A-Za-z0-9_])", msg) is not None


def _params() -> List[Tuple[str, str, str]]:
    out = []
    for e in ENTRIES:
        for arg in e.roles:
            for case in CASES:
                out.append((e.name, arg, case))
    return out


def _all_floats_finite(obj: Any) -> bool:
    return all(np.all(np.isfinite(x)) for x in _leaves(obj) if isinstance(x, np.ndarray) and x.dtype.kind in "fc")


@pytest.mark.parametrize("name,arg,case", _params())
def test_validation_table(name: str, arg: str, case: str) -> None:
    e = BY_NAME[name]
    exp = _expected(e, arg, case)
    role = e.roles[arg]
    bad = CASES[case](np.asarray(e.args[arg]), role)
    kw = dict(e.args, **{arg: bad})
    if exp in ("TypeError", "ValueError"):
        with pytest.raises((TypeError, ValueError)) as info:
            e.call(**kw)
        assert info.type is (TypeError if exp == "TypeError" else ValueError), f"{info.type.__name__}: {info.value}"
        assert _names(arg, str(info.value)), f"message does not name {arg!r}: {info.value}"
        return
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", abkit.AccuracyWarning)
        if exp in ("finite-or-ValueError", "accepted-analysis"):
            try:
                got = e.call(**kw)
            except np.linalg.LinAlgError:  # documented for the solvers: no (accurate) solution exists there
                return
            except ValueError as exc:
                assert _names(arg, str(exc)), f"message does not name {arg!r}: {exc}"
                return
            if exp == "finite-or-ValueError":
                assert _all_floats_finite(got), f"{name}({arg}={case}) returned non-finite values silently"
            return
        if exp == "finite-where-clean-or-ValueError":
            try:
                got = e.call(**kw)
            except ValueError as exc:
                assert _names(arg, str(exc)), f"message does not name {arg!r}: {exc}"
                return
            ref = e.call(**e.args)
            for a, b in ((got.states, ref.states), (got.residuals, ref.residuals)):
                if b is not None:
                    bad_ = np.isfinite(b) & ~np.isfinite(a)
                    assert not bad_.any(), f"{name}({arg}={case}) gave non-finite estimates silently at {np.argwhere(bad_)[:3].tolist()}"
            return
        if exp == "scaled":
            s = SCALE if case == "huge" else 1.0 / SCALE
            got = e.call(**kw).states
            ref = e.call(**e.args).states
            assert np.isfinite(ref).sum() > ref.size // 2
            np.testing.assert_array_equal(got, ref * s)
            return
        if exp == "same-float32":
            got = e.call(**kw).states
            ref = e.call(**dict(e.args, **{arg: _clean(bad)})).states
            assert got.dtype == np.float32, "float32 input must give float32 outputs"
            scale = np.nanmax(np.abs(ref), axis=tuple(range(1, ref.ndim)), keepdims=True)
            np.testing.assert_array_less(np.nan_to_num(np.abs(got - ref) / scale), 64 * np.finfo(np.float32).eps)
            assert np.array_equal(np.isnan(got), np.isnan(ref))
            return
        assert exp == "same", exp
        try:
            ref = e.call(**dict(e.args, **{arg: _clean(bad, role)}))
        except (ValueError, np.linalg.LinAlgError) as exc:  # e.g. bool/int values outside the domain
            with pytest.raises(type(exc)) as info:
                e.call(**kw)
            assert str(info.value) == str(exc)
            return
        got = e.call(**kw)
        assert _equal(got, ref), f"{name}({arg}={case}) differs from the call on a clean float64 copy"


# -- out= -----------------------------------------------------------------------

OUT_CASES = ("wrong-shape", "wrong-dtype", "aliases-input", "non-contiguous", "read-only", "not-an-array", "reused")


@pytest.mark.parametrize("name", [e.name for e in ENTRIES if e.out is not None])
@pytest.mark.parametrize("case", OUT_CASES)
def test_out_argument(name: str, case: str) -> None:
    e = BY_NAME[name]
    z = np.array(e.args["z"])
    shape = e.out(z)
    if case == "reused":  # the documented use: accepted, filled in place, reusable
        buf = np.full(shape, 123.0)
        first = e.call(z, out=buf)
        assert np.shares_memory(first.states, buf)
        ref = e.call(z)
        assert _equal(first.states, ref.states)
        e.call(z + 1.0, out=buf)
        assert _equal(buf, e.call(z + 1.0).states)
        return
    if case == "wrong-shape":
        out: Any = np.empty(shape[:-1] + (shape[-1] + 1,))
    elif case == "wrong-dtype":
        out = np.empty(shape, dtype=np.float32)
    elif case == "aliases-input":
        buf = np.zeros(int(np.prod(shape)) + z.size)
        zz = buf[: z.size].reshape(z.shape)
        zz[...] = z
        out = buf[z.size - 1 : z.size - 1 + int(np.prod(shape))].reshape(shape)  # overlaps z by one element
        z = zz
    elif case == "non-contiguous":
        out = np.empty(shape[:-1] + (2 * shape[-1],))[..., ::2]
    elif case == "read-only":
        out = np.empty(shape)
        out.flags.writeable = False
    else:
        out = np.empty(shape).tolist()
    with pytest.raises((TypeError, ValueError)) as info:
        e.call(z, out=out)
    assert _names("out", str(info.value)), f"message does not name out: {info.value}"


# -- the run keywords that are not arrays (docs/tracks.md) ----------------------------

#: (keyword, bad value, exception) for FixedGainFilter.run / smooth; the message must name the keyword
KEYWORD_CASES = [
    ("axes", 1, ValueError), ("axes", 4, ValueError), ("axes", 2.0, ValueError), ("axes", "2", ValueError), ("axes", True, ValueError),
    ("max_gap", 0.0, ValueError), ("max_gap", -1.0, ValueError), ("max_gap", float("nan"), ValueError), ("max_gap", "1", TypeError),
    ("max_gap", True, TypeError), ("max_gap", np.array([1.0, 2.0]), TypeError), ("max_gap", None, "no-t"),
    ("on_duplicate", "keep", ValueError), ("on_duplicate", None, ValueError), ("on_duplicate", 1, ValueError),
]


@pytest.mark.parametrize("method", ["run", "smooth"])
@pytest.mark.parametrize("kw,value,exc", KEYWORD_CASES, ids=[f"{k}={v!r}" for k, v, _ in KEYWORD_CASES])
def test_run_keywords(method: str, kw: str, value: Any, exc: Any) -> None:
    call = getattr(AB, method)
    z = np.stack([Z2, -Z2], axis=-1) if kw == "axes" else Z2
    if exc == "no-t":  # max_gap without timestamps: nothing to measure a gap with
        with pytest.raises(ValueError, match="max_gap"):
            call(Z2, max_gap=3.0)
        return
    with pytest.raises((TypeError, ValueError)) as info:
        call(z, **{kw: value}, **({} if kw == "axes" else {"t": TT}))
    assert info.type is exc, f"{info.type.__name__}: {info.value}"
    assert _names(kw, str(info.value)), f"message does not name {kw!r}: {info.value}"


# -- frame.filter: the DataFrame-specific bad inputs ----------------------------------
# (unknown column names, a string id column as a measurement, a non-filter, an existing
# estimate column and a NaN timestamp are in tests/test_frame.py::test_bad_input)


def _set(col: str, row: int, value: Any) -> Callable[[Any], Any]:
    def f(df: Any) -> Any:
        df = df.copy()
        df[col] = df[col].astype(object) if not isinstance(value, float) else df[col]
        df.loc[row, col] = value
        return df
    return f


def _retype(col: str, fn: Callable[[Any], Any]) -> Callable[[Any], Any]:
    def f(df: Any) -> Any:
        df = df.copy()
        df[col] = fn(df[col])
        return df
    return f


#: case -> (change to the DataFrame, keyword changes, exception, words the message must contain, also polars)
FRAME_CASES: Dict[str, Tuple[Optional[Callable[[Any], Any]], Dict[str, Any], Any, Tuple[str, ...], bool]] = {
    "columns-int": (None, dict(columns=3), TypeError, ("columns",), True),
    "columns-none": (None, dict(columns=None), TypeError, ("columns",), True),
    "columns-empty": (None, dict(columns=[]), ValueError, ("columns",), True),
    "columns-repeated": (None, dict(columns=["x", "x"]), ValueError, ("columns",), True),
    "id-none": (None, dict(id=None), TypeError, ("id",), True),
    "id-list": (None, dict(id=["id"]), TypeError, ("id",), True),
    "id-is-a-column": (None, dict(columns=["x", "id"]), ValueError, ("id",), True),
    "time-float": (None, dict(time=1.5), TypeError, ("time",), True),
    "time-is-id": (None, dict(time="id"), ValueError, ("time",), True),
    "time-inf": (_set("t", 5, np.inf), {}, ValueError, ("time", "row 5", "inf"), True),
    "time--inf": (_set("t", 9, -np.inf), {}, ValueError, ("time", "row 9", "inf"), True),
    "time-strings": (_retype("t", lambda s: s.astype(str)), {}, TypeError, ("time", "'t'"), True),
    "time-bool": (_retype("t", lambda s: s > 10), {}, TypeError, ("time", "'t'"), True),
    "time-complex": (_retype("t", lambda s: s.astype(complex)), {}, TypeError, ("time", "'t'"), False),
    "x-inf": (_set("x", 4, np.inf), {}, ValueError, ("'x'", "row 4"), True),
    "y--inf": (_set("y", 6, -np.inf), {}, ValueError, ("'y'", "row 6"), True),
    "x-bool": (_retype("x", lambda s: s > 0), {}, TypeError, ("'x'",), True),
    "x-strings": (_retype("x", lambda s: s.astype(str)), {}, TypeError, ("'x'",), True),
    "x-complex": (_retype("x", lambda s: s.astype(complex)), {}, TypeError, ("'x'",), False),
    "x-object-floats": (_retype("x", lambda s: s.astype(object)), {}, TypeError, ("'x'",), False),
    "id-missing": (_set("id", 3, np.nan), {}, ValueError, ("id", "row 3"), True),
    "max_gap-nan": (None, dict(max_gap=float("nan")), ValueError, ("max_gap",), True),
    "max_gap-string": (None, dict(max_gap="2"), TypeError, ("max_gap",), True),
    "on_duplicate-bad": (None, dict(on_duplicate="keep"), ValueError, ("on_duplicate",), True),
    "suffixes-short": (None, dict(suffixes=["p"]), ValueError, ("suffixes",), True),
}


@pytest.mark.parametrize("lib", ["pandas", "polars"])
@pytest.mark.parametrize("case", list(FRAME_CASES))
def test_frame_filter_bad_input(case: str, lib: str) -> None:
    change, kw, exc, words, polars_too = FRAME_CASES[case]
    fr = _frame()
    df = _long_frame()
    if change is not None:
        df = change(df)
    if lib == "polars":
        if not polars_too:
            pytest.skip("no such polars column (pandas-only dtype)")
        pl = pytest.importorskip("polars")
        df = pl.from_pandas(df)
    args = dict(id="id", time="t", columns=["x", "y"], filter=AB)
    args.update(kw)
    with pytest.raises((TypeError, ValueError)) as info:
        fr.filter(df, **args)
    assert info.type is exc, f"{info.type.__name__}: {info.value}"
    for w in words:
        assert w in str(info.value), f"message does not contain {w!r}: {info.value}"


def test_dask_filter_frame_delegates_validation() -> None:
    """dask.filter_frame runs frame.filter on each partition (and on the empty
    metadata frame up front): its bad arguments give frame.filter's errors."""
    adask = _dask()
    dd = _dd()
    ddf = dd.from_pandas(_long_frame().sort_values("id", kind="stable"), npartitions=3, sort=False)
    with pytest.raises(ValueError, match="columns: no column 'z'"):
        adask.filter_frame(ddf, id="id", time="t", columns=["x", "z"], filter=AB)
    with pytest.raises(ValueError, match="on_duplicate"):
        adask.filter_frame(ddf, id="id", time="t", columns="x", filter=AB, on_duplicate="keep")
    with pytest.raises(TypeError, match="columns"):
        adask.filter_frame(ddf, id="id", time="t", columns=3, filter=AB)
    bad = _set("t", 5, np.inf)(_long_frame().sort_values("id", kind="stable").reset_index(drop=True))
    with pytest.raises(ValueError, match=r"time column 't': timestamp at row \d+ is inf"):
        adask.filter_frame(dd.from_pandas(bad, npartitions=3, sort=False), id="id", time="t", columns="x", filter=AB).compute()
