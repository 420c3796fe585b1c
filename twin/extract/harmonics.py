"""Recognise running-speed harmonics among identified poles.

A harmonic (1X, 2X from unbalance, misalignment) looks to SSI like a mode
with near-zero damping. What tells them apart is the amplitude distribution
of the signal in a narrow band around the pole: a sinusoid has kurtosis 1.5,
the narrow-band response of a mode to random forces is Gaussian (kurtosis 3).
With a fraction ``r`` of the band's power in a sinusoid the kurtosis is
``3 - 1.5 r^2``.

The kurtosis of a narrow band is only as good as the number of independent
values the band holds over the record, about ``T x bandwidth``: over 20 min,
a 1.1 Hz mode at 0.15% damping gives about 13, and its band kurtosis fell
to 2.3 by chance, so the mode was taken for a harmonic. Two more facts
decide instead:

* a forced response of the rotor sits at a whole multiple of the running
  speed (1X unbalance, 2X misalignment, blade pass): when the record knows
  the speed, a pole away from every multiple (by more than
  :data:`ORDER_TOLERANCE` of its frequency, or two frequency bins ``2/T``)
  is no harmonic, whatever its band kurtosis;
* without the speed, a band with fewer than :data:`MIN_BAND_VALUES`
  independent values cannot tell, and the pole counts as a sinusoid only
  if SSI finds it as undamped as a sinusoid of the record can look
  (``ζ <`` :data:`SINUSOID_DAMPING_CYCLES` ``/ (ω T)``).
"""

from __future__ import annotations

import numpy as np

from twin.modes.analysis import damping_ratio

#: Poles damped less than this are tested for being a harmonic. SSI gives a sinusoid a damping ratio
#: of order ``1 / (omega T)`` (1e-4 for 1 Hz over 20 min); a structural mode in water keeps more.
#: A looser limit lets a lightly damped mode be taken for a harmonic: over 20 min the band kurtosis
#: of a 1.1 Hz mode at zeta = 0.65% has only ~30 independent envelope values and fell to 2.4.
HARMONIC_MAX_DAMPING = 0.002
#: Band kurtosis below this marks a harmonic (a sinusoid holding at least ~60% of the band power).
HARMONIC_KURTOSIS = 2.5
#: Half-width of the test band, relative to the frequency, at least this.
MIN_HALF_BAND = 0.005
#: A harmonic lies within this fraction of its frequency of a whole multiple of the running speed.
ORDER_TOLERANCE = 0.002
#: Independent values a band must hold over the record for its kurtosis to decide.
MIN_BAND_VALUES = 30
#: Without a running speed, an undecided band is a sinusoid when ``ζ ω T`` is below this.
SINUSOID_DAMPING_CYCLES = 1.0


def band_kurtosis(spectrum: np.ndarray, n: int, fs_hz: float, f_lo: float, f_hi: float) -> np.ndarray:
    """Kurtosis (3 for Gaussian) of each channel band-passed to ``[f_lo, f_hi]`` Hz, and the band power.

    Parameters
    ----------
    spectrum : (n // 2 + 1, channels) complex
        ``numpy.fft.rfft`` of the zero-mean record along time.
    n : int
        Number of samples of the record.

    Returns
    -------
    (kurtosis, power) : two arrays over channels

    Examples
    --------
    >>> t = np.arange(400_000) / 100.0
    >>> y = np.column_stack([np.sin(2 * np.pi * 5 * t), np.random.default_rng(0).standard_normal(len(t))])
    >>> k, _ = band_kurtosis(np.fft.rfft(y, axis=0), len(t), 100.0, 4.8, 5.2)
    >>> np.round(k, 1)
    array([1.5, 3. ])
    """
    f = np.fft.rfftfreq(n, 1.0 / fs_hz)
    band = (f >= f_lo) & (f <= f_hi)
    masked = np.zeros_like(spectrum)
    masked[band] = spectrum[band]
    x = np.fft.irfft(masked, n, axis=0)
    power = np.mean(x**2, axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        kurt = np.mean(x**4, axis=0) / power**2
    return kurt, power


def harmonic_test(
    spectrum: np.ndarray | None, n: int, fs_hz: float, pole: complex, running_speed_hz: float | None = None
) -> dict | None:
    """Test one pole: a dict describing it as a harmonic, or ``None`` for a structural mode.

    ``spectrum`` (as for :func:`band_kurtosis`) is only read for poles damped
    less than ``HARMONIC_MAX_DAMPING``; it may be ``None`` when there are none.
    """
    f = pole.imag / (2 * np.pi)
    zeta = float(damping_ratio(pole))
    if zeta >= HARMONIC_MAX_DAMPING:
        return None
    duration = n / fs_hz
    if running_speed_hz:
        k = max(round(f / running_speed_hz), 1)
        if abs(f - k * running_speed_hz) > max(ORDER_TOLERANCE * f, 2.0 / duration):
            return None  # no multiple of the running speed: a structural mode
    half = max(MIN_HALF_BAND, 2.0 * max(zeta, 0.0)) * f
    kurt, power = band_kurtosis(spectrum, n, fs_hz, f - half, f + half)
    ch = int(np.nanargmax(power))
    if not kurt[ch] < HARMONIC_KURTOSIS:
        return None
    if not running_speed_hz and duration * 2 * half < MIN_BAND_VALUES:
        if zeta * 2 * np.pi * f * duration >= SINUSOID_DAMPING_CYCLES:
            return None  # the band cannot tell, and it is damped beyond what a sinusoid shows
    out = {"frequency_hz": float(f), "damping_ratio": float(zeta), "kurtosis": float(kurt[ch]), "channel_index": ch}
    if running_speed_hz:
        order = f / running_speed_hz
        out["order"] = float(order)
        out["running_speed_multiple"] = int(round(order)) if abs(order - round(order)) < 0.02 else None
    return out
