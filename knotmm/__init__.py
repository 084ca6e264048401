"""knotmm: knotted flexible filaments sedimenting at low Reynolds number.

OpenMM computes the chain's forces; a Python-side overdamped integrator applies the
Rotne-Prager-Yamakawa mobility; mdtraj handles trajectory files. Everything in the API is
in model units: bead diameter ``d``, force ``F0`` (gravity on one bead), time ``tau_d``.
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("knotmm")
except PackageNotFoundError:  # pragma: no cover - running from a source tree
    __version__ = "0.0.0+unknown"

__all__ = ["__version__"]
