#!/usr/bin/env python3
"""Where the time of abkit.frame.filter goes: kernel vs Python/pandas layer.

    python bench/bench_frame.py [N_ROWS] [N_TRACKS]

Defaults: 10^7 rows (reports) in 10^4 tracks of mixed lengths, columns
id (int64), t (float64 seconds, irregular), x, y (float64). For a frame
already grouped by id and time-ordered, for the rows ordered by time with
the tracks interleaved (a live feed), and for the rows shuffled, it
times (best of 3):

- ``frame.filter(df, id=, time=, columns=["x", "y"], filter=f)`` (pandas
  and polars),
- the kernel alone: ``f.run(z, t=t, offsets=offsets, return_residuals=True)``
  on the prepared flat arrays, once per column (what frame.filter calls),

and prints the kernel's share of the total (the rest: factorising ids,
checking/sorting, gathering and scattering columns, building the frame).
"""

from __future__ import annotations

import os
import sys
import time

import numpy as np


def best(fn, repeats: int = 3) -> float:
    ts = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t0)
    return min(ts)


def main() -> None:
    import pandas as pd

    import abkit
    from abkit import frame

    n_rows = int(float(sys.argv[1])) if len(sys.argv) > 1 else 10_000_000
    n_tracks = int(float(sys.argv[2])) if len(sys.argv) > 2 else 10_000
    rng = np.random.default_rng(0)
    lens = rng.integers(10, 2 * n_rows // n_tracks - 10, n_tracks)
    lens = np.maximum(1, np.round(lens * n_rows / lens.sum()).astype(np.int64))
    n = int(lens.sum())
    ids = np.repeat(np.arange(n_tracks, dtype=np.int64) * 7919, lens)
    offsets = np.concatenate([[0], np.cumsum(lens)])
    dt = rng.uniform(0.5, 1.5, n)
    t = np.cumsum(dt)
    t -= np.repeat(t[offsets[:-1]], lens)
    x = np.cumsum(rng.normal(size=n))
    y = np.cumsum(rng.normal(size=n))
    df = pd.DataFrame({"id": ids, "t": t, "x": x, "y": y})
    f = abkit.AlphaBetaFilter.from_noise(0.5, 2.0, 1.0)
    print(f"{n:,} rows, {n_tracks:,} tracks (lengths {lens.min()}-{lens.max()}), 2 columns, "
          f"{os.cpu_count()} CPUs, best of 3")

    def kernel() -> None:
        for z in (x, y):
            f.run(z, t=t, offsets=offsets, return_residuals=True)

    t_kernel = best(kernel)
    rows = [("kernel alone (2 columns)", t_kernel)]
    shuffled = df.sample(frac=1.0, random_state=1).reset_index(drop=True)
    feed = df.sort_values("t", kind="stable").reset_index(drop=True)  # time-ordered, tracks interleaved
    for label, d in (("pandas, grouped", df), ("pandas, time-ordered feed", feed), ("pandas, shuffled", shuffled)):
        rows.append((label, best(lambda: frame.filter(d, id="id", time="t", columns=["x", "y"], filter=f))))
    try:
        import polars as pl
    except ImportError:
        pl = None
    if pl is not None:
        for label, d in (("polars, grouped", pl.from_pandas(df)), ("polars, time-ordered feed", pl.from_pandas(feed)),
                         ("polars, shuffled", pl.from_pandas(shuffled))):
            rows.append((label, best(lambda: frame.filter(d, id="id", time="t", columns=["x", "y"], filter=f))))
    print(f"\n{'run':<28}{'time [s]':>10}{'M rows/s':>10}{'kernel share':>14}")
    for label, s in rows:
        print(f"{label:<28}{s:>10.3f}{n / s / 1e6:>10.1f}{t_kernel / s:>14.2f}")


if __name__ == "__main__":
    main()
