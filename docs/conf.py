"""Sphinx configuration of knotmm's documentation (API reference, user guide, notebooks).

Build it from the repository root, offline, with warnings as errors::

    python -m sphinx -W --keep-going -b html docs build/docs/html

The API pages document the checkout the docs are in (not an installed copy): the repository
root goes first on ``sys.path`` here and on ``PYTHONPATH`` for the notebook kernels.
Notebooks (``docs/notebooks/``) are executed by myst-nb on every build.
"""

from __future__ import annotations

import os
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
# the kernels that run the notebooks are separate processes: they import the same checkout
os.environ["PYTHONPATH"] = os.pathsep.join(
    p for p in (str(ROOT), os.environ.get("PYTHONPATH", "")) if p
)
# no window for matplotlib, in Sphinx's process and in the kernels
os.environ.setdefault("MPLBACKEND", "Agg")

import knotmm  # noqa: E402

project = "knotmm"
author = "knotmm developers"
copyright = "knotmm developers, MIT licence"  # noqa: A001 - Sphinx's name
release = knotmm.__version__
version = ".".join(release.split(".")[:2])

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    "myst_nb",  # MyST markdown pages and executed notebooks (it brings myst-parser)
]

exclude_patterns = ["_build", "jupyter_execute", "**.ipynb_checkpoints", "Thumbs.db"]
root_doc = "index"
language = "en"

# -- autodoc and napoleon (numpy-style docstrings) ------------------------------------------
autodoc_member_order = "bysource"
autodoc_typehints = "signature"
autodoc_preserve_defaults = True
napoleon_google_docstring = False
napoleon_numpy_docstring = True
# "Attributes" sections as :ivar: fields: as attribute directives they would duplicate the
# dataclass fields that autodoc documents itself
napoleon_use_ivar = True
napoleon_use_rtype = False
# Types as explicit roles: Sphinx would otherwise resolve every word of a type such as
# "ndarray, shape (n_frames, n_beads, 3)" fuzzily, and "n_frames" names several properties
napoleon_preprocess_types = True


def _short_type_names(app, what, name, obj, options, signature, return_annotation):
    """A dataclass with a ``default_factory`` field has the signature ``(..., x=<factory>)``,
    which is not Python: Sphinx then prints the whole signature as text, and its type names'
    ``~`` ("show the short name") would appear literally (``~knotmm.config.RunConfig``).
    Those signatures get the short names themselves; parseable ones are left to Sphinx."""
    if signature and "<factory>" in signature:
        signature = re.sub(r"~(?:\w+\.)*(\w+)", r"\1", signature)
    return signature, return_annotation


def _write_notebooks(app, exception):
    """Each MyST notebook of docs/notebooks/ also as a Jupyter notebook beside its page
    (``notebooks/NAME.ipynb`` in the built site, linked from the page), read by myst-nb's own
    reader, without outputs: open it in Jupyter and run it."""
    if exception is not None or app.builder.format != "html":
        return
    import nbformat
    from myst_nb.core.read import read_myst_markdown_notebook

    out = Path(app.outdir) / "notebooks"
    out.mkdir(parents=True, exist_ok=True)
    for page in sorted((ROOT / "docs" / "notebooks").glob("*.md")):
        notebook = read_myst_markdown_notebook(page.read_text(), path=str(page))
        nbformat.write(notebook, str(out / f"{page.stem}.ipynb"))


def setup(app):
    app.connect("autodoc-process-signature", _short_type_names)
    app.connect("build-finished", _write_notebooks)


# -- MyST and myst-nb -----------------------------------------------------------------------
myst_enable_extensions = ["dollarmath", "colon_fence"]
myst_heading_anchors = 3
nb_execution_mode = "force"  # every build runs the notebooks: they are examples and tests
nb_execution_timeout = 120  # seconds per cell
nb_execution_raise_on_error = True
nb_execution_show_tb = True
nb_merge_streams = True

# -- HTML -----------------------------------------------------------------------------------
html_theme = "alabaster"  # ships with Sphinx: nothing to fetch
html_title = f"knotmm {release}"
html_static_path: list[str] = []
