"""The FMU's ``modelDescription.xml``, in FMI 2.0 and FMI 3.0, from one list of its variables.

:func:`variables` says what the FMU has (parameters of the built-in excitation, force inputs, the sensor
outputs, the modal states and their derivatives) with value references, units and start values; the
writers put that list in each standard's form. The value references are shared with the C runtime
(``twin/fmu/c/twin_core.c``).
"""

from __future__ import annotations

import datetime as _dt
from collections.abc import Sequence
from dataclasses import dataclass
from xml.etree import ElementTree as ET

import numpy as np

from twin import __version__
from twin.fem.excitation import machine_excitation
from twin.fmu import build

#: The FMU's units: name, SI base-unit exponents, display units (name, factor: shown = factor x value).
UNITS = (
    ("s", {"s": "1"}, ()),
    ("m", {"m": "1"}, (("um", 1e6), ("mm", 1e3))),
    ("m/s", {"m": "1", "s": "-1"}, (("mm/s", 1e3),)),
    ("N", {"kg": "1", "m": "1", "s": "-2"}, (("kN", 1e-3),)),
    ("kg.m", {"kg": "1", "m": "1"}, (("g.mm", 1e6),)),
    ("rad", {"rad": "1"}, (("deg", 180 / np.pi),)),
    ("N/sqrt(Hz)", {}, ()),
)
#: Value references of the parameters (shared with the runtime); inputs, outputs, states and their
#: derivatives count from VR_INPUT0, VR_OUTPUT0, VR_STATE0 (Re z_i at 2i, Im z_i at 2i + 1) and VR_DER0.
VR = {
    "unbalance_me": 1,
    "unbalance_phase": 2,
    "turbulence_asd": 3,
    "noise_std": 4,
    "unbalance_node": 5,
    "turbulence_seed": 6,
    "noise_seed": 7,
    "steady_start": 8,
}
VR_TIME, VR_INPUT0, VR_OUTPUT0, VR_STATE0, VR_DER0 = 0, 100, 1000, 100000, 200000
#: Length of the default experiment [s].
DEFAULT_STOP_S = 30.0
#: The FMI 3.0 log category of the runtime's messages (every one reports an error).
LOG_CATEGORY = "logStatusError"


@dataclass(frozen=True)
class Variable:
    """One variable of the FMU. ``kind`` is ``"real"``, ``"int"`` or ``"bool"``; ``derivative_of`` the value
    reference of the state whose derivative it is; ``attrs`` the unit, start, min, max as the XML has them."""

    name: str
    vr: int
    causality: str
    variability: str
    description: str
    kind: str = "real"
    initial: str | None = None
    derivative_of: int | None = None
    attrs: tuple[tuple[str, str], ...] = ()


def start_values(model) -> dict[str, float]:
    """Start values of the FMU's real parameters (modelDescription and runtime, where a reset returns them): the
    default experiment shows the machine running with its own unbalance and broad-band force
    (:func:`twin.fem.excitation.machine_excitation`).

    Examples
    --------
    >>> start_values(hydro_unit)
    {'unbalance_me': 100.0, 'unbalance_phase': 0.0, 'turbulence_asd': 3000.0, 'noise_std': 0.0}
    """
    ex = machine_excitation(model)
    return {
        "unbalance_me": ex.unbalance_me,
        "unbalance_phase": 0.0,
        "turbulence_asd": ex.broadband_asd,
        "noise_std": 0.0,
    }


def variables(model, ss, form, ports, unbalance_node: int, steady: bool, start: dict[str, float]) -> list[Variable]:
    """The FMU's variables, in the order of its modelDescription; ``start``: :func:`start_values`."""

    def real(name, vr, causality, variability, description, **attrs):
        return Variable(name, vr, causality, variability, description, attrs=tuple(attrs.items()))

    out = [
        real(
            "unbalance_me",
            VR["unbalance_me"],
            "parameter",
            "fixed",
            "unbalance mass times eccentricity (1X, forward)",
            start=repr(start["unbalance_me"]),
            unit="kg.m",
            min="0",
        ),
        real(
            "unbalance_phase",
            VR["unbalance_phase"],
            "parameter",
            "fixed",
            "phase of the unbalance at t = 0",
            start=repr(start["unbalance_phase"]),
            unit="rad",
            displayUnit="deg",
        ),
        real(
            "turbulence_asd",
            VR["turbulence_asd"],
            "parameter",
            "fixed",
            "amplitude spectral density of the white broad-band force (turbulence, process forces), x and y (one-sided)",
            start=repr(start["turbulence_asd"]),
            unit="N/sqrt(Hz)",
            min="0",
        ),
        real(
            "noise_std",
            VR["noise_std"],
            "parameter",
            "fixed",
            "standard deviation of the sensor noise",
            start=repr(start["noise_std"]),
            unit="m",
            displayUnit="um",
            min="0",
        ),
        Variable(
            "unbalance_node",
            VR["unbalance_node"],
            "parameter",
            "fixed",
            "node carrying the unbalance",
            "int",
            attrs=(("start", str(unbalance_node)), ("min", "0"), ("max", str(model.n_nodes - 1))),
        ),
        Variable(
            "turbulence_seed",
            VR["turbulence_seed"],
            "parameter",
            "fixed",
            "seed of the turbulence",
            "int",
            attrs=(("start", "1"),),
        ),
        Variable(
            "noise_seed",
            VR["noise_seed"],
            "parameter",
            "fixed",
            "seed of the sensor noise",
            "int",
            attrs=(("start", "2"),),
        ),
        Variable(
            "steady_start",
            VR["steady_start"],
            "parameter",
            "fixed",
            "start in the stationary response to the built-in excitation (else from rest)"
            + ("" if steady else "; this FMU was exported without it"),
            "bool",
            attrs=(("start", "true" if steady else "false"),),
        ),
    ]
    for j, port in enumerate(ports):
        out.append(
            real(
                port.name,
                VR_INPUT0 + j,
                "input",
                "continuous",
                f"external force at {port.port} (held over a step)",
                start="0",
                unit="N",
            )
        )
    for i, channel in enumerate(ss.outputs):
        sensor = next((s for s in model.sensors if s.name == channel), None)
        where = f" at {sensor.location} (node {sensor.node})" if sensor else ""
        out.append(
            Variable(
                channel,
                VR_OUTPUT0 + i,
                "output",
                "continuous",
                f"proximeter displacement {channel}{where}",
                initial="calculated",
                attrs=(("unit", "m"), ("displayUnit", "um")),
            )
        )
    n_states = 2 * form.n_modes
    for k in range(n_states):
        lam = form.poles[k // 2]
        what = (
            f"mode {k // 2 + 1} ({abs(lam.imag) / (2 * np.pi):.4g} Hz, damping ratio {-lam.real / abs(lam):.3g})"
            if lam.imag
            else f"real pole {k // 2 + 1} ({lam.real:.4g} 1/s)"
        )
        out.append(
            real(
                f"z[{k // 2 + 1}].{'im' if k % 2 else 're'}",
                VR_STATE0 + k,
                "local",
                "continuous",
                f"{'imaginary' if k % 2 else 'real'} part of the modal coordinate of {what}: the mode's "
                "displacement at the sensor it moves most",
                unit="m",
                displayUnit="um",
            )
        )
    for k in range(n_states):
        out.append(
            Variable(
                f"der(z[{k // 2 + 1}].{'im' if k % 2 else 're'})",
                VR_DER0 + k,
                "local",
                "continuous",
                "its time derivative",
                derivative_of=VR_STATE0 + k,
                attrs=(("unit", "m/s"),),
            )
        )
    return out


def _root(version, name, token_key, token, description) -> ET.Element:
    return ET.Element(
        "fmiModelDescription",
        fmiVersion=version,
        modelName=name,
        **{token_key: token},
        description=description,
        generationTool=f"twin {__version__}",
        generationDateAndTime=_dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
        variableNamingConvention="flat",
    )


def _units(root: ET.Element) -> None:
    units = ET.SubElement(root, "UnitDefinitions")
    for unit_name, base, display in UNITS:
        unit = ET.SubElement(units, "Unit", name=unit_name)
        if base:  # N/sqrt(Hz) has a half power of the second, which FMI's integer exponents cannot say
            ET.SubElement(unit, "BaseUnit", **base)
        for shown, factor in display:
            ET.SubElement(unit, "DisplayUnit", name=shown, factor=repr(factor))


def _dependencies(vs: Sequence[Variable], key) -> tuple[list, dict, list]:
    """Outputs, derivatives (with the keys of what each depends on) and initial unknowns, as ``key``s."""
    states = [key(v) for v in vs if v.vr >= VR_STATE0 and v.derivative_of is None]
    inputs = [key(v) for v in vs if v.causality == "input"]
    by_vr = {v.vr: v for v in vs}
    outputs = [key(v) for v in vs if v.causality == "output"]
    derivatives = {}
    for v in vs:
        if v.derivative_of is not None:
            first = v.derivative_of - (v.derivative_of - VR_STATE0) % 2  # the mode's real part
            derivatives[key(v)] = [*inputs, key(by_vr[first]), key(by_vr[first + 1])]
    return outputs, derivatives, states


def fmi2_description(
    model,
    ss,
    vs: Sequence[Variable],
    *,
    guid: str,
    identifier: str,
    name: str,
    description: str,
    step_s: float,
    kinds: Sequence[str],
) -> bytes:
    """``modelDescription.xml`` in FMI 2.0 (``kinds``: ``"cs"`` and/or ``"me"``)."""
    root = _root("2.0", name, "guid", guid, description)
    root.set("numberOfEventIndicators", "0")
    common = {
        "modelIdentifier": identifier,
        "canBeInstantiatedOnlyOncePerProcess": "false",
        "canNotUseMemoryManagementFunctions": "true",
        "canGetAndSetFMUstate": "true",
        "canSerializeFMUstate": "true",
        "providesDirectionalDerivative": "true",
    }
    interfaces = []
    if "me" in kinds:
        interfaces.append(ET.SubElement(root, "ModelExchange", completedIntegratorStepNotNeeded="true", **common))
    if "cs" in kinds:
        interfaces.append(
            ET.SubElement(
                root,
                "CoSimulation",
                canHandleVariableCommunicationStepSize="true",
                canInterpolateInputs="false",
                **common,
            )
        )
    for element in interfaces:
        ET.SubElement(ET.SubElement(element, "SourceFiles"), "File", name=f"{build.MODEL_IDENTIFIER}.c")
    _units(root)
    ET.SubElement(root, "DefaultExperiment", startTime="0", stopTime=repr(DEFAULT_STOP_S), stepSize=repr(step_s))
    mv = ET.SubElement(root, "ModelVariables")
    index = {v.vr: i + 1 for i, v in enumerate(vs)}  # FMI 2.0 refers to variables by 1-based index
    for v in vs:
        sv = ET.SubElement(
            mv,
            "ScalarVariable",
            name=v.name,
            valueReference=str(v.vr),
            causality=v.causality,
            variability=v.variability,
            description=v.description,
        )
        if v.initial:
            sv.set("initial", v.initial)
        attrs = dict(v.attrs)
        if v.derivative_of is not None:
            attrs["derivative"] = str(index[v.derivative_of])
        ET.SubElement(sv, {"real": "Real", "int": "Integer", "bool": "Boolean"}[v.kind], **attrs)
    outputs, derivatives, states = _dependencies(vs, lambda v: str(index[v.vr]))
    structure = ET.SubElement(root, "ModelStructure")
    out_el, der_el, init_el = (ET.SubElement(structure, tag) for tag in ("Outputs", "Derivatives", "InitialUnknowns"))
    for i in outputs:
        ET.SubElement(out_el, "Unknown", index=i, dependencies=" ".join(states))
    for i, deps in derivatives.items():
        ET.SubElement(der_el, "Unknown", index=i, dependencies=" ".join(deps))
    for i in sorted([*outputs, *states, *derivatives], key=int):
        ET.SubElement(init_el, "Unknown", index=i)
    ET.indent(root)
    return ET.tostring(root, encoding="UTF-8", xml_declaration=True)


def fmi3_description(
    model,
    ss,
    vs: Sequence[Variable],
    *,
    guid: str,
    identifier: str,
    name: str,
    description: str,
    step_s: float,
    kinds: Sequence[str],
) -> bytes:
    """``modelDescription.xml`` in FMI 3.0 (``kinds``: ``"cs"`` and/or ``"me"``), with the independent
    variable ``time``."""
    root = _root("3.0", name, "instantiationToken", guid, description)
    common = {
        "modelIdentifier": identifier,
        "canBeInstantiatedOnlyOncePerProcess": "false",
        "canGetAndSetFMUState": "true",
        "canSerializeFMUState": "true",
        "providesDirectionalDerivatives": "true",
    }
    if "me" in kinds:
        ET.SubElement(root, "ModelExchange", needsCompletedIntegratorStep="false", **common)
    if "cs" in kinds:
        ET.SubElement(
            root, "CoSimulation", canHandleVariableCommunicationStepSize="true", hasEventMode="false", **common
        )
    _units(root)
    categories = ET.SubElement(root, "LogCategories")
    ET.SubElement(categories, "Category", name=LOG_CATEGORY, description="why a call failed")
    ET.SubElement(root, "DefaultExperiment", startTime="0", stopTime=repr(DEFAULT_STOP_S), stepSize=repr(step_s))
    mv = ET.SubElement(root, "ModelVariables")
    ET.SubElement(
        mv,
        "Float64",
        name="time",
        valueReference=str(VR_TIME),
        causality="independent",
        variability="continuous",
        description="simulation time",
        unit="s",
    )
    for v in vs:
        attrs = {
            "name": v.name,
            "valueReference": str(v.vr),
            "causality": v.causality,
            "variability": v.variability,
            "description": v.description,
            **dict(v.attrs),
        }
        if v.initial:
            attrs["initial"] = v.initial
        if v.derivative_of is not None:
            attrs["derivative"] = str(v.derivative_of)  # FMI 3.0 refers to variables by value reference
        ET.SubElement(mv, {"real": "Float64", "int": "Int32", "bool": "Boolean"}[v.kind], **attrs)
    outputs, derivatives, states = _dependencies(vs, lambda v: str(v.vr))
    structure = ET.SubElement(root, "ModelStructure")
    for vr in outputs:
        ET.SubElement(structure, "Output", valueReference=vr, dependencies=" ".join(states))
    for vr, deps in derivatives.items():
        ET.SubElement(structure, "ContinuousStateDerivative", valueReference=vr, dependencies=" ".join(deps))
    for vr in [*outputs, *states, *derivatives]:
        ET.SubElement(structure, "InitialUnknown", valueReference=vr)
    ET.indent(root)
    return ET.tostring(root, encoding="UTF-8", xml_declaration=True)


def fmi3_build_description(identifier: str) -> bytes:
    """``sources/buildDescription.xml`` of an FMI 3.0 FMU: the one translation unit, built for FMI 3.0."""
    root = ET.Element("fmiBuildDescription", fmiVersion="3.0")
    config = ET.SubElement(root, "BuildConfiguration", modelIdentifier=identifier)
    files = ET.SubElement(config, "SourceFileSet", language="C99")
    ET.SubElement(files, "SourceFile", name=f"{build.MODEL_IDENTIFIER}.c")
    ET.SubElement(files, "PreprocessorDefinition", name="TWIN_FMI", value="3")
    ET.SubElement(config, "Library", name="m")
    ET.indent(root)
    return ET.tostring(root, encoding="UTF-8", xml_declaration=True)
