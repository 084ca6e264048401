"""Analysis of saved trajectories: the observables of the sedimenting-knot study.

Measured on a steady window of a run, in model units (d, tau_d): the sedimentation speed V,
the major radius rho0 (and N l0 / (2 pi p)), tau_sed = 2 rho0 / V, the swirl and rotation
periods from Fourier spectra, a per-bead fit of the vortex-knot formula (docs/model.md,
"Observables") with the scaled coordinates that collapse all beads, the writhe and
handedness, the rotation sense seen from above, and the knot type along the run.

Examples
--------
>>> from knotmm.analysis import analyze_run
>>> result = analyze_run("runs/trefoil")                      # doctest: +SKIP
>>> result.to_dict()["tau_swirl_over_tau_sed"]                # doctest: +SKIP

Modules: :mod:`~knotmm.io.run_data` (loading), :mod:`~knotmm.analysis.window` (steady
window), :mod:`~knotmm.analysis.spectra`, :mod:`~knotmm.analysis.fit`,
:mod:`~knotmm.analysis.knot_types`, :mod:`~knotmm.analysis.plots` (imported on first use),
:mod:`~knotmm.analysis.body` (torus normal, body
cylindrical coordinates, flat-torus criterion), :mod:`~knotmm.analysis.detect` (is there a
swirl?), :mod:`~knotmm.analysis.regimes` and :mod:`~knotmm.analysis.regime_report` (regime
checks and their analysis.json keys), :mod:`~knotmm.analysis.bootstrap` (block-bootstrap
uncertainties), :mod:`~knotmm.analysis.replicas` (a sweep directory: mean +- standard error
over replicas), :mod:`~knotmm.analysis.objects` (what each object is measured as: a ring, an
open chain, a link, separate chains; the elasto-gravitation number) and
:mod:`~knotmm.analysis.chains` (a run of several chains).
"""

from knotmm.analysis.body import BodyFrame, body_frame
from knotmm.analysis.core import ANALYSIS_FILE, analyze, analyze_run
from knotmm.analysis.detect import SwirlDetection, detect_swirl
from knotmm.analysis.fit import ScaledCoordinates, VortexFit, fit_vortex_knot, scaled_coordinates
from knotmm.analysis.geometry import Cylindrical, cylindrical, winding_numbers
from knotmm.analysis.knot_types import KnotTypes, handedness, knot_types, rotation_sense
from knotmm.analysis.replicas import analyze_sweep
from knotmm.analysis.result import AnalysisResult, format_table
from knotmm.analysis.spectra import SpectralPeak, Spectrum, rotation_spectrum, swirl_spectrum
from knotmm.analysis.window import Window, steady_window
from knotmm.io.run_data import RunData, load_run

_PLOTS = (
    "plot_com_height",
    "plot_bead_coordinate",
    "plot_time_series",
    "plot_spectrum",
    "plot_collapse",
    "plot_snapshot",
    "save_plots",
)

__all__ = [
    "ANALYSIS_FILE",
    "AnalysisResult",
    "BodyFrame",
    "Cylindrical",
    "KnotTypes",
    "RunData",
    "ScaledCoordinates",
    "SpectralPeak",
    "Spectrum",
    "SwirlDetection",
    "VortexFit",
    "Window",
    "analyze",
    "analyze_run",
    "analyze_sweep",
    "body_frame",
    "cylindrical",
    "detect_swirl",
    "fit_vortex_knot",
    "format_table",
    "handedness",
    "knot_types",
    "load_run",
    "rotation_sense",
    "rotation_spectrum",
    "scaled_coordinates",
    "steady_window",
    "swirl_spectrum",
    "winding_numbers",
    *_PLOTS,
]


def __getattr__(name: str):
    # plotting imports matplotlib; load it only when a plot function is asked for
    if name in _PLOTS:
        from knotmm.analysis import plots

        return getattr(plots, name)
    raise AttributeError(f"module 'knotmm.analysis' has no attribute {name!r}")


def __dir__():
    """The module's names with the plot functions imported on first use."""
    return sorted(set(globals()) | set(_PLOTS))
