r"""The Singer (exponentially correlated acceleration) model and its steady-state Kalman filter.

Singer's target model (Singer 1970, ref. [1] of Yoon & Hong [2]): the
acceleration is a first-order Gauss-Markov process,

.. math::

    \dot a = -a/\tau + w, \qquad E[a^2] = \sigma_m^2, \qquad
    w \text{ white with spectral density } q = 2\sigma_m^2/\tau,

and position and velocity integrate it. Sampled every ``T`` seconds the
state ``(position, velocity, acceleration)`` obeys ``x[k+1] = Phi x[k] + v[k]``
with ``Phi`` of eq (2) and ``Q = cov(v) = q [q_ij]`` with Singer's exact
``q_ij`` (eq (4)). Measurements are position (``sigma_pos``) or position and
velocity (``sigma_vel``) with independent white errors (eq (5)).

Naming in the literature
------------------------
* ``tau`` is the acceleration correlation time (the paper's tau); Singer
  writes ``alpha = 1/tau`` (the "maneuver rate"). Both are accepted here
  (``tau=`` or ``alpha=``, not both). ``theta = T/tau = alpha T``.
* ``sigma_m`` is the rms acceleration (Singer's sigma_m; the paper's figure
  caption calls it sigma_n). ``q`` is the spectral density of the driving
  white noise, ``q = 2 sigma_m^2 / tau`` (eq (4)); some authors call
  ``sigma_m^2`` itself "q", and some write the density as ``2 alpha sigma_m^2``
  -- the same thing. Give the process noise as ``sigma_m=`` or ``q=``.
* ``tau = np.inf`` (``alpha = 0``) is the constant-acceleration (white-jerk)
  model; its noise must be given as ``q`` (``sigma_m`` would be infinite).
  The paper's constant-acceleration limit uses ``q = sigma_a^2 T``. Results
  are continuous in ``tau`` at fixed ``q``.

Normalisation
-------------
The steady state depends on three numbers only: ``theta = T/tau``,
``q T^5 / sigma_pos^2`` (``= 2 theta p2^2`` with ``p2 = sigma_m T^2 / sigma_pos``,
the paper's abscissa) and ``sigma_vel T / sigma_pos``. Normalised rms errors
are in units of ``sigma_pos`` (position), ``sigma_pos / T`` (velocity) and
``sigma_pos / T^2`` (acceleration).

References
----------
.. [1] R. A. Singer, "Estimating optimal tracking filter performance for
   manned maneuvering targets", IEEE Trans. AES-6(4), 473-483, July 1970.
.. [2] Y.-K. Yoon, S.-M. Hong, "Closed-form solution of ECA target-tracking
   filter using position and velocity measurements" (paper 001).
.. [3] S. N. Gupta, "An extension of closed-form solution of target tracking
   filters with discrete measurements", IEEE Trans. AES-20, 1984
   (position-only case).
"""

from __future__ import annotations

from typing import Any, Optional, Tuple, Union

import numpy as np

from . import _abkit
from ._errors import perturbation_estimate, warn_accuracy
from ._results import out_value
from ._validate import as_float_array, broadcast, check_positive, check_representable
from .riccati import _perturbed

__all__ = ["model", "steady_state", "tracking_filter", "SingerSteadyState", "METHODS"]

ArrayLike = Any
FloatOrArray = Union[float, np.ndarray]

#: Accepted values of ``method`` and their codes in the Rust core.
METHODS = {"numeric": 0.0, "closed-form": 1.0, "auto": 2.0}
_METHOD_NAMES = {0.0: "numeric", 1.0: "closed-form"}


def _resolve_tau(tau: Optional[ArrayLike], alpha: Optional[ArrayLike]) -> np.ndarray:
    if (tau is None) == (alpha is None):
        raise ValueError("give exactly one of tau (correlation time) and alpha (= 1/tau)")
    if tau is not None:
        t = as_float_array("tau", tau)
        bad = ~((t > 0) & ~np.isnan(t))
        if bad.any():
            raise ValueError(f"tau must be > 0 (np.inf allowed), got {t[bad].ravel()[0]!r}")
        return t
    a = as_float_array("alpha", alpha)
    bad = ~(np.isfinite(a) & (a >= 0))
    if bad.any():
        raise ValueError(f"alpha must be finite and >= 0 (0 means tau = inf), got {a[bad].ravel()[0]!r}")
    with np.errstate(divide="ignore"):
        return 1.0 / a


def _resolve_q(sigma_m: Optional[ArrayLike], q: Optional[ArrayLike], tau: np.ndarray) -> Tuple[str, np.ndarray]:
    if (sigma_m is None) == (q is None):
        raise ValueError("give exactly one of sigma_m (rms acceleration) and q (white-noise spectral density)")
    if sigma_m is not None:
        s = as_float_array("sigma_m", sigma_m)
        check_positive("sigma_m", s)
        if np.isinf(tau).any():
            raise ValueError(
                "sigma_m cannot be used with tau = inf (the acceleration variance is infinite); "
                "give q instead, e.g. q = sigma_a**2 * T for the constant-acceleration filter"
            )
        return "sigma_m", s
    qq = as_float_array("q", q)
    check_positive("q", qq)
    return "q", qq


def model(
    T: ArrayLike,
    tau: Optional[ArrayLike] = None,
    sigma_m: Optional[ArrayLike] = None,
    alpha: Optional[ArrayLike] = None,
    *,
    q: Optional[ArrayLike] = None,
) -> Tuple[np.ndarray, np.ndarray]:
    r"""Transition matrix and process-noise covariance of the sampled Singer model.

    Parameters
    ----------
    T : float or array_like
        Sampling period (> 0).
    tau : float or array_like, optional
        Acceleration correlation time (> 0; ``np.inf`` for constant
        acceleration). Give ``tau`` or ``alpha``.
    sigma_m : float or array_like, optional
        Rms acceleration (> 0). Give ``sigma_m`` or ``q``.
    alpha : float or array_like, optional
        Singer's ``alpha = 1/tau`` (>= 0).
    q : float or array_like, optional
        Spectral density of the white noise driving the acceleration,
        ``q = 2 sigma_m^2 / tau``.

    Returns
    -------
    Phi, Q : ndarray, shape (..., 3, 3)
        Eq (2) and eq (4) for state ``(position, velocity, acceleration)``;
        ``...`` is the broadcast shape of the arguments.

    Notes
    -----
    ``Phi = [[1, T, tau^2 (theta - 1 + e^-theta)], [0, 1, tau (1 - e^-theta)], [0, 0, e^-theta]]``
    with ``theta = T / tau`` (eq (2)). ``Q = q [q_ij]`` with Singer's exact
    ``q_ij``, evaluated without cancellation: for ``theta <= 2`` through the
    functions ``phi_k(z) = sum_j z^j/(j+k)!`` (e.g.
    ``q_11 = T^5 (16 phi_5(-2 theta) - 2 phi_4(-theta))``), beyond that by
    Singer's expressions. ``tau = inf`` gives
    ``Q = q [[T^5/20, T^4/8, T^3/6], [., T^3/3, T^2/2], [., ., T]]``.
    Checked against Van Loan's matrix-exponential discretisation in the
    tests.

    Examples
    --------
    >>> import numpy as np
    >>> from abkit import singer
    >>> Phi, Q = singer.model(T=1.0, tau=np.inf, q=1.0)
    >>> Phi
    array([[1. , 1. , 0.5],
           [0. , 1. , 1. ],
           [0. , 0. , 1. ]])
    >>> np.allclose(Q, [[1/20, 1/8, 1/6], [1/8, 1/3, 1/2], [1/6, 1/2, 1]])
    True
    >>> Phi, Q = singer.model(T=0.5, tau=10.0, sigma_m=3.0)
    >>> round(float(Q[2, 2]), 12)  # sigma_m^2 (1 - exp(-2 T / tau))
    0.856463237676
    """
    t = as_float_array("T", T)
    check_positive("T", t)
    ta = _resolve_tau(tau, alpha)
    kind, val = _resolve_q(sigma_m, q, ta)
    shape, (tf, tauf, vf) = broadcast(["T", "tau", kind], [t, ta, val])
    with np.errstate(over="ignore", under="ignore"):
        qf = 2.0 * vf**2 / tauf if kind == "sigma_m" else vf
    names = ("T", "tau", kind)
    if kind == "sigma_m":
        check_representable("the noise density q = 2 sigma_m^2 / tau", qf.reshape(shape), names, (t, ta, val))
    out = _abkit.singer_model(tf, tauf, qf)
    check_representable("the model (Phi, Q)", out.max(axis=-1).reshape(shape), names, (t, ta, val))
    return out[:, :9].reshape(shape + (3, 3)), out[:, 9:].reshape(shape + (3, 3))


class SingerSteadyState:
    """Steady state of the Singer-model Kalman filter (from :func:`steady_state`).

    Arrays have the broadcast shape ``S`` of the inputs in front.

    Attributes
    ----------
    P_pred : ndarray, shape S + (3, 3)
        Steady-state prediction covariance, the solution of eq (6).
    K : ndarray, shape S + (3, p)
        Steady-state Kalman gain, eq (7); ``p = 1`` (position only) or 2.
    P_filt : ndarray, shape S + (3, 3)
        Filtered (estimation) covariance, eq (8).
    P_smooth : ndarray, shape S + (3, 3)
        Steady-state fixed-interval smoothing covariance, from the Lyapunov
        equation (22).
    eigenvalues : complex ndarray, shape S + (3,)
        The three eigenvalues of the Hamiltonian ``H_f`` outside the unit
        circle (by decreasing modulus); the reciprocals of the eigenvalues of
        the closed-loop predictor ``Phi (I - K H)``.
    rms_position, rms_velocity, rms_acceleration : float or ndarray
        Normalised rms prediction errors: ``sqrt(P_pred[0,0]) / sigma_pos``,
        ``sqrt(P_pred[1,1]) T / sigma_pos``, ``sqrt(P_pred[2,2]) T^2 / sigma_pos``
        (the quantities of the paper's Figs. 1-3).
    alpha, beta, gamma : float or ndarray or None
        Position-only filters: the equivalent alpha-beta-gamma gains
        ``alpha = K1``, ``beta = K2 T``, ``gamma = 2 K3 T^2`` (update
        ``x += alpha r``, ``v += beta/T r``, ``a += gamma/(2 T^2) r``).
        ``None`` for position-and-velocity measurements.
    Phi, Q : ndarray, shape S + (3, 3)
        The model, eqs (2) and (4).
    H : ndarray, shape (p, 3)
    R : ndarray, shape S + (p, p)
        The measurement model, eq (5).
    theta, p2 : float or ndarray
        ``T / tau`` and ``sigma_m T^2 / sigma_pos`` (``p2`` is ``nan`` when the
        noise was given as ``q``).
    method_used : str or ndarray of str
        ``"closed-form"`` or ``"numeric"`` for each element.
    """

    def __init__(self, **kw: Any) -> None:
        self.__dict__.update(kw)

    P_pred: np.ndarray
    K: np.ndarray
    P_filt: np.ndarray
    P_smooth: np.ndarray
    eigenvalues: np.ndarray
    rms_position: FloatOrArray
    rms_velocity: FloatOrArray
    rms_acceleration: FloatOrArray
    alpha: Optional[FloatOrArray]
    beta: Optional[FloatOrArray]
    gamma: Optional[FloatOrArray]
    Phi: np.ndarray
    Q: np.ndarray
    H: np.ndarray
    R: np.ndarray
    theta: FloatOrArray
    p2: FloatOrArray
    method_used: Union[str, np.ndarray]

    def __repr__(self) -> str:
        return f"SingerSteadyState(shape={np.shape(self.theta)}, method_used={self.method_used!r})"


_out = out_value


def _check_accuracy(P: np.ndarray, theta: np.ndarray, qn: np.ndarray, rv: np.ndarray, code: np.ndarray, shape: Tuple[int, ...]) -> None:
    """AccuracyWarning where a second solve with (theta, q, r) perturbed at
    1e-10 shows a condition number putting the error above the tolerance
    (eigenvalues near the unit circle)."""
    if P.shape[0] == 0:
        return
    tp, qp, rp = _perturbed((theta, qn, np.where(np.isfinite(rv), rv, np.inf)))
    try:
        Pp = _abkit.singer_steady_state(tp, qp, rp, code)[:, 0:9].reshape(P.shape)
    except (np.linalg.LinAlgError, ValueError):
        Pp = np.full_like(P, np.nan)
    est = perturbation_estimate(P, Pp)
    i = int(np.argmax(est))
    where = "" if shape == () else f" (at index {tuple(int(j) for j in np.unravel_index(i, shape))})"
    warn_accuracy(
        f"singer.steady_state: P_pred{where}", float(est[i]),
        f"theta = T/tau = {float(theta[i]):.6g}: the Riccati equation is ill-conditioned", stacklevel=4,
    )


def steady_state(
    T: ArrayLike,
    tau: Optional[ArrayLike] = None,
    sigma_m: Optional[ArrayLike] = None,
    sigma_pos: Optional[ArrayLike] = None,
    sigma_vel: Optional[ArrayLike] = None,
    method: str = "auto",
    *,
    alpha: Optional[ArrayLike] = None,
    q: Optional[ArrayLike] = None,
) -> SingerSteadyState:
    r"""Steady-state Kalman filter of the Singer model (Yoon & Hong, Gupta).

    Parameters
    ----------
    T : float or array_like
        Sampling period (> 0).
    tau : float or array_like, optional
        Acceleration correlation time (> 0, ``np.inf`` allowed with ``q``).
        Or give ``alpha = 1/tau``.
    sigma_m : float or array_like, optional
        Rms target acceleration (> 0). Or give ``q``.
    sigma_pos : float or array_like
        Rms position measurement error (> 0), the paper's sigma_1.
    sigma_vel : float or array_like, optional
        Rms velocity measurement error (> 0), the paper's sigma_2. ``None``
        (default): position-only measurements (Gupta's filter). ``np.inf``
        entries are position-only too (the limit sigma_2 -> infinity).
    method : {"auto", "closed-form", "numeric"}
        ``"numeric"``: the generic Riccati solver :func:`abkit.riccati.solve_dare`.
        ``"closed-form"``: the paper's Hamiltonian route.
        ``"auto"``: the closed form, falling back to numeric where its
        conditioning checks fail; see ``method_used``.
    alpha : float or array_like, optional
        Singer's ``1/tau``.
    q : float or array_like, optional
        White-noise spectral density ``2 sigma_m^2 / tau`` (required for
        ``tau = inf``; the constant-acceleration filter uses ``q = sigma_a^2 T``).

    Returns
    -------
    SingerSteadyState

    Raises
    ------
    ValueError
        Non-positive or non-finite ``T``, ``tau``, ``sigma_m``, ``sigma_pos``,
        ``sigma_vel``, ``q``; arguments that do not broadcast; an unknown
        ``method`` (the message names the argument).
    numpy.linalg.LinAlgError
        No checked steady state could be computed (``method="closed-form"``
        where the closed form's checks fail), or a computed variance is
        negative beyond the solver's tolerance.

    Warns
    -----
    abkit.AccuracyWarning
        The estimated relative error of ``P_pred`` exceeds ``1e-6`` for some
        element (measured by a second solve with ``theta``, ``q`` and ``r``
        perturbed by ``1e-10``); the message names the element and gives the
        estimate.

    Notes
    -----
    The closed form follows the paper: Vaughan's Hamiltonian ``H_f`` (eq (9),
    with ``U_3``, ``S_3`` corrected), the coefficients ``a, b, c`` of eq (12)
    (``b``, ``c`` as printed are wrong; abkit uses sums of principal minors),
    the cubic (16) for ``X = lambda + 1/lambda`` solved in closed form with
    eq (15), ``|lambda_i| > 1`` (refined by Newton steps on
    ``det(lambda I - H_f)``), eigenvectors by a structured null space
    instead of the garbled eq (17), and ``P = W21 W11^-1`` (eq (18)). Every
    closed-form result is checked (unit-circle margin, conditioning of
    ``W11``, ``Im P``, positive definiteness, Riccati residual <= 1e-13);
    ``"auto"`` falls back to the numeric solver where a check fails --
    typically ``T/tau >= 100`` or very little process noise (``p2`` below
    about 1e-4). See the "Paper 001" section of ``docs/errata.md``.

    Eq (6) is solved on the normalised model (see the module docstring);
    ``K`` is eq (7), ``P_filt`` eq (8) in Joseph form, ``P_smooth`` the
    Lyapunov equation (22) ``P_s - A P_s A^T = P_filt - A P A^T`` with
    ``A = P_filt Phi^T P^{-1}``. A batch is solved in Rust on all cores.

    Examples
    --------
    Position-only tracking, T = 1 s, tau = 20 s, sigma_m = 1 m/s^2, sigma_pos = 10 m:

    >>> from abkit import singer
    >>> s = singer.steady_state(T=1.0, tau=20.0, sigma_m=1.0, sigma_pos=10.0)
    >>> s.method_used
    'closed-form'
    >>> s.K.shape, round(s.alpha, 6), round(s.beta, 6), round(s.gamma, 6)
    ((3, 1), 0.44294, 0.128587, 0.034345)
    >>> s2 = singer.steady_state(1.0, 20.0, 1.0, 10.0, sigma_vel=[1.0, 100.0], method="numeric")
    >>> s2.P_pred.shape, s2.K.shape
    ((2, 3, 3), (2, 3, 2))
    """
    if method not in METHODS:
        raise ValueError(f"method must be one of {sorted(METHODS)}, got {method!r}")
    t = as_float_array("T", T)
    check_positive("T", t)
    ta = _resolve_tau(tau, alpha)
    kind, val = _resolve_q(sigma_m, q, ta)
    if sigma_pos is None:
        raise ValueError("sigma_pos (rms position measurement error) is required")
    sp = as_float_array("sigma_pos", sigma_pos)
    check_positive("sigma_pos", sp)
    pos_only = sigma_vel is None
    if pos_only:
        sv = np.asarray(np.inf)
    else:
        sv = as_float_array("sigma_vel", sigma_vel)
        bad = ~((sv > 0) & ~np.isnan(sv))
        if bad.any():
            raise ValueError(f"sigma_vel must be > 0 (np.inf for position only), got {sv[bad].ravel()[0]!r}")
    shape, (tf, tauf, vf, spf, svf) = broadcast(["T", "tau", kind, "sigma_pos", "sigma_vel"], [t, ta, val, sp, sv])
    theta = tf / tauf
    scale = tf**2 / spf  # T^2 / sigma_pos
    if kind == "sigma_m":
        p2 = vf * scale
        qn = 2.0 * theta * p2**2
    else:
        p2 = np.full_like(tf, np.nan)
        qn = vf * tf * scale**2
    rv = svf * tf / spf
    bad = ~(np.isfinite(qn) & (qn > 0))
    if bad.any():
        raise ValueError(
            f"the normalised process noise q T^5/sigma_pos^2 is not representable ({qn[bad][0]!r}); "
            "check the scales of T, tau, sigma_m/q and sigma_pos"
        )
    code = np.full_like(tf, METHODS[method])
    rows = _abkit.singer_steady_state(theta, qn, rv, code)
    n = rows.shape[0]
    P_n = rows[:, 0:9].reshape(n, 3, 3)
    K_n = rows[:, 9:15].reshape(n, 3, 2)
    Pf_n = rows[:, 15:24].reshape(n, 3, 3)
    Ps_n = rows[:, 24:33].reshape(n, 3, 3)
    eig = rows[:, 33:39:2] + 1j * rows[:, 34:39:2]
    used = rows[:, 39]
    Phi_n = rows[:, 40:49].reshape(n, 3, 3)
    Q_n = rows[:, 49:58].reshape(n, 3, 3)

    # Back to physical units: x = D x_N, D = diag(sigma_pos, sigma_pos/T, sigma_pos/T^2).
    d = np.stack([spf, spf / tf, spf / tf**2], axis=-1)
    dd = d[:, :, None] * d[:, None, :]
    p = 1 if pos_only else 2
    dm = np.stack([spf, spf / tf], axis=-1)[:, :p]
    K = K_n[:, :, :p] * d[:, :, None] / dm[:, None, :]
    if pos_only:
        H = np.array([[1.0, 0.0, 0.0]])
        R = (spf**2).reshape(n, 1, 1)
    else:
        H = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
        R = np.zeros((n, 2, 2))
        R[:, 0, 0] = spf**2
        R[:, 1, 1] = svf**2
    # Variances whose true value is below the solver's tolerance (1e-8 of
    # ||P||) can come out as tiny negatives; within 1e-7 of ||P|| they are
    # zero to that tolerance (fuzzing found -1e-16 next to ||P|| = 7e-9).
    # Beyond it the core returned an error (LinAlgError) above.
    dg = np.diagonal(P_n, axis1=1, axis2=2)
    diag = np.sqrt(np.maximum(dg, 0.0))
    _check_accuracy(P_n, theta, qn, rv, code, shape)

    def sh(x: np.ndarray, tail: Tuple[int, ...]) -> np.ndarray:
        return x.reshape(shape + tail)

    names = np.array(["numeric", "closed-form"])[used.astype(int)]
    res = SingerSteadyState(
        P_pred=sh(P_n * dd, (3, 3)),
        K=sh(K, (3, p)),
        P_filt=sh(Pf_n * dd, (3, 3)),
        P_smooth=sh(Ps_n * dd, (3, 3)),
        eigenvalues=sh(eig, (3,)),
        rms_position=_out(sh(diag[:, 0], ())),
        rms_velocity=_out(sh(diag[:, 1], ())),
        rms_acceleration=_out(sh(diag[:, 2], ())),
        alpha=_out(sh(K_n[:, 0, 0], ())) if pos_only else None,
        beta=_out(sh(K_n[:, 1, 0], ())) if pos_only else None,
        gamma=_out(sh(2.0 * K_n[:, 2, 0], ())) if pos_only else None,
        Phi=sh(Phi_n * d[:, :, None] / d[:, None, :], (3, 3)),
        Q=sh(Q_n * dd, (3, 3)),
        H=H,
        R=sh(R, (p, p)),
        theta=_out(sh(theta, ())),
        p2=_out(sh(p2, ())),
        method_used=str(names[0]) if shape == () else sh(names, ()),
    )
    return res


def tracking_filter(
    T: float,
    tau: Optional[float] = None,
    sigma_m: Optional[float] = None,
    sigma_pos: Optional[float] = None,
    *,
    alpha: Optional[float] = None,
    q: Optional[float] = None,
    method: str = "auto",
) -> Any:
    r"""The steady-state Singer filter (position-only) as a
    :class:`abkit.FixedGainFilter` that knows its model.

    Parameters are those of :func:`steady_state` (scalars; position-only
    measurements). The filter runs ``Phi`` and ``K`` of the steady state at
    ``T``; with timestamps ``t`` it uses at every step the steady state for
    that ``dt_k`` (``theta = dt_k / tau``, ``q_N = q dt_k^5 / sigma_pos^2``;
    closed form with numeric fallback, cached per distinct ``dt``), so its
    ``gain_schedule`` is ``"design"``.

    Returns
    -------
    FixedGainFilter

    Examples
    --------
    >>> import numpy as np
    >>> from abkit import singer
    >>> f = singer.tracking_filter(1.0, tau=20.0, sigma_m=1.0, sigma_pos=10.0)
    >>> f.gain_schedule, f.n
    ('design', 3)
    >>> r = f.run(np.array([0.0, 1.0, 2.0, 4.0]), t=[0.0, 1.0, 2.0, 3.5])
    >>> r.states.shape
    (3, 4)
    """
    from .filters import FixedGainFilter

    for name, v in (("T", T), ("tau", tau), ("sigma_m", sigma_m), ("sigma_pos", sigma_pos), ("alpha", alpha), ("q", q)):
        if v is not None and np.ndim(v) != 0:
            raise ValueError(f"{name} must be a scalar")
    ss = steady_state(T, tau, sigma_m, sigma_pos, method=method, alpha=alpha, q=q)
    ta = float(_resolve_tau(tau, alpha))
    kind, val = _resolve_q(sigma_m, q, np.asarray(ta))
    qd = 2.0 * float(val) ** 2 / ta if kind == "sigma_m" else float(val)
    f = FixedGainFilter(ss.Phi, ss.H, ss.K, T)
    f._tv_law = ("singer", np.array([[ta, qd, float(sigma_pos)]]))  # type: ignore[arg-type]
    f._kinematic = True
    return f
