"""benchmarks/: a few scripts over one harness, and a README and references that name them.

Reads files only (no benchmark is run): every script in ``benchmarks/`` is in the README's
table; every timing script takes its repetitions, medians and result files from
``harness.py``; every command the README gives names a script and a sub-command that exist;
every ``benchmarks/<name>.py`` named anywhere in the repository exists.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BENCH = ROOT / "benchmarks"
README = BENCH / "README.md"
#: Programs that are not timings over the harness: the yardsticks (whole programs of their
#: own, held to knotmm by tests/e2e), the harness itself, and a count that is not a timing.
STANDALONE = {"harness", "numba_chain", "numba_brownian", "count_allocations",
              "count_launches", "probe_fsal_brownian", "probe_stale_factor"}
#: Modules that scripts import (not run themselves).
MODULES = {"force_layouts", "preload_shim"}
#: Where the repository names benchmark scripts.
REFERRING = ["README.md", "plugin/README.md", "docs", "examples", "knotmm", "tests",
             "benchmarks"]


def _scripts() -> dict[str, Path]:
    return {p.stem: p for p in sorted(BENCH.glob("*.py"))}


def _subcommands(path: Path) -> set[str]:
    """The names given to ``add_parser`` in a script (its sub-commands)."""
    tree = ast.parse(path.read_text())
    return {node.args[0].value for node in ast.walk(tree)
            if isinstance(node, ast.Call) and getattr(node.func, "attr", "") == "add_parser"
            and node.args and isinstance(node.args[0], ast.Constant)}


def _imports(path: Path) -> set[str]:
    tree = ast.parse(path.read_text())
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module:
            found.add(node.module)
    return found


@pytest.mark.parametrize("name", sorted(_scripts()))
def test_every_script_is_in_the_readme_table(name):
    rows = [line for line in README.read_text().splitlines() if line.startswith("| `")]
    assert any(line.startswith(f"| `{name}.py`") for line in rows), (
        f"benchmarks/{name}.py is not a row of the table at the top of benchmarks/README.md")


@pytest.mark.parametrize("name", sorted(set(_scripts()) - STANDALONE - MODULES))
def test_every_timing_script_uses_the_harness(name):
    path = _scripts()[name]
    assert "harness" in _imports(path), f"benchmarks/{name}.py does not use harness.py"
    text = path.read_text()
    assert "--quick" in text or "add_options" in text, f"benchmarks/{name}.py has no --quick"


def test_readme_commands_name_existing_scripts_and_subcommands():
    scripts = _scripts()
    commands = re.findall(r"python benchmarks/(\w+)\.py(?:[ \t]+([a-z][\w-]*))?",
                          README.read_text())
    assert commands
    for name, word in commands:
        assert name in scripts, f"benchmarks/README.md runs benchmarks/{name}.py, not there"
        subs = _subcommands(scripts[name])
        if subs:
            assert word in subs, (f"benchmarks/README.md runs {name}.py {word!r}; its "
                                  f"sub-commands are {sorted(subs)}")


def test_references_to_benchmark_scripts_exist():
    """Every ``benchmarks/<name>.py`` named in the repository exists, and a sub-command named
    with it in one code span (```benchmarks/bench_steps.py brownian```) too."""
    scripts = _scripts()
    named = re.compile(r"benchmarks/(\w+)\.py")
    spans = re.compile(r"`benchmarks/(\w+)\.py ([a-z][\w-]*)`")
    for entry in REFERRING:
        base = ROOT / entry
        files = [base] if base.is_file() else [
            p for p in base.rglob("*") if p.suffix in {".py", ".md", ".toml", ".rst", ".txt"}]
        for path in files:
            text = path.read_text(errors="replace")
            where = path.relative_to(ROOT)
            for name in named.findall(text):
                assert name in scripts, f"{where} names benchmarks/{name}.py, which is gone"
            for name, word in spans.findall(text):
                assert word in _subcommands(scripts[name]), (
                    f"{where}: benchmarks/{name}.py has no sub-command {word!r}")
