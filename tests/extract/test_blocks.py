"""The jackknife's blocks: chosen where the user gives no number, refused with a number that is accepted, and
standard errors that stay honest in blocks shorter than a mode's decay."""

import json
import re
import warnings

import numpy as np
import pytest

from twin.defaults import SAMPLES
from twin.errors import SignalError, TwinWarning
from twin.extract import extract
from twin.extract.blocks import FEW_BLOCKS, adapted_blocks, most_blocks
from twin.extract.corpus import score, shear_frame, simulate_record, truth_modes

FRAME = shear_frame(5, damping_ratio=0.002)  # 0.91 to 6.1 Hz, the slowest decaying in 88 s


def _extract(ds, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return extract(ds, progress=False, **kw)


def test_the_default_is_the_shared_number_of_blocks_where_the_record_holds_them():
    plan = adapted_blocks(1200.0, most_blocks(24_000, 130), np.array([-0.04 + 6j]))
    assert plan.blocks == SAMPLES and plan.block_s == 80.0
    assert "the default number" in plan.reason and "longer than 3 time constants" in plan.reason


def test_a_short_record_gets_the_blocks_it_holds_and_says_so():
    """120 s at 20 Hz holds 9 blocks of the Hankel matrix's lags: the default takes 9 (and finds every mode),
    15 asked for is refused with a number that is then accepted."""
    ds = simulate_record(FRAME, duration_s=120.0, fs_hz=20.0, snr_db=40.0, quantities="velocity", seed=3)
    modes = _extract(ds)
    settings = json.loads(modes.attrs["settings"])
    assert settings["blocks"] == settings["samples"] == modes.sizes["sample"] < SAMPLES
    assert settings["blocks_chosen"].startswith(f"{settings['blocks']} blocks of ")
    assert "the most the record holds" in settings["blocks_chosen"]
    assert "judged on its frequency" in settings["blocks_chosen"]  # 13 s blocks, shorter than 3 x 88 s
    s = score(modes.frequency.values, modes.sensor_shape.values, truth_modes(FRAME, ds))
    assert len(s["found"]) == 5 and not s["spurious"], s
    with pytest.raises(SignalError, match=r"too short for 15 blocks.*at most (\d+)") as refused:
        _extract(ds, samples=15)
    most = int(re.search(r"at most (\d+)", str(refused.value)).group(1))
    assert most == settings["blocks"]
    assert json.loads(_extract(ds, samples=most).attrs["settings"])["blocks_chosen"] is None  # asked, not chosen


def test_shape_samples_follow_a_chosen_number_of_blocks():
    ds = simulate_record(FRAME, duration_s=120.0, fs_hz=20.0, snr_db=40.0, quantities="velocity", seed=3)
    settings = json.loads(_extract(ds, shape_samples=60).attrs["settings"])
    J = settings["samples"]
    assert settings["shape_samples"] == J * round(60 / J) and settings["shape_samples"] % J == 0
    with pytest.raises(SignalError, match="whole multiple of samples = 8"):
        _extract(ds, samples=8, shape_samples=60)


def test_few_blocks_warn_that_the_standard_errors_are_rough():
    ds = simulate_record(FRAME, duration_s=240.0, fs_hz=20.0, snr_db=40.0, quantities="velocity", seed=3)
    with pytest.warns(
        TwinWarning,
        match=f"from {FEW_BLOCKS - 2} blocks: each standard error rests on {FEW_BLOCKS - 3} degrees of freedom",
    ):
        extract(ds, samples=FEW_BLOCKS - 2, progress=False)


def test_delete_one_standard_errors_stay_honest_in_blocks_shorter_than_a_time_constant():
    """15 blocks of 40 s of a 600 s record damped 0.05% (the slowest mode's time constant 350 s): over eight
    seeds, the four lowest modes' frequencies (where found) have errors from the truth in their standard errors have an RMS near 1 (a t
    distribution with 14 degrees of freedom: 1.08), the damping ratios' no larger."""
    frame = shear_frame(5, damping_ratio=0.0005)
    zf, zd = [], []
    for seed in range(8):
        ds = simulate_record(frame, duration_s=600.0, fs_hz=20.0, snr_db=40.0, quantities="velocity", seed=seed)
        m, truth = _extract(ds), truth_modes(frame, ds)
        for f0, z0 in zip(truth.frequency.values[:4], truth.damping_ratio.values[:4]):
            k = int(np.argmin(np.abs(m.frequency.values - f0)))
            if abs(m.frequency.values[k] / f0 - 1) > 0.005:
                continue
            zf.append((m.frequency.values[k] - f0) / m.frequency_se.values[k])
            zd.append((m.damping_ratio.values[k] - z0) / m.damping_ratio_se.values[k])
    assert len(zf) >= 28  # of 32
    rms_f, rms_d = np.sqrt(np.mean(np.square(zf))), np.sqrt(np.mean(np.square(zd)))
    assert 0.7 < rms_f < 1.4 and rms_d < 1.4, (rms_f, rms_d)
