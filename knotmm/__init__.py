"""knotmm: knotted flexible filaments sedimenting at low Reynolds number.

OpenMM computes the chain's forces; an overdamped integrator applies the
Rotne-Prager-Yamakawa mobility; mdtraj handles trajectory files. Everything in the API is
in model units: bead diameter ``d``, force ``F0`` (gravity on one bead), time ``tau_d``
(``docs/model.md``). The package layout follows the flow of ``docs/architecture.md``.

The public API (stable names)::

    from knotmm import RunConfig, run, resume, build_system, Simulation, load_run, analyze_run

Each name is imported on first use, so ``import knotmm`` stays cheap.
"""


#: the one place the version is written: ``pyproject.toml`` reads it from here (scikit-build-core's
#: regex metadata provider), so the installed distribution and the package agree without
#: importlib.metadata at import time (0.05 s of every command's start)
__version__ = "0.1.0"

#: public name -> the module that owns it
_PUBLIC = {
    "RunConfig": "knotmm.config",
    "run": "knotmm.workflow",
    "resume": "knotmm.workflow",
    "build_system": "knotmm.shapes.builder",
    "Simulation": "knotmm.engine.simulation",
    "load_run": "knotmm.io.run_data",
    "analyze_run": "knotmm.analysis.core",
}

__all__ = ["__version__", *_PUBLIC]


def __getattr__(name: str):
    owner = _PUBLIC.get(name)
    if owner is None:
        raise AttributeError(f"module 'knotmm' has no attribute {name!r}")
    from importlib import import_module

    value = getattr(import_module(owner), name)
    globals()[name] = value
    return value


def __dir__():
    """The public names only (``__all__``: the API and ``__version__``), as ``dir`` shows them.

    The module's helpers (``_PUBLIC``, the version lookup) are private, so that ``dir`` and
    tab completion show the API.
    """
    return sorted(__all__)
