#!/usr/bin/env python3
"""Throughput of abkit.singer.steady_state against a Python loop over scipy.

    python bench/bench_singer.py [N] [N_SCIPY]

Draws N (default 100 000) parameter sets -- T/tau log-uniform in [1e-3, 10],
p2 = sigma_m T^2/sigma_pos log-uniform in [1e-3, 1e3], sigma_vel T/sigma_pos
log-uniform in [1, 100] (position and velocity measurements), i.e. inside
the closed form's stated range -- and reports solves per second for
method="auto" (closed form with fallback; the share that used the closed
form is printed), method="numeric", and a Python loop calling
scipy.linalg.solve_discrete_are (plus K and P_filt) on the first N_SCIPY
(default 2 000) sets, in the same run. The abkit numbers include the Python
layer (validation, broadcasting, unit scaling); the work runs in Rust on all
cores (rayon's global pool).
"""

from __future__ import annotations

import os
import sys
import time

import numpy as np
import scipy.linalg

from abkit import singer


def main() -> None:
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 100_000
    n_sp = int(sys.argv[2]) if len(sys.argv) > 2 else 2_000
    rng = np.random.default_rng(2024)
    T = 1.0
    theta = 10 ** rng.uniform(-3, 1, n)
    p2 = 10 ** rng.uniform(-3, 3, n)
    rv = 10 ** rng.uniform(0, 2, n)
    tau, sm, sp, sv = T / theta, p2, 1.0, rv

    print(f"{n} parameter sets, {os.cpu_count()} CPUs")
    rates = {}
    for method in ("auto", "numeric"):
        singer.steady_state(T, tau[:100], sm[:100], sp, sv[:100], method=method)  # warm up
        t0 = time.perf_counter()
        s = singer.steady_state(T, tau, sm, sp, sv, method=method)
        dt = time.perf_counter() - t0
        rates[method] = n / dt
        extra = ""
        if method == "auto":
            share = np.mean(s.method_used == "closed-form")
            extra = f" ({100 * share:.1f} % closed form)"
        print(f"abkit {method:8s}: {rates[method]:12.0f} solves/s{extra}")

    H = np.array([[1.0, 0, 0], [0, 1, 0]])
    Phi, Q = singer.model(T, tau=tau[:n_sp], sigma_m=sm[:n_sp])
    t0 = time.perf_counter()
    for i in range(n_sp):
        R = np.diag([sp**2, sv[i] ** 2])
        P = scipy.linalg.solve_discrete_are(Phi[i].T, H.T, Q[i], R)
        S = H @ P @ H.T + R
        K = P @ H.T @ np.linalg.inv(S)
        _ = (np.eye(3) - K @ H) @ P
    dt = time.perf_counter() - t0
    rate_sp = n_sp / dt
    print(f"scipy loop    : {rate_sp:12.0f} solves/s ({n_sp} sets)")
    for method, r in rates.items():
        print(f"speed-up {method:8s}: {r / rate_sp:8.1f} x")


if __name__ == "__main__":
    main()
