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


def _kalman_recursion_rms(p2: float, tau_over_T: float, rv):
    """Brute-force predict/update recursion to convergence on (Phi, Q) from
    Van Loan (scipy expm); T = sigma_pos = 1, sigma_m = p2."""
    import singer_ref

    q = 2 * p2**2 / tau_over_T
    Phi, Q = singer_ref.van_loan(1.0, tau_over_T, q)
    H = np.eye(3)[:1] if rv is None else np.eye(3)[:2]
    R = np.eye(1) if rv is None else np.diag([1.0, rv**2])
    P = np.eye(3)
    for _ in range(200000):
        S = H @ P @ H.T + R
        Pf = P - P @ H.T @ np.linalg.solve(S, H @ P)
        Pn = Phi @ Pf @ Phi.T + Q
        done = np.max(np.abs(Pn - P) / np.sqrt(np.outer(np.diag(Pn), np.diag(Pn)))) < 1e-15
        P = Pn
        if done:
            break
    return np.sqrt(np.diag(P))


@pytest.mark.parametrize("rv", [None, 0.5])
def test_singer_errors_against_kalman_recursion(rv, tmp_path: pathlib.Path) -> None:
    import matplotlib.pyplot as plt

    from abkit import plot

    p2 = np.array([0.01, 0.3, 10.0])
    axes = plot.singer_errors(p2=p2, sigma_vel_ratio=rv)
    for k, f in enumerate((1.0, 10.0)):
        tau = plot.singer_tau_over_T(p2, f)
        for j in range(len(p2)):
            want = _kalman_recursion_rms(p2[j], tau[j], rv)
            got = [np.asarray(ax.get_lines()[k].get_ydata())[j] for ax in axes]
            np.testing.assert_allclose(got, want, rtol=1e-9)
    path = tmp_path / "singer.png"
    axes[0].figure.savefig(path)
    plt.close(axes[0].figure)
    assert path.read_bytes()[:4] == b"\x89PNG"


def test_singer_tau_parametrisation() -> None:
    from abkit import plot

    np.testing.assert_allclose(plot.singer_tau_over_T(1.0), np.sqrt(3.96), rtol=1e-15)
    np.testing.assert_allclose(plot.singer_tau_over_T(1.0, 10.0), 10 * np.sqrt(3.96), rtol=1e-15)
