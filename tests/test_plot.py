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


# -- frequency response, pole-zero map, gain convergence, track view ----------------
# Expected values are computed here from (Phi, H, K) written out by hand, with
# scipy.signal (ss2tf, freqz, tf2zpk) and numpy.linalg.eigvals; rtol stated per test.

import scipy.signal as sig  # noqa: E402


def _ab_model(alpha: float, beta: float, T: float):
    Phi = np.array([[1.0, T], [0.0, 1.0]])
    H = np.array([[1.0, 0.0]])
    K = np.array([[alpha], [beta / T]])
    return Phi, H, K


def _abg_model(alpha: float, beta: float, gamma: float, T: float, c: float):
    Phi = np.array([[1.0, T, T * T / 2], [0.0, 1.0, T], [0.0, 0.0, 1.0]])
    H = np.array([[1.0, 0.0, 0.0]])
    K = np.array([[alpha], [beta / T], [c * gamma / T**2]])
    return Phi, H, K


def _filters():
    """(filter, Phi, H, K) for alpha-beta, alpha-beta-gamma (three conventions,
    small and large gains), a Singer design and a two-measurement filter."""
    from abkit import AlphaBetaFilter, AlphaBetaGammaFilter, FixedGainFilter, singer

    out = []
    for a, b, T in [(0.5, 0.2, 1.0), (1e-3, 5e-7, 0.01), (1.6, 0.7, 2.0)]:
        out.append((AlphaBetaFilter(a, b, T), *_ab_model(a, b, T)))
    for conv, c in [("standard", 0.5), ("chen-chui", 1.0), ("ghk", 2.0)]:
        out.append((AlphaBetaGammaFilter(0.6, 0.3, 0.05, 0.5, convention=conv), *_abg_model(0.6, 0.3, 0.05, 0.5, c)))
    s = singer.steady_state(T=1.0, tau=20.0, sigma_m=1.0, sigma_pos=10.0)
    out.append((FixedGainFilter(s.Phi, s.H, s.K, 1.0), np.asarray(s.Phi), np.asarray(s.H), np.asarray(s.K)))
    s2 = singer.steady_state(T=1.0, tau=20.0, sigma_m=1.0, sigma_pos=10.0, sigma_vel=2.0)
    out.append((FixedGainFilter(s2.Phi, s2.H, s2.K, 1.0), np.asarray(s2.Phi), np.asarray(s2.H), np.asarray(s2.K)))
    return out


def _tf(Phi, H, K, j=0):
    """x_k = A x_{k-1} + K z_k as a state-space system with state x_{k-1} and output x_k."""
    A = (np.eye(len(Phi)) - K @ H) @ Phi
    num, den = sig.ss2tf(A, K, A, K, input=j)
    return num, den, A


@pytest.mark.parametrize("case", range(8))
def test_frequency_response_against_scipy(case: int, tmp_path: pathlib.Path) -> None:
    import matplotlib.pyplot as plt

    from abkit import plot

    f, Phi, H, K = _filters()[case]
    j = 1 if H.shape[0] == 2 else 0
    fr = plot.frequency_response(f, n=200, measurement=j, states=range(len(Phi)))
    num, den, _ = _tf(Phi, H, K, j)
    for i in range(len(Phi)):
        _, want = sig.freqz(num[i], den, worN=fr.w)
        np.testing.assert_allclose(fr.response[i], want, rtol=1e-7, atol=1e-10 * np.max(np.abs(want)))
        # the plotted curves are these arrays
        np.testing.assert_allclose(fr.axes[0].get_lines()[i].get_ydata(), 20 * np.log10(np.abs(want)), rtol=1e-6, atol=1e-6)
        np.testing.assert_allclose(fr.axes[0].get_lines()[i].get_xdata(), fr.w / (2 * np.pi * f._t[0]), rtol=1e-15)
    assert fr.w[-1] == pytest.approx(np.pi, rel=1e-15) and fr.w[0] == pytest.approx(np.pi * 1e-3, rel=1e-12)
    path = tmp_path / "fr.png"
    fr.axes[0].figure.savefig(path)
    plt.close(fr.axes[0].figure)
    assert path.read_bytes()[:4] == b"\x89PNG"


def test_frequency_response_alphabeta_closed_form() -> None:
    """Position: z (alpha z + beta - alpha) / (z^2 + (alpha + beta - 2) z + 1 - alpha);
    velocity: (beta/T) z (z - 1) / (same); unit DC gain, no DC velocity."""
    import matplotlib.pyplot as plt

    from abkit import AlphaBetaFilter, plot

    a, b, T = 0.7, 0.35, 0.25
    fr = plot.frequency_response(AlphaBetaFilter(a, b, T), n=50)
    z = np.exp(1j * fr.w)
    d = z * z + (a + b - 2) * z + 1 - a
    np.testing.assert_allclose(fr.response[0], z * (a * z + b - a) / d, rtol=1e-12)
    np.testing.assert_allclose(fr.response[1], (b / T) * z * (z - 1) / d, rtol=1e-12)
    h0 = plot.transfer_response(AlphaBetaFilter(a, b, T), [0.0])
    assert abs(h0[0, 0] - 1) < 1e-14 and abs(h0[1, 0]) < 1e-14
    plt.close("all")


@pytest.mark.parametrize("case", range(8))
def test_pole_zero_against_eigvals_and_scipy(case: int, tmp_path: pathlib.Path) -> None:
    import matplotlib.pyplot as plt

    from abkit import plot

    f, Phi, H, K = _filters()[case]
    j = 1 if H.shape[0] == 2 else 0
    pz = plot.pole_zero(f, states=range(len(Phi)), measurement=j)
    num, den, A = _tf(Phi, H, K, j)
    np.testing.assert_allclose(np.sort_complex(pz.poles), np.sort_complex(np.linalg.eigvals(A)), rtol=1e-9, atol=1e-12)
    ax_poles = [ln for ln in pz.ax.get_lines() if ln.get_label().startswith("poles")][0]
    np.testing.assert_allclose(np.sort(ax_poles.get_xdata()), np.sort(np.linalg.eigvals(A).real), atol=1e-12)
    for i in range(len(Phi)):
        zs, _, _ = sig.tf2zpk(np.trim_zeros(num[i], "f") if np.any(num[i]) else num[i], den)
        got = np.sort_complex(np.asarray(pz.zeros[i], dtype=complex))
        want = np.sort_complex(np.asarray(zs, dtype=complex))
        assert got.shape == want.shape, (got, want)
        # multiple zeros (e.g. double at z = 1) are ill-conditioned: abs tol 1e-5
        np.testing.assert_allclose(got, want, atol=1e-5)
    path = tmp_path / "pz.png"
    pz.ax.figure.savefig(path)
    plt.close(pz.ax.figure)
    assert path.read_bytes()[:4] == b"\x89PNG"


def test_alphabeta_zero_closed_form() -> None:
    from abkit import AlphaBetaFilter, plot

    for a, b in [(0.5, 0.2), (0.05, 0.0013), (1.9, 0.15)]:
        z = plot.transfer_zeros(AlphaBetaFilter(a, b, 1.0), 0)
        np.testing.assert_allclose(z, [0.0, (a - b) / a], rtol=1e-12, atol=1e-15)
        # velocity: zeros at 0 and 1 (a differentiator's zero at DC)
        np.testing.assert_allclose(plot.transfer_zeros(AlphaBetaFilter(a, b, 1.0), 1), [0.0, 1.0], atol=1e-12)


def _kalman_gains_loop(F, H, Q, R, P0, n):
    """Paper 002's loop (Fig. 5), plain NumPy."""
    P = np.array(P0, float)
    out = []
    for _ in range(n):
        S = H @ P @ H.T + R
        K = P @ H.T @ np.linalg.inv(S)
        out.append(K)
        I_KH = np.eye(len(F)) - K @ H
        P = I_KH @ P @ I_KH.T + K @ R @ K.T
        P = F @ P @ F.T + Q
    return np.array(out)


@pytest.mark.parametrize("p0", [1e-6, 1.0, 1e6])
def test_gain_convergence_against_recursion_and_scipy(p0: float, tmp_path: pathlib.Path) -> None:
    import matplotlib.pyplot as plt
    import scipy.linalg as sl

    from abkit import KalmanFilter, plot

    T = 0.5
    F = np.array([[1.0, T, T * T / 2], [0.0, 1.0, T], [0.0, 0.0, 1.0]])
    H = np.array([[1.0, 0.0, 0.0]])
    g = np.array([[T**3 / 6], [T**2 / 2], [T]])
    Q = 0.3 * g @ g.T
    R = np.array([[2.0]])
    P0 = p0 * np.eye(3)
    gc = plot.gain_convergence(KalmanFilter(F, H, Q, R, P0=P0), n=150)
    want = _kalman_gains_loop(F, H, Q, R, P0, 150)
    np.testing.assert_allclose(gc.K, want, rtol=1e-9, atol=1e-13)
    for i in range(3):
        np.testing.assert_allclose(gc.axes[0].get_lines()[2 * i].get_ydata(), want[:, i, 0], rtol=1e-9, atol=1e-13)
    Pp = sl.solve_discrete_are(F.T, H.T, Q, R)
    k_inf = Pp @ H.T @ np.linalg.inv(H @ Pp @ H.T + R)
    np.testing.assert_allclose(gc.K_inf, k_inf, rtol=1e-9)
    np.testing.assert_allclose(gc.rel_error, np.max(np.abs(want - k_inf), axis=(1, 2)) / np.max(np.abs(k_inf)), rtol=1e-6, atol=1e-12)
    assert gc.rel_error[-1] < 1e-6
    path = tmp_path / "gc.png"
    gc.axes[0].figure.savefig(path)
    plt.close(gc.axes[0].figure)
    assert path.read_bytes()[:4] == b"\x89PNG"


def test_track_view(tmp_path: pathlib.Path) -> None:
    import matplotlib.pyplot as plt

    from abkit import AlphaBetaFilter, plot

    rng = np.random.default_rng(3)
    truth = np.cumsum(np.cumsum(rng.normal(0, 0.1, (3, 120)), axis=1), axis=1)
    z = truth + rng.normal(0, 1.0, truth.shape)
    miss = rng.random(z.shape) < 0.1
    miss[1, 40:55] = True  # a gap
    z[miss] = np.nan
    r = AlphaBetaFilter(0.4, 0.1, 0.5).run(z, return_residuals=True)
    axes = plot.track(r, z, truth=truth, index=1, T=0.5, t0=10.0)
    assert len(axes) == 3
    lines = axes[0].get_lines()
    t = 10.0 + 0.5 * np.arange(120)
    np.testing.assert_array_equal(lines[0].get_xdata(), t)
    np.testing.assert_array_equal(lines[0].get_ydata(), z[1])
    np.testing.assert_array_equal(lines[1].get_ydata(), r.position[1])
    np.testing.assert_array_equal(lines[2].get_ydata(), truth[1])
    np.testing.assert_array_equal(lines[3].get_xdata(), t[miss[1]])  # missed ticks
    res = axes[1].get_lines()[0].get_ydata()
    np.testing.assert_array_equal(res, r.residuals[1])
    assert np.all(np.isnan(res[miss[1]]))  # gaps stay gaps
    np.testing.assert_allclose(axes[2].get_lines()[0].get_ydata(), r.position[1] - truth[1])
    path = tmp_path / "track.png"
    axes[0].figure.savefig(path, dpi=80)
    plt.close(axes[0].figure)
    assert path.read_bytes()[:4] == b"\x89PNG"
    # without truth or residuals: two panels
    r2 = AlphaBetaFilter(0.4, 0.1, 0.5).run(z[0])
    ax2 = plot.track(r2, z[0])
    assert len(ax2) == 2 and "return_residuals" in ax2[1].texts[0].get_text()
    plt.close("all")


def test_new_plots_reject_bad_input() -> None:
    import matplotlib.pyplot as plt

    from abkit import AlphaBetaFilter, KalmanFilter, plot

    f = AlphaBetaFilter(0.5, 0.2, 1.0)
    with pytest.raises(TypeError, match="filt"):
        plot.frequency_response("not a filter")
    with pytest.raises(ValueError, match="per-track"):
        plot.pole_zero(AlphaBetaFilter([0.5, 0.4], [0.2, 0.1], 1.0))
    with pytest.raises(ValueError, match="n must"):
        plot.frequency_response(f, n=1)
    with pytest.raises(ValueError, match="states"):
        plot.frequency_response(f, states=[2])
    with pytest.raises(ValueError, match="measurement"):
        plot.transfer_response(f, [0.1], measurement=1)
    with pytest.raises(ValueError, match="two Axes"):
        plot.frequency_response(f, axes=[plt.gca()])
    with pytest.raises(TypeError, match="KalmanFilter"):
        plot.gain_convergence(f)
    with pytest.raises(ValueError, match="n must"):
        plot.gain_convergence(KalmanFilter(1.0, 1.0, 1.0, 1.0, P0=1.0), n=0)
    z = np.arange(10.0)
    r = f.run(z)
    with pytest.raises(TypeError, match="FilterResult"):
        plot.track(z, z)
    with pytest.raises(ValueError, match="shape"):
        plot.track(r, z[:5])
    with pytest.raises(ValueError, match="truth"):
        plot.track(r, z, truth=z[:3])
    plt.close("all")


def test_missing_matplotlib_gives_install_advice() -> None:
    import subprocess
    import sys

    code = (
        "import sys; sys.modules['matplotlib'] = None\n"
        "from abkit import AlphaBetaFilter, plot\n"
        "try:\n    plot.frequency_response(AlphaBetaFilter(0.5, 0.2, 1.0))\n"
        "except ImportError as e:\n    print(e)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert "pip install 'abkit[plot]'" in out.stdout
