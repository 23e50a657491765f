"""abkit.kalman against an independent NumPy Kalman loop, scipy's DARE and the
examples of paper 002. Tolerances: 1e-12 relative (scale of each quantity)
unless stated."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg

from abkit import kalman

RTOL = 1e-12


def ref_loop(F, H, Q, R, x0, P0, z):
    """Brown's Fig. 5 loop, one track, NaN = no update. Returns states, residuals, K list, P list."""
    F, H, Q, R = (np.atleast_2d(np.asarray(a, float)) for a in (F, H, Q, R))
    n = F.shape[0]
    x = np.array(x0, float).reshape(n)
    P = np.atleast_2d(np.asarray(P0, float))
    xs, es = [], []
    for k, zk in enumerate(np.atleast_2d(z.T).T if z.ndim > 1 else z[:, None]):
        if k > 0:
            x = F @ x
            P = F @ P @ F.T + Q
        if np.any(np.isnan(zk)):
            es.append(np.full(H.shape[0], np.nan))
        else:
            S = H @ P @ H.T + R
            K = P @ H.T @ np.linalg.inv(S)
            e = zk - H @ x
            x = x + K @ e
            I_KH = np.eye(n) - K @ H
            P = I_KH @ P @ I_KH.T + K @ R @ K.T
            es.append(e)
        xs.append(x.copy())
    return np.array(xs).T, np.array(es), P


def close(a, b, rtol=RTOL):
    a, b = np.asarray(a, float), np.asarray(b, float)
    assert np.array_equal(np.isnan(a), np.isnan(b))
    m = ~np.isnan(b)
    scale = max(1.0, float(np.max(np.abs(b[m])))) if m.any() else 1.0
    assert np.max(np.abs(a[m] - b[m]), initial=0.0) <= rtol * scale


def test_browns_random_constant_and_wiener_examples():
    g = kalman.gain_sequence(1.0, 1.0, 0.0, 0.25, 4.0, 5)
    assert g.K[0, 0, 0] == pytest.approx(16 / 17, rel=1e-15)
    # P_0 = (1 - K0) 4 = 4/17; next gain (4/17)/(4/17 + 1/4) = 16/33
    assert g.P_post[0, 0, 0] == pytest.approx(4 / 17, rel=1e-15)
    assert g.K[1, 0, 0] == pytest.approx(16 / 33, rel=1e-15)
    w = kalman.gain_sequence(1.0, 1.0, 1.0, 0.25, 0.0, 3)
    assert w.K[0, 0, 0] == 0.0
    assert w.K[1, 0, 0] == pytest.approx(0.8, rel=1e-15)


def test_recursive_average():
    """Q = 0 and a huge P0: the estimate is the running mean (paper 002, sec. 3); rtol 1e-9."""
    z = np.random.default_rng(3).normal(5.0, 2.0, 500)
    kf = kalman.KalmanFilter(1.0, 1.0, 0.0, 4.0, x0=[0.0], P0=1e14)
    est = kf.run(z).position
    np.testing.assert_allclose(est, np.cumsum(z) / np.arange(1, 501), rtol=1e-9)
    g = kf.gain_sequence(50)
    np.testing.assert_allclose(g.K[:, 0, 0], 1 / np.arange(1, 51), rtol=1e-9)


def model(n, m, T=0.5):
    F = np.eye(n)
    for i in range(n - 1):
        F[i, i + 1] = T
    if n >= 3:
        F[0, 2] = T * T / 2
    H = np.zeros((m, n))
    for j in range(m):
        H[j, j] = 1.0
    G = np.array([T ** (n - i) / max(1, n - i) for i in range(n)])
    Q = 0.3 * np.outer(G, G) + 1e-3 * np.eye(n)
    R = np.diag([0.8, 0.3][:m])
    return F, H, Q, R


@pytest.mark.parametrize("n,m", [(1, 1), (2, 1), (3, 1), (2, 2), (3, 2), (4, 1), (6, 2)])
def test_gain_sequence_matches_loop_and_converges_to_dare(n, m):
    F, H, Q, R = model(n, m)
    P0 = 10.0 * np.eye(n)
    g = kalman.gain_sequence(F, H, Q, R, P0, 400)
    P = P0.copy()
    for k in range(400):
        S = H @ P @ H.T + R
        K = P @ H.T @ np.linalg.inv(S)
        close(g.K[k], K, 1e-11)
        close(g.P_prior[k], P, 1e-11)
        I_KH = np.eye(n) - K @ H
        P = F @ (I_KH @ P @ I_KH.T + K @ R @ K.T) @ F.T + Q
    M = scipy.linalg.solve_discrete_are(F.T, H.T, Q, R)
    Kinf = M @ H.T @ np.linalg.inv(H @ M @ H.T + R)
    close(g.K[-1], Kinf, 1e-9)  # scipy's own accuracy bounds this comparison


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
@pytest.mark.parametrize("n,m", [(2, 1), (3, 1), (3, 2)])
def test_run_matches_reference_with_missed_samples(n, m, dtype):
    F, H, Q, R = model(n, m)
    rng = np.random.default_rng(n * 10 + m)
    nt, ns = 5, 300
    z = rng.normal(size=(nt, ns, m)) + np.arange(ns)[None, :, None] * 0.1
    z[1, 50:60] = np.nan  # track 1 misses samples: its own covariance recursion
    z[3, 0] = np.nan
    z[4] = np.nan  # all missed
    if m == 1:
        z = z[..., 0]
    z = z.astype(dtype)
    x0 = rng.normal(size=(nt, n))
    P0 = 5.0 * np.eye(n)
    kf = kalman.KalmanFilter(F, H, Q, R, x0=x0, P0=P0)
    res = kf.run(z, return_residuals=True)
    assert res.states.dtype == dtype
    for i in range(nt):
        zi = z[i].astype(np.float64)
        xs, es, Pf = ref_loop(F, H, Q, R, x0[i], P0, zi)
        tol = RTOL if dtype == np.float64 else 2e-6
        close(res.states[:, i], xs, 1e-10 if dtype == np.float64 else tol)
        if dtype == np.float64:
            close(res.residuals[i], es.reshape(res.residuals[i].shape), 1e-10)
            close(res.P_final[i], Pf, 1e-10)


def test_threads_bit_identical():
    F, H, Q, R = model(2, 1)
    z = np.random.default_rng(0).normal(size=(33, 200))
    z[5, 10] = np.nan
    kf = kalman.KalmanFilter(F, H, Q, R, P0=np.eye(2))
    a = kf.run(z, threads=1).states
    b = kf.run(z, threads=2).states
    assert np.array_equal(a, b)


@pytest.mark.parametrize(
    "kw, exc, name",
    [
        (dict(Q=[[1.0, 0.5], [0.0, 1.0]]), ValueError, "Q"),
        (dict(R=[[0.0]]), ValueError, "R"),
        (dict(R=[[-1.0]]), ValueError, "R"),
        (dict(P0=[[1.0, 0.0], [0.0, -1.0]]), ValueError, "P0"),
        (dict(F=np.eye(3)), ValueError, "H"),
        (dict(F=[[np.nan, 1.0], [0.0, 1.0]]), ValueError, "F"),
        (dict(H="x"), TypeError, "H"),
    ],
)
def test_bad_models(kw, exc, name):
    args = dict(F=[[1.0, 1.0], [0.0, 1.0]], H=[[1.0, 0.0]], Q=np.eye(2) * 0.1, R=[[1.0]], P0=np.eye(2))
    args.update(kw)
    with pytest.raises(exc, match=name):
        kalman.KalmanFilter(**args)


def test_bad_run_inputs():
    kf = kalman.KalmanFilter([[1.0, 1.0], [0.0, 1.0]], [[1.0, 0.0]], np.eye(2) * 0.1, [[1.0]], P0=np.eye(2))
    with pytest.raises(TypeError):
        kf.run(np.arange(5))
    with pytest.raises(ValueError):
        kf.run(np.zeros((2, 3, 4)))
    with pytest.raises(ValueError, match="P0"):
        kalman.KalmanFilter(1.0, 1.0, 0.0, 1.0)
    with pytest.raises(ValueError, match="n must"):
        kalman.gain_sequence(1.0, 1.0, 0.0, 1.0, 1.0, -1)
    for bad in (0, -2, 1.5, True):
        with pytest.raises(ValueError, match="threads must be a positive integer or None"):
            kf.run(np.zeros((2, 5)), threads=bad)
    kx = kalman.KalmanFilter([[1.0, 1.0], [0.0, 1.0]], [[1.0, 0.0]], np.eye(2) * 0.1, [[1.0]], P0=np.eye(2),
                             x0=np.zeros((3, 2)))
    with pytest.raises(ValueError, match="x0 has 3 rows but z has 2 tracks"):
        kx.run(np.zeros((2, 5)))
    assert kx.run(np.zeros((3, 5))).states.shape == (2, 3, 5)


@pytest.mark.parametrize("n,m", [(2, 1), (3, 2)])
def test_long_run_switches_to_the_limiting_gain_exactly(n, m):
    """3000 samples: the shared gains converge (to the last bit) early and the
    rest runs in the fixed-gain kernel; tracks with a missed sample keep their
    own covariance recursion. All equal the NumPy loop to 1e-10 of scale."""
    F, H, Q, R = model(n, m)
    g = kalman.gain_sequence(F, H, Q, R, 5.0 * np.eye(n), 3000)
    assert np.array_equal(g.K[-1], g.K[-2])  # converged: the tail path is used
    rng = np.random.default_rng(21)
    nt, ns = 9, 3000
    z = rng.normal(size=(nt, ns, m)) + np.arange(ns)[None, :, None] * 0.05
    z[2, 2500] = np.nan  # a miss after convergence: this track's own recursion
    if m == 1:
        z = z[..., 0]
    kf = kalman.KalmanFilter(F, H, Q, R, P0=5.0 * np.eye(n))
    for threads in (1, None):
        res = kf.run(z, threads=threads, return_residuals=True)
        for i in range(nt):
            xs, es, Pf = ref_loop(F, H, Q, R, np.zeros(n), 5.0 * np.eye(n), z[i])
            close(res.states[:, i], xs, 1e-10)
            close(res.residuals[i], es.reshape(res.residuals[i].shape), 1e-10)
            close(res.P_final[i], Pf, 1e-10)


def test_private_bindings_reject_zero_dimensions():
    # The Python layer never passes n = 0 or m = 0; the bindings check it
    # themselves (a remainder by n = 0 before, caught only as a panic).
    from abkit import _abkit

    e = np.zeros(0)
    for n, m in ((0, 1), (1, 0), (0, 0)):
        with pytest.raises(ValueError, match="sizes do not match n, m"):
            _abkit.kalman_gain_sequence(n, m, e, e, e, e, e, 3)
    # n = m = 0 with a non-empty x0: the size check of x0 took x0.len() % n
    z = np.zeros((1, 3, 0))
    with pytest.raises(ValueError, match="sizes do not match n, m"):
        _abkit.kalman_run(z, 0, 0, e, e, e, e, np.zeros(2), e, np.zeros((0, 1, 3)), np.zeros((1, 0, 0)))
