"""The design nomograph: its curves are the paper's equations (checked here
against closed forms written independently, rtol 1e-12) and it renders to PNG."""

from __future__ import annotations

import math
import pathlib

import numpy as np
import pytest

matplotlib = pytest.importorskip("matplotlib")
matplotlib.use("Agg")


def test_nomograph_curves_and_png(tmp_path: pathlib.Path) -> None:
    import matplotlib.pyplot as plt

    from abkit import alphabeta, plot

    ax = plot.nomograph(design=alphabeta.from_snr(0.1), n=50)
    beta_line = ax.get_lines()[0]
    a = np.asarray(beta_line.get_xdata())
    b = np.asarray(beta_line.get_ydata())
    # Kalman beta as a function of alpha: beta = 2 (1 - sqrt(1 - alpha))^2
    np.testing.assert_allclose(b, 2 * (1 - np.sqrt(1 - a)) ** 2, rtol=1e-12)
    twins = [t for t in ax.figure.axes if t is not ax]
    bw = np.asarray(twins[0].get_lines()[0].get_ydata())
    x = np.sqrt(b)
    d = 1 / math.sqrt(2)
    np.testing.assert_allclose(bw, x * (1 + (2 * d - x) ** 2) / (8 * d), rtol=1e-12)
    snr = np.asarray(twins[1].get_lines()[0].get_ydata())
    r = b**2 / (4 * (1 - a))  # Kalata: lambda^2 = beta^2/(1-alpha), r = lambda^2/4
    np.testing.assert_allclose(snr, 10 * np.log10(r), rtol=1e-10, atol=1e-10)
    path = tmp_path / "nomo.png"
    ax.figure.savefig(path)
    plt.close(ax.figure)
    assert path.stat().st_size > 10_000
    assert path.read_bytes()[:4] == b"\x89PNG"


def test_nomograph_rejects_array_design() -> None:
    from abkit import alphabeta, plot

    with pytest.raises(ValueError, match="scalar"):
        plot.nomograph(design=alphabeta.from_snr([0.1, 0.2]))
