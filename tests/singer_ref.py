"""Independent references for the Singer-model tests (nothing here calls abkit).

* ``q_quad``: Q by mpmath quadrature of its definition
  ``Q = q int_0^T g(s) g(s)^T ds``, ``g(s) = e^{A s} e_3``, with the
  closed-form ``e^{A s} e_3 = (tau^2 (s/tau - 1 + e^{-s/tau}), tau (1 - e^{-s/tau}), e^{-s/tau})``
  checked against expm in the tests.
* ``van_loan``: (Phi, Q) by Van Loan's method, in float64 (scipy expm) or
  mpmath (expm at high precision).
* ``hamiltonian``: the paper's H_f built from its definition (Vaughan).
* ``batch_smoother``: steady-state prediction, filter and smoother covariances
  as blocks of the inverse of the information matrix of a long batch
  least-squares problem (no Riccati or Lyapunov recursion).
"""

from __future__ import annotations

import mpmath
import numpy as np
import scipy.linalg


def cont_A(tau: float) -> np.ndarray:
    a = 0.0 if np.isinf(tau) else 1.0 / tau
    return np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, -a]])


def van_loan(T: float, tau: float, q: float):
    """(Phi, Q) of the continuous model by Van Loan (1978) with scipy.linalg.expm."""
    A = cont_A(tau)
    W = np.zeros((3, 3))
    W[2, 2] = q
    M = np.zeros((6, 6))
    M[:3, :3] = -A
    M[:3, 3:] = W
    M[3:, 3:] = A.T
    E = scipy.linalg.expm(M * T)
    Phi = E[3:, 3:].T
    Q = Phi @ E[:3, 3:]
    return Phi, (Q + Q.T) / 2


def van_loan_mp(T, tau, q, dps=60):
    """Van Loan in mpmath (all arguments as strings or mpf for exactness)."""
    with mpmath.workdps(dps):
        T, q = mpmath.mpf(T), mpmath.mpf(q)
        a = mpmath.mpf(0) if tau == "inf" else 1 / mpmath.mpf(tau)
        A = mpmath.matrix([[0, 1, 0], [0, 0, 1], [0, 0, -a]])
        M = mpmath.zeros(6, 6)
        for i in range(3):
            for j in range(3):
                M[i, j] = -A[i, j] * T
                M[3 + i, 3 + j] = A[j, i] * T
        M[2, 5] = q * T
        E = mpmath.expm(M)
        F3 = E[3:6, 3:6]
        G2 = E[0:3, 3:6]
        Phi = F3.T
        Q = Phi * G2
        return (np.array(Phi.tolist(), dtype=float), np.array(Q.tolist(), dtype=float))


def q_quad(T, tau, q, dps=40):
    """Q by mpmath quadrature of the definition (any T/tau)."""
    with mpmath.workdps(dps):
        T, tau, q = mpmath.mpf(T), mpmath.mpf(tau), mpmath.mpf(q)

        def g(s):
            # tau^2 (s/tau - 1 + e^{-s/tau}) = s^2 phi_2(-s/tau), tau (1 - e^{-s/tau}) = s phi_1(-s/tau),
            # phi_k(z) = 1F1(1; k+1; z) / k!
            z = -s / tau
            return [s**2 / 2 * mpmath.hyp1f1(1, 3, z), s * mpmath.hyp1f1(1, 2, z), mpmath.exp(z)]

        pts = [mpmath.mpf(0)]
        for m in (1, 5, 20, 60):
            if m * tau < T:
                pts.append(m * tau)
        pts.append(T)
        Q = np.zeros((3, 3))
        for i in range(3):
            for j in range(i, 3):
                v = q * mpmath.quad(lambda s: g(s)[i] * g(s)[j], pts)
                Q[i, j] = Q[j, i] = float(v)
        return Q


def phi_inv(Phi):
    return np.linalg.inv(Phi)


def hamiltonian(Phi, H, Q, R):
    """Vaughan's H_f of the paper: [[Phi^-T, Phi^-T H' R^-1 H], [Q Phi^-T, Phi + Q Phi^-T H' R^-1 H]]."""
    Fit = np.linalg.inv(Phi).T
    M = H.T @ np.linalg.solve(R, H)
    return np.block([[Fit, Fit @ M], [Q @ Fit, Phi + Q @ Fit @ M]])


def batch_smoother(Phi, H, Q, R, N=241, P0scale=1e6):
    """(P_pred, P_filt, P_smooth) at the middle of a long batch, from the joint information matrix.

    States x_0..x_N, prior x_0 ~ N(0, P0scale I), dynamics x_{k+1} = Phi x_k + v_k,
    measurements z_k = H x_k + w_k for k = 0..N. P_smooth: the marginal of x_m
    given all z; P_filt: given z_0..z_m (a batch ending at m); P_pred: the
    marginal of x_{m+1} given z_0..z_m.
    """
    n = Phi.shape[0]
    Qi = np.linalg.inv(Q)
    Ri = np.linalg.inv(R)

    def info(last_meas, n_states):
        J = np.zeros((n * n_states, n * n_states))
        J[:n, :n] += np.eye(n) / P0scale
        for k in range(n_states - 1):
            a, b = slice(n * k, n * k + n), slice(n * k + n, n * k + 2 * n)
            J[a, a] += Phi.T @ Qi @ Phi
            J[a, b] -= Phi.T @ Qi
            J[b, a] -= Qi @ Phi
            J[b, b] += Qi
        for k in range(min(last_meas + 1, n_states)):
            a = slice(n * k, n * k + n)
            J[a, a] += H.T @ Ri @ H
        return J

    m = N // 2
    Jall = info(N, N + 1)
    Ps = np.linalg.inv(Jall)[n * m : n * m + n, n * m : n * m + n]
    Jf = info(m, m + 2)  # states 0..m+1, measurements 0..m
    C = np.linalg.inv(Jf)
    Pf = C[n * m : n * m + n, n * m : n * m + n]
    Pp = C[n * (m + 1) :, n * (m + 1) :]
    return Pp, Pf, Ps
