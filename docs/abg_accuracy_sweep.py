"""Accuracy sweep of abkit.abg.from_noise against a 50-digit Riccati reference.

Reproduces the table of docs/abg.md ("Accuracy of from_noise"): 1296 points,
q_a = sigma_a h^4 / sigma_m in 1e-16 .. 1e16, q_p, q_v in {0, 1e-12, ..., 1e12},
h in {1e-3, 1, 2000, 1e4}; max relative error of alpha, beta, gamma per
region, and failures. The reference is the filter DARE solved by doubling in
mpmath (the same as tests/test_abg_accuracy.py). Needs numpy and mpmath;
runs in a few minutes.

    python docs/abg_accuracy_sweep.py
"""

from __future__ import annotations

import collections
import itertools
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from test_abg_accuracy import ref_gains  # noqa: E402

from abkit import abg  # noqa: E402


def main() -> int:
    hs = (1e-3, 1.0, 2000.0, 1e4)
    qas = [10.0**k for k in range(-16, 17, 4)]
    vals = [0.0, 1e-12, 1e-6, 1.0, 1e6, 1e12]
    agg: dict = collections.defaultdict(lambda: [0, 0, [0.0] * 3])
    for h, qa, qp, qv in itertools.product(hs, qas, vals, vals):
        sm = 1.0
        sp, sv, sa = qp * sm, qv * sm / h**2, qa * sm / h**4
        region = ("q_a < 1e-4" if qa < 1e-4 else "q_a > 1e4" if qa > 1e4 else "1e-4 <= q_a <= 1e4",
                  "q_p = q_v = 0" if qp == 0 and qv == 0 else "q_p or q_v > 0")
        a = agg[region]
        a[0] += 1
        r = ref_gains(sp, sv, sa, sm, h)
        try:
            d = abg.from_noise(sp, sv, sa, sm, h)
        except Exception as exc:  # noqa: BLE001 - counted and reported
            a[1] += 1
            print("failure", (sp, sv, sa, sm, h), type(exc).__name__, exc)
            continue
        for i, x in enumerate((d.alpha, d.beta, d.gamma)):
            a[2][i] = max(a[2][i], abs(float(x) - r[i]) / r[i])
    print(f"{'region':<22}{'noise':<16}{'n':>6}{'fail':>6}  max rel. error alpha / beta / gamma")
    for (q, k), (n, f, e) in sorted(agg.items()):
        print(f"{q:<22}{k:<16}{n:>6}{f:>6}  " + " / ".join(f"{x:.0e}" for x in e))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
