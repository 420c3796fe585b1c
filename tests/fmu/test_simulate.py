"""Signals through the FMU: file layout, round trip, truth in attrs, bad input."""

import json
import warnings

import numpy as np
import pytest
import xarray as xr

from twin import ModelError, TwinError
from twin.cli import main
from twin.fem.truthfile import Truth
from twin.fem.effects import MagneticPull
from twin.fmu import discretize, full_state_space, simulate_reference
from twin.fmu.excitation import excitation_forces, sensor_noise, turbulence_force
from twin.fmu.simulate import simulate
from tests.fmu.reference import fmu_reference


def test_signals_equal_the_numpy_reference_after_the_warm_up(hydro_unit):
    fs, warm, n = 256.0, 2.0, 128
    ds = simulate(hydro_unit, duration_s=n / fs, fs_hz=fs, seed=3, warmup_s=warm, progress=False)
    settings = json.loads(ds.attrs["settings"])
    ss = full_state_space(hydro_unit)
    h, total = 1 / fs, int(warm * fs) + n
    t = (np.arange(total) - int(warm * fs)) * h
    foh = excitation_forces(ss, t, 8, 100.0, 28, turbulence_force(total, 3000.0, 3, h))
    ref = simulate_reference(discretize(ss, h), ss.C, foh=foh)
    ref += sensor_noise(total, 8, settings["noise_std_m"], 3 + 7919)
    np.testing.assert_allclose(ds.displacement.values, ref[-n:], rtol=0, atol=1e-9 * np.abs(ref).max())
    np.testing.assert_allclose(ds.time.values, np.arange(n) / fs)


def test_signal_file_round_trip(tmp_path, hydro_unit):
    out = tmp_path / "signals.nc"
    ds = simulate(hydro_unit, duration_s=1.0, fs_hz=256.0, seed=1, output=out, progress=False, command="test")
    back = xr.open_dataset(out)
    xr.testing.assert_identical(back.load(), ds)
    assert back.displacement.attrs["units"] == "m" and back.attrs["sampling_rate"] == 256.0
    assert list(back.channel.values) == hydro_unit.channels
    assert list(back.location.values[:2]) == ["runner seals", "runner seals"]
    assert back.attrs["sampling_rate_units"] == "Hz" and back.time.attrs["units"] == "s"
    assert all("long_name" in back[c].attrs for c in ("channel", "node", "direction", "location"))
    assert [p.name for p in tmp_path.iterdir()] == ["signals.nc"]  # no temporary file left


def test_truth_is_recorded_in_the_attrs(hydro_unit):
    truth = Truth((MagneticPull(stiffness=-5e7),), "hidden.toml")
    ds = simulate(hydro_unit, duration_s=1.0, fs_hz=256.0, truth=truth, progress=False)
    assert json.loads(ds.attrs["truth"])["effects"]["magnetic_pull"]["stiffness"] == -5e7
    assert len(json.loads(ds.attrs["truth_modes"])) > 15


def test_bad_input(tmp_path, hydro_unit):
    with pytest.raises(ModelError, match="duration must be positive"):
        simulate(hydro_unit, duration_s=0.0, progress=False)
    with pytest.raises(ModelError, match="sampling rate must be positive"):
        simulate(hydro_unit, duration_s=1.0, fs_hz=-1.0, progress=False)
    with pytest.raises(TwinError, match="it is a folder"):
        simulate(hydro_unit, duration_s=1.0, output=tmp_path, progress=False)
    unstable = hydro_unit.with_values({"LGB.cxx": 1e3, "LGB.cyy": 1e3})
    with pytest.raises(ModelError, match="unstable at 134 rpm: modes at"):
        simulate(unstable, duration_s=1.0, output=tmp_path / "s.nc", progress=False)
    with pytest.warns(UserWarning, match="fs = 50 Hz is low for modes up to 100.0 Hz"):
        simulate(hydro_unit, duration_s=0.5, fs_hz=50.0, warmup_s=0.0, progress=False)
    assert list(tmp_path.iterdir()) == []


def test_simulate_command(tmp_path, capsys):
    out = tmp_path / "s.nc"
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert (
            main(
                ["simulate", "models/hydro_unit.toml", "--duration", "1", "--fs", "256", "--seed", "2", "-o", str(out)]
            )
            == 0
        )
    ds = xr.open_dataset(out)
    assert ds.sizes["time"] == 256 and ds.attrs["seed"] == 2
    assert (
        main(
            [
                "simulate",
                "models/hydro_unit.toml",
                "--duration",
                "1",
                "--truth",
                str(tmp_path / "none.toml"),
                "-o",
                str(tmp_path / "t.nc"),
            ]
        )
        == 2
    )
    assert "no such file" in capsys.readouterr().err


@pytest.mark.slow
def test_one_hour_with_the_paper_truth_has_the_predicted_variance(tmp_path, hydro_unit):
    from twin.fem.truthfile import paper_truth
    from twin.fmu.simulate import output_rms
    from twin.fmu.truth import truth_state_space

    out = tmp_path / "signals.nc"
    simulate(
        hydro_unit,
        duration_s=3600.0,
        fs_hz=256.0,
        seed=1,
        truth=paper_truth(),
        unbalance_me=0.0,
        noise_ratio=0.0,
        output=out,
        progress=False,
    )
    ds = xr.open_dataset(out)
    x = ds.displacement.values
    assert x.shape == (3600 * 256, 8) and np.all(np.isfinite(x))
    assert len(json.loads(ds.attrs["truth_modes"])) == 15
    # steady-state RMS of the truth system under the turbulence alone (discrete Lyapunov equation);
    # the slowest mode decorrelates in ~10 s, so 1 h gives the variance to a few percent
    ss = truth_state_space(hydro_unit, paper_truth())
    expected = output_rms(ss, 1 / 256.0, 3000.0, [ss.port_index("28.x"), ss.port_index("28.y")])
    np.testing.assert_allclose(x.std(axis=0), expected, rtol=0.15)


def test_a_steady_start_needs_no_warm_up(hydro_unit):
    """With steady_start the record is the reference run from the FMU's steady start, from its first sample."""
    fs, n = 256.0, 256
    ds = simulate(hydro_unit, duration_s=n / fs, fs_hz=fs, seed=5, steady_start=True, progress=False)
    settings = json.loads(ds.attrs["settings"])
    assert settings["warmup_s"] == 0 and settings["steady_start"] is True
    ref = fmu_reference(full_state_space(hydro_unit), n, me=100.0, asd=3000.0, seed=5, steady=True)
    ref += sensor_noise(n, 8, settings["noise_std_m"], 5 + 7919)
    np.testing.assert_allclose(ds.displacement.values, ref, rtol=0, atol=1e-9 * np.abs(ref).max())
    with pytest.raises(ModelError, match="not both"):
        simulate(hydro_unit, duration_s=1.0, steady_start=True, warmup_s=2.0, progress=False)
