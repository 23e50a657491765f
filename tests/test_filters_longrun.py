"""Long-run stability: 10^6 samples of a constant-velocity target.

The position/velocity error of the filter over 10^6 samples must agree with
the theoretical steady-state filtered covariance ``f.covariances(Q=0, R)``:
the mean squared error within 5 standard errors (batch means over 100 blocks
of 10^4 samples), no drift (first vs second half within 5 standard errors),
and no single sample beyond 6.5 theoretical sigma. Fixed seeds.
"""

from __future__ import annotations

import numpy as np
import pytest

import filterref as fr
from abkit import AlphaBetaFilter, AlphaBetaGammaFilter

N = 1_000_000
T = 0.01
P0, V = 1000.0, 25.0  # the target ends near 2.5e5
SIGMA = 5.0


def _target(rng, dtype):
    t = np.arange(N) * T
    pos = P0 + V * t
    z = (pos + rng.normal(0, SIGMA, N)).astype(dtype)
    return pos, z


def _check_component(err, var_theory, name):
    e2 = err**2
    blocks = e2.reshape(100, -1).mean(axis=1)
    se = blocks.std(ddof=1) / np.sqrt(blocks.size)
    mean = blocks.mean()
    assert abs(mean - var_theory) < 5 * se, f"{name}: mean sq error {mean:.6g} vs theory {var_theory:.6g} (se {se:.3g})"
    h1, h2 = blocks[:50].mean(), blocks[50:].mean()
    assert abs(h1 - h2) < 5 * 2 * se, f"{name}: drift {h1:.6g} -> {h2:.6g}"  # se of the half difference: 2 se
    assert np.max(np.abs(err)) < 6.5 * np.sqrt(var_theory), f"{name}: max |err| {np.max(np.abs(err)):.4g} sigma {np.sqrt(var_theory):.4g}"
    assert abs(np.mean(err)) < 5 * np.sqrt(var_theory) / np.sqrt(N / 1000), f"{name}: bias {np.mean(err):.3g}"


CASES = [
    ("ab", (0.3, 0.05), np.float64),
    ("ab", (0.8, 0.5), np.float64),
    ("ab", (0.05, 0.0013), np.float64),
    ("ab", (0.3, 0.05), np.float32),
    ("abg", (0.5, 0.2, 0.02), np.float64),
    ("abg", (0.5, 0.2, 0.02), np.float32),
]


@pytest.mark.parametrize("kind,gains,dtype", CASES, ids=lambda v: str(v))
def test_constant_velocity_million_samples(kind, gains, dtype):
    rng = np.random.default_rng(fr.seed_of("longrun", kind, gains, np.dtype(dtype).name))
    pos, z = _target(rng, dtype)
    f = AlphaBetaFilter(*gains, T) if kind == "ab" else AlphaBetaGammaFilter(*gains, T)
    n = f.n
    cov = f.covariances(np.zeros((n, n)), [[SIGMA**2]]).filtered
    r = f.run(z)
    assert r.states.dtype == dtype
    cut = 5000  # start-up transient (two-point start)
    ep = r.position[cut:].astype(np.float64) - pos[cut:]
    ev = r.velocity[cut:].astype(np.float64) - V
    assert np.all(np.isfinite(r.states[:, 1:]))
    m = (N - cut) // 100 * 100
    _check_component(ep[-m:], cov[0, 0], "position")
    _check_component(ev[-m:], cov[1, 1], "velocity")
    if kind == "abg":
        ea = r.acceleration[cut:].astype(np.float64)
        _check_component(ea[-m:], cov[2, 2], "acceleration")


def test_million_samples_with_missed_detections_stay_bounded():
    """10 % missed detections: no NaN after the start, error stays within a
    small multiple of the no-miss theory (coasting a constant-velocity target
    adds no model error)."""
    rng = np.random.default_rng(77)
    pos, z = _target(rng, np.float64)
    z[rng.random(N) < 0.1] = np.nan
    z[:3] = np.nan
    f = AlphaBetaFilter(0.3, 0.05, T)
    cov = f.covariances(np.zeros((2, 2)), [[SIGMA**2]]).filtered
    r = f.run(z, return_residuals=True)
    first = 20  # past the two-point start (whose residuals are NaN too)
    assert np.all(np.isfinite(r.states[:, 20:]))
    ep = r.position[5000:] - pos[5000:]
    rms = np.sqrt(np.mean(ep**2))
    assert rms < 1.5 * np.sqrt(cov[0, 0])
    assert np.max(np.abs(ep)) < 10 * np.sqrt(cov[0, 0])
    assert np.array_equal(np.isnan(r.residuals[first:]), np.isnan(z[first:]))


def test_million_samples_chunked_and_threads_bit_identical():
    """A single 10^6-sample track: thread counts change nothing (bit for bit);
    random chunking changes the segmentation of the single-long-track split
    (docs/filtering.md), so chunks agree within 1e-12 of the state's scale."""
    rng = np.random.default_rng(78)
    pos, z = _target(rng, np.float64)
    z[rng.random(N) < 0.05] = np.nan
    f = AlphaBetaFilter(0.3, 0.05, T)
    one = f.run(z, threads=1)
    for th in (None, 2, 3):
        assert np.array_equal(f.run(z, threads=th).states, one.states, equal_nan=True)
    cuts = np.sort(rng.integers(1, N, 6))
    st, parts = None, []
    for lo, hi in zip(np.r_[0, cuts], np.r_[cuts, N]):
        rr = f.run(z[lo:hi], state=st)
        st = rr.state
        parts.append(rr.states)
    got = np.concatenate(parts, axis=1)
    assert np.array_equal(np.isnan(got), np.isnan(one.states))
    pscale0 = np.nanmax(np.abs(one.states[0]))
    assert np.nanmax(np.abs(got[0] - one.states[0])) <= 1e-12 * pscale0
    assert np.nanmax(np.abs(got[1] - one.states[1])) <= 1e-12 * pscale0 / T
    # the last samples agree with the reference continued from the engine's own
    # state 1000 samples before the end. Positions are ~2.5e5 and velocities
    # ~25: a last-bit difference in position (e.g. a fused multiply-add) enters
    # the velocity through beta/T = 5 per sample, so the velocity is compared
    # at 1e-12 of the position scale divided by T (the state's scale in
    # velocity units), the position at 1e-12 of its own scale.
    x0 = one.states[:, N - 1001]
    s, _, _ = fr.run_ref(z[N - 1000 :], fr.ab_model(0.3, 0.05, T), x0)
    got = one.states[:, N - 1000 :]
    fr.assert_states_close(got[:1], s[:1], 1e-12)
    pscale = np.nanmax(np.abs(s[0]))
    assert np.array_equal(np.isnan(got), np.isnan(s))
    assert np.nanmax(np.abs(got[1] - s[1])) <= 1e-12 * pscale / T
