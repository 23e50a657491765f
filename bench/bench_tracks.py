#!/usr/bin/env python3
"""Benchmark of the real-world tracks kernels (issue 6, "Performance").

Ratios measured in one run, on the same machine, same total samples:

* irregular vs fixed-T: ``AlphaBetaFilter.from_noise(...).run(z, t=t)``
  (per-dt closed-form design at every step) vs ``.run(z)`` (the fixed-T
  rectangular kernel), 1,000 x 10,000 samples; also the fixed-gain
  schedule (``AlphaBetaFilter(alpha, beta, T).run(z, t=t)``) and the track
  kernel without timestamps on the same rectangle (``offsets=``).
  Target: irregular >= 0.5 of fixed-T. The same ratio for ragged tracks
  with timestamps (lengths 10..10,000), both gain schedules, against the
  rectangular fixed-T kernel on the same number of samples.
* a few long tracks (one, three) of 10^7 samples, with and without t, against
  one track with fixed T (the long tracks are split, docs/filtering.md).
* ragged vs rectangular: 10^7 samples as tracks of mixed lengths 10..10,000
  (log-uniform) in one flat array with ``offsets`` vs the rectangular
  fixed-T kernel on the same number of samples. Target: >= 0.8.
* the same in float32, with the default kernels (float64 arithmetic) and
  ``float32_arithmetic=True``, without timestamps.

Throughput is samples per second, best of ``--repeat`` round-robin rounds
(wall time, or CPU time of this process with ``--cpu``: steadier on a
shared machine, meaningful with ``--threads 1``), outputs
preallocated (``out=``), float64, threads = rayon's pool (``--threads 1``
for one thread). Usage::

    python bench/bench_tracks.py            # full sizes (~1 min)
    python bench/bench_tracks.py --quick    # 1/10 of the sizes
    python bench/bench_tracks.py --threads 1 --cpu --repeat 7

Prints a markdown table (the one in docs/benchmarks.md).
"""

from __future__ import annotations

import argparse
import platform
import time
from typing import List, Tuple

import numpy as np

import abkit
from abkit import AlphaBetaFilter


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--threads", type=int, default=None)
    ap.add_argument("--cpu", action="store_true", help="CPU time (time.process_time) instead of wall time")
    a = ap.parse_args()
    clock = time.process_time if a.cpu else time.perf_counter
    scale = 10 if a.quick else 1
    rng = np.random.default_rng(0)
    th = a.threads

    n_tracks, n_samples = 1000 // scale, 10_000
    N = n_tracks * n_samples
    t = np.cumsum(rng.exponential(0.1, (n_tracks, n_samples)), axis=1)
    # reports on a whole-second grid, 1 % missed (AIS / 1 Hz GNSS style)
    t_grid = np.cumsum(1.0 + (rng.random((n_tracks, n_samples)) < 0.01), axis=1)
    z = np.cumsum(rng.normal(0, 1, (n_tracks, n_samples)), axis=1) + rng.normal(0, 1, (n_tracks, n_samples))
    design = AlphaBetaFilter.from_noise(3.2, 32.0, 0.1)
    fixed = AlphaBetaFilter(design.alpha, design.beta, 0.1)
    out = np.empty((2, n_tracks, n_samples))
    off_rect = np.arange(n_tracks + 1, dtype=np.int64) * n_samples
    out_flat = np.empty((2, N))

    # ragged: lengths log-uniform in [10, 10000] up to 10^7 samples
    total = 10_000_000 // scale
    lens = []
    s = 0
    while s < total:
        L = int(round(10 ** rng.uniform(1, 4)))
        L = min(L, total - s)
        lens.append(L)
        s += L
    off = np.concatenate([[0], np.cumsum(lens)]).astype(np.int64)
    zr = np.cumsum(rng.normal(0, 1, total)) + rng.normal(0, 1, total)
    tr = np.cumsum(rng.exponential(0.1, total))  # increasing overall, so per track too
    # one track, and three (5, 3 and 2 tenths) of all samples
    off1 = np.array([0, total], dtype=np.int64)
    off3 = np.array([0, total // 2, total // 2 + 3 * total // 10, total], dtype=np.int64)
    # rectangular reference with the same number of samples
    rect_tracks = 1000 // scale
    zq = zr.reshape(rect_tracks, -1)
    tq = tr.reshape(zq.shape)
    out_q = np.empty((2,) + zq.shape)
    out_r = np.empty((2, total))
    # float32 data: the default kernels (float64 arithmetic) and
    # float32_arithmetic=True
    zr32, zq32 = zr.astype(np.float32), zq.astype(np.float32)
    out_r32, out_q32 = np.empty((2, total), np.float32), np.empty((2,) + zq.shape, np.float32)
    fixed32 = AlphaBetaFilter(design.alpha, design.beta, 0.1, float32_arithmetic=True)

    cases = {
        "fixed": lambda: design.run(z, out=out, threads=th),
        "irr_design": lambda: design.run(z, t=t, out=out, threads=th),
        "irr_fixed": lambda: fixed.run(z, t=t, out=out, threads=th),
        "irr_grid": lambda: design.run(z, t=t_grid, out=out, threads=th),
        "trk_no_t": lambda: design.run(z.reshape(-1), offsets=off_rect, out=out_flat, threads=th),
        "rect": lambda: design.run(zq, out=out_q, threads=th),
        "rag": lambda: design.run(zr, offsets=off, out=out_r, threads=th),
        "rect_t": lambda: design.run(zq, t=tq, out=out_q, threads=th),
        "rag_t": lambda: design.run(zr, t=tr, offsets=off, out=out_r, threads=th),
        "rag_t_fixed": lambda: fixed.run(zr, t=tr, offsets=off, out=out_r, threads=th),
        # a few long tracks (split into segments, docs/filtering.md)
        "long1": lambda: design.run(zr, out=out_r, threads=th),
        "long1_rag": lambda: design.run(zr, offsets=off1, out=out_r, threads=th),
        "long3_rag": lambda: design.run(zr, offsets=off3, out=out_r, threads=th),
        "long1_t": lambda: design.run(zr, t=tr, out=out_r, threads=th),
        "long1_t_fixed": lambda: fixed.run(zr, t=tr, out=out_r, threads=th),
        "long3_t": lambda: design.run(zr, t=tr, offsets=off3, out=out_r, threads=th),
        "rect32": lambda: fixed.run(zq32, out=out_q32, threads=th),
        "rag32": lambda: fixed.run(zr32, offsets=off, out=out_r32, threads=th),
        "rect32a": lambda: fixed32.run(zq32, out=out_q32, threads=th),
        "rag32a": lambda: fixed32.run(zr32, offsets=off, out=out_r32, threads=th),
    }
    # Round robin: every case once per round, best per case (load drifts
    # affect all cases alike).
    best_t = {k: float("inf") for k in cases}
    for fn in cases.values():
        fn()
    for _ in range(a.repeat):
        for k, fn in cases.items():
            t0 = clock()
            fn()
            best_t[k] = min(best_t[k], clock() - t0)
    t_fixed = best_t["fixed"]
    rows: List[Tuple[str, float]] = [
        ("fixed-T kernel, rectangular (run(z))", t_fixed),
        ("irregular t, design schedule (run(z, t=t))", best_t["irr_design"]),
        ("irregular t, fixed-gain schedule", best_t["irr_fixed"]),
        ("t on a whole-second grid (1 % missed), design schedule", best_t["irr_grid"]),
        ("track kernel without t (offsets = i*n_samples)", best_t["trk_no_t"]),
    ]
    t_rect, t_rag, t_rect_t, t_rag_t = (best_t[k] for k in ("rect", "rag", "rect_t", "rag_t"))

    print(f"abkit {abkit.__version__}, {platform.machine()}, numpy {np.__version__}, threads={th or 'pool'}, "
          f"best of {a.repeat}, {'CPU' if a.cpu else 'wall'} time")
    print()
    print(f"| Irregular timestamps ({n_tracks:,} x {n_samples:,}) | Msamples/s | vs fixed-T |")
    print("|---|---:|---:|")
    for name, tt in rows:
        print(f"| {name} | {N / tt / 1e6:.0f} | {t_fixed / tt:.2f} |")
    print()
    print(f"| Ragged ({len(lens):,} tracks, lengths 10..10,000, {total:,} samples) | Msamples/s | ratio |")
    print("|---|---:|---:|")
    print(f"| rectangular fixed-T kernel ({rect_tracks:,} x {total // rect_tracks:,}) | {total / t_rect / 1e6:.0f} | 1.00 |")
    print(f"| ragged, no t (offsets) | {total / t_rag / 1e6:.0f} | {t_rect / t_rag:.2f} |")
    print(f"| rectangular with t | {total / t_rect_t / 1e6:.0f} | 1.00 (t) |")
    print(f"| ragged with t | {total / t_rag_t / 1e6:.0f} | {t_rect_t / t_rag_t:.2f} (vs rectangular with t) |")
    print(f"| ragged with t, design schedule | {total / t_rag_t / 1e6:.0f} | {t_rect / t_rag_t:.2f} (vs rectangular fixed-T) |")
    t_rag_tf = best_t["rag_t_fixed"]
    print(f"| ragged with t, fixed-gain schedule | {total / t_rag_tf / 1e6:.0f} | {t_rect / t_rag_tf:.2f} (vs rectangular fixed-T) |")

    print()
    t_r32 = best_t["rect32"]
    print(f"| float32 ({total:,} samples), no t | Msamples/s | vs rectangular, default |")
    print("|---|---:|---:|")
    for name, k in (
        (f"rectangular ({rect_tracks:,} x {total // rect_tracks:,}), default (float64 arithmetic)", "rect32"),
        ("ragged (offsets), default", "rag32"),
        ("rectangular, float32_arithmetic=True", "rect32a"),
        ("ragged (offsets), float32_arithmetic=True", "rag32a"),
    ):
        print(f"| {name} | {total / best_t[k] / 1e6:.0f} | {t_r32 / best_t[k]:.2f} |")

    print()
    t_long = best_t["long1"]
    print(f"| A few long tracks ({total:,} samples) | Msamples/s | vs one track, fixed-T |")
    print("|---|---:|---:|")
    for name, k in (
        ("one track, fixed-T (run(z), split)", "long1"),
        ("one track, offsets (ragged, no t)", "long1_rag"),
        ("three tracks, offsets (no t)", "long3_rag"),
        ("one track with t, design schedule", "long1_t"),
        ("one track with t, fixed-gain schedule", "long1_t_fixed"),
        ("three tracks with t, design schedule", "long3_t"),
    ):
        print(f"| {name} | {total / best_t[k] / 1e6:.0f} | {t_long / best_t[k]:.2f} |")

if __name__ == "__main__":
    main()
