"""Independent reference computations for the abkit.alphabeta tests.

Nothing here calls abkit. Every expected value used by the tests comes from
one of these routines:

* the steady-state Kalman (DARE) solution of the normalised model
  - in float64 with ``scipy.linalg.solve_discrete_are``,
  - in float64 by brute-force Riccati (predict/update) iteration,
  - in mpmath (50 digits) by the structure-preserving doubling algorithm,
    checked by its Riccati residual and closed-loop stability;
* the fixed-gain steady-state covariance (Lyapunov equation)
  - in float64 with ``scipy.linalg.solve_discrete_lyapunov``,
  - in mpmath as a 3x3 linear system;
* deterministic simulation of the alpha-beta recursion (lag), in mpmath;
* Monte-Carlo simulation of the generating model and the filter recursion;
* numerical integration of |H(j 2 pi f)|^2 for the noise bandwidth.

Model (normalised): F = [[1, 1], [0, 1]], Q = r [[1, 2], [2, 4]], h = [1, 0],
unit measurement-noise variance.
"""

from __future__ import annotations

import math
from typing import Dict, Tuple

import mpmath
import numpy as np
import scipy.integrate
import scipy.linalg

DPS = 50

F = np.array([[1.0, 1.0], [0.0, 1.0]])
H = np.array([[1.0, 0.0]])
QN = np.array([[1.0, 2.0], [2.0, 4.0]])


def relerr(got, want) -> float:
    """Max elementwise |got - want| / |want| (want must be nonzero)."""
    got = np.asarray(got, dtype=float)
    want = np.asarray(want, dtype=float)
    return float(np.max(np.abs(got - want) / np.abs(want)))


# ---------------------------------------------------------------------------
# Kalman steady state: float64
# ---------------------------------------------------------------------------
def filtered_from_predicted(M: np.ndarray) -> np.ndarray:
    S = float((H @ M @ H.T)[0, 0]) + 1.0
    return M - (M @ H.T) @ (H @ M) / S


def dare_scipy(r: float) -> Tuple[np.ndarray, np.ndarray]:
    """(M, P): predicted and filtered steady-state covariance via scipy DARE."""
    M = scipy.linalg.solve_discrete_are(F.T, H.T, r * QN, np.array([[1.0]]))
    return M, filtered_from_predicted(M)


def riccati_iterate(r: float, tol: float = 1e-15, maxit: int = 200000) -> Tuple[np.ndarray, np.ndarray, int]:
    """(M, P, iterations): brute-force Riccati recursion from M0 = 100 I."""
    Q = r * QN
    M = 100.0 * np.eye(2)
    for k in range(maxit):
        P = filtered_from_predicted(M)
        Mn = F @ P @ F.T + Q
        if np.max(np.abs(Mn - M) / np.abs(Mn)) < tol:
            M = Mn
            return M, filtered_from_predicted(M), k
        M = Mn
    raise RuntimeError("Riccati iteration did not converge")


# ---------------------------------------------------------------------------
# Kalman steady state: mpmath, structure-preserving doubling
# ---------------------------------------------------------------------------
def _mm(a, b):
    return (
        (a[0][0] * b[0][0] + a[0][1] * b[1][0], a[0][0] * b[0][1] + a[0][1] * b[1][1]),
        (a[1][0] * b[0][0] + a[1][1] * b[1][0], a[1][0] * b[0][1] + a[1][1] * b[1][1]),
    )


def _madd(a, b):
    return ((a[0][0] + b[0][0], a[0][1] + b[0][1]), (a[1][0] + b[1][0], a[1][1] + b[1][1]))


def _mt(a):
    return ((a[0][0], a[1][0]), (a[0][1], a[1][1]))


def _minv(a):
    det = a[0][0] * a[1][1] - a[0][1] * a[1][0]
    return ((a[1][1] / det, -a[0][1] / det), (-a[1][0] / det, a[0][0] / det))


def _eye():
    one, zero = mpmath.mpf(1), mpmath.mpf(0)
    return ((one, zero), (zero, one))


_MP_CACHE: Dict[Tuple[str, int], Dict[str, mpmath.mpf]] = {}


def dare_mp(r) -> Dict[str, "mpmath.mpf"]:
    """Stabilising DARE solution of the normalised model at 50 digits.

    Structure-preserving doubling (Chu, Fan & Lin 2005) for
    ``X = A^T X (I + G X)^-1 A + Hq`` with ``A = F^T``, ``G = h^T h``,
    ``Hq = Q``; ``X`` is the predicted covariance M. The result is verified by
    the Riccati residual (< 1e-40 relative) and by closed-loop stability.

    ``r`` may be a float (taken exactly) or an mpf / decimal string.
    Returns m11, m12, m22, p11, p12, p22, alpha, beta as mpf.
    """
    key = (mpmath.mpf(r).__repr__() if not isinstance(r, float) else repr(r), DPS)
    if key in _MP_CACHE:
        return _MP_CACHE[key]
    with mpmath.workdps(DPS + 20):
        rr = mpmath.mpf(r)
        zero, one = mpmath.mpf(0), mpmath.mpf(1)
        A = ((one, zero), (one, one))  # F^T
        G = ((one, zero), (zero, zero))
        Hk = ((rr, 2 * rr), (2 * rr, 4 * rr))
        I = _eye()
        for _ in range(400):
            W = _minv(_madd(I, _mm(G, Hk)))
            AW = _mm(A, W)
            A_new = _mm(AW, A)
            G_new = _madd(G, _mm(_mm(AW, G), _mt(A)))
            H_new = _madd(Hk, _mm(_mm(_mt(A), Hk), _mm(W, A)))
            diff = max(abs(H_new[i][j] - Hk[i][j]) / abs(H_new[i][j]) for i in range(2) for j in range(2))
            A, G, Hk = A_new, G_new, H_new
            if diff < mpmath.mpf(10) ** (-(DPS + 10)):
                break
        else:  # pragma: no cover
            raise RuntimeError("doubling did not converge")
        m11, m12, m22 = Hk[0][0], (Hk[0][1] + Hk[1][0]) / 2, Hk[1][1]
        s = m11 + 1
        p11 = m11 / s
        p12 = m12 / s
        p22 = m22 - m12 * m12 / s
        # residual M - (F P F^T + Q)
        res = (
            m11 - (p11 + 2 * p12 + p22 + rr),
            m12 - (p12 + p22 + 2 * rr),
            m22 - (p22 + 4 * rr),
        )
        for e, m in zip(res, (m11, m12, m22)):
            assert abs(e) <= mpmath.mpf(10) ** (-40) * abs(m), "DARE residual too large"
        # stabilising: closed-loop poles of (I - K h) F-type recursion inside unit circle
        a, b = p11, p12
        tr = 2 - a - b
        det = 1 - a
        disc = tr * tr - 4 * det
        if disc >= 0:
            rho = max(abs((tr + mpmath.sqrt(disc)) / 2), abs((tr - mpmath.sqrt(disc)) / 2))
        else:
            rho = mpmath.sqrt(det)
        assert rho < 1, "DARE solution is not stabilising"
        assert m11 > 0 and m11 * m22 - m12 * m12 > 0, "DARE solution is not positive definite"
        out = dict(m11=m11, m12=m12, m22=m22, p11=p11, p12=p12, p22=p22, alpha=p11, beta=p12, r=rr)
    with mpmath.workdps(DPS):
        out = {k: +v for k, v in out.items()}  # round to DPS digits
    _MP_CACHE[key] = out
    return out


def dare_mp_float(r) -> Dict[str, float]:
    return {k: float(v) for k, v in dare_mp(r).items()}


def kalata_beta_mp(alpha):
    """Kalata: the Kalman beta for a given alpha, beta = 2(2 - a) - 4 sqrt(1 - a)."""
    with mpmath.workdps(DPS + 20):
        a = mpmath.mpf(alpha)
        u = mpmath.sqrt(1 - a)
        return +(2 * (2 - a) - 4 * u)


def kalata_r_mp(alpha):
    """SNR r whose Kalman design has this alpha: beta^2/(1 - alpha) = lambda^2 = 4 r."""
    with mpmath.workdps(DPS + 20):
        a = mpmath.mpf(alpha)
        b = kalata_beta_mp(a)
        return +(b * b / (1 - a) / 4)


# ---------------------------------------------------------------------------
# Fixed-gain steady state (Lyapunov)
# ---------------------------------------------------------------------------
def lyap_scipy(alpha: float, beta: float, r: float) -> Tuple[np.ndarray, np.ndarray]:
    """(P, M) of fixed gains K = [alpha, beta] at true SNR r, via scipy."""
    K = np.array([[alpha], [beta]])
    IKh = np.eye(2) - K @ H
    A = F @ IKh
    C = F @ (K @ K.T) @ F.T + r * QN
    M = scipy.linalg.solve_discrete_lyapunov(A, C)
    M = (M + M.T) / 2
    P = IKh @ M @ IKh.T + K @ K.T
    return P, M


def lyap_mp(alpha, beta, r) -> Tuple[list, list]:
    """(P, M) as [p11, p12, p22], [m11, m12, m22] mpf, via a 50-digit linear solve.

    Unknowns m11, m12, m22 of M = F ((I-Kh) M (I-Kh)^T + K K^T) F^T + Q.
    """
    with mpmath.workdps(DPS + 20):
        a, b, rr = mpmath.mpf(alpha), mpmath.mpf(beta), mpmath.mpf(r)

        def Pof(m11, m12, m22):
            # (I - K h) = [[1-a, 0], [-b, 1]]
            p11 = (1 - a) ** 2 * m11 + a * a
            p12 = (1 - a) * (-b * m11 + m12) + a * b
            p22 = b * b * m11 - 2 * b * m12 + m22 + b * b
            return p11, p12, p22

        def Mof(p11, p12, p22):
            return p11 + 2 * p12 + p22 + rr, p12 + p22 + 2 * rr, p22 + 4 * rr

        # M = L(M) + c is affine; build the matrix column by column
        z = mpmath.mpf(0)
        c = Mof(*Pof(z, z, z))
        A = mpmath.matrix(3, 3)
        for j in range(3):
            e = [z, z, z]
            e[j] = mpmath.mpf(1)
            col = Mof(*Pof(*e))
            for i in range(3):
                A[i, j] = (1 if i == j else 0) - (col[i] - c[i])
        m = mpmath.lu_solve(A, mpmath.matrix(list(c)))
        M = [m[0], m[1], m[2]]
        P = list(Pof(*M))
        return [+x for x in P], [+x for x in M]


# ---------------------------------------------------------------------------
# Deterministic design relations
# ---------------------------------------------------------------------------
def continuous_from_gains(alpha: float, beta: float) -> Tuple[float, float]:
    """(omega_n T, damping) from eq (15): beta = x^2, alpha = 2 delta x - x^2 / 2."""
    x = math.sqrt(beta)
    return x, (alpha + beta / 2) / (2 * x)


def noise_bandwidth_quad(wT: float, delta: float, T: float = 1.0) -> float:
    """One-sided noise bandwidth (Hz) times T of H(s) = (b1 s + b2)/(s^2 + 2 delta w s + w^2).

    b1 = w (2 delta - w T), b2 = w^2. Computed by scipy.integrate.quad of
    |H(j 2 pi f)|^2 over f in [0, inf), split at the resonance.
    """
    w = wT / T
    b1 = w * (2 * delta - wT)
    b2 = w * w

    def g(f):
        s = 2j * math.pi * f
        h = (b1 * s + b2) / (s * s + 2 * delta * w * s + w * w)
        return abs(h) ** 2

    fn = w / (2 * math.pi)
    pts = [0.0, fn * 0.5, fn, 2 * fn, 8 * fn]
    total = 0.0
    for lo, hi in zip(pts[:-1], pts[1:]):
        total += scipy.integrate.quad(g, lo, hi, epsabs=0, epsrel=1e-13, limit=400)[0]
    total += scipy.integrate.quad(g, pts[-1], np.inf, epsabs=0, epsrel=1e-13, limit=400)[0]
    return total * T


def bandwidth_cubic_roots(bn_t: float, delta: float) -> np.ndarray:
    """Real roots x = omega_n T of eq (16) in (0, min(4 delta, 1/delta)), ascending.

    x (1 + (2 delta - x)^2) / (8 delta) = bn_t  <=>
    x^3 - 4 delta x^2 + (1 + 4 delta^2) x - 8 delta bn_t = 0  (numpy.roots).
    """
    roots = np.roots([1.0, -4.0 * delta, 1.0 + 4.0 * delta * delta, -8.0 * delta * bn_t])
    hi = min(4 * delta, 1 / delta)
    real = [z.real for z in roots if abs(z.imag) <= 1e-9 * max(1.0, abs(z))]
    return np.sort([x for x in real if 0 < x < hi])


# ---------------------------------------------------------------------------
# Simulations of the recursion
# ---------------------------------------------------------------------------
def simulate_lag(alpha: float, beta: float, dps: int = 40, tol_exp: int = 30, maxit: int = 200000):
    """Steady-state lag under constant acceleration by running the recursion.

    Truth (units a T^2 and a T): x_{k+1} = F x_k + [1/2, 1] (constant
    acceleration held over each period), x_0 = 0. Noise-free measurement of
    position. The alpha-beta recursion starts at 0. Returns
    (pos_filt, vel_filt, pos_pred, vel_pred), each truth minus estimate, once
    the errors stop changing (to 1e-tol_exp). Uses mpmath so that the growing
    parabola costs no accuracy.
    """
    with mpmath.workdps(dps):
        a, b = mpmath.mpf(alpha), mpmath.mpf(beta)
        half = mpmath.mpf(1) / 2
        tp, tv = mpmath.mpf(0), mpmath.mpf(0)  # truth
        x, v = mpmath.mpf(0), mpmath.mpf(0)  # filter
        prev = None
        eps = mpmath.mpf(10) ** (-tol_exp)
        for k in range(maxit):
            tp, tv = tp + tv + half, tv + 1
            xp, vp = x + v, v
            e = tp - xp
            x, v = xp + a * e, v + b * e
            cur = (tp - x, tv - v, tp - xp, tv - vp)
            if prev is not None and all(abs(c - p) <= eps * (1 + abs(c)) for c, p in zip(cur, prev)):
                return tuple(float(c) for c in cur)
            prev = cur
    raise RuntimeError("lag simulation did not converge")


def monte_carlo_covariance(alpha: float, beta: float, r: float, nchains: int, nsteps: int, seed: int):
    """Sample covariances (P, M) of the estimation error at step nsteps.

    ``nchains`` independent runs of the generating model
    x_{k+1} = F x_k + sqrt(r) [1, 2] n_k (i.e. Q = r [[1,2],[2,4]]),
    z_k = x1_k + v_k, with the alpha-beta recursion, all started at the truth.
    Returns the sample covariance of the filtered error and of the one-step
    predicted error at the last step (independent samples across chains).
    """
    rng = np.random.default_rng(seed)
    sr = math.sqrt(r)
    tp = np.zeros(nchains)
    tv = np.zeros(nchains)
    x = np.zeros(nchains)
    v = np.zeros(nchains)
    for _ in range(nsteps):
        if sr:
            n = rng.standard_normal(nchains) * sr
            tp, tv = tp + tv + n, tv + 2 * n
        else:
            tp = tp + tv
        xp, vp = x + v, v
        z = tp + rng.standard_normal(nchains)
        e = z - xp
        x, v = xp + alpha * e, v + beta * e
    ef = np.stack([tp - x, tv - v])
    ep = np.stack([tp - xp, tv - vp])
    return np.cov(ef), np.cov(ep)
