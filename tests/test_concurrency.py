"""Concurrency: the GIL is released in every kernel, so many Python threads
may call abkit at once; results must equal serial calls bit for bit. abkit
objects also work across processes (pickling)."""

from __future__ import annotations

import concurrent.futures as cf
import pickle

import numpy as np

import abkit
from abkit import alphabeta


def _work(seed: int) -> tuple:
    rng = np.random.default_rng(seed)
    z = np.cumsum(rng.normal(size=(17, 500)), axis=1)
    z[rng.random(z.shape) < 0.05] = np.nan
    f = abkit.AlphaBetaFilter(0.3 + 0.01 * seed, 0.05, 0.5)
    g = abkit.AlphaBetaGammaFilter(0.5, 0.2, 0.02, 0.5)
    d = alphabeta.from_snr(10.0 ** rng.uniform(-6, 6, 1000))
    return f.run(z).states, g.smooth(z, Q=np.eye(3) * 1e-3, R=[[1.0]]).states, d.alpha, d.covariance_filtered


def _same(a: tuple, b: tuple) -> bool:
    return all(np.array_equal(x, y, equal_nan=True) for x, y in zip(a, b))


def test_many_threads_equal_serial() -> None:
    seeds = list(range(24))
    serial = [_work(s) for s in seeds]
    with cf.ThreadPoolExecutor(max_workers=8) as ex:
        threaded = list(ex.map(_work, seeds))
    assert all(_same(a, b) for a, b in zip(serial, threaded))


def test_process_pool_and_pickling() -> None:
    f = abkit.AlphaBetaFilter(0.5, 0.2, 1.0)
    d = alphabeta.from_noise(3.2, 32.0, 0.1)
    f2 = pickle.loads(pickle.dumps(f))
    d2 = pickle.loads(pickle.dumps(d))
    z = np.arange(50.0)
    assert np.array_equal(f.run(z).states, f2.run(z).states, equal_nan=True)
    assert d2.alpha == d.alpha and d2.T == d.T
    with cf.ProcessPoolExecutor(max_workers=2) as ex:
        got = list(ex.map(_work, [1, 2]))
    assert all(_same(a, b) for a, b in zip(got, [_work(1), _work(2)]))


# -- issue 8: spawn-context processes, and every heavy entry point at once ----

def test_process_pool_spawn_context() -> None:
    """abkit imports and computes in freshly spawned interpreters (no fork):
    the same results as in this process, bit for bit."""
    import multiprocessing as mp

    with cf.ProcessPoolExecutor(max_workers=2, mp_context=mp.get_context("spawn")) as ex:
        got = list(ex.map(_work, [3, 4, 5]))
    assert all(_same(a, b) for a, b in zip(got, [_work(3), _work(4), _work(5)]))


def _heavy_calls() -> list:
    """(name, zero-argument callable) for every entry point that does real work."""
    from abkit import abg, kalman, riccati, singer

    rng = np.random.default_rng(11)
    z = np.cumsum(rng.normal(size=(40, 2000)), axis=1)
    z[rng.random(z.shape) < 0.03] = np.nan
    z2 = np.stack([z, 0.5 * z], axis=-1)
    long = np.cumsum(rng.normal(size=70_000))  # the split single-track path
    ab = abkit.AlphaBetaFilter(0.4, 0.1, 0.5)
    abg3 = abkit.AlphaBetaGammaFilter(0.5, 0.2, 0.02, 0.5)
    fg2 = abkit.FixedGainFilter([[1.0, 1.0], [0.0, 1.0]], np.eye(2), [[0.5, 0.0], [0.0, 0.4]])
    kf = kalman.KalmanFilter([[1.0, 1.0], [0.0, 1.0]], [[1.0, 0.0]], np.eye(2) * 1e-2, [[1.0]], P0=np.eye(2) * 1e3)
    r = 10.0 ** rng.uniform(-6, 6, 5000)
    return [
        ("ab.run", lambda: ab.run(z, return_residuals=True).states),
        ("ab.run.long", lambda: ab.run(long).states),
        ("ab.smooth", lambda: ab.smooth(z).states),
        ("ab.smooth.lag", lambda: ab.smooth(z, lag=7).states),
        ("abg.run", lambda: abg3.run(z, threads=3).states),
        ("abg.smooth", lambda: abg3.smooth(z, Q=np.diag([1e-4, 1e-3, 1e-2]), R=[[1.0]]).states),
        ("fg2.run", lambda: fg2.run(z2, init="first").states),
        ("kf.run", lambda: kf.run(z).states),
        ("alphabeta.from_snr", lambda: alphabeta.from_snr(r).covariance_filtered),
        ("abg.from_noise", lambda: abg.from_noise(r, 1.0, 0.5, 2.0).gamma),
        ("singer.steady_state", lambda: singer.steady_state(1.0, r[:300], 1.0, 1.0).P_pred),
        ("riccati.kalman_steady_state", lambda: riccati.kalman_steady_state(np.eye(3) + np.eye(3, k=1), np.eye(1, 3), np.eye(3), [[1.0]]).P_pred),
    ]


def test_many_threads_every_heavy_entry_point_at_once() -> None:
    """32 threads, each calling every heavy entry point (in a different
    order), all at once: every result equals the serial one bit for bit."""
    import random
    import threading

    calls = _heavy_calls()
    serial = {name: f() for name, f in calls}
    barrier = threading.Barrier(32)
    errors: list = []

    def worker(seed: int) -> None:
        order = list(calls)
        random.Random(seed).shuffle(order)
        barrier.wait()
        for name, f in order:
            got = f()
            if not np.array_equal(got, serial[name], equal_nan=True):
                errors.append(name)

    threads = [threading.Thread(target=worker, args=(s,)) for s in range(32)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors, f"results differ from serial calls under concurrency: {sorted(set(errors))}"
