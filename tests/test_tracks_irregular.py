"""Irregular timestamps: per-dt gain schedules, gaps, duplicates, streaming.

Checked against the plain-Python reference loop of ``tracksref.py`` with the
per-step (Phi, K) taken from the closed-form designs of abkit.alphabeta /
abkit.abg / abkit.singer at that dt.
"""

from __future__ import annotations

import numpy as np
import pytest

import abkit
from abkit import AlphaBetaFilter, AlphaBetaGammaFilter, FixedGainFilter, alphabeta, abg, singer
from tracksref import TrackError, ca_phi, cv_phi, run_track

SW, SV = 3.2, 32.0


def ab_design_law(sw=SW, sv=SV):
    def law(dt):
        d = alphabeta.from_noise(sw, sv, dt)
        return cv_phi(dt), np.array([d.alpha, d.beta / dt])

    return law


def ab_fixed_law(a, b):
    return lambda dt: (cv_phi(dt), np.array([a, b / dt]))


def assert_close(actual, desired, rtol=1e-10):
    """Per component: |a - d| <= rtol (|d| + 1e-2 max|d|). The kernel's
    update is arranged for a short dependency chain ((1 - alpha) x_p +
    alpha z, fused multiply-adds), so it rounds differently from the
    reference; a large position enters the velocity's rounding."""
    actual, desired = np.asarray(actual, float), np.asarray(desired, float)
    assert actual.shape == desired.shape
    np.testing.assert_array_equal(np.isnan(actual), np.isnan(desired))
    for a, d in zip(actual.reshape(actual.shape[0], -1), desired.reshape(desired.shape[0], -1)):
        ok = ~np.isnan(d)
        scale = np.max(np.abs(d[ok])) if ok.any() else 0.0
        np.testing.assert_array_less(np.abs(a[ok] - d[ok]), rtol * (np.abs(d[ok]) + 1e-2 * scale) + 1e-300)


def random_times(rng, n, lo=-4, hi=3):
    dt = 10.0 ** rng.uniform(lo, hi, n)
    return np.cumsum(dt) - dt[0] + rng.uniform(-100, 100)


def noisy(rng, t, frac=0.15):
    z = 5.0 + 2.0 * t + 0.01 * t**2 + rng.normal(0, 1.0, t.size)
    z[rng.random(t.size) < frac] = np.nan
    return z


@pytest.mark.parametrize("init", ["two-point", "first"])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_ab_design_matches_reference_at_random_dt(init, seed):
    rng = np.random.default_rng(seed)
    t = random_times(rng, 300)
    z = noisy(rng, t)
    f = AlphaBetaFilter.from_noise(SW, SV, 0.1)
    assert f.gain_schedule == "design"
    r = f.run(z, t=t, init=init, return_residuals=True)
    ref, res, _, _ = run_track(z, t, ab_design_law(), 2, init=init)
    assert_close(r.states, ref)
    assert_close(r.residuals[None], res[None], rtol=1e-8)
    assert r.t is not None and np.array_equal(r.t, t)


def test_ab_fixed_gains_scale_rate_gain_with_dt():
    rng = np.random.default_rng(5)
    t = random_times(rng, 200, -2, 1)
    z = noisy(rng, t)
    f = AlphaBetaFilter(0.5, 0.3, 1.0)
    assert f.gain_schedule == "fixed"
    r = f.run(z, t=t)
    ref, _, _, _ = run_track(z, t, ab_fixed_law(0.5, 0.3), 2)
    assert_close(r.states, ref)


def test_from_design_of_kalman_design_uses_design_schedule():
    d = alphabeta.from_snr(0.04)
    f = AlphaBetaFilter.from_design(d, T=0.5)
    assert f.gain_schedule == "design"
    # lambda = 2 sqrt(r) = ratio T^2  ->  ratio = sigma_w / sigma_v
    ratio = 2 * np.sqrt(0.04) / 0.25
    rng = np.random.default_rng(3)
    t = random_times(rng, 100, -2, 1)
    z = noisy(rng, t)
    r = f.run(z, t=t)
    ref, _, _, _ = run_track(z, t, ab_design_law(ratio, 1.0), 2)
    assert_close(r.states, ref)
    assert AlphaBetaFilter.from_design(alphabeta.analyze(0.5, 0.1), T=1.0).gain_schedule == "fixed"


def _one_step_gains(f, dts):
    """Gains at each dt from one step: init='first' at (t=0, z=0), then z=1
    at t=dt: x = K[0], v = K[1] (, a = K[2])."""
    n = dts.size
    z = np.tile([0.0, 1.0], (n, 1))
    t = np.stack([np.zeros(n), dts], axis=1)
    return f.run(z, t=t, init="first").states[:, :, 1]


def test_per_dt_alphabeta_gains_equal_closed_form_design():
    rng = np.random.default_rng(7)
    dts = np.concatenate([10.0 ** rng.uniform(-5, 4, 200), [1e-3, 1.0, 1e3]])
    k = _one_step_gains(AlphaBetaFilter.from_noise(SW, SV, 1.0), dts)
    d = alphabeta.from_noise(SW, SV, dts)
    np.testing.assert_allclose(k[0], d.alpha, rtol=1e-14)
    np.testing.assert_allclose(k[1], d.beta / dts, rtol=1e-14)


def test_per_dt_alphabeta_gains_against_50_digit_design():
    """The kernels' per-dt gains (one square root, one division, the rate
    gain formed without dividing by dt) against the exact design in 50-digit
    arithmetic, tracking index 1e-300 .. 1e300 and beyond (limit (1, 2/dt)):
    within 1e-15 relative (a few ulp)."""
    mpmath = pytest.importorskip("mpmath")
    mpmath.mp.dps = 50
    ratio = 0.1
    dts = np.concatenate([10.0 ** np.linspace(-150, 150, 301), 10.0 ** np.random.default_rng(3).uniform(-8, 8, 200)])
    k = _one_step_gains(AlphaBetaFilter.from_noise(ratio, 1.0, 1.0), dts)
    for dt, a, g in zip(dts, k[0], k[1]):
        lam = mpmath.mpf(ratio) * mpmath.mpf(dt) ** 2
        s = mpmath.sqrt(lam * (lam + 8))
        u, v = 4 / (lam + 4 + s), (lam + s) / (lam + 4 + s)  # v = 1 - u without cancellation
        ea, eg = v * (1 + u), 2 * v * v / mpmath.mpf(dt)  # alpha = 1 - u^2
        assert abs(a - ea) <= 1e-15 * ea, (dt, a, ea)
        assert abs(g - eg) <= 1e-15 * eg, (dt, g, eg)


def test_per_dt_abg_gains_equal_closed_form_design():
    rng = np.random.default_rng(8)
    dts = 10.0 ** rng.uniform(-2, 2, 40)
    for noise in [(0.0, 0.0, 0.1, 1.0), (0.3, 0.2, 0.1, 1.0)]:
        f = AlphaBetaGammaFilter.from_noise(*noise, T=1.0)
        assert f.gain_schedule == "design"
        k = _one_step_gains(f, dts)
        d = abg.from_noise(*noise, h=dts, convention="chen-chui")
        np.testing.assert_allclose(k[0], d.alpha, rtol=1e-13)
        np.testing.assert_allclose(k[1], d.beta / dts, rtol=1e-13)
        np.testing.assert_allclose(k[2], d.gamma / dts**2, rtol=1e-12)


def test_per_dt_singer_gains_equal_steady_state_design():
    rng = np.random.default_rng(9)
    dts = 10.0 ** rng.uniform(-1, 1.3, 25)
    f = singer.tracking_filter(1.0, tau=20.0, sigma_m=1.0, sigma_pos=10.0)
    assert f.gain_schedule == "design"
    k = _one_step_gains(f, dts)
    s = singer.steady_state(dts, tau=20.0, sigma_m=1.0, sigma_pos=10.0)
    np.testing.assert_allclose(k.T, s.K[:, :, 0], rtol=1e-9)


def test_abg_fixed_and_design_match_reference():
    rng = np.random.default_rng(11)
    t = random_times(rng, 150, -1, 0.5)
    z = noisy(rng, t)
    f = AlphaBetaGammaFilter(0.5, 0.3, 0.05, 1.0)  # standard: gamma / (2 dt^2)
    r = f.run(z, t=t)
    ref, _, _, _ = run_track(z, t, lambda dt: (ca_phi(dt), np.array([0.5, 0.3 / dt, 0.025 / dt**2])), 3)
    np.testing.assert_allclose(r.states, ref, rtol=1e-11, atol=1e-9, equal_nan=True)
    f = AlphaBetaGammaFilter.from_noise(0.3, 0.2, 0.1, 1.0, T=1.0)

    def law(dt):
        d = abg.from_noise(0.3, 0.2, 0.1, 1.0, h=dt, convention="chen-chui")
        return ca_phi(dt), np.array([d.alpha, d.beta / dt, d.gamma / dt**2])

    r = f.run(z, t=t)
    ref, _, _, _ = run_track(z, t, law, 3)
    np.testing.assert_allclose(r.states, ref, rtol=1e-10, atol=1e-9, equal_nan=True)


def test_singer_matches_reference():
    rng = np.random.default_rng(12)
    t = random_times(rng, 80, -1, 1)
    z = noisy(rng, t)
    f = singer.tracking_filter(1.0, tau=20.0, sigma_m=1.0, sigma_pos=10.0)

    def law(dt):
        s = singer.steady_state(dt, tau=20.0, sigma_m=1.0, sigma_pos=10.0)
        return s.Phi, s.K[:, 0]

    r = f.run(z, t=t)
    ref, _, _, _ = run_track(z, t, law, 3)
    np.testing.assert_allclose(r.states, ref, rtol=1e-8, atol=1e-8, equal_nan=True)


def test_general_fixed_gain_filter_with_t_is_a_clear_error():
    f = FixedGainFilter([[1.0, 1.0], [0.0, 1.0]], [[1.0, 0.0]], [[0.5], [0.2]])
    with pytest.raises(ValueError, match="Phi\\(dt\\)"):
        f.run(np.arange(4.0), t=np.arange(4.0))
    # without t, offsets work for any filter
    r = f.run(np.arange(4.0), offsets=[0, 2, 4], init="first")
    assert r.states.shape == (2, 4)


def test_duplicates_raise_naming_track_and_sample():
    f = AlphaBetaFilter(0.5, 0.2, 1.0)
    z = np.ones((3, 5))
    t = np.tile(np.arange(5.0), (3, 1))
    t[2, 3] = t[2, 2]
    with pytest.raises(ValueError, match=r"track 2, sample 3: t=2(\.0)? not after t=2"):
        f.run(z, t=t)
    t[2, 3] = 1.0
    with pytest.raises(ValueError, match=r"track 2, sample 3"):
        f.run(z, t=t)


@pytest.mark.parametrize("seed", [0, 1])
def test_duplicates_dropped_match_reference(seed):
    rng = np.random.default_rng(seed)
    t = np.round(np.cumsum(rng.uniform(0, 1, 200)), 1)  # many repeats
    t[rng.random(200) < 0.05] -= 3.0  # out-of-order reports
    z = noisy(rng, t)
    f = AlphaBetaFilter.from_noise(SW, SV, 0.1)
    r = f.run(z, t=t, on_duplicate="drop", return_residuals=True)
    ref, res, nd, _ = run_track(z, t, ab_design_law(), 2, drop=True)
    assert nd > 0 and int(r.n_dropped[0]) == nd
    assert_close(r.states, ref)
    assert_close(r.residuals[None], res[None], rtol=1e-8)


@pytest.mark.parametrize("init", ["two-point", "first"])
def test_max_gap_restarts_match_reference(init):
    rng = np.random.default_rng(4)
    dt = rng.uniform(0.1, 1.0, 300)
    dt[rng.random(300) < 0.03] = 50.0
    t = np.cumsum(dt)
    z = noisy(rng, t)
    f = AlphaBetaFilter.from_noise(SW, SV, 0.5)
    r = f.run(z, t=t, max_gap=10.0, init=init)
    ref, _, _, nr = run_track(z, t, ab_design_law(), 2, max_gap=10.0, init=init)
    assert nr > 0 and int(r.n_restarts[0]) == nr
    assert_close(r.states, ref)


def test_nan_and_bad_timestamps():
    f = AlphaBetaFilter(0.5, 0.2, 1.0)
    z = np.ones((2, 4))
    t = np.tile(np.arange(4.0), (2, 1))
    t[1, 2] = np.nan
    with pytest.raises(ValueError, match="track 1, sample 2: t=NaN is not finite"):
        f.run(z, t=t)
    with pytest.raises(ValueError, match="t must have the sample shape"):
        f.run(z, t=np.arange(3.0))
    with pytest.raises(TypeError, match="t must be"):
        f.run(z, t=np.ones((2, 4), dtype=complex))
    with pytest.raises(ValueError, match="max_gap needs timestamps t"):
        f.run(z, max_gap=1.0)
    for bad in (0.0, -1.0, np.nan):
        with pytest.raises(ValueError, match="max_gap must be > 0"):
            f.run(z, t=np.arange(4.0), max_gap=bad)
    with pytest.raises(ValueError, match="on_duplicate must be"):
        f.run(z, t=np.arange(4.0), on_duplicate="keep")


def test_shared_time_vector_broadcasts_to_tracks():
    f = AlphaBetaFilter.from_noise(SW, SV, 0.1)
    rng = np.random.default_rng(1)
    t = random_times(rng, 50, -2, 0)
    z = np.stack([noisy(rng, t) for _ in range(3)])
    r = f.run(z, t=t)
    for i in range(3):
        np.testing.assert_array_equal(r.states[:, i], f.run(z[i], t=t).states)


def test_float32_inputs():
    rng = np.random.default_rng(2)
    t = random_times(rng, 100, -2, 1)
    z = noisy(rng, t).astype(np.float32)
    f = AlphaBetaFilter.from_noise(SW, SV, 0.1)
    r = f.run(z, t=t.astype(np.float32))
    assert r.states.dtype == np.float32
    ref, _, _, _ = run_track(z.astype(np.float64), t.astype(np.float32).astype(np.float64), ab_design_law(), 2)
    np.testing.assert_allclose(r.states, ref, rtol=2e-6, atol=1e-5, equal_nan=True)


@pytest.mark.parametrize("opts", [dict(), dict(max_gap=5.0), dict(on_duplicate="drop")])
def test_streaming_with_t_equals_one_call(opts):
    rng = np.random.default_rng(6)
    t = np.round(np.cumsum(rng.exponential(1.0, (4, 120)), axis=1), 0)
    z = np.stack([noisy(rng, ti) for ti in t])
    f = AlphaBetaFilter.from_noise(SW, SV, 1.0)
    drop = opts.get("on_duplicate") == "drop"
    if not drop:
        t = np.cumsum(rng.exponential(1.0, (4, 120)), axis=1)
    full = f.run(z, t=t, **opts)
    st = None
    parts = []
    for a, b in [(0, 1), (1, 37), (37, 38), (38, 120)]:
        r = f.run(z[:, a:b], t=t[:, a:b], state=st, **opts)
        st = r.state
        parts.append(r.states)
    np.testing.assert_array_equal(np.concatenate(parts, axis=-1), full.states)
    np.testing.assert_array_equal(st.t_last, full.state.t_last)
    assert np.array_equal(st.t_last, t[:, -1]) or drop


def test_nothing_modified_in_place():
    rng = np.random.default_rng(0)
    t = random_times(rng, 60, -1, 1)
    t[10] = t[9]
    z = noisy(rng, t)
    z0, t0 = z.copy(), t.copy()
    off = np.array([0, 20, 60])
    f = AlphaBetaFilter.from_noise(SW, SV, 0.1)
    r1 = f.run(z, t=t, offsets=off, on_duplicate="drop")
    s0 = r1.state._packed.copy()
    f.run(z, t=t + 1e4, offsets=off, state=r1.state, on_duplicate="drop")
    assert np.array_equal(z, z0, equal_nan=True) and np.array_equal(t, t0) and np.array_equal(off, [0, 20, 60])
    assert np.array_equal(r1.state._packed, s0, equal_nan=True)


def test_explicit_init_state_is_one_period_before_first_sample():
    f = AlphaBetaFilter(0.5, 0.2, 2.0)
    z = np.array([1.0, 3.0, 4.0])
    t = np.array([10.0, 11.0, 13.0])
    r = f.run(z, t=t, init=[0.0, 0.5])
    ref = []
    x = np.array([0.0, 0.5])
    for zk, dt in zip(z, [2.0, 1.0, 2.0]):
        xp = cv_phi(dt) @ x
        x = xp + np.array([0.5, 0.2 / dt]) * (zk - xp[0])
        ref.append(x)
    np.testing.assert_allclose(r.states, np.array(ref).T, rtol=1e-15)


def test_constant_velocity_target_with_irregular_t_stays_within_theory():
    # Noise-free constant velocity: exact after the two-point start for any
    # dt (Phi(dt) is the true transition). With noise: unbiased, and the
    # position error rms below the measurement noise (VRR = alpha-ish < 1).
    rng = np.random.default_rng(13)
    n_tracks, n = 200, 400
    t = np.cumsum(rng.exponential(0.5, (n_tracks, n)), axis=1)
    truth = 7.0 - 3.0 * t
    f = AlphaBetaFilter.from_noise(0.01, 1.0, 0.5)
    r = f.run(truth, t=t)
    np.testing.assert_allclose(r.position[:, 1:], truth[:, 1:], rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(r.velocity[:, 1:], -3.0, rtol=1e-7)
    z = truth + rng.normal(0, 1.0, truth.shape)
    r = f.run(z, t=t)
    err = (r.position - truth)[:, n // 2 :]
    assert abs(err.mean()) < 5 * 1.0 / np.sqrt(err.size) * 3
    assert np.sqrt((err**2).mean()) < 0.5
    # the same data with the fixed-T filter ignoring the timestamps is biased
    bad = f.run(z)
    assert np.sqrt(((bad.position - truth)[:, n // 2 :] ** 2).mean()) > 1.0


def test_transient_kalman_rejects_track_keywords():
    f = AlphaBetaFilter.from_design(alphabeta.from_snr(0.1), T=1.0, transient="kalman")
    with pytest.raises(ValueError, match="transient='kalman' does not support"):
        f.run(np.arange(5.0), t=np.arange(5.0))


@pytest.mark.parametrize("max_gap", [None, 5.0])
@pytest.mark.parametrize("ragged", [False, True])
@pytest.mark.parametrize("law", ["design", "fixed"])
def test_inf_measurement_with_timestamps_is_named(max_gap, ragged, law):
    # An Inf in z is an error naming its track and sample, with timestamps
    # too: found from the final states after the run without max_gap, by a
    # scan before the run with it (a restart after the Inf would forget it:
    # track 2 has a 100 s gap after the Inf).
    rng = np.random.default_rng(3)
    z = rng.normal(size=(4, 50)).cumsum(1)
    t = np.cumsum(rng.uniform(0.5, 1.5, (4, 50)), axis=1)
    t[2, 20:] += 100.0
    z[2, 17] = -np.inf
    design = AlphaBetaFilter.from_noise(1.0, 2.0, 1.0)
    f = design if law == "design" else AlphaBetaFilter(design.alpha, design.beta, 1.0)
    kw = dict(t=t.reshape(-1), offsets=np.arange(5) * 50) if ragged else dict(t=t)
    zz = z.reshape(-1) if ragged else z
    with pytest.raises(ValueError, match=r"track 2, sample 17: z must be finite or NaN \(a missed detection\), got -inf"):
        f.run(zz, max_gap=max_gap, **kw)
    z[2, 17] = 1.0
    r = f.run(zz, max_gap=max_gap, **kw)
    assert np.all(np.isfinite(r.position))
