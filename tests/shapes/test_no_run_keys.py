"""The geometry code never reads the run file's ``[run]`` table (issue 31).

What a template takes from the run (the perturbation's seed, the longest bond, the memory
budget) comes typed, in a ``TemplateSpec`` and a ``RunResources``; their two constructors
from a run configuration are the documented places of ``knotmm/shapes/`` that read ``run.*``
keys. Read from the source with ``ast``: a string that is a ``run.*`` key (``"run.seed"``,
not a message that names one) or a ``.table("run")`` anywhere else fails.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

SHAPES = Path(__file__).resolve().parents[2] / "knotmm" / "shapes"
#: (module file, qualified function) where reading ``run.*`` keys is the point.
ALLOWED = {("spec.py", "TemplateSpec.of"), ("resources.py", "RunResources.of")}
KEY = re.compile(r"run\.[a-z_]+")


def run_key_reads(source: str) -> list[tuple[str, int, str]]:
    """``(qualified function, line, what)`` of every ``run.*`` key read in ``source``."""
    found = []

    def visit(node, scope):
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                visit(child, [*scope, child.name])
                continue
            where = ".".join(scope) or "<module>"
            if (isinstance(child, ast.Constant) and isinstance(child.value, str)
                    and KEY.fullmatch(child.value)):
                found.append((where, child.lineno, child.value))
            elif (isinstance(child, ast.Call) and isinstance(child.func, ast.Attribute)
                  and child.func.attr == "table" and child.args
                  and isinstance(child.args[0], ast.Constant) and child.args[0].value == "run"):
                found.append((where, child.lineno, '.table("run")'))
            visit(child, scope)

    tree = ast.parse(source)
    for node in tree.body:  # skip the docstrings: they may name keys
        if not (isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant)):
            visit(ast.Module(body=[node], type_ignores=[]), [])
    return found


def test_the_reader_finds_key_reads_not_messages():
    src = ('def f(cfg):\n    """Uses run.seed."""\n    a = cfg["run.seed"]\n'
           '    b = f"run.max_bond_length={a}"\n    return cfg.table("run"), cfg["knot.seed"]\n')
    assert [(w, what) for w, _, what in run_key_reads(src)] == [
        ("f", "run.seed"), ("f", '.table("run")')]


def test_no_module_of_shapes_reads_the_run_table():
    reads = []
    for path in sorted(SHAPES.glob("*.py")):
        for where, line, what in run_key_reads(path.read_text()):
            if (path.name, where) not in ALLOWED:
                reads.append(f"knotmm/shapes/{path.name}:{line} {where}: {what}")
    assert not reads, "the geometry reads run.* keys:\n" + "\n".join(reads)
