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

import json

import numpy as np
from scipy.signal import zoom_fft

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


#: A running-speed line is removed when its power stands this many times above the local spectrum's median.
LINE_TO_FLOOR = 10.0
#: The running speed is refined within this fraction of the record's value (a synchronous unit's speed
#: follows the grid frequency, within a few tenths of a percent).
SPEED_SEARCH = 0.005


def _wave_power(wave: np.ndarray, y: np.ndarray) -> float:
    """Power of the real record's channels along ``wave`` = ``exp(-2 pi i f t)`` (periodogram, summed over
    channels): its real and imaginary parts in one real product, five times quicker than the complex one,
    which casts the record to complex first."""
    return float(np.sum((np.stack([wave.real, wave.imag]) @ y) ** 2))


def _line_power(y: np.ndarray, t: np.ndarray, f_hz: float) -> float:
    """Power of the record's channels at one frequency (periodogram, summed over channels)."""
    return _wave_power(np.exp(-2j * np.pi * f_hz * t), y)


def grid_power(y: np.ndarray, fs_hz: float, grid_hz: np.ndarray) -> np.ndarray:
    """:func:`_line_power` at every frequency of an evenly spaced grid [Hz], by one chirp-z transform.

    The same sums as one complex exponential per frequency (to about 1e-12 of the largest), in a few FFTs
    of the record instead of ``len(grid_hz)`` passes over it: the running speed's search on a 20-min record
    at 256 Hz took 2.0 s that way, 0.24 s so.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> y = rng.standard_normal((5000, 2))
    >>> grid = np.linspace(2.0, 2.5, 11)
    >>> t = np.arange(5000) / 50.0
    >>> bool(np.allclose(grid_power(y, 50.0, grid), [_line_power(y, t, f) for f in grid], rtol=1e-9))
    True
    """
    if len(grid_hz) == 1:
        return np.array([_line_power(y, np.arange(y.shape[0]) / fs_hz, float(grid_hz[0]))])
    spectrum = zoom_fft(y, [float(grid_hz[0]), float(grid_hz[-1])], m=len(grid_hz), fs=fs_hz, endpoint=True, axis=0)
    return np.sum(np.abs(spectrum) ** 2, axis=1)


def remove_running_harmonics(
    y: np.ndarray, fs_hz: float, running_hz: float, fmax_hz: float
) -> tuple[np.ndarray, list[dict]]:
    """Subtract the sinusoids at whole multiples of the running speed from a record.

    A forced response at 1X (unbalance) or 2X next to a damped mode leaks
    into that mode's SSI estimate: on the hydro unit the 1X line at 2.23 Hz
    biased the 2.6 Hz generator mode (7.5% damped) beyond its standard error,
    and with it the magnetic pull updated from that mode. A sinusoid is
    deterministic: it is fitted by least squares and subtracted before SSI.
    The running speed is first refined (within :data:`SPEED_SEARCH`) to the
    frequency where the 1X line is strongest; each multiple ``k`` up to
    ``fmax_hz`` whose line stands :data:`LINE_TO_FLOOR` times above the
    median of the spectrum around it (2-30 bins away) is removed.

    Parameters
    ----------
    y : (n, channels)
        Zero-mean record.
    fs_hz, running_hz, fmax_hz : float
        Sampling rate, running speed (from the record) and highest frequency of interest [Hz].

    Returns
    -------
    (y, removed)
        The record without the lines, and per removed line its ``frequency_hz``,
        ``running_speed_multiple``, ``amplitude`` (largest over channels, the
        record's unit) and ``line_to_floor_db``.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> t = np.arange(120_000) / 50.0
    >>> y = rng.standard_normal((len(t), 2)) + np.outer(np.cos(2 * np.pi * 2.2345 * t), [3.0, 1.0])
    >>> clean, removed = remove_running_harmonics(y, 50.0, 134 / 60, 20.0)
    >>> [(r["running_speed_multiple"], round(r["frequency_hz"], 4), round(r["amplitude"], 2)) for r in removed]
    [(1, 2.2345, 3.0)]
    >>> float(np.round(clean.std(axis=0).max(), 2))
    1.0
    """
    n = y.shape[0]
    t = np.arange(n) / fs_hz
    T = n / fs_hz
    grid = running_hz * (
        1.0 + np.linspace(-SPEED_SEARCH, SPEED_SEARCH, 2 * int(np.ceil(SPEED_SEARCH * running_hz * T * 4)) + 1)
    )
    f1 = float(grid[np.argmax(grid_power(y, fs_hz, grid))])
    if f1 > 0:  # the peak between grid points: a parabola through the three around it
        p = [_line_power(y, t, f1 + d) for d in (-0.25 / T, 0.0, 0.25 / T)]
        den = p[0] - 2 * p[1] + p[2]
        if den < 0:
            f1 += 0.25 / T * 0.5 * (p[0] - p[2]) / den
    spectrum = np.sum(np.abs(np.fft.rfft(y, axis=0)) ** 2, axis=1)
    bins = np.fft.rfftfreq(n, 1.0 / fs_hz)
    out = y.copy()
    removed = []
    step = np.exp(-2j * np.pi * f1 * t)
    wave = np.ones(n, dtype=complex)  # exp(-2 pi i k f1 t), one multiplication a line: no exponential per line
    for k in range(1, int(fmax_hz // f1) + 1):
        f = k * f1
        wave *= step
        centre = int(round(f * T))
        near = np.r_[centre - 30 : centre - 1, centre + 2 : centre + 31]
        near = near[(near > 0) & (near < len(bins))]
        if near.size == 0:
            continue
        ratio = _wave_power(wave, out) / float(np.median(spectrum[near]))
        if not ratio > LINE_TO_FLOOR:
            continue
        basis = np.column_stack([wave.real, -wave.imag])  # cos and sin of 2 pi f t
        coef = np.linalg.solve(basis.T @ basis, basis.T @ out)  # least squares: two nearly orthogonal columns
        out -= basis @ coef
        removed.append(
            {
                "frequency_hz": float(f),
                "running_speed_multiple": k,
                "removed": True,
                "amplitude": float(np.max(np.hypot(coef[0], coef[1]))),
                "line_to_floor_db": float(10 * np.log10(ratio)),
            }
        )
    return out, removed


def line_frequencies(harmonics_attr: str) -> tuple[list[float], list[float]]:
    """The frequencies [Hz] of a ``modes.nc`` ``harmonics`` attr: the lines removed before SSI, those rejected.

    Examples
    --------
    >>> line_frequencies('[{"frequency_hz": 2.233, "removed": true}, {"frequency_hz": 4.47, "kurtosis": 1.6}]')
    ([2.233], [4.47])
    """
    lines = json.loads(harmonics_attr)
    return (
        [h["frequency_hz"] for h in lines if h.get("removed")],
        [h["frequency_hz"] for h in lines if not h.get("removed")],
    )
