"""``abkit bench``: a small, self-contained version of ``bench/run.py``.

The same alpha-beta filter (``alpha = 0.5``, ``beta = 0.2``, ``T = 0.1``,
outputs position and velocity, started from the zero state so that every
implementation is the same LTI system) run by

* abkit (``AlphaBetaFilter.run`` into a preallocated ``out=``, rayon's pool
  and one thread),
* NumPy vectorised over tracks (a Python loop over samples),
* ``scipy.signal.lfilter`` (position and velocity transfer functions;
  skipped when scipy is not installed),
* a pure Python loop (on a subset of the tracks; its rate is per sample),

and the memory-bandwidth ceiling: one pass that reads ``z`` and writes the
same output bytes (``np.copyto`` twice). Every implementation's output is
checked against abkit's before it is timed. Times are the best of
``--repeat`` warm runs. The full benchmark (C, numba, criterion) is
``bench/run.py`` in the source tree; see ``docs/benchmarks.md``.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from typing import Any, Callable, List, Optional, Tuple

import numpy as np

from ._progress import Progress

__all__ = ["add_parser"]

ALPHA, BETA, T = 0.5, 0.2, 0.1


def _python_loop(z: List[float]) -> Tuple[List[float], List[float]]:
    g = BETA / T
    x = v = 0.0
    pos, vel = [], []
    for zk in z:
        xp = x + T * v
        e = zk - xp
        x = xp + ALPHA * e
        v = v + g * e
        pos.append(x)
        vel.append(v)
    return pos, vel


def _numpy_loop(z: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """Vectorised over tracks; works on the (samples, tracks) layout so each
    step is contiguous (the transposes are part of the cost)."""
    nt, ns = z.shape
    zt = np.ascontiguousarray(z.T)
    pt = np.empty((ns, nt), dtype=z.dtype)
    vt = np.empty((ns, nt), dtype=z.dtype)
    x = np.zeros(nt, dtype=z.dtype)
    v = np.zeros(nt, dtype=z.dtype)
    e = np.empty(nt, dtype=z.dtype)
    g = BETA / T
    for k in range(ns):
        x += T * v  # prediction x_p (v unchanged)
        np.subtract(zt[k], x, out=e)
        x += ALPHA * e
        v += g * e
        pt[k] = x
        vt[k] = v
    return pt.T, vt.T


def _lfilter_coeffs() -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    # X/Z = (a + (b - a) q^-1) / D,  V/Z = (b/T)(1 - q^-1) / D,
    # D = 1 + (a + b - 2) q^-1 + (1 - a) q^-2
    den = np.array([1.0, ALPHA + BETA - 2.0, 1.0 - ALPHA])
    return np.array([ALPHA, BETA - ALPHA]), np.array([BETA / T, -BETA / T]), den


def _rel(a: np.ndarray, ref: np.ndarray) -> float:
    a = np.asarray(a, dtype=np.float64)
    ref = np.asarray(ref, dtype=np.float64)
    scale = float(np.max(np.abs(ref))) or 1.0
    return float(np.max(np.abs(a - ref))) / scale


def _best(fn: Callable[[], Any], repeat: int) -> float:
    fn()
    best = math.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def _bench(a: argparse.Namespace) -> int:
    from . import __version__
    from .filters import AlphaBetaFilter

    nt, ns, repeat = a.tracks, a.samples, a.repeat
    dt = np.dtype(a.dtype)
    tol = 1e-9 if dt == np.float64 else 2e-3
    rng = np.random.default_rng(0)
    k = np.arange(ns)
    z = (100.0 * np.sin(0.01 * k + rng.uniform(0, 6.3, (nt, 1))) + rng.standard_normal((nt, ns))).astype(dt)
    n = nt * ns
    f = AlphaBetaFilter(ALPHA, BETA, T)
    zero = np.zeros(2)
    out = np.empty((2, nt, ns), dtype=dt)
    ref = f.run(z, init=zero, out=out)
    ref_pos, ref_vel = ref.position.copy(), ref.velocity.copy()
    try:
        import scipy
        import scipy.signal
    except ImportError:
        scipy = None  # type: ignore[assignment]
    py_tracks = max(1, min(nt, 50_000 // ns)) if ns <= 50_000 else 1
    py_samples = min(ns, 50_000)
    zl = [z[i, :py_samples].astype(np.float64).tolist() for i in range(py_tracks)]

    rows: List[Tuple[str, Optional[float], Optional[float], str]] = []  # name, time per sample, err, note

    def add(name: str, fn: Callable[[], Any], samples: int, err: Optional[float], note: str = "") -> None:
        if err is not None and not err <= tol:
            raise RuntimeError(f"abkit bench: {name} disagrees with abkit (relative difference {err:.3g})")
        rows.append((name, _best(fn, repeat) / samples, err, note))

    steps = 6 if scipy is not None else 5
    print(f"abkit bench: alpha-beta filter, {nt:,} tracks x {ns:,} samples, {dt.name}, best of {repeat} "
          f"(abkit {__version__}, numpy {np.__version__}"
          f"{', scipy ' + scipy.__version__ if scipy is not None else ', scipy not installed'}, {os.cpu_count()} CPUs)")
    with Progress(steps, "abkit bench") as bar:
        add("abkit, all cores (out=)", lambda: f.run(z, init=zero, out=out), n, 0.0)
        bar.update()
        add("abkit, 1 thread (out=)", lambda: f.run(z, init=zero, out=out, threads=1), n, 0.0)
        bar.update()
        p2, v2 = np.empty_like(z), np.empty_like(z)

        workers = max(1, min(os.cpu_count() or 1, nt))
        blocks = [slice(i * nt // workers, (i + 1) * nt // workers) for i in range(workers)]
        pool = ThreadPoolExecutor(workers)

        def copy_block(b: slice) -> None:
            # one pass over the block: z read once (cache-sized pieces), two outputs written
            for r in range(b.start, b.stop, 16):
                rr = slice(r, min(r + 16, b.stop))
                np.copyto(p2[rr], z[rr])
                np.copyto(v2[rr], z[rr])

        def ceiling() -> None:
            list(pool.map(copy_block, blocks))

        add("ceiling: read z, write 2 outputs", ceiling, n, None, f"NumPy copy, {workers} threads")
        pool.shutdown()
        bar.update()
        pn, vn = _numpy_loop(z)
        add("NumPy vectorised over tracks", lambda: _numpy_loop(z), n, max(_rel(pn, ref_pos), _rel(vn, ref_vel)))
        bar.update()
        if scipy is not None:
            bx, bv, den = _lfilter_coeffs()

            def lf() -> Tuple[np.ndarray, np.ndarray]:
                return scipy.signal.lfilter(bx, den, z, axis=-1), scipy.signal.lfilter(bv, den, z, axis=-1)

            lp, lv = lf()
            add("scipy.signal.lfilter (x2)", lf, n, max(_rel(lp, ref_pos), _rel(lv, ref_vel)))
            bar.update()
        pp, pv = _python_loop(zl[0])
        err = max(_rel(np.array(pp), ref_pos[0, :py_samples]), _rel(np.array(pv), ref_vel[0, :py_samples]))
        add("pure Python loop", lambda: [_python_loop(t) for t in zl], py_tracks * py_samples, err,
            f"on {py_tracks * py_samples:,} samples")
        bar.update()
    if scipy is None:
        rows.append(("scipy.signal.lfilter (x2)", None, None, "scipy not installed"))

    t_ab = rows[0][1]
    assert t_ab is not None
    t_ceiling = rows[2][1]
    assert t_ceiling is not None
    print(f"{'method':<34}{'M samples/s':>13}{'time / abkit':>14}{'max rel diff':>14}  note")
    for name, tm, diff, note in rows:
        if tm is None:
            print(f"{name:<34}{'-':>13}{'-':>14}{'-':>14}  {note}")
            continue
        e = "-" if diff is None else f"{diff:.1e}"
        print(f"{name:<34}{1e-6 / tm:>13.4g}{tm / t_ab:>13.3g}x{e:>14}  {note}")
    print(f"abkit runs at {t_ceiling / t_ab:.0%} of the memory-bandwidth ceiling (a copy pass moving the same bytes"
          f"{'; above 100%: this NumPy copy is not a tuned ceiling, see bench/run.py' if t_ceiling > t_ab else ''}).")
    print("Ratios are from this run on this machine; the full cross-language benchmark (C, numba, Rust) "
          "is bench/run.py in the source tree (docs/benchmarks.md).")
    return 0


def add_parser(sub: Any, positive_int: Any) -> argparse.ArgumentParser:
    """Register ``abkit bench`` on the CLI's subparsers."""
    b = sub.add_parser(
        "bench",
        help="benchmark abkit's alpha-beta filter against NumPy, scipy.signal.lfilter and pure Python",
        description="Run the same alpha-beta filter with abkit, a NumPy loop vectorised over tracks, "
        "scipy.signal.lfilter (if installed) and pure Python (on a subset), plus a memory-bandwidth "
        "ceiling pass; check every output against abkit's; print samples/s and the ratios. A few "
        "seconds at the default size.",
    )
    b.add_argument("--tracks", type=positive_int, default=2000, help="number of tracks (default 2000)")
    b.add_argument("--samples", type=positive_int, default=2000, help="samples per track (default 2000)")
    b.add_argument("--repeat", type=positive_int, default=3, help="timed runs per method, best kept (default 3)")
    b.add_argument("--dtype", choices=("float64", "float32"), default="float64", help="data type (default float64)")
    b.set_defaults(func=_bench)
    return b
