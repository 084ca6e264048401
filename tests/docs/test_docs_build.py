"""The documentation builds, offline, with warnings as errors, and runs its notebooks.

Slow (a Sphinx build that executes docs/notebooks/, about a minute on 2 cores); skipped
where the ``docs`` extra (Sphinx, myst-nb, py3Dmol, ipykernel) is not installed.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow

DOCS = Path(__file__).resolve().parents[2] / "docs"


def test_sphinx_build_passes_with_warnings_as_errors(tmp_path):
    for module in ("sphinx", "myst_nb", "py3Dmol", "ipykernel"):
        pytest.importorskip(module, reason=f"{module} missing: pip install '.[docs]'")
    out = tmp_path / "html"
    proc = subprocess.run(
        [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-b", "html", "-q",
         str(DOCS), str(out)],
        capture_output=True, text=True, timeout=600,
    )
    assert proc.returncode == 0, f"sphinx failed:\n{proc.stdout[-4000:]}\n{proc.stderr[-8000:]}"

    # the API reference documents the public names, the lazily imported ones included
    api = {page: (out / "api" / f"{page}.html").read_text() for page in ("io", "analysis")}
    assert 'id="knotmm.io.run_data.RunData.to_mdtraj"' in api["io"]
    assert 'id="knotmm.analysis.plot_collapse"' in api["analysis"]
    assert 'id="knotmm.analysis.analyze"' in api["analysis"]
    # the notebook ran: its outputs are in the page
    notebook = (out / "notebooks" / "first_run.html").read_text()
    assert "RunData(" in notebook and "60 beads, 1 closed chain" in notebook
    assert "3dmolviewer" in notebook  # the py3Dmol view
    assert "V [d/tau_d]" in notebook  # the analysis summary
    # ... and as a Jupyter notebook beside the page, linked from it, with the page's code
    import nbformat

    assert 'href="first_run.ipynb"' in notebook
    ipynb = nbformat.read(str(out / "notebooks" / "first_run.ipynb"), as_version=4)
    nbformat.validate(ipynb)
    code = [c.source for c in ipynb.cells if c.cell_type == "code"]
    assert any("knotmm.RunConfig.from_dict" in c for c in code)
    # no signature shows a type as Sphinx's "~module.Name" text (dataclasses with a factory
    # default: their signatures are not parsed, issue 35)
    for page in sorted((out / "api").glob("*.html")):
        assert "~knotmm" not in page.read_text(), page.name
        assert "~pathlib" not in page.read_text(), page.name
    for page in ("model", "architecture", "guide/index", "api/index"):
        assert (out / f"{page}.html").is_file(), page
