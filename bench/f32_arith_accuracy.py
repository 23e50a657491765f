"""What float32 *arithmetic* would cost in accuracy (a study, not a test).

abkit filters float32 data in float64 arithmetic and rounds each output
once, so its float32 results are the float64 results rounded (0.5 ulp).
float32 arithmetic (eight slots per AVX2 register instead of four) is the
route to issue 3's float32 throughput targets on AVX2 CPUs
(docs/benchmarks.md, sessions 21-22). This script measures what it would
cost: the alpha-beta recursion (abkit's step: ``x_p = x + T v`` fused,
``r = z - x_p``, ``x = x_p + alpha r`` fused, ``v = v + (beta/T) r``
fused; a fused operation emulated as float64 then one rounding) in float32
against float64 on the same float32 measurements, for Kalata-designed gains
over tracking indices 1e-5..1e3 and position offsets 0, 1e3, 1e5.

Reported per design: the largest |x32 - x64| relative to the array's scale
(the suite's float64 metric) and the RMS of x32 - x64 relative to the RMS
estimation error of the float64 filter itself.

    python bench/f32_arith_accuracy.py [N_SAMPLES]
"""
import sys

import numpy as np


def kalata(lam):
    """Alpha-beta gains of the steady-state Kalman filter for tracking index lam."""
    beta = (lam * lam + 4 * lam - lam * np.sqrt(lam * lam + 8 * lam)) / 4
    return np.sqrt(2 * beta) - beta / 2, beta


def fused32(a, b, c):
    """a * b + c with one rounding to float32 (a, b, c float32; exact product in float64)."""
    return (a.astype(np.float64) * b.astype(np.float64) + c.astype(np.float64)).astype(np.float32)


def main(n):
    rng = np.random.default_rng(7)
    lams = np.logspace(-5, 3, 9)
    alpha, beta = kalata(lams)
    T = 0.1
    a32, bt32 = alpha.astype(np.float32), (beta / T).astype(np.float32)
    t32 = np.full(len(lams), T, np.float32)
    print(f"{'lambda':>9} {'alpha':>9} | max|x32-x64| / scale for offsets 0, 1e3, 1e5 | rms(x32-x64) / rms error")
    rows = {}
    for offset in (0.0, 1e3, 1e5):
        sig_w = lams / T**2  # sigma_v = 1
        xt = np.zeros(len(lams))
        vt = np.full(len(lams), 10.0)
        err = np.zeros(len(lams))
        scale = np.zeros(len(lams))
        dev2 = np.zeros(len(lams))
        e2 = np.zeros(len(lams))
        for k in range(n):
            acc = rng.normal(size=len(lams)) * sig_w
            xt = xt + T * vt + acc * T * T / 2
            vt = vt + acc * T
            z = (offset + xt + rng.normal(size=len(lams))).astype(np.float32)
            if k == 0:
                x64, v64 = z.astype(np.float64), np.zeros(len(lams))
                x32, v32 = z.copy(), np.zeros(len(lams), np.float32)
                continue
            xp = x64 + T * v64
            r = z - xp
            x64, v64 = xp + alpha * r, v64 + (beta / T) * r
            xp32 = fused32(t32, v32, x32)
            r32 = z - xp32
            x32, v32 = fused32(a32, r32, xp32), fused32(bt32, r32, v32)
            if k > 100:
                err = np.maximum(err, np.abs(x32.astype(np.float64) - x64.astype(np.float32)))
                scale = np.maximum(scale, np.abs(x64))
                dev2 += (x32 - x64) ** 2
                e2 += (x64 - offset - xt) ** 2
        rows[offset] = (err / scale, np.sqrt(dev2 / e2))
    for i, lam in enumerate(lams):
        rel = "  ".join(f"{rows[o][0][i]:8.1e}" for o in rows)
        rms = "  ".join(f"{rows[o][1][i]:8.1e}" for o in rows)
        print(f"{lam:9.1e} {alpha[i]:9.2e} | {rel} | {rms}")
    print(f"float32 epsilon {np.finfo(np.float32).eps:.1e}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 20000)
