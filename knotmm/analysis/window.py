"""The steady window: where the knot is in its periodic falling state.

Criterion (used by ``knotmm analyze`` unless ``--from``/``--to`` are given)
--------------------------------------------------------------------------
Four per-frame signals describe the state of the structure:

* ``radius`` R(t): the mean bead distance from the vertical axis through the centre of mass
  (the torus radius), in d;
* ``cross_section`` A(t): the rms distance of the beads from the torus core circle,
  sqrt(mean((rho - R)^2 + (z - z_com)^2)), in d;
* ``speed`` v(t): the falling speed of the centre of mass, -dz_com/dt, in d/tau_d;
* ``tilt`` theta(t): the tilt of the structure's mean plane, 2 |sum_i z_i exp(i alpha_i)| /
  sum_i rho_i (z about the centre of mass), in rad; zero for a level torus knot.

The window is found in two passes.

1. Coarse: each signal is smoothed by a running median over ``smooth`` frames (default: 2 %
   of the trajectory, at least 5). The steady level of R, A and v is the *mode* of the
   smoothed signal (the value with the most frames near it); the band is ``tol`` (default
   5 %) of the steady radius for R and A, of the steady speed for v, and 0.1 rad for the
   tilt, widened to 4 standard errors of the smoothed signal when the data are noisy. The
   coarse window is the longest stretch in which all signals lie in their bands (gaps
   shorter than ``smooth`` frames closed).
2. Fine: the swirl period is measured on the coarse window and each signal is averaged
   over one period (which removes the swirl's ripple). The middle third of the coarse
   window is the reference: a signal's level is the median of its centred period average
   there, its band the larger of ``fine_tol`` (default 1 %) of the level (0.02 rad for the
   tilt) and 1.5 times the half-range (5th to 95th percentile) it spans there. The window
   grows from the reference in both directions while every signal stays in its band: going
   back, the average over the *following* swirl period is tested; going forward, the
   average over the *preceding* one, so that neither end is blurred by the averaging. The
   start thus skips the initial transient, including a swirl amplitude that is still
   relaxing; the end is where the periodic state ends.

The end is reported as a ``"collapse"`` when the radius is the signal that leaves its band
and then drops below its coarse band by more than the band's half-width again (the torus
radius shrank by more than 2 ``tol``), as a ``"departure: <signal>"`` of the first signal
to leave its band otherwise, or as the ``"end of trajectory"``. Independently,
``collapse_time`` is the first time after the window start at which the smoothed radius
is that far below its steady level (None if it never is).

An open chain (``steady_window(..., open_chain=True)``) has no torus: its signals are the
falling speed, the radius of gyration ``rg`` (d), the end-to-end length ``end_to_end`` (d)
and the end-to-end vector's angle to the vertical ``angle`` (rad); the same two passes run
with bands of ``tol`` and ``fine_tol`` of each signal's own level (the angle's 0.1 and 0.02 rad),
no swirl averaging, and no collapse: the end is a departure of a signal or the end of the
trajectory.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.ndimage import median_filter, uniform_filter1d

from knotmm.analysis.geometry import Cylindrical, cylindrical
from knotmm.analysis.spectra import swirl_spectrum
from knotmm.errors import ConfigError

__all__ = [
    "Window",
    "open_chain_signals",
    "steady_window",
    "window_signals",
    "longest_run",
    "rotation_unmeasured",
    "MIN_FRAMES",
    "MIN_ROTATION_FRACTION",
]

#: Fewest frames a window may hold (spectra and fits need several samples per period).
MIN_FRAMES = 16

#: Smallest part of one rotation a window must hold for tau_rot to be reported (issue 35:
#: "tau_rot 7189 +- 1.1e+05" came from 0 % of a turn). The examples' READMEs report tau_rot
#: from 24-76 % of a turn and bracket it as an extrapolation from 4-14 %; a steady rigid
#: rotation's line is exact to 1 % from a quarter turn.
MIN_ROTATION_FRACTION = 0.2

_SIGNALS = ("radius", "cross_section", "speed", "tilt")
#: An open chain's signals (no torus): speed, radius of gyration, end-to-end length and angle.
_OPEN_SIGNALS = ("speed", "rg", "end_to_end", "angle")
_ANGLES = ("tilt", "angle")  # bands in rad about their level, not relative
_COARSE_TILT = 0.1  # rad
_FINE_TILT = 0.02  # rad


@dataclass
class Window:
    """The time window the observables are measured on.

    Attributes
    ----------
    start, stop : int
        First and last frame (inclusive).
    t0, t1 : float
        Their times, in tau_d.
    automatic_start, automatic_stop : bool
        Whether each end was detected (True) or given by the user (False).
    end_reason : str
        ``"end of trajectory"``, ``"collapse"`` (the torus radius dropped well below its
        steady band), ``"departure: <signal>"`` (that signal left its band first) or ``"given"``.
    collapse_time : float or None
        First time after the window start at which the torus radius collapsed (fell more
        than 2 ``tol`` below its steady level), in tau_d; None if it never did.
    levels : dict
        Steady level and half-width of the fine band of each signal (``radius``,
        ``cross_section`` in d; ``speed`` in d/tau_d; ``tilt`` in rad).
    criterion : str
        One line describing how the window was chosen.
    notes : list of str
        Warnings (for example a window that is a small part of the trajectory).
    """

    start: int
    stop: int
    t0: float
    t1: float
    automatic_start: bool = True
    automatic_stop: bool = True
    end_reason: str = "end of trajectory"
    collapse_time: float | None = None
    levels: dict = field(default_factory=dict)
    criterion: str = ""
    notes: list = field(default_factory=list)

    @property
    def frames(self) -> slice:
        """Slice selecting the window's frames."""
        return slice(self.start, self.stop + 1)

    @property
    def n_frames(self) -> int:
        """Number of frames in the window."""
        return self.stop - self.start + 1

    def to_dict(self) -> dict:
        """JSON-ready description."""
        return {
            "t0": self.t0,
            "t1": self.t1,
            "frames": [self.start, self.stop],
            "automatic_start": self.automatic_start,
            "automatic_stop": self.automatic_stop,
            "end_reason": self.end_reason,
            "collapse_time": self.collapse_time,
            "levels": self.levels,
            "criterion": self.criterion,
        }


def window_signals(
    times: np.ndarray, positions: np.ndarray, cyl: Cylindrical | None = None
) -> dict[str, np.ndarray]:
    """Per-frame state signals used to find the steady window.

    Parameters
    ----------
    times : ndarray, shape (n_frames,)
        In tau_d.
    positions : ndarray, shape (n_frames, n_beads, 3)
        In d.
    cyl : Cylindrical, optional
        The positions' cylindrical coordinates, if already computed.

    Returns
    -------
    dict of ndarray, each shape (n_frames,)
        ``radius`` R (d), ``cross_section`` A (d), ``speed`` v = -dz_com/dt (d/tau_d) and
        ``tilt`` (rad).
    """
    cyl = cylindrical(positions) if cyl is None else cyl
    radius = cyl.rho.mean(axis=1)
    cross = np.sqrt(np.mean((cyl.rho - radius[:, None]) ** 2 + cyl.z**2, axis=1))
    speed = -np.gradient(cyl.com[:, 2], times) if len(times) > 1 else np.zeros(1)
    harmonic = np.abs((cyl.z * np.exp(1j * cyl.alpha)).sum(axis=1))
    with np.errstate(divide="ignore", invalid="ignore"):
        tilt = np.nan_to_num(2.0 * harmonic / cyl.rho.sum(axis=1))
    return {"radius": radius, "cross_section": cross, "speed": speed, "tilt": tilt}


def open_chain_signals(times: np.ndarray, positions: np.ndarray) -> dict[str, np.ndarray]:
    """Per-frame signals of an open chain's steady window.

    Parameters
    ----------
    times : ndarray, shape (n_frames,)
        In tau_d.
    positions : ndarray, shape (n_frames, n_beads, 3)
        In d, beads in chain order.

    Returns
    -------
    dict of ndarray, each shape (n_frames,)
        ``speed`` v = -dz_com/dt (d/tau_d), ``rg`` the radius of gyration (d),
        ``end_to_end`` |r_last - r_first| (d) and ``angle`` its angle to the vertical (rad).
    """
    x = np.asarray(positions, dtype=np.float64)
    com = x.mean(axis=1)
    speed = -np.gradient(com[:, 2], times) if len(times) > 1 else np.zeros(1)
    rg = np.sqrt(np.mean(np.sum((x - com[:, None, :]) ** 2, axis=-1), axis=1))
    e = x[:, -1] - x[:, 0]
    length = np.linalg.norm(e, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        angle = np.nan_to_num(np.arccos(np.clip(np.abs(e[:, 2]) / length, 0.0, 1.0)))
    return {"speed": speed, "rg": rg, "end_to_end": length, "angle": angle}


def rotation_unmeasured(period: float, uncertainty: float, length: float) -> str | None:
    """Why a rotation period is not measured in a window, or None when it is.

    Parameters
    ----------
    period, uncertainty : float
        The rotation spectrum's peak period and its standard error, in tau_d.
    length : float
        The window's length, in tau_d.

    Returns
    -------
    str or None
        The reason (for a note) when the window holds less than
        :data:`MIN_ROTATION_FRACTION` of a rotation or the uncertainty is not smaller than
        the period; None when the period is measured.
    """
    if not (math.isfinite(period) and period > 0):
        return f"the {length:g} tau_d window shows no rotation"
    fraction = length / period
    if fraction < MIN_ROTATION_FRACTION:
        return (f"the {length:g} tau_d window covers {fraction:.1%} of a rotation "
                f"(at least {MIN_ROTATION_FRACTION:.0%} needed)")
    if not (math.isfinite(uncertainty) and uncertainty < period):
        return "the rotation period's uncertainty is as large as the period itself"
    return None


def _mode_level(values: np.ndarray, half_width: float) -> float:
    """The most populated level: the value with the most values within +-half_width.

    A box-count mode is found with half the width, then refined by moving to the median
    of the values within +-half_width until it stops moving (a median mean-shift), so the
    level sits in the middle of a plateau rather than at its edge.
    """
    ordered = np.sort(values)
    narrow = 0.5 * half_width
    counts = np.searchsorted(ordered, ordered + narrow, side="right") - np.searchsorted(
        ordered, ordered - narrow, side="left"
    )
    level = float(np.median(ordered[counts == counts.max()]))
    for _ in range(50):
        near = ordered[np.abs(ordered - level) <= half_width]
        new = float(np.median(near)) if near.size else level
        if abs(new - level) <= 1e-9 * max(1.0, abs(level)):
            break
        level = new
    return level


def _close_gaps(mask: np.ndarray, max_gap: int) -> np.ndarray:
    """Mark short runs of False between True runs as True."""
    out = mask.copy()
    idx = np.flatnonzero(mask)
    if idx.size < 2:
        return out
    for g in np.flatnonzero(np.diff(idx) > 1):
        a, b = idx[g], idx[g + 1]
        if b - a - 1 <= max_gap:
            out[a:b] = True
    return out


def longest_run(mask: np.ndarray) -> tuple[int, int] | None:
    """First and last index of the longest stretch of True values (None if there is none)."""
    if not mask.any():
        return None
    edges = np.flatnonzero(np.diff(np.r_[False, mask, False].astype(np.int8)))
    starts, stops = edges[::2], edges[1::2] - 1
    k = int(np.argmax(stops - starts))
    return int(starts[k]), int(stops[k])


def _coarse(signals: dict[str, np.ndarray], smooth: int, tol: float,
            names: tuple[str, ...] = _SIGNALS):
    """Pass 1: mask of frames whose smoothed signals lie in their coarse bands."""
    smoothed = {k: median_filter(v, size=smooth, mode="nearest") for k, v in signals.items()}
    radius_level = None
    if "radius" in names:
        radius_level = _mode_level(smoothed["radius"], tol * np.median(smoothed["radius"]))
    bands: dict[str, tuple[float, float]] = {}
    mask = np.ones(len(signals[names[0]]), dtype=bool)
    for name in names:
        s = smoothed[name]
        resid = signals[name] - s
        noise = 4.0 * 1.4826 * np.median(np.abs(resid - np.median(resid))) / np.sqrt(smooth)
        if name == "tilt":
            level, half = 0.0, max(_COARSE_TILT, noise)
            mask &= s <= half
        elif name == "angle":  # about its own level, in rad
            half = max(_COARSE_TILT, noise)
            level = _mode_level(s, half)
            mask &= np.abs(s - level) <= half
        else:
            scale = radius_level
            if name not in ("radius", "cross_section"):  # the speed, an open chain's sizes
                scale = abs(_mode_level(s, tol * max(abs(np.median(s)), 1e-12)))
            half = max(tol * scale, noise, 1e-12)
            level = _mode_level(s, half)
            if name == "speed":
                half = max(tol * abs(level), noise, 1e-12)
            mask &= np.abs(s - level) <= half
        bands[name] = (level, half)
    return mask, smoothed, bands


def _swirl_frames(t, cyl: Cylindrical, start: int, stop: int) -> int:
    """The swirl period in frames, measured on frames start..stop (0 if unusable)."""
    sel = slice(start, stop + 1)
    period = swirl_spectrum(t[sel], cyl.rho[sel], cyl.z[sel]).peak.period
    width = int(round(period / (t[1] - t[0]))) if np.isfinite(period) else 0
    return width if 1 <= width <= (stop - start + 1) // 4 else 0


def _fine(t, cyl, signals, start: int, stop: int, fine_tol: float,
          names: tuple[str, ...] = _SIGNALS):
    """Pass 2: grow the window from the middle third of the coarse window (averaged over a
    swirl period where ``cyl`` is given, else frame by frame).

    Returns (start, stop, first signal to leave after the end or None, levels).
    """
    width = 0
    if cyl is not None and stop - start + 1 >= 2 * MIN_FRAMES:
        width = _swirl_frames(t, cyl, start, stop)
    size = max(width, 1)
    third = (stop - start + 1) // 3
    if third >= 2 * size:
        ref = slice(start + third, stop + 1 - third)
    else:
        ref = slice(start, stop + 1)
    n = len(t)
    ahead_ok = np.ones(n, dtype=bool)
    behind_ok = np.ones(n, dtype=bool)
    leaving: dict[str, np.ndarray] = {}
    levels = {}
    for name in names:
        centred = uniform_filter1d(signals[name], size=size, mode="nearest")
        level = float(np.median(centred[ref]))
        lo, hi = np.percentile(centred[ref], [5.0, 95.0])
        floor = _FINE_TILT if name in _ANGLES else fine_tol * abs(level)
        band = max(floor, 0.75 * (hi - lo), 1e-12)
        ahead_ok &= np.abs(_running_mean(signals[name], size, ahead=True) - level) <= band
        bad_behind = np.abs(_running_mean(signals[name], size, ahead=False) - level) > band
        behind_ok &= ~bad_behind
        leaving[name] = bad_behind
        levels[name] = {"level": level, "band": band}
    bad_before = np.flatnonzero(~ahead_ok[: ref.start])
    new_start = int(bad_before[-1]) + 1 if bad_before.size else 0
    bad_after = np.flatnonzero(~behind_ok[ref.stop :])
    new_stop = ref.stop + int(bad_after[0]) - 1 if bad_after.size else n - 1
    culprit = None
    if new_stop < n - 1:
        culprit = next(k for k in names if leaving[k][new_stop + 1])
    return new_start, new_stop, culprit, levels


def _running_mean(x: np.ndarray, size: int, ahead: bool) -> np.ndarray:
    """Mean over frames [i, i+size) (ahead) or (i-size, i] (behind), shortened at the ends."""
    c = np.r_[0.0, np.cumsum(x)]
    i = np.arange(len(x))
    if ahead:
        lo, hi = i, np.minimum(i + size, len(x))
    else:
        lo, hi = np.maximum(i - size + 1, 0), i + 1
    return (c[hi] - c[lo]) / (hi - lo)


def steady_window(
    times,
    positions,
    t_from: float | None = None,
    t_to: float | None = None,
    tol: float = 0.05,
    smooth: int | None = None,
    fine_tol: float = 0.01,
    open_chain: bool = False,
) -> Window:
    """Find the steady periodic window (see the module docstring for the criterion).

    Parameters
    ----------
    times : ndarray, shape (n_frames,)
        Frame times, in tau_d.
    positions : ndarray, shape (n_frames, n_beads, 3)
        Bead positions, in d.
    t_from, t_to : float, optional
        Replace the detected start / end (snapped to the nearest frame). A side not given
        keeps its detected value, unless that would leave fewer than :data:`MIN_FRAMES`
        frames, in which case the trajectory's first / last frame is used.
    tol : float
        Relative half-width of the coarse bands.
    smooth : int, optional
        Running-median width in frames of the coarse pass; default
        ``max(5, n_frames // 50)`` (odd).
    fine_tol : float
        Relative half-width of the fine bands (before widening to the signals' spread).
    open_chain : bool
        The positions are one open chain: its own signals (:func:`open_chain_signals`), no
        torus, no swirl, no collapse (module docstring).

    Returns
    -------
    Window

    Raises
    ------
    ConfigError
        If ``t_from``/``t_to`` lie outside the trajectory or leave too few frames.
    """
    t = np.asarray(times, dtype=np.float64)
    n = len(t)
    if n < MIN_FRAMES:
        raise ConfigError(
            f"the trajectory has {n} frames: the analysis needs at least {MIN_FRAMES}; "
            "run longer or write frames more often"
        )
    span = f"[{t[0]:g}, {t[-1]:g}]"
    for name, value in (("--from", t_from), ("--to", t_to)):
        if value is not None and not (t[0] - 1e-9 <= value <= t[-1] + 1e-9):
            raise ConfigError(f"{name} {value:g} lies outside the trajectory's times {span}")
    if t_from is not None and t_to is not None and t_from >= t_to:
        raise ConfigError(f"--from {t_from:g} must be earlier than --to {t_to:g}")

    smooth = int(max(5, n // 50) if smooth is None else smooth) | 1
    if open_chain:
        cyl, names = None, _OPEN_SIGNALS
        signals = open_chain_signals(t, positions)
    else:
        cyl, names = cylindrical(positions), _SIGNALS
        signals = window_signals(t, positions, cyl)
    mask, smoothed, bands = _coarse(signals, smooth, tol, names)
    run = longest_run(_close_gaps(mask, smooth))
    notes: list[str] = []
    levels: dict = {k: {"level": v[0], "band": v[1]} for k, v in bands.items()}
    culprit = None
    if run is None:
        notes.append("no frame is steady by the criterion: the whole trajectory is used")
        start, stop = 0, n - 1
    else:
        start, stop, culprit, levels = _fine(t, cyl, signals, *run, fine_tol, names)

    # collapse: the smoothed radius falls well below its steady level after the steady start
    collapse = None
    if not open_chain:
        r_level, r_band = bands["radius"]
        low = np.flatnonzero(smoothed["radius"][start:] < r_level - 2.0 * r_band)
        collapse = start + int(low[0]) if low.size else None
    collapse_time = float(t[collapse]) if collapse is not None else None

    auto_start, auto_stop = t_from is None, t_to is None
    if t_from is not None:
        start = int(np.argmin(np.abs(t - t_from)))
    if t_to is not None:
        stop = int(np.argmin(np.abs(t - t_to)))
    if stop - start + 1 < MIN_FRAMES:
        found = (t[start], t[stop], stop - start + 1)
        if auto_stop:
            stop = n - 1
        if auto_start and stop - start + 1 < MIN_FRAMES:
            start = 0
        if auto_start or auto_stop:
            notes.append(
                f"the steady stretch found, t = {found[0]:g}-{found[1]:g}, holds {found[2]} "
                f"frames, fewer than the {MIN_FRAMES} the analysis needs: the window is "
                f"widened to t = {t[start]:g}-{t[stop]:g}, which is not steady; run longer "
                f"(or write frames more often) or set --from/--to"
            )
    if stop - start + 1 < MIN_FRAMES:
        raise ConfigError(
            f"the window [{t[start]:g}, {t[stop]:g}] holds {stop - start + 1} frames: the "
            f"analysis needs at least {MIN_FRAMES}; widen --from/--to"
        )

    if auto_stop and collapse is not None and start < collapse <= stop:
        stop = max(collapse - 1, start + MIN_FRAMES - 1)  # end before the collapse
        culprit = "radius"
    if not auto_stop:
        end_reason = "given"
    elif stop == n - 1:
        end_reason = "end of trajectory"
    elif culprit == "radius" and collapse_time is not None:
        end_reason = "collapse"
    else:
        end_reason = f"departure: {culprit}" if culprit else "departure"
    if collapse is not None and start <= collapse <= stop:
        notes.append(f"the window includes a collapse of the torus radius at t = {collapse_time:g}")
    if (auto_start or auto_stop) and (stop - start + 1) < 0.2 * n:
        notes.append(
            f"the steady window covers only {stop - start + 1} of {n} frames: the run may "
            "not have reached a periodic state; check the time series or set --from/--to"
        )
    criterion = (
        f"signals (torus radius, cross-section, falling speed, tilt) in their bands: coarse "
        f"pass {tol:.0%} around their modes (running median of {smooth} frames), then "
        f"one-swirl-period averages within max({fine_tol:.0%}, spread) of the middle third"
    )
    if open_chain:
        criterion = (
            f"an open chain's signals (falling speed, radius of gyration, end-to-end length "
            f"and angle to the vertical) in their bands: coarse pass {tol:.0%} around their "
            f"modes (the angle 0.1 rad; running median of {smooth} frames), then frame by "
            f"frame within max({fine_tol:.0%}, spread) of the middle third"
        )
    return Window(
        start=start,
        stop=stop,
        t0=float(t[start]),
        t1=float(t[stop]),
        automatic_start=auto_start,
        automatic_stop=auto_stop,
        end_reason=end_reason,
        collapse_time=collapse_time,
        levels=levels,
        criterion=criterion,
        notes=notes,
    )
