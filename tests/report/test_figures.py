"""Figures of a comparison: one scale for before and after, the MAC matrix near the band, files written."""

import numpy as np
import pytest

from twin.fem.effects import MagneticPull
from twin.fem.truthfile import Truth
from twin.loop.candidates import add_effects
from twin.loop.compare import compare
from twin.report.figures import comparison_figures, mac_columns, modal_spectrum
from twin.update import synthesize_modes


@pytest.fixture(scope="module")
def before_after(hydro_unit):
    data = synthesize_modes(hydro_unit, Truth((MagneticPull(-1e8),)), n_modes=13, samples=20, seed=3)
    return compare(hydro_unit, data), compare(
        add_effects(hydro_unit, ["magnetic_pull"]), data, values={"MAG.stiffness": -1e8}
    )


def test_mac_matrix_keeps_the_paired_and_in_band_model_modes(before_after):
    table = before_after[0]
    cols = mac_columns(table)
    assert set(table["partner"].values - 1) <= set(cols.tolist())
    assert len(cols) < 0.3 * table.sizes["mode_model"]  # the kHz modes are left out
    f = table["model_mode_frequency"].values[cols]
    assert f.max() <= 1.1 * float(table["measured_frequency"].max()) or np.isin(cols, table["partner"].values - 1).all()
    # the pairing is the best MAC for the well-separated modes
    m = table["mac_matrix"].values
    rows = np.flatnonzero(table["mac"].values > 0.99)
    assert np.all(m[rows, table["partner"].values[rows] - 1] == m[rows].max(axis=1))


def test_before_and_after_are_drawn_into_three_figures(before_after, tmp_path):
    paths = comparison_figures(list(before_after), tmp_path / "figs", labels=["before", "after"])
    assert [p.name for p in paths] == ["errors.png", "mac.png", "spectra.png"]
    assert all(p.stat().st_size > 10_000 for p in paths)


def test_modal_spectrum_peaks_at_each_mode_with_the_half_power_width():
    f0, zeta = 10.0, 0.01
    w0 = 2 * np.pi * f0
    pole = w0 * (-zeta + 1j * np.sqrt(1 - zeta**2))
    f = np.linspace(9, 11, 20001)
    s = modal_spectrum(np.array([pole]), np.array([[1.0]]), f)[0]
    half = f[s >= s.max() / 2]
    assert f[np.argmax(s)] == pytest.approx(f0 * np.sqrt(1 - zeta**2), abs=1e-3)
    assert half[-1] - half[0] == pytest.approx(2 * zeta * f0, rel=0.01)  # the half-power bandwidth


def test_the_spectra_of_a_record_are_its_psd_peaking_at_its_modes(tmp_path, make_record):
    """With the record, spectra.png is what a monitoring engineer reads: each channel's PSD [µm²/Hz], which peaks
    at the modes the channel sees most, with the identified and the model's modes marked."""
    import xarray as xr

    from twin.report.figures import psd_figure, record_psd

    poles = [-0.02 * 2 * np.pi * 2 + 2j * np.pi * 2, -0.01 * 2 * np.pi * 5 + 2j * np.pi * 5]
    record = make_record(
        poles, [[1e-6, 0.05e-6j], [0.05e-6, 1e-6]], fs_hz=32.0, duration_s=400.0, seed=2, channels=["A_x", "A_y"]
    )
    freq, psd, channels = record_psd(record, ["A_x", "A_y", "B_x"], 2.0)  # B_x: not in the record
    assert channels == ("A_x", "A_y")
    assert freq[np.argmax(psd[:, 0])] == pytest.approx(2.0, abs=2 * freq[1])
    assert freq[np.argmax(psd[:, 1])] == pytest.approx(5.0, abs=2 * freq[1])
    # the PSD integrates to the channel's variance [µm²]
    assert np.sum(psd[:, 0]) * freq[1] == pytest.approx(1e12 * record["displacement"].values[:, 0].var(), rel=0.05)
    table = xr.Dataset(
        {"measured_frequency": ("mode", [2.0, 5.0]), "model_frequency": ("mode", [2.1, 4.9])},
        coords={"channel": ["A_x", "A_y"]},
    )
    assert psd_figure(record, [table], ["model"], tmp_path / "spectra.png").stat().st_size > 10_000
