"""smooth(t=...): the RTS smoother with the per-dt backward gain."""

from __future__ import annotations

import math

import numpy as np
import pytest

from abkit import AlphaBetaFilter, AlphaBetaGammaFilter, alphabeta
from tracksref import cv_phi

SW, SV = 3.2, 32.0


def backward_gain(dt, alpha=None, beta=None):
    """A = P Phi^T M^-1 from the design's covariances (paper 000 units)."""
    d = alphabeta.from_noise(SW, SV, dt) if alpha is None else alphabeta.analyze(alpha, beta)
    nn = np.diag([1.0, 1.0 / dt])
    p = nn @ d.covariance_filtered @ nn
    m = nn @ d.covariance_predicted @ nn
    return p @ cv_phi(dt).T @ np.linalg.inv(m)


def ref_smooth(xf, t, gain, max_gap=math.inf, lag=None):
    """Plain loop: skip NaN samples, restart at gaps > max_gap."""
    n = xf.shape[1]
    xs = xf.copy()
    kept = [k for k in range(n) if not np.isnan(xf[:, k]).any()]
    if lag is None:
        nxt = None
        for k in reversed(kept):
            if nxt is not None and t[nxt[1]] - t[k] <= max_gap:
                dt = t[nxt[1]] - t[k]
                xs[:, k] = xf[:, k] + gain(dt) @ (nxt[0] - cv_phi(dt) @ xf[:, k])
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
            dt = t[j] - t[i]
            s = xf[:, i] + gain(dt) @ (s - cv_phi(dt) @ xf[:, i])
        xs[:, k] = s
    return xs


def data(seed, n=300):
    rng = np.random.default_rng(seed)
    dt = 10.0 ** rng.uniform(-2, 0.5, n)
    dt[rng.random(n) < 0.02] = 30.0
    t = np.cumsum(dt)
    z = 3.0 + 1.5 * t + rng.normal(0, 1, n)
    z[rng.random(n) < 0.1] = np.nan
    return t, z


@pytest.mark.parametrize("lag", [None, 0, 1, 5])
@pytest.mark.parametrize("max_gap", [None, 10.0])
def test_design_smoother_matches_reference(lag, max_gap):
    t, z = data(0)
    f = AlphaBetaFilter.from_noise(SW, SV, 0.3)
    xf = f.run(z, t=t, max_gap=max_gap).states
    r = f.smooth(z, t=t, lag=lag, max_gap=max_gap)
    ref = ref_smooth(xf, t, backward_gain, math.inf if max_gap is None else max_gap, lag)
    np.testing.assert_allclose(r.states, ref, rtol=1e-9, atol=1e-9, equal_nan=True)


def test_fixed_gain_smoother_matches_reference():
    t, z = data(1)
    f = AlphaBetaFilter(0.4, 0.1, 0.5)
    an = backward_gain(1.0, 0.4, 0.1)  # normalised: dt = 1

    def gain(dt):
        d = np.diag([1.0, 1.0 / dt])
        return d @ an @ np.linalg.inv(d)

    xf = f.run(z, t=t).states
    ref = ref_smooth(xf, t, gain)
    np.testing.assert_allclose(f.smooth(z, t=t).states, ref, rtol=1e-9, atol=1e-9, equal_nan=True)


def test_regular_t_equals_plain_smoother():
    rng = np.random.default_rng(2)
    T = 0.25
    t = np.arange(400) * T
    z = 1.0 + 0.5 * t + rng.normal(0, 1, t.size)
    f = AlphaBetaFilter.from_noise(SW, SV, T)
    for lag in (None, 4):
        np.testing.assert_allclose(f.smooth(z, t=t, lag=lag).states, f.smooth(z, lag=lag).states, rtol=1e-9, atol=1e-9, equal_nan=True)


def test_dropped_samples_are_skipped_by_the_smoother():
    t, z = data(3)
    t2 = np.insert(t, [50, 120], [t[49], t[118]])
    z2 = np.insert(z, [50, 120], [99.0, -99.0])
    f = AlphaBetaFilter.from_noise(SW, SV, 0.3)
    a = f.smooth(z, t=t).states
    b = f.smooth(z2, t=t2, on_duplicate="drop")
    keep = np.ones(t2.size, bool)
    keep[[50, 121]] = False
    np.testing.assert_array_equal(b.states[:, keep], a)
    assert np.isnan(b.states[:, ~keep]).all() and b.n_dropped[0] == 2


def test_ragged_smooth_equals_each_track_alone():
    t1, z1 = data(4, 100)
    t2, z2 = data(5, 37)
    f = AlphaBetaFilter.from_noise(SW, SV, 0.3)
    r = f.smooth(np.concatenate([z1, z2]), t=np.concatenate([t1, t2]), offsets=[0, 100, 137], lag=3)
    np.testing.assert_array_equal(r.states[:, :100], f.smooth(z1, t=t1, lag=3).states)
    np.testing.assert_array_equal(r.states[:, 100:], f.smooth(z2, t=t2, lag=3).states)


def test_smoothing_beats_filtering_on_irregular_cv_target():
    rng = np.random.default_rng(6)
    t = np.cumsum(rng.exponential(0.5, (100, 300)), axis=1)
    truth = 2.0 - 1.0 * t
    z = truth + rng.normal(0, 1, t.shape)
    f = AlphaBetaFilter.from_noise(0.05, 1.0, 0.5)
    ef = (f.run(z, t=t).position - truth)[:, 50:-50]
    es = (f.smooth(z, t=t).position - truth)[:, 50:-50]
    assert np.sqrt((es**2).mean()) < 0.8 * np.sqrt((ef**2).mean())


def test_smooth_offsets_without_t_for_any_filter():
    rng = np.random.default_rng(7)
    z = np.cumsum(rng.normal(0, 1, (3, 80)), axis=1)
    f = AlphaBetaGammaFilter(0.5, 0.2, 0.02, 1.0)
    Q = np.diag([0.0, 0.0, 0.01])
    rect = f.smooth(z, Q=Q, R=[[1.0]], lag=None)
    flat = f.smooth(z.reshape(-1), offsets=[0, 80, 160, 240], Q=Q, R=[[1.0]])
    np.testing.assert_allclose(flat.states.reshape(rect.states.shape), rect.states, rtol=1e-12, atol=1e-12, equal_nan=True)
    ab = AlphaBetaFilter(0.5, 0.2, 1.0)
    np.testing.assert_allclose(
        ab.smooth(z.reshape(-1), offsets=[0, 80, 160, 240], lag=2).states.reshape(2, 3, 80),
        ab.smooth(z, lag=2).states, rtol=1e-12, atol=1e-12, equal_nan=True,
    )


def test_smooth_with_t_errors():
    f = AlphaBetaFilter.from_noise(SW, SV, 0.3)
    with pytest.raises(ValueError, match="Q, R and smoother_gain apply without t"):
        f.smooth(np.ones(5), t=np.arange(5.0), Q=np.eye(2), R=[[1.0]])
    # smooth(t=...) of the 3-state filters: tests/test_smooth_t.py. A
    # general filter cannot build Phi(dt), as for run(t=...).
    from abkit import FixedGainFilter

    gen = FixedGainFilter([[1.0, 1.0], [0.0, 1.0]], [[1.0, 0.0]], [[0.5], [0.2]])
    with pytest.raises(ValueError, match="t= needs a filter that knows its continuous model"):
        gen.smooth(np.ones(5), t=np.arange(5.0), init="first")
