"""The numpy reference of the FMU's runs: the exact recursion of the state space with its excitation."""

import numpy as np

from twin.fem.model import RPM_TO_RAD_S
from twin.fmu import discretize, simulate_reference
from twin.fmu.excitation import excitation_forces, gaussian_stream, turbulence_force
from twin.fmu.steady import STEADY_STREAM, steady_start, steady_state

H = 1.0 / 256.0


def fmu_reference(ss, n, me=0.0, node=8, phase=0.0, asd=0.0, seed=1, inputs=None, steady=False, t0=0.0):
    """Exact recursion with the FMU's excitation: external inputs ZOH, unbalance and turbulence FOH; from
    rest, or (``steady``) from the FMU's steady start (twin.fmu.steady)."""
    t = t0 + np.arange(n) * H
    zoh = np.zeros((n, len(ss.ports)))
    turbulence = turbulence_force(n, asd, seed, H)
    foh = excitation_forces(ss, t, node, me, 28, turbulence, phase_rad=phase)
    for port, values in (inputs or {}).items():
        zoh[:, ss.port_index(port)] += values
    disc = discretize(ss, H)
    x0 = None
    if steady:
        omega = ss.speed_rpm * RPM_TO_RAD_S
        g = gaussian_stream((seed & (2**64 - 1)) ^ STEADY_STREAM, disc.phi.shape[0])
        x0 = steady_state(
            steady_start(disc, omega, ss.node_ports(28)),
            disc,
            t0_s=t0,
            omega_rad_s=omega,
            me_kgm=me,
            phase_rad=phase,
            unbalance_ports=ss.node_ports(node),
            turbulence_asd=asd,
            g=g,
            turbulence_ports=ss.node_ports(28) if asd > 0 else [],
            f0=turbulence[0],
        )
    return simulate_reference(disc, ss.C, zoh=zoh, foh=foh, x0=x0)
