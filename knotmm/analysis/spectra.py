"""Swirl and rotation periods from Fourier spectra of the beads' cylindrical coordinates.

Two complex signals per bead carry the two motions as single spectral lines:

* swirl: ``(z - <z>) + i (rho - <rho>)``. A bead circling its cross-section (an ellipse in
  the rho-z plane) is one line at ``+1/tau_swirl`` or ``-1/tau_swirl`` depending on the
  sense of the swirl, plus a weak mirror line set by the ellipse's eccentricity.
* rotation: ``exp(i alpha)``. A rigid rotation is one line at ``1/tau_rot``, positive when
  the knot turns counterclockwise seen from above. Because the signal is complex there is
  no mirror line, so the peak is unbiased even when the window is shorter than tau_rot.

The spectrum is the power of the Hann-tapered signals summed over beads, on a grid zero
padded eightfold. The peak is then refined below the grid spacing by maximising the exact
discrete-time Fourier transform of the tapered data (for one line in white noise this is
the maximum-likelihood frequency). The uncertainty combines in quadrature two estimates:
the standard error of the same peak found bead by bead (scatter across beads /
sqrt(n_beads), which measures noise), and half the difference between the peaks of the
window's first and second halves (which measures drift and irregularity of the motion).
Neither covers the bias of a window too short for the motion, which ``resolution`` bounds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize_scalar

from knotmm.errors import ConfigError

__all__ = [
    "SpectralPeak",
    "check_time_scale",
    "Spectrum",
    "line_spectrum",
    "refine_frequency",
    "rotation_spectrum",
    "swirl_spectrum",
]

_PAD = 8
_LOCAL_POINTS = 41


@dataclass
class SpectralPeak:
    """A refined spectral line.

    Attributes
    ----------
    frequency : float
        Signed frequency of the line, in 1/tau_d.
    frequency_uncertainty : float
        Standard error of the frequency, in 1/tau_d.
    period : float
        ``1 / |frequency|``, in tau_d (``inf`` for a zero frequency).
    period_uncertainty : float
        Standard error of the period, in tau_d.
    resolution : float
        Width of one Fourier bin of the window, ``1 / (window length)``, in 1/tau_d.
    bead_frequencies : ndarray, shape (n_beads,)
        The line's frequency found bead by bead, in 1/tau_d.
    half_frequencies : tuple of float
        The line's frequency in the first and second half of the window, in 1/tau_d.
    """

    frequency: float
    frequency_uncertainty: float
    period: float
    period_uncertainty: float
    resolution: float
    bead_frequencies: np.ndarray
    half_frequencies: tuple[float, float] = (float("nan"), float("nan"))

    def to_dict(self) -> dict:
        """JSON-ready summary (without the per-bead values)."""
        return {
            "frequency": self.frequency,
            "frequency_uncertainty": self.frequency_uncertainty,
            "period": self.period,
            "period_uncertainty": self.period_uncertainty,
            "resolution": self.resolution,
            "bead_frequency_spread": float(np.std(self.bead_frequencies)),
            "half_window_frequencies": list(self.half_frequencies),
        }


@dataclass
class Spectrum:
    """Power spectrum of one family of signals, with its main line.

    Attributes
    ----------
    frequencies : ndarray, shape (n_freq,)
        Signed frequencies in increasing order, in 1/tau_d.
    power : ndarray, shape (n_freq,)
        Power summed over beads, normalised to a maximum of 1.
    peak : SpectralPeak
        The refined main line.
    name : str
        ``"swirl"`` or ``"rotation"``.
    """

    frequencies: np.ndarray
    power: np.ndarray
    peak: SpectralPeak
    name: str


def _taper(m: int) -> np.ndarray:
    return np.hanning(m + 2)[1:-1]


def _dtft(signals: np.ndarray, times: np.ndarray, freqs: np.ndarray) -> np.ndarray:
    """Fourier transform at arbitrary frequencies: (n_freq, n_signals) complex."""
    phase = np.exp(-2j * np.pi * np.outer(freqs, times - times[0]))
    return phase @ signals


def refine_frequency(
    tapered: np.ndarray, times: np.ndarray, guess: float, half_width: float
) -> float:
    """Frequency of the maximum of the summed power within guess +- half_width.

    Parameters
    ----------
    tapered : ndarray, shape (n_frames, n_signals), complex
        Signals already multiplied by their taper.
    times : ndarray, shape (n_frames,)
        In tau_d.
    guess, half_width : float
        In 1/tau_d.

    Returns
    -------
    float
        In 1/tau_d.
    """

    def negative_power(f: float) -> float:
        return -float((np.abs(_dtft(tapered, times, np.array([f]))) ** 2).sum())

    res = minimize_scalar(
        negative_power,
        bounds=(guess - half_width, guess + half_width),
        method="bounded",
        options={"xatol": half_width * 1e-4},
    )
    return float(res.x)


#: Frame spacings (tau_d) a spectrum is computed for: outside, squared frequencies and
#: periods under- or overflow in double precision (1e300 tau_d gives f**2 = 0).
TIME_SCALES = (1e-100, 1e100)


def check_time_scale(dt: float, length: float) -> None:
    """ConfigError (one line) for a time axis the spectra cannot resolve in double precision."""
    lo, hi = TIME_SCALES
    if not (np.isfinite(dt) and np.isfinite(length) and lo <= dt and length <= hi):
        raise ConfigError(
            f"frames {dt:g} tau_d apart over {length:g} tau_d: outside what a spectrum resolves "
            f"in double precision (spacing >= {lo:g}, window <= {hi:g} tau_d); check the frame "
            f"interval (--frame-interval or run.toml's output.frame_interval)"
        )


def line_spectrum(
    signals: np.ndarray, times: np.ndarray, min_frequency: float = 0.0, name: str = ""
) -> Spectrum:
    """Power spectrum of complex signals and its strongest line, refined below a bin.

    Parameters
    ----------
    signals : ndarray, shape (n_frames, n_signals), complex
        One column per bead, sampled at ``times``.
    times : ndarray, shape (n_frames,)
        Uniformly spaced times, in tau_d.
    min_frequency : float
        Lines with ``|f| < min_frequency`` (1/tau_d) are not considered.
    name : str
        A label kept on the result.

    Returns
    -------
    Spectrum
    """
    m = len(times)
    dt = float(times[1] - times[0])
    length = m * dt
    check_time_scale(dt, length)
    tapered = signals * _taper(m)[:, None]
    n_fft = int(2 ** np.ceil(np.log2(_PAD * m)))
    power = (np.abs(np.fft.fft(tapered, n=n_fft, axis=0)) ** 2).sum(axis=1)
    freqs = np.fft.fftfreq(n_fft, d=dt)
    order = np.argsort(freqs)
    freqs, power = freqs[order], power[order]
    allowed = np.abs(freqs) >= min_frequency
    if not allowed.any():
        allowed[:] = True
    k = int(np.argmax(np.where(allowed, power, -np.inf)))
    grid_step = 1.0 / (n_fft * dt)

    f0 = refine_frequency(tapered, times, freqs[k], grid_step)

    # bead by bead: parabola through the local maximum on a fine grid of +-1 bin
    local = f0 + np.linspace(-1.0, 1.0, _LOCAL_POINTS) / length
    bead_power = np.abs(_dtft(tapered, times, local)) ** 2
    j = np.clip(np.argmax(bead_power, axis=0), 1, _LOCAL_POINTS - 2)
    cols = np.arange(bead_power.shape[1])
    y0, y1, y2 = bead_power[j - 1, cols], bead_power[j, cols], bead_power[j + 1, cols]
    denom = y0 - 2.0 * y1 + y2
    with np.errstate(divide="ignore", invalid="ignore"):
        shift = np.where(denom < 0, 0.5 * (y0 - y2) / denom, 0.0)
    bead_f = local[j] + shift * (local[1] - local[0])
    n_beads = bead_f.size
    f_err = float(np.std(bead_f, ddof=1) / np.sqrt(n_beads)) if n_beads > 1 else 0.0
    halves = (float("nan"), float("nan"))
    if m >= 16:
        h = m // 2
        halves = tuple(
            refine_frequency(part * _taper(len(ts))[:, None], ts, f0, 1.0 / (len(ts) * dt))
            for part, ts in ((signals[:h], times[:h]), (signals[h:], times[h:]))
        )
        f_err = float(np.hypot(f_err, 0.5 * (halves[1] - halves[0])))
    period = 1.0 / abs(f0) if f0 != 0 else float("inf")
    period_err = f_err / f0**2 if f0 != 0 else float("inf")
    peak = SpectralPeak(f0, f_err, period, float(period_err), 1.0 / length, bead_f, halves)
    top = power.max()
    return Spectrum(freqs, power / top if top > 0 else power, peak, name)  # 0: a rigid motion


def swirl_spectrum(times, rho, z) -> Spectrum:
    """Spectrum of the swirl: ``(z - <z>) + i (rho - <rho>)`` of every bead.

    Parameters
    ----------
    times : ndarray, shape (n_frames,)
        Uniform times, in tau_d.
    rho, z : ndarray, shape (n_frames, n_beads)
        Cylindrical radius and height above the centre of mass, in d.

    Returns
    -------
    Spectrum
        Its peak's ``|frequency|`` is ``1/tau_swirl``, searched over ``|f| >= 2 / T`` (two
        periods in the window of length T), the band the swirl is detected in
        (:mod:`knotmm.analysis.detect`): a slower line (a drift, or the slow wobble of a
        torus at finite temperature) is no swirl period this window can measure.
    """
    t = np.asarray(times, dtype=np.float64)
    signal = (z - z.mean(axis=0)) + 1j * (rho - rho.mean(axis=0))
    length = len(t) * (t[1] - t[0])
    return line_spectrum(signal, t, min_frequency=2.0 / length, name="swirl")


def rotation_spectrum(times, alpha) -> Spectrum:
    """Spectrum of the rigid rotation: ``exp(i alpha)`` of every bead.

    Parameters
    ----------
    times : ndarray, shape (n_frames,)
        Uniform times, in tau_d.
    alpha : ndarray, shape (n_frames, n_beads)
        Azimuth about the vertical axis through the centre of mass, in rad.

    Returns
    -------
    Spectrum
        Its peak's frequency is ``1/tau_rot``, positive for a counterclockwise rotation seen
        from above.
    """
    t = np.asarray(times, dtype=np.float64)
    return line_spectrum(np.exp(1j * alpha), t, name="rotation")
