"""The ``abkit`` command line.

Commands
--------
abkit design alphabeta ...
    Design or analyse an alpha-beta filter and print it as a table (or JSON).
abkit design abg ...
abkit design singer ...
    Near-optimal alpha-beta-gamma design (Chen & Chui) from the noise or the
    tracking index, or analysis of given gains.
abkit run INPUT -o OUTPUT ...
    Filter a file of tracks (CSV, Parquet, .npy, .npz); see ``abkit run --help``.
abkit demo
    Manoeuvring targets simulated, filtered and smoothed with alpha-beta,
    alpha-beta-gamma and Singer filters designed from the scenario's noise:
    empirical vs theoretical errors, throughput, a figure
    (``_cli_demo.py``).
abkit bench
    abkit's alpha-beta filter against NumPy, scipy.signal.lfilter and pure
    Python, and the memory-bandwidth ceiling (``_cli_bench.py``).
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import List, Optional, Sequence

from . import __version__
from ._cli_args import fraction as _fraction
from ._cli_args import positive_int as _positive_int
from . import abg
from . import alphabeta as ab

__all__ = ["main"]

_SOURCES = (
    ("noise", ("sigma_w", "sigma_v", "T")),
    ("snr", ("snr",)),
    ("snr_db", ("snr_db",)),
    ("tracking_index", ("tracking_index",)),
    ("tracking_error", ("tracking_error",)),
    ("bandwidth", ("bandwidth",)),
    ("natural_frequency", ("omega_n", "T")),
    ("gains", ("alpha", "beta")),
)


def _design_singer(a: argparse.Namespace) -> int:
    import numpy as np

    from . import singer

    try:
        r = singer.steady_state(a.T, a.tau, a.sigma_m, a.sigma_pos, a.sigma_vel, method=a.method)
    except (ValueError, TypeError, ArithmeticError) as exc:
        print(f"abkit design singer: error: {exc}", file=sys.stderr)
        return 2
    except Exception as exc:  # numpy.linalg.LinAlgError: no stabilising solution
        print(f"abkit design singer: error: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 2

    def conv(x: object) -> object:
        arr = np.asarray(x)
        if np.iscomplexobj(arr):
            return conv(np.stack([arr.real, arr.imag], axis=-1))
        if arr.dtype.kind in "fc":
            return [conv(v) for v in arr] if arr.ndim else (float(arr) if np.isfinite(arr) else None)
        return arr.tolist()

    fields = ["method_used", "K", "P_pred", "P_filt", "P_smooth", "eigenvalues", "rms_position", "rms_velocity",
              "rms_acceleration", "Phi", "Q", "H", "R"]
    if a.sigma_vel is None:
        fields += ["alpha", "beta", "gamma"]
    d = {"T": a.T, "tau": a.tau, "sigma_m": a.sigma_m, "sigma_pos": a.sigma_pos, "sigma_vel": a.sigma_vel}
    d.update({f: conv(getattr(r, f)) if f != "method_used" else str(r.method_used) for f in fields})
    if a.json:
        print(json.dumps(d, indent=2, allow_nan=False))
        return 0
    meas = "position only" if a.sigma_vel is None else f"position + velocity (sigma_vel={a.sigma_vel:g})"
    print(f"Singer (ECA) steady-state Kalman filter: T={a.T:g}, tau={a.tau:g}, sigma_m={a.sigma_m:g}, "
          f"sigma_pos={a.sigma_pos:g}, {meas}  [{r.method_used}]")
    with np.printoptions(precision=6, suppress=False, linewidth=100):
        print("  gain K (filter form):\n" + "\n".join("    " + ln for ln in str(np.asarray(r.K)).splitlines()))
        print("  rms prediction error: position {:.6g}, velocity {:.6g}, acceleration {:.6g}".format(
            float(np.sqrt(r.P_pred[0, 0])), float(np.sqrt(r.P_pred[1, 1])), float(np.sqrt(r.P_pred[2, 2]))))
        print("  rms filtered error:   position {:.6g}, velocity {:.6g}, acceleration {:.6g}".format(
            float(np.sqrt(r.P_filt[0, 0])), float(np.sqrt(r.P_filt[1, 1])), float(np.sqrt(r.P_filt[2, 2]))))
        print("  Hamiltonian eigenvalues outside the unit circle: " + ", ".join(f"{complex(e):.6g}" for e in np.ravel(r.eigenvalues)))
        if a.sigma_vel is None:
            print(f"  equivalent alpha-beta-gamma gains: alpha={float(np.asarray(r.alpha)):.6g}, beta={float(np.asarray(r.beta)):.6g}, gamma={float(np.asarray(r.gamma)):.6g}")
    return 0


def _design_from_args(p: argparse.ArgumentParser, a: argparse.Namespace) -> ab.AlphaBeta:
    given = {k for k in ("sigma_w", "sigma_v", "snr", "snr_db", "tracking_index", "tracking_error",
                         "bandwidth", "omega_n", "alpha", "beta") if getattr(a, k) is not None}
    damping = a.damping if a.damping is not None else ab.KALMAN_DAMPING
    if a.damping is not None and not given & {"bandwidth", "omega_n"}:
        p.error("--damping applies only to --bandwidth and --omega-n designs")

    def only(*names: str) -> bool:
        return given == set(names)

    if only("sigma_w", "sigma_v"):
        if a.T is None:
            p.error("--sigma-w/--sigma-v need -T")
        return ab.from_noise(a.sigma_w, a.sigma_v, a.T)
    if only("snr"):
        d = ab.from_snr(a.snr)
    elif only("snr_db"):
        d = ab.from_snr(10.0 ** (a.snr_db / 10.0))
    elif only("tracking_index"):
        d = ab.from_tracking_index(a.tracking_index)
    elif only("tracking_error"):
        d = ab.from_tracking_error(a.tracking_error)
    elif only("bandwidth"):
        d = ab.from_bandwidth(a.bandwidth, damping)
    elif only("omega_n"):
        if a.T is None:
            p.error("--omega-n needs -T")
        return ab.from_natural_frequency(a.omega_n, a.T, damping)
    elif only("alpha", "beta"):
        d = ab.analyze(a.alpha, a.beta)
    else:
        p.error(
            "give exactly one design source: --sigma-w/--sigma-v/-T, --snr, --snr-db, "
            "--tracking-index, --tracking-error, --bandwidth [--damping], "
            "--omega-n/-T [--damping], or --alpha/--beta"
        )
    if a.T is not None:
        d.T = a.T
    return d


def _design_alphabeta(p: argparse.ArgumentParser, a: argparse.Namespace) -> int:
    try:
        d = _design_from_args(p, a)
    except (ValueError, TypeError) as exc:
        print(f"abkit design alphabeta: error: {exc}", file=sys.stderr)
        return 2
    if a.json:
        print(json.dumps(d.to_dict(), indent=2, allow_nan=False))
    else:
        print(d.table())
    return 0


def _design_abg(p: argparse.ArgumentParser, a: argparse.Namespace) -> int:
    noise = [a.sigma_p, a.sigma_v, a.sigma_a, a.sigma_m]
    gains = [a.alpha, a.beta, a.gamma]
    srcs = [any(v is not None for v in noise), a.tracking_index is not None, any(v is not None for v in gains)]
    if sum(srcs) != 1:
        p.error("give exactly one design source: --sigma-p/--sigma-v/--sigma-a/--sigma-m [-T], "
                "--tracking-index, or --alpha/--beta/--gamma")
    try:
        if srcs[0]:
            if a.sigma_a is None or a.sigma_m is None:
                p.error("--sigma-a and --sigma-m are required (--sigma-p, --sigma-v default to 0)")
            h = a.T if a.T is not None else 1.0
            d = abg.from_noise(a.sigma_p or 0.0, a.sigma_v or 0.0, a.sigma_a, a.sigma_m, h, convention=a.convention)
        elif srcs[1]:
            d = abg.from_tracking_index(a.tracking_index, model=a.model, convention=a.convention)
        else:
            if any(v is None for v in gains):
                p.error("--alpha, --beta and --gamma go together")
            d = abg.analyze(a.alpha, a.beta, a.gamma, convention=a.convention)
    except (ValueError, TypeError, ArithmeticError) as exc:
        print(f"abkit design abg: error: {exc}", file=sys.stderr)
        return 2
    except Exception as exc:  # numpy.linalg.LinAlgError: no limiting gain
        print(f"abkit design abg: error: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 2
    if a.T is not None:
        d.h = a.T
    if a.json:
        print(json.dumps(d.to_dict(), indent=2, allow_nan=False))
    else:
        print(d.table())
    return 0


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="abkit", description="Design, analyse and run fixed-gain tracking filters.")
    p.add_argument("--version", action="version", version=f"abkit {__version__}")
    sub = p.add_subparsers(dest="command", required=True)

    d = sub.add_parser("design", help="design a filter")
    dsub = d.add_subparsers(dest="family", required=True)
    q = dsub.add_parser(
        "alphabeta",
        help="alpha-beta design (Kalman or deterministic) or analysis of given gains",
        description="Design an alpha-beta filter from one source and print it. "
        "Sources: physical noise (--sigma-w --sigma-v -T), SNR r (--snr or --snr-db), "
        "tracking index (--tracking-index), normalised tracking error (--tracking-error), "
        "noise bandwidth x period (--bandwidth [--damping]), natural frequency "
        "(--omega-n -T [--damping]), or analyse gains (--alpha --beta).",
    )
    q.add_argument("--sigma-w", type=float, help="white acceleration std (e.g. ft/s^2)")
    q.add_argument("--sigma-v", type=float, help="measurement noise std (e.g. ft)")
    q.add_argument("-T", "--period", dest="T", type=float, help="sampling period (s)")
    q.add_argument("--snr", type=float, help="r = ((sigma_w T^2/2)/sigma_v)^2")
    q.add_argument("--snr-db", type=float, help="10 log10 r")
    q.add_argument("--tracking-index", type=float, help="Kalata's lambda = sigma_w T^2 / sigma_v")
    q.add_argument("--tracking-error", type=float, help="sigma_t^2/sigma_v^2 in (0, 1)")
    q.add_argument("--bandwidth", type=float, help="noise bandwidth x period B_N*T")
    q.add_argument("--omega-n", type=float, help="natural frequency (rad/s)")
    q.add_argument("--damping", type=float, help="damping ratio (default 1/sqrt(2))")
    q.add_argument("--alpha", type=float, help="position gain (with --beta: analyse)")
    q.add_argument("--beta", type=float, help="velocity gain x T")
    q.add_argument("--json", action="store_true", help="print JSON instead of a table")
    q.set_defaults(func=lambda a: _design_alphabeta(q, a))

    g = dsub.add_parser(
        "abg",
        help="near-optimal alpha-beta-gamma design (Chen & Chui) or analysis of given gains",
        description="Design a near-optimal alpha-beta-gamma filter (the limiting Kalman gain) from "
        "the noise variances (--sigma-p --sigma-v --sigma-a --sigma-m [-T]) or the tracking index "
        "sqrt(sigma_a/sigma_m) T^2 (--tracking-index), or analyse gains (--alpha --beta --gamma).",
    )
    g.add_argument("--sigma-p", type=float, help="position process noise variance (default 0)")
    g.add_argument("--sigma-v", type=float, help="velocity process noise variance (default 0)")
    g.add_argument("--sigma-a", type=float, help="acceleration process noise variance (> 0)")
    g.add_argument("--sigma-m", type=float, help="measurement noise variance (> 0)")
    g.add_argument("-T", "--period", dest="T", type=float, help="sampling period h (default 1)")
    g.add_argument("--tracking-index", type=float, help="sqrt(sigma_a/sigma_m) T^2 (acceleration-driven model)")
    g.add_argument("--model", choices=("acceleration", "dwpa", "continuous"), default="acceleration",
                   help="noise model of --tracking-index (default acceleration; dwpa: same gains; "
                   "continuous: continuous white jerk)")
    g.add_argument("--alpha", type=float, help="position gain")
    g.add_argument("--beta", type=float, help="velocity gain x T")
    g.add_argument("--gamma", type=float, help="acceleration gain (see --convention)")
    g.add_argument("--convention", choices=sorted(abg.CONVENTIONS), default="chen-chui",
                   help="gamma convention (default chen-chui: gain gamma/T^2)")
    g.add_argument("--json", action="store_true", help="print JSON instead of a table")
    g.set_defaults(func=lambda a: _design_abg(g, a))

    sg = dsub.add_parser(
        "singer",
        help="steady-state Kalman filter of the Singer (exponentially correlated acceleration) model",
        description="Steady state of the Singer-model Kalman filter (Yoon & Hong closed form with a "
        "numeric fallback): gain, prediction/filtered covariances, Hamiltonian eigenvalues.",
    )
    sg.add_argument("-T", "--period", dest="T", type=float, required=True, help="sampling period (s)")
    sg.add_argument("--tau", type=float, required=True, help="manoeuvre time constant (s); inf for constant acceleration")
    sg.add_argument("--sigma-m", type=float, required=True, help="rms manoeuvre acceleration")
    sg.add_argument("--sigma-pos", type=float, required=True, help="position measurement noise std")
    sg.add_argument("--sigma-vel", type=float, default=None, help="velocity measurement noise std (omit: position only)")
    sg.add_argument("--method", choices=["auto", "closed-form", "numeric"], default="auto")
    sg.add_argument("--json", action="store_true", help="print JSON instead of a table")
    sg.set_defaults(func=_design_singer)

    from . import _cli_demo

    _cli_demo.add_parser(sub, _positive_int, _fraction)

    from . import _cli_bench

    _cli_bench.add_parser(sub, _positive_int)

    from . import _cli_run

    _cli_run.add_parser(sub)
    return p


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Entry point of the ``abkit`` console script."""
    args: List[str] = list(sys.argv[1:] if argv is None else argv)
    p = _parser()
    ns = p.parse_args(args)
    try:
        return int(ns.func(ns))
    except BrokenPipeError:  # e.g. `abkit design ... --json | head`
        import os

        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
