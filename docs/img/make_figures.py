#!/usr/bin/env python3
"""Regenerate the figures shown in docs/plots.md and docs/getting-started.md:
``python docs/img/make_figures.py`` (needs abkit[plot])."""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from abkit import AlphaBetaFilter, AlphaBetaGammaFilter, KalmanFilter, alphabeta, plot  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))


def save(fig, name: str, dpi: int = 72) -> None:
    fig.savefig(os.path.join(HERE, name), dpi=dpi)
    plt.close(fig)


f = AlphaBetaFilter.from_design(alphabeta.from_snr(0.01), T=0.1)
save(plot.frequency_response(f).axes[0].figure, "frequency_response.png")
save(plot.pole_zero(AlphaBetaGammaFilter(0.5, 0.3, 0.05, 1.0)).ax.figure, "pole_zero.png")
T = 0.5
kf = KalmanFilter([[1, T], [0, 1]], [[1, 0]], np.diag([0.0, 0.01]), 1.0, P0=100 * np.eye(2))
save(plot.gain_convergence(kf, n=80).axes[0].figure, "gain_convergence.png")
rng = np.random.default_rng(0)
truth = np.cumsum(np.cumsum(rng.normal(0, 0.2, 200)))
z = truth + rng.normal(0, 2, 200)
z[rng.random(200) < 0.05] = np.nan
z[80:95] = np.nan
save(plot.track(f.run(z, return_residuals=True), z, truth=truth, T=0.1)[0].figure, "track.png")
with tempfile.TemporaryDirectory() as d:
    subprocess.run([sys.executable, "-m", "abkit", "demo", "--tracks", "2000", "--out", d], check=True, stdout=subprocess.DEVNULL)
    from PIL import Image  # a dependency of matplotlib

    im = Image.open(os.path.join(d, "abkit_demo.png")).convert("RGB")
    im = im.resize((1000, round(im.height * 1000 / im.width)), Image.LANCZOS)
    im.quantize(colors=128).save(os.path.join(HERE, "demo.png"), optimize=True)
