"""Compliance of abkit's batched filters with an independent NumPy reference.

Every expected value comes from tests/filterref.py, a plain per-sample NumPy
implementation of the documented semantics (issue 3, abkit.filters
docstrings) that never calls abkit.

Tolerances
----------
float64: every state component (and the residuals) within ``1e-12 x`` the
reference component's max |value| over the array; NaN patterns identical.

float32 (z given as float32; the reference is computed in float64 from the
same float32 values): docs/filtering.md says "Arithmetic is float64
throughout; float32 outputs are the float64 results rounded once", so every
output element must be the float64 reference correctly rounded to float32, up
to the float64 reference's own error: ``|got - ref| <= 0.5 ulp_f32(ref) +
1e-12 scale``. (Observed for ``run``: the states equal ``np.float32(ref)`` for
every element checked; residuals, which can cancel, differ from
``np.float32(ref)`` in ~1e-4 of elements by one ulp at a rounding tie. For
``smooth`` see test_filters_smoother.py::test_smoother_float32.)

abkit may use fused multiply-adds (docs/filtering.md), the reference does
not: the two agree to a few float64 ulps of the array's scale per step.
"""

from __future__ import annotations

import numpy as np
import pytest

import abkit
import filterref as fr
from abkit import AlphaBetaFilter, AlphaBetaGammaFilter, FixedGainFilter

RTOL = 1e-12
PATTERNS = ["none", "random", "leading", "trailing", "all-nan-tracks", "runs", "start-gaps", "one-valid", "mixed"]
INITS = ["two-point", "first", "array"]


def _init(init, rng, n, ntr=None):
    if init != "array":
        return init
    shape = (n,) if ntr is None else (ntr, n)
    return rng.normal(0, 3, shape)


def check_run(f, model, z, init, rtol=RTOL, m=1):
    r = f.run(z, init=init, return_residuals=True)
    s, res, st = fr.run_ref(z, model, init)
    assert r.states.dtype == z.dtype
    fr.assert_states_close(r.states, s, rtol)
    fr.assert_resid_close(r.residuals, res, rtol, m=m)
    # final state: phase for every track, x for running tracks
    ph = np.atleast_1d(r.state.phase)
    assert np.array_equal(ph, st.phase), (ph, st.phase)
    x = np.atleast_2d(r.state.x)
    run = st.phase == 2
    if run.any():
        fr.assert_states_close(x[run].T, st.x[run].T, rtol, "final state")
    return r


# ---------------------------------------------------------------------------
# alpha-beta
# ---------------------------------------------------------------------------
AB_CASES = [(seed, pat, init) for seed, pat in enumerate(PATTERNS) for init in INITS]


@pytest.mark.parametrize("seed,pattern,init", AB_CASES)
def test_alphabeta_random_gains(seed, pattern, init):
    rng = np.random.default_rng(1000 + seed)
    a, b = fr.random_ab_gains(rng)
    T = rng.uniform(0.05, 3.0)
    z = fr.with_nans(rng, fr.kinematic_z(rng, 6, 240, T), pattern)
    check_run(AlphaBetaFilter(a, b, T), fr.ab_model(a, b, T), z, _init(init, rng, 2))


# gains at the edges of the stable triangle (slow poles, overshoot, oscillation)
AB_EDGE = [(0.01, 1e-4), (0.02, 0.3), (1.95, 0.05), (0.05, 3.85), (1.0, 1.9), (1.9, 0.15), (0.5, 2.9), (1.0, 1.0), (1.5, 0.5)]


@pytest.mark.parametrize("a,b", AB_EDGE)
@pytest.mark.parametrize("init", ["two-point", "first"])
def test_alphabeta_edge_gains(a, b, init):
    assert fr.closed_loop_radius(fr.ab_model(a, b, 1.0))[0] < 1
    rng = np.random.default_rng(int(a * 1000 + b * 10))
    z = fr.with_nans(rng, fr.kinematic_z(rng, 3, 400, 0.7), "runs")
    check_run(AlphaBetaFilter(a, b, 0.7), fr.ab_model(a, b, 0.7), z, init)


@pytest.mark.parametrize("init", INITS)
@pytest.mark.parametrize("pattern", ["none", "mixed", "start-gaps"])
def test_alphabeta_single_track_1d(init, pattern):
    rng = np.random.default_rng(7)
    a, b = fr.random_ab_gains(rng)
    z = fr.with_nans(rng, fr.kinematic_z(rng, 1, 300, 0.25), pattern)[0]
    r = check_run(AlphaBetaFilter(a, b, 0.25), fr.ab_model(a, b, 0.25), z, _init(init, rng, 2))
    assert r.states.shape == (2, 300) and r.residuals.shape == (300,)
    assert r.position.shape == (300,) and r.velocity.shape == (300,)
    assert np.ndim(r.state.phase) == 0 and r.state.x.shape == (2,)


@pytest.mark.parametrize("init", INITS)
@pytest.mark.parametrize("pattern", ["none", "mixed", "start-gaps"])
def test_alphabeta_per_track_gains(init, pattern):
    rng = np.random.default_rng(11)
    ntr = 9
    a, b = fr.random_ab_gains(rng, ntr)
    T = rng.uniform(0.05, 2.0, ntr)
    z = fr.with_nans(rng, fr.kinematic_z(rng, ntr, 200, T), pattern)
    check_run(AlphaBetaFilter(a, b, T), fr.ab_model(a, b, T), z, _init(init, rng, 2, ntr))


def test_alphabeta_per_track_gains_broadcast_scalar_T():
    rng = np.random.default_rng(12)
    a, b = fr.random_ab_gains(rng, 5)
    z = fr.with_nans(rng, fr.kinematic_z(rng, 5, 150, 0.3), "mixed")
    check_run(AlphaBetaFilter(a, b, 0.3), fr.ab_model(a, b, 0.3), z, "two-point")
    # per-track beta only
    check_run(AlphaBetaFilter(0.4, b, 0.3), fr.ab_model(0.4, b, 0.3), z, "first")


def test_alphabeta_init_array_single_row_for_all_tracks():
    rng = np.random.default_rng(13)
    z = fr.with_nans(rng, fr.kinematic_z(rng, 4, 100, 1.0), "leading")
    x0 = np.array([3.0, -1.0])
    check_run(AlphaBetaFilter(0.5, 0.2, 1.0), fr.ab_model(0.5, 0.2, 1.0), z, x0)


def test_alphabeta_from_design_equals_direct():
    d = abkit.alphabeta.from_snr(0.3)
    rng = np.random.default_rng(14)
    z = fr.with_nans(rng, fr.kinematic_z(rng, 3, 100, 0.5), "random")
    r1 = AlphaBetaFilter.from_design(d, 0.5).run(z)
    r2 = AlphaBetaFilter(d.alpha, d.beta, 0.5).run(z)
    assert np.array_equal(r1.states, r2.states, equal_nan=True)
    check_run(AlphaBetaFilter.from_design(d, 0.5), fr.ab_model(d.alpha, d.beta, 0.5), z, "two-point")


def test_alphabeta_hand_computed():
    """Tiny hand-checked case: z = 0, 1, NaN, 4 with alpha=0.5, beta=0.2, T=1."""
    z = np.array([0.0, 1.0, np.nan, 4.0])
    r = AlphaBetaFilter(0.5, 0.2, 1.0).run(z, return_residuals=True)
    # two-point: [0, NaN], [1, 1]; coast: [2, 1]; update: xp = [3, 1], e = 1 -> [3.5, 1.2]
    want = np.array([[0.0, 1.0, 2.0, 3.5], [np.nan, 1.0, 1.0, 1.2]])
    np.testing.assert_allclose(r.states, want, rtol=1e-15, atol=0)
    assert np.array_equal(np.isnan(r.residuals), [True, True, True, False])
    assert r.residuals[3] == 1.0


# ---------------------------------------------------------------------------
# alpha-beta-gamma
# ---------------------------------------------------------------------------
ABG_CASES = [(conv, seed, pat, init) for conv in fr.ABG_C for seed, pat in enumerate(PATTERNS[::2] + ["mixed"]) for init in INITS]


@pytest.mark.parametrize("conv,seed,pattern,init", ABG_CASES)
def test_alphabetagamma_random_gains(conv, seed, pattern, init):
    rng = np.random.default_rng(2000 + 31 * seed + len(conv))
    T = rng.uniform(0.05, 2.0)
    a, b, g = fr.random_abg_gains(rng, conv, T)
    z = fr.with_nans(rng, fr.kinematic_z(rng, 5, 240, T), pattern)
    f = AlphaBetaGammaFilter(a, b, g, T, convention=conv)
    r = check_run(f, fr.abg_model(a, b, g, T, conv), z, _init(init, rng, 3))
    assert r.acceleration.shape == z.shape


def test_alphabetagamma_default_convention_is_standard():
    rng = np.random.default_rng(21)
    z = fr.kinematic_z(rng, 2, 80, 0.5)
    r1 = AlphaBetaGammaFilter(0.5, 0.4, 0.1, 0.5).run(z)
    r2 = AlphaBetaGammaFilter(0.5, 0.4, 0.1, 0.5, convention="standard").run(z)
    assert np.array_equal(r1.states, r2.states, equal_nan=True)
    check_run(AlphaBetaGammaFilter(0.5, 0.4, 0.1, 0.5), fr.abg_model(0.5, 0.4, 0.1, 0.5, "standard"), z, "two-point")


def test_alphabetagamma_conventions_map_gamma():
    """The same filter-form gain through the three conventions gives the same output."""
    rng = np.random.default_rng(22)
    z = fr.with_nans(rng, fr.kinematic_z(rng, 3, 120, 0.4), "random")
    k2 = 0.05  # gamma-gain as c * gamma
    outs = [AlphaBetaGammaFilter(0.5, 0.3, k2 / c, 0.4, convention=conv).run(z).states for conv, c in fr.ABG_C.items()]
    for o in outs[1:]:
        fr.assert_states_close(o, outs[0], RTOL)


@pytest.mark.parametrize("conv", list(fr.ABG_C))
@pytest.mark.parametrize("init", INITS)
def test_alphabetagamma_per_track_gains(conv, init):
    rng = np.random.default_rng(23 + len(conv))
    ntr = 6
    T = rng.uniform(0.1, 2.0, ntr)
    gains = np.array([fr.random_abg_gains(rng, conv, t) for t in T])
    a, b, g = gains.T
    z = fr.with_nans(rng, fr.kinematic_z(rng, ntr, 200, T), "mixed")
    f = AlphaBetaGammaFilter(a, b, g, T, convention=conv)
    check_run(f, fr.abg_model(a, b, g, T, conv), z, _init(init, rng, 3, ntr))


# ---------------------------------------------------------------------------
# general fixed-gain filters
# ---------------------------------------------------------------------------
def _singer(T=0.5, beta=0.3):
    Phi = fr.singer_phi(T, beta)
    H = np.array([[1.0, 0, 0], [0, 1.0, 0]])
    K = fr.dare_gain(Phi, H, np.diag([0.01, 0.02, 0.1]), np.diag([1.0, 0.5]))
    return Phi, H, K, T


def _cv2d(T=1.0):
    """4 states [x, vx, y, vy], x and y measured."""
    Phi = np.kron(np.eye(2), np.array([[1.0, T], [0.0, 1.0]]))
    H = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0]])
    Q = np.kron(np.eye(2), fr.white_accel_Q(T, 0.5))
    K = fr.dare_gain(Phi, H, Q, np.diag([1.0, 2.0]))
    return Phi, H, K, T


def _random_h(T=0.5, seed=0):
    rng = np.random.default_rng(seed)
    Phi = fr.singer_phi(T, 0.5)
    H = rng.normal(size=(2, 3))
    K = fr.dare_gain(Phi, H, np.diag([0.05, 0.05, 0.2]), np.array([[1.0, 0.2], [0.2, 0.7]]))
    return Phi, H, K, T


def _jerk4(T=1.0):
    """alpha-beta-gamma-theta style 4-state [p, v, a, j], position measured."""
    Phi = np.array([[1, T, T * T / 2, T**3 / 6], [0, 1, T, T * T / 2], [0, 0, 1, T], [0, 0, 0, 1.0]])
    H = np.array([[1.0, 0, 0, 0]])
    K = fr.dare_gain(Phi, H, np.diag([0, 0, 0, 1e-3]), [[1.0]])
    return Phi, H, K, T


def _six(T=0.5):
    """6 states: 2-D constant acceleration [x, vx, ax, y, vy, ay], x and y measured."""
    cv = np.array([[1.0, T, T * T / 2], [0.0, 1.0, T], [0.0, 0.0, 1.0]])
    Phi = np.kron(np.eye(2), cv)
    H = np.zeros((2, 6))
    H[0, 0] = H[1, 3] = 1.0
    Q = np.kron(np.eye(2), np.diag([1e-4, 1e-3, 1e-2]))
    K = fr.dare_gain(Phi, H, Q, np.array([[1.0, 0.3], [0.3, 2.0]]))
    return Phi, H, K, T


def _scalar1(T=1.0):
    return np.array([[0.95]]), np.array([[1.0]]), np.array([[0.3]]), T


def _singer_m1(T=0.5):
    Phi = fr.singer_phi(T, 0.3)
    H = np.array([[1.0, 0, 0]])
    K = fr.dare_gain(Phi, H, np.diag([0.0, 0.0, 0.1]), [[1.0]])
    return Phi, H, K, T


FG_MODELS = {"singer-pos-vel": _singer, "cv2d-4state": _cv2d, "random-H": _random_h, "six-state": _six}
FG_M1 = {"jerk-4state": _jerk4, "scalar-n1": _scalar1, "singer-pos": _singer_m1}


@pytest.mark.parametrize("name", list(FG_MODELS))
@pytest.mark.parametrize("pattern", ["none", "random", "leading", "all-nan-tracks", "runs", "mixed"])
@pytest.mark.parametrize("init", ["first", "array"])
def test_fixed_gain_vector_measurements(name, pattern, init):
    Phi, H, K, T = FG_MODELS[name]()
    n = Phi.shape[0]
    rng = np.random.default_rng(fr.seed_of(name, pattern, init))
    ntr, N = 5, 200
    z = rng.normal(0, 5, (ntr, N, 2)) + np.cumsum(rng.normal(0, 1, (ntr, N, 2)), axis=1)
    z = fr.with_nans(rng, z, pattern)
    f = FixedGainFilter(Phi, H, K, T)
    r = check_run(f, fr.general_model(Phi, H, K, T), z, _init(init, rng, n), m=2)
    assert r.states.shape == (n, ntr, N) and r.residuals.shape == (ntr, N, 2)


@pytest.mark.parametrize("name", list(FG_MODELS))
def test_fixed_gain_vector_single_track(name):
    Phi, H, K, T = FG_MODELS[name]()
    rng = np.random.default_rng(31)
    z = fr.with_nans(rng, fr.kinematic_z(rng, 1, 150, T, m=2), "mixed")[0]
    r = check_run(FixedGainFilter(Phi, H, K, T), fr.general_model(Phi, H, K, T), z, "first", m=2)
    assert r.states.shape == (Phi.shape[0], 150) and r.residuals.shape == (150, 2)


def test_fixed_gain_one_nan_component_is_a_miss():
    Phi, H, K, T = _singer()
    z = np.tile(np.array([1.0, 0.5]), (6, 1))
    z[3, 1] = np.nan  # only the velocity component missing
    r = FixedGainFilter(Phi, H, K, T).run(z, init="first", return_residuals=True)
    s, res, _ = fr.run_ref(z, fr.general_model(Phi, H, K, T), "first")
    fr.assert_states_close(r.states, s)
    assert np.all(np.isnan(r.residuals[3])) and np.all(np.isnan(r.residuals[0]))
    # coasting: x3 = Phi x2
    np.testing.assert_allclose(r.states[:, 3], Phi @ r.states[:, 2], rtol=1e-13)


@pytest.mark.parametrize("name", list(FG_M1))
@pytest.mark.parametrize("pattern", ["none", "start-gaps", "one-valid", "mixed"])
@pytest.mark.parametrize("init", INITS)
def test_fixed_gain_scalar_measurements(name, pattern, init):
    Phi, H, K, T = FG_M1[name]()
    n = Phi.shape[0]
    if init == "two-point" and n < 2:
        with pytest.raises(ValueError, match="two-point"):
            FixedGainFilter(Phi, H, K, T).run(np.zeros((2, 5)), init="two-point")
        return
    rng = np.random.default_rng(fr.seed_of(name, pattern, init))
    z = fr.with_nans(rng, fr.kinematic_z(rng, 5, 200, T), pattern)
    check_run(FixedGainFilter(Phi, H, K, T), fr.general_model(Phi, H, K, T), z, _init(init, rng, n))


def test_fixed_gain_equals_alphabeta():
    """FixedGainFilter with the alpha-beta model matches AlphaBetaFilter (both vs the reference)."""
    rng = np.random.default_rng(41)
    a, b, T = 0.6, 0.25, 0.2
    z = fr.with_nans(rng, fr.kinematic_z(rng, 4, 300, T), "mixed")
    m = fr.ab_model(a, b, T)
    for init in ["two-point", "first"]:
        r1 = check_run(FixedGainFilter(m.Phi[0], m.H[0], m.K[0], T), m, z, init)
        r2 = check_run(AlphaBetaFilter(a, b, T), m, z, init)
        fr.assert_states_close(r1.states, r2.states)


@pytest.mark.parametrize("init", ["first", "array"])
def test_fixed_gain_per_track_models(init):
    rng = np.random.default_rng(51)
    ntr = 4
    Ts = rng.uniform(0.2, 1.0, ntr)
    mods = [_singer(T, rng.uniform(0.1, 1.0)) for T in Ts]
    Phi = np.stack([m[0] for m in mods])
    H = np.stack([m[1] for m in mods])
    K = np.stack([m[2] for m in mods]) * rng.uniform(0.8, 1.2, (ntr, 1, 1))
    assert np.all(fr.closed_loop_radius(fr.general_model(Phi, H, K)) < 1)
    z = fr.with_nans(rng, fr.kinematic_z(rng, ntr, 200, Ts, m=2), "mixed")
    f = FixedGainFilter(Phi, H, K, Ts)
    check_run(f, fr.general_model(Phi, H, K, Ts), z, _init(init, rng, 3, ntr), m=2)
    # shared H, per-track Phi and K
    f = FixedGainFilter(Phi, H[0], K, Ts)
    check_run(f, fr.general_model(Phi, H[0], K, Ts), z, "first", m=2)


# ---------------------------------------------------------------------------
# float32
# ---------------------------------------------------------------------------
def assert_f32_rounded(got, want, what="states"):
    """got: float32 (n, ...); want: float64 reference (n, ...)."""
    assert got.dtype == np.float32
    assert np.array_equal(np.isnan(got), np.isnan(want)), what
    for c in range(want.shape[0]):
        w, g = want[c], got[c].astype(np.float64)
        fin = ~np.isnan(w)
        if not fin.any():
            continue
        scale = np.max(np.abs(w[fin]))
        assert scale < 1e30
        ulp = np.spacing(np.abs(w[fin]).astype(np.float32)).astype(np.float64)
        err = np.abs(g[fin] - w[fin])
        bound = 0.5 * ulp + 1e-12 * scale
        assert np.all(err <= bound), f"{what}[{c}]: worst {np.max(err / ulp):.3g} ulp"


F32_CASES = [("ab", p) for p in ["none", "random", "mixed", "start-gaps"]] + [("abg", p) for p in ["none", "mixed"]] + [
    ("singer", p) for p in ["none", "mixed"]
]


@pytest.mark.parametrize("kind,pattern", F32_CASES)
@pytest.mark.parametrize("init", INITS)
def test_float32_correctly_rounded(kind, pattern, init):
    rng = np.random.default_rng(fr.seed_of(kind, pattern, init))
    T = 0.5
    m = 1
    if kind == "ab":
        a, b = rng.uniform(0.2, 1.2), rng.uniform(0.05, 0.6)
        f, model = AlphaBetaFilter(a, b, T), fr.ab_model(a, b, T)
    elif kind == "abg":
        a, b, g = 0.5, 0.2, 0.02
        f, model = AlphaBetaGammaFilter(a, b, g, T), fr.abg_model(a, b, g, T)
    else:
        Phi, H, K, T = _singer(T)
        f, model, m = FixedGainFilter(Phi, H, K, T), fr.general_model(Phi, H, K, T), 2
        if init == "two-point":
            init = "first"
    z = fr.with_nans(rng, fr.kinematic_z(rng, 5, 1500, T, m=m), pattern).astype(np.float32)
    init_v = _init(init, rng, model.n)
    r = f.run(z, init=init_v, return_residuals=True)
    assert r.states.dtype == np.float32 and r.residuals.dtype == np.float32
    assert r.position.dtype == np.float32
    s, res, st = fr.run_ref(z, model, init_v)  # float64 reference from the float32 values
    assert_f32_rounded(r.states, s)
    assert_f32_rounded(r.residuals[None] if m == 1 else np.moveaxis(r.residuals, -1, 0), res[None] if m == 1 else np.moveaxis(res, -1, 0), "residuals")
    assert np.array_equal(np.atleast_1d(r.state.phase), st.phase)


def test_float32_states_exactly_rounded():
    """Observed property, stated in the module docs: the float32 states are the
    float64 reference rounded to float32, element for element."""
    rng = np.random.default_rng(61)
    z = fr.with_nans(rng, fr.kinematic_z(rng, 4, 2000, 0.3), "random").astype(np.float32)
    r = AlphaBetaFilter(0.7, 0.3, 0.3).run(z)
    s, _, _ = fr.run_ref(z, fr.ab_model(0.7, 0.3, 0.3))
    fin = ~np.isnan(s)
    frac = np.mean(r.states[fin] == s[fin].astype(np.float32))
    assert frac > 0.9999, frac


# ---------------------------------------------------------------------------
# result object
# ---------------------------------------------------------------------------
def test_result_layout():
    rng = np.random.default_rng(71)
    z = fr.kinematic_z(rng, 3, 50, 1.0)
    r = AlphaBetaFilter(0.5, 0.2, 1.0).run(z)
    assert r.residuals is None
    # Component-major, each plane contiguous (the planes' padding: test_output_layout.py).
    assert r.states.shape == (2, 3, 50) and r.states[0].flags.c_contiguous and r.states[1].flags.c_contiguous
    assert r.position.shape == z.shape and r.velocity.shape == z.shape
    assert r.position.flags.c_contiguous and r.velocity.flags.c_contiguous
    assert np.shares_memory(r.position, r.states)
    assert np.array_equal(r.position, r.states[0]) and np.array_equal(r.velocity, r.states[1], equal_nan=True)
    with pytest.raises(AttributeError):
        r.acceleration
    assert isinstance(r, abkit.FilterResult) and isinstance(r.state, abkit.FilterState)
    assert r.state.n_tracks == 3 and r.state.n == 2 and r.state.x.shape == (3, 2) and r.state.phase.shape == (3,)
    r3 = AlphaBetaGammaFilter(0.5, 0.2, 0.05, 1.0).run(z)
    assert r3.acceleration.shape == z.shape and r3.states.shape == (3, 3, 50)
    rs = FixedGainFilter([[0.9]], [[1.0]], [[0.5]]).run(z, init="first")
    with pytest.raises(AttributeError):
        rs.velocity


def test_list_input_residuals_shaped_like_z():
    """Documented: residuals are "shaped like z" -- also for array_like (list) input."""
    f = AlphaBetaFilter(0.5, 0.2, 1.0)
    z = [0.0, 1.0, 2.5, 3.0]
    r = f.run(z, return_residuals=True)
    assert r.states.shape == (2, 4)
    assert r.residuals.shape == (4,), r.residuals.shape
    r2 = f.run([z, z], return_residuals=True)
    assert r2.residuals.shape == (2, 4), r2.residuals.shape


# ---------------------------------------------------------------------------
# track counts (interleaved kernels: remainders) and short tracks
# ---------------------------------------------------------------------------
NTR = [1, 2, 3, 4, 5, 6, 7, 8, 9, 11, 13, 15, 16, 17, 31, 33, 64, 65, 129]


@pytest.mark.parametrize("ntr", NTR)
@pytest.mark.parametrize("kind", ["ab", "ab-per-track", "abg", "singer"])
def test_track_counts(ntr, kind):
    rng = np.random.default_rng(fr.seed_of("ntr", ntr, kind))
    N = 60
    T = 0.5
    if kind.startswith("ab-"):
        a, b = fr.random_ab_gains(rng, ntr)
        f, model, m, init = AlphaBetaFilter(a, b, T), fr.ab_model(a, b, T), 1, "two-point"
    elif kind == "ab":
        a, b = fr.random_ab_gains(rng)
        f, model, m, init = AlphaBetaFilter(a, b, T), fr.ab_model(a, b, T), 1, "two-point"
    elif kind == "abg":
        a, b, g = fr.random_abg_gains(rng, "standard", T)
        f, model, m, init = AlphaBetaGammaFilter(a, b, g, T), fr.abg_model(a, b, g, T), 1, "two-point"
    else:
        Phi, H, K, T = _singer(T)
        f, model, m, init = FixedGainFilter(Phi, H, K, T), fr.general_model(Phi, H, K, T), 2, "first"
    z = fr.with_nans(rng, fr.kinematic_z(rng, ntr, N, T, m=m), "mixed")
    for th in (1, 2):
        r = f.run(z, init=init, return_residuals=True, threads=th)
        s, res, _ = fr.run_ref(z, model, init)
        fr.assert_states_close(r.states, s)
        fr.assert_resid_close(r.residuals, res, m=m)
    A = 0.3 * np.eye(model.n)
    xf3, _, _ = fr.filter_ref(fr.as_tracks(z, m)[0], model, init)
    for lag in (None, 3):
        sm = f.smooth(z, init=init, smoother_gain=A, lag=lag)
        fr.assert_states_close(sm.states, np.moveaxis(fr.smooth_ref(xf3, model, A, lag), 2, 0))


@pytest.mark.parametrize("N", [1, 2, 3, 4, 5, 8])
@pytest.mark.parametrize("ntr", [1, 7, 300])
def test_short_tracks(N, ntr):
    rng = np.random.default_rng(fr.seed_of("short", N, ntr))
    a, b = fr.random_ab_gains(rng, ntr)
    z = fr.with_nans(rng, fr.kinematic_z(rng, ntr, N, 1.0), "random")
    for init in ("two-point", "first"):
        f = AlphaBetaFilter(a, b, 1.0)
        check_run(f, fr.ab_model(a, b, 1.0), z, init)
        A = np.array([[0.4, 0.2], [-0.1, 0.3]])
        xf3, _, _ = fr.filter_ref(z[:, :, None], fr.ab_model(a, b, 1.0), init)
        for lag in (None, 1):
            fr.assert_states_close(f.smooth(z, init=init, smoother_gain=A, lag=lag).states, np.moveaxis(fr.smooth_ref(xf3, fr.ab_model(a, b, 1.0), A, lag), 2, 0))


def test_single_track_million_samples_vs_scalar_reference():
    """One 10^6-sample track (5 % misses, two-point start after a NaN lead) against
    a plain-Python scalar loop. Position within 1e-12 of its scale; velocity
    within 1e-12 of the position scale / T (a last-bit position difference
    enters the velocity through beta/T per sample: the positions here are
    ~1e4, the velocities ~1)."""
    rng = np.random.default_rng(81)
    N, T, a, b = 1_000_000, 0.01, 0.3, 0.05
    z = rng.normal(size=N) + np.arange(N) * 0.01
    z[rng.random(N) < 0.05] = np.nan
    z[:7] = np.nan
    r = AlphaBetaFilter(a, b, T).run(z)
    p, v = fr.ab_scalar_ref(z, a, b, T)
    fr.assert_states_close(r.states[:1], p[None])
    assert np.array_equal(np.isnan(r.velocity), np.isnan(v))
    pscale = np.nanmax(np.abs(p))
    assert np.nanmax(np.abs(r.velocity - v)) <= 1e-12 * pscale / T


@pytest.mark.parametrize("offset", [1e6, 1e9])
@pytest.mark.parametrize("kind", ["ab", "abg", "fg-ab", "fg4"])
def test_large_position_offsets(offset, kind):
    """Positions far from 0 with small rates: the rates are ill-conditioned
    (a last-bit change of a position ~offset moves the velocity by ~K/T ulps of
    the offset), in the reference as in abkit. Positions within 1e-12 of their
    scale; rate component c within 1e-12 of the position scale / T^c."""
    rng = np.random.default_rng(fr.seed_of("offset", offset, kind))
    T = 0.1
    if kind == "ab":
        f, model = AlphaBetaFilter(0.3, 0.05, T), fr.ab_model(0.3, 0.05, T)
    elif kind == "abg":
        f, model = AlphaBetaGammaFilter(0.5, 0.2, 0.02, T), fr.abg_model(0.5, 0.2, 0.02, T)
    elif kind == "fg-ab":
        m0 = fr.ab_model(0.3, 0.05, T)
        f, model = FixedGainFilter(m0.Phi[0], m0.H[0], m0.K[0], T), m0
    else:
        Phi, H, K, _ = _jerk4(T)
        f, model = FixedGainFilter(Phi, H, K, T), fr.general_model(Phi, H, K, T)
    z = offset + fr.with_nans(rng, fr.kinematic_z(rng, 4, 1000, T), "mixed")
    for init in ("two-point", "first"):
        r = f.run(z, init=init)
        s, _, _ = fr.run_ref(z, model, init)
        fr.assert_states_close(r.states, s, RTOL, kin_T=T)
