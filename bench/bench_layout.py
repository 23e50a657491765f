#!/usr/bin/env python3
"""How the output layout moves the alpha-beta kernel's speed (issue 3).

``run(z, out=out)`` writes position and velocity into one ``(2, n_tracks,
n_samples)`` array, so the velocity plane starts ``n_tracks * n_samples``
elements after the position plane: on a 64-byte line boundary of its own
only when that count is a multiple of 8 (``float64``) or 16 (``float32``),
as in ``bench/run.py``'s shapes. Here shapes of about 10^7 samples whose
velocity plane lies 0-7 (``float64``) elements off the position plane's
lines, and for each, in the same round-robin run (one thread, ``out=``
reused, minimum of ``--repeat`` rounds):

* abkit ``AlphaBetaFilter.run`` and ``AlphaBetaGammaFilter.run`` (3 outputs)
  into a C-contiguous ``out=`` (``np.empty``) and into ``out=`` in the
  padded plane layout of the fresh results (``abkit.empty_states``: every
  plane on the position plane's line phase), and the general 3-state
  kernel (``FixedGainFilter``, the alpha-beta-gamma filter's matrices) in
  both layouts;
* ``copy2nt``: ``bench/run.py``'s non-temporal copy pass (z to two outputs),
  which streams only when both outputs are mutually line-aligned (else
  ordinary stores, as abkit's row lanes);
* ``copy2ntx``: the same bytes, each output streamed from its own first line
  boundary: the ceiling for any layout.

Prints a markdown table: ns per sample and abkit's fraction of ``copy2ntx``
(C-contiguous and padded ``out=``).

    python bench/bench_layout.py [--repeat 7] [--only f64|f32]
"""

from __future__ import annotations

import argparse
import ctypes
import os
import sys
import time

import numpy as np

import abkit

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from run import build_c, make_z, ptr  # noqa: E402

SHAPES = [
    (1000, 10000),
    (999, 10001),
    (999, 10002),
    (1001, 10010),
    (999, 10004),
    (1000, 10001),
    (100_000, 100),
    (99_999, 101),
]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--only", choices=["f64", "f32"])
    args = ap.parse_args()
    lib = build_c()
    P, N = ctypes.c_void_p, ctypes.c_ssize_t
    for name in ("copy2ntx_f64", "copy2ntx_f32"):
        getattr(lib, name).argtypes = [P, P, P, N]
        getattr(lib, name).restype = ctypes.c_int
    ab = abkit.AlphaBetaFilter(0.5, 0.2, 0.1)
    abg = abkit.AlphaBetaGammaFilter(0.5, 0.4, 0.1, 0.1)
    g3 = abkit.FixedGainFilter(abg.Phi, abg.H, abg.K)
    dts = [np.float64, np.float32] if not args.only else [np.float64 if args.only == "f64" else np.float32]
    print(
        "| dtype | tracks x samples | v plane off x's lines (elements) | copy2nt | copy2ntx "
        "| alpha-beta, C out | padded out | abkit / copy2ntx, C / padded "
        "| alpha-beta-gamma, C out | padded out | general 3-state, C out | padded out |"
    )
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for dt in dts:
        s = "f64" if dt == np.float64 else "f32"
        for nt, ns in SHAPES:
            n = nt * ns
            z = make_z(nt, ns, dt)
            out = np.empty((2, nt, ns), dtype=dt)
            o3 = np.empty((3, nt, ns), dtype=dt)
            out_p = abkit.empty_states((2, nt, ns), dt)
            o3_p = abkit.empty_states((3, nt, ns), dt)
            cp = np.empty((2, nt, ns), dtype=dt)
            zp, c0, c1 = ptr(z), ptr(cp[0]), ptr(cp[1])
            per_line = 64 // z.itemsize
            off = (ptr(out[1]) - ptr(out[0])) // z.itemsize % per_line
            copy2nt = getattr(lib, f"copy2nt_{s}")
            copy2ntx = getattr(lib, f"copy2ntx_{s}")
            for f in (copy2nt, copy2ntx):
                cp.fill(0)
                f(zp, c0, c1, n)
                if not (np.array_equal(cp[0], z) and np.array_equal(cp[1], z)):
                    raise AssertionError(f"{f.__name__} is wrong")
            ref = ab.run(z, return_residuals=True).states
            if not np.array_equal(ab.run(z, out=out, threads=1).states, ref, equal_nan=True):
                raise AssertionError("abkit differs from its scalar path")
            if not np.array_equal(ab.run(z, out=out_p, threads=1).states, ref, equal_nan=True):
                raise AssertionError("abkit's padded layout differs")
            cases = [
                ("ab", lambda: ab.run(z, out=out, threads=1)),
                ("nt", lambda: copy2nt(zp, c0, c1, n)),
                ("ntx", lambda: copy2ntx(zp, c0, c1, n)),
                ("ab_p", lambda: ab.run(z, out=out_p, threads=1)),
                ("abg", lambda: abg.run(z, out=o3, threads=1)),
                ("abg_p", lambda: abg.run(z, out=o3_p, threads=1)),
                ("g3", lambda: g3.run(z, out=o3, threads=1)),
                ("g3_p", lambda: g3.run(z, out=o3_p, threads=1)),
            ]
            best = {k: float("inf") for k, _ in cases}
            for k, f in cases:
                f()
            for _ in range(args.repeat):
                for k, f in cases:
                    t0 = time.perf_counter()
                    f()
                    best[k] = min(best[k], time.perf_counter() - t0)
            ns_ = {k: v / n * 1e9 for k, v in best.items()}
            print(
                f"| {s} | {nt:,} x {ns:,} | {off} | {ns_['nt']:.3f} | {ns_['ntx']:.3f} "
                f"| {ns_['ab']:.3f} | {ns_['ab_p']:.3f} | {ns_['ntx'] / ns_['ab']:.2f} / {ns_['ntx'] / ns_['ab_p']:.2f} "
                f"| {ns_['abg']:.3f} | {ns_['abg_p']:.3f} | {ns_['g3']:.3f} | {ns_['g3_p']:.3f} |",
                flush=True,
            )
            del z, out, o3, cp, out_p, o3_p


if __name__ == "__main__":
    main()
