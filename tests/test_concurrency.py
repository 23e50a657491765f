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
