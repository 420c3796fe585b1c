"""pLSCF: exact modes from exact covariances, heavily damped overlapping modes from a record, the algorithm option."""

import numpy as np
import pytest

from twin.errors import SignalError
from twin.extract import extract
from twin.extract.algorithms import Algorithm
from twin.extract.plscf import matrix_fraction
from twin.extract.ssi import block_covariances
from twin.modes.shapes import mac


def _modal_covariances(poles, shapes, participation, fs, n_lags):
    """``R_k = 2 Re(sum_r psi_r g_r^T mu_r^k)``: the covariances of a record of these modes, exactly."""
    mu = np.exp(np.asarray(poles) / fs)
    return np.array([2 * np.real((shapes * mu**k) @ participation.T) for k in range(n_lags + 1)])


def test_exact_covariances_give_the_exact_modes_and_unstable_extra_poles():
    """Three modes damped 5-10%, two 1 Hz apart: every order that holds them gives their poles and shapes (to the
    half spectra's truncation at the last lag, where window and decay leave 1e-6 of the first lag's); the
    fraction's extra poles are unstable (negative damping), so a stabilisation diagram never keeps them."""
    fs = 100.0
    f, z = np.array([10.0, 11.0, 25.0]), np.array([0.07, 0.05, 0.10])
    poles = 2 * np.pi * f * (-z + 1j * np.sqrt(1 - z**2))
    rng = np.random.default_rng(3)
    shapes = rng.standard_normal((4, 3)) + 1j * rng.standard_normal((4, 3))
    g = rng.standard_normal((4, 3)) + 1j * rng.standard_normal((4, 3))
    R = _modal_covariances(poles, shapes, g, fs, 200)
    fit = matrix_fraction(R, 24, fs, (0.0, 50.0), first_lag=2)
    assert fit.orders.tolist() == [4, 8, 12, 16, 20, 24]
    for n in fit.orders[1:]:  # order 4 holds two poles: too few
        lam, phi = fit.modes(n)
        stable = lam.real < 0
        order = np.argsort(lam[stable].imag)
        assert np.allclose(lam[stable][order], poles, rtol=1e-6)
        assert np.all(np.diag(mac(phi[:, stable][:, order].T, shapes.T)) > 1 - 1e-6)


def test_a_band_too_narrow_for_the_order_is_a_clear_error():
    R = np.random.default_rng(0).standard_normal((21, 2, 2))
    with pytest.raises(ValueError, match="frequency lines"):
        matrix_fraction(R, 40, 10.0, (1.0, 1.2))
    with pytest.raises(ValueError, match="lag 0 holds the sensor noise"):
        matrix_fraction(R, 4, 10.0, (0.0, 5.0), first_lag=0)


def test_heavily_damped_weak_modes_driven_at_one_point(make_record):
    """Five modes damped 4-10%, driven by one force, the upper two weak (a fifth of the first's amplitude) on
    six channels with 10% sensor noise: pLSCF finds all five within their standard errors and nothing else
    (SSI, at its defaults, finds the strongest one or two of them on this record)."""
    f, z = np.array([20.0, 21.5, 26.0, 41.0, 47.0]), np.array([0.04, 0.08, 0.07, 0.10, 0.09])
    poles = 2 * np.pi * f * (-z + 1j * np.sqrt(1 - z**2))
    rng = np.random.default_rng(11)
    shapes = rng.standard_normal((5, 6)) + 0.3j * rng.standard_normal((5, 6))
    amplitude = np.array([1.0, 0.7, 0.5, 0.25, 0.2])
    one_force = rng.standard_normal((5, 1)) + 1j * rng.standard_normal((5, 1))
    ds = make_record(
        poles,
        shapes * amplitude[:, None],
        fs_hz=128.0,
        duration_s=600.0,
        seed=6,
        participation=one_force,
        noise_ratio=0.1,
    )
    modes = extract(ds, fmax_hz=50.0, algorithm="plscf", progress=False)
    assert modes.sizes["mode"] == 5
    assert np.all(np.abs(modes.frequency.values - poles.imag / (2 * np.pi)) < 3 * modes.frequency_se.values)
    assert np.all(np.abs(modes.damping_ratio.values - z) < 3 * modes.damping_ratio_se.values)
    assert np.all(np.diag(mac(modes.sensor_shape.values, shapes)) > 0.95)
    assert "pLSCF" in modes.attrs["producer"]


def test_the_algorithm_is_an_option_checked_before_the_record_is_read():
    with pytest.raises(SignalError, match="algorithm must be one of ssi, plscf"):
        extract("no-such-file.nc", algorithm="fdd")
    with pytest.raises(ValueError, match="algorithm must be one of"):
        Algorithm("fdd")


def test_both_algorithms_read_the_same_covariances():
    y = np.random.default_rng(0).standard_normal((4000, 3))
    R = block_covariances(y, 21).covariance()
    ssi, plscf = Algorithm("ssi").fit(R, 10, 12, 20.0), Algorithm("plscf", (0.0, 8.0)).fit(R, 10, 12, 20.0)
    assert ssi.n_channels == plscf.n_channels == 3
    assert plscf.orders.tolist() == [3, 6, 9, 12]
    assert ssi.orders.tolist() == [2, 4, 6, 8, 10, 12]


def test_the_command_line_and_the_loop_calibration_keep_the_algorithm(make_record, tmp_path):
    """``twin extract --algorithm plscf`` writes it in the settings, and the loop's calibration records are
    extracted with it (:func:`twin.loop.bootstrap.record_settings`)."""
    import json

    from twin.cli import main
    from twin.loop.bootstrap import record_settings
    from twin.modes import read_modes

    lam = 2 * np.pi * 3.0 * (-0.06 + 1j)
    ds = make_record([lam], np.array([[1.0, 0.5j, 0.8]]), fs_hz=20.0, duration_s=400.0, seed=1)
    ds.to_netcdf(tmp_path / "signals.nc")
    out = tmp_path / "modes.nc"
    assert main(["extract", str(tmp_path / "signals.nc"), "-o", str(out), "--fmax", "8", "--algorithm", "plscf"]) == 0
    modes = read_modes(out)
    assert json.loads(modes.attrs["settings"])["algorithm"] == "plscf"
    assert record_settings(modes)[2]["algorithm"] == "plscf"
    assert abs(float(modes.frequency[0]) - 3.0) < 3 * float(modes.frequency_se[0])
