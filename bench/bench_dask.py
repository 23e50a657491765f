#!/usr/bin/env python3
"""Dask overhead: abkit.dask.run on a 2-worker LocalCluster against the
in-memory filter.run, same data size, same run.

    python bench/bench_dask.py [N_SAMPLES] [N_TRACKS]

Defaults: 10^8 samples as 1,000 tracks x 100,000 samples (float64,
alpha-beta). Three timings, each the best of REPEATS:

- in-memory: ``f.run(z)`` on a numpy array in this process (rayon's pool,
  all cores);
- dask, track chunks: ``abkit.dask.run(f, z, threads=1)`` on a dask array
  chunked along tracks only (8 chunks),
  already persisted on the 2 workers (1 thread each), the estimates
  persisted on the workers (not gathered: that would time the network);
- dask, track x time chunks: the same with the samples cut into 10 time
  chunks (the state carried from chunk to chunk, in order).

Generating the data is not timed (it is persisted first). The ratio
dask / in-memory is the overhead of scheduling, serialisation of the state
between time chunks and the per-block Python layer; both use the machine's
cores (2 worker processes x 1 thread, or rayon's pool in memory).
"""

from __future__ import annotations

import os
import sys
import time

import numpy as np

REPEATS = 3


def best(fn, repeats: int = REPEATS) -> float:
    ts = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t0)
    return min(ts)


def main() -> None:
    import dask.array as da
    from distributed import Client, LocalCluster, wait

    import abkit
    from abkit import dask as adask

    n_total = int(float(sys.argv[1])) if len(sys.argv) > 1 else 100_000_000
    n_tracks = int(sys.argv[2]) if len(sys.argv) > 2 else 1_000
    n_samples = n_total // n_tracks
    f = abkit.AlphaBetaFilter(0.5, 0.2, 1.0)
    print(f"{n_tracks:,} tracks x {n_samples:,} samples = {n_tracks * n_samples:,} samples (float64), "
          f"{os.cpu_count()} CPUs, best of {REPEATS}")

    rng = np.random.default_rng(0)
    z = rng.standard_normal((n_tracks, n_samples))
    out = np.empty((2,) + z.shape)
    f.run(z[:10], threads=None)
    t_mem = best(lambda: f.run(z, out=out))
    del z, out

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
            Client(cluster) as client:
        rows = []
        for label, chunks in (("track chunks", (n_tracks // 8, n_samples)),
                              ("track x time chunks", (n_tracks // 8, n_samples // 10))):
            zd = da.random.default_rng(0).standard_normal((n_tracks, n_samples), chunks=chunks).persist()
            wait(zd)

            count = [0]

            def go() -> None:
                # a new filter each time (same cost): the graph's keys are deterministic, and
                # the same keys would find the previous (not yet released) results on the workers
                count[0] += 1
                g = abkit.AlphaBetaFilter(0.5 + 1e-12 * count[0], 0.2, 1.0)
                s = adask.run(g, zd, threads=1).states.persist()
                wait(s)
                client.cancel(s)
                del s

            go()  # warm the workers (imports, rayon)
            rows.append((label, zd.numblocks, best(go)))
            del zd

    n = n_tracks * n_samples
    print(f"\n{'run':<40}{'blocks':>10}{'time [s]':>10}{'M samples/s':>13}{'vs in-memory':>14}")
    print(f"{'in-memory f.run (rayon, all cores)':<40}{'-':>10}{t_mem:>10.3f}{n / t_mem / 1e6:>13.0f}{1.0:>14.2f}")
    for label, blocks, t in rows:
        name = f"abkit.dask.run, {label}"
        nb = f"{blocks[0]}x{blocks[1]}"
        print(f"{name:<40}{nb:>10}{t:>10.3f}{n / t / 1e6:>13.0f}{t / t_mem:>14.2f}")


if __name__ == "__main__":
    main()
