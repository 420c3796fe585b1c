"""The FMU's built-in excitation, reproduced in numpy for the reference simulation.

* 1X unbalance at a node: ``F = m e Ω² [cos(Ω t + φ), sin(Ω t + φ)]`` (forward rotating).
* Turbulence on the runner: white force noise of one-sided amplitude spectral
  density ``a`` [N/√Hz] in x and y, i.e. samples of std ``a / sqrt(2 h)``.
* Sensor noise: white, std ``σ`` [m], added to each output sample.

Random numbers come from splitmix64 with Box-Muller, one stream per seed,
normals used in the order cos, sin, cos, sin, ... exactly as the C runtime.
"""

from __future__ import annotations

import numpy as np

from twin.fem.model import RPM_TO_RAD_S
from twin.fmu.statespace import StateSpace

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)


def splitmix64(seed: int, count: int) -> np.ndarray:
    """The first ``count`` outputs of splitmix64 started at ``seed``.

    Examples
    --------
    >>> hex(int(splitmix64(0, 1)[0]))  # the reference value of splitmix64
    '0xe220a8397b1dcdaf'
    """
    with np.errstate(over="ignore"):
        state = np.uint64(seed & 0xFFFFFFFFFFFFFFFF) + _GOLDEN * np.arange(1, count + 1, dtype=np.uint64)
        z = (state ^ (state >> np.uint64(30))) * _M1
        z = (z ^ (z >> np.uint64(27))) * _M2
        return z ^ (z >> np.uint64(31))


def gaussian_stream(seed: int, count: int) -> np.ndarray:
    """``count`` standard normal numbers of the runtime's generator for ``seed``.

    Examples
    --------
    >>> z = gaussian_stream(7, 100_000)
    >>> abs(float(z.mean())) < 0.01, abs(float(z.std()) - 1) < 0.01
    (True, True)
    """
    n_pairs = (count + 1) // 2
    raw = splitmix64(seed, 2 * n_pairs).reshape(n_pairs, 2)
    u1 = ((raw[:, 0] >> np.uint64(11)).astype(float) + 1.0) * 2.0**-53
    u2 = (raw[:, 1] >> np.uint64(11)).astype(float) * 2.0**-53
    r = np.sqrt(-2.0 * np.log(u1))
    pairs = np.column_stack([r * np.cos(2 * np.pi * u2), r * np.sin(2 * np.pi * u2)])
    return pairs.ravel()[:count]


def unbalance_force(t: np.ndarray, me_kgm: float, phase_rad: float, omega_rad_s: float) -> np.ndarray:
    """1X unbalance force [N], shape ``(len(t), 2)`` for x and y."""
    t = np.asarray(t, dtype=float)
    a = me_kgm * omega_rad_s**2
    return np.column_stack([a * np.cos(omega_rad_s * t + phase_rad), a * np.sin(omega_rad_s * t + phase_rad)])


def turbulence_force(n_samples: int, asd: float, seed: int, h: float) -> np.ndarray:
    """Turbulence force samples [N], shape ``(n_samples, 2)``; one sample per step boundary."""
    return asd / np.sqrt(2.0 * h) * gaussian_stream(seed, 2 * n_samples).reshape(n_samples, 2)


def excitation_forces(
    ss: StateSpace,
    t: np.ndarray,
    unbalance_node: int | str,
    me_kgm: float,
    turbulence_node: int | str,
    turbulence: np.ndarray,
    phase_rad: float = 0.0,
) -> np.ndarray:
    """The FMU's built-in excitation as the force input of the reference simulation, ``(len(t), ports)`` [N].

    The 1X unbalance (:func:`unbalance_force`, at the system's running speed) at ``unbalance_node`` and the
    turbulence samples ``turbulence`` ``(len(t), 2)`` [N] (e.g. :func:`turbulence_force`) at
    ``turbulence_node``, both in x and y; zero at every other port. The FMU takes them linear between
    samples: pass the array as ``foh`` to :func:`twin.fmu.statespace.simulate_reference`.

    Examples
    --------
    >>> from twin.fmu.statespace import full_state_space
    >>> ss = full_state_space(hydro_unit)
    >>> t = np.arange(4) / 256.0
    >>> f = excitation_forces(ss, t, 8, 100.0, 28, turbulence_force(4, 3000.0, 1, 1 / 256.0))
    >>> f.shape == (4, len(ss.ports)), int(np.count_nonzero(f.any(axis=0)))
    (True, 4)
    """
    t = np.asarray(t, dtype=float)
    turbulence = np.asarray(turbulence, dtype=float)
    if turbulence.shape != (len(t), 2):
        raise ValueError(f"turbulence must be {len(t)} samples of x and y, shape ({len(t)}, 2), got {turbulence.shape}")
    forces = np.zeros((len(t), len(ss.ports)))
    forces[:, ss.node_ports(unbalance_node)] = unbalance_force(t, me_kgm, phase_rad, ss.speed_rpm * RPM_TO_RAD_S)
    forces[:, ss.node_ports(turbulence_node)] += turbulence
    return forces


def sensor_noise(n_samples: int, n_channels: int, std: float, seed: int) -> np.ndarray:
    """Sensor noise [m], shape ``(n_samples, n_channels)``."""
    return std * gaussian_stream(seed, n_samples * n_channels).reshape(n_samples, n_channels)
