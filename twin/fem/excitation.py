"""What drives a machine in operation: its 1X unbalance and its broad-band process forces.

A machine's model file declares them in its ``[excitation]`` table; what it
leaves out is derived from the machine itself:

``unbalance_at``
    Where the residual unbalance sits: a disk's name, a region's name (its
    first node) or a node number. Default: the heaviest disk (node 0 without
    disks).
``unbalance_me`` [kg m]
    Its size. Default: the permissible residual unbalance of the balance
    quality grade ``balance_grade`` for the whole rotor's mass ``m`` at its
    running speed ``Ω`` (ISO 21940-11): ``m e = G m / Ω``.
``balance_grade`` [mm/s]
    ``G``, default 2.5 (G2.5: turbine and generator rotors, machine tools).
``broadband_at``
    Where broad-band process forces act (turbulence, flow, rubbing): a disk's
    or region's name or a node number. Default: the ``immersed`` region where
    the model has one, else the heaviest disk.
``broadband_asd`` [N/√Hz]
    Their one-sided amplitude spectral density, white, in x and y. Default:
    :data:`BROADBAND_PER_WEIGHT` of the rotor's weight per √Hz.
``max_response`` [m]
    The largest peak-to-peak shaft displacement at a sensor that a simulation
    may reach (a bearing clearance, say). Default: :data:`ABSURD_FACTOR` times
    the ISO 20816-1 / ISO 7919-1 zone C/D boundary for shaft vibration,
    ``13 200 / √n`` µm peak to peak at ``n`` rpm; a simulation above that
    boundary is warned about, above ``max_response`` refused
    (:func:`twin.fmu.simulate.simulate`).

Every stage that drives the model reads the one resolved set,
:func:`machine_excitation`: the simulation, a campaign, the loop's
calibration and the FMU's start values.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from twin.errors import ModelError

#: ISO 21940-11's balance quality grade [mm/s] of turbine and generator rotors, the default of a rotor's unbalance.
BALANCE_GRADE_MM_S = 2.5
#: The default broad-band process force [N/√Hz] per newton of the rotor's weight: the hydro unit's runner
#: turbulence (3000 N/√Hz) against its 888 t rotor is 3.4e-4.
BROADBAND_PER_WEIGHT = 3e-4
#: ISO 20816-1 / ISO 7919-1's zone C/D boundary for relative shaft displacement: ``13 200 / √n`` µm peak to peak at
#: ``n`` rpm, where vibration starts to damage a machine.
ZONE_CD_UM_SQRT_RPM = 13200.0
#: A response this many times the zone C/D boundary is refused unless the model file states a larger bound: far
#: past the bearings' clearance, where a linear model no longer holds.
ABSURD_FACTOR = 10.0
GRAVITY = 9.80665


@dataclass(frozen=True)
class Excitation:
    """The ``[excitation]`` table as a model file declares it: nodes resolved, ``None`` where it says nothing."""

    unbalance_node: int | None = None
    unbalance_me: float | None = None
    balance_grade: float = BALANCE_GRADE_MM_S
    broadband_node: int | None = None
    broadband_asd: float | None = None
    max_response: float | None = None


@dataclass(frozen=True)
class MachineExcitation:
    """The excitation a machine is driven with, every value set (SI), and where each came from.

    Attributes
    ----------
    unbalance_node : int
    unbalance_me : float
        Residual unbalance [kg m] (1X, forward rotating).
    broadband_node : int
    broadband_asd : float
        One-sided ASD of the broad-band force in x and y [N/√Hz].
    warn_response, max_response : float
        Peak-to-peak shaft displacement [m] above which a simulation warns, and is refused.
    sources : dict
        How each value was set: ``"declared"`` or the rule that derived it.
    """

    unbalance_node: int
    unbalance_me: float
    broadband_node: int
    broadband_asd: float
    warn_response: float
    max_response: float
    sources: dict[str, str] = field(default_factory=dict)

    def describe(self) -> str:
        """One line per value, with its source."""
        return "\n".join(
            [
                f"1X unbalance {self.unbalance_me:.4g} kg m at node {self.unbalance_node} ({self.sources['unbalance']})",
                f"broad-band force {self.broadband_asd:.4g} N/sqrt(Hz) in x and y at node {self.broadband_node} "
                f"({self.sources['broadband']})",
                f"largest simulated shaft vibration {1e6 * self.max_response:.4g} um peak to peak "
                f"({self.sources['max_response']}; warned above {1e6 * self.warn_response:.4g} um)",
            ]
        )


def rotor_mass(model) -> float:
    """The rotor's whole mass [kg]: shaft and disks (the mass matrix's rigid translation in x)."""
    m = model.matrices()["M"]
    x = np.zeros(m.shape[0])
    x[0::4] = 1.0
    return float(x @ m @ x)


def heaviest_disk_node(model) -> int:
    """The node of the heaviest disk (node 0 for a rotor without disks)."""
    return max(model.disks, key=lambda d: d.m).node if model.disks else 0


def machine_excitation(model) -> MachineExcitation:
    """The excitation of ``model``: its declared ``[excitation]`` with the rest derived from the machine.

    Examples
    --------
    >>> ex = machine_excitation(hydro_unit)  # declared in its model file
    >>> ex.unbalance_me, ex.unbalance_node, ex.broadband_asd, ex.broadband_node
    (100.0, 8, 3000.0, 28)
    >>> from twin import load_model, shipped_model
    >>> rig = machine_excitation(load_model(shipped_model("ross_reference")))  # nothing declared: derived
    >>> round(rig.unbalance_me * 1e3, 2), rig.unbalance_node, round(1e6 * rig.warn_response)  # g m, node, um
    (13.47, 2, 1140)
    """
    declared: Excitation = getattr(model, "excitation", None) or Excitation()
    sources: dict[str, str] = {}
    mass = rotor_mass(model)
    omega = model.speed_rpm * np.pi / 30.0
    node = declared.unbalance_node if declared.unbalance_node is not None else heaviest_disk_node(model)
    if declared.unbalance_me is not None:
        me, sources["unbalance"] = declared.unbalance_me, "declared"
    elif omega > 0:
        me = declared.balance_grade * 1e-3 * mass / omega
        sources["unbalance"] = (
            f"balance grade G{declared.balance_grade:g} for the {mass:.4g} kg rotor at {model.speed_rpm:g} rpm"
        )
    else:
        me, sources["unbalance"] = 0.0, "none at standstill"
    if declared.broadband_node is not None:
        at = declared.broadband_node
    elif "immersed" in model.regions:
        at = model.regions["immersed"][0]
    else:
        at = heaviest_disk_node(model)
    if declared.broadband_asd is not None:
        asd, sources["broadband"] = declared.broadband_asd, "declared"
    else:
        asd = BROADBAND_PER_WEIGHT * mass * GRAVITY
        sources["broadband"] = f"{BROADBAND_PER_WEIGHT:g} of the rotor's weight per sqrt(Hz)"
    if model.speed_rpm > 0:
        warn = ZONE_CD_UM_SQRT_RPM / np.sqrt(model.speed_rpm) * 1e-6
        zone = f"ISO 20816-1 zone C/D at {model.speed_rpm:g} rpm"
    else:
        warn, zone = np.inf, "no zone at standstill"
    if declared.max_response is not None:
        limit, sources["max_response"] = declared.max_response, "declared"
    elif np.isfinite(warn):
        limit = ABSURD_FACTOR * warn
        sources["max_response"] = f"{ABSURD_FACTOR:g} times the {zone}"
    else:
        limit, sources["max_response"] = np.inf, zone
    if not (np.isfinite(me) and me >= 0 and np.isfinite(asd) and asd >= 0):
        raise ModelError(f"model '{model.name}': the excitation must be finite and not negative")
    return MachineExcitation(int(node), float(me), int(at), float(asd), float(min(warn, limit)), float(limit), sources)
