"""Packaging and documentation checks: doctests, the .pyi stub, README/CI
consistency, and the errata check script."""

from __future__ import annotations

import doctest
import importlib
import pathlib
import re
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("module", ["abkit.abg", "abkit.alphabeta", "abkit.riccati", "abkit.singer", "abkit.plot", "abkit.cli", "abkit.filters", "abkit.kalman", "abkit.feed"])
def test_doctests(module: str) -> None:
    """Every docstring example runs and prints what it shows."""
    pytest.importorskip("matplotlib")
    mod = importlib.import_module(module)
    res = doctest.testmod(mod, optionflags=doctest.NORMALIZE_WHITESPACE | doctest.ELLIPSIS)
    assert res.failed == 0
    if module != "abkit.cli":
        assert res.attempted > 0


def test_stub_matches_extension_module() -> None:
    """The hand-written _abkit.pyi agrees with the compiled module (mypy.stubtest)."""
    pytest.importorskip("mypy")
    out = subprocess.run(
        [sys.executable, "-m", "mypy.stubtest", "abkit._abkit"],
        capture_output=True,
        text=True,
        cwd=str(ROOT / "tests"),
    )
    assert out.returncode == 0, out.stdout + out.stderr


def _readme_commands() -> list:
    text = (ROOT / "README.md").read_text()
    setup = text.split("## Set up", 1)[1].split("\n## ", 1)[0]
    return re.findall(r"```sh\n(.*?)\n```", setup, flags=re.S)


def test_readme_has_exactly_two_setup_commands_and_ci_runs_the_test_one() -> None:
    cmds = _readme_commands()
    assert len(cmds) == 2, cmds
    assert "abkit demo" in cmds[0]
    assert "pytest" in cmds[1] and "cargo test" in cmds[1]
    ci = (ROOT / ".ci" / "run").read_text().strip().splitlines()
    assert ci[-1].strip() == cmds[1].strip(), "the last line of .ci/run must be the README's test command"


def test_errata_check_script_passes() -> None:
    """docs/errata_checks.py re-derives every erratum numerically and exits 0."""
    pytest.importorskip("scipy")
    pytest.importorskip("mpmath")
    out = subprocess.run([sys.executable, str(ROOT / "docs" / "errata_checks.py")], capture_output=True, text=True)
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-3000:]


def test_errata_check_script_001_passes() -> None:
    """docs/errata_checks_001.py (paper 001, Yoon & Hong) re-derives every erratum and exits 0."""
    pytest.importorskip("scipy")
    out = subprocess.run([sys.executable, str(ROOT / "docs" / "errata_checks_001.py")], capture_output=True, text=True)
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-3000:]


def test_errata_check_script_004_passes() -> None:
    """docs/errata_checks_004.py (paper 004, Chen & Chui) re-derives every erratum and exits 0."""
    pytest.importorskip("scipy")
    pytest.importorskip("mpmath")
    out = subprocess.run([sys.executable, str(ROOT / "docs" / "errata_checks_004.py")], capture_output=True, text=True)
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-3000:]


def test_singer_benchmark_runs() -> None:
    """bench/bench_singer.py runs (tiny sizes) and reports every path."""
    pytest.importorskip("scipy")
    out = subprocess.run(
        [sys.executable, str(ROOT / "bench" / "bench_singer.py"), "3000", "20"], capture_output=True, text=True
    )
    assert out.returncode == 0, out.stderr[-3000:]
    for key in ("abkit auto", "abkit numeric", "scipy loop", "speed-up"):
        assert key in out.stdout


def test_package_type_checks() -> None:
    """The public Python layer type-checks against the hand-written stub."""
    pytest.importorskip("mypy")
    out = subprocess.run(
        [sys.executable, "-m", "mypy", "--ignore-missing-imports", "--no-incremental", str(ROOT / "python" / "abkit")],
        capture_output=True,
        text=True,
        cwd=str(ROOT),
    )
    assert out.returncode == 0, out.stdout + out.stderr


def test_readme_quick_start_runs() -> None:
    """The README's Python quick start executes as written."""
    text = (ROOT / "README.md").read_text()
    code = re.findall(r"```python\n(.*?)\n```", text, flags=re.S)
    assert code, "README has no python quick start"
    lines = code[0].splitlines()
    assert len(lines) <= 12
    out = subprocess.run([sys.executable, "-c", code[0]], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr


def _nav_pages() -> list:
    text = (ROOT / "mkdocs.yml").read_text()
    nav = text.split("\nnav:\n", 1)[1].split("\n\n", 1)[0]
    return re.findall(r":\s*([\w./-]+\.md)\s*$", nav, flags=re.M)


def test_every_docs_page_is_in_the_site_nav() -> None:
    """Each Markdown page under docs/ is reachable from the MkDocs nav, and
    every nav entry exists (a new page must be added to mkdocs.yml)."""
    docs = ROOT / "docs"
    pages = sorted(str(p.relative_to(docs)) for p in docs.rglob("*.md"))
    nav = _nav_pages()
    assert len(nav) == len(set(nav)), "duplicate nav entries"
    assert sorted(nav) == pages, f"missing from nav: {sorted(set(pages) - set(nav))}; not in docs/: {sorted(set(nav) - set(pages))}"


@pytest.mark.parametrize("page", ["getting-started.md", "singer.md", "riccati.md", "plots.md"])
def test_docs_python_examples_run(page: str, tmp_path: pathlib.Path) -> None:
    """The ```python blocks of the page run, in order, in one namespace."""
    pytest.importorskip("matplotlib")
    blocks = re.findall(r"```python\n(.*?)\n```", (ROOT / "docs" / page).read_text(), flags=re.S)
    assert blocks
    code = "\n".join(blocks)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=str(tmp_path))
    assert out.returncode == 0, out.stderr


def test_mkdocs_build_strict(tmp_path: pathlib.Path) -> None:
    """The documentation site builds with --strict (CI runs it too)."""
    pytest.importorskip("mkdocs")
    pytest.importorskip("mkdocstrings")
    out = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-q", "-d", str(tmp_path / "site")],
                         capture_output=True, text=True, cwd=str(ROOT), env={**__import__("os").environ, "NO_MKDOCS_2_WARNING": "1"})
    assert out.returncode == 0, out.stdout + out.stderr
    assert (tmp_path / "site" / "api" / "filters" / "index.html").exists()
