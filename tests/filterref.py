"""Independent plain-NumPy reference for the abkit.filters compliance tests.

Nothing in this module imports abkit. It implements the *documented*
semantics of the batched fixed-gain filtering engine (issue 3 and the
docstrings of ``abkit.filters``) directly, one sample at a time, vectorised
over tracks only, in float64:

* per sample ``x_p = Phi x``, ``e = z - H x_p``, ``x = x_p + K e``; the update is
  skipped (coast, ``x = x_p``) when any component of ``z`` is NaN, and the
  residual is NaN then;
* before a track's first valid sample its estimates are NaN;
* ``init="first"``: at the first valid sample the state is ``pinv(H) z`` (that
  sample's output is that state, residual NaN), filtering from the next one;
* ``init="two-point"`` (kinematic ``[position, velocity, ...]`` state measured
  in position): at the first valid sample the output is ``[z1, NaN, ...]``; at
  the missed samples that follow it stays ``[z1, NaN, ...]``; at the second
  valid sample, ``g`` samples after the first, the state is
  ``[z2, (z2 - z1) / (g T), 0, ...]`` (output, residual NaN); filtering from the
  next sample;
* an explicit init array is the state just before sample 0;
* the steady-state RTS smoother ``x_s[k] = x_f[k] + A (x_s[k+1] - Phi x_f[k])``
  over the whole track (fixed interval) or over the window ``k..k+L`` started
  from ``x_f[min(k+L, n-1)]`` (fixed lag); samples whose filtered estimate has a
  NaN component stay as filtered and the recursion restarts below them;
* steady-state covariances from the fixed-gain Lyapunov equations
  (``scipy.linalg.solve_discrete_lyapunov``) and the Kalman (DARE) design
  (``scipy.linalg.solve_discrete_are``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional, Tuple

import numpy as np
import scipy.linalg

#: filter-form acceleration gain factor c in K[2] = c * gamma / T^2
ABG_C = {"standard": 0.5, "chen-chui": 1.0, "ghk": 2.0}


# ---------------------------------------------------------------------------
# models
# ---------------------------------------------------------------------------
@dataclass
class Model:
    """Per-parameter-set model: Phi (P, n, n), H (P, m, n), K (P, n, m), T (P,)."""

    Phi: np.ndarray
    H: np.ndarray
    K: np.ndarray
    T: np.ndarray

    @property
    def n(self) -> int:
        return self.Phi.shape[-1]

    @property
    def m(self) -> int:
        return self.H.shape[-2]

    def for_tracks(self, ntr: int) -> "Model":
        P = self.Phi.shape[0]
        assert P in (1, ntr), (P, ntr)
        b = lambda a: np.broadcast_to(a, (ntr,) + a.shape[1:])  # noqa: E731
        return Model(b(self.Phi), b(self.H), b(self.K), b(self.T))


def _vec(*vals) -> Tuple[np.ndarray, ...]:
    arrs = np.broadcast_arrays(*[np.atleast_1d(np.asarray(v, dtype=np.float64)) for v in vals])
    return tuple(a.reshape(-1) for a in arrs)


def ab_model(alpha, beta, T) -> Model:
    a, b, t = _vec(alpha, beta, T)
    P = a.size
    phi = np.zeros((P, 2, 2))
    phi[:, 0, 0] = phi[:, 1, 1] = 1.0
    phi[:, 0, 1] = t
    h = np.zeros((P, 1, 2))
    h[:, 0, 0] = 1.0
    k = np.zeros((P, 2, 1))
    k[:, 0, 0] = a
    k[:, 1, 0] = b / t
    return Model(phi, h, k, t)


def abg_model(alpha, beta, gamma, T, convention: str = "standard") -> Model:
    a, b, g, t = _vec(alpha, beta, gamma, T)
    c = ABG_C[convention]
    P = a.size
    phi = np.zeros((P, 3, 3))
    phi[:, 0, 0] = phi[:, 1, 1] = phi[:, 2, 2] = 1.0
    phi[:, 0, 1] = phi[:, 1, 2] = t
    phi[:, 0, 2] = t * t / 2.0
    h = np.zeros((P, 1, 3))
    h[:, 0, 0] = 1.0
    k = np.zeros((P, 3, 1))
    k[:, 0, 0] = a
    k[:, 1, 0] = b / t
    k[:, 2, 0] = c * g / (t * t)
    return Model(phi, h, k, t)


def general_model(Phi, H, K, T=1.0) -> Model:
    phi = np.asarray(Phi, dtype=np.float64)
    h = np.asarray(H, dtype=np.float64)
    k = np.asarray(K, dtype=np.float64)
    if phi.ndim == 2:
        phi = phi[None]
    if h.ndim == 2:
        h = h[None]
    if k.ndim == 2:
        k = k[None]
    P = max(phi.shape[0], h.shape[0], k.shape[0])
    t = np.broadcast_to(np.atleast_1d(np.asarray(T, dtype=np.float64)), (P,))
    b = lambda a: np.broadcast_to(a, (P,) + a.shape[1:]).copy()  # noqa: E731
    return Model(b(phi), b(h), b(k), t.copy())


def closed_loop_radius(model: Model) -> np.ndarray:
    n = model.n
    a = (np.eye(n) - model.K @ model.H) @ model.Phi
    return np.max(np.abs(np.linalg.eigvals(a)), axis=-1)


def singer_phi(T: float, a: float) -> np.ndarray:
    """Singer model transition for [position, velocity, acceleration]."""
    e = np.exp(-a * T)
    return np.array(
        [
            [1.0, T, (a * T - 1.0 + e) / (a * a)],
            [0.0, 1.0, (1.0 - e) / a],
            [0.0, 0.0, e],
        ]
    )


def dare_gain(Phi, H, Q, R) -> np.ndarray:
    """Steady-state Kalman (filter-form) gain from scipy's DARE."""
    Phi, H, Q, R = (np.asarray(v, dtype=np.float64) for v in (Phi, H, Q, R))
    M = scipy.linalg.solve_discrete_are(Phi.T, H.T, Q, R)
    return M @ H.T @ np.linalg.inv(H @ M @ H.T + R)


# ---------------------------------------------------------------------------
# filter
# ---------------------------------------------------------------------------
@dataclass
class RefState:
    x: np.ndarray  # (ntr, n)
    phase: np.ndarray  # (ntr,) 0 no valid sample yet, 1 one valid sample held, 2 running
    z1: np.ndarray  # (ntr,) first valid position (two-point start)
    gap: np.ndarray  # (ntr,) samples since the first valid one (two-point start)

    @classmethod
    def new(cls, ntr: int, n: int) -> "RefState":
        return cls(np.zeros((ntr, n)), np.zeros(ntr, dtype=np.int64), np.zeros(ntr), np.zeros(ntr, dtype=np.int64))

    def copy(self) -> "RefState":
        return RefState(self.x.copy(), self.phase.copy(), self.z1.copy(), self.gap.copy())


def as_tracks(z, m: int) -> Tuple[np.ndarray, bool]:
    """User layout -> (n_tracks, n_samples, m) float64 copy, and single-track flag."""
    z = np.array(z, dtype=np.float64)  # exact for float32 input
    if m == 1:
        if z.ndim == 1:
            return z[None, :, None], True
        assert z.ndim == 2
        return z[:, :, None], False
    if z.ndim == 2:
        return z[None], True
    assert z.ndim == 3
    return z, False


def _mv(A: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Batched matrix @ vector: (t, i, j) x (t, j) -> (t, i), plain sums."""
    return np.sum(A * x[:, None, :], axis=-1)


def filter_ref(z3: np.ndarray, model: Model, init="two-point", state: Optional[RefState] = None):
    """Run the documented fixed-gain filter.

    Returns ``states (ntr, N, n)``, ``residuals (ntr, N, m)`` and the final
    :class:`RefState`.
    """
    z3 = np.asarray(z3, dtype=np.float64)
    ntr, N, m = z3.shape
    mod = model.for_tracks(ntr)
    n = mod.n
    assert mod.m == m
    if state is None:
        st = RefState.new(ntr, n)
        if not isinstance(init, str):
            st.x[:] = np.broadcast_to(np.asarray(init, dtype=np.float64), (ntr, n))
            st.phase[:] = 2
    else:
        st = state.copy()
    mode = init if isinstance(init, str) else "first"
    hpinv = np.linalg.pinv(mod.H)  # (ntr, n, m)
    out = np.full((ntr, N, n), np.nan)
    res = np.full((ntr, N, m), np.nan)
    for j in range(N):
        zj = z3[:, j, :]
        valid = ~np.isnan(zj).any(axis=1)
        ph = st.phase.copy()
        run = np.nonzero(ph == 2)[0]
        if run.size:
            xp = _mv(mod.Phi[run], st.x[run])
            e = zj[run] - _mv(mod.H[run], xp)
            v = valid[run]
            xn = xp.copy()
            if v.any():
                xn[v] = xp[v] + _mv(mod.K[run][v], e[v])
                res[run[v], j] = e[v]
            st.x[run] = xn
            out[run, j] = xn
        one = ph == 1
        if one.any():
            st.gap[one] += 1
            sec = np.nonzero(one & valid)[0]
            hold = np.nonzero(one & ~valid)[0]
            if sec.size:
                x = np.zeros((sec.size, n))
                x[:, 0] = zj[sec, 0]
                x[:, 1] = (zj[sec, 0] - st.z1[sec]) / (st.gap[sec] * mod.T[sec])
                st.x[sec] = x
                st.phase[sec] = 2
                out[sec, j] = x
            if hold.size:
                out[hold, j, 0] = st.z1[hold]
        zero = np.nonzero((ph == 0) & valid)[0]
        if zero.size:
            if mode == "first":
                x = _mv(hpinv[zero], zj[zero])
                st.x[zero] = x
                st.phase[zero] = 2
                out[zero, j] = x
            elif mode == "two-point":
                st.z1[zero] = zj[zero, 0]
                st.gap[zero] = 0
                st.phase[zero] = 1
                out[zero, j, 0] = zj[zero, 0]
            else:  # pragma: no cover
                raise ValueError(mode)
    return out, res, st


def to_user(states3: np.ndarray, res3: np.ndarray, single: bool, m: int):
    """(ntr, N, n) / (ntr, N, m) -> abkit's layouts: states (n, [ntr,] N), residuals shaped like z."""
    s = np.moveaxis(states3, 2, 0)  # (n, ntr, N)
    if single:
        s = s[:, 0]
    r = res3
    if m == 1:
        r = r[..., 0]
    if single:
        r = r[0]
    return s, r


def run_ref(z, model: Model, init="two-point", state: Optional[RefState] = None):
    """User-layout convenience: returns (states, residuals, final RefState) in abkit's layouts."""
    z3, single = as_tracks(z, model.m)
    s3, r3, st = filter_ref(z3, model, init, state)
    s, r = to_user(s3, r3, single, model.m)
    return s, r, st


# ---------------------------------------------------------------------------
# smoother
# ---------------------------------------------------------------------------
def smooth_ref(xf: np.ndarray, model: Model, A: np.ndarray, lag: Optional[int] = None) -> np.ndarray:
    """Steady-state RTS smoothing of filtered estimates ``xf (ntr, N, n)``.

    ``A``: (n, n) or (ntr, n, n).
    """
    ntr, N, n = xf.shape
    mod = model.for_tracks(ntr)
    A = np.broadcast_to(np.asarray(A, dtype=np.float64).reshape((-1, n, n)), (ntr, n, n))
    Phi = mod.Phi
    finite = np.isfinite(xf).all(axis=2)  # (ntr, N)
    xs = xf.copy()
    if N == 0:
        return xs
    if lag is None:
        for k in range(N - 2, -1, -1):
            ok = finite[:, k] & finite[:, k + 1]
            if ok.any():
                i = np.nonzero(ok)[0]
                d = xs[i, k + 1] - _mv(Phi[i], xf[i, k])
                xs[i, k] = xf[i, k] + _mv(A[i], d)
        return xs
    L = int(lag)
    ks = np.arange(N)
    end = np.minimum(ks + L, N - 1)
    s = xf[:, end].copy()  # (ntr, N, n): running estimate for every k
    Phi_b = np.broadcast_to(Phi[:, None], (ntr, N, n, n))
    A_b = np.broadcast_to(A[:, None], (ntr, N, n, n))
    for d in range(L - 1, -1, -1):
        j = ks + d
        act = j < end  # windows that include sample j = k + d below their end
        if not act.any():
            continue
        jj = np.where(act, j, 0)
        jn = np.where(act, j + 1, 0)
        xfj = xf[:, jj]  # (ntr, N, n)
        ok = finite[:, jj] & finite[:, jn]
        cand = xfj + np.sum(A_b * (s - np.sum(Phi_b * xfj[:, :, None, :], axis=-1))[:, :, None, :], axis=-1)
        new = np.where(ok[..., None], cand, xfj)
        s = np.where(act[None, :, None], new, s)
    return s


# ---------------------------------------------------------------------------
# covariances
# ---------------------------------------------------------------------------
@dataclass
class Cov:
    predicted: np.ndarray
    filtered: np.ndarray
    smoothed: np.ndarray
    smoother_gain: np.ndarray


def fixed_gain_cov(Phi, H, K, Q, R) -> Cov:
    """Steady-state covariances of a fixed-gain filter under (Q, R) (Lyapunov)."""
    Phi, H, K, Q, R = (np.atleast_2d(np.asarray(v, dtype=np.float64)) for v in (Phi, H, K, Q, R))
    n = Phi.shape[0]
    ikh = np.eye(n) - K @ H
    a = Phi @ ikh
    M = scipy.linalg.solve_discrete_lyapunov(a, Phi @ K @ R @ K.T @ Phi.T + Q)
    P = ikh @ M @ ikh.T + K @ R @ K.T
    A = P @ Phi.T @ np.linalg.inv(M)
    Ps = None
    if np.max(np.abs(np.linalg.eigvals(A))) < 1 - 1e-9:  # else: no steady-state smoother covariance
        Ps = scipy.linalg.solve_discrete_lyapunov(A, P - A @ M @ A.T)
    return Cov(M, P, Ps, A)


def white_accel_Q(T: float, sigma_w: float) -> np.ndarray:
    d = np.array([[T * T / 2.0], [T]])
    return sigma_w**2 * (d @ d.T)


def snr_sigma_w(r: float, T: float, sigma_v: float = 1.0) -> float:
    """sigma_w with r = ((sigma_w T^2 / 2) / sigma_v)^2 (Painter et al. eq (9))."""
    return 2.0 * np.sqrt(r) * sigma_v / (T * T)


def kalman_ab_dare(r: float, T: float):
    """Kalman alpha-beta design for SNR r from scipy's DARE, physical units.

    Returns (alpha, beta, A) with A = P Phi^T M^-1.
    """
    Phi = np.array([[1.0, T], [0.0, 1.0]])
    H = np.array([[1.0, 0.0]])
    Q = white_accel_Q(T, snr_sigma_w(r, T))
    R = np.array([[1.0]])
    M = scipy.linalg.solve_discrete_are(Phi.T, H.T, Q, R)
    K = M @ H.T @ np.linalg.inv(H @ M @ H.T + R)
    P = (np.eye(2) - K @ H) @ M
    A = P @ Phi.T @ np.linalg.inv(M)
    return float(K[0, 0]), float(K[1, 0] * T), A


def kalman_snr_of_alpha(alpha: float) -> float:
    """The SNR r whose Kalman alpha-beta design has this alpha.

    Kalman designs satisfy beta = 2 (2 - alpha) - 4 sqrt(1 - alpha) and
    lambda^2 = beta^2 / (1 - alpha) = 4 r.
    """
    u = np.sqrt(1.0 - alpha)
    beta_k = 2.0 * (1.0 - u) ** 2  # = 2(2 - alpha) - 4 sqrt(1 - alpha)
    return beta_k**2 / (4.0 * (1.0 - alpha))


def default_ab_smoother_gain(alpha: float, beta: float, T: float) -> np.ndarray:
    """Documented default backward gain of AlphaBetaFilter: the covariances of
    these gains under the Kalman-equivalent model (the SNR whose Kalman
    design has this alpha), A = P Phi^T M^-1."""
    r = kalman_snr_of_alpha(alpha)
    Phi = np.array([[1.0, T], [0.0, 1.0]])
    H = np.array([[1.0, 0.0]])
    K = np.array([[alpha], [beta / T]])
    return fixed_gain_cov(Phi, H, K, white_accel_Q(T, snr_sigma_w(r, T)), [[1.0]]).smoother_gain


# ---------------------------------------------------------------------------
# comparisons and data
# ---------------------------------------------------------------------------
def assert_states_close(got: np.ndarray, want: np.ndarray, rtol: float = 1e-12, what: str = "states", kin_T: Optional[float] = None) -> float:
    """Component-major arrays (n, ...): identical NaN pattern; finite values
    within ``rtol * scale_c`` where ``scale_c`` is the max |value| of component
    ``c`` of the reference (at least the smallest normal number). Returns the
    worst error in units of the scale."""
    got = np.asarray(got)
    want = np.asarray(want)
    assert got.shape == want.shape, f"{what}: shape {got.shape} != {want.shape}"
    gn, wn = np.isnan(got), np.isnan(want)
    if not np.array_equal(gn, wn):
        idx = np.argwhere(gn != wn)[:5]
        raise AssertionError(f"{what}: NaN pattern differs at {idx.tolist()} (got {[got[tuple(i)] for i in idx]}, want {[want[tuple(i)] for i in idx]})")
    worst = 0.0
    for c in range(want.shape[0]):
        w = want[c].astype(np.float64)
        g = got[c].astype(np.float64)
        fin = ~np.isnan(w)
        if not fin.any():
            continue
        scale = max(float(np.max(np.abs(w[fin]))), np.finfo(np.float64).tiny)
        if kin_T is not None and c > 0:
            # kinematic state: the position scale in this component's units
            # (a last-bit position error enters the rates through K/T^c)
            scale = max(scale, float(np.nanmax(np.abs(want[0]))) / kin_T**c)
        err = float(np.max(np.abs(g[fin] - w[fin]))) / scale
        worst = max(worst, err)
        if not err <= rtol:
            i = np.unravel_index(int(np.argmax(np.where(fin, np.abs(g - w), -1.0))), w.shape)
            raise AssertionError(f"{what}[{c}]: max error {err:.3g} x scale {scale:.3g} > {rtol:g} at {i}: got {g[i]!r}, want {w[i]!r}")
    return worst


def assert_resid_close(got: np.ndarray, want: np.ndarray, rtol: float = 1e-12, m: int = 1) -> float:
    """Residuals shaped like z: move the measurement component first if m == 2."""
    got = np.asarray(got)
    want = np.asarray(want)
    if m == 1:
        return assert_states_close(got[None], want[None], rtol, "residuals")
    return assert_states_close(np.moveaxis(got, -1, 0), np.moveaxis(want, -1, 0), rtol, "residuals")


def random_ab_gains(rng: np.random.Generator, size=None, margin: float = 0.05):
    """Uniform in the stable triangle alpha > 0, beta > 0, 2 alpha + beta < 4 (with a margin)."""
    while True:
        a = rng.uniform(margin, 2.0 - margin, size)
        b = rng.uniform(margin / 4, 4.0 - margin, size)
        ok = 2 * a + b < 4.0 - margin
        if np.all(ok):
            return a, b
        if size is None:
            continue
        # resample the bad ones
        a2, b2 = random_ab_gains(rng, int(np.sum(~ok)), margin)
        a = np.array(a, dtype=float)
        b = np.array(b, dtype=float)
        a[~ok], b[~ok] = a2, b2
        return a, b


def random_abg_gains(rng: np.random.Generator, convention: str, T: float = 1.0, rho_max: float = 0.97):
    """Random (alpha, beta, gamma) whose closed loop has spectral radius < rho_max."""
    while True:
        a = rng.uniform(0.05, 1.9)
        b = rng.uniform(0.01, 3.0)
        g = rng.uniform(0.001, 2.0) / ABG_C[convention]
        if closed_loop_radius(abg_model(a, b, g, T, convention))[0] < rho_max:
            return a, b, g


def kinematic_z(rng: np.random.Generator, ntr: int, N: int, T, noise: float = 1.0, m: int = 1) -> np.ndarray:
    """Maneuvering-ish positions (ntr, N) (or velocities too, (ntr, N, 2)) with noise."""
    T = np.broadcast_to(np.atleast_1d(np.asarray(T, dtype=float)), (ntr,))[:, None]
    t = np.arange(N)[None, :] * T
    p0 = rng.uniform(-50, 50, (ntr, 1))
    v0 = rng.uniform(-5, 5, (ntr, 1))
    a0 = rng.uniform(-0.5, 0.5, (ntr, 1))
    w = np.cumsum(rng.normal(0, 0.2, (ntr, N)), axis=1) * T  # random velocity wander
    pos = p0 + v0 * t + 0.5 * a0 * np.minimum(t, 20.0) ** 2 + np.cumsum(w, axis=1) * T
    vel = v0 + a0 * np.minimum(t, 20.0) + w
    zp = pos + rng.normal(0, noise, (ntr, N))
    if m == 1:
        return zp
    zv = vel + rng.normal(0, noise, (ntr, N))
    return np.stack([zp, zv], axis=-1)


def with_nans(rng: np.random.Generator, z: np.ndarray, pattern: str) -> np.ndarray:
    """Insert NaN (missed detections) in the (ntr, N[, m]) array z by pattern."""
    z = np.array(z, dtype=float)
    ntr, N = z.shape[:2]
    vec = z.ndim == 3

    def kill(i, j, comp=None):
        if vec:
            if comp is None:
                comp = rng.integers(0, z.shape[2])  # one component NaN is enough
            z[i, j, comp] = np.nan
        else:
            z[i, j] = np.nan

    if pattern == "none":
        return z
    if pattern == "random":
        for i in range(ntr):
            for j in np.nonzero(rng.random(N) < 0.25)[0]:
                kill(i, j)
    elif pattern == "leading":
        for i in range(ntr):
            for j in range(rng.integers(0, min(N, 15))):
                kill(i, j)
    elif pattern == "trailing":
        for i in range(ntr):
            for j in range(N - rng.integers(0, min(N, 15)), N):
                kill(i, j)
    elif pattern == "all-nan-tracks":
        for i in range(0, ntr, 3):
            for j in range(N):
                kill(i, j)
    elif pattern == "runs":
        for i in range(ntr):
            j = 0
            while j < N:
                j += rng.integers(1, 12)
                L = rng.integers(1, 9)
                for jj in range(j, min(N, j + L)):
                    kill(i, jj)
                j += L
    elif pattern == "start-gaps":
        # NaN runs across the two-point start: lead NaN, 1st valid, gap, 2nd valid, ...
        for i in range(ntr):
            lead = rng.integers(0, 4)
            gap = rng.integers(0, 6)
            for j in range(lead):
                kill(i, j)
            for j in range(lead + 1, min(N, lead + 1 + gap)):
                kill(i, j)
            if rng.random() < 0.5 and lead + 2 + gap < N:
                kill(i, lead + 2 + gap)  # a miss right after the second valid one
    elif pattern == "one-valid":
        # tracks with a single valid sample (two-point start never completes)
        for i in range(ntr):
            keep = rng.integers(0, N)
            for j in range(N):
                if j != keep:
                    kill(i, j)
    elif pattern == "mixed":
        for i in range(ntr):
            p = ["random", "leading", "trailing", "runs", "start-gaps", "none"][i % 6]
            z[i : i + 1] = with_nans(rng, z[i : i + 1], p)
        if ntr > 1:
            z[ntr // 2] = np.nan
    else:  # pragma: no cover
        raise ValueError(pattern)
    return z


def seed_of(*parts) -> int:
    """A deterministic seed from a case's parameters (str hash() is salted per process)."""
    import zlib

    return zlib.crc32(repr(parts).encode())


def ab_scalar_ref(z, alpha: float, beta: float, T: float):
    """Plain-Python scalar alpha-beta loop (two-point start) for one long track.

    Returns (position, velocity) as float64 arrays. Same semantics as
    filter_ref, written out for speed on 10^6 samples.
    """
    zl = np.asarray(z, dtype=np.float64).tolist()
    n = len(zl)
    pos = [math.nan] * n
    vel = [math.nan] * n
    kb = beta / T
    phase = 0
    x = v = z1 = 0.0
    gap = 0
    for j, zj in enumerate(zl):
        valid = zj == zj
        if phase == 2:
            xp = x + T * v
            if valid:
                e = zj - xp
                x = xp + alpha * e
                v = v + kb * e
            else:
                x = xp
            pos[j] = x
            vel[j] = v
        elif phase == 1:
            gap += 1
            if valid:
                x = zj
                v = (zj - z1) / (gap * T)
                phase = 2
                pos[j] = x
                vel[j] = v
            else:
                pos[j] = z1
        elif valid:
            z1 = zj
            gap = 0
            phase = 1
            pos[j] = z1
    return np.array(pos), np.array(vel)
