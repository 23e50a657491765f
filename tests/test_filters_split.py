"""The single-long-track segment split (docs/filtering.md) against the
unsplit recursion: a strided view of the same data is never split, so the
two runs compare the split with the plain sequential loop. Tolerance 1e-12 of
each state's scale (velocity: position scale / T)."""

from __future__ import annotations

import numpy as np
import pytest

import abkit


def _pair(z: np.ndarray) -> tuple:
    zz = np.empty((z.size, 2), dtype=z.dtype)
    zz[:, 0] = z
    return z, zz[:, 0]  # contiguous (split) and strided (unsplit)


@pytest.mark.parametrize(
    "alpha,beta,T,nan_frac,offset",
    [
        (0.5, 0.2, 0.1, 0.0, 0.0),
        (0.5, 0.2, 0.1, 0.05, 1e4),
        (0.3, 0.05, 1.0, 0.2, -5e3),
        (0.9, 0.8, 0.01, 0.01, 0.0),
        (0.05, 0.0013, 1.0, 0.0, 0.0),  # slow loop: not split, still equal
    ],
)
@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_split_equals_sequential(alpha, beta, T, nan_frac, offset, dtype):
    rng = np.random.default_rng(11)
    n = 300_001
    x = offset + np.cumsum(np.cumsum(rng.normal(0, 0.01, n))) * T
    z = (x + rng.normal(size=n)).astype(dtype)
    z[rng.random(n) < nan_frac] = np.nan
    z[150_000:150_500] = np.nan  # a long coast across segment boundaries
    f = abkit.AlphaBetaFilter(alpha, beta, T)
    zc, zs = _pair(z)
    for threads in (1, 2):
        a = f.run(zc, threads=threads)
        b = f.run(zs, threads=1)
        assert np.array_equal(np.isnan(a.states), np.isnan(b.states))
        pscale = float(np.nanmax(np.abs(b.states[0].astype(np.float64))))
        tol = 1e-12 if dtype == np.float64 else 4 * float(np.finfo(np.float32).eps)
        dp = np.nanmax(np.abs(a.states[0].astype(np.float64) - b.states[0]))
        dv = np.nanmax(np.abs(a.states[1].astype(np.float64) - b.states[1]))
        assert dp <= tol * pscale and dv <= tol * pscale / T, (dp, dv, pscale)
        assert np.allclose(a.state.x, b.state.x, rtol=0, atol=tol * pscale / T)
    # thread count never changes the split result
    assert np.array_equal(f.run(zc, threads=1).states, f.run(zc, threads=2).states, equal_nan=True)
