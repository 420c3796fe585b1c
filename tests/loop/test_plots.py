"""Figures of a comparison: one scale for before and after, the MAC matrix near the band, files written."""

import numpy as np
import pytest

from twin.fem.effects import MagneticPull
from twin.fem.truthfile import Truth
from twin.loop.candidates import add_effects
from twin.loop.compare import compare
from twin.loop.plots import comparison_figures, mac_columns, modal_spectrum
from twin.update import synthesize_modes


@pytest.fixture(scope="module")
def before_after(hydro_unit):
    data = synthesize_modes(hydro_unit, Truth((MagneticPull(-1e8),)), n_modes=13, samples=20, seed=3)
    return compare(hydro_unit, data), compare(add_effects(hydro_unit, ["magnetic_pull"]), data, values={"MAG.stiffness": -1e8})


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
