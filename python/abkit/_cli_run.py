"""``abkit run``: filter a file of tracks (CSV, Parquet, .npy, .npz).

Registered as a subcommand by :mod:`abkit.cli` (``add_parser``). Layouts:

- ``.npy`` / ``.npz`` arrays: ``(n_samples,)`` or ``(n_tracks, n_samples)``;
  an ``.npz`` may also hold timestamps (``--time KEY``, same shape) and, for
  ragged tracks, a flat ``z`` with ``--offsets KEY``.
- tables (CSV, Parquet), wide: no ``--id``; every measurement column is one
  track, every row one sample (``--time`` names a shared time column).
- tables, long: ``--id`` names the track column, one row per report
  (``--time``, ``--columns``); see :func:`abkit.frame.filter`.

Everything is processed in chunks of ``--chunk-rows`` rows (samples), the
filter state carried from chunk to chunk, so memory is bounded by a chunk,
not the file. Output is written to a temporary file next to ``OUTPUT`` and
renamed when complete.
"""

from __future__ import annotations

import argparse
import csv
import math
import os
import re
import sys
import tempfile
import time as _time
import warnings
import zipfile
from typing import Any, Dict, Iterator, List, Optional, Sequence, Tuple

import numpy as np

from ._cli_args import positive_float as _positive_float
from ._cli_args import positive_int as _positive_int

__all__ = ["add_parser"]

_FORMATS = {".csv": "csv", ".parquet": "parquet", ".pq": "parquet", ".npy": "npy", ".npz": "npz"}
_FRAME_EXTRA = "install abkit[frame] (or pip install pyarrow)"


class DataError(Exception):
    """Bad input data: reported as ``abkit run: error: ...``, exit status 1."""


class MissingExtra(Exception):
    """An optional dependency is missing: reported with install advice, exit 1."""


class _NotStreamable(Exception):
    """Long-format input not grouped by id (or not time-ordered within a
    track): the caller falls back to loading the file whole."""


class _NotGrouped(_NotStreamable):
    """The rows are not grouped by id: a time-ordered feed may still stream."""


# -- progress bar ------------------------------------------------------------------------
class Progress:
    """A small progress bar on stderr, drawn at most 10 times a second; silent
    when disabled (``--quiet``) or when stderr is not a terminal."""

    def __init__(self, total: Optional[float], unit: str, enabled: bool, stream: Any = None):
        self.total = total if total and total > 0 else None
        self.unit = unit
        self.stream = stream if stream is not None else sys.stderr
        self.enabled = enabled
        self.t0 = _time.monotonic()
        self.last = 0.0
        self.done = 0.0
        self.drawn = False

    def update(self, done: float, force: bool = False) -> None:
        self.done = done
        if not self.enabled:
            return
        now = _time.monotonic()
        if not force and now - self.last < 0.1:
            return
        self.last = now
        el = now - self.t0
        if self.total:
            frac = min(1.0, done / self.total)
            bar = "#" * int(30 * frac) + "." * (30 - int(30 * frac))
            text = f"\rabkit run [{bar}] {100 * frac:5.1f}% {_si(done)}/{_si(self.total)} {self.unit} {el:6.1f} s"
        else:
            text = f"\rabkit run {_si(done)} {self.unit} {el:6.1f} s"
        self.stream.write(text)
        self.stream.flush()
        self.drawn = True

    def close(self) -> None:
        if self.enabled:
            self.update(self.total if self.total else self.done, force=True)
            if self.drawn:
                self.stream.write("\n")
                self.stream.flush()


def _si(x: float) -> str:
    for f, s in ((1e9, "G"), (1e6, "M"), (1e3, "k")):
        if abs(x) >= f:
            return f"{x / f:.1f}{s}"
    return f"{x:.0f}"


# -- arguments -------------------------------------------------------------------------
_AB_FLAGS = ("sigma_w", "snr", "snr_db", "tracking_error", "bandwidth", "omega_n", "damping")
_ABG_FLAGS = ("sigma_p", "sigma_a", "gamma")
_SINGER_FLAGS = ("tau", "sigma_pos")


def add_parser(sub: Any) -> argparse.ArgumentParser:
    """Register ``abkit run`` on the subparsers object of :mod:`abkit.cli`."""
    r = sub.add_parser(
        "run",
        help="filter a file of tracks (CSV, Parquet, .npy, .npz) and write the estimates",
        description="Filter a file of tracks and write the estimates in the same format. "
        "Arrays (.npy/.npz): (n_samples,) or (n_tracks, n_samples). Tables (CSV/Parquet): wide "
        "(no --id: each measurement column is one track, each row a sample) or long (--id: one row "
        "per report). The file is streamed in chunks of --chunk-rows; long tables stream when grouped by "
        "id or ordered by --time (otherwise they are loaded whole, with a warning). The filter is designed with "
        "the flags of 'abkit design alphabeta|abg|singer'.",
        epilog="Exit status: 0 success, 1 bad data or a missing optional dependency, 2 usage error.",
    )
    r.add_argument("input", metavar="INPUT", help="input file (.csv, .parquet/.pq, .npy, .npz)")
    r.add_argument("-o", "--output", required=True, metavar="OUTPUT", help="output file, same format as INPUT")
    r.add_argument("--format", choices=("csv", "parquet", "npy", "npz"), help="file format (default: from the extension)")
    io = r.add_argument_group("data layout")
    io.add_argument("--id", help="long tables: the track id column")
    io.add_argument("--time", help="timestamp column (tables) or array name (.npz); seconds")
    io.add_argument("--columns", help="comma-separated measurement columns (default: every numeric column "
                    "except --id and --time)")
    io.add_argument("--key", help=".npz: name of the measurement array (default 'z', or the only array)")
    io.add_argument("--offsets", help=".npz: name of the offsets array of ragged tracks (z flat)")
    io.add_argument("--chunk-rows", type=_positive_int, default=1_000_000,
                    help="rows (samples) per chunk; memory is bounded by a chunk (default 1000000)")
    fl = r.add_argument_group("filter")
    fl.add_argument("--filter", choices=("alphabeta", "abg", "singer"), default="alphabeta",
                    help="filter family (default alphabeta)")
    fl.add_argument("--init", choices=("two-point", "first"), default="two-point", help="start-up (default two-point)")
    fl.add_argument("--max-gap", type=_positive_float, help="restart a track after a silence longer than this (needs --time)")
    fl.add_argument("--on-duplicate", choices=("raise", "drop"), default="raise",
                    help="non-increasing timestamps: error (default) or drop the later reports (needs --time)")
    fl.add_argument("-T", "--period", dest="T", type=float, help="sampling period (s)")
    d = r.add_argument_group("design (as in 'abkit design alphabeta|abg|singer')")
    d.add_argument("--sigma-w", type=float, help="alphabeta: white acceleration std")
    d.add_argument("--sigma-v", type=float, help="alphabeta: measurement noise std; abg: velocity process noise variance")
    d.add_argument("--snr", type=float, help="alphabeta: r = ((sigma_w T^2/2)/sigma_v)^2")
    d.add_argument("--snr-db", type=float, help="alphabeta: 10 log10 r")
    d.add_argument("--tracking-index", type=float, help="alphabeta: Kalata's lambda; abg: sqrt(sigma_a/sigma_m) T^2")
    d.add_argument("--tracking-error", type=float, help="alphabeta: sigma_t^2/sigma_v^2 in (0, 1)")
    d.add_argument("--bandwidth", type=float, help="alphabeta: noise bandwidth x period")
    d.add_argument("--omega-n", type=float, help="alphabeta: natural frequency (rad/s)")
    d.add_argument("--damping", type=float, help="alphabeta: damping ratio")
    d.add_argument("--alpha", type=float, help="alphabeta/abg: position gain")
    d.add_argument("--beta", type=float, help="alphabeta/abg: velocity gain x T")
    d.add_argument("--gamma", type=float, help="abg: acceleration gain (see --convention)")
    d.add_argument("--sigma-p", type=float, help="abg: position process noise variance")
    d.add_argument("--sigma-a", type=float, help="abg: acceleration process noise variance")
    d.add_argument("--sigma-m", type=float, help="abg: measurement noise variance; singer: rms manoeuvre acceleration")
    d.add_argument("--model", choices=("acceleration", "dwpa", "continuous"), default="acceleration",
                   help="abg: noise model of --tracking-index")
    d.add_argument("--convention", default="chen-chui", help="abg: gamma convention (default chen-chui)")
    d.add_argument("--tau", type=float, help="singer: manoeuvre time constant (s)")
    d.add_argument("--sigma-pos", type=float, help="singer: position measurement noise std")
    r.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    r.set_defaults(func=lambda a: _main(r, a))
    return r


def _make_filter(p: argparse.ArgumentParser, a: argparse.Namespace) -> Any:
    """The filter chosen by ``--filter`` and the design flags (usage errors exit 2)."""
    from . import abg, singer
    from .filters import AlphaBetaFilter, AlphaBetaGammaFilter

    def reject(names: Sequence[str], family: str) -> None:
        bad = [n for n in names if getattr(a, n) is not None]
        if bad:
            p.error(f"--{bad[0].replace('_', '-')} does not apply to --filter {family}")

    if a.filter == "alphabeta":
        from .cli import _design_from_args

        reject(_ABG_FLAGS + _SINGER_FLAGS, "alphabeta")
        if a.sigma_m is not None:
            p.error("--sigma-m does not apply to --filter alphabeta (use --sigma-v)")
        ns = argparse.Namespace(**vars(a))
        dab = _design_from_args(p, ns)
        T = a.T if a.T is not None else dab.T
        if T is None:
            if a.time is None:
                p.error("give the sampling period -T (or timestamps with --time)")
            T = 1.0
        if a.sigma_w is not None and a.sigma_v is not None:
            # from the noise: with --time, the design for every step dt (gain_schedule "design")
            return AlphaBetaFilter.from_noise(a.sigma_w, a.sigma_v, T)
        return AlphaBetaFilter.from_design(dab, T=T)
    if a.filter == "abg":
        reject(_AB_FLAGS + _SINGER_FLAGS, "abg")
        noise = [a.sigma_p, a.sigma_v, a.sigma_a, a.sigma_m]
        gains = [a.alpha, a.beta, a.gamma]
        srcs = [any(v is not None for v in noise), a.tracking_index is not None, any(v is not None for v in gains)]
        if sum(srcs) != 1:
            p.error("--filter abg: give exactly one design source: --sigma-p/--sigma-v/--sigma-a/--sigma-m, "
                    "--tracking-index, or --alpha/--beta/--gamma")
        if a.convention not in abg.CONVENTIONS:
            p.error(f"--convention must be one of {', '.join(sorted(abg.CONVENTIONS))}")
        h = a.T if a.T is not None else 1.0
        if srcs[0]:
            if a.sigma_a is None or a.sigma_m is None:
                p.error("--sigma-a and --sigma-m are required (--sigma-p, --sigma-v default to 0)")
            # from the noise: with --time, the design for every step dt (gain_schedule "design")
            return AlphaBetaGammaFilter.from_noise(a.sigma_p or 0.0, a.sigma_v or 0.0, a.sigma_a, a.sigma_m, h,
                                                   convention=a.convention)
        elif srcs[1]:
            d = abg.from_tracking_index(a.tracking_index, model=a.model, convention=a.convention)
        else:
            if any(v is None for v in gains):
                p.error("--alpha, --beta and --gamma go together")
            d = abg.analyze(a.alpha, a.beta, a.gamma, convention=a.convention)
        return d.filter(h)
    reject(_AB_FLAGS + _ABG_FLAGS + ("alpha", "beta", "tracking_index", "sigma_v"), "singer")
    if a.T is None or a.tau is None or a.sigma_m is None or a.sigma_pos is None:
        p.error("--filter singer needs -T, --tau, --sigma-m and --sigma-pos")
    return singer.tracking_filter(a.T, a.tau, a.sigma_m, a.sigma_pos)


def _main(p: argparse.ArgumentParser, a: argparse.Namespace) -> int:
    fmt = a.format or _FORMATS.get(os.path.splitext(a.input)[1].lower())
    if fmt is None:
        p.error(f"cannot tell the format of {a.input!r} from its extension; use --format csv|parquet|npy|npz")
    out_ext = _FORMATS.get(os.path.splitext(a.output)[1].lower())
    if out_ext is not None and out_ext != fmt:
        p.error(f"the output is written in the input's format ({fmt}); {a.output!r} looks like {out_ext}")
    if os.path.abspath(a.input) == os.path.abspath(a.output):
        p.error("OUTPUT must differ from INPUT")
    if (a.max_gap is not None or a.on_duplicate != "raise") and a.time is None:
        p.error("--max-gap and --on-duplicate need timestamps (--time)")
    if fmt in ("npy", "npz"):
        if a.id is not None or a.columns is not None:
            p.error("--id and --columns apply to tables (CSV, Parquet), not to arrays")
        if fmt == "npy" and (a.time is not None or a.key is not None or a.offsets is not None):
            p.error("--time, --key and --offsets apply to .npz files (an .npy holds one array)")
    elif a.key is not None or a.offsets is not None:
        p.error("--key and --offsets apply to .npz files")
    columns = None
    if a.columns is not None:
        columns = [c.strip() for c in a.columns.split(",")]
        if not all(columns):
            p.error(f"--columns: empty column name in {a.columns!r}")
        if len(set(columns)) != len(columns):
            p.error(f"--columns: repeated column name in {a.columns!r}")
        if a.id in columns or a.time in columns:
            p.error("--columns must not include the --id or --time column")
    try:
        filt = _make_filter(p, a)
    except (ValueError, TypeError, ArithmeticError) as exc:
        print(f"abkit run: error: design: {exc}", file=sys.stderr)
        return 2
    except Exception as exc:  # numpy.linalg.LinAlgError: no stabilising design
        print(f"abkit run: error: design: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 2
    if not os.path.exists(a.input):
        print(f"abkit run: error: {a.input}: no such file", file=sys.stderr)
        return 1
    kw: Dict[str, Any] = {}
    if a.max_gap is not None:
        kw["max_gap"] = a.max_gap
    if a.on_duplicate != "raise":
        kw["on_duplicate"] = a.on_duplicate
    job = _Job(a.input, a.output, fmt, filt, a.init, kw, a.chunk_rows, not a.quiet and sys.stderr.isatty())
    try:
        if fmt in ("npy", "npz"):
            job.arrays(a.key, a.time, a.offsets)
        else:
            job.table(a.id, a.time, columns)
    except DataError as exc:
        print(f"abkit run: error: {exc}", file=sys.stderr)
        return 1
    except MissingExtra as exc:
        print(f"abkit run: error: {exc}", file=sys.stderr)
        return 1
    except OSError as exc:
        print(f"abkit run: error: {exc}", file=sys.stderr)
        return 1
    return 0


# -- the job ---------------------------------------------------------------------------
_WHERE = re.compile(r"track (\d+), sample (\d+)")


class _Job:
    def __init__(self, src: str, dst: str, fmt: str, filt: Any, init: str, kw: Dict[str, Any], chunk: int, progress: bool):
        self.src, self.dst, self.fmt, self.filt, self.init, self.kw = src, dst, fmt, filt, init, kw
        self.chunk, self.progress = chunk, progress
        self.suffixes = ["pos", "vel", "acc"][: filt.n] if filt.n <= 3 else [f"x{i}" for i in range(filt.n)]

    # --- output written atomically ---
    def _tmp(self) -> str:
        d = os.path.dirname(os.path.abspath(self.dst))
        fd, path = tempfile.mkstemp(prefix=".abkit-run-", suffix=os.path.splitext(self.dst)[1], dir=d)
        os.close(fd)
        return path

    def _run(self, z: np.ndarray, where: Any, **kw: Any) -> Any:
        """filter.run with data errors restated as DataError naming the file
        and the place (``where(track, sample) -> str``)."""
        try:
            return self.filt.run(z, init=self.init, return_residuals=True, **kw, **self.kw)
        except ValueError as exc:
            msg = str(exc)
            m = _WHERE.search(msg)
            if m is None:
                raise DataError(f"{self.src}: {msg}") from None
            rest = msg[m.end():].lstrip(": ")
            raise DataError(f"{self.src}, {where(int(m.group(1)), int(m.group(2)))}: {rest}") from None

    # ---------------------------------------------------------------- arrays
    def arrays(self, key: Optional[str], tkey: Optional[str], okey: Optional[str]) -> None:
        with tempfile.TemporaryDirectory(prefix="abkit-run-") as tmp:
            if self.fmt == "npy":
                z = _load_npy(self.src)
                t = None
            else:
                names = _npz_names(self.src)
                if key is None:
                    key = "z" if "z" in names else names[0] if len(names) == 1 else None
                    if key is None:
                        raise DataError(f"{self.src}: several arrays ({', '.join(names)}) and none named 'z'; choose one with --key")
                for what, k in (("--key", key), ("--time", tkey), ("--offsets", okey)):
                    if k is not None and k not in names:
                        raise DataError(f"{self.src}: no array {k!r} ({what}); the file has {', '.join(names)}")
                z = _npz_member(self.src, key, tmp)
                t = None if tkey is None else _npz_member(self.src, tkey, tmp)
                if okey is not None:
                    offsets = np.asarray(_npz_member(self.src, okey, tmp))
                    self._ragged_arrays(z, t, offsets, key, tmp)
                    return
            self._rect_arrays(z, t, key or "z", tmp)

    def _check_array(self, name: str, a: np.ndarray, ndims: Tuple[int, ...]) -> None:
        if a.dtype.kind not in "iuf":
            raise DataError(f"{self.src}: array {name!r} must be numeric, got dtype {a.dtype}")
        if a.ndim not in ndims:
            raise DataError(f"{self.src}: array {name!r} must have shape (n_samples,) or (n_tracks, n_samples), got {a.shape}")

    def _rect_arrays(self, z: np.ndarray, t: Optional[np.ndarray], key: str, tmp: str) -> None:
        self._check_array(key, z, (1, 2))
        if t is not None:
            self._check_array("time", t, (1, 2))
            if t.shape != z.shape:
                raise DataError(f"{self.src}: timestamps have shape {t.shape}, measurements {z.shape}")
        z2 = z[None] if z.ndim == 1 else z
        t2 = None if t is None else (t[None] if t.ndim == 1 else t)
        n_tracks, n_samples = z2.shape
        dtype = z.dtype if z.dtype in (np.float32, np.float64) else np.dtype(np.float64)
        n = self.filt.n
        out_path = self._tmp()
        try:
            if self.fmt == "npy":
                states = np.lib.format.open_memmap(out_path, mode="w+", dtype=dtype, shape=(n,) + z.shape)
                res = None
            else:
                parts = {s: np.lib.format.open_memmap(os.path.join(tmp, f"{s}.npy"), mode="w+", dtype=dtype, shape=z.shape)
                         for s in ["position", "velocity", "acceleration"][:n] + ["residual"]}
                states, res = None, parts["residual"]
                if t is not None:
                    counts = {s: np.zeros(n_tracks, dtype=np.int64) for s in ("n_dropped", "n_restarts")}
            prog = Progress(z.size, "samples", self.progress)
            tb = max(1, min(n_tracks, self.chunk // max(1, n_samples)))
            sb = n_samples if tb * n_samples <= self.chunk else self.chunk
            done = 0
            for i0 in range(0, n_tracks, tb):
                i1 = min(n_tracks, i0 + tb)
                state = None
                for j0 in range(0, max(n_samples, 1), sb):
                    j1 = min(n_samples, j0 + sb)
                    zb = np.asarray(z2[i0:i1, j0:j1], dtype=dtype)
                    kw: Dict[str, Any] = {"state": state}
                    if t2 is not None:
                        kw["t"] = np.asarray(t2[i0:i1, j0:j1], dtype=np.float64)
                    r = self._run(zb, lambda k, s: f"track {i0 + k}, sample {j0 + s}", **kw)
                    state = r.state
                    if states is not None:
                        states.reshape((n,) + z2.shape)[:, i0:i1, j0:j1] = r.states
                    else:
                        for c, name in enumerate(["position", "velocity", "acceleration"][:n]):
                            parts[name].reshape(z2.shape)[i0:i1, j0:j1] = r.states[c]
                        parts["residual"].reshape(z2.shape)[i0:i1, j0:j1] = r.residuals
                        if t is not None:
                            for s in counts:
                                counts[s][i0:i1] += getattr(r, s)
                    done += zb.size
                    prog.update(done)
            prog.close()
            if states is not None:
                states.flush()
                del states
            else:
                for m in parts.values():
                    m.flush()
                extra = {}
                if t is not None:
                    extra = {s: (v[0] if z.ndim == 1 else v) for s, v in counts.items()}
                _write_npz(out_path, [os.path.join(tmp, f"{s}.npy") for s in parts], extra)
                del parts, res
            os.replace(out_path, self.dst)
        except BaseException:
            _remove(out_path)
            raise

    def _ragged_arrays(self, z: np.ndarray, t: Optional[np.ndarray], offsets: np.ndarray, key: str, tmp: str) -> None:
        """Flat ``z`` with ``offsets`` (track i = z[offsets[i]:offsets[i+1]]),
        streamed in row chunks; a track cut by a chunk boundary continues
        from its state. Same as ``filter.run(z, t=t, offsets=offsets)``."""
        from .dask import _state_rows
        from .frame import Grouping, run_grouped

        self._check_array(key, z, (1,))
        if offsets.dtype.kind not in "iu" or offsets.ndim != 1 or offsets.size < 1 or offsets[0] != 0 \
                or np.any(np.diff(offsets) < 0) or offsets[-1] != z.size:
            raise DataError(f"{self.src}: offsets must be 1-D integers starting at 0, non-decreasing, ending at "
                            f"len(z) = {z.size}")
        if t is not None and (t.shape != z.shape or t.dtype.kind not in "iuf"):
            raise DataError(f"{self.src}: timestamps must be numbers of the shape of z {z.shape}, got {t.shape} {t.dtype}")
        offsets = offsets.astype(np.int64)
        n_tracks, N = offsets.size - 1, z.size
        dtype = z.dtype if z.dtype in (np.float32, np.float64) else np.dtype(np.float64)
        n = self.filt.n
        names = ["position", "velocity", "acceleration"][:n] + ["residual"]
        parts = {s: np.lib.format.open_memmap(os.path.join(tmp, f"{s}.npy"), mode="w+", dtype=dtype, shape=(N,)) for s in names}
        dropped = np.zeros(n_tracks, dtype=np.int64)
        restarts = np.zeros(n_tracks, dtype=np.int64)
        out_path = self._tmp()
        try:
            prog = Progress(N, "samples", self.progress)
            carry = None
            for r0 in range(0, N, self.chunk):
                r1 = min(N, r0 + self.chunk)
                # the non-empty tracks with rows in [r0, r1), bounds relative to r0
                k0 = int(np.searchsorted(offsets, r0, side="right")) - 1
                k1 = int(np.searchsorted(offsets, r1, side="left"))
                lens = np.diff(np.clip(offsets[k0:k1 + 1] - r0, 0, r1 - r0))
                tracks = np.arange(k0, k1)[lens > 0]
                local = np.concatenate([[0], np.cumsum(lens[lens > 0])])
                g = Grouping(None, local.astype(np.int64), r1 - r0)
                zb = np.asarray(z[r0:r1], dtype=dtype)
                tb = None if t is None else np.asarray(t[r0:r1], dtype=np.float64)
                cont = carry is not None and offsets[tracks[0]] < r0

                def where(k: int, smp: int, _tr: np.ndarray = tracks, _g: Grouping = g, _r0: int = r0) -> str:
                    return f"track {int(_tr[k])}, sample {_r0 + _g.row(k, smp) - int(offsets[_tr[k]])}"

                try:
                    r = run_grouped(self.filt, g, [zb], tb, init=self.init, kw=self.kw,
                                    first_state=[carry] if cont else None, where=where)[0]
                except ValueError as exc:
                    raise DataError(f"{self.src}: {exc}") from None
                for c, name in enumerate(names[:-1]):
                    parts[name][r0:r1] = r.states[c]
                parts["residual"][r0:r1] = r.residuals
                np.add.at(dropped, tracks, r.n_dropped)
                np.add.at(restarts, tracks, r.n_restarts)
                nt = g.offsets.size - 1
                carry = _state_rows(r.state, nt - 1, nt)
                prog.update(r1)
            prog.close()
            for m in parts.values():
                m.flush()
            extra: Dict[str, np.ndarray] = {"offsets": offsets}
            if t is not None:
                extra.update(n_dropped=dropped, n_restarts=restarts)
            _write_npz(out_path, [os.path.join(tmp, f"{s}.npy") for s in names], extra)
            del parts
            os.replace(out_path, self.dst)
        except BaseException:
            _remove(out_path)
            raise

    # ---------------------------------------------------------------- tables
    def table(self, id_col: Optional[str], time_col: Optional[str], columns: Optional[List[str]]) -> None:
        reader = _TableReader(self.src, self.fmt, self.chunk, id_col, time_col, columns)
        if id_col is None:
            self._wide(reader, time_col)
            return
        try:
            try:
                self._long(reader, id_col, time_col, stream=True)
            except _NotGrouped as exc:
                if time_col is None:
                    raise
                reader = _TableReader(self.src, self.fmt, self.chunk, id_col, time_col, reader.given)
                self._feed(reader, id_col, time_col, exc)
        except _NotStreamable as exc:
            print(f"abkit run: warning: {self.src}: {exc}; loading the whole file (memory grows with the file; "
                  f"group the rows by --id, ordered by --time within a track, or order them by --time, to stream)",
                  file=sys.stderr)
            reader = _TableReader(self.src, self.fmt, self.chunk, id_col, time_col, reader.given)
            self._long(reader, id_col, time_col, stream=False)

    def _long(self, reader: "_TableReader", id_col: str, time_col: Optional[str], stream: bool) -> None:
        """Long tables. ``stream``: chunk by chunk, the track cut by a chunk
        boundary continued from its state; raises _NotStreamable when the
        rows are not grouped by id (or a track's times go back). Else the
        whole file at once, grouped and time-ordered like abkit.frame.filter."""
        import pyarrow as pa

        from .dask import _state_rows
        from .frame import group, run_grouped

        out_path = self._tmp()
        writer = None
        totals = {"tracks": 0, "rows": 0, "dropped": 0, "restarts": 0}
        try:
            prog = Progress(reader.total, reader.unit, self.progress and stream)
            chunks = iter(reader) if stream else iter([_whole(reader)])
            finished: set = set()
            carry: Optional[List[Any]] = None
            carry_id: Any = None
            carry_t = -math.inf
            names: List[List[str]] = []
            for row0, tab in chunks:
                cols = reader.columns or []
                if not names:
                    names = self._out_names(cols, tab.column_names)
                idcol = tab.column(id_col)
                if idcol.null_count:
                    i = int(np.flatnonzero(idcol.is_null().to_numpy(zero_copy_only=False))[0])
                    raise DataError(f"{self.src}, row {row0 + i + 1}, column {id_col!r}: missing track id")
                ids = idcol.to_numpy(zero_copy_only=False)
                t = None if time_col is None else reader.values(tab, time_col, row0, time=True)
                zs = [reader.values(tab, c, row0) for c in cols]
                nrow = len(ids)
                if stream:
                    change = ids[1:] != ids[:-1]
                    starts = np.concatenate([[0], np.flatnonzero(change) + 1])
                    run_ids = ids[starts].tolist()
                    cont = carry is not None and run_ids[0] == carry_id
                    if carry is not None and not cont:
                        finished.add(carry_id)
                    fresh = run_ids[1:] if cont else run_ids
                    if len(set(fresh)) != len(fresh) or any(v in finished for v in fresh):
                        raise _NotGrouped(f"the rows are not grouped by {id_col!r}")
                    if t is not None and nrow > 1 and np.any((np.diff(t) < 0) & ~change):
                        raise _NotStreamable(f"the times of a track go back in the file (column {time_col!r})")
                    if cont and t is not None and t[0] < carry_t:
                        raise _NotStreamable(f"the times of a track go back in the file (column {time_col!r})")
                    codes = np.repeat(np.arange(starts.size), np.diff(np.append(starts, nrow)))
                    finished.update(run_ids[:-1])
                else:
                    codes = pa.compute.dictionary_encode(idcol).combine_chunks().indices.to_numpy(zero_copy_only=False)
                    cont = False
                g = group(codes.astype(np.int64), t)

                def where(k: int, smp: int, _g: Any = g, _ids: Any = ids, _row0: int = row0) -> str:
                    r = _g.row(k, smp)
                    return f"row {_row0 + r + 1} ({id_col} {_ids[r]!r}), column {time_col!r}"

                first = [carry[c] for c in range(len(cols))] if cont and carry is not None else None
                try:
                    res = run_grouped(self.filt, g, zs, t, init=self.init, kw=self.kw, first_state=first, where=where)
                except ValueError as exc:
                    raise DataError(f"{self.src}, {exc}") from None
                nt = g.offsets.size - 1
                if res:
                    totals["dropped"] += int(res[0].n_dropped.sum())
                    totals["restarts"] += int(res[0].n_restarts.sum())
                totals["tracks"] += nt - (1 if cont else 0)
                totals["rows"] += nrow
                out = tab
                for row, r in zip(names, res):
                    states = g.put(r.states)
                    for c, nm in enumerate(row[:-1]):
                        out = out.append_column(nm, pa.array(states[c]))
                    assert r.residuals is not None
                    out = out.append_column(row[-1], pa.array(g.put(r.residuals)))
                if stream and nrow:
                    carry = [_state_rows(r.state, nt - 1, nt) for r in res]
                    carry_id = ids[-1]
                    carry_t = t[-1] if t is not None else -math.inf
                writer = writer or _TableWriter(out_path, self.fmt, out.schema)
                writer.write(out)
                prog.update(reader.progress())
            if writer is None:
                writer = _TableWriter(out_path, self.fmt, reader.empty_schema(self._out_names(reader.columns or [], [])))
            writer.close()
            prog.close()
            os.replace(out_path, self.dst)
        except BaseException:
            if writer is not None:
                writer.close()
            _remove(out_path)
            raise
        if self.progress:
            print(f"abkit run: {totals['tracks']} tracks, {totals['rows']} rows, {totals['dropped']} dropped as "
                  f"duplicates, {totals['restarts']} restarts after gaps", file=sys.stderr)

    def _feed(self, reader: "_TableReader", id_col: str, time_col: str, not_grouped: Exception) -> None:
        """A long table ordered by time (tracks interleaved): streamed chunk
        by chunk through one :class:`abkit.FeedTracker` per column (per-id
        state tables), the same estimates as grouping the whole file.
        Raises _NotStreamable when a time goes back in the file."""
        import pyarrow as pa

        from .feed import FeedTracker

        out_path = self._tmp()
        writer = None
        try:
            prog = Progress(reader.total, reader.unit, self.progress)
            trackers: List[FeedTracker] = []
            names: List[List[str]] = []
            t_last = -math.inf
            n_rows = 0
            for row0, tab in reader:
                cols = reader.columns or []
                if not names:
                    names = self._out_names(cols, tab.column_names)
                    trackers = [FeedTracker(self.filt, init=self.init, **self.kw) for _ in cols]
                idcol = tab.column(id_col)
                if idcol.null_count:
                    i = int(np.flatnonzero(idcol.is_null().to_numpy(zero_copy_only=False))[0])
                    raise DataError(f"{self.src}, row {row0 + i + 1}, column {id_col!r}: missing track id")
                ids = idcol.to_numpy(zero_copy_only=False)
                t = reader.values(tab, time_col, row0, time=True)
                if t.size and (t[0] < t_last or bool(np.any(t[1:] < t[:-1]))):
                    raise _NotStreamable(f"{not_grouped}, nor ordered by {time_col!r}")
                out = tab
                for tr, c, row in zip(trackers, cols, names):
                    try:
                        r = tr.update(ids, t, reader.values(tab, c, row0))
                    except ValueError as exc:
                        m = re.match(r"row (\d+) \(id .*?\): ", str(exc))
                        if m is None:
                            raise DataError(f"{self.src}: {exc}") from None
                        k = int(m.group(1))
                        rest = str(exc)[m.end():]
                        col = c if rest.startswith("z ") else time_col
                        raise DataError(f"{self.src}, row {row0 + k + 1} ({id_col} {ids[k]!r}), column {col!r}: {rest}") from None
                    for j, nm in enumerate(row[:-1]):
                        out = out.append_column(nm, pa.array(r.states[j]))
                    assert r.residuals is not None
                    out = out.append_column(row[-1], pa.array(r.residuals))
                if t.size:
                    t_last = float(t[-1])
                n_rows += len(ids)
                writer = writer or _TableWriter(out_path, self.fmt, out.schema)
                writer.write(out)
                prog.update(reader.progress())
            if writer is None:
                writer = _TableWriter(out_path, self.fmt, reader.empty_schema(self._out_names(reader.columns or [], [])))
            writer.close()
            prog.close()
            os.replace(out_path, self.dst)
        except BaseException:
            if writer is not None:
                writer.close()
            _remove(out_path)
            raise
        if self.progress:
            tr0 = trackers[0] if trackers else None
            print(f"abkit run: {0 if tr0 is None else tr0.n_tracks} tracks, {n_rows} rows (a feed ordered by time), "
                  f"{0 if tr0 is None else int(tr0.n_dropped.sum())} dropped as duplicates, "
                  f"{0 if tr0 is None else int(tr0.n_restarts.sum())} restarts after gaps", file=sys.stderr)

    def _out_names(self, columns: Sequence[str], existing: Sequence[str]) -> List[List[str]]:
        names = [[f"{c}_{s}" for s in self.suffixes] + [f"{c}_res"] for c in columns]
        for row in names:
            for nm in row:
                if nm in existing:
                    raise DataError(f"{self.src}: column {nm!r} already exists; it would be overwritten by an estimate")
        return names

    def _wide(self, reader: "_TableReader", time_col: Optional[str]) -> None:
        import pyarrow as pa

        out_path = self._tmp()
        writer = None
        try:
            prog = Progress(reader.total, reader.unit, self.progress)
            state = None
            names: List[List[str]] = []
            for row0, tab in reader:
                cols = reader.columns or []
                if not names:
                    names = self._out_names(cols, tab.column_names)
                z = np.stack([reader.values(tab, c, row0) for c in cols]) if cols else np.empty((0, tab.num_rows))
                kw: Dict[str, Any] = {"state": state}
                if time_col is not None:
                    tt = reader.values(tab, time_col, row0, time=True)
                    kw["t"] = np.ascontiguousarray(np.broadcast_to(tt, z.shape))
                r = self._run(z, lambda k, s: f"row {row0 + s + 1}, column {cols[k]!r}", **kw)
                state = r.state
                new = {}
                for k, row in enumerate(names):
                    for c, nm in enumerate(row[:-1]):
                        new[nm] = r.states[c, k]
                    new[row[-1]] = r.residuals[k]
                out = tab
                for nm, v in new.items():
                    out = out.append_column(nm, pa.array(v))
                writer = writer or _TableWriter(out_path, self.fmt, out.schema)
                writer.write(out)
                prog.update(reader.progress())
            if writer is None:  # empty input: header only
                writer = _TableWriter(out_path, self.fmt, reader.empty_schema(self._out_names(reader.columns or [], [])))
            writer.close()
            prog.close()
            os.replace(out_path, self.dst)
        except BaseException:
            if writer is not None:
                writer.close()
            _remove(out_path)
            raise


def _whole(reader: "_TableReader") -> Tuple[int, Any]:
    pa = reader.pa
    tabs = [tab for _, tab in reader]
    if not tabs:
        return 0, pa.table({c: pa.array([], pa.float64()) for c in reader.header}) if reader.fmt == "csv" else \
            reader._pf.schema_arrow.empty_table()
    return 0, pa.concat_tables(tabs).combine_chunks()


def _remove(path: str) -> None:
    try:
        os.remove(path)
    except OSError:
        pass


# -- array files -------------------------------------------------------------------------
def _load_npy(path: str) -> np.ndarray:
    try:
        return np.load(path, mmap_mode="r", allow_pickle=False)
    except ValueError as exc:
        raise DataError(f"{path}: not a readable .npy array ({exc})") from None


def _npz_names(path: str) -> List[str]:
    try:
        with zipfile.ZipFile(path) as zf:
            return [n[:-4] for n in zf.namelist() if n.endswith(".npy")]
    except zipfile.BadZipFile as exc:
        raise DataError(f"{path}: not a readable .npz file ({exc})") from None


def _npz_member(path: str, name: str, tmp: str) -> np.ndarray:
    """A member of an .npz as a read-only memory map: in place when stored
    uncompressed (np.savez), else decompressed to a temporary file first
    (np.savez_compressed). Never read whole into memory."""
    with zipfile.ZipFile(path) as zf:
        info = zf.getinfo(name + ".npy")
        if info.compress_type == zipfile.ZIP_STORED:
            with open(path, "rb") as f:
                f.seek(info.header_offset)
                head = f.read(30)
                if head[:4] != b"PK\x03\x04":
                    raise DataError(f"{path}: corrupt zip member {name!r}")
                start = info.header_offset + 30 + int.from_bytes(head[26:28], "little") + int.from_bytes(head[28:30], "little")
                f.seek(start)
                shape, fortran, dtype = _npy_header(f, path, name)
                data = f.tell()
            if dtype.hasobject:
                raise DataError(f"{path}: array {name!r} holds Python objects")
            if int(np.prod(shape)) == 0:
                return np.zeros(shape, dtype=dtype)
            return np.memmap(path, dtype=dtype, mode="r", offset=data, shape=shape, order="F" if fortran else "C")
        out = os.path.join(tmp, f"in-{name}.npy")
        with zf.open(info) as src, open(out, "wb") as dst:
            while True:
                block = src.read(1 << 24)
                if not block:
                    break
                dst.write(block)
    return _load_npy(out)


def _npy_header(f: Any, path: str, name: str) -> Tuple[Tuple[int, ...], bool, np.dtype]:
    fmt = np.lib.format
    try:
        version = fmt.read_magic(f)
        if version == (1, 0):
            return fmt.read_array_header_1_0(f)
        return fmt.read_array_header_2_0(f)
    except ValueError as exc:
        raise DataError(f"{path}: array {name!r} is not a valid .npy ({exc})") from None


def _write_npz(path: str, members: Sequence[str], extra: Dict[str, np.ndarray]) -> None:
    """An .npz (uncompressed, like np.savez) from .npy files on disk, copied
    in pieces, plus small in-memory arrays."""
    import io

    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_STORED, allowZip64=True) as zf:
        for m in members:
            zf.write(m, arcname=os.path.basename(m))
        for k, v in extra.items():
            buf = io.BytesIO()
            np.lib.format.write_array(buf, np.asarray(v), allow_pickle=False)
            zf.writestr(k + ".npy", buf.getvalue())


# -- table files -------------------------------------------------------------------------
def _pyarrow() -> Any:
    try:
        import pyarrow
        import pyarrow.csv  # noqa: F401
        import pyarrow.parquet  # noqa: F401
    except ImportError:
        raise MissingExtra(f"reading CSV and Parquet files needs pyarrow: {_FRAME_EXTRA}") from None
    return pyarrow


_NULLS = frozenset(["", "#N/A", "#N/A N/A", "#NA", "-1.#IND", "-1.#QNAN", "-NaN", "-nan", "1.#IND", "1.#QNAN",
                    "N/A", "NA", "NULL", "NaN", "n/a", "nan", "null"])


class _TableReader:
    """Chunks of exactly ``chunk`` rows (the last one shorter) of a CSV or
    Parquet file as pyarrow Tables, with the 0-based number of their first row."""

    def __init__(self, path: str, fmt: str, chunk: int, id_col: Optional[str], time_col: Optional[str], columns: Optional[List[str]]):
        pa = _pyarrow()
        self.pa, self.path, self.fmt, self.chunk = pa, path, fmt, chunk
        self.id_col, self.time_col = id_col, time_col
        self.given = columns
        self.columns: Optional[List[str]] = columns
        self._fh: Any = None
        if fmt == "csv":
            with open(path, newline="", encoding="utf-8", errors="replace") as f:
                header = next(csv.reader(f), None)
            if not header:
                raise DataError(f"{path}: empty file (no header row)")
            self.header = header
            self.total = float(os.path.getsize(path))
            self.unit = "bytes"
        else:
            try:
                self._pf = pa.parquet.ParquetFile(path)
            except Exception as exc:  # pyarrow.ArrowInvalid and friends
                raise DataError(f"{path}: not a readable Parquet file ({exc})") from None
            self.header = list(self._pf.schema_arrow.names)
            self.total = float(self._pf.metadata.num_rows)
            self.unit = "rows"
        for what, c in (("--id", id_col), ("--time", time_col)):
            if c is not None and c not in self.header:
                raise DataError(f"{path}: no column {c!r} ({what}); columns are {', '.join(self.header)}")
        for c in columns or []:
            if c not in self.header:
                raise DataError(f"{path}: no column {c!r} (--columns); columns are {', '.join(self.header)}")
        self._rows = 0

    def progress(self) -> float:
        if self.fmt == "csv":
            return float(self._fh.tell()) if self._fh is not None and not self._fh.closed else self.total
        return float(self._rows)

    def _batches(self) -> Iterator[Any]:
        pa = self.pa
        if self.fmt == "parquet":
            yield from self._pf.iter_batches(batch_size=self.chunk)
            return
        types: Dict[str, Any] = {}
        for c in self.header:
            if c == self.time_col or (self.given is not None and c in self.given):
                types[c] = pa.float64()
            elif self.given is not None or c == self.id_col:
                types[c] = pa.string()  # passed through as written
        # A native file, not a Python one: Arrow's read-ahead thread must never
        # need the GIL, or an error that ends the process while it is reading
        # aborts the interpreter at exit ("terminate called without an active
        # exception": the thread is killed taking the GIL during finalisation).
        self._fh = pa.OSFile(self.path, "rb")
        try:
            reader = pa.csv.open_csv(self._fh, read_options=pa.csv.ReadOptions(block_size=1 << 22),
                                     convert_options=pa.csv.ConvertOptions(column_types=types))
            while True:
                try:
                    yield reader.read_next_batch()
                except StopIteration:
                    return
        except pa.ArrowInvalid as exc:
            raise self._csv_error(exc) from None
        finally:
            self._fh.close()

    def _csv_error(self, exc: Exception) -> DataError:
        """Find the row of a CSV conversion error (Arrow names only the column)."""
        msg = str(exc)
        m = re.search(r"CSV column #(\d+)", msg)
        if m is None:
            return DataError(f"{self.path}: {msg}")
        col = int(m.group(1))
        name = self.header[col] if col < len(self.header) else f"#{col}"
        want_float = "double" in msg or "float" in msg
        with open(self.path, newline="", encoding="utf-8", errors="replace") as f:
            rd = csv.reader(f)
            next(rd, None)
            for i, row in enumerate(rd, start=1):
                if col >= len(row):
                    return DataError(f"{self.path}, row {i} (line {i + 1}): {len(row)} fields, expected {len(self.header)}")
                v = row[col].strip()
                if v in _NULLS:
                    continue
                try:
                    x = float(v)
                    if not want_float and x != int(x):
                        raise ValueError
                except (ValueError, OverflowError):
                    return DataError(f"{self.path}, row {i} (line {i + 1}), column {name!r}: not a number: {row[col]!r}")
        return DataError(f"{self.path}, column {name!r}: {msg}")

    def __iter__(self) -> Iterator[Tuple[int, Any]]:
        pa = self.pa
        pending: List[Any] = []
        have = 0
        row0 = 0
        for b in self._batches():
            if self.columns is None:
                self.columns = self._default_columns(b.schema)
            pending.append(b)
            have += b.num_rows
            while have >= self.chunk:
                tab = pa.Table.from_batches(pending).combine_chunks()
                head, rest = tab.slice(0, self.chunk), tab.slice(self.chunk)
                yield row0, head
                row0 += self.chunk
                self._rows = row0
                pending = rest.to_batches() if rest.num_rows else []
                have = rest.num_rows
        if have:
            yield row0, pa.Table.from_batches(pending).combine_chunks()
            self._rows = row0 + have

    def _default_columns(self, schema: Any) -> List[str]:
        pa = self.pa
        cols = [f.name for f in schema if f.name not in (self.id_col, self.time_col)
                and (pa.types.is_floating(f.type) or pa.types.is_integer(f.type))]
        if not cols:
            raise DataError(f"{self.path}: no numeric measurement columns; name them with --columns")
        return cols

    def values(self, tab: Any, name: str, row0: int, time: bool = False) -> np.ndarray:
        """A column as float64 (nulls -> NaN: missed detections; for the time
        column an error naming the row). Timestamps become seconds."""
        pa = self.pa
        col = tab.column(name)
        typ = col.type
        if time and (pa.types.is_timestamp(typ) or pa.types.is_date(typ)):
            col = col.cast(pa.timestamp("ns", tz=typ.tz if pa.types.is_timestamp(typ) else None)).cast(pa.int64())
            arr = col.to_numpy(zero_copy_only=False).astype(np.float64) / 1e9 if col.null_count == 0 else None
        elif pa.types.is_floating(typ) or pa.types.is_integer(typ) or pa.types.is_decimal(typ):
            arr = col.to_numpy(zero_copy_only=False).astype(np.float64, copy=False) if col.null_count == 0 else None
        else:
            raise DataError(f"{self.path}, column {name!r}: expected numbers, got {typ}")
        if arr is None:
            if time:
                i = int(np.flatnonzero(col.is_null().to_numpy(zero_copy_only=False))[0])
                raise DataError(f"{self.path}, row {row0 + i + 1}, column {name!r}: missing timestamp")
            arr = col.cast(pa.float64()).fill_null(float("nan")).to_numpy(zero_copy_only=False)
        if time and not np.all(np.isfinite(arr)):
            i = int(np.flatnonzero(~np.isfinite(arr))[0])
            raise DataError(f"{self.path}, row {row0 + i + 1}, column {name!r}: timestamp {arr[i]!r} is not finite")
        return arr

    def empty_schema(self, names: List[List[str]]) -> Any:
        pa = self.pa
        if self.fmt == "parquet":
            schema = self._pf.schema_arrow
        else:
            schema = pa.schema([pa.field(c, pa.string()) for c in self.header])
        for row in names:
            for nm in row:
                schema = schema.append(pa.field(nm, pa.float64()))
        return schema


class _TableWriter:
    def __init__(self, path: str, fmt: str, schema: Any):
        pa = _pyarrow()
        self.fmt = fmt
        if fmt == "csv":
            try:
                opts = pa.csv.WriteOptions(quoting_style="needed")
            except TypeError:  # pragma: no cover - old pyarrow
                opts = pa.csv.WriteOptions()
            self._w = pa.csv.CSVWriter(path, schema, write_options=opts)
        else:
            self._w = pa.parquet.ParquetWriter(path, schema)
        self._open = True

    def write(self, tab: Any) -> None:
        self._w.write_table(tab)

    def close(self) -> None:
        if self._open:
            self._w.close()
            self._open = False
