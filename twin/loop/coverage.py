"""Whether measured modes are enough to judge a model: coverage of the band and length of the record.

A diagnosis from two of the dozen modes a band holds can say nothing about
the other ten: "nothing missing" would be a guess. Before judging, the twin
counts the model's modes in the band the modes were extracted from (damped
less than the extraction accepts) and the modes measured there, and checks
that the record holds enough periods of the lowest of them. When either
falls short the verdict is "not enough data", with what is short.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from twin.fem.model import RotorModel
from twin.modes.analysis import damping_ratio
from twin.modes.measured import Measured
from twin.modes.sensitivity import solve_modes

#: At least this fraction of the model's modes in the band must be measured.
MIN_COVERAGE = 0.5
#: The record must hold this many periods of the lowest model mode in the band (as extraction asks of ``fmin``).
MIN_CYCLES = 100


@dataclass(frozen=True)
class Coverage:
    """The model's modes in the measured band against the measured ones, and the record length."""

    band_hz: tuple[float, float]
    in_band_hz: np.ndarray  # damped frequencies of the model's modes in the band [Hz]
    n_measured: int
    duration_s: float

    @property
    def lowest_hz(self) -> float:
        """Lowest model mode in the band [Hz] (NaN when there is none)."""
        return float(self.in_band_hz.min()) if len(self.in_band_hz) else float("nan")

    @property
    def too_few(self) -> bool:
        """Fewer than :data:`MIN_COVERAGE` of the model's modes in the band are measured."""
        return self.n_measured < MIN_COVERAGE * len(self.in_band_hz)

    @property
    def too_short(self) -> bool:
        """The record holds fewer than :data:`MIN_CYCLES` periods of the lowest model mode in the band."""
        return bool(len(self.in_band_hz)) and self.duration_s * self.lowest_hz < MIN_CYCLES

    @property
    def enough(self) -> bool:
        """Whether the measured modes can judge the model."""
        return not (self.too_few or self.too_short)

    def text(self) -> str:
        """What the data cover, and what is short, in words."""
        lo, hi = self.band_hz
        words = (
            f"{self.n_measured} of the model's {len(self.in_band_hz)} modes between {lo:g} and {hi:g} Hz "
            f"are measured, from {self.duration_s:g} s of signals"
        )
        short = []
        if self.too_few:
            short.append(f"fewer than {MIN_COVERAGE:.0%} of the modes in the band")
        if self.too_short:
            need = MIN_CYCLES / self.lowest_hz
            short.append(
                f"the record is shorter than {MIN_CYCLES} periods of the lowest mode "
                f"({self.lowest_hz:.3g} Hz: {need:.0f} s)"
            )
        return words + (f"; not enough: {' and '.join(short)}" if short else "")


def coverage(model: RotorModel, meas: Measured) -> Coverage | None:
    """What the measured modes cover of the model's band; None when they carry no band (synthetic modes).

    Examples
    --------
    >>> import dataclasses
    >>> from twin.modes.measured import measured_modes
    >>> from twin.update import synthesize_modes
    >>> model = hydro_unit
    >>> meas = measured_modes(synthesize_modes(model, samples=5, seed=1).isel(mode=[0, 3]))  # 2 modes
    >>> c = coverage(model, dataclasses.replace(meas, band_hz=(0.0, 60.0), duration_s=5.0, zeta_max=0.25))
    >>> len(c.in_band_hz), c.n_measured, c.enough
    (12, 2, False)
    """
    if meas.band_hz is None or meas.duration_s is None:
        return None
    sol = solve_modes(model)
    f = sol.poles.imag / (2 * np.pi)
    lo, hi = meas.band_hz
    keep = (f >= lo) & (f <= hi)
    if meas.zeta_max is not None:
        keep &= damping_ratio(sol.poles) < meas.zeta_max
    return Coverage((lo, hi), f[keep], len(meas.mode), float(meas.duration_s))
