"""smooth(t=...) of the 3-state kinematic filters (alpha-beta-gamma, fixed
gains and noise design, and the Singer filter): the RTS smoother with the
backward gain of each interval.

Reference (independent of abkit's solvers): the forward filter is the plain
loop of ``tracksref.run_track`` with the per-dt gains of the steady-state
Kalman filter of the model at that dt, and the backward pass a plain loop
with ``A(dt) = P_filt Phi(dt)^T P_pred^-1``; both from
``scipy.linalg.solve_discrete_are`` polished by the Riccati recursion.
Models: the alpha-beta-gamma design uses Chen & Chui's per-step noise
``Q = diag(sigma_p, sigma_v, sigma_a)``, ``R = sigma_m`` with
``Phi = [[1, dt, dt^2/2], [0, 1, dt], [0, 0, 1]]``; fixed gains the
Kalman-equivalent model of the gains (Chen & Chui's Corollary, written out
here) with the normalised noise held constant, i.e.
``Q(dt) = diag(q_p, q_v / dt^2, q_a / dt^4) sigma_m``; the Singer filter
Van Loan's ``(Phi, Q)`` of the continuous model (``singer_ref.van_loan``)
and ``R = sigma_pos^2``.

Tolerance: smoothed states agree with the reference to 1e-10 relative to
each component's scale over the track (``atol = 1e-10 * max |x_c|``,
``rtol = 1e-10``).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.linalg

from abkit import AlphaBetaGammaFilter, abg, singer
from singer_ref import van_loan
from tracksref import ca_phi, run_track

RTOL = 1e-10
NOISE = (0.01, 0.02, 0.05, 1.0)  # sigma_p, sigma_v, sigma_a, sigma_m (variances)
TAU, SIGMA_M, SIGMA_POS = 20.0, 1.0, 2.0
Q_SINGER = 2.0 * SIGMA_M**2 / TAU  # white-noise density of the Singer acceleration
H = np.array([[1.0, 0.0, 0.0]])


def kalman(phi, q, r):
    """(K filter form, A backward gain) of the steady-state Kalman filter."""
    m = scipy.linalg.solve_discrete_are(phi.T, H.T, q, np.array([[r]]))
    for _ in range(60):  # polish: the Riccati recursion from the DARE solution
        k = m[:, 0] / (m[0, 0] + r)
        p = m - np.outer(k, m[0, :])
        p = (p + p.T) / 2
        m = phi @ p @ phi.T + q
    k = m[:, 0] / (m[0, 0] + r)
    p = m - np.outer(k, m[0, :])
    return k, p @ phi.T @ np.linalg.inv(m)


class Model:
    """Per-dt (Phi, K) of the forward pass and (Phi, A) of the backward one."""

    def __init__(self, phi_q_r, fixed_k=None):
        self.phi_q_r = phi_q_r
        self.fixed_k = fixed_k
        self.cache = {}

    def _at(self, dt):
        if dt not in self.cache:
            phi, q, r = self.phi_q_r(dt)
            k, a = kalman(phi, q, r)
            if self.fixed_k is not None:
                k = self.fixed_k(dt)
            self.cache[dt] = (phi, k, a)
        return self.cache[dt]

    def law(self, dt):
        phi, k, _ = self._at(dt)
        return phi, k

    def back(self, dt):
        phi, _, a = self._at(dt)
        return phi, a


def abg_design_model(noise=NOISE):
    sp, sv, sa, sm = noise
    return Model(lambda dt: (ca_phi(dt), np.diag([sp, sv, sa]), sm))


def corollary_noise(a, b, g):
    """Chen & Chui's Corollary (iv)-(vi), h = 1 units, gamma in the paper's convention."""
    om = 1.0 - a
    return ((a * a + a * b + a * g / 2 - 2 * b) / om, (b * b - 2 * a * g) / om, g * g / om)


def abg_fixed_model(a, b, g_cc):
    qp, qv, qa = corollary_noise(a, b, g_cc)
    return Model(
        lambda dt: (ca_phi(dt), np.diag([qp, qv / dt**2, qa / dt**4]), 1.0),
        fixed_k=lambda dt: np.array([a, b / dt, g_cc / dt**2]),
    )


def singer_model():
    def pqr(dt):
        phi, q = van_loan(dt, TAU, Q_SINGER)
        return phi, q, SIGMA_POS**2

    return Model(pqr)


def ref_smooth(xf, t, back, max_gap=math.inf, lag=None):
    """Plain loop: skip NaN samples, restart at gaps > max_gap."""
    n = xf.shape[1]
    xs = xf.copy()
    kept = [k for k in range(n) if not np.isnan(xf[:, k]).any()]
    if lag is None:
        nxt = None
        for k in reversed(kept):
            if nxt is not None and t[nxt[1]] - t[k] <= max_gap:
                phi, a = back(t[nxt[1]] - t[k])
                xs[:, k] = xf[:, k] + a @ (nxt[0] - phi @ xf[:, k])
            nxt = (xs[:, k], k)
        return xs
    for k in kept:
        chain = [k]
        for j in range(k + 1, min(k + lag, n - 1) + 1):
            if np.isnan(xf[:, j]).any():
                continue
            if t[j] - t[chain[-1]] > max_gap:
                break
            chain.append(j)
        s = xf[:, chain[-1]]
        for i, j in reversed(list(zip(chain[:-1], chain[1:]))):
            phi, a = back(t[j] - t[i])
            s = xf[:, i] + a @ (s - phi @ xf[:, i])
        xs[:, k] = s
    return xs


def reference(z, t, model, max_gap=None, lag=None, drop=False, init="two-point"):
    xf, _, _, _ = run_track(z, t, model.law, 3, init=init, max_gap=max_gap, drop=drop)
    return xf, ref_smooth(xf, t, model.back, math.inf if max_gap is None else max_gap, lag)


def assert_states(got, ref, rtol=RTOL):
    assert got.shape == ref.shape
    np.testing.assert_array_equal(np.isnan(got), np.isnan(ref))
    for c in range(ref.shape[0]):
        scale = np.nanmax(np.abs(ref[c]))
        np.testing.assert_allclose(got[c], ref[c], rtol=rtol, atol=rtol * scale, equal_nan=True, err_msg=f"component {c}")


def data(seed, n=200, gaps=True, lo=-0.7, hi=0.3):
    """Random steps 10**U(lo, hi), a few 30 s gaps, 10% missed detections,
    a target with constant acceleration."""
    rng = np.random.default_rng(seed)
    dt = 10.0 ** rng.uniform(lo, hi, n)
    if gaps:
        dt[rng.random(n) < 0.02] = 30.0
    t = np.cumsum(dt)
    z = 3.0 + 1.5 * t - 0.01 * t * t + rng.normal(0, 1, n)
    z[rng.random(n) < 0.1] = np.nan
    return t, z


def abg_fixed_filter():
    """Near-optimal fixed gains (those of the design at h = 1), standard convention."""
    d = abg.from_noise(*NOISE, h=1.0, convention="standard")
    return AlphaBetaGammaFilter(d.alpha, d.beta, d.gamma, 1.0), (float(d.alpha), float(d.beta), float(d.gamma) / 2.0)


FILTERS = ("abg-design", "abg-fixed", "singer")


_MODELS: dict = {}


def make(kind):
    """(filter, reference model); the models (and their per-dt solutions)
    are shared by the tests."""
    f, model = _make(kind)
    return f, _MODELS.setdefault(kind, model)


def _make(kind):
    if kind == "abg-design":
        return AlphaBetaGammaFilter.from_noise(*NOISE, T=1.0), abg_design_model()
    if kind == "abg-fixed":
        f, (a, b, g_cc) = abg_fixed_filter()
        return f, abg_fixed_model(a, b, g_cc)
    return singer.tracking_filter(1.0, tau=TAU, sigma_m=SIGMA_M, sigma_pos=SIGMA_POS), singer_model()


@pytest.mark.parametrize("kind", FILTERS)
@pytest.mark.parametrize("lag", [None, 0, 3])
@pytest.mark.parametrize("max_gap", [None, 10.0])
def test_matches_reference(kind, lag, max_gap):
    t, z = data(1)
    f, model = make(kind)
    assert f.gain_schedule == ("fixed" if kind == "abg-fixed" else "design")
    xf, xs = reference(z, t, model, max_gap=max_gap, lag=lag)
    r = f.smooth(z, t=t, max_gap=max_gap, lag=lag)
    if max_gap is not None:
        assert r.n_restarts[0] > 0
    assert_states(f.run(z, t=t, max_gap=max_gap).states, xf)
    assert_states(r.states, xs)
    if lag == 0:
        assert_states(r.states, xf)


@pytest.mark.parametrize("kind", FILTERS)
def test_init_first_and_nan_runs(kind):
    t, z = data(2, gaps=False)
    z[20:35] = np.nan  # a long coast
    z[:3] = np.nan  # missed detections before the start
    f, model = make(kind)
    _, xs = reference(z, t, model, init="first")
    assert_states(f.smooth(z, t=t, init="first").states, xs)


@pytest.mark.parametrize("kind", FILTERS)
def test_regular_t_equals_smoother_without_t(kind):
    """t = k T (exact in binary): the per-dt smoother is the constant one."""
    rng = np.random.default_rng(3)
    T = 0.5
    t = np.arange(300) * T
    z = 1.0 + 0.5 * t + 0.02 * t * t + rng.normal(0, 1, t.size)
    z[rng.random(t.size) < 0.1] = np.nan
    if kind == "abg-design":
        f = AlphaBetaGammaFilter.from_noise(*NOISE, T=T)
        kw = dict(Q=np.diag(NOISE[:3]), R=[[NOISE[3]]])
    elif kind == "abg-fixed":
        d = abg.from_noise(*NOISE, h=T, convention="standard")
        f = AlphaBetaGammaFilter(d.alpha, d.beta, d.gamma, T)
        kw = {}  # the Kalman-equivalent model's gain (as alpha-beta)
    else:
        f = singer.tracking_filter(T, tau=TAU, sigma_m=SIGMA_M, sigma_pos=SIGMA_POS)
        s = singer.steady_state(T, tau=TAU, sigma_m=SIGMA_M, sigma_pos=SIGMA_POS)
        kw = dict(Q=s.Q, R=s.R)
    for lag in (None, 4):
        a = f.smooth(z, t=t, lag=lag).states
        b = f.smooth(z, lag=lag, **kw).states
        assert_states(a, b, rtol=1e-12)


@pytest.mark.parametrize("kind", FILTERS)
def test_ragged_axes_duplicates_float32(kind):
    f, _ = make(kind)
    t1, z1 = data(4, 120)
    t2, z2 = data(5, 37)
    # ragged: each track as alone (bit-identical)
    r = f.smooth(np.concatenate([z1, z2]), t=np.concatenate([t1, t2]), offsets=[0, 120, 120, 157], max_gap=10.0, lag=5)
    np.testing.assert_array_equal(r.states[:, :120], f.smooth(z1, t=t1, max_gap=10.0, lag=5).states)
    np.testing.assert_array_equal(r.states[:, 120:], f.smooth(z2, t=t2, max_gap=10.0, lag=5).states)
    # rectangular batch with a shared t equals each row alone
    zz = np.stack([z1, z1[::-1].copy()])
    rb = f.smooth(zz, t=t1)
    for i in range(2):
        np.testing.assert_array_equal(rb.states[:, i], f.smooth(zz[i], t=t1).states)
    # axes: each spatial axis as alone
    za = np.stack([z1, 2.0 * z1 + 1.0], axis=-1)
    ra = f.smooth(za, t=t1, axes=2)
    for a in range(2):
        np.testing.assert_array_equal(ra.states[..., a], f.smooth(za[:, a].copy(), t=t1).states)
    # dropped duplicates are skipped (NaN) and change nothing else
    t3 = np.insert(t1, [50, 90], [t1[49], t1[87]])
    z3 = np.insert(z1, [50, 90], [99.0, -99.0])
    r3 = f.smooth(z3, t=t3, on_duplicate="drop")
    keep = np.ones(t3.size, bool)
    keep[[50, 91]] = False
    np.testing.assert_array_equal(r3.states[:, keep], f.smooth(z1, t=t1).states)
    assert np.isnan(r3.states[:, ~keep]).all() and r3.n_dropped[0] == 2
    # float32 in, float32 out, close to float64 (the estimates are stored in
    # float32 between the passes)
    r32 = f.smooth(z1.astype(np.float32), t=t1)
    assert r32.states.dtype == np.float32
    r64 = f.smooth(z1.astype(np.float32).astype(np.float64), t=t1).states
    assert_states(r32.states.astype(np.float64), r64, rtol=1e-4)


def test_dropped_and_float32_match_reference():
    """The reference with drop=True, and float32 estimates smoothed from the
    float32 filtered ones."""
    t, z = data(6)
    t = np.insert(t, [40, 41], [t[39], t[39] - 0.1])
    z = np.insert(z, [40, 41], [5.0, 6.0])
    f, model = make("abg-design")
    _, xs = reference(z, t, model, drop=True, max_gap=10.0)
    assert_states(f.smooth(z, t=t, on_duplicate="drop", max_gap=10.0).states, xs)
    xf32 = f.run(z.astype(np.float32), t=t, on_duplicate="drop").states.astype(np.float64)
    ref32 = ref_smooth(xf32, t, model.back)
    got = f.smooth(z.astype(np.float32), t=t, on_duplicate="drop").states.astype(np.float64)
    assert_states(got, ref32.astype(np.float32).astype(np.float64), rtol=1e-6)


def test_per_track_fixed_gains():
    t1, z1 = data(7, 80)
    t2, z2 = data(8, 80)
    d = abg.from_noise(0.01, 0.02, np.array([0.05, 0.5]), 1.0, h=1.0, convention="standard")
    f = AlphaBetaGammaFilter(d.alpha, d.beta, d.gamma, 1.0)
    r = f.smooth(np.stack([z1, z2]), t=np.stack([t1, t2]))
    for i, (t, z) in enumerate(((t1, z1), (t2, z2))):
        a, b, g = float(d.alpha[i]), float(d.beta[i]), float(d.gamma[i]) / 2.0
        _, xs = reference(z, t, abg_fixed_model(a, b, g))
        assert_states(r.states[:, i], xs)


def test_default_smoother_gain_is_the_kalman_equivalent_one():
    f, (a, b, g) = abg_fixed_filter()
    _, want = kalman(*abg_fixed_model(a, b, g).phi_q_r(1.0))
    np.testing.assert_allclose(f.smoother_gain()[0], want, rtol=1e-9, atol=1e-12)


def test_errors():
    t = np.arange(6.0)
    z = np.arange(6.0) ** 2
    # fixed gains with no Kalman-equivalent model (not near-optimal)
    f = AlphaBetaGammaFilter(0.5, 0.4, 0.1, 1.0, convention="chen-chui")
    assert not abg.is_near_optimal(0.5, 0.4, 0.1)
    with pytest.raises(ValueError, match="no Kalman-equivalent model"):
        f.smooth(z, t=t)
    with pytest.raises(ValueError, match="no Kalman-equivalent model"):
        f.smooth(z)
    # a step at which the design has no solution: named by track and sample
    s = singer.tracking_filter(1.0, tau=TAU, sigma_m=SIGMA_M, sigma_pos=SIGMA_POS)
    tt = np.stack([t, t])
    tt[1, 4:] = tt[1, 3] + 1e-70 * np.arange(1, 3)
    with pytest.raises(ValueError, match=r"track 1, sample 4"):
        s.smooth(np.stack([z, z]), t=tt)
    g = AlphaBetaGammaFilter.from_noise(*NOISE, T=1.0)
    with pytest.raises(ValueError, match="Q, R and smoother_gain apply without t"):
        g.smooth(z, t=t, Q=np.eye(3), R=[[1.0]])


@pytest.mark.parametrize("kind", FILTERS)
def test_smoothing_beats_filtering_on_a_simulated_target(kind):
    """A manoeuvring target (Singer-like acceleration) sampled at random
    times: the smoothed positions have a clearly smaller rms error."""
    rng = np.random.default_rng(10)
    n_tracks, n = 40, 300
    if kind == "abg-fixed":
        # fixed gains keep their poles per sample, not per second: with
        # widely varying steps the time-varying loop can diverge; jitter only
        dt = 0.6 * rng.uniform(0.7, 1.3, (n_tracks, n))
    else:
        dt = rng.exponential(0.6, (n_tracks, n)) + 0.05
    t = np.cumsum(dt, axis=1)
    acc = np.zeros((n_tracks, n))
    vel = np.zeros((n_tracks, n))
    pos = np.zeros((n_tracks, n))
    for k in range(1, n):
        h = dt[:, k]
        rho = np.exp(-h / TAU)
        acc[:, k] = rho * acc[:, k - 1] + np.sqrt(SIGMA_M**2 * (1 - rho**2)) * rng.normal(size=n_tracks)
        vel[:, k] = vel[:, k - 1] + h * acc[:, k - 1]
        pos[:, k] = pos[:, k - 1] + h * vel[:, k - 1] + 0.5 * h * h * acc[:, k - 1]
    z = pos + rng.normal(0, SIGMA_POS, pos.shape)
    z[rng.random(z.shape) < 0.05] = np.nan
    if kind == "singer":
        f = singer.tracking_filter(0.6, tau=TAU, sigma_m=SIGMA_M, sigma_pos=SIGMA_POS)
    elif kind == "abg-design":
        f = AlphaBetaGammaFilter.from_noise(0.0, 0.0, 0.05, SIGMA_POS**2, T=0.6)
    else:
        d = abg.from_noise(0.0, 0.0, 0.05, SIGMA_POS**2, h=0.6, convention="standard")
        f = AlphaBetaGammaFilter(d.alpha, d.beta, d.gamma, 0.6)
    ef = (f.run(z, t=t).position - pos)[:, 50:-50]
    es = (f.smooth(z, t=t).position - pos)[:, 50:-50]
    rf, rs = np.sqrt(np.mean(ef**2)), np.sqrt(np.mean(es**2))
    assert rs < 0.8 * rf, (rs, rf)
