"""Figures. Needs matplotlib (``pip install abkit[plot]``).

Functions
---------
nomograph
    The alpha-beta design nomograph of Painter et al. (1990), Fig. 4.
singer_errors
    Normalised rms prediction errors of the Singer-model filter against
    p2 = sigma_m T^2 / sigma_pos, Yoon & Hong's Figs. 1-3.
frequency_response
    Magnitude and phase of a fixed-gain filter's position and velocity
    transfer functions (from its state-space form).
pole_zero
    Pole-zero map of a fixed-gain filter with the unit circle.
gain_convergence
    The Kalman recursion's gains converging to the steady-state gain.
track
    Measurements, estimates, residuals (and errors against the truth) of a
    filtered track, missed detections marked.
"""

from __future__ import annotations

from typing import Any, Dict, NamedTuple, Optional, Sequence, Tuple

import numpy as np

from . import alphabeta as _ab
from . import singer as _singer

__all__ = [
    "nomograph",
    "singer_errors",
    "singer_tau_over_T",
    "frequency_response",
    "transfer_response",
    "transfer_zeros",
    "pole_zero",
    "gain_convergence",
    "track",
    "FrequencyResponse",
    "PoleZero",
    "GainConvergence",
]


def _pyplot() -> Any:
    try:
        import matplotlib

        if matplotlib.get_backend().lower() not in ("agg", "pdf", "svg", "cairo") and not _has_display():
            matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:  # exercised in tests by hiding matplotlib
        raise ImportError("abkit.plot needs matplotlib: install it with pip install 'abkit[plot]'") from None
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
    p2 = np.asarray(p2, dtype=float)
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
    x = np.logspace(-3, 3, 61) if p2 is None else np.asarray(p2, dtype=float).ravel()
    if axes is None:
        _, axes = plt.subplots(3, 1, figsize=(6.0, 10.0), constrained_layout=True, sharex=True)
    axes = list(axes)
    if len(axes) != 3:
        raise ValueError(f"axes must be three Axes, got {len(axes)}")
    styles = ["-", ":", "--", "-."]
    labels = ["sqrt(P11) / sigma_pos", "sqrt(P22) T / sigma_pos", "sqrt(P33) T^2 / sigma_pos"]
    for k, f in enumerate(factors):
        tau = singer_tau_over_T(x, f)
        s = _singer.steady_state(1.0, tau, x, 1.0, sigma_vel_ratio, method=method)
        for ax, y in zip(axes, (s.rms_position, s.rms_velocity, s.rms_acceleration)):
            ax.loglog(x, np.atleast_1d(y), styles[k % 4], color="k", label=f"tau/T = {f:g} [0.56 + 3.4 p2^-0.86]^1/2")
    for ax, lab, title in zip(axes, labels, ("Fig. 1: position", "Fig. 2: velocity", "Fig. 3: acceleration")):
        ax.set_ylabel(lab)
        ax.set_title(f"{title} (normalised rms prediction error)")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(loc="best", fontsize="small")
    axes[-1].set_xlabel("p2 = sigma_m T^2 / sigma_pos")
    return axes


# -- filters -------------------------------------------------------------------


def _one_filter(filt: Any, name: str = "filt") -> Tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """(Phi, H, K, T) of a filter with one parameter set."""
    from .filters import FixedGainFilter

    if not isinstance(filt, FixedGainFilter):
        raise TypeError(f"{name} must be an abkit filter (FixedGainFilter, AlphaBetaFilter, AlphaBetaGammaFilter), got {type(filt).__name__}")
    if filt.n_params != 1:
        raise ValueError(f"{name} has {filt.n_params} per-track parameter sets; plot one design at a time")
    return np.asarray(filt.Phi, float), np.asarray(filt.H, float), np.asarray(filt.K, float), float(filt._t[0])


_STATE_NAMES = ("position", "velocity", "acceleration", "state 3", "state 4", "state 5")


class FrequencyResponse(NamedTuple):
    """Result of :func:`frequency_response`.

    Attributes
    ----------
    axes : list of two matplotlib Axes
        Magnitude (dB) and phase (degrees).
    w : ndarray, shape (n_freq,)
        Frequencies in radians per sample, in ``(0, pi]``.
    freq : ndarray, shape (n_freq,)
        The same in Hz, ``w / (2 pi T)``.
    response : complex ndarray, shape (n_states, n_freq)
        ``H_i(e^{jw})``: the response of each state estimate to the
        measurement (component ``measurement``), in the state's units per
        measurement unit (velocity: 1/s).
    states : tuple of int
        The state indices of ``response``'s rows.
    """

    axes: Any
    w: np.ndarray
    freq: np.ndarray
    response: np.ndarray
    states: Tuple[int, ...]


def transfer_response(filt: Any, w: Any, measurement: int = 0) -> np.ndarray:
    r"""Frequency response of every state estimate of a fixed-gain filter.

    The filter ``x_k = A x_{k-1} + K z_k`` with ``A = (I - K H) Phi`` has the
    transfer function ``X(z) = z (z I - A)^{-1} K Z(z)``; this evaluates it
    on the unit circle.

    Parameters
    ----------
    filt : FixedGainFilter
        Any abkit fixed-gain filter with one parameter set.
    w : array_like
        Frequencies in radians per sample.
    measurement : int
        Which measurement component drives the response (vector measurements).

    Returns
    -------
    complex ndarray, shape (n, len(w))

    Examples
    --------
    >>> from abkit import AlphaBetaFilter, plot
    >>> h = plot.transfer_response(AlphaBetaFilter(0.5, 0.2, 1.0), [0.0])
    >>> complex(h[0, 0]), complex(h[1, 0])  # unit DC gain on position, none on velocity
    ((1+0j), 0j)
    """
    phi, h, k, _ = _one_filter(filt)
    n, m = phi.shape[0], h.shape[0]
    if not isinstance(measurement, (int, np.integer)) or not 0 <= measurement < m:
        raise ValueError(f"measurement must be an integer in [0, {m}), got {measurement!r}")
    a = (np.eye(n) - k @ h) @ phi
    ww = np.asarray(w, dtype=float).ravel()
    z = np.exp(1j * ww)
    out = np.empty((n, ww.size), dtype=complex)
    for i, zi in enumerate(z):
        out[:, i] = zi * np.linalg.solve(zi * np.eye(n) - a, k[:, measurement])
    return out


def frequency_response(
    filt: Any,
    axes: Optional[Any] = None,
    n: int = 512,
    states: Optional[Sequence[int]] = None,
    measurement: int = 0,
    w_min: float = 1e-3,
) -> FrequencyResponse:
    r"""Magnitude and phase of a filter's position and velocity responses.

    Computed from the state-space form (``Phi``, ``H``, ``K``) by
    :func:`transfer_response` on ``n`` log-spaced frequencies from
    ``w_min * pi`` to ``pi`` radians per sample (the Nyquist frequency).

    Parameters
    ----------
    filt : FixedGainFilter
        An :class:`abkit.FixedGainFilter`, :class:`abkit.AlphaBetaFilter` or
        :class:`abkit.AlphaBetaGammaFilter` with one parameter set.
    axes : sequence of two matplotlib Axes, optional
        Magnitude and phase panels; a new figure if omitted.
    n : int
        Number of frequencies (>= 2).
    states : sequence of int, optional
        State indices to plot (default: position and velocity, or all states
        of a one-state filter).
    measurement : int
        Measurement component driving the response.
    w_min : float
        Lowest frequency as a fraction of Nyquist, in (0, 1).

    Returns
    -------
    FrequencyResponse
        The axes and the computed arrays.

    Notes
    -----
    Position follows a constant-velocity input without lag at DC (0 dB) and
    peaks near the filter's natural frequency; the velocity estimate behaves
    as a differentiator (``+20 dB/decade``) at low frequency, ``|H_v| ~ w/T``.

    Examples
    --------
    >>> import matplotlib
    >>> matplotlib.use("Agg")
    >>> from abkit import AlphaBetaFilter, plot
    >>> fr = plot.frequency_response(AlphaBetaFilter(0.5, 0.2, 0.1), n=64)
    >>> fr.response.shape, fr.states
    ((2, 64), (0, 1))
    >>> round(float(fr.freq[-1]), 6)  # Nyquist of T = 0.1 s
    5.0
    """
    phi, _, _, t = _one_filter(filt)
    if not isinstance(n, (int, np.integer)) or n < 2:
        raise ValueError(f"n must be an integer >= 2, got {n!r}")
    if not 0.0 < w_min < 1.0:
        raise ValueError(f"w_min must be in (0, 1), got {w_min!r}")
    nx = phi.shape[0]
    st = tuple(range(min(2, nx))) if states is None else tuple(int(s) for s in states)
    if not st or any(not 0 <= s < nx for s in st):
        raise ValueError(f"states must be indices in [0, {nx}), got {states!r}")
    w = np.pi * np.logspace(np.log10(w_min), 0.0, int(n))
    resp = transfer_response(filt, w, measurement)[list(st)]
    freq = w / (2 * np.pi * t)
    plt = _pyplot()
    if axes is None:
        _, axes = plt.subplots(2, 1, figsize=(7.0, 6.5), sharex=True, constrained_layout=True)
    axes = list(np.ravel(axes))
    if len(axes) != 2:
        raise ValueError(f"axes must be two Axes (magnitude, phase), got {len(axes)}")
    units = {0: "", 1: " (1/s)", 2: " (1/s^2)"}
    for i, s in enumerate(st):
        lab = _STATE_NAMES[s] + units.get(s, "")
        with np.errstate(divide="ignore"):
            axes[0].semilogx(freq, 20 * np.log10(np.abs(resp[i])), color=f"C{i}", label=lab)
        axes[1].semilogx(freq, np.degrees(np.unwrap(np.angle(resp[i]))), color=f"C{i}", label=lab)
    axes[0].set_ylabel("magnitude (dB)")
    axes[1].set_ylabel("phase (degrees)")
    axes[1].set_xlabel(f"frequency (Hz; T = {t:g} s, Nyquist {1 / (2 * t):g} Hz)")
    axes[0].set_title(f"Frequency response of {type(filt).__name__}: estimate per unit measurement")
    for ax in axes:
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(loc="best")
    return FrequencyResponse(axes, w, freq, resp, st)


class PoleZero(NamedTuple):
    """Result of :func:`pole_zero`: the Axes, the closed-loop ``poles``
    (eigenvalues of ``(I - K H) Phi``) and ``zeros``, a dict from state index
    to the zeros of that state's transfer function (the pole-zero
    cancellations of a non-minimal realisation are not removed)."""

    ax: Any
    poles: np.ndarray
    zeros: Dict[int, np.ndarray]


def transfer_zeros(filt: Any, state: int, measurement: int = 0) -> np.ndarray:
    r"""Zeros of one state's transfer function ``z e_i^T (zI - A)^{-1} K``.

    By the matrix determinant lemma the numerator of
    ``c (zI - A)^{-1} b`` is ``det(zI - A + b c) - det(zI - A)``, so the
    zeros are ``0`` and the roots of that polynomial difference.

    Examples
    --------
    >>> from abkit import AlphaBetaFilter, plot
    >>> [round(float(v), 12) for v in plot.transfer_zeros(AlphaBetaFilter(0.5, 0.2, 1.0), 0)]
    [0.0, 0.6]
    """
    phi, h, k, _ = _one_filter(filt)
    n, m = phi.shape[0], h.shape[0]
    if not isinstance(state, (int, np.integer)) or not 0 <= state < n:
        raise ValueError(f"state must be an integer in [0, {n}), got {state!r}")
    if not isinstance(measurement, (int, np.integer)) or not 0 <= measurement < m:
        raise ValueError(f"measurement must be an integer in [0, {m}), got {measurement!r}")
    a = (np.eye(n) - k @ h) @ phi
    b = k[:, measurement : measurement + 1]
    c = np.eye(n)[state : state + 1]
    num = np.poly(a - b @ c) - np.poly(a)
    scale = max(1.0, float(np.max(np.abs(np.poly(a)))))
    nz = np.flatnonzero(np.abs(num) > 1e-12 * scale)
    if nz.size == 0:
        return np.zeros(0)
    roots = np.roots(num[nz[0]:])
    zs = np.concatenate([[0.0], roots])
    return np.sort_complex(zs) if np.iscomplexobj(zs) else np.sort(zs)


def pole_zero(
    filt: Any,
    ax: Optional[Any] = None,
    states: Optional[Sequence[int]] = None,
    measurement: int = 0,
) -> PoleZero:
    r"""Pole-zero map of a fixed-gain filter, with the unit circle.

    Poles (``x``) are the eigenvalues of the closed loop ``(I - K H) Phi``
    (inside the unit circle for a stable filter, :attr:`FixedGainFilter.spectral_radius`);
    zeros (``o``) those of the position and velocity transfer functions
    (:func:`transfer_zeros`).

    Parameters
    ----------
    filt : FixedGainFilter
        Any abkit fixed-gain filter with one parameter set.
    ax : matplotlib Axes, optional
    states : sequence of int, optional
        States whose zeros are drawn (default position and velocity).
    measurement : int
        Measurement component (vector measurements).

    Returns
    -------
    PoleZero

    Examples
    --------
    >>> import matplotlib
    >>> matplotlib.use("Agg")
    >>> from abkit import AlphaBetaFilter, plot
    >>> pz = plot.pole_zero(AlphaBetaFilter(0.5, 0.2, 1.0))
    >>> bool(max(abs(pz.poles)) < 1)
    True
    """
    phi, h, k, _ = _one_filter(filt)
    nx = phi.shape[0]
    st = tuple(range(min(2, nx))) if states is None else tuple(int(s) for s in states)
    if not st or any(not 0 <= s < nx for s in st):
        raise ValueError(f"states must be indices in [0, {nx}), got {states!r}")
    poles = np.linalg.eigvals((np.eye(nx) - k @ h) @ phi)
    zeros = {s: transfer_zeros(filt, s, measurement) for s in st}
    plt = _pyplot()
    if ax is None:
        _, ax = plt.subplots(figsize=(6.0, 6.0), constrained_layout=True)
    th = np.linspace(0.0, 2 * np.pi, 721)
    ax.plot(np.cos(th), np.sin(th), color="0.5", lw=0.8, label="unit circle")
    ax.axhline(0.0, color="0.8", lw=0.6)
    ax.axvline(0.0, color="0.8", lw=0.6)
    ax.plot(poles.real, poles.imag, "x", color="k", ms=10, mew=2, ls="none", label="poles (closed loop)")
    markers = ["o", "s", "D", "^", "v", "<"]
    for i, s in enumerate(st):
        zz = np.asarray(zeros[s], dtype=complex)
        ax.plot(zz.real, zz.imag, markers[i % 6], mfc="none", color=f"C{i}", ms=9 + 3 * i, mew=1.5, ls="none",
                label=f"zeros ({_STATE_NAMES[s]})")
    rho = float(np.max(np.abs(poles)))
    ax.set_aspect("equal")
    lim = max(1.1, 1.1 * max([rho] + [float(np.max(np.abs(z))) for z in zeros.values() if z.size]))
    ax.set_xlim(-lim, lim)
    ax.set_ylim(-lim, lim)
    ax.set_xlabel("Re z")
    ax.set_ylabel("Im z")
    ax.set_title(f"Pole-zero map of {type(filt).__name__} (spectral radius {rho:.4g})")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="lower left", fontsize="small")
    return PoleZero(ax, poles, zeros)


# -- Kalman gain convergence -----------------------------------------------------


class GainConvergence(NamedTuple):
    """Result of :func:`gain_convergence`: the two Axes, the gains ``K``
    (n_steps, n, m) of :func:`abkit.kalman.gain_sequence`, the steady-state
    gain ``K_inf`` (n, m) of :func:`abkit.riccati.kalman_steady_state`, and
    ``rel_error`` (n_steps,), ``max |K_k - K_inf| / max |K_inf|``."""

    axes: Any
    K: np.ndarray
    K_inf: np.ndarray
    rel_error: np.ndarray


def gain_convergence(kf: Any, n: int = 60, axes: Optional[Any] = None) -> GainConvergence:
    r"""Gains of the Kalman recursion converging to the steady-state gain.

    Top: every component of ``K_k`` (the filter-form gain of paper 002's
    loop, :func:`abkit.kalman.gain_sequence`) against ``k``, with the
    steady-state gain of the DARE (:func:`abkit.riccati.kalman_steady_state`)
    dashed. Bottom: the relative distance ``max|K_k - K_inf| / max|K_inf|``
    on a log scale (geometric convergence at the rate of the closed-loop
    spectral radius, paper 004 Lemma 1).

    Parameters
    ----------
    kf : KalmanFilter
        The model and prior (:class:`abkit.KalmanFilter`).
    n : int
        Number of steps (>= 1).
    axes : sequence of two matplotlib Axes, optional

    Returns
    -------
    GainConvergence

    Examples
    --------
    >>> import matplotlib
    >>> matplotlib.use("Agg")
    >>> import numpy as np
    >>> from abkit import KalmanFilter, plot
    >>> kf = KalmanFilter([[1, 1], [0, 1]], [[1, 0]], np.diag([0.0, 0.01]), 1.0, P0=np.eye(2) * 100)
    >>> gc = plot.gain_convergence(kf, n=200)
    >>> bool(gc.rel_error[-1] < 1e-6)
    True
    """
    from . import riccati
    from .kalman import KalmanFilter

    if not isinstance(kf, KalmanFilter):
        raise TypeError(f"kf must be an abkit.KalmanFilter, got {type(kf).__name__}")
    if not isinstance(n, (int, np.integer)) or isinstance(n, bool) or n < 1:
        raise ValueError(f"n must be a positive integer, got {n!r}")
    g = kf.gain_sequence(int(n))
    ss = riccati.kalman_steady_state(kf.F, kf.H, kf.Q, kf.R)
    k_inf = np.asarray(ss.K)
    scale = max(float(np.max(np.abs(k_inf))), 1e-300)
    rel = np.max(np.abs(g.K - k_inf[None]), axis=(1, 2)) / scale
    plt = _pyplot()
    if axes is None:
        _, axes = plt.subplots(2, 1, figsize=(7.0, 6.5), sharex=True, constrained_layout=True)
    axes = list(np.ravel(axes))
    if len(axes) != 2:
        raise ValueError(f"axes must be two Axes, got {len(axes)}")
    steps = np.arange(int(n))
    nx, nz = k_inf.shape
    c = 0
    for i in range(nx):
        for j in range(nz):
            lab = f"K[{i},{j}]" if nz > 1 else f"K[{i}] ({_STATE_NAMES[i]})"
            axes[0].plot(steps, g.K[:, i, j], "-", marker=".", ms=3, color=f"C{c % 10}", label=lab)
            axes[0].axhline(k_inf[i, j], color=f"C{c % 10}", ls="--", lw=0.9)
            c += 1
    axes[0].set_ylabel("gain K_k (dashed: steady state)")
    axes[0].set_title("Kalman gain convergence to the steady-state (DARE) gain")
    axes[0].legend(loc="best", fontsize="small")
    pos = np.where(rel > 0, rel, np.nan)
    axes[1].semilogy(steps, pos, "k.-", ms=3)
    axes[1].set_ylabel("max|K_k - K_inf| / max|K_inf|")
    axes[1].set_xlabel("step k")
    for ax in axes:
        ax.grid(True, which="both", alpha=0.3)
    return GainConvergence(axes, g.K, k_inf, rel)


# -- tracks ------------------------------------------------------------------------


def track(
    result: Any,
    z: Any,
    truth: Optional[Any] = None,
    index: int = 0,
    T: float = 1.0,
    t0: float = 0.0,
    axes: Optional[Any] = None,
) -> Any:
    r"""Measurements, estimates, residuals (and errors against the truth) of one track.

    Panels: (1) measurements (dots), position estimate (line), truth (thin
    grey, if given), missed detections (NaN measurements) as ticks along the
    bottom; (2) residuals ``z - H x_p`` (needs ``return_residuals=True``;
    NaN gaps stay gaps); (3) if ``truth`` is given, the position error
    ``estimate - truth``.

    Parameters
    ----------
    result : FilterResult
        From ``run``/``smooth`` of an abkit filter (scalar measurements).
    z : array_like
        The measurements that were filtered, ``(n_samples,)`` or
        ``(n_tracks, n_samples)``.
    truth : array_like, optional
        True positions, shaped like ``z``.
    index : int
        Track to draw (ignored for a single track).
    T, t0 : float
        Sampling period and start time of the time axis.
    axes : sequence of matplotlib Axes, optional
        Two (no truth) or three (with truth) Axes.

    Returns
    -------
    list of matplotlib Axes

    Examples
    --------
    >>> import matplotlib
    >>> matplotlib.use("Agg")
    >>> import numpy as np
    >>> from abkit import AlphaBetaFilter, plot
    >>> z = np.arange(20.0); z[5] = np.nan
    >>> r = AlphaBetaFilter(0.5, 0.2, 1.0).run(z, return_residuals=True)
    >>> len(plot.track(r, z, truth=np.arange(20.0)))
    3
    """
    from .filters import FilterResult

    if not isinstance(result, FilterResult):
        raise TypeError(f"result must be a FilterResult (from run or smooth), got {type(result).__name__}")
    zz = np.asarray(z, dtype=float)
    pos = np.asarray(result.position)
    if zz.shape != pos.shape:
        raise ValueError(f"z must have the result's sample shape {pos.shape} (scalar measurements), got {zz.shape}")
    res = None if result.residuals is None else np.asarray(result.residuals)
    tr = None
    if truth is not None:
        tr = np.asarray(truth, dtype=float)
        if tr.shape != zz.shape:
            raise ValueError(f"truth must have the shape of z {zz.shape}, got {tr.shape}")
    if zz.ndim == 2:
        if not isinstance(index, (int, np.integer)) or not -zz.shape[0] <= index < zz.shape[0]:
            raise ValueError(f"index must be a track index in [0, {zz.shape[0]}), got {index!r}")
        zz, pos = zz[index], pos[index]
        res = None if res is None else res[index]
        tr = None if tr is None else tr[index]
    if not (np.isfinite(T) and T > 0):
        raise ValueError(f"T must be > 0, got {T!r}")
    t = t0 + T * np.arange(zz.size)
    plt = _pyplot()
    npan = 3 if tr is not None else 2
    if axes is None:
        _, axes = plt.subplots(npan, 1, figsize=(8.0, 2.6 * npan + 0.8), sharex=True, constrained_layout=True)
    axes = list(np.ravel(axes))
    if len(axes) != npan:
        raise ValueError(f"axes must be {npan} Axes ({'with' if tr is not None else 'without'} truth), got {len(axes)}")
    miss = np.isnan(zz)
    ax = axes[0]
    ax.plot(t, zz, ".", color="C0", ms=3, label="measurements")
    ax.plot(t, pos, "-", color="C1", lw=1.3, label="estimate")
    if tr is not None:
        ax.plot(t, tr, "-", color="0.3", lw=0.8, label="truth")
    if miss.any():
        ax.plot(t[miss], np.full(int(miss.sum()), 0.02), "|", color="C3", ms=8,
                transform=ax.get_xaxis_transform(), label=f"missed ({int(miss.sum())})")
    ax.set_ylabel("position")
    ax.set_title("Track: measurements, estimates" + (", truth" if tr is not None else ""))
    ax.legend(loc="best", fontsize="small")
    ax = axes[1]
    if res is not None:
        ax.plot(t, res, "-", color="C2", lw=0.8, label="residual z - H x_p")
        ax.axhline(0.0, color="0.5", lw=0.6)
    else:
        ax.text(0.5, 0.5, "no residuals (run with return_residuals=True)", ha="center", va="center", transform=ax.transAxes)
    ax.set_ylabel("residual")
    if tr is not None:
        ax = axes[2]
        ax.plot(t, pos - tr, "-", color="C1", lw=0.8, label="estimate - truth")
        ax.plot(t, zz - tr, ".", color="C0", ms=2, alpha=0.5, label="measurement - truth")
        ax.axhline(0.0, color="0.5", lw=0.6)
        ax.set_ylabel("position error")
        ax.legend(loc="best", fontsize="small")
    axes[-1].set_xlabel("time")
    for a in axes:
        a.grid(True, alpha=0.3)
    return axes
