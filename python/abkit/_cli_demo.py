"""``abkit demo``: manoeuvring targets filtered and smoothed, errors against theory.

The scenario: ``targets`` targets moving in the plane, each coordinate an
independent Singer process (exponentially correlated acceleration, Singer
1970; sampled exactly with :func:`abkit.singer.model`), measured in position
every ``T`` seconds with white noise, with missed detections (NaN). From
the scenario's noise the demo designs

* an alpha-beta filter (:func:`abkit.alphabeta.from_noise` with the white
  acceleration ``sigma_w = sigma_m``, the rms manoeuvre acceleration),
* a near-optimal alpha-beta-gamma filter (:func:`abkit.abg.from_noise`
  with the acceleration increment variance of one period,
  ``sigma_m^2 (1 - exp(-2 T / tau))``),
* the Singer filter (:func:`abkit.singer.steady_state` run by
  :class:`abkit.FixedGainFilter`), whose model is the truth,

filters and smooths every track with each, and prints the empirical rms
errors next to the exact steady-state values under the true (Singer)
model and under each filter's own design model.

Theory under the true model (:func:`true_model_covariance`): with the
filter's error ``e = M s - x`` (``s`` the true state, ``M`` picking the
filter's states), ``e' = (I - K H)[(M Phi_t - Phi_f M) s + Phi_f e + M w] - K v``.
For kinematic filters ``M Phi_t - Phi_f M`` acts on the acceleration only,
a stationary AR(1) process, so ``[a, e]`` is a stationary linear system
whose covariance is a Lyapunov equation. It is exact for any of the three
filters (for the Singer filter it is the usual steady state).
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from typing import Any, Dict, List, Optional, Tuple

import numpy as np

from ._progress import Progress

__all__ = ["add_parser", "true_model_covariance", "simulate"]

# The scenario (a manoeuvring aircraft seen by a surveillance radar).
T = 1.0  # s, scan period
TAU = 10.0  # s, manoeuvre correlation time
SIGMA_M = 5.0  # m/s^2, rms manoeuvre acceleration
SIGMA_POS = 30.0  # m, position measurement noise
SPEED = 150.0  # m/s, rms initial speed per coordinate


def _dlyap(a: np.ndarray, q: np.ndarray) -> np.ndarray:
    n = a.shape[0]
    x = np.linalg.solve(np.eye(n * n) - np.kron(a, a), q.reshape(-1)).reshape(n, n)
    return 0.5 * (x + x.T)


def true_model_covariance(phi_t: np.ndarray, q_t: np.ndarray, r: np.ndarray, phi_f: np.ndarray, h_f: np.ndarray, k: np.ndarray) -> np.ndarray:
    """Steady-state filtered error covariance of a fixed-gain kinematic filter
    (``phi_f``, ``h_f``, ``k``, states ``[position, velocity, ...]``) tracking
    the 3-state Singer truth (``phi_t``, ``q_t``, measurement noise ``r``).

    Raises ValueError if the model difference acts on more than the
    acceleration or the filter is unstable.
    """
    n = phi_f.shape[0]
    m_sel = np.eye(3)[:n]
    d = m_sel @ phi_t - phi_f @ m_sel
    if np.max(np.abs(d[:, :2])) > 1e-12 * max(1.0, float(np.max(np.abs(phi_t)))):
        raise ValueError("the model difference acts on position or velocity: no stationary error")
    ikh = np.eye(n) - k @ h_f
    a_aug = np.zeros((n + 1, n + 1))
    a_aug[0, 0] = phi_t[2, 2]
    a_aug[1:, 0] = ikh @ d[:, 2]
    a_aug[1:, 1:] = ikh @ phi_f
    if np.max(np.abs(np.linalg.eigvals(a_aug))) >= 1.0:
        raise ValueError("unstable: no steady-state error covariance")
    p = r.shape[0]
    g = np.zeros((n + 1, 3 + p))
    g[0, :3] = np.eye(3)[2]
    g[1:, :3] = ikh @ m_sel
    g[1:, 3:] = -k
    noise = np.zeros((3 + p, 3 + p))
    noise[:3, :3] = q_t
    noise[3:, 3:] = r
    return _dlyap(a_aug, g @ noise @ g.T)[1:, 1:]


def simulate(rng: np.random.Generator, n_rows: int, n_samples: int, phi: np.ndarray, q: np.ndarray, sigma_m: float, missed: float) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Truth (position, velocity) and measurements of ``n_rows`` independent
    Singer coordinates, stationary acceleration from the start."""
    lq = np.linalg.cholesky(q)
    s = np.empty((n_rows, 3))
    s[:, 0] = rng.normal(0.0, 1000.0, n_rows)
    s[:, 1] = rng.normal(0.0, SPEED, n_rows)
    s[:, 2] = rng.normal(0.0, sigma_m, n_rows)
    pos = np.empty((n_rows, n_samples))
    vel = np.empty((n_rows, n_samples))
    phi_t = phi.T.copy()
    lq_t = lq.T.copy()
    for k in range(n_samples):
        if k:
            s = s @ phi_t + rng.standard_normal((n_rows, 3)) @ lq_t
        pos[:, k] = s[:, 0]
        vel[:, k] = s[:, 1]
    z = pos + rng.normal(0.0, SIGMA_POS, pos.shape)
    if missed > 0:
        z[rng.random(z.shape) < missed] = np.nan
    return pos, vel, z


def _designs() -> Dict[str, Any]:
    from . import abg, singer
    from . import alphabeta as ab
    from .filters import AlphaBetaFilter, FixedGainFilter

    phi_t, q_t = singer.model(T, TAU, SIGMA_M)
    r = np.array([[SIGMA_POS**2]])
    d_ab = ab.from_noise(SIGMA_M, SIGMA_POS, T)
    f_ab = AlphaBetaFilter.from_design(d_ab)
    sig_a = SIGMA_M**2 * (1.0 - math.exp(-2.0 * T / TAU))
    d_abg = abg.from_noise(0.0, 0.0, sig_a, SIGMA_POS**2, T)
    f_abg = d_abg.filter(T)
    q_abg = np.diag([0.0, 0.0, sig_a])
    s = singer.steady_state(T, TAU, SIGMA_M, SIGMA_POS)
    f_s = FixedGainFilter(s.Phi, s.H, s.K, T)
    dw = np.array([[T * T / 2], [T]])
    return {
        "truth": (phi_t, q_t, r),
        "filters": [
            ("alpha-beta", f_ab, dict(), SIGMA_M**2 * (dw @ dw.T),
             f"alpha={d_ab.alpha:.4g}, beta={d_ab.beta:.4g} (white acceleration sigma_w = sigma_m)"),
            ("alpha-beta-gamma", f_abg, dict(Q=q_abg, R=r), q_abg,
             f"alpha={d_abg.alpha:.4g}, beta={d_abg.beta:.4g}, gamma={d_abg.gamma:.4g} (chen-chui; "
             f"Wiener acceleration, increment variance sigma_m^2 (1 - e^(-2T/tau)))"),
            ("Singer", f_s, dict(Q=np.asarray(s.Q), R=r), np.asarray(s.Q),
             f"K = [{', '.join(f'{float(v):.4g}' for v in np.ravel(s.K))}] (the true model)"),
        ],
    }


def _demo(a: argparse.Namespace) -> int:
    n_targets, n_samples, missed = a.tracks, a.samples, a.missed
    rng = np.random.default_rng(a.seed)
    des = _designs()
    phi_t, q_t, r = des["truth"]
    filters = des["filters"]
    print("abkit demo: manoeuvring targets (Singer model) filtered and smoothed")
    print(f"  {n_targets:,} targets x {n_samples:,} samples in the plane (x and y: {2 * n_targets:,} tracks), "
          f"T = {T:g} s, manoeuvre tau = {TAU:g} s, rms acceleration sigma_m = {SIGMA_M:g} m/s^2,")
    print(f"  position noise sigma = {SIGMA_POS:g} m, {missed:.0%} missed detections, seed {a.seed}")
    print("Filters designed from the scenario's noise:")
    for name, _, _, _, desc in filters:
        print(f"  {name:<17} {desc}")
    print()

    n_rows = 2 * n_targets
    chunk = max(1, min(n_rows, 2_000_000 // max(n_samples, 1)))
    chunk += chunk % 2  # whole targets
    warm = max(1, min(100, n_samples // 5))
    edge = slice(warm, n_samples - warm) if n_samples > 2 * warm else slice(warm, None)
    nf = len(filters)
    sse = np.zeros((nf, 2, 2))  # filter, (filtered, smoothed), (pos, vel)
    cnt = np.zeros((nf, 2, 2))
    curve = np.zeros((nf, 2, n_samples))  # squared error per sample: filtered position, velocity
    t_run = np.zeros(nf)
    t_smooth = np.zeros(nf)
    t_sim = 0.0
    keep: Dict[str, Any] = {}
    for _, f, _, _, _ in filters:  # start rayon's pool outside the timings
        f.run(np.zeros((4, 8)), threads=None)
    with Progress(n_rows, "abkit demo: simulating, filtering, smoothing") as bar:
        for start in range(0, n_rows, chunk):
            rows = min(chunk, n_rows - start)
            t0 = time.perf_counter()
            pos, vel, z = simulate(rng, rows, n_samples, phi_t, q_t, SIGMA_M, missed)
            t_sim += time.perf_counter() - t0
            truth = (pos, vel)
            for i, (name, f, skw, _, _) in enumerate(filters):
                t0 = time.perf_counter()
                res = f.run(z)
                t_run[i] += time.perf_counter() - t0
                t0 = time.perf_counter()
                sm = f.smooth(z, **skw)
                t_smooth[i] += time.perf_counter() - t0
                for j in range(2):
                    ef = res.states[j][:, warm:] - truth[j][:, warm:]
                    es = sm.states[j][:, edge] - truth[j][:, edge]
                    sse[i, 0, j] += float(np.nansum(ef * ef))
                    sse[i, 1, j] += float(np.nansum(es * es))
                    cnt[i, 0, j] += np.count_nonzero(~np.isnan(ef))
                    cnt[i, 1, j] += np.count_nonzero(~np.isnan(es))
                    curve[i, j] += np.nansum((res.states[j] - truth[j]) ** 2, axis=0)
                if start == 0:
                    keep[name] = (res.states[:2, :2].copy(), sm.states[:2, :2].copy())
            if start == 0:
                keep["truth"] = (pos[:2].copy(), vel[:2].copy(), z[:2].copy())
            bar.update(rows)

    theory_true: List[Optional[np.ndarray]] = []
    rows_out = []
    print(f"{'rms error':<42}{'empirical':>11}{'theory':>11}{'theory':>11}")
    print(f"{'':<42}{'':>11}{'(truth)':>11}{'(design)':>11}")
    for i, (name, f, skw, q_design, _) in enumerate(filters):
        try:
            p_true = true_model_covariance(phi_t, q_t, r, np.asarray(f.Phi), np.asarray(f.H), np.asarray(f.K))
        except ValueError:
            p_true = None
        theory_true.append(p_true)
        cov_d = f.covariances(q_design, r)
        matched = name == "Singer"
        for kind in range(2):
            for j, (qname, unit) in enumerate((("position", "m"), ("velocity", "m/s"))):
                emp = math.sqrt(sse[i, kind, j] / cnt[i, kind, j]) if cnt[i, kind, j] else float("nan")
                if kind == 0:
                    th_t = math.sqrt(p_true[j, j]) if p_true is not None else float("nan")
                    th_d = math.sqrt(cov_d.filtered[j, j])
                else:
                    sm_d = cov_d.smoothed
                    th_d = math.sqrt(sm_d[j, j]) if sm_d is not None else float("nan")
                    th_t = th_d if matched else float("nan")
                label = f"{name} {qname}, {'filtered' if kind == 0 else 'smoothed'} [{unit}]"
                rows_out.append((label, emp, th_t, th_d))
                tt = f"{th_t:>11.4g}" if math.isfinite(th_t) else f"{'-':>11}"
                td = f"{th_d:>11.4g}" if math.isfinite(th_d) else f"{'-':>11}"
                te = f"{emp:>11.4g}" if math.isfinite(emp) else f"{'-':>11}"
                print(f"{label:<42}{te}{tt}{td}")
    print("  theory (truth): exact steady state under the true Singer model (filtered; smoothed only where")
    print("    the filter's model is the truth). theory (design): under the filter's own design model --")
    print("    alpha-beta and alpha-beta-gamma are MISMATCHED (their models are not the Singer truth), so")
    print("    their design-model values are not what they achieve; the Singer filter's model matches.")
    if not cnt.all():
        print(f"  '-' in the empirical column: no samples after the {warm}-sample start-up (use more --samples).")
    if missed > 0:
        print(f"  Theory assumes every detection; {missed:.0%} missed detections raise the empirical values a little.")
    n = float(n_rows) * n_samples
    print(f"\nThroughput ({n / 1e6:.3g} M samples per filter; simulation took {t_sim:.2f} s):")
    for i, (name, _, _, _, _) in enumerate(filters):
        print(f"  {name:<17} filter {n / t_run[i] / 1e6:8.1f} M samples/s ({t_run[i]:.3f} s); "
              f"filter+smooth {n / t_smooth[i] / 1e6:8.1f} M samples/s ({t_smooth[i]:.3f} s)")
    print()
    if a.no_plot:
        return 0
    try:
        from . import plot

        plt = plot._pyplot()
    except ImportError:
        print("abkit demo: figure skipped: matplotlib is not installed (pip install 'abkit[plot]'); "
              "use --no-plot to silence this", file=sys.stderr)
        return 0
    os.makedirs(a.out, exist_ok=True)
    path = os.path.join(a.out, "abkit_demo.png")
    fig = _figure(plt, filters, keep, curve, n_rows, theory_true, n_samples)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    print(f"wrote the figure (tracks, estimates, error vs theory): {path}")
    return 0


def _figure(plt: Any, filters: list, keep: Dict[str, Any], curve: np.ndarray, n_rows: int, theory_true: list, n_samples: int) -> Any:
    fig, axs = plt.subplots(2, 2, figsize=(13.0, 9.5), constrained_layout=True)
    pos, vel, z = keep["truth"]
    sm_s = keep["Singer"][1]
    ax = axs[0, 0]
    w = slice(0, min(n_samples, 80))
    x0, y0 = pos[0][0], pos[1][0]
    ax.plot(z[0][w] - x0, z[1][w] - y0, ".", ms=4, color="C0", label="measurements")
    ax.plot(pos[0][w] - x0, pos[1][w] - y0, "-", color="0.2", lw=1.2, label="truth")
    est = keep["Singer"][0]
    ax.plot(est[0][0][w] - x0, est[0][1][w] - y0, "-", color="C3", lw=1.0, label="Singer filtered")
    ax.plot(sm_s[0][0][w] - x0, sm_s[0][1][w] - y0, "--", color="k", lw=1.0, label="Singer smoothed")
    ax.set_xlabel("x (m, from the start)")
    ax.set_ylabel("y (m, from the start)")
    ax.set_title(f"Target 1 in the plane, first {w.stop} scans")
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(loc="best", fontsize="small")
    ax = axs[0, 1]
    t = T * np.arange(n_samples)
    w = slice(0, min(n_samples, 120))
    ax.plot(t[w], z[0][w] - pos[0][w], ".", color="C0", ms=3, label="measurement - truth")
    for i, (name, _, _, _, _) in enumerate(filters):
        ax.plot(t[w], keep[name][0][0][0][w] - pos[0][w], "-", color=f"C{i + 1}", lw=1.0, label=f"{name} filtered - truth")
    ax.plot(t[w], sm_s[0][0][w] - pos[0][w], "--", color="k", lw=1.0, label="Singer smoothed - truth")
    ax.axhline(0.0, color="0.5", lw=0.6)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("x position error (m)")
    ax.set_title("Target 1, x: position errors (no dot: missed detection)")
    ax.legend(loc="best", fontsize="small")
    for j, (ax, qname, unit) in enumerate(((axs[1, 0], "position", "m"), (axs[1, 1], "velocity", "m/s"))):
        for i, (name, _, _, _, _) in enumerate(filters):
            ax.plot(t, np.sqrt(curve[i, j] / n_rows), "-", color=f"C{i + 1}", lw=1.0, label=f"{name}: empirical")
            p = theory_true[i]
            if p is not None:
                ax.axhline(math.sqrt(p[j, j]), color=f"C{i + 1}", ls="--", lw=1.2, label=f"{name}: theory (true model)")
        steady = [float(np.sqrt(np.median(curve[i, j, n_samples // 5:] / n_rows))) for i in range(len(filters))]
        lows = [math.sqrt(p[j, j]) for p in theory_true if p is not None] + steady
        ax.set_ylim(0.85 * min(lows), 1.2 * max(steady))
        ax.set_xlabel("time (s)")
        ax.set_ylabel(f"rms {qname} error over {n_rows:,} tracks ({unit})")
        ax.set_title(f"Filtered {qname} error vs theory (theory: no missed detections)")
        ax.legend(loc="upper right", fontsize="small", ncol=1)
        ax.grid(True, which="both", alpha=0.3)
    return fig


def add_parser(sub: Any, positive_int: Any, fraction: Any) -> argparse.ArgumentParser:
    """Register ``abkit demo`` on the CLI's subparsers."""
    dm = sub.add_parser(
        "demo",
        help="simulate manoeuvring targets, filter and smooth them with alpha-beta, alpha-beta-gamma and "
        "Singer filters, compare with theory",
        description="Simulate TRACKS manoeuvring targets (Singer model: exponentially correlated "
        "acceleration, tau = 10 s, rms 5 m/s^2) in the plane, SAMPLES radar scans each (T = 1 s, "
        "position noise 30 m, a fraction MISSED of missed detections); design alpha-beta, "
        "alpha-beta-gamma and Singer filters from the scenario's noise; filter and smooth every track; "
        "print the empirical rms errors next to the steady-state theory and the throughput; write "
        "abkit_demo.png (tracks, estimates, error vs theory) to OUT. Defaults: 10,000 targets x 1,000 "
        "samples (2 x 10^7 coordinate samples per filter).",
    )
    dm.add_argument("--tracks", type=positive_int, default=10000, metavar="TRACKS", help="simulated targets (default 10000)")
    dm.add_argument("--samples", type=positive_int, default=1000, metavar="SAMPLES", help="samples per target (default 1000)")
    dm.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    dm.add_argument("--missed", type=fraction, default=0.05, metavar="MISSED", help="fraction of missed detections in [0, 1) (default 0.05)")
    dm.add_argument("--out", default=".", help="directory for abkit_demo.png (default: current directory)")
    dm.add_argument("--no-plot", action="store_true", help="print the tables only (no figure)")
    dm.set_defaults(func=_demo)
    return dm
