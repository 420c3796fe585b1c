"""extract(): complex gyroscopic modes kept, harmonics rejected, the shear-frame reference, bad input, files."""

import json
import warnings

import numpy as np
import pytest
import xarray as xr

from twin import load_model, modal
from twin.cli import main
from twin.errors import SignalError, TwinWarning
from twin.extract import extract
from twin.fmu.statespace import full_state_space
from twin.modes import read_modes
from twin.modes.sensitivity import state_modes
from twin.modes.shapes import mac

# the toy records here have 2-3 channels and low rates on purpose: extract's warnings about that are expected
# (test_bad_requests_are_clear_errors checks them)
pytestmark = [
    pytest.mark.filterwarnings("ignore:signals. \\d channel:twin.errors.TwinWarning"),
    pytest.mark.filterwarnings("ignore:signals. sampled at:twin.errors.TwinWarning"),
]


@pytest.fixture(scope="module")
def gyro_record(make_record):
    """600 s of the gyroscopic rotor (circular whirl modes, MPC = 0) driven by white forces at the disk."""
    model = load_model("tests/data/gyro_rotor.toml")
    ss = full_state_space(model)
    lam, right, left = state_modes(ss.A)
    keep = lam.imag / (2 * np.pi) < 180.0
    lam, right, left = lam[keep], right[keep], left[keep]
    ports = [ss.port_index("4.x"), ss.port_index("4.y")]
    fs = 500.0
    ds = make_record(
        lam,
        (ss.C @ right.T).T,
        fs_hz=fs,
        duration_s=600.0,
        seed=3,
        noise_ratio=0.05,
        participation=(left @ ss.B[:, ports]) / fs * 1e3,
        channels=list(model.channels),
    )
    return model, ds


def test_gyroscopic_circular_modes_are_found_with_their_phase(gyro_record):
    model, ds = gyro_record
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        m = extract(ds, samples=20, fmax_hz=180.0, progress=False)
    ref = modal(model, n_modes=5)
    # modes 4 and 5 (137, 165 Hz, 5.3% damped) are near the sensor noise with disk forcing: mode 4 is found on
    # some seeds (this one: 135.95 Hz, 0.2 of its bandwidth its standard error); whatever else is found is
    # one of them, within 3 standard errors, never a spurious pole
    assert 3 <= m.sizes["mode"] <= 5
    for j in range(3, m.sizes["mode"]):
        k = int(np.argmin(np.abs(ref.frequency.values - float(m.frequency[j]))))
        assert k >= 3 and abs(float(m.frequency[j] - ref.frequency[k])) < 3 * float(m.frequency_se[j])
    for k in range(3):
        j = int(np.argmin(np.abs(m.frequency.values - float(ref.frequency[k]))))
        assert abs(float(m.frequency[j]) / float(ref.frequency[k]) - 1) < 0.005
        dz = abs(float(m.damping_ratio[j]) - float(ref.damping_ratio[k]))
        # over seeds 3-12 the standard error is 0.82-1.21 times the spread of the damping ratios, with
        # errors up to 3.4 standard errors (mode 1 of this seed: 3.3): 4 of them is a real bound
        assert dz < 0.2 * float(ref.damping_ratio[k]) and dz < 4 * float(m.damping_ratio_se[j])
        assert float(mac(m.sensor_shape.values[j], ref.sensor_shape.values[k])) > 0.99
    assert np.all(m.MPC.values < 0.05) and np.all(m.MPD.values > 40)  # circular whirls kept, phase intact
    # every sample keeps the phase: the reference channel real positive, the others complex
    ref_ch = [list(m.channel.values).index(c) for c in m.reference_channel.values]
    pivot = np.take_along_axis(m.shape.values, np.array(ref_ch)[:, None, None], axis=2)
    assert np.allclose(pivot.imag, 0, atol=1e-12) and np.all(pivot.real > 0)


def test_running_speed_harmonic_is_rejected_and_reported(make_record):
    poles = np.array([-0.01 * 2 * np.pi * 3.1 + 2j * np.pi * 3.1, -0.02 * 2 * np.pi * 7.0 + 2j * np.pi * 7.0])
    shapes = np.array([[1.0, 1j, 0.4], [0.3, -0.5, 1.0]])
    ds = make_record(
        poles,
        shapes,
        fs_hz=32.0,
        duration_s=1200.0,
        seed=5,
        sinusoid=(2.25, 40.0 * np.array([1.0, -1j, 0.2])),
        attrs={"speed_rpm": 135.0},
    )
    m = extract(ds, samples=20, max_order=40, progress=False, remove_harmonics=False)
    for f in (3.1, 7.0):
        assert np.min(np.abs(m.frequency.values / f - 1)) < 5e-3
    assert np.min(np.abs(m.frequency.values - 2.25)) > 0.05  # the 1X line is no mode
    harmonics = json.loads(m.attrs["harmonics"])
    assert len(harmonics) == 1 and harmonics[0]["running_speed_multiple"] == 1
    assert abs(harmonics[0]["frequency_hz"] - 2.25) < 1e-3 and harmonics[0]["kurtosis"] < 2.0
    assert (m.diagram_mode.values == -2).any()
    # by default, the extraction subtracts the line before SSI: reported as removed, and SSI never sees it
    m = extract(ds, samples=20, max_order=40, progress=False)
    harmonics = json.loads(m.attrs["harmonics"])
    assert len(harmonics) == 1 and harmonics[0]["removed"] and harmonics[0]["running_speed_multiple"] == 1
    assert abs(harmonics[0]["frequency_hz"] - 2.25) < 1e-4
    assert harmonics[0]["amplitude"] == pytest.approx(40.0, rel=0.02)  # |a| of cos(2 pi f t) Re(a) - sin Im(a)
    assert not (m.diagram_mode.values == -2).any()
    for f in (3.1, 7.0):
        assert np.min(np.abs(m.frequency.values / f - 1)) < 5e-3
    # nothing but the two modes: a noise pole that persisted over orders next to the 7 Hz mode (7.26 Hz on this
    # seed) scatters over its samples beyond its own bandwidth and is dropped, listed as such
    assert m.sizes["mode"] == 2
    for u in json.loads(m.attrs["undetermined_poles"]):
        assert min(abs(u["frequency_hz"] / f - 1) for f in (3.1, 7.0)) > 5e-3
        assert (
            u["frequency_se_hz"] > u["damping_ratio"] * u["frequency_hz"] / 2
            or u["damping_ratio_se"] > 0.5 * u["damping_ratio"]
        )


def test_shear_frame_reference(shear_frame):
    """KOMA's shear frame: the 5 modes. The record was integrated with the trapezoidal rule at its
    sampling step, so its poles are the reference ones through z = (1 + l h/2) / (1 - l h/2)."""
    ds, omega_n, xi, _ = shear_frame
    m = extract(ds, samples=10, progress=False)
    h = 1.0 / 12.0
    lam_c = -xi * omega_n + 1j * omega_n * np.sqrt(1 - xi**2)
    lam_d = np.log((1 + lam_c * h / 2) / (1 - lam_c * h / 2)) / h
    f_ref, z_ref = lam_d.imag / (2 * np.pi), -lam_d.real / np.abs(lam_d)
    assert m.sizes["mode"] == 5
    f_err = np.abs(m.frequency.values / f_ref - 1)
    # mode 1 (0.18 Hz, 217 periods in the record) has a standard error of about 0.6% of frequency
    assert np.all(f_err[1:] < 0.005) and f_err[0] < 0.01
    # errors in standard errors: with J = 10 the standard error is itself uncertain (t with 9 degrees of
    # freedom, 3.5 its two-sided 0.5% point); measured 0.4, 0.6, 0.5, 1.1, 2.7
    z = (m.frequency.values - f_ref) / m.frequency_se.values
    assert np.all(np.abs(z) < 3.5) and np.sqrt(np.mean(z**2)) < 2.0, z
    # damping from 1200 s is uncertain by 10-25% (jackknife standard error): within 2.5 of them
    assert np.all(np.abs(m.damping_ratio.values - z_ref) < 2.5 * m.damping_ratio_se.values)
    # with 99 block rows a noise cluster at 2.66 Hz has no counterpart in 45% of the reduced records' orders:
    # its samples, held at the full-record pole there, scatter within its bandwidth only when that is ignored
    with pytest.warns(
        TwinWarning,
        match=r"signals: 2.65\d Hz left out: stable over the model orders, but its "
        r"frequency .* scatters over the samples by 1.\d times",
    ):
        longer = extract(ds, samples=10, block_rows=99, progress=False)
    assert longer.sizes["mode"] == 5
    assert np.all(np.abs(longer.frequency.values / f_ref - 1)[1:] < 0.005)


def test_bad_requests_are_clear_errors(make_record):
    ds = make_record(np.array([-0.1 + 2j * np.pi * 2.0]), np.array([[1.0, 1j]]), fs_hz=20.0, duration_s=100.0, seed=0)
    with pytest.raises(SignalError, match=r"too short for modes down to fmin = 0.5 Hz: it needs 200 s"):
        extract(ds, fmin_hz=0.5, progress=False)
    with pytest.raises(SignalError, match="too short for 100 blocks"):
        extract(ds, samples=100, progress=False)
    with pytest.raises(SignalError, match="fmax = 20 Hz must be positive and at most Nyquist"):
        extract(ds, fmax_hz=20.0, progress=False)
    with pytest.raises(SignalError, match="samples must be at least 2"):
        extract(ds, samples=1, progress=False)
    with pytest.raises(SignalError, match="max_order must be at least 2"):
        extract(ds, max_order=1, progress=False)
    for bad in (0, 2.5, "3"):
        with pytest.raises(SignalError, match=f"first_lag must be a whole number of samples, at least 1.*got {bad!r}"):
            extract(ds, first_lag=bad, progress=False)
    with pytest.raises(SignalError, match="nowhere.nc: no such signals file"):
        extract("nowhere.nc", progress=False)


def test_poor_records_warn_before_the_work(make_record, tmp_path):
    """Two channels, or 20 Hz sampling without fmax: extraction runs but says what it cannot see."""
    from twin.errors import TwinWarning

    ds = make_record(np.array([-0.1 + 2j * np.pi * 2.0]), np.array([[1.0, 1j]]), fs_hz=20.0, duration_s=200.0, seed=0)
    with pytest.warns(TwinWarning) as caught:
        extract(ds, samples=10, max_order=16, progress=False)
    text = " ".join(str(w.message) for w in caught)
    assert "2 channel(s)" in text and "use at least 4" in text
    assert "sampled at 20 Hz and no fmax given: modes are extracted up to 8 Hz only" in text
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        extract(ds, samples=10, max_order=16, fmax_hz=8.0, progress=False)
    assert not any("no fmax given" in str(w.message) for w in caught)
    # a folder or a text file given as signals is named as such
    with pytest.raises(SignalError, match="is a folder, not a signals file"):
        extract(tmp_path, progress=False)
    (tmp_path / "a.nc").write_text("time,x\n0,1\n")
    with pytest.raises(SignalError, match="a.nc: not a NetCDF file"):
        extract(tmp_path / "a.nc", progress=False)


def test_files_and_command_line(make_record, tmp_path, capsys):
    poles = np.array([-0.02 * 2 * np.pi * 2.0 + 2j * np.pi * 2.0, -0.01 * 2 * np.pi * 5.0 + 2j * np.pi * 5.0])
    ds = make_record(
        poles,
        np.array([[1.0, 1j], [1.0, -0.5]]),
        fs_hz=20.0,
        duration_s=1000.0,
        seed=1,
        channels=["A_x", "A_y"],
        attrs={"truth": "{}", "seed": 1},
    )
    signals = tmp_path / "signals.nc"
    ds.to_netcdf(signals)
    out, png = tmp_path / "modes.nc", tmp_path / "stab.png"
    assert main(["extract", str(signals), "-o", str(out), "--samples", "10", "--plot", str(png)]) == 0
    assert png.stat().st_size > 10_000 and "modes, 10 samples each" in capsys.readouterr().out
    raw = xr.load_dataset(out)
    for v in ("pole_real", "pole_imag", "shape_real", "shape_imag", "frequency", "damping_ratio", "MPC", "MPD"):
        assert v in raw
    assert raw.shape_real.dims == ("mode", "sample", "channel") and "truth" in raw.attrs
    assert json.loads(raw.attrs["settings"])["samples"] == 10
    m = read_modes(out)
    assert np.iscomplexobj(m.pole) and np.iscomplexobj(m.shape) and np.iscomplexobj(m.sensor_shape)
    for f in (2.0, 5.0):
        assert np.min(np.abs(m.frequency.values / f - 1)) < 5e-3
    settings = json.loads(raw.attrs["settings"])
    assert settings["delete_blocks"] == 1 and settings["order_spread"] == "shapes"
    assert settings["first_lag"] == 3  # the first lag at or beyond a period of fmax (8 Hz) at 20 Hz
    assert main(["extract", str(signals), "-o", str(out), "--samples", "10", "--first-lag", "1"]) == 0
    assert json.loads(xr.load_dataset(out).attrs["settings"])["first_lag"] == 1
    honest = tmp_path / "honest.nc"
    assert (
        main(["extract", str(signals), "-o", str(honest), "--samples", "10", "--delete-half", "--order-spread", "all"])
        == 0
    )
    settings = json.loads(xr.load_dataset(honest).attrs["settings"])
    assert settings["delete_blocks"] == 5 and settings["order_spread"] == "all" and settings["blocks"] == 10
    assert main(["extract", str(signals), "-o", str(honest), "--samples", "12", "--blocks", "6", "--delete-half"]) == 0
    raw = xr.load_dataset(honest)
    settings = json.loads(raw.attrs["settings"])
    assert (settings["blocks"], settings["samples"], settings["delete_blocks"], raw.sizes["sample"]) == (6, 12, 3, 12)
    assert main(["extract", str(signals), "-o", str(honest), "--samples", "10", "--shape-samples", "30"]) == 0
    raw = xr.load_dataset(honest)
    settings = json.loads(raw.attrs["settings"])
    assert (settings["samples"], settings["shape_samples"], settings["delete_blocks"], raw.sizes["sample"]) == (
        10,
        30,
        1,
        30,
    )
    # delete-one gives one sample per block: asking for more is named, with nothing written
    assert main(["extract", str(signals), "-o", str(tmp_path / "one.nc"), "--samples", "12", "--blocks", "6"]) == 2
    assert "one sample per block" in capsys.readouterr().err and not (tmp_path / "one.nc").exists()
    # bad input: one line, exit status 2, no file left behind
    ds["displacement"][10, 0] = np.nan
    ds.to_netcdf(tmp_path / "bad.nc")
    assert main(["extract", str(tmp_path / "bad.nc"), "-o", str(tmp_path / "bad_modes.nc")]) == 2
    assert "channel 'A_x' has 1 NaN" in capsys.readouterr().err
    assert not list(tmp_path.glob("bad_modes*"))


def test_decimation_by_a_prime_factor_above_eight(make_record):
    """fs / (2.5 fmax) = 11: one FIR stage of 11 (no factor of 8 or less divides it)."""
    lam = -0.02 * 2 * np.pi * 1.0 + 2j * np.pi * 1.0
    ds = make_record(np.array([lam]), np.array([[1.0, 0.6j]]), fs_hz=110.0, duration_s=600.0, seed=2)
    m = extract(ds, samples=10, fmax_hz=4.0, max_order=16, progress=False)
    assert json.loads(m.attrs["settings"])["decimation"] == 11
    assert np.min(np.abs(m.frequency.values - 1.0)) < 0.01


def test_the_extraction_runs_on_one_blas_thread(make_record, monkeypatch):
    # many small SVDs and QRs: OpenBLAS's threads cost more than they gain (benchmarks/extract_threads.py);
    # the limit holds inside the SSI passes and is lifted again afterwards
    import twin.extract.steps as core
    from twin.tasks import blas_threads

    seen, ssi_pass = [], core.ssi_pass
    monkeypatch.setattr(core, "ssi_pass", lambda *a, **k: seen.append(blas_threads()) or ssi_pass(*a, **k))
    outside = blas_threads()
    ds = make_record(np.array([-0.1 + 2j * np.pi * 2.0]), np.array([[1.0, 1j]]), fs_hz=20.0, duration_s=600.0, seed=0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        extract(ds, samples=4, max_order=8, fmax_hz=8.0, progress=False)
    assert seen and set(seen) == {1}
    assert blas_threads() == outside


def test_a_short_record_of_lightly_damped_modes_keeps_every_mode(make_record):
    """240 s of seven modes damped 0.2%: 16 s blocks are a fifth of a time constant of the slowest, too short to
    tell their damping, and a mode whose damping scattered was dropped as "no physical mode" (8.19 Hz here).
    Every mode is kept, on the default and on fewer samples alike, and nothing else comes in."""
    f = np.array([1.2, 2.1, 3.4, 4.9, 6.3, 8.2, 9.9])
    poles = -0.002 * 2 * np.pi * f + 2j * np.pi * f * np.sqrt(1 - 0.002**2)
    shapes = np.random.default_rng(3).standard_normal((len(f), 5)) + 0j
    ds = make_record(poles, shapes, fs_hz=32.0, duration_s=240.0, seed=3, noise_ratio=0.05)
    for samples in (15, 8):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", TwinWarning)  # the blocks are short: said, and true
            found = extract(ds, fmax_hz=12.0, samples=samples, progress=False)["frequency"].values
        assert len(found) == len(f), (samples, found)
        np.testing.assert_allclose(np.sort(found), f, rtol=5e-3)


def test_a_record_without_modes_is_a_no_mode_error():
    """White noise alone: the record is read and analysed, and the error says no mode stood out of it (a
    NoModeError, which programs going over many records can tell from bad input), with the block rows."""
    from twin.errors import NoModeError

    rng = np.random.default_rng(3)
    ds = xr.Dataset(
        {"displacement": (("time", "channel"), 1e-6 * rng.standard_normal((20 * 600, 4)))},
        coords={"channel": ["a", "b", "c", "d"]},
        attrs={"sampling_rate": 20.0},
    )
    with pytest.raises(NoModeError, match="no physical mode found between") as caught:
        extract(ds, progress=False)
    assert isinstance(caught.value, SignalError) and caught.value.block_rows >= 1
