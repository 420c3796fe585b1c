"""The numpy copy of the FMU's built-in excitation."""

import numpy as np
import pytest

from twin.fmu.excitation import (
    excitation_forces,
    gaussian_stream,
    sensor_noise,
    splitmix64,
    turbulence_force,
    unbalance_force,
)
from twin.fmu.statespace import full_state_space


def test_splitmix64_reference_values():
    # published first outputs of splitmix64 for seed 0 (Vigna)
    assert [hex(int(v)) for v in splitmix64(0, 3)] == ["0xe220a8397b1dcdaf", "0x6e789e6aa1b965f4", "0x6c45d188009454f"]


def test_gaussian_stream_is_standard_normal_and_reproducible():
    z = gaussian_stream(11, 400_000)
    assert abs(z.mean()) < 5 / np.sqrt(z.size)
    assert abs(z.std() - 1) < 5 / np.sqrt(2 * z.size)
    assert abs(np.mean(z**4) - 3) < 0.05  # Gaussian kurtosis
    np.testing.assert_array_equal(z[:7], gaussian_stream(11, 7))
    assert not np.allclose(z[:100], gaussian_stream(12, 100))


def test_turbulence_has_the_requested_spectral_density():
    h, asd = 1 / 256, 300.0
    f = turbulence_force(2**16, asd, 3, h)
    # one-sided PSD of white samples of std s at rate 1/h is 2 s^2 h
    np.testing.assert_allclose(2 * f.var(axis=0) * h, asd**2, rtol=0.02)


def test_unbalance_is_forward_rotating():
    omega = 14.0
    f = unbalance_force(np.array([0.0, np.pi / (2 * omega)]), 2.0, 0.0, omega)
    np.testing.assert_allclose(f, [[2 * omega**2, 0.0], [0.0, 2 * omega**2]], atol=1e-9)
    assert sensor_noise(4, 3, 1e-6, 1).shape == (4, 3)


def test_excitation_forces_put_each_force_at_its_node_and_nowhere_else(hydro_unit):
    ss = full_state_space(hydro_unit)
    h, n = 1 / 256, 16
    t = np.arange(n) * h
    turbulence = turbulence_force(n, 3000.0, 5, h)
    f = excitation_forces(ss, t, 8, 100.0, 28, turbulence, phase_rad=0.3)
    omega = ss.speed_rpm * 2 * np.pi / 60
    np.testing.assert_array_equal(
        f[:, [ss.port_index("8.x"), ss.port_index("8.y")]], unbalance_force(t, 100.0, 0.3, omega)
    )
    np.testing.assert_array_equal(f[:, [ss.port_index("28.x"), ss.port_index("28.y")]], turbulence)
    assert np.count_nonzero(f.any(axis=0)) == 4
    # one node for both: the forces add
    both = excitation_forces(ss, t, 28, 100.0, 28, turbulence)
    np.testing.assert_allclose(
        both[:, [ss.port_index("28.x"), ss.port_index("28.y")]], unbalance_force(t, 100.0, 0.0, omega) + turbulence
    )
    with pytest.raises(ValueError, match=r"turbulence must be 16 samples of x and y, shape \(16, 2\), got \(15, 2\)"):
        excitation_forces(ss, t, 8, 100.0, 28, turbulence[:15])
