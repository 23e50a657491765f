"""Figures. Needs matplotlib (``pip install abkit[plot]``).

Functions
---------
nomograph
    The alpha-beta design nomograph of Painter et al. (1990), Fig. 4.
"""

from __future__ import annotations

from typing import Any, Optional

import numpy as np

from . import alphabeta as _ab

__all__ = ["nomograph"]


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
