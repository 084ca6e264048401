"""Which regime is a run in? Swirl detection, torus shape and tilt of the steady window.

:func:`assess` is called by :func:`knotmm.analysis.core.analyze` between finding the steady
window and measuring on it. On the body frame (:mod:`knotmm.analysis.body`) it

1. tests the window for a swirl (:func:`knotmm.analysis.detect.detect_swirl`). A run with no
   external force (``model.gravity = 0``) has none by construction: the overdamped
   dynamics ``dx/dt = M(x) F(x)`` with ``F = -grad U`` and a positive mobility ``M`` lowers
   ``U`` at every instant (``dU/dt = -F.MF <= 0``), so the chain converges to a steady
   shape and has no periodic orbit; what the detector sees there is that relaxation. When the
   window holds none, the rest of the usable trajectory is tested too; with no swirl anywhere
   there is no periodic state to find, so an automatic window becomes the whole usable
   trajectory (a rigid ring sinking and turning is steady throughout);
2. cuts an automatic window with a swirl that is mostly level (inclination at most
   :data:`knotmm.analysis.body.TILTED_DEG`) but tilts past it somewhere (a flip inside the
   window) to its longest level stretch, end reason ``"tilt"``;
3. moves an automatic window start past the initial relaxation of the swirl amplitude: the
   one-period running mean of the body-frame cross-section ``A_b(t) = sqrt(mean_i((rho_i -
   <rho>)^2 + z_i^2))`` must stay within :data:`RELAXATION_TOL` (5 %) of its level over
   the window's second half, or within 4 standard errors of that level when the data are
   noisier, from the start to the end of the window;
4. decides whether the window is a flat torus (:data:`TOROIDAL_WINDOW`: at least 80 % of its
   frames meet :data:`knotmm.analysis.body.TORUS_CRITERION`) and whether it is tilted (median
   inclination above :data:`knotmm.analysis.body.TILTED_DEG`). The lab-frame rotation sense
   and the vortex-knot fit are reported only for a toroidal, untilted window.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from scipy.ndimage import uniform_filter1d

from knotmm.analysis.body import TILTED_DEG, BodyFrame, body_frame, inclination_summary
from knotmm.analysis.detect import SwirlDetection, detect_swirl
from knotmm.analysis.window import MIN_FRAMES, Window, longest_run

__all__ = ["Regime", "assess", "RELAXATION_TOL", "TOROIDAL_WINDOW", "UNDRIVEN"]

#: Fraction of toroidal frames that makes a window toroidal.
TOROIDAL_WINDOW = 0.8
#: Relative band of the swirl amplitude that ends the initial relaxation.
RELAXATION_TOL = 0.05


@dataclass
class Regime:
    """What :func:`assess` found.

    Attributes
    ----------
    window : Window
        The window to measure on (possibly widened or started later than the one given).
    body : BodyFrame
        Over the whole trajectory.
    detection : SwirlDetection
        The swirl test on the (final) window.
    toroidal : bool
        The window is a flat torus.
    tilted : bool
        The window's median inclination exceeds ``TILTED_DEG``.
    summary : dict
        :func:`knotmm.analysis.body.inclination_summary` of the final window.
    notes : list of str
    """

    window: Window
    body: BodyFrame
    detection: SwirlDetection
    toroidal: bool
    tilted: bool
    summary: dict
    notes: list = field(default_factory=list)


#: Why an undriven run has no swirl (module docstring, item 1).
UNDRIVEN = (
    "no swirl: model.gravity = 0, and with no external force the overdamped chain only "
    "lowers its energy (dU/dt = -F.M F <= 0) until its shape is steady"
)


def _detect(body: BodyFrame, positions: np.ndarray, sel: slice,
            driven: bool = True) -> SwirlDetection:
    top = float(np.abs(positions[sel]).max())
    found = detect_swirl(body.times[sel], body.rho[sel], body.z[sel], max_coordinate=top)
    if not driven:
        return replace(found, detected=False, reason=UNDRIVEN, steady=True)
    return found


def _whole(window: Window, times: np.ndarray, n_usable: int, why: str) -> Window:
    """The window widened to the whole usable trajectory on its automatic sides."""
    start = 0 if window.automatic_start else window.start
    stop = n_usable - 1 if window.automatic_stop else window.stop
    end = window.end_reason
    if window.automatic_stop:
        end = "end of trajectory" if stop == len(times) - 1 else "knot type change"
    return _moved(window, times, start, stop, end_reason=end, criterion=why)


def _moved(window: Window, times: np.ndarray, start: int, stop: int, **changes) -> Window:
    """The window with new first and last frames (and other changes); its notes dropped."""
    changes.setdefault("notes", [])
    return replace(
        window, start=start, stop=stop, t0=float(times[start]), t1=float(times[stop]), **changes
    )


def _level_stretch(body: BodyFrame, window: Window) -> tuple[int, int] | None:
    """Longest stretch of the window with inclination <= TILTED_DEG, if the window is mostly
    level but not everywhere (a flip inside it); None otherwise or if that is too short."""
    level = body.inclination[window.frames] <= TILTED_DEG
    if level.all() or level.mean() < 0.5:
        return None
    first, last = longest_run(level)
    if last - first + 1 < MIN_FRAMES:
        return None
    return window.start + first, window.start + last


def relaxation_end(body: BodyFrame, window: Window, frequency: float) -> int:
    """First frame of the window after the swirl amplitude's initial relaxation.

    Parameters
    ----------
    body : BodyFrame
    window : Window
    frequency : float
        Swirl frequency, 1/tau_d (sets the averaging over one period).

    Returns
    -------
    int
        A frame index, ``window.start`` if the amplitude is steady from the start.
    """
    sel = window.frames
    t = body.times
    dt = float(t[1] - t[0])
    rho, z = body.rho[sel], body.z[sel]
    amp = np.sqrt(np.mean((rho - rho.mean(axis=1, keepdims=True)) ** 2 + z**2, axis=1))
    size = max(1, int(round(1.0 / (abs(frequency) * dt)))) if frequency else 1
    smooth = uniform_filter1d(amp, size=size, mode="nearest")
    late = smooth[len(smooth) // 2 :]
    level = float(np.median(late))
    resid = amp[len(amp) // 2 :] - np.median(amp[len(amp) // 2 :])
    noise = 4.0 * 1.4826 * float(np.median(np.abs(resid))) / np.sqrt(size)
    band = max(RELAXATION_TOL * level, noise)
    bad = np.flatnonzero(np.abs(smooth - level) > band)
    bad = bad[bad < len(smooth) // 2]
    if not bad.size:
        return window.start
    # the running mean at frame k covers frames k - size/2 .. k + size/2
    return window.start + min(int(bad[-1]) + 1 + size // 2, window.n_frames - MIN_FRAMES)


def assess(times, positions, window: Window, n_usable: int, driven: bool = True) -> Regime:
    """Detect the swirl, fix the window's start, classify its shape (module docstring).

    Parameters
    ----------
    times : ndarray, shape (n_frames,)
        In tau_d.
    positions : ndarray, shape (n_frames, n_beads, 3)
        In d.
    window : Window
        From :func:`knotmm.analysis.window.steady_window`.
    n_usable : int
        Frames before a change of knot type (the automatic window stays inside them).
    driven : bool
        False for a run with no external force (``model.gravity = 0``): no swirl (module
        docstring).

    Returns
    -------
    Regime
    """
    x = np.asarray(positions, dtype=np.float64)
    body = body_frame(x, times)
    notes: list[str] = []
    detection = _detect(body, x, window.frames, driven)
    automatic = window.automatic_start or window.automatic_stop
    if not detection.detected and automatic:
        wide = _whole(
            window,
            body.times,
            n_usable,
            "no swirl detected in the body frame: no periodic state to find, so the "
            "window is the whole usable trajectory",
        )
        if (wide.start, wide.stop) != (window.start, window.stop):
            wide_detection = _detect(body, x, wide.frames, driven)
            if not wide_detection.detected:
                notes.append(
                    f"no swirl anywhere in the run: the window is widened from "
                    f"[{window.t0:g}, {window.t1:g}] to [{wide.t0:g}, {wide.t1:g}] tau_d"
                )
                window, detection = wide, wide_detection
    if detection.detected and window.automatic_start and window.automatic_stop:
        level = _level_stretch(body, window)
        if level is not None:
            notes.append(
                f"the torus tilts past {TILTED_DEG:g} deg inside the window "
                f"[{window.t0:g}, {window.t1:g}]: the window is cut to its longest level "
                f"stretch [{body.times[level[0]]:g}, {body.times[level[1]]:g}] tau_d"
            )
            end = "tilt" if level[1] < len(body.times) - 1 else window.end_reason
            window = _moved(window, body.times, *level, end_reason=end)
            detection = _detect(body, x, window.frames, driven)
    if detection.detected and window.automatic_start:
        start = relaxation_end(body, window, detection.frequency)
        if start > window.start:
            notes.append(
                f"the window starts at t = {body.times[start]:g} tau_d, after the initial "
                f"relaxation of the swirl amplitude (was {window.t0:g})"
            )
            window = _moved(window, body.times, start, window.stop, notes=window.notes)
            detection = _detect(body, x, window.frames, driven)
    summary = inclination_summary(body, window.frames)
    toroidal = summary["torus_fraction_window"] >= TOROIDAL_WINDOW
    tilted = summary["window_inclination_median_deg"] > TILTED_DEG
    if not toroidal:
        notes.append(
            f"the window is not a flat torus ({summary['torus_fraction_window']:.0%} of its "
            f"frames meet the shape criterion, {TOROIDAL_WINDOW:.0%} needed): rotation sense, "
            "vortex-knot fit and C are not reported"
        )
    elif tilted:
        notes.append(
            f"the torus is tilted in the window (median inclination "
            f"{summary['window_inclination_median_deg']:.3g} deg > {TILTED_DEG:g}): the "
            "lab-frame rotation sense is not reported; use the body-frame values"
        )
    if summary["tilts_after_window"]:
        notes.append(
            f"the torus tilts after the window: inclination up to "
            f"{summary['after_window_inclination_max_deg']:.3g} deg (at most "
            f"{summary['window_inclination_max_deg']:.3g} deg in the window)"
        )
    if body.max_turn_deg > 45.0:
        notes.append(
            f"the torus normal turns by up to {body.max_turn_deg:.3g} deg between frames: "
            "flips may be miscounted; write frames more often"
        )
    return Regime(window, body, detection, toroidal, tilted, summary, notes)
