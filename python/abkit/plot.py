"""Figures. Needs matplotlib (``pip install abkit[plot]``).

Functions
---------
nomograph
    The alpha-beta design nomograph of Painter et al. (1990), Fig. 4.
singer_errors
    Normalised rms prediction errors of the Singer-model filter against
    p2 = sigma_m T^2 / sigma_pos, Yoon & Hong's Figs. 1-3.
"""

from __future__ import annotations

from typing import Any, Optional

import numpy as np

from . import alphabeta as _ab
from . import singer as _singer
from ._validate import as_float_array, check_positive

__all__ = ["nomograph", "singer_errors", "singer_tau_over_T"]


def _pyplot() -> Any:
    try:
        import matplotlib

        if matplotlib.get_backend().lower() not in ("agg", "pdf", "svg", "cairo") and not _has_display():
            matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:  # pragma: no cover - exercised only without matplotlib
        raise ImportError("abkit.plot needs matplotlib: pip install 'abkit[plot]'") from None
    return plt


def _has_display() -> bool:
    import os

    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def nomograph(ax: Optional[Any] = None, design: Optional[_ab.AlphaBeta] = None, n: int = 400) -> Any:
    r"""Draw the alpha-beta design nomograph (Painter et al. 1990, Fig. 4).

    For Kalman-optimal damping (``1/sqrt(2)``), plots against ``alpha`` (the
    normalised tracking error ``sigma_t^2/sigma_v^2``, eq (14)): ``beta``
    (eq (15)), the noise-bandwidth product ``B_N T`` (eq (16)) and the SNR
    ``10 log10 r`` in dB (eqs (9), (14)), each on its own axis. All curves are
    computed from the equations through :func:`abkit.alphabeta.from_tracking_error`.

    Parameters
    ----------
    ax : matplotlib Axes, optional
        Axes to draw on; a new figure is made if omitted.
    design : AlphaBeta, optional
        A scalar Kalman design to mark (vertical line at its ``alpha`` and
        markers on each curve), as in the paper's worked example.
    n : int, optional
        Number of points per curve.

    Returns
    -------
    matplotlib Axes
        The ``alpha``/``beta`` axes; the ``B_N T`` and SNR axes are its twins.

    Notes
    -----
    The paper's SNR scale is read off its chart; the curves here are the
    equations, which disagree with the chart-read numbers of the paper's
    example (``docs/errata.md``).

    Examples
    --------
    >>> import matplotlib
    >>> matplotlib.use("Agg")
    >>> from abkit import alphabeta, plot
    >>> ax = plot.nomograph(design=alphabeta.from_snr(0.1))
    >>> ax.get_xlabel()
    'alpha = normalised tracking error variance  sigma_t^2 / sigma_v^2'
    """
    plt = _pyplot()
    if ax is None:
        _, ax = plt.subplots(figsize=(8.0, 6.0), constrained_layout=True)
    if n < 2:
        raise ValueError(f"n must be >= 2, got {n}")
    alpha = np.linspace(0.0, 1.0, n + 2)[1:-1]
    d = _ab.from_tracking_error(alpha)
    c_beta, c_bw, c_snr = "C0", "C1", "C2"
    ax.plot(alpha, d.beta, color=c_beta, label="beta")
    ax.set_xlim(0.0, 1.0)
    ax.set_ylim(0.0, 2.0)
    ax.set_xlabel("alpha = normalised tracking error variance  sigma_t^2 / sigma_v^2")
    ax.set_ylabel("beta", color=c_beta)
    ax.grid(True, alpha=0.3)

    ax_bw = ax.twinx()
    ax_bw.plot(alpha, d.bandwidth_T, color=c_bw, label="B_N T")
    ax_bw.set_ylim(0.0, 0.25)
    ax_bw.set_ylabel("B_N T (noise bandwidth x period)", color=c_bw)

    ax_snr = ax.twinx()
    ax_snr.spines["right"].set_position(("axes", 1.13))
    ax_snr.plot(alpha, d.snr_db, color=c_snr, label="SNR (dB)")
    ax_snr.set_ylim(-80.0, 40.0)
    ax_snr.set_ylabel("SNR = 10 log10 r  (dB)", color=c_snr)

    if design is not None:
        if design.shape != ():
            raise ValueError("design must be a scalar AlphaBeta design")
        a = design.alpha
        ax.axvline(a, color="0.4", lw=0.8, ls="--")
        ax.plot([a], [design.beta], "o", color=c_beta)
        ax_bw.plot([a], [design.bandwidth_T], "s", color=c_bw)
        ax_snr.plot([a], [design.snr_db], "^", color=c_snr)
        ax.set_title(
            f"alpha={a:.4g}, beta={design.beta:.4g}, B_N T={design.bandwidth_T:.4g}, SNR={design.snr_db:.4g} dB"
        )
    else:
        ax.set_title("Alpha-beta design nomograph (Kalman-optimal damping 1/sqrt(2))")
    lines = ax.get_lines()[:1] + ax_bw.get_lines()[:1] + ax_snr.get_lines()[:1]
    ax.legend(lines, [ln.get_label() for ln in lines], loc="upper left")
    return ax


def singer_tau_over_T(p2: Any, factor: float = 1.0) -> np.ndarray:
    """The paper's parametrisation of Figs. 1-3: ``tau/T = factor [0.56 + 3.4 p2^-0.86]^(1/2)``.

    ``factor = 1`` is the solid curves, ``factor = 10`` the dotted ones.
    """
    p2 = as_float_array("p2", p2)
    check_positive("p2", p2)
    return factor * np.sqrt(0.56 + 3.4 * p2**-0.86)


def singer_errors(
    axes: Optional[Any] = None,
    p2: Optional[Any] = None,
    sigma_vel_ratio: Optional[float] = None,
    factors: Any = (1.0, 10.0),
    method: str = "auto",
) -> Any:
    r"""Normalised rms prediction errors of the Singer filter (Yoon & Hong, Figs. 1-3).

    For each ``p2 = sigma_m T^2 / sigma_pos`` the correlation time follows the
    paper's parametrisation ``tau/T = f [0.56 + 3.4 p2^-0.86]^(1/2)`` with
    ``f = 1`` (solid) and ``f = 10`` (dotted), and the steady state comes from
    :func:`abkit.singer.steady_state`. Plotted (log-log): ``sqrt(P11)/sigma_pos``,
    ``sqrt(P22) T/sigma_pos``, ``sqrt(P33) T^2/sigma_pos`` of the prediction
    covariance ``P_pred``.

    Parameters
    ----------
    axes : sequence of three matplotlib Axes, optional
        New figure with three panels if omitted.
    p2 : array_like, optional
        Abscissa values (default ``logspace(-3, 3, 61)``).
    sigma_vel_ratio : float, optional
        ``sigma_vel T / sigma_pos`` for position-and-velocity measurements;
        ``None`` (default) is position only. The transcription of the paper
        does not state the velocity accuracy used in its figures.
    factors : sequence of float
        The factors ``f`` of the parametrisation (the paper: 1 and 10).
    method : str
        Passed to :func:`abkit.singer.steady_state`.

    Returns
    -------
    list of three matplotlib Axes
        Position, velocity, acceleration; one line per factor, in order.

    Examples
    --------
    >>> import matplotlib
    >>> matplotlib.use("Agg")
    >>> from abkit import plot
    >>> axes = plot.singer_errors(p2=[0.01, 1.0, 100.0])
    >>> [ax.get_ylabel() for ax in axes]
    ['sqrt(P11) / sigma_pos', 'sqrt(P22) T / sigma_pos', 'sqrt(P33) T^2 / sigma_pos']
    """
    plt = _pyplot()
    x = np.logspace(-3, 3, 61) if p2 is None else as_float_array("p2", p2).ravel()
    if x.size == 0:
        raise ValueError("p2 must not be empty")
    check_positive("p2", x)
    if axes is None:
        _, axes = plt.subplots(3, 1, figsize=(6.0, 10.0), constrained_layout=True, sharex=True)
    axes = list(axes)
    if len(axes) != 3:
        raise ValueError(f"axes must be three Axes, got {len(axes)}")
    styles = ["-", ":", "--", "-."]
    labels = ["sqrt(P11) / sigma_pos", "sqrt(P22) T / sigma_pos", "sqrt(P33) T^2 / sigma_pos"]
    for k, f in enumerate(factors):
        tau = singer_tau_over_T(x, f)
        try:
            s = _singer.steady_state(1.0, tau, x, 1.0, sigma_vel_ratio, method=method)
        except ValueError as exc:
            raise type(exc)(f"p2 is outside the range this figure can be computed for: {exc}") from None
        for ax, y in zip(axes, (s.rms_position, s.rms_velocity, s.rms_acceleration)):
            ax.loglog(x, np.atleast_1d(y), styles[k % 4], color="k", label=f"tau/T = {f:g} [0.56 + 3.4 p2^-0.86]^1/2")
    for ax, lab, title in zip(axes, labels, ("Fig. 1: position", "Fig. 2: velocity", "Fig. 3: acceleration")):
        ax.set_ylabel(lab)
        ax.set_title(f"{title} (normalised rms prediction error)")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(loc="best", fontsize="small")
    axes[-1].set_xlabel("p2 = sigma_m T^2 / sigma_pos")
    return axes
