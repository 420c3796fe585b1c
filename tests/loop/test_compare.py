"""Comparison of a model with measured modes: pairing, the error figure, the table, bad input."""

import dataclasses

import numpy as np
import pytest

from twin.errors import CompareError
from twin.fem.effects import MagneticPull
from twin.fem.truthfile import Truth
from twin.loop.compare import compare, overall_error
from twin.modes.measured import measured_modes
from twin.update import synthesize_modes


def _data(model, truth, seed=3, variance=(0.01, 0.01), samples=100):
    return synthesize_modes(
        model, truth, n_modes=None if truth.per_mode else 13, samples=samples, seed=seed, pole_variance=variance
    )


def test_error_is_the_rms_relative_pole_distance():
    meas = np.array([-1 + 100j, -2 + 200j])
    model = meas * np.array([1.01, 1.0])
    assert overall_error(model, meas) == pytest.approx(0.01 / np.sqrt(2), rel=1e-12)
    # equal relative uncertainties: the weighted error is the plain RMS
    assert overall_error(model, meas, 1e-3 * np.abs(meas)[:, None] * [1, 1]) == pytest.approx(
        0.01 / np.sqrt(2), rel=1e-12
    )


def test_error_weighs_each_pole_part_by_its_inverse_variance():
    meas = np.array([100j, -60 + 80j])  # |λ| = 100
    model = meas + np.array([1j, 3.0])  # 1% on the first mode's imaginary part, 3% on the second's real part
    sigma = np.array([[0.1, 0.1], [1.0, 2.0]])
    w = (100 / sigma) ** 2
    expected = np.sqrt(2 * (w[0, 1] * 0.01**2 + w[1, 0] * 0.03**2) / w.sum())
    assert overall_error(model, meas, sigma) == pytest.approx(expected, rel=1e-12)
    # a mode whose pole is only known to 10% hardly counts: the error is the well-known mode's 1%
    assert overall_error(model, meas, np.array([[0.1, 0.1], [10.0, 10.0]])) == pytest.approx(0.01, rel=0.01)


def test_model_equal_to_the_truth_has_error_at_the_noise_floor(hydro_unit):
    truth = Truth((MagneticPull(-1e8),))
    data = _data(hydro_unit, truth, variance=(0.0, 0.0))
    table = compare(dataclasses.replace(hydro_unit, effects=truth.effects), data)
    assert table.sizes["mode"] == 13 and len(table.attrs["poorly_paired"]) == 0
    assert table.attrs["error"] < 1e-10 and float(table["mac"].min()) > 0.99  # round-off
    assert float(table["shape_error"].max()) < 0.05 * 1.5  # the 5% shape noise, averaged over 100 samples


def test_hidden_effect_shows_in_the_table(hydro_unit):
    data = _data(hydro_unit, Truth((MagneticPull(-1e8),)))
    table = compare(hydro_unit, data)
    meas = measured_modes(data)
    # mode 2 (generator mode) moves most: 11.7% in frequency, far beyond the measurement sigma
    k = int(np.argmax(np.abs(table["frequency_error"].values)))
    assert int(table["mode"][k]) == 2 and float(table["z_frequency"][k]) > 50
    paired = np.isin(meas.mode, table["mode"])
    assert paired.all()  # every measured mode counts
    assert table.attrs["error_rms"] == pytest.approx(overall_error(_poles(table), meas.pole[paired]), rel=1e-9)
    assert table.attrs["error"] == pytest.approx(
        overall_error(_poles(table), meas.pole[paired], meas.sigma[paired]), rel=1e-9
    )
    # E is the comparison's chi2 written as a relative pole error
    norm = np.sum((np.abs(meas.pole[paired])[:, None] / meas.sigma[paired]) ** 2)
    assert table.attrs["error"] == pytest.approx(np.sqrt(2 * table.attrs["chi2"] / norm), rel=1e-9)


def _poles(table):
    z, f = table["model_damping_ratio"].values, table["model_frequency"].values
    return 2 * np.pi * f * (-z / np.sqrt(1 - z**2) + 1j)


def test_per_mode_model_compares_mode_by_mode(hydro_unit):
    from twin.fem.truthfile import paper_truth

    truth = paper_truth()
    data = _data(hydro_unit, truth, variance=(0.0, 0.0))
    fitted = dataclasses.replace(hydro_unit, effects=truth.effects)
    table = compare(fitted, data)
    assert table.attrs["error"] < 1e-9
    assert table.sizes["mode"] == 15


def test_uncertainty_is_the_standard_error_plus_the_tolerance(hydro_unit):
    data = _data(hydro_unit, Truth((MagneticPull(0.0),)), variance=(1.0, 4.0), samples=400, seed=5)
    meas = measured_modes(data, tolerance=0.0)
    assert np.allclose(meas.sigma[:, 0], 1 / 20, rtol=0.1) and np.allclose(meas.sigma[:, 1], 2 / 20, rtol=0.1)
    wide = measured_modes(data, tolerance=1e-2)
    assert np.all(wide.sigma[:, 1] >= 1e-2 * np.abs(wide.pole))


def test_bad_input_is_named(hydro_unit):
    data = _data(hydro_unit, Truth((MagneticPull(0.0),)), samples=5)
    with pytest.raises(CompareError, match=r"channel\(s\) \['XX_x'\] are not sensors"):
        compare(hydro_unit, data.assign_coords(channel=["XX_x", *data["channel"].values[1:]]))
    bad = data.copy(deep=True)
    bad["pole"][2, 1] = np.nan
    with pytest.raises(CompareError, match=r"mode\(s\) \[3\] have non-finite"):
        compare(hydro_unit, bad)
    with pytest.raises(CompareError, match="at least 2 samples"):
        compare(hydro_unit, data.isel(sample=[0]))
    with pytest.raises(CompareError, match="no variable 'pole'"):
        compare(hydro_unit, data.drop_vars("pole"))


def test_no_measured_mode_is_ever_dropped(hydro_unit):
    """A strong magnetic pull moves two modes so far that no model mode looks like them: they still count."""
    data = _data(hydro_unit, Truth((MagneticPull(-2.5e8),)))
    table = compare(hydro_unit, data)
    assert table.sizes["mode"] == data.sizes["mode"]
    assert len(table.attrs["poorly_paired"]) >= 1
    low = table["mac"].values < table.attrs["min_mac"]
    assert set(table["mode"].values[low]) == set(table.attrs["poorly_paired"])
    z = table["z_frequency"].values ** 2 + table["z_damping"].values ** 2
    assert table.attrs["chi2"] == pytest.approx(z.sum()) and z[low].sum() > 0.5 * z.sum()  # and they weigh most


def test_pairing_is_one_to_one_and_follows_the_pole(hydro_unit):
    from twin.modes.measured import channel_dofs, pair_with_measured
    from twin.modes.sensitivity import solve_modes

    meas = measured_modes(_data(hydro_unit, Truth((MagneticPull(-1e8),))))
    sol = solve_modes(hydro_unit)
    _, cols = pair_with_measured(sol, meas, channel_dofs(hydro_unit, meas.channels))
    assert len(set(cols)) == len(cols) == len(meas.mode)
    # the 17.15 Hz mode pairs with the 17.15 Hz model mode, not with a kHz mode that the 8 sensors see alike
    k = int(np.argmin(np.abs(meas.frequency - 17.15)))
    assert abs(sol.poles[cols[k]].imag / (2 * np.pi) - 17.15) < 0.1


def test_per_mode_effect_with_fewer_values_than_measured_modes(hydro_unit):
    """twin compare --effect fsi_per_mode: a per-mode effect sized to the measured modes, zero-valued."""
    from twin.loop.candidates import add_effects

    data = _data(hydro_unit, Truth((MagneticPull(0.0),)), samples=20)
    model = add_effects(hydro_unit, ["fsi_per_mode"], data["mode"].values)
    table = compare(model, data)
    assert table.attrs["error"] == pytest.approx(compare(hydro_unit, data).attrs["error"], rel=1e-9)


def test_z_scores_have_the_sign_of_their_errors(hydro_unit):
    """z_f follows df and z_zeta follows dzeta (the real part of a pole is -zeta omega: its sign is flipped)."""
    table = compare(hydro_unit, _data(hydro_unit, Truth((MagneticPull(-1e8),))))
    for z, d in (("z_frequency", "frequency_error"), ("z_damping", "damping_error")):
        big = np.abs(table[z].values) > 3
        assert big.any() and np.all(np.sign(table[z].values[big]) == np.sign(table[d].values[big])), z
