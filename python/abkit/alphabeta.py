r"""Alpha-beta filter design and analysis (Painter, Kerstetter & Jowers, 1990).

The alpha-beta filter tracks position and velocity from noisy position
measurements taken every ``T`` seconds::

    predict:  x_p = x + T v
    residual: e   = z - x_p
    update:   x   = x_p + alpha e,    v = v + (beta / T) e

The steady-state Kalman filter of the "white acceleration held over each
period" model (paper eq (2)) has exactly this form, so a design can come from
noise statistics (Kalman) or from classical loop specifications (damping,
natural frequency, noise bandwidth). This module does both in closed form,
and analyses any gains.

Every constructor accepts scalars or numpy arrays, broadcasts them, computes
in Rust, and returns one :class:`AlphaBeta` whose fields are floats (scalar
input) or arrays of the broadcast shape.

Normalisation
-------------
Covariances are dimensionless: position in units of ``sigma_v``, velocity in
units of ``sigma_v / T``; the measurement noise has unit variance and the
process noise is ``r * [[1, 2], [2, 4]]`` with the SNR
``r = ((sigma_w T^2 / 2) / sigma_v)^2`` of eq (9). Use
:meth:`AlphaBeta.scaled_covariance` for physical units.

Constructors
------------
from_snr, from_noise, from_tracking_index, from_tracking_error,
from_bandwidth, from_natural_frequency, analyze.

References
----------
.. [1] J. H. Painter, D. Kerstetter, S. Jowers, "Reconciling steady-state
   Kalman and alpha-beta filter design", IEEE Trans. Aerospace and
   Electronic Systems 26(6), 986-991, Nov. 1990.
.. [2] P. R. Kalata, "The tracking index: a generalized parameter for
   alpha-beta and alpha-beta-gamma target trackers", IEEE Trans. AES 20(2),
   174-182, 1984.
"""

from __future__ import annotations

import math
from typing import Any, Dict, NamedTuple, Optional, Tuple, Union

import numpy as np

from . import _abkit
from ._results import FloatOrArray, RowResult, call_binding, out_value
from ._validate import (
    as_float_array,
    broadcast,
    broadcast_shape,
    check_representable,
    check_nonnegative,
    check_open_interval,
    check_positive,
)

__all__ = [
    "AlphaBeta",
    "ErrorCovariance",
    "Lag",
    "VarianceReduction",
    "KALMAN_DAMPING",
    "from_snr",
    "from_noise",
    "from_tracking_index",
    "from_tracking_error",
    "from_bandwidth",
    "from_natural_frequency",
    "analyze",
    "error_covariance",
]

#: Damping ratio realised by every Kalman-optimal alpha-beta filter, 1/sqrt(2).
KALMAN_DAMPING = 1.0 / math.sqrt(2.0)

ArrayLike = Any

_FIELDS = tuple(_abkit.ALPHABETA_FIELDS)
_IDX = {name: i for i, name in enumerate(_FIELDS)}


class VarianceReduction(NamedTuple):
    """Variance reduction ratios: output noise variance / measurement noise variance.

    Position ratios are in units of ``sigma_v**2``, velocity ratios in units of
    ``sigma_v**2 / T**2`` (measurement noise only, no process noise).
    """

    position_filtered: FloatOrArray
    velocity_filtered: FloatOrArray
    position_predicted: FloatOrArray
    velocity_predicted: FloatOrArray


class Lag(NamedTuple):
    """Steady-state lag (true minus estimate) under a constant acceleration ``a``.

    Position lags are in units of ``a T**2``, velocity lags in units of ``a T``.
    """

    position_filtered: FloatOrArray
    velocity_filtered: FloatOrArray
    position_predicted: FloatOrArray
    velocity_predicted: FloatOrArray


class ErrorCovariance(NamedTuple):
    """Steady-state error covariances, arrays of shape ``(..., 2, 2)``."""

    filtered: np.ndarray
    predicted: np.ndarray


def _sym(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    out = np.empty(a.shape + (2, 2))
    out[..., 0, 0] = a
    out[..., 0, 1] = b
    out[..., 1, 0] = b
    out[..., 1, 1] = c
    return out


_out = out_value


class AlphaBeta(RowResult):
    """An alpha-beta filter design and its steady-state analysis.

    Created by the constructors of :mod:`abkit.alphabeta`, never directly.
    Every attribute is a float (or bool) for scalar input and an array of the
    broadcast input shape otherwise.

    Attributes
    ----------
    alpha, beta : float or ndarray
        Position gain and velocity gain times period; the physical gains are
        ``(g1, g2) = (alpha, beta / T)`` (eq (5)).
    r : float or ndarray
        The SNR ``((sigma_w T^2/2)/sigma_v)^2`` whose Kalman design has this
        ``alpha`` (eqs (9), (14)); ``inf`` where ``alpha >= 1``.
    snr_db : float or ndarray
        ``10 log10(r)``.
    tracking_index : float or ndarray
        Kalata's ``lambda = sigma_w T^2 / sigma_v = 2 sqrt(r)``.
    kalman_optimal : bool or ndarray of bool
        Whether ``beta`` is the Kalman ``beta`` for this ``alpha``
        (to 1e-9 relative).
    damping, omega_n_T : float or ndarray
        Damping ratio and ``omega_n T`` of the impulse-invariant continuous
        equivalent, eq (15). Kalman designs have damping ``1/sqrt(2)``.
    bandwidth_T : float or ndarray
        One-sided noise bandwidth (Hz) times ``T``, eq (16), of the continuous
        prototype.
    bandwidth_T_discrete : float or ndarray
        Equivalent noise bandwidth of the discrete filter times ``T``
        (half the position variance reduction ratio).
    tracking_error_ratio : float or ndarray
        Steady-state filtered position error variance over ``sigma_v^2`` at the
        model SNR ``r``; equals ``alpha`` for Kalman designs (eq (14)).
    covariance_filtered, covariance_predicted : ndarray, shape (..., 2, 2)
        Normalised steady-state error covariances at the model SNR ``r``
        (filtered: eq (12); predicted: one step ahead).
    b1_T, b2_T2, K_T, zero_T : float or ndarray
        The continuous equivalent of Fig. 3 made dimensionless:
        ``b1 T``, ``b2 T^2``, the gain ``K T`` (= ``b1 T``) and zero ``z T``.
    poles : complex ndarray, shape (..., 2)
        Closed-loop poles in the z-plane, roots of
        ``z^2 - (2 - alpha - beta) z + (1 - alpha)``.
    stable : bool or ndarray of bool
        Closed-loop (Jury) stability: ``alpha > 0``, ``beta > 0``,
        ``2 alpha + beta < 4``.
    valid : bool or ndarray of bool
        The paper's design region: stable, ``alpha < 1``, ``sqrt(beta) <= pi``
        (the approximate Nyquist bound).
    variance_reduction : VarianceReduction
        Noise-only output variance ratios, filtered and predicted.
    lag : Lag
        Steady-state lag under constant acceleration.
    T : float or None
        The sampling period, when the constructor was given one.
    design : str
        Name of the constructor that made this object.

    Notes
    -----
    Steady-state quantities of an unstable filter are ``inf``.
    """

    __slots__ = ("T", "design")
    _IDX = _IDX

    def __init__(self, rows: np.ndarray, shape: Tuple[int, ...], T: Optional[float], design: str):
        super().__init__(rows, shape)
        self.T = T
        self.design = design

    # -- fields -------------------------------------------------------------
    @property
    def alpha(self) -> FloatOrArray:
        return self._get("alpha")

    @property
    def beta(self) -> FloatOrArray:
        return self._get("beta")

    @property
    def r(self) -> FloatOrArray:
        return self._get("r")

    @property
    def snr_db(self) -> FloatOrArray:
        with np.errstate(divide="ignore"):
            return _out(10.0 * np.log10(self._raw("r")))

    @property
    def tracking_index(self) -> FloatOrArray:
        return self._get("tracking_index")

    @property
    def kalman_optimal(self) -> Union[bool, np.ndarray]:
        return self._flag("kalman_optimal")

    @property
    def damping(self) -> FloatOrArray:
        return self._get("damping")

    @property
    def omega_n_T(self) -> FloatOrArray:
        return self._get("omega_n_T")

    @property
    def bandwidth_T(self) -> FloatOrArray:
        return self._get("bandwidth_T")

    @property
    def bandwidth_T_discrete(self) -> FloatOrArray:
        """Equivalent noise bandwidth of the discrete filter times ``T``.

        Half the filtered-position variance reduction ratio (the sum of the
        squared impulse response); unlike eq (16) (the continuous prototype)
        this is the bandwidth that sets the measurement-noise variance of
        the filtered position. ``inf`` for an unstable filter.
        """
        return _out(0.5 * self._raw("vrr_position_filtered"))

    @property
    def tracking_error_ratio(self) -> FloatOrArray:
        return self._get("p11")

    @property
    def covariance_filtered(self) -> np.ndarray:
        return _sym(self._raw("p11"), self._raw("p12"), self._raw("p22"))

    @property
    def covariance_predicted(self) -> np.ndarray:
        return _sym(self._raw("m11"), self._raw("m12"), self._raw("m22"))

    @property
    def b1_T(self) -> FloatOrArray:
        return self._get("b1_T")

    @property
    def b2_T2(self) -> FloatOrArray:
        return self._get("b2_T2")

    @property
    def K_T(self) -> FloatOrArray:
        return self._get("b1_T")

    @property
    def zero_T(self) -> FloatOrArray:
        return self._get("zero_T")

    @property
    def poles(self) -> np.ndarray:
        p = np.empty(self._shape + (2,), dtype=complex)
        p[..., 0] = self._raw("pole1_re") + 1j * self._raw("pole1_im")
        p[..., 1] = self._raw("pole2_re") + 1j * self._raw("pole2_im")
        return p

    @property
    def stable(self) -> Union[bool, np.ndarray]:
        return self._flag("stable")

    @property
    def valid(self) -> Union[bool, np.ndarray]:
        return self._flag("valid")

    @property
    def variance_reduction(self) -> VarianceReduction:
        return VarianceReduction(
            self._get("vrr_position_filtered"),
            self._get("vrr_velocity_filtered"),
            self._get("vrr_position_predicted"),
            self._get("vrr_velocity_predicted"),
        )

    @property
    def lag(self) -> Lag:
        return Lag(
            self._get("lag_position_filtered"),
            self._get("lag_velocity_filtered"),
            self._get("lag_position_predicted"),
            self._get("lag_velocity_predicted"),
        )

    # -- methods ----------------------------------------------------------
    def _period(self, T: Optional[ArrayLike]) -> np.ndarray:
        if T is None:
            if self.T is None:
                raise ValueError("T must be given: this design was not made with a sampling period")
            T = self.T
        t = as_float_array("T", T)
        check_positive("T", t)
        return t

    def gains(self, T: Optional[ArrayLike] = None) -> Tuple[FloatOrArray, FloatOrArray]:
        """Physical gains ``(g1, g2) = (alpha, beta / T)`` (eq (5)).

        Parameters
        ----------
        T : float or array_like, optional
            Sampling period; defaults to the period the design was made with.
        """
        t = self._period(T)
        return self.alpha, _out(np.asarray(self._raw("beta") / t))

    def continuous(self, T: Optional[ArrayLike] = None) -> Dict[str, FloatOrArray]:
        """The continuous-time equivalent of Fig. 3 in physical units (1/s).

        Returns ``b1``, ``b2``, the transfer-function gain ``K`` and zero ``z``
        of ``Y(s)/Z(s) = K (s - z) / (s^2 + 2 delta omega_n s + omega_n^2)``,
        plus ``omega_n`` and ``damping`` (eqs (6)-(7)).
        """
        t = self._period(T)
        out = {
            "b1": np.asarray(self._raw("b1_T") / t),
            "b2": np.asarray(self._raw("b2_T2") / t**2),
            "K": np.asarray(self._raw("b1_T") / t),
            "z": np.asarray(self._raw("zero_T") / t),
            "omega_n": np.asarray(self._raw("omega_n_T") / t),
        }
        for name, v in out.items():
            if np.all(np.isfinite(self._raw("b2_T2"))):
                check_representable(f"continuous(): {name}", v, ("T",), (t,))
        res: Dict[str, FloatOrArray] = {k: _out(v) for k, v in out.items()}
        res["damping"] = self.damping
        return res

    def scaled_covariance(self, sigma_v: ArrayLike, T: Optional[ArrayLike] = None, kind: str = "filtered") -> np.ndarray:
        """Steady-state covariance in physical units.

        ``[[P11 sigma_v^2, P12 sigma_v^2 / T], [., P22 sigma_v^2 / T^2]]`` of
        the normalised ``covariance_filtered`` (``kind="filtered"``) or
        ``covariance_predicted`` (``kind="predicted"``).
        """
        if kind not in ("filtered", "predicted"):
            raise ValueError(f"kind must be 'filtered' or 'predicted', got {kind!r}")
        sv = as_float_array("sigma_v", sigma_v)
        check_positive("sigma_v", sv)
        t = self._period(T)
        c = self.covariance_filtered if kind == "filtered" else self.covariance_predicted
        s = np.empty(broadcast_shape(("sigma_v", "T"), (sv, t)) + (2, 2))
        s[..., 0, 0] = sv**2
        s[..., 0, 1] = sv**2 / t
        s[..., 1, 0] = sv**2 / t
        s[..., 1, 1] = sv**2 / t**2
        out = c * s
        if np.all(np.isfinite(c)):
            check_representable("scaled_covariance()", out.reshape(out.shape[:-2] + (4,)).max(axis=-1), ("sigma_v", "T"), (sv, t))
        return out

    def error_covariance(self, r_true: ArrayLike) -> ErrorCovariance:
        """Steady-state covariance of these gains when the true SNR is ``r_true``.

        See :func:`error_covariance`.
        """
        return error_covariance(self._raw("alpha"), self._raw("beta"), r_true)

    def to_dict(self) -> Dict[str, Any]:
        """All fields as plain Python values (lists for arrays); JSON-serialisable.

        Non-finite values (``inf`` for quantities that do not exist, e.g. the
        covariances of an unstable filter) become ``None``; complex poles
        become ``[re, im]`` pairs.
        """

        def conv(x: Any) -> Any:
            if isinstance(x, np.ndarray):
                if np.iscomplexobj(x):
                    return conv(np.stack([x.real, x.imag], axis=-1))
                return [conv(v) for v in x] if x.ndim > 0 else conv(x.item())
            if isinstance(x, (np.floating, float)):
                return float(x) if math.isfinite(x) else None
            if isinstance(x, np.bool_):
                return bool(x)
            return x

        d: Dict[str, Any] = {"design": self.design, "T": self.T}
        for name in _PUBLIC:
            d[name] = conv(getattr(self, name))
        d["variance_reduction"] = {k: conv(v) for k, v in self.variance_reduction._asdict().items()}
        d["lag"] = {k: conv(v) for k, v in self.lag._asdict().items()}
        if self.T is not None:
            g1, g2 = self.gains()
            d["g1"], d["g2"] = conv(g1), conv(g2)
        return d

    def table(self) -> str:
        """A human-readable table of the design (scalar designs only)."""
        if self._shape != ():
            return repr(self)
        rows = [
            ("alpha (g1)", self.alpha),
            ("beta (g2*T)", self.beta),
        ]
        if self.T is not None:
            rows.append(("g2 = beta/T [1/s]", self.gains()[1]))
        rows += [
            ("SNR r", self.r),
            ("SNR [dB]", self.snr_db),
            ("tracking index lambda", self.tracking_index),
            ("Kalman optimal", self.kalman_optimal),
            ("damping", self.damping),
            ("omega_n*T [rad]", self.omega_n_T),
            ("B_N*T", self.bandwidth_T),
        ]
        if self.T is not None:
            rows.append(("B_N [Hz]", self.bandwidth_T / self.T))
        rows += [
            ("tracking error ratio", self.tracking_error_ratio),
            ("stable", self.stable),
            ("in design region", self.valid),
        ]
        vr = self.variance_reduction
        rows += [
            ("VRR position (filtered)", vr.position_filtered),
            ("VRR velocity (filtered)", vr.velocity_filtered),
            ("lag/(a T^2) position (filt.)", self.lag.position_filtered),
        ]
        w = max(len(k) for k, _ in rows)
        lines = [f"AlphaBeta design ({self.design}{', T=' + format(self.T, 'g') if self.T is not None else ''})"]
        for k, v in rows:
            vs = str(v) if isinstance(v, bool) else f"{v:.10g}"
            lines.append(f"  {k:<{w}}  {vs}")
        return "\n".join(lines)

    def __repr__(self) -> str:
        if self._shape == ():
            return (
                f"AlphaBeta(alpha={self.alpha:.10g}, beta={self.beta:.10g}, r={self.r:.6g}, "
                f"damping={self.damping:.6g}, bandwidth_T={self.bandwidth_T:.6g}, "
                f"kalman_optimal={self.kalman_optimal}, stable={self.stable})"
            )
        return f"AlphaBeta(shape={self._shape}, design={self.design!r})"


_PUBLIC = (
    "alpha", "beta", "r", "snr_db", "tracking_index", "kalman_optimal", "damping",
    "omega_n_T", "bandwidth_T", "bandwidth_T_discrete", "tracking_error_ratio", "covariance_filtered",
    "covariance_predicted", "b1_T", "b2_T2", "K_T", "zero_T", "poles", "stable", "valid",
)


_call = call_binding


def _run(func: Any, names: Tuple[str, ...], values: Tuple[Any, ...], checks: Dict[str, str], T: Any = None, design: str = "") -> AlphaBeta:
    arrays = [as_float_array(n, v) for n, v in zip(names, values)]
    for n, a in zip(names, arrays):
        kind = checks.get(n, "positive")
        if kind == "positive":
            check_positive(n, a)
        elif kind == "unit":
            check_open_interval(n, a, 0.0, 1.0)
    shape, flat = broadcast(names, arrays)
    rows = _call(func, shape, *flat)
    t = float(T) if T is not None and np.ndim(T) == 0 else None
    return AlphaBeta(np.asarray(rows), shape, t, design)


def from_snr(r: ArrayLike) -> AlphaBeta:
    r"""Kalman alpha-beta design from the signal-to-noise ratio ``r``.

    Parameters
    ----------
    r : float or array_like
        ``((sigma_w T^2 / 2) / sigma_v)^2`` (eq (9)): the variance of the
        position perturbation over one period caused by the white
        acceleration, over the measurement noise variance. Finite, > 0.

    Returns
    -------
    AlphaBeta

    Raises
    ------
    ValueError
        If ``r`` is not finite and positive.
    TypeError
        If ``r`` is not real.

    See Also
    --------
    from_noise, from_tracking_index, from_tracking_error

    Notes
    -----
    The steady-state Riccati equation (4), in the normalised form (9), has the
    unique positive-definite solution (12); ``alpha = p11``, ``beta = p12``
    (eq (13)). abkit evaluates it without cancellation through
    ``u = sqrt(1 - alpha)``::

        lambda = 2 sqrt(r),  S = sqrt(lambda (lambda + 8))
        u = 4 / (lambda + 4 + S),  v = 1 - u = (lambda + S) / (lambda + 4 + S)
        alpha = v (1 + u),  beta = 2 v^2,  p22 = 4 v^3 / u

    The paper's printed ``p12`` (transcription 000) is wrong; see
    ``docs/errata.md``.

    Examples
    --------
    >>> from abkit import alphabeta
    >>> d = alphabeta.from_snr(0.01)
    >>> round(d.damping, 12) == round(alphabeta.KALMAN_DAMPING, 12)
    True
    >>> d.kalman_optimal, d.stable
    (True, True)
    >>> bool(abs(d.alpha - d.tracking_error_ratio) < 1e-15)
    True
    """
    return _run(_abkit.alphabeta_from_snr, ("r",), (r,), {}, design="from_snr")


def from_noise(sigma_w: ArrayLike, sigma_v: ArrayLike, T: ArrayLike) -> AlphaBeta:
    r"""Kalman alpha-beta design from the physical noise.

    Parameters
    ----------
    sigma_w : float or array_like
        Standard deviation of the white acceleration, held constant over each
        period (paper Fig. 1), e.g. ft/s^2.
    sigma_v : float or array_like
        Standard deviation of the position measurement noise, e.g. ft.
    T : float or array_like
        Sampling period, s.

    Returns
    -------
    AlphaBeta
        With ``T`` recorded (scalar ``T`` only), so ``gains()`` needs no argument.

    Raises
    ------
    ValueError
        If an argument is not finite and positive, or
        ``sigma_w T^2 / sigma_v`` over- or underflows.

    Notes
    -----
    ``r = ((sigma_w T^2/2)/sigma_v)^2`` (eq (9)), evaluated as the tracking
    index ``lambda = sigma_w T^2 / sigma_v`` to avoid squaring.

    Examples
    --------
    The paper's GPS car (sigma_w = 3.2 ft/s^2, sigma_v = 32 ft, T = 0.1 s):

    >>> from abkit import alphabeta
    >>> car = alphabeta.from_noise(3.2, 32.0, 0.1)
    >>> print(f"{car.tracking_index:.6g}")
    0.001
    >>> print(f"{car.r:.6g}")
    2.5e-07
    """
    return _run(_abkit.alphabeta_from_noise, ("sigma_w", "sigma_v", "T"), (sigma_w, sigma_v, T), {}, T=T, design="from_noise")


def from_tracking_index(lam: ArrayLike) -> AlphaBeta:
    r"""Kalman alpha-beta design from Kalata's tracking index.

    Parameters
    ----------
    lam : float or array_like
        ``lambda = sigma_w T^2 / sigma_v = 2 sqrt(r)``; finite, > 0.

    Returns
    -------
    AlphaBeta

    Notes
    -----
    Kalata's relations ``beta^2 / (1 - alpha) = lambda^2`` and
    ``beta = 2 (2 - alpha) - 4 sqrt(1 - alpha)`` hold for the result.

    Examples
    --------
    >>> from abkit import alphabeta
    >>> d = alphabeta.from_tracking_index(0.5)
    >>> bool(abs(d.beta**2 / (1 - d.alpha) - 0.25) < 1e-14)
    True
    """
    return _run(_abkit.alphabeta_from_tracking_index, ("lam",), (lam,), {}, design="from_tracking_index")


def from_tracking_error(ratio: ArrayLike) -> AlphaBeta:
    r"""Kalman alpha-beta design from the normalised tracking error variance.

    Parameters
    ----------
    ratio : float or array_like
        ``sigma_t^2 / sigma_v^2`` in (0, 1): the steady-state filtered position
        error variance over the measurement noise variance. For a Kalman
        design it equals ``alpha`` (eq (14)).

    Returns
    -------
    AlphaBeta

    Notes
    -----
    The paper solves (14) for ``r`` numerically; it has the closed form
    ``u = sqrt(1 - ratio)``, ``lambda = 2 (ratio / (1 + u))^2 / u``,
    ``r = lambda^2 / 4``.

    Examples
    --------
    >>> from abkit import alphabeta
    >>> d = alphabeta.from_tracking_error(0.5)
    >>> d.alpha
    0.5
    """
    return _run(_abkit.alphabeta_from_tracking_error, ("ratio",), (ratio,), {"ratio": "unit"}, design="from_tracking_error")


def from_bandwidth(bn_t: ArrayLike, damping: ArrayLike = KALMAN_DAMPING) -> AlphaBeta:
    r"""Deterministic alpha-beta design from the noise bandwidth and damping.

    Parameters
    ----------
    bn_t : float or array_like
        One-sided noise bandwidth (Hz) times the sampling period (s), ``B_N T``.
    damping : float or array_like, optional
        Damping ratio ``delta`` of the continuous equivalent; default
        ``1/sqrt(2)`` (the Kalman-optimal damping).

    Returns
    -------
    AlphaBeta

    Raises
    ------
    ValueError
        If ``bn_t`` or ``damping`` is not finite and positive, or ``bn_t`` is
        too large for a stable filter with positive ``alpha`` at that damping
        (the message gives the bound; 0.25 at the default damping).

    Notes
    -----
    Eq (16), ``B_N T = sqrt(beta)/(8 delta) (1 + (2 delta - sqrt(beta))^2)``,
    is a cubic in ``x = omega_n T = sqrt(beta)``. abkit solves it by
    safeguarded Newton iteration on ``(0, min(4 delta, 1/delta))``, the
    ``omega_n T`` of stable filters with positive ``alpha``; where (16) is not
    monotone there (``sqrt(3)/2 < delta < 1``) it returns the smallest root.
    Then ``beta = x^2`` and ``alpha = 2 delta x - x^2 / 2`` (eq (15)).

    Examples
    --------
    >>> from abkit import alphabeta
    >>> d = alphabeta.from_bandwidth(0.1)
    >>> bool(abs(d.bandwidth_T - 0.1) < 1e-15), d.kalman_optimal
    (True, True)
    """
    return _run(_abkit.alphabeta_from_bandwidth, ("bn_t", "damping"), (bn_t, damping), {}, design="from_bandwidth")


def from_natural_frequency(omega_n: ArrayLike, T: ArrayLike, damping: ArrayLike = KALMAN_DAMPING) -> AlphaBeta:
    r"""Deterministic alpha-beta design from natural frequency and damping.

    Parameters
    ----------
    omega_n : float or array_like
        Undamped natural frequency of the continuous equivalent, rad/s.
    T : float or array_like
        Sampling period, s.
    damping : float or array_like, optional
        Damping ratio; default ``1/sqrt(2)``.

    Returns
    -------
    AlphaBeta

    Raises
    ------
    ValueError
        If an argument is not finite and positive, or ``omega_n T`` is outside
        ``(0, min(4 delta, 1/delta))`` (positive ``alpha``, stable loop).

    Notes
    -----
    Impulse invariance (eqs (6)-(7)) gives ``beta = (omega_n T)^2`` and
    ``alpha = (omega_n T)(2 delta - omega_n T / 2)`` (eq (15)).

    Examples
    --------
    >>> from abkit import alphabeta
    >>> d = alphabeta.from_natural_frequency(2.0, 0.1, damping=0.5)
    >>> print(f"{d.alpha:.4f} {d.beta:.4f}")
    0.1800 0.0400
    """
    return _run(
        _abkit.alphabeta_from_natural_frequency,
        ("omega_n", "T", "damping"),
        (omega_n, T, damping),
        {},
        T=T,
        design="from_natural_frequency",
    )


def analyze(alpha: ArrayLike, beta: ArrayLike) -> AlphaBeta:
    r"""Analyse arbitrary alpha-beta gains, Kalman-optimal or not.

    Parameters
    ----------
    alpha, beta : float or array_like
        Gains; must be finite and positive. Unstable gains are accepted and
        reported (``stable=False``, steady-state quantities ``inf``).

    Returns
    -------
    AlphaBeta
        ``r`` is the SNR whose Kalman design has this ``alpha``; the
        covariances are those of *these* gains at that SNR (solved from the
        fixed-gain Lyapunov equation), so ``tracking_error_ratio`` exceeds
        ``alpha`` unless the gains are Kalman-optimal.

    Examples
    --------
    Benedict-Bordner gains (``beta = alpha^2 / (2 - alpha)``) are not Kalman:

    >>> from abkit import alphabeta
    >>> d = alphabeta.analyze(0.5, 0.25 / 1.5)
    >>> d.kalman_optimal, d.stable
    (False, True)
    """
    return _run(_abkit.alphabeta_analyze, ("alpha", "beta"), (alpha, beta), {}, design="analyze")


def error_covariance(alpha: ArrayLike, beta: ArrayLike, r_true: ArrayLike) -> ErrorCovariance:
    r"""Actual steady-state error covariance of given gains under the true SNR.

    Parameters
    ----------
    alpha, beta : float or array_like
        Filter gains; must give a stable filter.
    r_true : float or array_like
        True SNR ``((sigma_w T^2/2)/sigma_v)^2``; finite, >= 0 (0 means
        measurement noise only: the variance reduction ratios).

    Returns
    -------
    ErrorCovariance
        ``filtered`` and ``predicted``, arrays of shape ``(..., 2, 2)``,
        normalised (position in ``sigma_v``, velocity in ``sigma_v / T``).

    Raises
    ------
    ValueError
        If the gains are not positive, the filter is unstable
        (``beta >= 4 - 2 alpha``), or ``r_true`` is negative or not finite.

    Notes
    -----
    The closed-form solution of the fixed-gain Lyapunov equation
    ``M = F ((I - K h) M (I - K h)^T + K K^T) F^T + Q``; with
    ``D = alpha (4 - 2 alpha - beta)``::

        P11 = (2a^2 - 3ab + 2b)/D + r 2(1 - a)^2/(a b)
        P12 = b(2a - b)/D        + r (1 - a)(2a - b)/(a b)
        P22 = 2b^2/D             + r (2a^2 - 3ab + 2b)/(a b)

    For the Kalman gains of ``r_true`` it reduces to eq (12). This is the
    quantitative form of the paper's remark that the tracking error differs
    from (14) when the actual noise differs from the design's.

    Examples
    --------
    >>> from abkit import alphabeta
    >>> d = alphabeta.from_snr(0.1)
    >>> c = alphabeta.error_covariance(d.alpha, d.beta, 0.1)
    >>> bool(abs(c.filtered[0, 0] - d.alpha) < 1e-12)
    True
    """
    names = ("alpha", "beta", "r_true")
    arrays = [as_float_array(n, v) for n, v in zip(names, (alpha, beta, r_true))]
    check_positive("alpha", arrays[0])
    check_positive("beta", arrays[1])
    check_nonnegative("r_true", arrays[2])
    shape, flat = broadcast(names, arrays)
    rows = _call(_abkit.alphabeta_error_covariance, shape, *flat)
    f = rows.reshape(shape + (6,))
    return ErrorCovariance(_sym(f[..., 0], f[..., 1], f[..., 2]), _sym(f[..., 3], f[..., 4], f[..., 5]))
