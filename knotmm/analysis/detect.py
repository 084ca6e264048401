"""Is there a swirl at all? A significance test and a precision floor for the swirl line.

The swirl spectrum (:mod:`knotmm.analysis.spectra`) always has a highest point, even when the
beads do not move relative to each other (a rigid ring: the "swirl" is float32 rounding of
the DCD). A line counts as a swirl only if it passes both tests below, on the body-frame
swirl signal ``s_i(t) = (z_i - <z_i>) + i (rho_i - <rho_i>)`` (:mod:`knotmm.analysis.body`;
a rigid motion of any kind leaves it at zero):

1. Significance against the local noise floor. Each bead's signal is detrended (linear fit)
   and Hann tapered; the periodogram ``P_k`` (unpadded FFT, summed over beads) is searched
   for its maximum over the swirl band, ``|f| >= 2 / T`` (two periods in the window of
   length T) up to the Nyquist frequency. The noise floor ``S`` at the peak is the median
   of ``P`` over the bins 3 to ``W`` bins away from it (``W = max(8, m / 16)``, m frames),
   divided by ln 2: for Gaussian noise of locally flat spectrum a periodogram bin is at
   least as concentrated as an exponential variable of mean ``S`` (exponential for one
   independent signal, chi-square with more degrees of freedom for several), so the
   median/ln 2 does not underestimate the mean. Under that null hypothesis
   ``Pr(P_k > r S) <= exp(-r)`` per bin and, over the ``K`` bins of the band,
   ``Pr(max > r S) <= K exp(-r)``. The line is significant if ``K exp(-r) <``
   :data:`FALSE_ALARM` (0.01): the stated false-alarm probability. ``p_value`` is
   ``min(1, K exp(-r))``.
2. A line, not the foot of a red spectrum. A chain drifting or relaxing towards a steady
   shape has a spectrum that falls from zero frequency: its highest point in the band is the
   band's lowest bin, however significant against the noise further out. The line must be a
   local maximum: above the bin next to it towards zero frequency (and the one beyond it).
   A swirl slower than half the window gives such a spectrum too (its line lies below the
   band), so a red spectrum alone says no more than "no swirl in this window". It says
   "steady shape" (``steady``) only when the shape's motion dies out as well: the body-frame
   speed ``u(t) = (sum_i |ds_i/dt|^2)^(1/2)`` (frame differences of the raw signal), averaged
   over the last quarter of the window, is below :data:`RELAXED` times its average over the
   first quarter. A swirl keeps ``u`` nearly constant, since its beads carry phases spread
   over the period; a relaxation ``exp(-t/T)`` passes once the window exceeds ``3 T``.
3. Amplitude above the file's precision. A DCD stores Angstrom in float32: a coordinate of
   magnitude X (in d) is rounded to within half a float32 spacing, ``ulp(10 X) / 10`` d.
   The line's amplitude (the larger of its rms per-bead half-amplitudes in rho and z) must
   exceed :data:`PRECISION_FACTOR` (10) times the spacing at the largest coordinate of the
   window. Applied to every trajectory, since every run is saved as a DCD.

Half-amplitudes: for one coordinate ``c_i(t)`` of bead i, ``2 |sum_t w_t c_i(t) exp(-2 pi i f
t)| / sum_t w_t`` (Hann weights ``w``, the detrended signal) at the line's frequency; for
``c = A sin(2 pi f t + phi)`` this is A. ``swirl_amplitude_rho`` / ``_z`` are their rms over
beads.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from knotmm.analysis.spectra import refine_frequency
from knotmm.units import angstrom_to_d, d_to_angstrom

__all__ = [
    "FALSE_ALARM",
    "PRECISION_FACTOR",
    "RELAXED",
    "SwirlDetection",
    "detect_swirl",
    "float32_spacing",
    "line_amplitudes",
    "motion_decay",
]

#: False-alarm probability of the significance test.
FALSE_ALARM = 0.01
#: The swirl's amplitude must exceed this many float32 spacings of the largest coordinate.
PRECISION_FACTOR = 10.0
#: A red spectrum is a relaxation towards a steady shape when the body-frame speed over the
#: window's last quarter is below this fraction of its speed over the first quarter.
RELAXED = 0.1
_GUARD = 3
_MIN_BINS = 8


@dataclass(frozen=True)
class SwirlDetection:
    """Outcome of the swirl detector.

    Attributes
    ----------
    detected : bool
    frequency : float
        Signed frequency of the strongest line of the swirl band, 1/tau_d (refined below the
        grid spacing with :func:`knotmm.analysis.spectra.refine_frequency`).
    power_ratio : float
        Its power over the local noise floor ``S``.
    threshold : float
        ``ln(K / FALSE_ALARM)``: the ratio needed.
    p_value : float
        Bound on the probability of a noise peak this high anywhere in the band.
    n_bins : int
        K, the bins searched.
    amplitude_rho, amplitude_z : float
        Rms per-bead half-amplitudes at the line, in d.
    amplitude_floor : float
        ``PRECISION_FACTOR`` float32 spacings of the largest coordinate, in d.
    reason : str
        One line: why the swirl is (not) detected.
    steady : bool
        The chain converges to a steady shape rather than oscillating: a red spectrum whose
        motion dies out (module docstring, item 2), or a run with no external force
        (:mod:`knotmm.analysis.regimes`). Never True with ``detected``.
    motion_decay : float
        Body-frame speed over the last quarter of the window over that of the first
        (module docstring, item 2); about 1 for a swirl, NaN when the window is too short.
    """

    detected: bool
    frequency: float
    power_ratio: float
    threshold: float
    p_value: float
    n_bins: int
    amplitude_rho: float
    amplitude_z: float
    amplitude_floor: float
    reason: str
    steady: bool = False
    motion_decay: float = math.nan

    def to_dict(self) -> dict:
        """JSON-ready summary."""
        return {
            "detected": self.detected,
            "frequency": self.frequency,
            "power_ratio": self.power_ratio,
            "threshold": self.threshold,
            "p_value": self.p_value,
            "false_alarm": FALSE_ALARM,
            "n_bins": self.n_bins,
            "amplitude_rho": self.amplitude_rho,
            "amplitude_z": self.amplitude_z,
            "amplitude_floor": self.amplitude_floor,
            "reason": self.reason,
            "steady_shape": self.steady,
            "motion_decay": self.motion_decay,
        }


def float32_spacing(max_abs_d: float) -> float:
    """Spacing of float32 numbers near a coordinate stored in Angstrom, in d.

    Parameters
    ----------
    max_abs_d : float
        The coordinate's magnitude, in d (1 d = 10 Angstrom in the DCD).
    """
    return angstrom_to_d(float(np.spacing(np.float32(d_to_angstrom(abs(max_abs_d))))))


def _detrend(x: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Remove a per-column mean and linear trend in s (s centred)."""
    x = x - x.mean(axis=0)
    slope = (s[:, None] * x).sum(axis=0) / (s * s).sum()
    return x - s[:, None] * slope


def line_amplitudes(times, values, frequency: float) -> np.ndarray:
    """Per-column half-amplitude of the line at ``frequency`` (module docstring).

    Parameters
    ----------
    times : ndarray, shape (n_frames,)
        Uniform, in tau_d.
    values : ndarray, shape (n_frames, n_columns), real
    frequency : float
        In 1/tau_d.

    Returns
    -------
    ndarray, shape (n_columns,)
        Same units as ``values``.
    """
    t = np.asarray(times, dtype=np.float64)
    s = t - t.mean()
    w = np.hanning(len(t) + 2)[1:-1]
    x = _detrend(np.asarray(values, dtype=np.float64), s)
    phase = np.exp(-2j * np.pi * frequency * s) * w
    return 2.0 * np.abs(phase @ x) / w.sum()


def detect_swirl(times, rho, z, max_coordinate: float | None = None) -> SwirlDetection:
    """Apply the swirl significance test and the precision floor (module docstring).

    Parameters
    ----------
    times : ndarray, shape (n_frames,)
        Uniform, in tau_d.
    rho, z : ndarray, shape (n_frames, n_beads)
        Body-frame radius and height of every bead, in d.
    max_coordinate : float, optional
        Largest absolute lab coordinate in the window, in d (sets the precision floor;
        default: no floor).

    Returns
    -------
    SwirlDetection
    """
    t = np.asarray(times, dtype=np.float64)
    m = len(t)
    dt = float(t[1] - t[0])
    s = t - t.mean()
    r = _detrend(np.asarray(rho, dtype=np.float64), s)
    h = _detrend(np.asarray(z, dtype=np.float64), s)
    w = np.hanning(m + 2)[1:-1][:, None]
    power = (np.abs(np.fft.fft((h + 1j * r) * w, axis=0)) ** 2).sum(axis=1)
    k_all = np.fft.fftfreq(m) * m  # signed bin numbers
    band = np.abs(k_all) >= 2
    n_bins = int(band.sum())
    floor = PRECISION_FACTOR * float32_spacing(max_coordinate) if max_coordinate else 0.0
    if n_bins == 0 or not np.isfinite(power).all():
        return SwirlDetection(
            False,
            math.nan,
            math.nan,
            math.nan,
            1.0,
            0,
            math.nan,
            math.nan,
            floor,
            "the window is too short for two swirl periods",
        )
    k = int(np.flatnonzero(band)[np.argmax(power[band])])
    kk = k_all[k]
    half_width = max(_MIN_BINS, m // 16)
    dist = np.abs(k_all - kk)
    dist = np.minimum(dist, m - dist)  # the spectrum is periodic
    ring = (dist >= _GUARD) & (dist <= half_width)
    noise = float(np.median(power[ring])) / math.log(2.0)
    ratio = float(power[k] / noise) if noise > 0 else math.inf
    threshold = math.log(n_bins / FALSE_ALARM)
    p_value = min(1.0, n_bins * math.exp(-ratio)) if math.isfinite(ratio) else 0.0
    # the amplitudes need the line's frequency below the grid spacing (scalloping)
    freq = refine_frequency((h + 1j * r) * w, t, float(kk / (m * dt)), 1.0 / (m * dt))
    a_rho = float(np.sqrt(np.mean(line_amplitudes(t, rho, freq) ** 2)))
    a_z = float(np.sqrt(np.mean(line_amplitudes(t, z, freq) ** 2)))
    amplitude = max(a_rho, a_z)
    bins = np.rint(k_all).astype(int)
    step = int(np.sign(kk))
    toward = int(np.flatnonzero(bins == int(round(kk)) - step)[0])
    beyond = np.flatnonzero(bins == int(round(kk)) + step)
    peak = power[k] > power[toward] and (not beyond.size or power[k] > power[beyond[0]])
    decay = motion_decay(rho, z)
    if ratio <= threshold:
        reason = (
            f"no swirl detected: the strongest line of the swirl band (period "
            f"{1 / abs(freq):.4g} tau_d) is {ratio:.3g} times the local noise floor, below "
            f"the {threshold:.3g} needed for a false-alarm probability of {FALSE_ALARM:g}"
        )
        detected = False
    elif not peak:
        head = (f"no swirl detected: the swirl band's strongest bin (period "
                f"{m * dt / abs(kk):.4g} tau_d) is no spectral line: the power rises towards "
                f"zero frequency")
        if decay < RELAXED:
            reason = (f"{head} and the shape's motion dies out (its body-frame speed falls "
                      f"to {decay:.2g} of its start over the window): a relaxation towards "
                      f"a steady shape, not an oscillation")
        else:
            reason = (f"{head} while the shape keeps moving: a drift, or a swirl slower "
                      f"than half the window ({m * dt:.4g} tau_d); a longer run tells")
        detected = False
    elif amplitude <= floor:
        reason = (
            f"no swirl detected: the line's amplitude {amplitude:.2g} d is below "
            f"{PRECISION_FACTOR:g} float32 spacings of the coordinates ({floor:.2g} d), "
            "the precision of the DCD"
        )
        detected = False
    else:
        reason = (
            f"swirl detected: line {ratio:.3g} times the noise floor (threshold "
            f"{threshold:.3g}, false-alarm probability {FALSE_ALARM:g}), amplitude "
            f"{amplitude:.3g} d above the precision floor {floor:.2g} d"
        )
        detected = True
    return SwirlDetection(
        detected, freq, ratio, threshold, p_value, n_bins, a_rho, a_z, floor, reason,
        steady=bool(not peak and ratio > threshold and decay < RELAXED), motion_decay=decay,
    )


def motion_decay(rho, z) -> float:
    """Body-frame speed over the last quarter of the frames over that over the first.

    Parameters
    ----------
    rho, z : ndarray, shape (n_frames, n_beads)
        Body-frame radius and height of every bead, in d (uniform frames).

    Returns
    -------
    float
        ``mean(u, last quarter) / mean(u, first quarter)``, ``u`` the frame-to-frame
        displacement of the signal ``z + i rho`` summed over beads in quadrature (module
        docstring, item 2); NaN with fewer than 5 frames, inf when the first quarter is at
        rest.
    """
    s = np.asarray(z, dtype=np.float64) + 1j * np.asarray(rho, dtype=np.float64)
    u = np.sqrt((np.abs(np.diff(s, axis=0)) ** 2).sum(axis=1))
    if len(u) < 4:
        return math.nan
    quarter = len(u) // 4
    early, late = float(u[:quarter].mean()), float(u[-quarter:].mean())
    return late / early if early > 0 else (math.inf if late > 0 else 1.0)
