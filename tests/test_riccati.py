"""abkit.riccati against independent references.

* The real cases of the DARE benchmark collection of Benner, Laub &
  Mehrmann (SPC 95_23, 1995) that scipy's own test suite uses
  (scipy/linalg/tests/test_solvers.py, TestSolveDiscreteAre): relative
  residual, computed here, <= 1e-12, and closed-loop stability.
* scipy.linalg.solve_discrete_are on random stabilisable/detectable systems
  (n = 1..8 and n = 100), with and without the cross term S.
* Properties: residual, symmetry, positive semi-definiteness, scaling.
* Brute-force Riccati (predict/update) recursion for kalman_steady_state.
* LinAlgError where no stabilising solution exists (including the case where
  scipy returns a non-stabilising X), ValueError naming the argument.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg

from abkit.riccati import kalman_steady_state, solve_dare, solve_dare_info


def rel_residual(A, B, Q, R, X, S=None):
    """||res||_F / (||A'XA|| + ||X|| + ||Q|| + ||(A'XB+S)K||), computed here."""
    if S is None:
        S = np.zeros(B.shape)
    K = np.linalg.solve(R + B.T @ X @ B, B.T @ X @ A + S.T)
    axa = A.T @ X @ A
    corr = (A.T @ X @ B + S) @ K
    res = axa - X - corr + Q
    den = sum(np.linalg.norm(m) for m in (axa, X, Q, corr))
    return np.linalg.norm(res) / den, max(abs(np.linalg.eigvals(A - B @ K)))


def _darex():
    """(name, A, B, Q, R) of the real benchmark cases (data of Benner-Laub-Mehrmann / scipy's tests)."""
    cases = []
    add = lambda name, a, b, q, r: cases.append((name, *(np.atleast_2d(np.asarray(x, float)) for x in (a, b, q, r))))  # noqa: E731
    add(
        "gh-2251",
        [[0.63399379, 0.54906824, 0.76253406], [0.5404729, 0.53745766, 0.08731853], [0.27524045, 0.84922129, 0.4681622]],
        [[0.96861695], [0.05532739], [0.78934047]],
        np.eye(3),
        [[1]],
    )
    add("darex1", [[4, 3], [-4.5, -3.5]], [[1], [-1]], [[9, 6], [6, 4]], [[1]])
    add("darex2", [[0.9512, 0], [0, 0.9048]], [[4.877, 4.877], [-1.1895, 3.569]], np.diag([0.005, 0.02]), np.diag([1 / 3, 3]))
    add("darex3 (R = 0)", [[2, -1], [1, 0]], [[1], [0]], [[0, 0], [0, 1]], [[0]])
    add("darex4 (Q indefinite, R singular)", [[0, 1], [0, -1]], [[1, 0], [2, 1]], np.array([[-4, -4], [-4, 7]]) / 11, [[9, 3], [3, 1]])
    add("darex5", [[0, 1], [0, 0]], [[0], [1]], [[1, 2], [2, 4]], [[1]])
    rot = np.array([[0.998, 0.067, 0, 0], [-0.067, 0.998, 0, 0], [0, 0, 0.998, 0.153], [0, 0, -0.153, 0.998]])
    add(
        "darex6",
        rot,
        [[0.0033, 0.0200], [0.1000, -0.0007], [0.0400, 0.0073], [-0.0028, 0.1000]],
        [[1.87, 0, 0, -0.244], [0, 0.744, 0.205, 0], [0, 0.205, 0.589, 0], [-0.244, 0, 0, 1.048]],
        np.eye(2),
    )
    add(
        "darex7",
        [
            [0.984750, -0.079903, 0.0009054, -0.0010765],
            [0.041588, 0.998990, -0.0358550, 0.0126840],
            [-0.546620, 0.044916, -0.3299100, 0.1931800],
            [2.662400, -0.100450, -0.9245500, -0.2632500],
        ],
        [[0.0037112, 0.0007361], [-0.0870510, 9.3411e-6], [-1.198440, -4.1378e-4], [-3.192700, 9.2535e-4]],
        np.eye(4) * 1e-2,
        np.eye(2),
    )
    add(
        "darex8",
        [[-0.6, -2.2, -3.6, -5.400018], [1.0, 0.6, 0.8, 3.399982], [0.0, 1.0, 1.8, 3.799982], [0.0, 0.0, 0.0, -0.999982]],
        [[1.0, -1.0, -1.0, -1.0], [0.0, 1.0, -1.0, -1.0], [0.0, 0.0, 1.0, -1.0], [0.0, 0.0, 0.0, 1.0]],
        [[2, 1, 3, 6], [1, 2, 2, 5], [3, 2, 6, 11], [6, 5, 11, 22]],
        np.eye(4),
    )
    add(
        "darex9",
        0.01
        * np.array(
            [
                [95.4070, 1.9643, 0.3597, 0.0673, 0.0190],
                [40.8490, 41.3170, 16.0840, 4.4679, 1.1971],
                [12.2170, 26.3260, 36.1490, 15.9300, 12.3830],
                [4.1118, 12.8580, 27.2090, 21.4420, 40.9760],
                [0.1305, 0.5808, 1.8750, 3.6162, 94.2800],
            ]
        ),
        0.01 * np.array([[0.0434, -0.0122], [2.6606, -1.0453], [3.7530, -5.5100], [3.6076, -6.6000], [0.4617, -0.9148]]),
        np.eye(5),
        np.eye(2),
    )
    add(
        "darex10",
        np.kron(np.eye(2), np.diag([1, 1], k=1)),
        np.kron(np.eye(2), [[0], [0], [1]]),
        scipy.linalg.block_diag([[1, 1, 0], [1, 1, 0], [0, 0, 0]], [[1, -1, 0], [-1, 1, 0], [0, 0, 0]]),
        np.diag([3, 1]),
    )
    a11 = 0.001 * np.array(
        [
            [870.1, 135.0, 11.59, 0.5014, -37.22, 0.3484, 0, 4.242, 7.249],
            [76.55, 897.4, 12.72, 0.5504, -40.16, 0.3743, 0, 4.53, 7.499],
            [-127.2, 357.5, 817, 1.455, -102.8, 0.987, 0, 11.85, 18.72],
            [-363.5, 633.9, 74.91, 796.6, -273.5, 2.653, 0, 31.72, 48.82],
            [-960, 1645.9, -128.9, -5.597, 71.42, 7.108, 0, 84.52, 125.9],
            [-664.4, 112.96, -88.89, -3.854, 84.47, 13.6, 0, 144.3, 101.6],
            [-410.2, 693, -54.71, -2.371, 66.49, 12.49, 0.1063, 99.97, 69.67],
            [-179.9, 301.7, -23.93, -1.035, 60.59, 22.16, 0, 213.9, 35.54],
            [-345.1, 580.4, -45.96, -1.989, 105.6, 19.86, 0, 219.1, 215.2],
        ]
    )
    b11 = 0.001 * np.array(
        [
            [4.7600, -0.5701, -83.6800],
            [0.8790, -4.7730, -2.7300],
            [1.4820, -13.1200, 8.8760],
            [3.8920, -35.1300, 24.8000],
            [10.3400, -92.7500, 66.8000],
            [7.2030, -61.5900, 38.3400],
            [4.4540, -36.8300, 20.2900],
            [1.9710, -15.5400, 6.9370],
            [3.7730, -30.2800, 14.6900],
        ]
    )
    add("darex11", a11, b11, np.diag([50, 0, 0, 0, 50, 0, 0, 0, 0]), np.eye(3))
    add("darex12 (ill-conditioned)", [[0, 1e6], [0, 0]], [[0], [1]], np.eye(2), [[1]])
    add("darex13", np.array([[16, 10, -2], [10, 13, -8], [-2, -8, 7]]) / 9, np.eye(3), 1e6 * np.eye(3), 1e6 * np.eye(3))
    add(
        "darex14 (eigenvalue 1 - 1e-8)",
        [[1 - 1e-8, 0, 0, 0], [1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0]],
        [[1e-8], [0], [0], [0]],
        np.diag([0, 0, 0, 1]),
        [[0.25]],
    )
    add("darex15 (n = 100)", np.eye(100, k=1), np.flipud(np.eye(100, 1)), np.eye(100), [[1]])
    return cases


DAREX = _darex()


@pytest.mark.parametrize("name,A,B,Q,R", DAREX, ids=[c[0] for c in DAREX])
def test_benchmark_collection(name, A, B, Q, R):
    sol = solve_dare_info(A, B, Q, R)
    X = sol.X
    rel, rho = rel_residual(A, B, Q, R, X)
    assert rel <= 1e-12, rel
    assert rho < 1.0
    assert sol.spectral_radius < 1.0
    np.testing.assert_array_equal(X, X.T)
    # Agreement with scipy where scipy's own answer is accurate.
    Xs = scipy.linalg.solve_discrete_are(A, B, Q, R)
    rel_s, rho_s = rel_residual(A, B, Q, R, Xs)
    if rel_s < 1e-13 and rho_s < 1 - 1e-6:
        assert np.linalg.norm(X - Xs) <= 1e-9 * np.linalg.norm(Xs)


def _random_system(rng, n, m, p_q=None):
    A = rng.normal(size=(n, n)) * rng.uniform(0.3, 1.5)
    B = rng.normal(size=(n, m))
    C = rng.normal(size=(p_q or n, n))
    Q = C.T @ C
    D = rng.normal(size=(m, m))
    R = D @ D.T + 0.1 * np.eye(m)
    return A, B, Q, R


@pytest.mark.parametrize("seed", range(40))
def test_random_systems_against_scipy(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 9))
    m = int(rng.integers(1, n + 1))
    A, B, Q, R = _random_system(rng, n, m)
    X = solve_dare(A, B, Q, R)
    Xs = scipy.linalg.solve_discrete_are(A, B, Q, R)
    rel, rho = rel_residual(A, B, Q, R, X)
    assert rel <= 1e-12 and rho < 1
    assert np.linalg.norm(X - Xs) <= 1e-8 * np.linalg.norm(Xs)
    np.testing.assert_array_equal(X, X.T)
    assert np.linalg.eigvalsh(X).min() >= -1e-12 * np.linalg.norm(X)
    # Scaling: (Q, R) -> c (Q, R) gives c X.
    c = 10.0 ** rng.uniform(-6, 6)
    Xc = solve_dare(A, B, c * Q, c * R)
    assert np.linalg.norm(Xc - c * X) <= 1e-9 * c * np.linalg.norm(X)


@pytest.mark.parametrize("seed", range(10))
def test_cross_term_against_scipy(seed):
    rng = np.random.default_rng(100 + seed)
    n, m = 4, 2
    A, B, Q, R = _random_system(rng, n, m)
    S = 0.1 * rng.normal(size=(n, m))
    X = solve_dare(A, B, Q, R, S)
    Xs = scipy.linalg.solve_discrete_are(A, B, Q, R, s=S)
    rel, rho = rel_residual(A, B, Q, R, X, S)
    assert rel <= 1e-12 and rho < 1
    assert np.linalg.norm(X - Xs) <= 1e-8 * np.linalg.norm(Xs)


def test_rank_deficient_q_detectable():
    # Q weights only one output of an observable unstable pair.
    rng = np.random.default_rng(7)
    A, B, _, R = _random_system(rng, 6, 2)
    C = rng.normal(size=(1, 6))
    Q = C.T @ C
    X = solve_dare(A, B, Q, R)
    rel, rho = rel_residual(A, B, Q, R, X)
    assert rel <= 1e-12 and rho < 1


def test_n100_random():
    rng = np.random.default_rng(3)
    n, m = 100, 5
    A = rng.normal(size=(n, n)) / np.sqrt(n) * 1.2
    B = rng.normal(size=(n, m))
    Q = np.eye(n)
    R = np.eye(m)
    X = solve_dare(A, B, Q, R)
    rel, rho = rel_residual(A, B, Q, R, X)
    assert rel <= 1e-12 and rho < 1
    Xs = scipy.linalg.solve_discrete_are(A, B, Q, R)
    assert np.linalg.norm(X - Xs) <= 1e-8 * np.linalg.norm(Xs)


# --- no stabilising solution -------------------------------------------------
def test_unit_circle_mode_not_weighted_raises_where_scipy_does_not():
    A = np.array([[1.0, 0.0], [0.0, 0.5]])
    B = np.array([[1.0], [1.0]])
    Q = np.diag([0.0, 1.0])
    R = np.array([[1.0]])
    Xs = scipy.linalg.solve_discrete_are(A, B, Q, R)
    _, rho_s = rel_residual(A, B, Q, R, Xs)
    assert rho_s >= 1 - 1e-9  # scipy's X is not stabilising
    with pytest.raises(np.linalg.LinAlgError, match="stabilising"):
        solve_dare(A, B, Q, R)


@pytest.mark.parametrize(
    "A,B,Q,R",
    [
        ([[1.0]], [[1.0]], [[0.0]], [[1.0]]),  # unit-circle mode, unweighted
        ([[0.6, -0.8], [0.8, 0.6]], [[1.0], [0.0]], np.zeros((2, 2)), [[1.0]]),  # rotation, unweighted
        ([[2.0]], [[0.0]], [[1.0]], [[1.0]]),  # unstable, not stabilisable
        ([[2.0, 0.0], [0.0, 0.5]], [[0.0], [1.0]], np.eye(2), [[1.0]]),  # unstable mode B cannot reach
        ([[1.0]], [[0.0]], [[1.0]], [[0.0]]),  # R + B'XB = 0 for every X
    ],
)
def test_no_stabilising_solution(A, B, Q, R):
    with pytest.raises(np.linalg.LinAlgError):
        solve_dare(A, B, Q, R)


# --- bad input ---------------------------------------------------------------
I2 = np.eye(2)
B2 = np.ones((2, 1))
R1 = np.eye(1)


@pytest.mark.parametrize(
    "args,name",
    [
        ((np.ones((2, 3)), B2, I2, R1), "A"),
        ((I2, np.ones((3, 1)), I2, R1), "B"),
        ((I2, B2, np.eye(3), R1), "Q"),
        ((I2, B2, I2, np.eye(2)), "R"),
        ((I2, B2, np.array([[1.0, 0.5], [0.0, 1.0]]), R1), "Q"),
        ((I2, B2, I2, R1, np.ones((1, 2))), "S"),
        ((np.array([[np.nan, 0], [0, 1]]), B2, I2, R1), "A"),
        ((I2, B2, I2, np.array([[np.inf]])), "R"),
        ((np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((0, 0)), R1), "A"),
        ((np.ones(3), B2, I2, R1), "A"),
    ],
)
def test_bad_input_names_argument(args, name):
    with pytest.raises(ValueError, match=rf"^{name} "):
        solve_dare(*args)


def test_non_symmetric_r_and_complex_input():
    with pytest.raises(ValueError, match="^R must be symmetric"):
        solve_dare(I2, np.ones((2, 2)), I2, np.array([[1.0, 0.2], [0.0, 1.0]]))
    with pytest.raises(TypeError, match="^A "):
        solve_dare(I2 * 1j, B2, I2, R1)


# --- Kalman steady state -----------------------------------------------------
def _kalman_iterate(F, H, Q, R, steps=20000):
    """Predict/update recursion from P = I until it stops changing (1e-14 relative)."""
    P = np.eye(F.shape[0])
    I = np.eye(len(P))
    for _ in range(steps):
        S = H @ P @ H.T + R
        K = np.linalg.solve(S, H @ P).T
        Pf = (I - K @ H) @ P
        Pn = F @ Pf @ F.T + Q
        Pn = (Pn + Pn.T) / 2  # rounding asymmetry would grow under an unstable F
        if np.max(np.abs(Pn - P)) <= 1e-14 * np.max(np.abs(P)):
            break
        P = Pn
    return P, K, Pf


@pytest.mark.parametrize("seed", range(8))
def test_kalman_steady_state_against_recursion_and_scipy(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 6))
    p = int(rng.integers(1, n + 1))
    F = rng.normal(size=(n, n)) * 0.9
    H = rng.normal(size=(p, n))
    G = rng.normal(size=(n, n))
    Q = G @ G.T
    D = rng.normal(size=(p, p))
    R = D @ D.T + 0.1 * np.eye(p)
    ks = kalman_steady_state(F, H, Q, R)
    P, K, Pf = _kalman_iterate(F, H, Q, R)
    scale = np.linalg.norm(P)
    assert np.linalg.norm(ks.P_pred - P) <= 1e-9 * scale
    assert np.linalg.norm(ks.K - K) <= 1e-9 * max(np.linalg.norm(K), 1e-300)
    assert np.linalg.norm(ks.P_filt - Pf) <= 1e-9 * scale
    np.testing.assert_allclose(ks.K_pred, F @ ks.K, rtol=1e-12, atol=1e-14 * np.abs(ks.K_pred).max())
    np.testing.assert_allclose(ks.S, H @ ks.P_pred @ H.T + R, rtol=1e-12)
    Ps = scipy.linalg.solve_discrete_are(F.T, H.T, Q, R)
    assert np.linalg.norm(ks.P_pred - Ps) <= 1e-9 * scale
    assert ks.spectral_radius < 1
    assert max(abs(np.linalg.eigvals(F - ks.K_pred @ H))) < 1


def test_kalman_bad_input_names_argument():
    with pytest.raises(ValueError, match="^H "):
        kalman_steady_state(I2, np.ones((1, 3)), I2, R1)
    with pytest.raises(ValueError, match="^F "):
        kalman_steady_state(np.ones((2, 3)), np.ones((1, 2)), I2, R1)
    with pytest.raises(np.linalg.LinAlgError):
        # The unstable mode 2 is not observed.
        kalman_steady_state([[1.0, 0.0], [0.0, 2.0]], [[1.0, 0.0]], np.eye(2), [[1.0]])


# --- property tests (hypothesis) ----------------------------------------------
hypothesis = pytest.importorskip("hypothesis")
from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402


@settings(max_examples=40, deadline=None, derandomize=True, database=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 6), m=st.integers(1, 3), logc=st.floats(-4, 4))
def test_property_similarity_and_scaling(seed, n, m, logc):
    """X is covariant under a change of state coordinates x = T z
    (A -> T^-1 A T, B -> T^-1 B, Q -> T' Q T, X -> T' X T), scales with
    (Q, R) -> c (Q, R), and is symmetric PSD with a small residual
    (<= 1e-10 relative on these random, sometimes ill-conditioned systems;
    the 1e-12 bound is asserted on the well-conditioned benchmark cases).
    Derandomized so that CI is reproducible."""
    rng = np.random.default_rng(seed)
    A, B, Q, R = _random_system(rng, n, m)
    try:
        X = solve_dare(A, B, Q, R)
    except np.linalg.LinAlgError:
        # Only acceptable if scipy's answer is not stabilising either.
        Xs = scipy.linalg.solve_discrete_are(A, B, Q, R)
        assert rel_residual(A, B, Q, R, Xs)[1] >= 1 - 1e-6
        return
    rel, rho = rel_residual(A, B, Q, R, X)
    assert rel <= 1e-10 and rho < 1
    assert np.linalg.eigvalsh(X).min() >= -1e-10 * np.linalg.norm(X)
    T = rng.normal(size=(n, n)) + 3 * np.eye(n)
    Ti = np.linalg.inv(T)
    Xt = solve_dare(Ti @ A @ T, Ti @ B, T.T @ Q @ T, R)
    want = T.T @ X @ T
    cond = np.linalg.cond(T) ** 2
    assert np.linalg.norm(Xt - want) <= 1e-10 * cond * np.linalg.norm(want)
    c = 10.0**logc
    assert np.linalg.norm(solve_dare(A, B, c * Q, c * R) - c * X) <= 1e-9 * c * np.linalg.norm(X)
