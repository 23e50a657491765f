"""Accuracy sweep of the alpha-beta-gamma RTS backward gain against a 50-digit reference.

Reproduces the table of docs/abg.md ("Backward (smoother) gains"): the same
1296 points as docs/abg_accuracy_sweep.py (q_a = sigma_a h^4 / sigma_m in
1e-16 .. 1e16, q_p, q_v in {0, 1e-12, ..., 1e12}, h in {1e-3, 1, 2000, 1e4}).
Error: normalised gain A_N, per row relative to the row's largest entry,
max over rows, against the 50-digit RTS gain of tests/test_abg_backward.py.

Columns: "before" is the former float64 evaluation from the rounded gains
(P~, (I - w H) P~ and the equilibrated Cholesky inverse, re-evaluated here in
NumPy exactly as the former Rust ``abg_backward_normalised``); "design" is
the current design path (``AlphaBetaGammaFilter.from_noise(...).smoother_gain()``,
double-double from the noise); "fixed" the current fixed-gain path
(``AlphaBetaGammaFilter(alpha, beta, gamma).smoother_gain()`` of the rounded
gains, double-double from the gains as exact), against the reference of
those exact gains. Needs numpy and mpmath; runs in several minutes.

    python docs/abg_backward_sweep.py
"""

from __future__ import annotations

import collections
import itertools
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from test_abg_backward import ref_backward_gains, ref_backward_noise, row_error  # noqa: E402

from abkit import AlphaBetaGammaFilter, abg  # noqa: E402


def former_f64(a: float, b: float, g: float) -> np.ndarray:
    """The former float64 evaluation (rust/abkit-core/src/irregular.rs before the fix)."""
    p22 = b * (a + b + 0.25 * g) - 0.5 * g * (2.0 + a)
    p23 = g * (a + 0.5 * b)
    m = np.array([[a, b, g], [b, p22, p23], [g, p23, g * (b + g)]])
    ikh = np.eye(3)
    ikh[:, 0] -= [a, b, g]
    p = ikh @ m
    p = (p + p.T) * 0.5
    s = np.diag(1.0 / np.sqrt(np.diag(m)))
    ms = s @ m @ s
    ms = (ms + ms.T) * 0.5
    lc = np.linalg.cholesky(ms)
    li = np.linalg.inv(lc)
    minv = s @ (li.T @ li) @ s
    phi = np.array([[1.0, 1.0, 0.5], [0.0, 1.0, 1.0], [0.0, 0.0, 1.0]])
    return p @ phi.T @ minv


def _normalise(a: np.ndarray, h: float) -> np.ndarray:
    d = np.array([1.0, h, h * h])
    return a * d[:, None] / d[None, :]


def main() -> int:
    hs = (1e-3, 1.0, 2000.0, 1e4)
    qas = [10.0**k for k in range(-16, 17, 4)]
    vals = [0.0, 1e-12, 1e-6, 1.0, 1e6, 1e12]
    agg: dict = collections.defaultdict(lambda: [0, 0, [0.0] * 3])
    for h, qa, qp, qv in itertools.product(hs, qas, vals, vals):
        sm = 1.0
        sp, sv, sa = qp * sm, qv * sm / h**2, qa * sm / h**4
        a = agg[f"q_a = {qa:.0e}"]
        a[0] += 1
        try:
            d = abg.from_noise(sp, sv, sa, sm, h, convention="chen-chui")
        except ValueError:  # alpha rounds to 1: no filter to smooth
            a[1] += 1
            continue
        al, be, ga = float(d.alpha), float(d.beta), float(d.gamma)
        ref = ref_backward_noise(sp, sv, sa, sm, h)
        errs = [row_error(former_f64(al, be, ga), ref)]
        errs.append(row_error(_normalise(AlphaBetaGammaFilter.from_noise(sp, sv, sa, sm, T=h).smoother_gain()[0], h), ref))
        fx = AlphaBetaGammaFilter(al, be, ga, h, convention="chen-chui").smoother_gain()[0]
        errs.append(row_error(_normalise(fx, h), ref_backward_gains(al, be, ga)))
        for i, e in enumerate(errs):
            a[2][i] = max(a[2][i], e)
    print(f"{'region':<14}{'n':>6}{'skip':>6}  max row-rel. error before / design / fixed")
    for q, (n, f, e) in sorted(agg.items(), key=lambda kv: float(kv[0].split('=')[1])):
        print(f"{q:<14}{n:>6}{f:>6}  " + " / ".join(f"{x:.0e}" for x in e))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
