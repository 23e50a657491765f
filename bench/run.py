#!/usr/bin/env python3
"""Cross-language benchmark of abkit's alpha-beta filter (issue 3, "Performance").

The same alpha-beta filter (two-point start, position + velocity outputs,
NaN-free input) in pure Python, NumPy vectorised over tracks,
``scipy.signal.lfilter``, numba (``@njit`` default and
``fastmath={'contract'}``), plain C (``gcc -O3 -march=native``, via ctypes),
the pure-Rust kernel (criterion, ``rust/abkit-core/benches/filter.rs``) and
abkit from Python; plus the memory-bandwidth ceiling (a pass that reads ``z``
once and writes the same output bytes). Every implementation's output is
checked against abkit's before it is timed.

Usage::

    python bench/run.py --quick          # small sizes, < 30 s, no criterion
    python bench/run.py                  # full run (~5-10 min, with criterion)
    python bench/run.py --json out.json  # also dump every number

See bench/README.md and docs/benchmarks.md.
"""

from __future__ import annotations

import argparse
import ctypes
import functools
import json
import math
import os
import platform
import re
import shutil
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from typing import Any, Callable, Dict, List, Optional, Tuple

import numpy as np
import scipy
import scipy.signal

import abkit

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)

# The filter (the same constants as rust/abkit-core/benches/filter.rs).
ALPHA, BETA, T = 0.5, 0.2, 0.1
ABG = (0.5, 0.4, 0.1)  # alpha-beta-gamma gains (standard convention)

try:
    import numba
    from numba import njit

    HAVE_NUMBA = True
except Exception:  # pragma: no cover - reported in the output
    HAVE_NUMBA = False

# -----------------------------------------------------------------------------
# helpers


def log(*a: object) -> None:
    print(*a, file=sys.stderr, flush=True)


def timeit(fn: Callable[[], object], repeat: int) -> Tuple[float, float]:
    """(min, median) wall time of ``fn`` over ``repeat`` warm runs (one
    untimed warm-up run first)."""
    fn()
    ts = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t0)
    ts.sort()
    return ts[0], ts[len(ts) // 2]


def rel_err(a: np.ndarray, ref: np.ndarray) -> float:
    """max |a - ref| / max |ref| over finite entries; inf if the NaN
    patterns differ."""
    a = np.asarray(a, dtype=np.float64)
    ref = np.asarray(ref, dtype=np.float64)
    if a.shape != ref.shape:
        return math.inf
    na, nr = np.isnan(a), np.isnan(ref)
    if not np.array_equal(na, nr):
        return math.inf
    m = ~nr
    if not m.any():
        return 0.0
    scale = float(np.max(np.abs(ref[m])))
    return float(np.max(np.abs(a[m] - ref[m]))) / (scale if scale > 0 else 1.0)


def make_z(nt: int, ns: int, dtype: Any, seed: int = 1) -> np.ndarray:
    """Manoeuvring targets (bounded sine trajectories) plus unit noise."""
    rng = np.random.default_rng(seed)
    z = np.empty((nt, ns), dtype=dtype)
    k = np.arange(ns, dtype=np.float64)
    step = max(1, 1_000_000 // ns)  # fill in blocks of tracks (bounded temporaries)
    for i0 in range(0, nt, step):
        i1 = min(nt, i0 + step)
        ph = rng.uniform(0, 2 * np.pi, size=(i1 - i0, 1))
        w = rng.uniform(0.002, 0.02, size=(i1 - i0, 1))
        z[i0:i1] = 100.0 * np.sin(w * k + ph) + rng.standard_normal((i1 - i0, ns))
    return z


def machine_info() -> Dict[str, str]:
    info = {"python": sys.version.split()[0], "numpy": np.__version__, "scipy": scipy.__version__,
            "numba": numba.__version__ if HAVE_NUMBA else "not installed",
            "abkit": getattr(abkit, "__version__", "?"), "platform": platform.platform()}
    try:
        ls = subprocess.run(["lscpu"], capture_output=True, text=True, check=True).stdout
        for line in ls.splitlines():
            key, _, val = line.partition(":")
            if key.strip() in ("Model name", "CPU(s)", "Core(s) per socket", "Socket(s)", "Thread(s) per core",
                               "L2 cache", "L3 cache", "Hypervisor vendor"):
                info[key.strip()] = val.strip()
    except Exception:
        pass
    try:
        with open("/proc/meminfo") as fh:
            info["MemTotal"] = fh.readline().split(":")[1].strip()
    except Exception:
        pass
    try:
        info["gcc"] = subprocess.run(["gcc", "--version"], capture_output=True, text=True).stdout.splitlines()[0]
        info["rustc"] = subprocess.run(["rustc", "--version"], capture_output=True, text=True).stdout.strip()
    except Exception:
        pass
    try:
        head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no", "rust", "python"], cwd=ROOT,
                               capture_output=True, text=True).stdout.strip()
        info["abkit source"] = f"git {head}{' + uncommitted changes in rust/ or python/' if dirty else ''}"
        so = abkit._abkit.__file__
        info["installed _abkit built"] = time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime(os.path.getmtime(so)))
    except Exception:
        pass
    info["load average (start)"] = " ".join(f"{x:.2f}" for x in os.getloadavg())
    return info


# -----------------------------------------------------------------------------
# C kernels


def build_c() -> ctypes.CDLL:
    out_dir = tempfile.mkdtemp(prefix="abkit-bench-")
    so = os.path.join(out_dir, "libab.so")
    cmd = ["gcc", "-O3", "-march=native", "-shared", "-fPIC", "-o", so, os.path.join(HERE, "ab.c"), "-lm"]
    subprocess.run(cmd, check=True)
    lib = ctypes.CDLL(so)  # CDLL: the GIL is released during calls
    P, N, D = ctypes.c_void_p, ctypes.c_ssize_t, ctypes.c_double
    for name in ("ab_f64", "ab_f32", "ab_f64_x8", "ab_f32_x8"):
        getattr(lib, name).argtypes = [P, P, P, N, N, D, D, D]
        getattr(lib, name).restype = None
    for name in ("copy2_f64", "copy2_f32", "copy2seg_f64", "copy2seg_f32"):
        getattr(lib, name).argtypes = [P, P, P, N]
        getattr(lib, name).restype = None
    for name in ("copy3_f64", "copy3_f32", "copy3seg_f64", "copy3seg_f32"):
        getattr(lib, name).argtypes = [P, P, P, P, N]
        getattr(lib, name).restype = None
    for name in ("copy2nt_f64", "copy2nt_f32"):  # return 1 if streaming stores were used
        getattr(lib, name).argtypes = [P, P, P, N]
        getattr(lib, name).restype = ctypes.c_int
    for name in ("copy3nt_f64", "copy3nt_f32"):
        getattr(lib, name).argtypes = [P, P, P, P, N]
        getattr(lib, name).restype = ctypes.c_int
    lib.nt_available.restype = ctypes.c_int
    lib.touch_pages.argtypes = [P, N]
    lib.touch_pages.restype = None
    return lib


def ptr(a: np.ndarray) -> int:
    return a.ctypes.data


def sfx(dtype: Any) -> str:
    return "f64" if np.dtype(dtype) == np.float64 else "f32"


# -----------------------------------------------------------------------------
# pure Python and NumPy


def ab_python(z: List[float], alpha: float, beta: float, t: float) -> Tuple[List[float], List[float]]:
    g = beta / t
    pos = [z[0], z[1]]
    vel = [math.nan, (z[1] - z[0]) / t]
    x, v = z[1], (z[1] - z[0]) / t
    for zk in z[2:]:
        xp = x + t * v
        e = zk - xp
        x = xp + alpha * e
        v = v + g * e
        pos.append(x)
        vel.append(v)
    return pos, vel


def ab_numpy(z: np.ndarray, pos: np.ndarray, vel: np.ndarray, alpha: float, beta: float, t: float) -> None:
    """Vectorised over tracks, a Python loop over samples. Works on the
    transposed (samples, tracks) layout so that each step touches contiguous
    memory; the transposes are part of the cost."""
    nt, ns = z.shape
    g = beta / t
    zt = np.ascontiguousarray(z.T, dtype=np.float64)
    pt = np.empty((ns, nt))
    vt = np.empty((ns, nt))
    pt[0] = zt[0]
    vt[0] = np.nan
    x = zt[1].copy()
    v = (zt[1] - zt[0]) / t
    pt[1] = x
    vt[1] = v
    xp = np.empty(nt)
    e = np.empty(nt)
    for k in range(2, ns):
        np.multiply(v, t, out=xp)
        xp += x
        np.subtract(zt[k], xp, out=e)
        np.multiply(e, alpha, out=x)
        x += xp
        v += g * e
        pt[k] = x
        vt[k] = v
    pos[...] = pt.T
    vel[...] = vt.T


# -----------------------------------------------------------------------------
# scipy.signal.lfilter
#
# With s = [x, v] the filtered state, the filter is s_k = A s_{k-1} + B z_k,
# A = [[1-a, (1-a) T], [-b/T, 1-b]], B = [a, b/T]: an LTI system with
#   X(q)/Z(q) = (a + (b - a) q^-1) / (1 - (2 - a - b) q^-1 + (1 - a) q^-2)
#   V(q)/Z(q) = (b/T) (1 - q^-1)   / (same denominator).
# The two-point start fixes s_1 = [z1, (z1 - z0)/T]; lfilter runs from sample
# 2 on with the direct-form-II-transposed initial conditions that reproduce
# the recursion from s_1 (a fictitious s_0 = A^-1 (s_1 - B z_1) supplies the
# second past output), so every output sample matches, not only the steady
# part.


def lfilter_coeffs(alpha: float, beta: float, t: float):
    den = np.array([1.0, -(2.0 - alpha - beta), 1.0 - alpha])
    bx = np.array([alpha, beta - alpha])
    bv = np.array([beta / t, -beta / t])
    return den, bx, bv


def lfilter_zi(z: np.ndarray, alpha: float, beta: float, t: float):
    den, bx, bv = lfilter_coeffs(alpha, beta, t)
    z0 = z[:, 0].astype(np.float64)
    z1 = z[:, 1].astype(np.float64)
    x1, v1 = z1, (z1 - z0) / t
    # s0 = A^-1 (s1 - B z1), det A = 1 - a
    r0, r1 = x1 - alpha * z1, v1 - beta / t * z1
    x0 = ((1 - beta) * r0 - (1 - alpha) * t * r1) / (1 - alpha)
    v0 = (beta / t * r0 + (1 - alpha) * r1) / (1 - alpha)
    a1, a2 = den[1], den[2]
    zix = np.stack([bx[1] * z1 - a1 * x1 - a2 * x0, -a2 * x1], axis=-1)
    ziv = np.stack([bv[1] * z1 - a1 * v1 - a2 * v0, -a2 * v1], axis=-1)
    return den, bx, bv, zix, ziv


# -----------------------------------------------------------------------------
# numba

if HAVE_NUMBA:

    def _ab_loop(z, pos, vel, alpha, beta, t):  # pragma: no cover - compiled
        nt, ns = z.shape
        g = beta / t
        for i in range(nt):
            pos[i, 0] = z[i, 0]
            vel[i, 0] = np.nan
            if ns < 2:
                continue
            x = np.float64(z[i, 1])
            v = (np.float64(z[i, 1]) - np.float64(z[i, 0])) / t
            pos[i, 1] = x
            vel[i, 1] = v
            for k in range(2, ns):
                xp = x + t * v
                e = np.float64(z[i, k]) - xp
                x = xp + alpha * e
                v = v + g * e
                pos[i, k] = x
                vel[i, k] = v

    ab_numba = njit(_ab_loop)
    ab_numba_contract = njit(fastmath={"contract"})(_ab_loop)

    @njit
    def fg3_ref(z, phi, kg, t, out):  # pragma: no cover - compiled
        """Reference for 3-state filters, H = [1, 0, 0], two-point start."""
        nt, ns = z.shape
        for i in range(nt):
            out[0, i, 0] = z[i, 0]
            out[1, i, 0] = np.nan
            out[2, i, 0] = np.nan
            x = np.zeros(3)
            x[0] = z[i, 1]
            x[1] = (np.float64(z[i, 1]) - np.float64(z[i, 0])) / t
            for c in range(3):
                out[c, i, 1] = x[c]
            xp = np.zeros(3)
            for k in range(2, ns):
                for r in range(3):
                    xp[r] = phi[r, 0] * x[0] + phi[r, 1] * x[1] + phi[r, 2] * x[2]
                e = np.float64(z[i, k]) - xp[0]
                for r in range(3):
                    x[r] = xp[r] + kg[r] * e
                    out[r, i, k] = x[r]


# -----------------------------------------------------------------------------
# Rust (criterion)

_UNIT = {"ps": 1e-12, "ns": 1e-9, "µs": 1e-6, "us": 1e-6, "ms": 1e-3, "s": 1.0}


def run_criterion(scale: int) -> Dict[str, Tuple[float, float, float, float]]:
    """Run the criterion bench; {name: (lo, estimate, hi, fastest iteration)}
    in seconds per iteration (lo/estimate/hi: criterion's interval of the
    mean; fastest: the bench's own `min-iteration` line, NaN if absent)."""
    if shutil.which("cargo") is None:
        log("cargo not found: skipping the criterion bench")
        return {}
    env = dict(os.environ, CARGO_TERM_COLOR="never", ABKIT_BENCH_SCALE=str(scale))
    log("building + running the criterion bench (cargo bench -p abkit-core --bench filter) ...")
    p = subprocess.run(["cargo", "bench", "-p", "abkit-core", "--bench", "filter", "--", "--noplot"],
                       cwd=ROOT, env=env, capture_output=True, text=True)
    if p.returncode != 0:
        log(p.stderr[-3000:])
        log("criterion bench failed: skipping")
        return {}
    res: Dict[str, Tuple[float, float, float, float]] = {}
    mins: Dict[str, float] = {}
    name: Optional[str] = None
    for line in p.stdout.splitlines():
        m = re.match(r"^min-iteration (\S+): ([\d.eE+-]+) s", line)
        if m:
            mins[m.group(1)] = float(m.group(2))
            continue
        m = re.match(r"^(\S+/\S+)", line)
        if m and not line.startswith(" "):
            name = m.group(1)
        m = re.search(r"time:\s*\[([\d.]+) (\S+) ([\d.]+) (\S+) ([\d.]+) (\S+)\]", line)
        if m and name:
            vals = [float(m.group(i)) * _UNIT[m.group(i + 1)] for i in (1, 3, 5)]
            res[name] = (vals[0], vals[1], vals[2], math.nan)
            name = None
    for k, v in res.items():
        res[k] = (v[0], v[1], v[2], mins.get(k, math.nan))
    return res


# -----------------------------------------------------------------------------
# the benchmark


class Bench:
    def __init__(self, quick: bool, repeat: int, lib: ctypes.CDLL):
        self.quick = quick
        self.repeat = repeat
        self.lib = lib
        self.rows: List[dict] = []
        self.failures: List[str] = []
        self.current = ""
        self.ab = abkit.AlphaBetaFilter(ALPHA, BETA, T)
        self.abg = abkit.AlphaBetaGammaFilter(*ABG, T)
        # a general 3-state filter (Singer-like: decaying acceleration)
        rho = 0.9
        self.phi3 = np.array([[1.0, T, T * T / 2], [0.0, 1.0, T], [0.0, 0.0, rho]])
        self.k3 = np.array([0.5, 0.4 / T, 0.1 / (T * T)])
        self.gen3 = abkit.FixedGainFilter(self.phi3, [[1.0, 0.0, 0.0]], self.k3[:, None], T)
        self.gen2 = abkit.FixedGainFilter([[1.0, T], [0.0, 1.0]], [[1.0, 0.0]], [[ALPHA], [BETA / T]], T)

    def record(self, wl: str, dtype: Any, method: str, n: int, t: Tuple[float, float], err: Optional[float],
               note: str = "", kind: str = "ab") -> None:
        row = dict(workload=wl, dtype=sfx(dtype), method=method, kind=kind, samples=n, t_min=t[0], t_med=t[1],
                   rate=n / t[0], err=err, note=note)
        self.rows.append(row)
        log(f"  {wl:>16} {sfx(dtype)} {method:<34} {n / t[0] / 1e6:9.1f} Msamples/s"
            f"  (min {t[0] * 1e3:8.2f} ms, median {t[1] * 1e3:8.2f} ms)  err {err if err is not None else '-'}")

    def check(self, name: str, got: Tuple[np.ndarray, ...], ref: Tuple[np.ndarray, ...], tol: float) -> float:
        """Max relative deviation; a failure is logged and listed in the
        report (the run goes on, the row is still timed)."""
        err = max(rel_err(g, r) for g, r in zip(got, ref))
        if not err <= tol:
            log(f"CHECK FAILED: {name}: relative error {err:.3g} > {tol:g} against abkit")
            self.failures.append(f"{self.current}: {name}: relative error {err:.3g} > tolerance {tol:g}")
        return err

    def workload(self, nt: int, ns: int, dtype: Any) -> None:
        """Check every implementation on one workload, then time them all
        round-robin (each round runs every case once, so a burst of load
        from elsewhere hits all of them alike; min over the rounds)."""
        lib, R = self.lib, self.repeat
        dt = np.dtype(dtype)
        s = sfx(dt)
        wl = f"{nt:,} x {ns:,}"
        n = nt * ns
        tol = 1e-9 if dt == np.float64 else 1e-6
        log(f"workload {wl} {s}")
        self.current = f"{wl} {s}"
        z = make_z(nt, ns, dt)
        zp = ptr(z)
        cases: List[Tuple[str, str, Callable[[], object], Optional[float], str]] = []

        def add(method: str, kind: str, fn: Callable[[], object], err: Optional[float], note: str = "") -> None:
            cases.append((method, kind, fn, err, note))

        # abkit reference output (threads=1, out= reused)
        ab = self.ab
        out = np.empty((2, nt, ns), dtype=dt)
        ab.run(z, out=out, threads=1)
        ref = (out[0].copy(), out[1].copy())

        # -- bandwidth ceiling: read z once, write the 2 output arrays -----
        copy2 = getattr(lib, f"copy2_{s}")
        copy3 = getattr(lib, f"copy3_{s}")
        o = np.empty((2, nt, ns), dtype=dt)
        o.fill(0)
        p0, p1 = ptr(o[0]), ptr(o[1])
        copy2(zp, p0, p1, n)
        if not (np.array_equal(o[0], z) and np.array_equal(o[1], z)):
            raise AssertionError("copy pass is wrong")
        add("ceiling: C copy (z -> pos, vel)", "ceiling2", lambda: copy2(zp, p0, p1, n), None)
        def copyto2() -> None:
            np.copyto(o[0], z)
            np.copyto(o[1], z)

        add("ceiling: np.copyto(pos, z); np.copyto(vel, z)", "ceiling2", copyto2, None)
        add("ceiling: np.multiply(z, 1.0, out=...) x2", "ceiling2",
            lambda: (np.multiply(z, 1.0, out=o[0]), np.multiply(z, 1.0, out=o[1])), None)
        copy2seg = getattr(lib, f"copy2seg_{s}")
        o.fill(0)
        copy2seg(zp, p0, p1, n)
        if not (np.array_equal(o[0], z) and np.array_equal(o[1], z)):
            raise AssertionError("segmented copy pass is wrong")
        add("ceiling: C copy, 8 segments interleaved", "ceiling2", lambda: copy2seg(zp, p0, p1, n), None)
        copy2nt = getattr(lib, f"copy2nt_{s}")
        o.fill(0)
        used = copy2nt(zp, p0, p1, n)
        if not (np.array_equal(o[0], z) and np.array_equal(o[1], z)):
            raise AssertionError("non-temporal copy pass is wrong")
        add("ceiling: C copy, non-temporal stores", "ceiling2_nt", lambda: copy2nt(zp, p0, p1, n), None,
            "" if used else "streaming stores NOT used (alignment/ISA): plain stores")
        # 2 threads (ctypes releases the GIL): each thread copies half
        half = n // 2
        pool = ThreadPoolExecutor(2)
        isz = dt.itemsize

        def copy2_2t() -> None:
            f1 = pool.submit(copy2, zp, p0, p1, half)
            f2 = pool.submit(copy2, zp + half * isz, p0 + half * isz, p1 + half * isz, n - half)
            f1.result()
            f2.result()

        add("ceiling: C copy, 2 threads", "ceiling2_2t", copy2_2t, None)

        def copy2nt_2t() -> None:
            f1 = pool.submit(copy2nt, zp, p0, p1, half)
            f2 = pool.submit(copy2nt, zp + half * isz, p0 + half * isz, p1 + half * isz, n - half)
            f1.result()
            f2.result()

        add("ceiling: C copy, non-temporal, 2 threads", "ceiling2_nt_2t", copy2nt_2t, None)

        # fresh (unfaulted) outputs: allocation + page faults + copy pass
        def fresh_copy() -> None:
            f = np.empty((2, nt, ns), dtype=dt)
            copy2(zp, ptr(f[0]), ptr(f[1]), n)

        add("ceiling: np.empty + C copy (fresh outputs)", "fresh_copy", fresh_copy, None)

        # allocation alone: np.empty + one write per 4 KiB page (the page faults)
        def fresh_alloc() -> None:
            f = np.empty((2, nt, ns), dtype=dt)
            lib.touch_pages(ptr(f), f.nbytes)

        add("allocation alone: np.empty + C page touch (fresh outputs)", "fresh_alloc", fresh_alloc, None)
        # 3-output ceiling (alpha-beta-gamma / 3-state)
        o3c = np.empty((3, nt, ns), dtype=dt)
        o3c.fill(0)
        q0, q1, q2 = ptr(o3c[0]), ptr(o3c[1]), ptr(o3c[2])
        add("ceiling3: C copy (z -> 3 outputs)", "ceiling3", lambda: copy3(zp, q0, q1, q2, n), None)
        copy3seg = getattr(lib, f"copy3seg_{s}")
        o3c.fill(0)
        copy3seg(zp, q0, q1, q2, n)
        if not all(np.array_equal(o3c[j], z) for j in range(3)):
            raise AssertionError("segmented copy3 pass is wrong")
        add("ceiling3: C copy, 8 segments interleaved", "ceiling3", lambda: copy3seg(zp, q0, q1, q2, n), None)

        def copyto3() -> None:
            for j in range(3):
                np.copyto(o3c[j], z)

        add("ceiling3: np.copyto x3", "ceiling3", copyto3, None)
        copy3nt = getattr(lib, f"copy3nt_{s}")
        o3c.fill(0)
        used = copy3nt(zp, q0, q1, q2, n)
        if not all(np.array_equal(o3c[j], z) for j in range(3)):
            raise AssertionError("non-temporal copy3 pass is wrong")
        add("ceiling3: C copy, non-temporal stores", "ceiling3_nt", lambda: copy3nt(zp, q0, q1, q2, n), None,
            "" if used else "streaming stores NOT used (alignment/ISA): plain stores")

        # -- abkit ---------------------------------------------------------------
        add("abkit threads=1, out= reused", "abkit1", lambda: ab.run(z, out=out, threads=1), 0.0)
        out2 = np.empty_like(out)
        r2 = ab.run(z, out=out2, threads=2)
        e2 = self.check("abkit threads=2 vs threads=1", (r2.position, r2.velocity), ref, 1e-12)
        del r2
        add("abkit threads=2, out= reused", "abkit2", lambda: ab.run(z, out=out2, threads=2), e2)
        r = ab.run(z, threads=1)
        e = self.check("abkit without out= vs with", (r.position, r.velocity), ref, 1e-12)
        del r
        add("abkit threads=1, no out= (fresh)", "abkit1_fresh", lambda: ab.run(z, threads=1), e)
        add("abkit threads=None (pool), no out=", "abkit_default", lambda: ab.run(z), e)
        if dt == np.float32:
            # the opt-in float32 arithmetic (docs/filtering.md): within its
            # documented drift, 2 (1 + 1/alpha) float32 eps of the scale
            ab32 = abkit.AlphaBetaFilter(ALPHA, BETA, T, float32_arithmetic=True)
            o32 = np.empty_like(out)
            ab32.run(z, out=o32, threads=1)
            # (velocities against the position scale / T, as in the tests:
            # a position error enters the velocity through beta / T)
            tol32 = 2.0 * (1.0 + 1.0 / ALPHA) * float(np.finfo(np.float32).eps)
            vscale = float(np.nanmax(np.abs(ref[1].astype(np.float64))))
            pscale = float(np.nanmax(np.abs(ref[0].astype(np.float64)))) / T
            e = max(self.check("abkit float32_arithmetic=True, position", (o32[0],), (ref[0],), tol32),
                    self.check("abkit float32_arithmetic=True, velocity", (o32[1],), (ref[1],),
                               tol32 * max(1.0, pscale / max(vscale, 1e-300))))
            add("abkit float32_arithmetic=True, threads=1, out=", "abkit1_f32a",
                lambda: ab32.run(z, out=o32, threads=1), e)
        og2 = np.empty((2, nt, ns), dtype=dt)
        self.gen2.run(z, out=og2, threads=1)
        e = self.check("abkit FixedGainFilter 2-state", (og2[0], og2[1]), ref, tol)
        add("abkit general kernel, 2-state (diag.)", "abkit_gen2", lambda: self.gen2.run(z, out=og2, threads=1), e)

        # -- C ---------------------------------------------------------------
        cab = getattr(lib, f"ab_{s}")
        cab8 = getattr(lib, f"ab_{s}_x8")
        oc = np.empty((2, nt, ns), dtype=dt)
        c0, c1 = ptr(oc[0]), ptr(oc[1])
        cab(zp, c0, c1, nt, ns, ALPHA, BETA, T)
        e = self.check("C", (oc[0], oc[1]), ref, tol)
        add("C gcc -O3 -march=native", "c", lambda: cab(zp, c0, c1, nt, ns, ALPHA, BETA, T), e)
        oc.fill(0)
        cab8(zp, c0, c1, nt, ns, ALPHA, BETA, T)
        e = self.check("C x8", (oc[0], oc[1]), ref, tol)
        add("C, 8 tracks interleaved (diag.)", "c_x8", lambda: cab8(zp, c0, c1, nt, ns, ALPHA, BETA, T), e)

        # -- numba -----------------------------------------------------------
        if HAVE_NUMBA:
            for name, fn, kind in (("numba @njit", ab_numba, "numba"),
                                   ("numba @njit fastmath={'contract'}", ab_numba_contract, "numba_contract")):
                oc.fill(0)
                fn(z, oc[0], oc[1], ALPHA, BETA, T)
                e = self.check(name, (oc[0], oc[1]), ref, tol)
                add(name, kind, functools.partial(fn, z, oc[0], oc[1], ALPHA, BETA, T), e)

        # -- scipy.signal.lfilter ---------------------------------------------
        den, bx, bv, zix, ziv = lfilter_zi(z, ALPHA, BETA, T)
        if dt == np.float32:  # compute in float32, as lfilter does for float32 data
            den, bx, bv = den.astype(dt), bx.astype(dt), bv.astype(dt)
            zix, ziv = zix.astype(dt), ziv.astype(dt)
        zt = z[:, 2:]

        def lf():
            yx, _ = scipy.signal.lfilter(bx, den, zt, axis=-1, zi=zix)
            yv, _ = scipy.signal.lfilter(bv, den, zt, axis=-1, zi=ziv)
            return yx, yv

        yx, yv = lf()
        px = np.concatenate([z[:, :1], z[:, 1:2], yx], axis=1)
        pv = np.concatenate([np.full((nt, 1), np.nan), (z[:, 1:2].astype(np.float64) - z[:, :1]) / T, yv], axis=1)
        e = self.check("lfilter", (px, pv), ref, tol if dt == np.float64 else 1e-4)
        del yx, yv, px, pv
        add("scipy.signal.lfilter (x2, allocates)", "lfilter", lf, e,
            "f32: computes in float32" if dt == np.float32 else "")

        # -- NumPy vectorised over tracks (full size when there are tracks) -----
        if nt >= 100:
            on = np.empty((2, nt, ns), dtype=dt)
            ab_numpy(z, on[0], on[1], ALPHA, BETA, T)
            e = self.check("numpy", (on[0], on[1]), ref, tol)
            add("NumPy, vectorised over tracks", "numpy", lambda: ab_numpy(z, on[0], on[1], ALPHA, BETA, T), e)

        # -- alpha-beta-gamma and the general 3-state kernel --------------------
        for name, filt, phi, kg, kind in (
            ("abkit AlphaBetaGammaFilter threads=1, out=", self.abg, self.abg.Phi, self.abg.K[:, 0], "abg"),
            ("abkit FixedGainFilter 3x3 threads=1, out=", self.gen3, self.phi3, self.k3, "gen3"),
        ):
            o3 = np.empty((3, nt, ns), dtype=dt)
            filt.run(z, out=o3, threads=1)
            e3: Optional[float] = None
            if HAVE_NUMBA:
                r3 = np.empty_like(o3)
                fg3_ref(z, np.ascontiguousarray(phi), np.ascontiguousarray(kg), T, r3)
                e3 = self.check(name, tuple(o3), tuple(r3), tol)
                del r3
            add(name, kind, functools.partial(filt.run, z, out=o3, threads=1), e3)

        # -- time everything, round-robin --------------------------------------
        for c in cases:  # warm (and, for fresh-output cases, a first allocation)
            c[2]()
        times: List[List[float]] = [[] for _ in cases]
        for _ in range(R):
            for j, c in enumerate(cases):
                t0 = time.perf_counter()
                c[2]()
                times[j].append(time.perf_counter() - t0)
        for (method, kind, _, err, note), ts in zip(cases, times):
            ts.sort()
            self.record(wl, dt, method, n, (ts[0], ts[len(ts) // 2]), err, note=note, kind=kind)
        pool.shutdown()
        cases.clear()

        # -- slow ones, on a short track, extrapolated per sample ---------------
        m = 20_000 if not self.quick else 5_000
        zs = make_z(1, m, dt, seed=3)
        if nt < 100:  # NumPy over 1 track: a Python loop over 10^7 samples
            on = np.empty((2, 1, m), dtype=dt)
            ab_numpy(zs, on[0], on[1], ALPHA, BETA, T)
            rn = ab.run(zs, threads=1)
            e = self.check("numpy", (on[0], on[1]), (rn.position, rn.velocity), tol)
            tn = timeit(lambda: ab_numpy(zs, on[0], on[1], ALPHA, BETA, T), 3)
            self.record(wl, dt, "NumPy, vectorised over tracks", n, (tn[0] * n / m, tn[1] * n / m), e,
                        note=f"extrapolated from 1 x {m}", kind="numpy")
        zl = zs[0].astype(np.float64).tolist()
        py_x, py_v = ab_python(zl, ALPHA, BETA, T)
        rp = ab.run(zs[0], threads=1)
        e = self.check("python", (np.asarray(py_x, dtype=dt), np.asarray(py_v, dtype=dt)),
                       (rp.position, rp.velocity), tol)
        tp = timeit(lambda: ab_python(zl, ALPHA, BETA, T), 3)
        self.record(wl, dt, "pure Python loop", n, (tp[0] * n / m, tp[1] * n / m), e,
                    note=f"extrapolated from 1 x {m}", kind="python")

    def overheads(self) -> Dict[str, float]:
        """Per-call and per-track overheads of abkit (float64)."""
        res = {}
        ab = self.ab
        z = make_z(1, 16, np.float64)
        out = np.empty((2, 1, 16))
        t, _ = timeit(lambda: ab.run(z, out=out, threads=1), 2000)
        res["per-call (1 x 16, out=)"] = t
        for nt, ns in ((100_000, 2), (100_000, 10)):
            z = make_z(nt, ns, np.float64)
            out = np.empty((2, nt, ns))
            t, _ = timeit(lambda: ab.run(z, out=out, threads=1), self.repeat)
            res[f"abkit {nt} x {ns}"] = t
            c = self.lib.ab_f64
            zp, p0, p1 = ptr(z), ptr(out[0]), ptr(out[1])
            t, _ = timeit(lambda: c(zp, p0, p1, nt, ns, ALPHA, BETA, T), self.repeat)
            res[f"C {nt} x {ns}"] = t
        st = ab.run(z).state
        t, _ = timeit(lambda: ab.run(z, out=out, threads=1, state=st), self.repeat)
        res["abkit 100000 x 10, state= (streaming)"] = t
        return res


# -----------------------------------------------------------------------------
# report


def fmt_rate(r: float) -> str:
    return f"{r / 1e6:,.0f}" if r >= 1e7 else f"{r / 1e6:,.2f}"


def report(b: Bench, crit: Dict[str, Tuple[float, float, float, float]], sizes, overheads, info) -> str:
    rows = b.rows
    out: List[str] = []
    w = out.append
    C2, RS2 = ("ceiling2", "ceiling2_nt"), ("ceiling2",)
    C3, RS3 = ("ceiling3", "ceiling3_nt"), ("ceiling3",)

    def get(wl: str, dt: str, kind: str) -> Any:
        """The fastest row of this kind (None if there is none)."""
        c = [r for r in rows if r["workload"] == wl and r["dtype"] == dt and r["kind"] == kind]
        return min(c, key=lambda r: r["t_min"]) if c else None

    def tmin(wl: str, dt: str, kinds: Tuple[str, ...]) -> float:
        return min(r["t_min"] for r in rows if r["workload"] == wl and r["dtype"] == dt and r["kind"] in kinds)

    def crit_t(group: str, dt: str, nt: int, ns: int, which: int = 1) -> Optional[float]:
        """criterion's mean estimate (which=1) or the fastest iteration (3)."""
        t = crit.get(f"{group}/{dt}/{nt}x{ns}")
        return t[which] if t and not math.isnan(t[which]) else None

    if b.failures:
        w("### CHECK FAILURES\n")
        for f in b.failures:
            w(f"- {f}")
        w("")
    w("### Machine and run\n")
    for k, v in info.items():
        w(f"- {k}: {v}")
    w("")
    wls = [(f"{nt:,} x {ns:,}", nt, ns) for nt, ns in sizes]
    for wl, nt, ns in wls:
        n = nt * ns
        w(f"### {wl} (tracks x samples), alpha-beta\n")
        w("| method | f64 Msamples/s | x ceil | x ceil-RS | f32 Msamples/s | x ceil | x ceil-RS | err f64 / f32 | note |")
        w("|---|---:|---:|---:|---:|---:|---:|---|---|")
        methods: List[Tuple[str, str]] = []
        for r in rows:
            if (r["workload"] == wl and (r["method"], r["kind"]) not in methods
                    and r["kind"] not in ("abg", "gen3", "ceiling3", "ceiling3_nt")):
                methods.append((r["method"], r["kind"]))
        methods += [("Rust filter_ab, 1 thread (criterion mean)", "crit:ab_serial:1"),
                    ("Rust filter_ab, 1 thread (fastest iteration)", "crit:ab_serial:3"),
                    ("Rust filter_ab, rayon 2 threads (criterion mean)", "crit:ab_parallel:1"),
                    ("Rust filter_ab, rayon 2 threads (fastest iteration)", "crit:ab_parallel:3")]
        for method, kind in methods:
            cells: List[str] = []
            errs: List[str] = []
            notes = set()
            for dt in ("f64", "f32"):
                if kind.startswith("crit:"):
                    _, group, which = kind.split(":")
                    t = crit_t(group, dt, nt, ns, int(which))
                    errs.append("-")
                else:
                    row: Any = next((x for x in rows if x["workload"] == wl and x["dtype"] == dt
                                     and x["method"] == method), None)
                    t = row["t_min"] if row else None
                    if row:
                        errs.append("-" if row["err"] is None else f"{row['err']:.0e}")
                        if row["note"]:
                            notes.add(row["note"])
                if t is None:
                    cells += ["-", "-", "-"]
                    continue
                cells += [fmt_rate(n / t), f"{tmin(wl, dt, C2) / t:.2f}", f"{tmin(wl, dt, RS2) / t:.2f}"]
            if all(c == "-" for c in cells):
                continue
            w(f"| {method} | {' | '.join(cells)} | {' / '.join(errs)} | {'; '.join(sorted(notes))} |")
        w("")
        w("abkit (threads=1, out= reused) speed-up over, same run:\n")
        w("| vs | f64 | f32 |")
        w("|---|---:|---:|")
        for label, kind in (("numba @njit (default)", "numba"), ("numba fastmath={'contract'}", "numba_contract"),
                            ("scipy.signal.lfilter", "lfilter"), ("C -O3", "c"), ("NumPy vectorised", "numpy"),
                            ("pure Python", "python")):
            cells = []
            for dt in ("f64", "f32"):
                a, o = get(wl, dt, "abkit1"), get(wl, dt, kind)
                cells.append(f"{o['t_min'] / a['t_min']:.2f}x" if a and o else "-")
            w(f"| {label} | {' | '.join(cells)} |")
        w("")
    # 3-state
    w("### alpha-beta-gamma and the general 3-state kernel (threads=1, out= reused)\n")
    w("Ceilings: read z once, write 3 output arrays (best pass / best regular-store pass).\n")
    w("| workload | dtype | method | Msamples/s | x ceil3 | x ceil3-RS | err |")
    w("|---|---|---|---:|---:|---:|---|")
    for wl, nt, ns in wls:
        for dt in ("f64", "f32"):
            c3, r3 = tmin(wl, dt, C3), tmin(wl, dt, RS3)
            w(f"| {wl} | {dt} | ceiling, 3 outputs (best pass) | {fmt_rate(nt * ns / c3)} | 1.00 | {r3 / c3:.2f} | |")
            for kind in ("abg", "gen3"):
                r = get(wl, dt, kind)
                if r:
                    err = "-" if r["err"] is None else f"{r['err']:.0e}"
                    w(f"| {wl} | {dt} | {r['method']} | {fmt_rate(r['rate'])} | {c3 / r['t_min']:.2f} | "
                      f"{r3 / r['t_min']:.2f} | {err} |")
            for wi, what in ((1, "criterion mean"), (3, "fastest iteration")):
                t = crit_t("general3_serial", dt, nt, ns, wi)
                if t:
                    w(f"| {wl} | {dt} | Rust filter_general<3,1> (abg gains), {what} | {fmt_rate(nt * ns / t)} | "
                      f"{c3 / t:.2f} | {r3 / t:.2f} | |")
    w("")
    # targets
    w("### Targets (issue 3)\n")
    w("| target | workload | f64 | f32 | met? |")
    w("|---|---|---:|---:|---|")

    def target(label: str, wl: str, vals: Dict[str, Optional[float]], thr: float) -> None:
        ok = [v >= thr for v in vals.values() if v is not None]
        cells = [f"{vals[d]:.2f}" if vals.get(d) is not None else "-" for d in ("f64", "f32")]
        met = "n/a" if not ok else ("yes" if all(ok) else ("no" if not any(ok) else "partly"))
        w(f"| {label} | {wl} | {cells[0]} | {cells[1]} | {met} |")

    dts = ("f64", "f32")
    a1 = {(wl, dt): get(wl, dt, "abkit1")["t_min"] for wl, _, _ in wls for dt in dts}
    # without out= (fresh outputs), and allocating the outputs alone
    fresh = {(wl, dt): get(wl, dt, "abkit1_fresh")["t_min"] for wl, _, _ in wls for dt in dts}
    alloc = {(wl, dt): tmin(wl, dt, ("fresh_alloc",)) for wl, _, _ in wls for dt in dts}
    for kinds, what in ((C2, "ceiling (best pass)"), (RS2, "regular-store ceiling")):
        for wl, nt, ns in wls:
            thr = 0.55 if nt == 1 else 0.8
            target(f">= {thr} of {what}, 1 thread, out=", wl, {dt: tmin(wl, dt, kinds) / a1[wl, dt] for dt in dts}, thr)
    for kinds, what in ((C2, "ceiling (best pass)"), (RS2, "regular-store ceiling")):
        for wl, nt, ns in wls:
            thr = 0.55 if nt == 1 else 0.8
            f32a = get(wl, "f32", "abkit1_f32a")
            target(f"float32_arithmetic=True: >= {thr} of {what}, 1 thread, out=", wl,
                   {"f64": None, "f32": tmin(wl, "f32", kinds) / f32a["t_min"] if f32a else None}, thr)
    for wl, nt, ns in wls:
        target(">= 3x numba @njit", wl, {dt: (get(wl, dt, "numba")["t_min"] / a1[wl, dt]
                                             if get(wl, dt, "numba") else None) for dt in dts}, 3.0)
    for wl, nt, ns in wls:
        target(">= 5x lfilter", wl, {dt: get(wl, dt, "lfilter")["t_min"] / a1[wl, dt] for dt in dts}, 5.0)
    for wl, nt, ns in wls:
        bw = {dt: tmin(wl, dt, ("ceiling2",)) / tmin(wl, dt, ("ceiling2_2t",)) for dt in dts}
        bwn = {dt: tmin(wl, dt, ("ceiling2_nt",)) / tmin(wl, dt, ("ceiling2_nt_2t",)) for dt in dts}
        target(f"2 threads >= 1.5x 1 thread (copy pass 2t/1t: plain {bw['f64']:.2f}/{bw['f32']:.2f}, "
               f"non-temporal {bwn['f64']:.2f}/{bwn['f32']:.2f})", wl,
               {dt: a1[wl, dt] / get(wl, dt, "abkit2")["t_min"] for dt in dts}, 1.5)
    for wl, nt, ns in wls:
        target("no out=: 1.1 x (time with out= + allocating the outputs alone) / time without (>= 1 met)",
               wl, {dt: (a1[wl, dt] + alloc[wl, dt]) * 1.1 / fresh[wl, dt] for dt in dts}, 1.0)
    for wl, nt, ns in wls:
        extra = {dt: fresh[wl, dt] - a1[wl, dt] for dt in dts}
        # math.inf: no extra time at all
        target("no out=, stricter: 1.1 x allocating the outputs alone / (time without - time with) (>= 1 met)",
               wl, {dt: 1.1 * alloc[wl, dt] / extra[dt] if extra[dt] > 0 else math.inf for dt in dts}, 1.0)
    for wl, nt, ns in wls:
        vals = {}
        for dt in dts:
            cdiff = max(0.0, tmin(wl, dt, ("fresh_copy",)) - tmin(wl, dt, ("ceiling2",)))
            vals[dt] = (a1[wl, dt] + cdiff) * 1.1 / fresh[wl, dt]
        target("(for reference) the same with the copy pass's fresh - warm as the allocation cost", wl, vals, 1.0)
    for kinds, what in ((C3, "ceiling3 (best pass)"), (RS3, "regular-store ceiling3")):
        for wl, nt, ns in wls:
            target(f"general 3-state >= 0.5 of {what}", wl,
                   {dt: tmin(wl, dt, kinds) / get(wl, dt, "gen3")["t_min"] for dt in dts}, 0.5)
    w("")
    w("### Fresh outputs and per-track overhead\n")
    w("| quantity | value |")
    w("|---|---:|")
    for wl, nt, ns in wls:
        for dt in dts:
            cdiff = tmin(wl, dt, ("fresh_copy",)) - tmin(wl, dt, ("ceiling2",))
            w(f"| {wl} {dt}: allocating the outputs alone (np.empty + one write per page); copy pass fresh - warm "
              f"| {alloc[wl, dt] * 1e3:.1f} ms; {cdiff * 1e3:.1f} ms "
              f"(abkit with out=: {a1[wl, dt] * 1e3:.1f} ms, without: {fresh[wl, dt] * 1e3:.1f} ms) |")
    for k, v in overheads.items():
        w(f"| {k} | {v * 1e6:,.1f} µs |")
    for k, v in crit.items():
        if k.startswith("overhead/"):
            w(f"| Rust core only, filter_ab {k.split('/')[-1]} (criterion mean / fastest) | "
              f"{v[1] * 1e6:,.1f} / {v[3] * 1e6:,.1f} µs |")
    w("")
    return "\n".join(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="small sizes (1/100 of the samples), no criterion; < 30 s")
    ap.add_argument("--repeat", type=int, default=None, help="timed runs per measurement (default 9, quick 5)")
    ap.add_argument("--no-rust", action="store_true", help="skip the criterion bench")
    ap.add_argument("--rust", action="store_true", help="run the criterion bench even with --quick")
    ap.add_argument("--json", help="write all raw numbers to this file")
    ap.add_argument("--only", choices=["f64", "f32"], help="one dtype only")
    args = ap.parse_args()
    t_start = time.perf_counter()
    info = machine_info()
    scale = 100 if args.quick else 1
    total = 10_000_000 // scale
    sizes = [(1, total), (100_000 // scale, 100), (1_000 // min(scale, 100), total // (1_000 // min(scale, 100)))]
    repeat = args.repeat or (5 if args.quick else 9)
    if not HAVE_NUMBA:
        log("numba is not installed (pip install numba): its rows are skipped")
    lib = build_c()
    b = Bench(args.quick, repeat, lib)
    dts = [np.float64, np.float32] if not args.only else [np.float64 if args.only == "f64" else np.float32]
    for nt, ns in sizes:
        for dt in dts:
            b.workload(nt, ns, dt)
    overheads = b.overheads()
    crit: Dict[str, Tuple[float, float, float, float]] = {}
    if (not args.quick or args.rust) and not args.no_rust:
        crit = run_criterion(scale)
    info["load average (end)"] = " ".join(f"{x:.2f}" for x in os.getloadavg())
    info["repeats"] = f"min of {repeat} warm runs (pure Python and extrapolated NumPy: 3)"
    info["wall time of this run"] = f"{time.perf_counter() - t_start:.0f} s"
    text = report(b, crit, sizes, overheads, info) if not args.only else ""
    print(text)
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(dict(info=info, rows=b.rows, criterion=crit, overheads=overheads), fh, indent=1)


if __name__ == "__main__":
    main()
