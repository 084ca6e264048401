"""Knot templates: starting shapes of the bead chain, built and checked before any run.

Every template is a closed polygon of beads in d (``docs/model.md``, "Starting shapes"):

* :mod:`~knotmm.shapes.curves`: tube curves (torus knots, closed braids) and equal-chord
  bead placement;
* :mod:`~knotmm.shapes.knotinfo`: built-in braid words and the KnotInfo tables;
* :mod:`~knotmm.shapes.geometry`: :func:`torus_knot`, :func:`braid_knot`,
  :func:`named_knot`, :func:`from_file`, :func:`mirror_image` (arrays);
* :mod:`~knotmm.shapes.checks`: :func:`check_template` (bonds, steric distances, knot type);
* :mod:`~knotmm.shapes.builder`: :func:`build_template`, the one builder that reads a run
  file (its ``[knot]`` and ``[model]`` keys; what it takes of the run comes as a
  :class:`~knotmm.shapes.spec.TemplateSpec` and a
  :class:`~knotmm.shapes.resources.RunResources`), :func:`minimal_beads`, and
  :func:`build_system` (run file -> OpenMM objects).

Reading a frame of a PDB/DCD file lives in :mod:`knotmm.io.structure`.

Examples
--------
>>> from knotmm.shapes import torus_knot
>>> torus_knot(2, 3, beads=120).shape
(120, 3)
"""

from knotmm.shapes.builder import Template, build_system, build_template, minimal_beads
from knotmm.shapes.checks import BOND_TOLERANCE, TemplateCheck, check_template
from knotmm.shapes.geometry import braid_knot, from_file, mirror_image, named_knot, torus_knot
from knotmm.shapes.knotinfo import (
    BUILTIN_BRAIDS,
    knotinfo_available,
    list_named_knots,
    named_knot_word,
)

__all__ = [
    "BOND_TOLERANCE",
    "BUILTIN_BRAIDS",
    "Template",
    "TemplateCheck",
    "braid_knot",
    "build_system",
    "build_template",
    "check_template",
    "from_file",
    "knotinfo_available",
    "list_named_knots",
    "minimal_beads",
    "mirror_image",
    "named_knot",
    "named_knot_word",
    "torus_knot",
]
