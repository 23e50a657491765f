"""No panic crosses into Python (issue 8): the static rules that keep it so.

- The core and the bindings deny ``clippy::unwrap_used`` and
  ``clippy::expect_used`` outside tests, and CI runs clippy with
  ``-D warnings`` over the whole workspace (so the lint is really enforced).
- Independently of clippy, no ``.unwrap()``, ``.expect(``, ``panic!``,
  ``unreachable!``, ``todo!``, ``unimplemented!`` or ``unwrap_unchecked``
  appears in non-test Rust source (``src/tests/`` holds the unit tests).
- Every ``#[pyfunction]`` reaches the core only through ``convert::guard``
  (directly or through a ``convert`` helper that calls it), which turns a
  panic into a ``RuntimeError``.
"""

from __future__ import annotations

import pathlib
import re

ROOT = pathlib.Path(__file__).resolve().parents[1]
CRATES = [ROOT / "rust" / "abkit-core", ROOT / "rust" / "abkit-py"]
BANNED = re.compile(r"\.unwrap\(\)|\.expect\(|\bpanic!|\bunreachable!|\btodo!|\bunimplemented!|unwrap_unchecked")


def _strip_comments(text: str) -> str:
    text = re.sub(r"/\*.*?\*/", "", text, flags=re.S)
    return "\n".join(line.split("//", 1)[0] for line in text.splitlines())


def _sources() -> list:
    files = []
    for crate in CRATES:
        for p in sorted((crate / "src").rglob("*.rs")):
            if "tests" in p.relative_to(crate / "src").parts:
                continue
            files.append(p)
    return files


def test_lint_attribute_present_in_both_crates() -> None:
    for crate in CRATES:
        lib = (crate / "src" / "lib.rs").read_text()
        assert "#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]" in lib, crate.name


def test_ci_enforces_clippy_with_deny_warnings() -> None:
    ci = (ROOT / ".ci" / "run").read_text().splitlines()
    clippy = [i for i, line in enumerate(ci) if line.strip().startswith("cargo clippy")]
    assert clippy, "CI must run cargo clippy"
    line = ci[clippy[0]]
    assert "--workspace" in line and "--all-targets" in line and "-D warnings" in line, line
    assert "set -euo pipefail" in "\n".join(ci[:10]), "CI must stop on the first failing command"
    assert clippy[0] < len(ci) - 1


def test_no_unwrap_expect_or_panic_outside_tests() -> None:
    offenders = []
    sources = _sources()
    assert len(sources) >= 15, [str(p) for p in sources]
    for p in sources:
        text = _strip_comments(p.read_text())
        # inline test modules (none today) are exempt like src/tests/
        text = re.split(r"#\[cfg\(test\)\]\s*mod tests\s*\{", text)[0]
        for no, line in enumerate(text.splitlines(), 1):
            if BANNED.search(line):
                offenders.append(f"{p.relative_to(ROOT)}:{no}: {line.strip()}")
    assert not offenders, "panicking calls in non-test Rust code:\n" + "\n".join(offenders)


def test_the_rule_checker_catches_an_unwrap() -> None:
    """The pattern above is not vacuous."""
    for bad in ("let x = v.unwrap();", "y.expect(\"no\")", "panic!(\"x\")", "unreachable!()"):
        assert BANNED.search(_strip_comments(bad))
    assert not BANNED.search(_strip_comments("// v.unwrap() in a comment"))
    assert not BANNED.search("v.unwrap_or(0.0); w.unwrap_or_else(f)")


def _functions(text: str) -> dict:
    """name -> body of each top-level ``fn`` (up to the next item)."""
    parts = re.split(r"\n(?=(?:#\[[^\n]*\]\s*\n)*(?:pub(?:\([a-z]+\))? )?fn )", text)
    out = {}
    for part in parts:
        m = re.search(r"fn ([a-z_0-9]+)", part)
        if m:
            out[m.group(1)] = part
    return out


def test_every_binding_goes_through_the_panic_guard() -> None:
    src = ROOT / "rust" / "abkit-py" / "src"
    funcs: dict = {}
    for p in sorted(src.glob("*.rs")):
        funcs.update(_functions(_strip_comments(p.read_text())))
    # helpers that call guard, directly or through another such helper
    guarded = {name for name, body in funcs.items() if "guard(" in body and name != "guard"}
    while True:
        more = {n for n, b in funcs.items() if n not in guarded and any(re.search(rf"\b{g}(::<[^>]*>)?\(", b) for g in guarded)}
        if not more:
            break
        guarded |= more
    assert "rows" in guarded
    n = 0
    bad = []
    for p in sorted(src.glob("*.rs")):
        text = _strip_comments(p.read_text())
        for chunk in text.split("#[pyfunction]")[1:]:
            n += 1
            name = re.search(r"fn ([a-z_0-9]+)", chunk).group(1)
            if name not in guarded:
                bad.append(f"{p.name}: {name}")
    assert n >= 20, n
    assert not bad, f"bindings that call the core without convert::guard: {bad}"
