"""The ``abkit`` console script. Expected numbers come from Kalata's closed
forms (alpha from the tracking index), written out here independently of
abkit; relative tolerance 1e-12 unless stated."""

from __future__ import annotations

import json
import math
import pathlib
import subprocess
import sys

import pytest

RTOL = 1e-12


def run(*args: str, cwd: str | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "abkit", *args], capture_output=True, text=True, cwd=cwd)


def kalata(lam: float) -> tuple:
    """Kalata (1984): alpha and beta of the Kalman alpha-beta filter for index lam."""
    alpha = (-(lam**2) - 8 * lam + (lam + 4) * math.sqrt(lam**2 + 8 * lam)) / 8
    beta = (lam**2 + 4 * lam - lam * math.sqrt(lam**2 + 8 * lam)) / 4
    return alpha, beta


def test_design_json_matches_kalata() -> None:
    out = run("design", "alphabeta", "--sigma-w", "3.2", "--sigma-v", "32", "-T", "0.1", "--json")
    assert out.returncode == 0, out.stderr
    d = json.loads(out.stdout)
    lam = 3.2 * 0.1**2 / 32
    a, b = kalata(lam)
    # Kalata's printed form cancels at small lam: 1e-9 relative at lam = 1e-3.
    assert d["alpha"] == pytest.approx(a, rel=1e-9)
    assert d["beta"] == pytest.approx(b, rel=1e-9)
    assert d["g2"] == pytest.approx(b / 0.1, rel=1e-9)
    assert d["r"] == pytest.approx((lam / 2) ** 2, rel=RTOL)
    assert d["kalman_optimal"] is True and d["stable"] is True


@pytest.mark.parametrize(
    "args, lam",
    [
        (["--snr", "0.25"], 1.0),
        (["--snr-db", "0"], 2.0),
        (["--tracking-index", "0.7"], 0.7),
    ],
)
def test_design_sources(args: list, lam: float) -> None:
    out = run("design", "alphabeta", *args, "--json")
    assert out.returncode == 0, out.stderr
    d = json.loads(out.stdout)
    a, b = kalata(lam)
    assert d["alpha"] == pytest.approx(a, rel=1e-12)
    assert d["beta"] == pytest.approx(b, rel=1e-12)


def test_design_bandwidth_and_analysis() -> None:
    d = json.loads(run("design", "alphabeta", "--bandwidth", "0.1", "--damping", "0.8", "--json").stdout)
    x = math.sqrt(d["beta"])
    # eq (16) at the returned omega_n*T reproduces the requested bandwidth
    assert x * (1 + (1.6 - x) ** 2) / 6.4 == pytest.approx(0.1, rel=1e-12)
    assert d["alpha"] == pytest.approx(2 * 0.8 * x - x * x / 2, rel=1e-12)
    a = json.loads(run("design", "alphabeta", "--alpha", "0.5", "--beta", "3.5", "--json").stdout)
    assert a["stable"] is False and a["covariance_filtered"][0][0] is None


def test_table_output() -> None:
    out = run("design", "alphabeta", "--tracking-error", "0.5")
    assert out.returncode == 0
    assert "alpha (g1)" in out.stdout and "0.5" in out.stdout


@pytest.mark.parametrize(
    "args, needle",
    [
        (["--bandwidth", "0.3"], "bn_t"),
        (["--snr", "-1"], "r must be"),
        (["--sigma-w", "1", "--sigma-v", "1"], "-T"),
        (["--snr", "1", "--bandwidth", "0.1"], "exactly one"),
        (["--tracking-error", "1.5"], "ratio"),
    ],
)
def test_design_errors_exit_2(args: list, needle: str) -> None:
    out = run("design", "alphabeta", *args)
    assert out.returncode == 2
    assert needle in out.stderr
    assert "Traceback" not in out.stderr


def test_demo_writes_figure(tmp_path: pathlib.Path) -> None:
    """The demo's designs are printed (alpha-beta from Kalata's closed form at
    the scenario's tracking index sigma_m T^2 / sigma_pos = 5/30) and the
    figure is written."""
    pytest.importorskip("matplotlib")
    out = run("demo", "--out", str(tmp_path), "--tracks", "100", "--samples", "300")
    assert out.returncode == 0, out.stderr
    png = tmp_path / "abkit_demo.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 50_000
    a, b = kalata(5.0 / 30.0)
    assert f"alpha-beta        alpha={a:.4g}, beta={b:.4g}" in out.stdout
    assert "MISMATCHED" in out.stdout and "M samples/s" in out.stdout
    assert out.stderr == ""  # no progress bar when stderr is not a terminal


def test_demo_help() -> None:
    out = run("demo", "--help")
    assert out.returncode == 0
    for flag in ("--tracks", "--samples", "--seed", "--missed", "--out", "--no-plot"):
        assert flag in out.stdout


def _demo_rows(stdout: str) -> dict:
    rows = {}
    for ln in stdout.splitlines():
        if "filtered [" in ln or "smoothed [" in ln:
            label, rest = ln.split("]", 1)
            vals = [float(v) if v != "-" else None for v in rest.split()]
            rows[label + "]"] = vals
    return rows


def test_demo_errors_match_theory_without_misses() -> None:
    """No missed detections: every empirical rms error is within 3 % of the
    exact steady state under the true (Singer) model, for the mismatched
    alpha-beta and alpha-beta-gamma filters too; the Singer filter's own
    (design) theory equals the true-model theory."""
    out = run("demo", "--no-plot", "--tracks", "1500", "--samples", "500", "--seed", "1", "--missed", "0")
    assert out.returncode == 0, out.stderr
    rows = _demo_rows(out.stdout)
    assert len(rows) == 12
    checked = 0
    for label, (emp, th_true, th_design) in rows.items():
        if th_true is not None:
            assert abs(emp / th_true - 1) < 0.03, (label, emp, th_true)
            checked += 1
        if label.startswith("Singer"):
            assert th_true == th_design
    assert checked == 8  # 3 filters x 2 filtered + Singer's 2 smoothed
    # the design models of the mismatched filters are visibly wrong for alpha-beta
    emp, th_true, th_design = rows["alpha-beta position, filtered [m]"]
    assert th_design < 0.8 * emp


def test_demo_with_misses_is_a_little_worse_than_theory() -> None:
    out = run("demo", "--no-plot", "--tracks", "500", "--samples", "400", "--seed", "2", "--missed", "0.1")
    assert out.returncode == 0, out.stderr
    for label, (emp, th_true, _) in _demo_rows(out.stdout).items():
        if th_true is not None:
            assert 1.0 < emp / th_true < 1.2, (label, emp, th_true)


def test_demo_without_matplotlib_skips_the_figure(tmp_path: pathlib.Path) -> None:
    code = (
        "import sys; sys.modules['matplotlib'] = None\n"
        "from abkit.cli import main\n"
        f"sys.exit(main(['demo', '--tracks', '20', '--samples', '50', '--out', {str(tmp_path)!r}]))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert "figure skipped" in out.stderr and "pip install 'abkit[plot]'" in out.stderr
    assert "Traceback" not in out.stderr and not (tmp_path / "abkit_demo.png").exists()


def test_true_model_covariance_matched_equals_steady_state() -> None:
    """For the Singer filter (model = truth) the augmented-state theory equals
    the filter's own steady-state covariance (rtol 1e-9)."""
    import numpy as np

    from abkit import FixedGainFilter, _cli_demo, singer

    s = singer.steady_state(0.5, 7.0, 2.0, 10.0)
    f = FixedGainFilter(s.Phi, s.H, s.K, 0.5)
    p = _cli_demo.true_model_covariance(np.asarray(s.Phi), np.asarray(s.Q), np.asarray(s.R), np.asarray(s.Phi), np.asarray(s.H), np.asarray(s.K))
    np.testing.assert_allclose(p, f.covariances(s.Q, s.R).filtered, rtol=1e-9)
    np.testing.assert_allclose(p, s.P_filt, rtol=1e-8)


def test_progress_bar_only_on_a_terminal() -> None:
    import io

    from abkit._progress import Progress

    class Tty(io.StringIO):
        def isatty(self) -> bool:
            return True

    tty, plain = Tty(), io.StringIO()
    for stream in (tty, plain):
        with Progress(4, "work", stream=stream) as p:
            for _ in range(4):
                p.update()
    assert "work [" in tty.getvalue() and "100%" in tty.getvalue()
    assert plain.getvalue() == ""


@pytest.mark.parametrize("args", [["--tracks", "0"], ["--missed", "1.5"], ["--samples", "x"]])
def test_demo_bad_flags(args: list) -> None:
    out = run("demo", "--no-plot", *args)
    assert out.returncode == 2 and "Traceback" not in out.stderr


def test_design_abg_sources() -> None:
    """`abkit design abg`: noise, tracking index (closed form 2(1-s)^3 = lam s (1+s)) and analysis."""
    d = json.loads(run("design", "abg", "--sigma-a", "1", "--sigma-m", "1", "--json").stdout)
    s = math.sqrt(1 - d["alpha"])
    assert 2 * (1 - s) ** 3 == pytest.approx(s * (1 + s), rel=1e-12)
    assert d["near_optimal"] and d["convention"] == "chen-chui"
    t = json.loads(run("design", "abg", "--tracking-index", "1", "--convention", "standard", "--json").stdout)
    assert t["gamma"] == pytest.approx(2 * d["gamma"], rel=1e-14)
    n = json.loads(run("design", "abg", "--sigma-p", "0.3", "--sigma-v", "0.2", "--sigma-a", "0.1", "--sigma-m", "1", "-T", "0.7", "--json").stdout)
    assert n["h"] == 0.7 and n["noise_ratios"]["sigma_p"] == pytest.approx(0.3, rel=1e-10)
    c = json.loads(run("design", "abg", "--tracking-index", "1", "--model", "continuous", "--json").stdout)
    assert c["stable"] and c["alpha"] != d["alpha"]
    a = run("design", "abg", "--alpha", "0.5", "--beta", "0.2", "--gamma", "0.02")
    assert a.returncode == 0 and "near-optimal" in a.stdout


@pytest.mark.parametrize(
    "args,needle",
    [
        (["--sigma-a", "0", "--sigma-m", "1"], "Lemma 2"),
        (["--sigma-a", "-1", "--sigma-m", "1"], "sigma_a"),
        (["--tracking-index", "1", "--alpha", "0.5"], "exactly one"),
        (["--alpha", "0.5", "--beta", "0.2"], "go together"),
        (["--sigma-p", "1"], "required"),
    ],
)
def test_design_abg_errors_exit_2(args: list, needle: str) -> None:
    out = run("design", "abg", *args)
    assert out.returncode == 2 and needle in out.stderr


@pytest.mark.parametrize("sigma_vel", [None, 1.0])
def test_design_singer_json_matches_scipy(sigma_vel) -> None:
    """`abkit design singer --json`: the gain equals the Kalman gain from
    scipy's DARE for the Singer model built here with Van Loan's method
    (rtol 1e-8)."""
    import numpy as np
    import scipy.linalg as sl

    T, tau, sm, sp = 1.0, 10.0, 2.0, 5.0
    args = ["design", "singer", "-T", str(T), "--tau", str(tau), "--sigma-m", str(sm), "--sigma-pos", str(sp), "--json"]
    if sigma_vel is not None:
        args += ["--sigma-vel", str(sigma_vel)]
    out = run(*args)
    assert out.returncode == 0, out.stderr
    d = json.loads(out.stdout)
    a = 1.0 / tau
    A = np.array([[0, 1, 0], [0, 0, 1], [0, 0, -a]])
    Qc = np.zeros((3, 3))
    Qc[2, 2] = 2 * a * sm**2
    M = sl.expm(np.block([[-A, Qc], [np.zeros((3, 3)), A.T]]) * T)
    Phi = M[3:, 3:].T
    Q = Phi @ M[:3, 3:]
    H = np.eye(3)[:1] if sigma_vel is None else np.eye(3)[:2]
    R = np.diag([sp**2] + ([] if sigma_vel is None else [sigma_vel**2]))
    P = sl.solve_discrete_are(Phi.T, H.T, Q, R)
    K = P @ H.T @ np.linalg.inv(H @ P @ H.T + R)
    np.testing.assert_allclose(np.array(d["K"]), K, rtol=1e-8, atol=1e-12)
    assert d["method_used"] in ("closed-form", "numeric")


def test_design_singer_errors() -> None:
    out = run("design", "singer", "-T", "-1", "--tau", "10", "--sigma-m", "2", "--sigma-pos", "5")
    assert out.returncode == 2 and "T" in out.stderr and "Traceback" not in out.stderr
    out = run("design", "singer", "--tau", "10")
    assert out.returncode == 2


@pytest.mark.parametrize("dtype", ["float64", "float32"])
def test_bench_runs_and_prints_the_table(dtype: str) -> None:
    """`abkit bench` at a tiny size: every method is checked against abkit
    inside the command (it fails otherwise); the table lists them all. No
    timing assertions."""
    out = run("bench", "--tracks", "3", "--samples", "40", "--repeat", "1", "--dtype", dtype)
    assert out.returncode == 0, out.stderr
    for name in ("abkit, all cores", "abkit, 1 thread", "ceiling", "NumPy vectorised", "scipy.signal.lfilter", "pure Python loop"):
        assert name in out.stdout, name
    assert "M samples/s" in out.stdout and "of the memory-bandwidth ceiling" in out.stdout
    diffs = [float(ln.split()[-1]) for ln in out.stdout.splitlines() if ln.startswith(("NumPy", "scipy"))]
    assert len(diffs) == 2 and max(diffs) < (1e-9 if dtype == "float64" else 2e-3)


def test_bench_lfilter_coefficients_match_the_recursion() -> None:
    """The transfer functions the benchmark gives lfilter reproduce a plain
    alpha-beta loop from the zero state (rtol 1e-12)."""
    import numpy as np
    import scipy.signal

    from abkit import _cli_bench

    z = np.random.default_rng(5).normal(size=200).cumsum()
    bx, bv, den = _cli_bench._lfilter_coeffs()
    a, b, T = _cli_bench.ALPHA, _cli_bench.BETA, _cli_bench.T
    x = v = 0.0
    px, pv = [], []
    for zk in z:
        xp = x + T * v
        x, v = xp + a * (zk - xp), v + b / T * (zk - xp)
        px.append(x)
        pv.append(v)
    np.testing.assert_allclose(scipy.signal.lfilter(bx, den, z), px, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(scipy.signal.lfilter(bv, den, z), pv, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("args", [["--tracks", "0"], ["--dtype", "int8"], ["--repeat", "x"]])
def test_bench_bad_flags(args: list) -> None:
    out = run("bench", *args)
    assert out.returncode == 2 and "Traceback" not in out.stderr


def test_bench_without_scipy_says_so() -> None:
    code = (
        "import sys; sys.modules['scipy'] = None\n"
        "from abkit.cli import main\n"
        "sys.exit(main(['bench', '--tracks', '2', '--samples', '30', '--repeat', '1']))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert "scipy not installed" in out.stdout and "NumPy vectorised" in out.stdout
