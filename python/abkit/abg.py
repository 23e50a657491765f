r"""Near-optimal alpha-beta-gamma filters (Chen & Chui, paper 004).

The alpha-beta-gamma filter tracks position, velocity and acceleration from
noisy position measurements taken every ``h`` seconds::

    predict:  y_p = Phi y,       Phi = [[1, h, h^2/2], [0, 1, h], [0, 0, 1]]
    update:   y   = y_p + w (z - y_p[0])

It is *near-optimal* (Chen & Chui) when ``Phi w`` is the limiting Kalman
gain of the model with process noise ``Q = diag(sigma_p, sigma_v, sigma_a)``
and measurement noise ``R = sigma_m`` (all four are *variances*, the paper's
notation). This module designs such filters from the noise
(:func:`from_noise`, :func:`from_tracking_index`), goes back from gains to
noise (:func:`noise_ratios`, :func:`is_near_optimal`), analyses any gains
(:func:`analyze`), and covers the paper's coloured-measurement-noise
alpha-beta-gamma-theta filter (:func:`coloured`) and the decoupled recursive
(IIR) forms of its Theorem 3 (:func:`decoupled`).

Conventions
-----------
Published alpha-beta-gamma filters disagree on what ``gamma`` means. The
filter-form gain ``w`` for ``(alpha, beta, gamma)`` is

==============  ===========================================  =====================
convention      ``w``                                        used by
==============  ===========================================  =====================
``chen-chui``   ``[alpha, beta/h, gamma/h^2]``               paper 004 (default here)
``standard``    ``[alpha, beta/h, gamma/(2 h^2)]``           Bar-Shalom, Kalata, tracklib
``ghk``         ``[g, h_/h, 2 k/h^2]``                       FilterPy's g-h-k filter
==============  ===========================================  =====================

(:data:`CONVENTIONS` is :data:`abkit.filters.ABG_CONVENTIONS`, the factor on
``gamma/h^2``.) Every function here takes ``convention=`` for the gains it
accepts or returns; :func:`convert` translates. The *predictor-form* gain is
``K = Phi w`` (the one-step predictor ``y_p+ = Phi y_p + K (z - y_p[0])``);
:func:`to_predictor` and :func:`from_predictor` translate.

Units of the analysis
---------------------
Covariances and variance reduction ratios are normalised: position in units
of ``sigma_m`` (variance), velocity of ``sigma_m / h^2``, acceleration of
``sigma_m / h^4``. Lags under a constant jerk ``j`` are in units of
``j h^3`` (position), ``j h^2`` (velocity), ``j h`` (acceleration).

References
----------
.. [1] G. Chen, C. K. Chui, "On near-optimal linear digital tracking
   filters" (paper 004). Printed formulas that failed their numerical check
   are listed in ``docs/errata.md`` (section "Paper 004").
.. [2] Y. Bar-Shalom, X. R. Li, T. Kirubarajan, *Estimation with
   Applications to Tracking and Navigation*, Wiley 2001, sec. 6.5.
"""

from __future__ import annotations

import math
from typing import Any, Dict, NamedTuple, Optional, Tuple, Union

import numpy as np

from . import _abkit
from ._results import FloatOrArray, RowResult, call_binding, out_value
from ._validate import as_float_array, broadcast, check_positive, check_representable
from .filters import ABG_CONVENTIONS

__all__ = [
    "ABG",
    "CONVENTIONS",
    "Coloured",
    "ColouredGains",
    "Decoupled",
    "Gains",
    "NoiseRatios",
    "StabilityMargins",
    "analyze",
    "coloured",
    "coloured_from_noise",
    "convert",
    "decoupled",
    "from_noise",
    "from_predictor",
    "from_tracking_index",
    "is_near_optimal",
    "noise_ratios",
    "stability_region",
    "to_predictor",
]

#: The alpha-beta-gamma conventions: the factor ``c`` in ``w[2] = c gamma / h^2``.
CONVENTIONS = ABG_CONVENTIONS

ArrayLike = Any

_FIELDS = tuple(_abkit.ABG_FIELDS)
_IDX = {name: i for i, name in enumerate(_FIELDS)}
_CFIELDS = tuple(_abkit.ABG_COLOURED_FIELDS)


class Gains(NamedTuple):
    """Alpha-beta-gamma gains in one convention."""

    alpha: FloatOrArray
    beta: FloatOrArray
    gamma: FloatOrArray


class NoiseRatios(NamedTuple):
    """``sigma_p / sigma_m``, ``sigma_v / sigma_m``, ``sigma_a / sigma_m`` (ratios of variances)."""

    sigma_p: FloatOrArray
    sigma_v: FloatOrArray
    sigma_a: FloatOrArray


class VarianceReduction(NamedTuple):
    """Noise-only output variance over the measurement variance ``sigma_m``.

    Velocity in units of ``1/h^2``, acceleration of ``1/h^4``.
    """

    position_filtered: FloatOrArray
    velocity_filtered: FloatOrArray
    acceleration_filtered: FloatOrArray
    position_predicted: FloatOrArray
    velocity_predicted: FloatOrArray
    acceleration_predicted: FloatOrArray


class Lag(NamedTuple):
    """Steady-state lag (true minus estimate) under a constant jerk ``j``.

    Position in units of ``j h^3``, velocity ``j h^2``, acceleration ``j h``.
    """

    position_filtered: FloatOrArray
    velocity_filtered: FloatOrArray
    acceleration_filtered: FloatOrArray
    position_predicted: FloatOrArray
    velocity_predicted: FloatOrArray
    acceleration_predicted: FloatOrArray


_out = out_value


def _check_convention(name: str, convention: str) -> float:
    if convention not in CONVENTIONS:
        raise ValueError(f"{name} must be one of {sorted(CONVENTIONS)}, got {convention!r}")
    return float(CONVENTIONS[convention])


_call = call_binding


def _prepare(names: Tuple[str, ...], values: Tuple[Any, ...]) -> Tuple[Tuple[int, ...], list]:
    arrays = [as_float_array(n, v) for n, v in zip(names, values)]
    return broadcast(names, arrays)


def _finite(names: Tuple[str, ...], flat: list) -> None:
    for n, x in zip(names, flat):
        bad = ~np.isfinite(x)
        if bad.any():
            raise ValueError(f"{n} must be finite, got {x[bad][0]!r}")


def _to_cc(gamma: np.ndarray, convention: str) -> np.ndarray:
    return gamma * _check_convention("convention", convention)


def convert(alpha: ArrayLike, beta: ArrayLike, gamma: ArrayLike, frm: str = "standard", to: str = "chen-chui") -> Gains:
    r"""Translate alpha-beta-gamma gains between conventions.

    Parameters
    ----------
    alpha, beta, gamma : float or array_like
        Gains in convention ``frm``.
    frm, to : {"chen-chui", "standard", "ghk"}
        Source and target conventions (see :data:`CONVENTIONS`).

    Returns
    -------
    Gains
        ``alpha`` and ``beta`` unchanged, ``gamma * c_frm / c_to``.

    Notes
    -----
    The three conventions share ``w[0] = alpha`` and ``w[1] = beta/h`` and
    differ in ``w[2] = c gamma/h^2`` with ``c`` = 1 (Chen & Chui's
    ``[alpha, beta/h, gamma/h^2]``, paper 004 sec. 2), 1/2 (Bar-Shalom) or 2
    (FilterPy's ``k``).

    Examples
    --------
    >>> from abkit import abg
    >>> abg.convert(0.5, 0.2, 0.04, frm="standard", to="chen-chui")
    Gains(alpha=0.5, beta=0.2, gamma=0.02)
    >>> abg.convert(0.5, 0.2, 0.02, frm="chen-chui", to="ghk").gamma
    0.01
    """
    cf = _check_convention("frm", frm)
    ct = _check_convention("to", to)
    shape, (a, b, g) = _prepare(("alpha", "beta", "gamma"), (alpha, beta, gamma))
    _finite(("alpha", "beta", "gamma"), [a, b, g])
    a, b, g = (x.reshape(shape) for x in (a, b, g))
    return Gains(_out(a.copy()), _out(b.copy()), _out(g * (cf / ct)))


def to_predictor(alpha: ArrayLike, beta: ArrayLike, gamma: ArrayLike, h: ArrayLike = 1.0, *, convention: str = "chen-chui") -> np.ndarray:
    r"""Predictor-form gain ``K = Phi w`` of filter-form gains.

    Parameters
    ----------
    alpha, beta, gamma : float or array_like
        Filter-form gains in ``convention``.
    h : float or array_like
        Sampling period, > 0.
    convention : {"chen-chui", "standard", "ghk"}

    Returns
    -------
    ndarray, shape (..., 3)
        ``K`` in physical units (position, per ``h``, per ``h^2``).

    Notes
    -----
    Chen & Chui's eq (5): the limiting filter is
    ``y_k+1 = Phi y_k + (Phi^-1 K)(z_k+1 - H' Phi y_k)``, so the
    alpha-beta-gamma gain is ``w = Phi^-1 K`` (sec. 2).

    Examples
    --------
    >>> from abkit import abg
    >>> K = abg.to_predictor(0.5, 0.2, 0.02, h=1.0)
    >>> [round(float(x), 12) for x in K]
    [0.71, 0.22, 0.02]
    >>> abg.from_predictor(K, h=1.0)
    Gains(alpha=0.5, beta=0.2, gamma=0.02)
    """
    c = _check_convention("convention", convention)
    shape, (a, b, g, t) = _prepare(("alpha", "beta", "gamma", "h"), (alpha, beta, gamma, h))
    _finite(("alpha", "beta", "gamma"), [a, b, g])
    if not np.all(np.isfinite(t) & (t > 0)):
        raise ValueError(f"h must be finite and > 0, got {h!r}")
    w2 = c * g / (t * t)
    w1 = b / t
    k = np.stack([a + t * w1 + 0.5 * t * t * w2, w1 + t * w2, w2], axis=-1)
    check_representable("to_predictor(): K", k.reshape(shape + (3,)).sum(axis=-1), ("alpha", "beta", "gamma", "h"), [x.reshape(shape) for x in (a, b, g, t)])
    return k.reshape(shape + (3,))


def from_predictor(K: ArrayLike, h: ArrayLike = 1.0, *, convention: str = "chen-chui") -> Gains:
    r"""Filter-form gains ``(alpha, beta, gamma)`` of a predictor-form gain ``K``.

    Parameters
    ----------
    K : array_like, shape (..., 3)
        Predictor-form gain (physical units).
    h : float or array_like
        Sampling period, > 0.
    convention : {"chen-chui", "standard", "ghk"}
        Convention of the returned gains.

    Returns
    -------
    Gains

    Notes
    -----
    ``w = Phi^-1 K`` with ``Phi^-1 = [[1, -h, h^2/2], [0, 1, -h], [0, 0, 1]]``
    (the inverse of eq (5)'s relation; see :func:`to_predictor`).

    Examples
    --------
    >>> from abkit import abg
    >>> abg.from_predictor([0.71, 0.22, 0.02], convention="standard").gamma
    0.04
    """
    c = _check_convention("convention", convention)
    k = as_float_array("K", K)
    if k.ndim < 1 or k.shape[-1] != 3:
        raise ValueError(f"K must have shape (..., 3), got {k.shape}")
    if not np.all(np.isfinite(k)):
        raise ValueError("K must be finite (no NaN or Inf entries)")
    t = as_float_array("h", h)
    if not np.all(np.isfinite(t) & (t > 0)):
        raise ValueError(f"h must be finite and > 0, got {h!r}")
    w2 = k[..., 2]
    w1 = k[..., 1] - t * w2
    w0 = k[..., 0] - t * k[..., 1] + 0.5 * t * t * w2
    g = w2 * t * t / c
    return Gains(_out(np.asarray(w0 + 0.0)), _out(np.asarray(w1 * t)), _out(np.asarray(g)))


class ABG(RowResult):
    """An alpha-beta-gamma design or analysis (steady state).

    Created by :func:`from_noise`, :func:`from_tracking_index` and
    :func:`analyze`, never directly. Every attribute is a float (bool) for
    scalar input and an array of the broadcast shape otherwise.

    Attributes
    ----------
    alpha, beta, gamma : float or ndarray
        Gains in :attr:`convention`.
    convention : str
    h : float or None
        The period when the constructor was given a scalar one.
    near_optimal : bool or ndarray of bool
        Chen & Chui's Corollary (i)-(iii): ``Phi w`` is the limiting Kalman
        gain for some diagonal ``Q`` and ``R > 0``.
    p_tilde_min_eig : float or ndarray
        Smallest eigenvalue of the Corollary's matrix P~ (iii).
    noise_ratios : NoiseRatios
        Corollary (iv)-(vi) in the normalised units of ``h = 1``:
        ``sigma_p/sigma_m``, ``sigma_v h^2/sigma_m``, ``sigma_a h^4/sigma_m``
        (NaN where not near-optimal).
    stable : bool or ndarray of bool
        Spectral radius of ``(I - w H) Phi`` below 1.
    spectral_radius : float or ndarray
    poles : complex ndarray, shape (..., 3)
        Closed-loop poles, by decreasing modulus.
    variance_reduction : VarianceReduction
        Measurement-noise-only variances of the estimates over ``sigma_m``.
    covariance_filtered, covariance_predicted : ndarray, shape (..., 3, 3)
        Steady-state error covariances at the model noise (:attr:`noise_ratios`),
        normalised (see the module docs), from the Lyapunov equation; NaN
        where not near-optimal. For near-optimal gains
        ``covariance_predicted = P~ / (1 - alpha)`` (Corollary (iii)).
    lag : Lag
        Steady-state lag under constant jerk.

    Notes
    -----
    Steady-state quantities of an unstable filter are ``inf``.
    """

    __slots__ = ("h", "convention", "design")
    _IDX = _IDX

    def __init__(self, rows: np.ndarray, shape: Tuple[int, ...], h: Optional[float], convention: str, design: str):
        super().__init__(rows, shape)
        self.h = h
        self.convention = convention
        self.design = design

    @property
    def alpha(self) -> FloatOrArray:
        return self._get("alpha")

    @property
    def beta(self) -> FloatOrArray:
        return self._get("beta")

    @property
    def gamma(self) -> FloatOrArray:
        return _out(self._raw("gamma") / CONVENTIONS[self.convention])

    @property
    def gains(self) -> Gains:
        """``(alpha, beta, gamma)`` in :attr:`convention`."""
        return Gains(self.alpha, self.beta, self.gamma)

    @property
    def near_optimal(self) -> Union[bool, np.ndarray]:
        return self._flag("near_optimal")

    @property
    def p_tilde_min_eig(self) -> FloatOrArray:
        return self._get("p_tilde_min_eig")

    @property
    def noise_ratios(self) -> NoiseRatios:
        return NoiseRatios(self._get("q_p"), self._get("q_v"), self._get("q_a"))

    @property
    def stable(self) -> Union[bool, np.ndarray]:
        return self._flag("stable")

    @property
    def spectral_radius(self) -> FloatOrArray:
        return self._get("spectral_radius")

    @property
    def poles(self) -> np.ndarray:
        p = np.empty(self._shape + (3,), dtype=complex)
        for i in range(3):
            p[..., i] = self._raw(f"pole{i + 1}_re") + 1j * self._raw(f"pole{i + 1}_im")
        return p

    @property
    def variance_reduction(self) -> VarianceReduction:
        return VarianceReduction(*(self._get(f"vrr_{q}_{k}") for k in ("filtered", "predicted") for q in ("position", "velocity", "acceleration")))

    def _cov(self, p: str) -> np.ndarray:
        out = np.empty(self._shape + (3, 3))
        for i in range(3):
            for j in range(i, 3):
                out[..., i, j] = out[..., j, i] = self._raw(f"{p}{i + 1}{j + 1}")
        return out

    @property
    def covariance_filtered(self) -> np.ndarray:
        return self._cov("p")

    @property
    def covariance_predicted(self) -> np.ndarray:
        return self._cov("m")

    @property
    def lag(self) -> Lag:
        return Lag(*(self._get(f"lag_{q}_{k}") for k in ("filtered", "predicted") for q in ("position", "velocity", "acceleration")))

    def to_dict(self) -> Dict[str, Any]:
        """All fields as plain Python values (lists for arrays); JSON-serialisable.

        Non-finite values become ``None``; complex poles ``[re, im]`` pairs.

        Examples
        --------
        >>> from abkit import abg
        >>> d = abg.from_tracking_index(1.0).to_dict()
        >>> d["near_optimal"], d["convention"], len(d["poles"])
        (True, 'chen-chui', 3)
        """

        def conv(x: Any) -> Any:
            if isinstance(x, np.ndarray):
                if np.iscomplexobj(x):
                    return conv(np.stack([x.real, x.imag], axis=-1))
                return [conv(v) for v in x] if x.ndim > 0 else conv(x.item())
            if isinstance(x, (np.floating, float)):
                return float(x) if math.isfinite(x) else None
            if isinstance(x, (np.bool_, bool)):
                return bool(x)
            return x

        d: Dict[str, Any] = {"design": self.design, "convention": self.convention, "h": self.h}
        for name in ("alpha", "beta", "gamma", "near_optimal", "p_tilde_min_eig", "stable", "spectral_radius", "poles",
                     "covariance_filtered", "covariance_predicted"):
            d[name] = conv(getattr(self, name))
        for name in ("noise_ratios", "variance_reduction", "lag"):
            d[name] = {k: conv(v) for k, v in getattr(self, name)._asdict().items()}
        return d

    def table(self) -> str:
        """A human-readable table of the design (scalar designs only)."""
        if self._shape != ():
            return repr(self)
        q, vr, lag = self.noise_ratios, self.variance_reduction, self.lag
        rows: list = [
            ("convention", self.convention),
            ("alpha", self.alpha),
            ("beta", self.beta),
            ("gamma", self.gamma),
            ("near-optimal (Chen & Chui)", self.near_optimal),
            ("sigma_p/sigma_m", q.sigma_p),
            ("sigma_v h^2/sigma_m", q.sigma_v),
            ("sigma_a h^4/sigma_m", q.sigma_a),
            ("stable", self.stable),
            ("spectral radius", self.spectral_radius),
            ("VRR position (filtered)", vr.position_filtered),
            ("VRR velocity (filtered) [1/h^2]", vr.velocity_filtered),
            ("VRR acceleration (filtered) [1/h^4]", vr.acceleration_filtered),
            ("jerk lag, position (predicted) [j h^3]", lag.position_predicted),
        ]
        if self.h is not None:
            rows.insert(0, ("h", self.h))
        out = []
        for k, v in rows:
            val = f"{v:.6g}" if isinstance(v, float) else str(v)
            out.append(f"{k:<40}{val:>16}")
        return "\n".join(out)

    def filter(self, h: Optional[float] = None) -> Any:
        """An :class:`abkit.AlphaBetaGammaFilter` running these gains (period ``h``)."""
        from .filters import AlphaBetaGammaFilter

        period = h if h is not None else (self.h if self.h is not None else 1.0)
        t = as_float_array("h", period)
        if t.ndim > 1:
            raise ValueError(f"h must be a scalar or a 1-D array (one per track), got shape {t.shape}")
        check_positive("h", t)
        with np.errstate(over="ignore", under="ignore", divide="ignore"):
            scale = np.maximum(t * t, self.gamma / (t * t))
        check_representable("the filter's transition and gains", np.where(scale > 0, scale, np.nan), ("h",), (t,))
        return AlphaBetaGammaFilter(self.alpha, self.beta, self.gamma, period, convention=self.convention)

    def __repr__(self) -> str:
        if self._shape == ():
            return (
                f"ABG(alpha={self.alpha:.6g}, beta={self.beta:.6g}, gamma={self.gamma:.6g}, "
                f"convention={self.convention!r}, near_optimal={self.near_optimal}, stable={self.stable})"
            )
        return f"ABG(shape={self._shape}, convention={self.convention!r}, design={self.design!r})"


def _analyse(a: np.ndarray, b: np.ndarray, g_cc: np.ndarray, shape: Tuple[int, ...], h: Any, convention: str, design: str) -> ABG:
    rows = _call(_abkit.abg_analyze, shape, a, b, g_cc)
    hh = float(h) if h is not None and np.ndim(h) == 0 else None
    return ABG(rows, shape, hh, convention, design)


def from_noise(
    sigma_p: ArrayLike, sigma_v: ArrayLike, sigma_a: ArrayLike, sigma_m: ArrayLike, h: ArrayLike = 1.0, *, convention: str = "chen-chui"
) -> ABG:
    r"""Near-optimal (limiting Kalman) alpha-beta-gamma gains from the noise.

    Parameters
    ----------
    sigma_p, sigma_v, sigma_a : float or array_like
        Process noise *variances* on position, velocity and acceleration,
        ``Q = diag(sigma_p, sigma_v, sigma_a)`` (paper 004, sec. 1); finite,
        >= 0; ``sigma_a`` must be > 0 for a limiting gain to exist.
    sigma_m : float or array_like
        Measurement noise variance ``R``, finite, > 0.
    h : float or array_like
        Sampling period, > 0.
    convention : {"chen-chui", "standard", "ghk"}
        Convention of the returned gains.

    Returns
    -------
    ABG

    Raises
    ------
    ValueError
        For a negative, NaN or infinite argument (named), ``sigma_m <= 0``,
        a noise ratio that over- or underflows, or a process noise so much
        larger than ``sigma_m`` that ``alpha`` rounds to 1 (names ``sigma_m``).
    numpy.linalg.LinAlgError
        If ``sigma_a = 0``: Lemma 2, no limiting gain exists.

    Notes
    -----
    Lemma 1: the Kalman gains converge to ``K = Phi S H (H' S H + R)^-1``
    with ``S`` the stabilising solution of the steady-state Riccati
    equation; the gains are ``w = Phi^-1 K = [alpha, beta/h, gamma/h^2]``.
    Computed in Rust in closed form: :func:`from_tracking_index` when
    ``sigma_p = sigma_v = 0``, otherwise the spectral factorisation of the
    measurement's third difference (the closed-loop poles from the roots of
    a cubic, then the gains as sums of positive terms), accurate to 1e-13
    relative (a few ulps observed) over the whole domain, ``alpha`` near 1
    included (docs/abg.md, "Accuracy"); the checked Riccati solver of
    :mod:`abkit.riccati` only where that cubic would over/underflow.
    Inverse: :func:`noise_ratios` (Corollary (iv)-(vi)).

    Examples
    --------
    >>> from abkit import abg
    >>> d = abg.from_noise(0.3, 0.2, 0.1, 1.0, h=0.7)
    >>> d.near_optimal, d.stable
    (True, True)
    >>> [round(x, 10) for x in abg.noise_ratios(d.alpha, d.beta, d.gamma, h=0.7)]
    [0.3, 0.2, 0.1]
    """
    _check_convention("convention", convention)
    names = ("sigma_p", "sigma_v", "sigma_a", "sigma_m", "h")
    shape, flat = _prepare(names, (sigma_p, sigma_v, sigma_a, sigma_m, h))
    g = _call(_abkit.abg_from_noise, shape, *flat)
    return _analyse(g[:, 0].copy(), g[:, 1].copy(), g[:, 2].copy(), shape, h, convention, "from_noise")


def from_tracking_index(lam: ArrayLike, *, model: str = "acceleration", convention: str = "chen-chui") -> ABG:
    r"""Closed-form near-optimal gains when only the acceleration is driven.

    Parameters
    ----------
    lam : float or array_like
        Tracking index ``sqrt(sigma_a / sigma_m) h^2`` (``sigma_a``,
        ``sigma_m`` variances), finite, > 0; for ``model="continuous"``
        ``sqrt(q h / sigma_m) h^2`` with ``q`` the jerk power spectral density.
    model : {"acceleration", "dwpa", "continuous"}
        ``"acceleration"`` (``Q = diag(0, 0, sigma_a)``) and ``"dwpa"``
        (discrete white jerk) have the same gains, in closed form;
        ``"continuous"`` is the continuous white-noise jerk model
        ``Q = q [[h^5/20, h^4/8, h^3/6], [h^4/8, h^3/3, h^2/2], [h^3/6, h^2/2, h]]``,
        solved by the Riccati solver (no closed form).
    convention : {"chen-chui", "standard", "ghk"}

    Returns
    -------
    ABG
        (``near_optimal`` refers to Chen & Chui's diagonal ``Q``: it is
        ``False`` for most ``"continuous"`` designs.)

    Notes
    -----
    Two common models give the same limiting gains: Chen & Chui's
    ``Q = diag(0, 0, sigma_a)`` and Bar-Shalom's discrete Wiener process
    acceleration ("white jerk", ``Q = sigma_a g g'``, ``g = [h^2/2, h, 1]``);
    ``g = Phi e3``, so the noise only enters half a step earlier. With
    ``s = sqrt(1 - alpha)``, Corollary (iv)-(v) with ``sigma_p = sigma_v = 0``
    give ``beta^2 = 2 alpha gamma`` and
    ``alpha^2 + alpha beta + alpha gamma/2 = 2 beta``, hence (Chen-Chui)::

        beta = 2 (1 - s)^2,  gamma = 2 (1 - s)^3 / (1 + s),
        2 (1 - s)^3 = lam s (1 + s)      (Corollary (vi): gamma = lam s)

    in the standard convention Bar-Shalom's ``beta = 2(2 - alpha) - 4 s``,
    ``gamma = beta^2 / alpha``, ``gamma^2 / (4 (1 - alpha)) = lam^2``. The
    cubic has one root in (0, 1), found to full precision by safeguarded
    Newton. Checked against the Riccati solver and mpmath (tests).

    Examples
    --------
    >>> from abkit import abg
    >>> d = abg.from_tracking_index(1.0)
    >>> round(d.beta, 12) == round(d.alpha ** 2 * 0 + 2 * (1 - (1 - d.alpha) ** 0.5) ** 2, 12)
    True
    >>> s = abg.from_tracking_index(1.0, convention="standard")
    >>> bool(abs(s.gamma - s.beta ** 2 / s.alpha) < 1e-14)
    True
    """
    _check_convention("convention", convention)
    if model not in ("acceleration", "dwpa", "continuous"):
        raise ValueError(f"model must be 'acceleration', 'dwpa' or 'continuous', got {model!r}")
    shape, flat = _prepare(("lam",), (lam,))
    g = _call(_abkit.abg_from_tracking_index, shape, flat[0], model == "continuous")
    return _analyse(g[:, 0].copy(), g[:, 1].copy(), g[:, 2].copy(), shape, None, convention, "from_tracking_index")


def analyze(alpha: ArrayLike, beta: ArrayLike, gamma: ArrayLike, *, convention: str = "chen-chui") -> ABG:
    r"""Steady-state analysis of arbitrary alpha-beta-gamma gains.

    Parameters
    ----------
    alpha, beta, gamma : float or array_like
        Gains in ``convention``, finite.
    convention : {"chen-chui", "standard", "ghk"}

    Returns
    -------
    ABG

    Notes
    -----
    Poles: eigenvalues of ``(I - w H) Phi``, whose characteristic polynomial
    (Theorem 3 with ``theta = r = 0``) is
    ``z^3 - (3 - alpha - beta - gamma/2) z^2 + (3 - 2 alpha - beta + gamma/2) z - (1 - alpha)``.
    Covariances: the discrete Lyapunov equation of the error; lag: the
    fixed point of the error recursion driven by a constant jerk.

    Examples
    --------
    >>> from abkit import abg
    >>> d = abg.analyze(0.5, 0.2, 0.02)
    >>> d.stable, d.near_optimal
    (True, False)
    >>> round(d.lag.position_predicted, 12)
    50.0
    """
    c = _check_convention("convention", convention)
    shape, (a, b, g) = _prepare(("alpha", "beta", "gamma"), (alpha, beta, gamma))
    return _analyse(a, b, g * c, shape, None, convention, "analyze")


def noise_ratios(alpha: ArrayLike, beta: ArrayLike, gamma: ArrayLike, h: ArrayLike = 1.0, *, convention: str = "chen-chui") -> NoiseRatios:
    r"""The noise for which given gains are near-optimal (Corollary (iv)-(vi)).

    Parameters
    ----------
    alpha, beta, gamma : float or array_like
        Gains in ``convention``.
    h : float or array_like
        Sampling period, > 0.
    convention : {"chen-chui", "standard", "ghk"}

    Returns
    -------
    NoiseRatios
        ``sigma_p/sigma_m``, ``sigma_v/sigma_m``, ``sigma_a/sigma_m``.

    Raises
    ------
    ValueError
        Naming the gain, if the gains are near-optimal for no noise
        (Corollary (i)-(iii) fail).

    Notes
    -----
    Chen & Chui's Corollary, checked against the Riccati solver::

        sigma_p/sigma_m = (alpha^2 + alpha beta + alpha gamma/2 - 2 beta) / (1 - alpha)
        sigma_v/sigma_m = (beta^2 - 2 alpha gamma) / ((1 - alpha) h^2)
        sigma_a/sigma_m = gamma^2 / ((1 - alpha) h^4)

    Examples
    --------
    >>> from abkit import abg
    >>> d = abg.from_tracking_index(0.5)
    >>> [round(x, 12) for x in abg.noise_ratios(d.alpha, d.beta, d.gamma)]
    [0.0, 0.0, 0.25]
    """
    c = _check_convention("convention", convention)
    shape, (a, b, g, t) = _prepare(("alpha", "beta", "gamma", "h"), (alpha, beta, gamma, h))
    q = _call(_abkit.abg_noise_ratios, shape, a, b, g * c, t)
    return NoiseRatios(*(_out(q[:, i].reshape(shape)) for i in range(3)))


def is_near_optimal(alpha: ArrayLike, beta: ArrayLike, gamma: ArrayLike, *, convention: str = "chen-chui") -> Union[bool, np.ndarray]:
    r"""Whether gains are near-optimal (Corollary (i)-(iii)).

    Parameters
    ----------
    alpha, beta, gamma : float or array_like
        Gains in ``convention``, finite.
    convention : {"chen-chui", "standard", "ghk"}

    Returns
    -------
    bool or ndarray of bool

    Notes
    -----
    (i) ``0 < alpha < 1``, ``gamma > 0``; (ii)
    ``sqrt(2 alpha gamma) <= beta <= alpha (alpha + gamma/2) / (2 - alpha)``;
    (iii) the matrix P~ is nonnegative definite. (ii) is
    ``sigma_v >= 0``, ``sigma_p >= 0``; P~ is ``(1 - alpha)`` times the
    normalised steady-state prediction covariance. Equalities are accepted
    to a relative 1e-9 (gains computed for ``sigma_p = 0`` round either way).

    Examples
    --------
    >>> from abkit import abg
    >>> d = abg.from_noise(0.0, 0.0, 1.0, 1.0)
    >>> abg.is_near_optimal(d.alpha, d.beta, d.gamma)
    True
    >>> abg.is_near_optimal(0.5, 0.4, 0.1)
    False
    """
    c = _check_convention("convention", convention)
    shape, (a, b, g) = _prepare(("alpha", "beta", "gamma"), (alpha, beta, gamma))
    out = _call(_abkit.abg_conditions, shape, a, b, g * c)[:, 0].reshape(shape) != 0.0
    return bool(out) if out.ndim == 0 else out


class StabilityMargins(NamedTuple):
    """Jury's conditions for the alpha-beta-gamma loop as margins (all > 0 iff stable)."""

    gamma: FloatOrArray
    four_minus_2alpha_minus_beta: FloatOrArray
    one_minus_abs_one_minus_alpha: FloatOrArray
    determinant: FloatOrArray
    stable: Union[bool, np.ndarray]


def stability_region(alpha: ArrayLike, beta: ArrayLike, gamma: ArrayLike, *, convention: str = "chen-chui") -> StabilityMargins:
    r"""Closed-form stability region of the alpha-beta-gamma filter (Jury's test).

    Parameters
    ----------
    alpha, beta, gamma : float or array_like
        Gains in ``convention``, finite.
    convention : {"chen-chui", "standard", "ghk"}

    Returns
    -------
    StabilityMargins
        The four margins (in the Chen-Chui convention) and the verdict.

    Notes
    -----
    The closed loop has the characteristic polynomial (Theorem 3 with
    ``theta = r = 0``)
    ``p(z) = z^3 - (3 - alpha - beta - gamma/2) z^2 + (3 - 2 alpha - beta + gamma/2) z - (1 - alpha)``.
    Jury's conditions ``p(1) > 0``, ``-p(-1) > 0``, ``|a0| < 1`` and
    ``1 - a0^2 > |a0 a2 - a1|`` become::

        gamma > 0,   2 alpha + beta < 4,   0 < alpha < 2,
        alpha (2 - alpha) > |alpha^2 + alpha beta + alpha gamma/2 - 2 alpha - gamma|

    (checked against the eigenvalues on random gains in the tests).

    Examples
    --------
    >>> from abkit import abg
    >>> abg.stability_region(0.5, 0.2, 0.02).stable
    True
    >>> abg.stability_region(0.5, 0.2, -0.02).stable
    False
    """
    c = _check_convention("convention", convention)
    shape, (a, b, g) = _prepare(("alpha", "beta", "gamma"), (alpha, beta, gamma))
    m = _call(_abkit.abg_jury, shape, a, b, g * c)
    st = np.all(m > 0, axis=1).reshape(shape)
    col = [_out(m[:, i].reshape(shape)) for i in range(4)]
    return StabilityMargins(col[0], col[1], col[2], col[3], bool(st) if st.ndim == 0 else st)


class Coloured(NamedTuple):
    """Theorem 2 for given alpha-beta-gamma-theta gains (see :func:`coloured`)."""

    near_optimal: Union[bool, np.ndarray]
    conditions_hold: Union[bool, np.ndarray]
    conditions: np.ndarray
    alpha_plus_theta_minus_1: FloatOrArray
    sigma_tilde_min_eig: FloatOrArray
    sigma_p_over_sigma_a: FloatOrArray
    sigma_v_over_sigma_a: FloatOrArray
    sigma_m_over_sigma_a: FloatOrArray
    riccati_gains: np.ndarray
    gain_mismatch: FloatOrArray


def coloured(
    alpha: ArrayLike, beta: ArrayLike, gamma: ArrayLike, theta: ArrayLike, r: ArrayLike, h: ArrayLike = 1.0, *, convention: str = "chen-chui"
) -> Coloured:
    r"""Theorem 2: the alpha-beta-gamma-theta filter for coloured measurement noise.

    The measurement is ``z = position + v`` with ``v_k+1 = r v_k + eta_k``
    (``var eta = sigma_m``) and no white measurement noise; the augmented
    state is ``[position, velocity, acceleration, v]`` and the filter gain is
    ``[alpha, beta/h, gamma/h^2, theta]``.

    Parameters
    ----------
    alpha, beta, gamma, theta : float or array_like
        Gains (``gamma`` in ``convention``, nonzero).
    r : float or array_like
        Noise correlation, ``0 < |r| < 1``.
    h : float or array_like
        Sampling period, > 0.
    convention : {"chen-chui", "standard", "ghk"}

    Returns
    -------
    Coloured
        ``conditions`` (..., 5): the values of (i)-(v) (corrected, see Notes);
        ``sigma_tilde_min_eig``: (ix); the ratios (vi)-(viii) (variances of
        position, velocity process noise and of ``eta`` over ``sigma_a``);
        ``riccati_gains`` (..., 4): the limiting gain of the 4-state model
        with those ratios, computed independently by the Riccati solver with
        ``R = 0``, as ``[alpha, beta, gamma, theta]`` (Chen-Chui);
        ``gain_mismatch``: its largest relative difference from the given
        gains; ``near_optimal``: the conditions hold and the gains agree to
        1e-6.

    Notes
    -----
    Checked against the Riccati solution of the augmented model (errata
    "Paper 004"): (vi), (vii), (i), (ii), (iv) and
    ``sigma~11 .. sigma~34`` are right as printed (``Sigma~`` is
    ``gamma^2/(h^4 sigma_a)`` times the scaled prediction covariance);
    ``sigma~44`` and (viii) are wrong: ``sigma~44 = theta - sigma~14``,
    ``sigma_m/sigma_a = h^4/gamma^2 ((1 - r^2) sigma~44 + r^2 theta^2)``, and
    (v) is ``sigma~44 >= 0``. In (iii) ``theta gamma`` is a misprint of
    ``theta r`` ((iii) is ``4 sigma~22 >= 0``). Not stated in the paper: with
    no white measurement noise the filter reproduces ``z`` exactly, so
    ``alpha + theta = 1`` is necessary (reported as
    ``alpha_plus_theta_minus_1``).

    Examples
    --------
    >>> from abkit import abg
    >>> c = abg.coloured(0.9331025947536, 0.5689980498127, 0.1404521424780, 0.0668974052464, 0.6, h=0.8)
    >>> c.near_optimal
    True
    >>> [round(float(x), 6) for x in (c.sigma_p_over_sigma_a, c.sigma_v_over_sigma_a, c.sigma_m_over_sigma_a)]
    [3.0, 2.0, 5.0]
    """
    c = _check_convention("convention", convention)
    names = ("alpha", "beta", "gamma", "theta", "r", "h")
    shape, (a, b, g, th, rr, t) = _prepare(names, (alpha, beta, gamma, theta, r, h))
    row = _call(_abkit.abg_coloured, shape, a, b, g * c, th, rr, t)
    f = {n: row[:, i].reshape(shape) for i, n in enumerate(_CFIELDS)}

    def flag(x: np.ndarray) -> Union[bool, np.ndarray]:
        y = x != 0.0
        return bool(y) if y.ndim == 0 else y

    return Coloured(
        near_optimal=flag(f["near_optimal"]),
        conditions_hold=flag(f["conditions_hold"]),
        conditions=row[:, :5].reshape(shape + (5,)),
        alpha_plus_theta_minus_1=_out(f["alpha_plus_theta_minus_1"]),
        sigma_tilde_min_eig=_out(f["sigma_tilde_min_eig"]),
        sigma_p_over_sigma_a=_out(f["sigma_p_over_sigma_a"]),
        sigma_v_over_sigma_a=_out(f["sigma_v_over_sigma_a"]),
        sigma_m_over_sigma_a=_out(f["sigma_m_over_sigma_a"]),
        riccati_gains=row[:, 10:14].reshape(shape + (4,)),
        gain_mismatch=_out(f["gain_mismatch"]),
    )


class ColouredGains(NamedTuple):
    """Alpha-beta-gamma-theta gains (``gamma`` in the requested convention)."""

    alpha: FloatOrArray
    beta: FloatOrArray
    gamma: FloatOrArray
    theta: FloatOrArray


def coloured_from_noise(
    sigma_p: ArrayLike, sigma_v: ArrayLike, sigma_a: ArrayLike, sigma_m: ArrayLike, r: ArrayLike, h: ArrayLike = 1.0, *, convention: str = "chen-chui"
) -> ColouredGains:
    r"""Near-optimal alpha-beta-gamma-theta gains for coloured measurement noise.

    Parameters
    ----------
    sigma_p, sigma_v, sigma_a : float or array_like
        Process noise variances (``sigma_a > 0``, Theorem 1).
    sigma_m : float or array_like
        Variance of the driving noise ``eta`` of the measurement noise
        ``v_k+1 = r v_k + eta_k``, >= 0.
    r : float or array_like
        Correlation, ``|r| < 1``.
    h : float or array_like
        Sampling period, > 0.
    convention : {"chen-chui", "standard", "ghk"}

    Returns
    -------
    ColouredGains

    Raises
    ------
    ValueError
        Naming a bad argument.
    numpy.linalg.LinAlgError
        If ``sigma_a = 0`` or the Riccati problem has no stabilising solution.

    Notes
    -----
    The limiting Kalman gain of Theorem 1's augmented model with ``G = 0``,
    ``F = r`` (state ``[x, x', x'', v]``, ``H = [1, 0, 0, 1]``, ``R = 0``),
    from :func:`abkit.riccati.solve_dare` (which handles the singular ``R``);
    ``K_c = Phi_c [alpha, beta/h, gamma/h^2, theta]`` (sec. 3). The result
    satisfies ``alpha + theta = 1`` and :func:`coloured` recovers the noise.

    Examples
    --------
    >>> from abkit import abg
    >>> g = abg.coloured_from_noise(3.0, 2.0, 1.0, 5.0, r=0.6, h=0.8)
    >>> round(g.alpha + g.theta, 12)
    1.0
    >>> c = abg.coloured(*g, r=0.6, h=0.8)
    >>> c.near_optimal, round(c.sigma_m_over_sigma_a, 9)
    (True, 5.0)
    """
    c = _check_convention("convention", convention)
    names = ("sigma_p", "sigma_v", "sigma_a", "sigma_m", "r", "h")
    shape, flat = _prepare(names, (sigma_p, sigma_v, sigma_a, sigma_m, r, h))
    k = _call(_abkit.abg_coloured_from_noise, shape, *flat)
    col = [k[:, i].reshape(shape) for i in range(4)]
    return ColouredGains(_out(col[0]), _out(col[1]), _out(col[2] / c), _out(col[3]))


class Decoupled(NamedTuple):
    """Theorem 3's uncoupled recursive filters (see :func:`decoupled`)."""

    b: np.ndarray
    a: np.ndarray
    poles: np.ndarray
    stable: Union[bool, np.ndarray]
    spectral_radius: FloatOrArray


def decoupled(
    alpha: ArrayLike,
    beta: ArrayLike,
    gamma: ArrayLike,
    theta: ArrayLike = 0.0,
    r: ArrayLike = 0.0,
    h: ArrayLike = 1.0,
    *,
    convention: str = "chen-chui",
) -> Decoupled:
    r"""Theorem 3: the filter as four uncoupled recursive (IIR) filters.

    Parameters
    ----------
    alpha, beta, gamma, theta : float or array_like
        Gains (``gamma`` in ``convention``); ``theta = r = 0`` is the
        white-noise alpha-beta-gamma filter.
    r : float or array_like
        Measurement-noise correlation.
    h : float or array_like
        Sampling period, > 0.
    convention : {"chen-chui", "standard", "ghk"}

    Returns
    -------
    Decoupled
        ``b`` (..., 4, 4): numerators (coefficients of ``z_k .. z_k-3``) of
        the position, velocity, acceleration and noise estimates; ``a``
        (..., 5): the common denominator ``[1, -a1, -a2, -a3, -a4]``;
        ``scipy.signal.lfilter(b[i], a, z)`` reproduces component ``i`` of
        the filter started from zero. ``poles`` (..., 4): eigenvalues of
        ``A`` by decreasing modulus; ``stable``: spectral radius < 1.

    Notes
    -----
    From ``(A - zI) Y = -z Z w`` (sec. 3). Checked coefficient by coefficient
    against ``scipy.signal.ss2tf`` and a state-space simulation: two printed
    coefficients are wrong (errata "Paper 004"): ``a1`` has ``(1 - theta) r``
    (printed ``(theta - 1) r``), and the acceleration numerator is
    ``gamma/h^2 [1, -(2 + r), 1 + 2r, -r]`` (printed ``-(2 + gamma)``).

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> from abkit import abg, AlphaBetaGammaFilter
    >>> d = abg.decoupled(0.5, 0.2, 0.02)
    >>> z = np.arange(10.0) ** 2
    >>> f = AlphaBetaGammaFilter(0.5, 0.2, 0.02, 1.0, convention="chen-chui")
    >>> x = f.run(z, init=np.zeros(3)).states
    >>> bool(np.allclose(lfilter(d.b[0], d.a, z), x[0]))
    True
    """
    c = _check_convention("convention", convention)
    names = ("alpha", "beta", "gamma", "theta", "r", "h")
    shape, (a, b, g, th, rr, t) = _prepare(names, (alpha, beta, gamma, theta, r, h))
    row = _call(_abkit.abg_decoupled, shape, a, b, g * c, th, rr, t)
    poles = (row[:, 21:29:2] + 1j * row[:, 22:29:2]).reshape(shape + (4,))
    st = row[:, 29].reshape(shape) != 0.0
    return Decoupled(
        b=row[:, :16].reshape(shape + (4, 4)),
        a=row[:, 16:21].reshape(shape + (5,)),
        poles=poles,
        stable=bool(st) if st.ndim == 0 else st,
        spectral_radius=_out(row[:, 30].reshape(shape)),
    )
