"""Whether measured modes cover enough of the band, from a record long enough."""

import dataclasses

import numpy as np

from twin.loop.coverage import MIN_CYCLES, coverage
from twin.modes.measured import measured_modes
from twin.update import synthesize_modes


def _meas(model, keep, duration_s):
    meas = measured_modes(synthesize_modes(model, samples=5, seed=1))
    return dataclasses.replace(meas.subset(np.asarray(keep)), band_hz=(0.0, 60.0), duration_s=duration_s, zeta_max=0.25)


def test_band_count_and_record_length(hydro_unit):
    # 13 modes below 60 Hz, one damped at 66%: 12 a 0.25 extraction can find
    c = coverage(hydro_unit, _meas(hydro_unit, range(10), 1200.0))
    assert len(c.in_band_hz) == 12 and c.n_measured == 10 and c.enough
    assert c.text() == "10 of the model's 12 modes between 0 and 60 Hz are measured, from 1200 s of signals"
    few = coverage(hydro_unit, _meas(hydro_unit, [0, 1, 2, 3, 4], 1200.0))
    assert few.too_few and not few.too_short and "fewer than 50% of the modes in the band" in few.text()
    short = coverage(hydro_unit, _meas(hydro_unit, range(10), 60.0))
    assert short.too_short and not short.too_few
    assert f"shorter than {MIN_CYCLES} periods of the lowest mode (1.11 Hz: 90 s)" in short.text()


def test_synthetic_modes_carry_no_band(hydro_unit):
    assert coverage(hydro_unit, measured_modes(synthesize_modes(hydro_unit, samples=5, seed=1))) is None
