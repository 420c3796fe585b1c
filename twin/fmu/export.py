"""Export a rotor model as an FMI 2.0 co-simulation FMU.

The FMU holds

* ``modelDescription.xml``: inputs (forces at named nodes), outputs (the
  sensor channels), parameters of the built-in excitation;
* ``resources/twin_lti.bin``: the exact step matrices of the linear system
  (full FEM or truncated modal basis) for the nominal communication step, the
  port map, the GUID, the real parameters' start values and the steady start's
  matrices (:mod:`twin.fmu.steady`);
* ``binaries/<platform>/<modelIdentifier>.<so|dylib|dll>``: the generic runtime,
  compiled once per platform (:mod:`twin.fmu.build`);
* ``sources/``: the runtime's C source and the FMI headers, so the FMU can be
  rebuilt on another platform (with ``-DFMI2_FUNCTION_PREFIX=<modelIdentifier>_``
  for static linking beside other FMUs);
* ``documentation/index.html``: what the FMU is (model, truth, variables and units).

The modelName is the model's (and its truth's) name, the modelIdentifier that
name as a C identifier. The FMU's state can be got, set and serialized.

The file is written to a temporary name and renamed when complete, so a
failed export never leaves half an FMU behind.
"""

from __future__ import annotations

import datetime as _dt
import hashlib
import logging
import re
import struct
import uuid
import zipfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from xml.etree import ElementTree as ET

import numpy as np

from twin import __version__
from twin.defaults import DEFAULT_TURBULENCE_ASD, DEFAULT_UNBALANCE_ME
from twin.errors import ModelError, TwinError
from twin.fem.model import RPM_TO_RAD_S, RotorModel
from twin.fmu import build
from twin.fmu.documentation import documentation_html
from twin.fmu.modal import modal_form
from twin.fmu.statespace import StateSpace, check_stable, discretize
from twin.fmu.steady import steady_start as stationary_start
from twin.fmu.truth import model_state_space
from twin.netcdf import atomic_output

log = logging.getLogger(__name__)

#: The FMU's units: name, SI base-unit exponents, display units (name, factor: shown = factor x value).
UNITS = (("m", {"m": "1"}, (("um", 1e6), ("mm", 1e3))), ("m/s", {"m": "1", "s": "-1"}, (("mm/s", 1e3),)), ("N", {"kg": "1", "m": "1", "s": "-2"}, (("kN", 1e-3),)),
         ("kg.m", {"kg": "1", "m": "1"}, (("g.mm", 1e6),)), ("rad", {"rad": "1"}, (("deg", 180 / np.pi),)),
         ("N/sqrt(Hz)", {}, ()))  # fmt: skip

# value references, shared with twin_lti.c
VR = {"unbalance_me": 1, "unbalance_phase": 2, "turbulence_asd": 3, "noise_std": 4,
      "unbalance_node": 5, "turbulence_seed": 6, "noise_seed": 7, "steady_start": 8}  # fmt: skip
VR_INPUT0, VR_OUTPUT0 = 100, 1000
#: Start values of the real parameters (modelDescription and runtime, where fmi2Reset returns them): the
#: default experiment shows the unit running with twin's default unbalance and turbulence.
START = {"unbalance_me": DEFAULT_UNBALANCE_ME, "unbalance_phase": 0.0, "turbulence_asd": DEFAULT_TURBULENCE_ASD,
         "noise_std": 0.0}  # fmt: skip
#: The resource file's format, shared with twin_lti.c (MAGIC).
RESOURCE_MAGIC = b"TWINLTI5"
#: The FMI interfaces an export declares, by its ``kind``.
KINDS = {"both": ("cs", "me"), "cs": ("cs",), "me": ("me",)}
#: First value references of the continuous states (Re z_i at 2i, Im z_i at 2i + 1) and of their derivatives.
VR_STATE0, VR_DER0 = 100000, 200000
#: Length of the default experiment [s].
DEFAULT_STOP_S = 30.0


@dataclass(frozen=True)
class Port:
    """An FMU force input: variable ``name`` drives state-space port ``port`` (``"<node>.<x|y>"``)."""

    name: str
    port: str


def resolve_inputs(model: RotorModel, inputs: Sequence[str] | None) -> list[Port]:
    """FMU force inputs from names like ``"runner.x"`` (a disk, bearing or sensor name) or ``"12.y"`` (a node).

    By default every disk gets an x and a y force input.

    Examples
    --------
    >>> from twin import load_model, shipped_model
    >>> [p.name for p in resolve_inputs(load_model(shipped_model("hydro_unit")), ["runner.x", "12.y"])]
    ['F_runner_x', 'F_12_y']
    """
    if inputs is None:
        inputs = [f"{d.name}.{axis}" for d in model.disks for axis in ("x", "y")]
    named = {d.name: d.node for d in model.disks}
    named.update({b.name: b.node for b in model.bearings})
    named.update({s.name.rsplit("_", 1)[0]: s.node for s in model.sensors})
    out = []
    for item in inputs:
        where, _, axis = item.rpartition(".")
        if axis not in ("x", "y") or not where:
            raise ModelError(f"force input '{item}' must look like '<node or name>.x' or '<node or name>.y'")
        if where.isdigit():
            node = int(where)
            if node >= model.n_nodes:
                raise ModelError(f"force input '{item}': node {node} does not exist (nodes 0..{model.n_nodes - 1})")
        elif where in named:
            node = named[where]
        else:
            raise ModelError(f"force input '{item}': no node, disk, bearing or sensor called '{where}' "
                             f"(names: {', '.join(sorted(named))})")  # fmt: skip
        out.append(Port(f"F_{where}_{axis}", f"{node}.{axis}"))
    if len({p.name for p in out}) != len(out):
        raise ModelError(f"force inputs are given twice: {list(inputs)}")
    return out


def default_unbalance_node(model: RotorModel) -> int:
    """The generator region's node if declared, else the heaviest disk's node."""
    if "generator" in model.regions:
        return model.regions["generator"][0]
    if model.disks:
        return max(model.disks, key=lambda d: d.m).node
    return 0


def default_turbulence_node(model: RotorModel) -> int | None:
    """The immersed (runner) region's node, where turbulence acts; None without one."""
    return model.regions["immersed"][0] if "immersed" in model.regions else None


def export_fmu(
    model: RotorModel,
    path: str | Path,
    *,
    step_s: float = 1.0 / 256.0,
    basis: str = "full",
    fmax_hz: float | None = None,
    inputs: Sequence[str] | None = None,
    state_space: StateSpace | None = None,
    unbalance_node: int | None = None,
    turbulence_node: int | None = None,
    description: str | None = None,
    name: str | None = None,
    steady_start: bool = True,
    kind: str = "both",
) -> Path:
    """Export the model as an FMI 2.0 co-simulation FMU.

    Parameters
    ----------
    model : RotorModel
        Supplies names, sensors and regions, and the state space unless given.
    path : path
        The ``.fmu`` file to write.
    step_s : float
        Nominal communication step [s]; the FMU integrates exactly over it.
    basis : {"full", "modal"}
        Full FEM (``2 n_dof`` states) or the modes up to ``fmax_hz``.
    fmax_hz : float, optional
        Highest damped frequency kept by the modal basis [Hz].
    inputs : list of str, optional
        Force inputs, e.g. ``["runner.x", "runner.y"]`` (default: x and y at every disk).
    state_space : StateSpace, optional
        Use this system (e.g. a truth model) instead of building one from ``model``.
    unbalance_node, turbulence_node : int, optional
        Default node of the 1X unbalance (a parameter of the FMU) and node of the
        turbulence force (fixed); defaults: generator region, immersed region.
    description : str, optional
        The modelDescription's description (default: model, speed, basis, states).
    name : str, optional
        The FMU's modelName (default: the model's name); its modelIdentifier, the name of its
        binaries, is this name as a C identifier (:func:`model_identifier`).
    steady_start : bool
        Ship the matrices of the steady start (:mod:`twin.fmu.steady`; a discrete Lyapunov solution,
        under a second for the full hydro unit) and start steady by default; False: the FMU starts from
        rest only (its ``steady_start`` parameter is false and cannot be set).
    kind : {"both", "cs", "me"}
        The FMI interfaces the FMU declares: co-simulation (the FMU steps itself, exactly), model
        exchange (the host's solver integrates its modal states), or both (one binary serves both).

    Returns
    -------
    Path
        The FMU written.

    Examples
    --------
    >>> from twin.fmu import export_fmu
    >>> import tempfile, pathlib
    >>> from twin import load_model, shipped_model
    >>> out = pathlib.Path(tempfile.mkdtemp()) / "unit.fmu"
    >>> export_fmu(load_model(shipped_model("hydro_unit")), out, basis="modal", fmax_hz=50.0).name
    'unit.fmu'
    """
    path = Path(path)
    if kind not in KINDS:
        raise TwinError(f"kind must be one of {', '.join(KINDS)} (FMI interfaces), got {kind!r}")
    if not path.parent.is_dir():
        raise TwinError(f"cannot write {path}: folder {path.parent} does not exist")
    if state_space is None:
        state_space = model_state_space(model, basis, fmax_hz)
    ports = resolve_inputs(model, inputs)
    unbalance_node = default_unbalance_node(model) if unbalance_node is None else int(unbalance_node)
    turbulence_node = default_turbulence_node(model) if turbulence_node is None else int(turbulence_node)
    for what, node in (("unbalance_node", unbalance_node), ("turbulence_node", turbulence_node)):
        if node is not None and not 0 <= node < model.n_nodes:
            raise ModelError(f"{what} {node} does not exist (nodes 0..{model.n_nodes - 1})")
    check_stable(state_space, model.name)

    form = modal_form(state_space)
    turb = [-1, -1] if turbulence_node is None else state_space.node_ports(turbulence_node)
    in_ports = [state_space.port_index(p.port) for p in ports]
    omega = state_space.speed_rpm * RPM_TO_RAD_S
    steady = None
    if steady_start:
        steady = stationary_start(discretize(state_space, step_s), omega, [p for p in turb if p >= 0])
    body = b"".join([
        np.asarray(in_ports, dtype="<i4").tobytes(),
        *(np.ascontiguousarray(a, dtype="<c16").tobytes() for a in (form.poles, form.wb.T, form.cv)),
        *([] if steady is None else [np.ascontiguousarray(form.left @ steady.factor, dtype="<c16").tobytes()]),
    ])  # fmt: skip
    name = model.name if name is None else str(name)
    identifier = model_identifier(name)
    guid = "{" + str(uuid.UUID(hashlib.sha256(body + name.encode()).hexdigest()[:32])) + "}"
    n, p = state_space.B.shape
    dims = (form.n_modes, n, p, state_space.C.shape[0], len(ports), *turb, unbalance_node, int(steady is not None))
    starts = [START[k] for k in ("unbalance_me", "unbalance_phase", "turbulence_asd", "noise_std")]
    head = RESOURCE_MAGIC + struct.pack("<9i6d", *dims, step_s, omega, *starts)
    resource = head + guid.encode().ljust(64, b"\0") + body

    xml = _model_description(model, state_space, form, ports, guid, step_s, unbalance_node, description, name,
                             identifier, steady is not None, KINDS[kind])  # fmt: skip
    library = build.compiled_runtime()
    plat = build.platform_folder()
    headers = build.fmi2_headers()
    with atomic_output(path, ".fmu.part") as tmp, zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("modelDescription.xml", xml)
        z.writestr("documentation/index.html", documentation_html(xml, state_space.attrs, step_s))
        z.writestr("resources/twin_lti.bin", resource)
        z.write(library, f"binaries/{plat}/{identifier}{build.shared_library_suffix()}")
        z.write(build.runtime_source(), f"sources/{build.MODEL_IDENTIFIER}.c")
        for name, text in headers.items():
            z.writestr(f"sources/{name}", text)
    log.info("wrote %s: %d states, %d inputs, %d outputs, step %g s", path, n, len(ports), len(state_space.outputs), step_s)
    return path


def _var(parent, name, vr, causality, variability, description, kind="Real", initial=None, **attrs):
    sv = ET.SubElement(parent, "ScalarVariable", name=name, valueReference=str(vr), causality=causality,
                       variability=variability, description=description)  # fmt: skip
    if initial:
        sv.set("initial", initial)
    ET.SubElement(sv, kind, **{k: str(v) for k, v in attrs.items()})


def model_identifier(name: str) -> str:
    """An FMU's modelIdentifier for a model name: a C identifier of at most 64 characters (the name of
    its binaries and, compiled from source, the prefix of its functions).

    Examples
    --------
    >>> model_identifier("hydro_unit truth: magnetic_pull, bearing_change:UGB")
    'hydro_unit_truth_magnetic_pull_bearing_change_UGB'
    >>> model_identifier("2-stage pump")
    'm_2_stage_pump'
    """
    ident = re.sub(r"_+", "_", re.sub(r"[^0-9A-Za-z_]", "_", name)).strip("_") or "model"
    return ("m_" + ident if ident[0].isdigit() else ident)[:64]


def _model_description(model, ss, form, ports, guid, step_s, unbalance_node, description, name, identifier,
                       steady: bool, kinds: tuple[str, ...]) -> bytes:  # fmt: skip
    root = ET.Element("fmiModelDescription", fmiVersion="2.0", modelName=name, guid=guid,
                      description=description or f"{model.name} at {ss.speed_rpm:g} rpm, {ss.basis} basis, "
                                                 f"{ss.n_states} states (twin linear rotor)",
                      generationTool=f"twin {__version__}",
                      generationDateAndTime=_dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
                      variableNamingConvention="flat", numberOfEventIndicators="0")  # fmt: skip
    common = {"modelIdentifier": identifier, "canBeInstantiatedOnlyOncePerProcess": "false",
              "canNotUseMemoryManagementFunctions": "true", "canGetAndSetFMUstate": "true",
              "canSerializeFMUstate": "true", "providesDirectionalDerivative": "true"}  # fmt: skip
    interfaces = []
    if "me" in kinds:
        interfaces.append(ET.SubElement(root, "ModelExchange", completedIntegratorStepNotNeeded="true", **common))
    if "cs" in kinds:
        interfaces.append(ET.SubElement(root, "CoSimulation", canHandleVariableCommunicationStepSize="true",
                                        canInterpolateInputs="false", **common))  # fmt: skip
    for cs in interfaces:
        files = ET.SubElement(cs, "SourceFiles")
        ET.SubElement(files, "File", name=f"{build.MODEL_IDENTIFIER}.c")
    units = ET.SubElement(root, "UnitDefinitions")
    for unit_name, base, display in UNITS:
        unit = ET.SubElement(units, "Unit", name=unit_name)
        if base:  # N/sqrt(Hz) has a half power of the second, which FMI 2.0's integer exponents cannot say
            ET.SubElement(unit, "BaseUnit", **base)
        for shown, factor in display:
            ET.SubElement(unit, "DisplayUnit", name=shown, factor=repr(factor))
    ET.SubElement(root, "DefaultExperiment", startTime="0", stopTime=repr(DEFAULT_STOP_S), stepSize=repr(step_s))
    mv = ET.SubElement(root, "ModelVariables")
    _var(mv, "unbalance_me", VR["unbalance_me"], "parameter", "fixed",
         "unbalance mass times eccentricity (1X, forward)", start=repr(START["unbalance_me"]), unit="kg.m",
         min="0")
    _var(mv, "unbalance_phase", VR["unbalance_phase"], "parameter", "fixed", "phase of the unbalance at t = 0",
         start=repr(START["unbalance_phase"]), unit="rad", displayUnit="deg")
    _var(mv, "turbulence_asd", VR["turbulence_asd"], "parameter", "fixed",
         "amplitude spectral density of the white turbulence force on the runner, x and y (one-sided)",
         start=repr(START["turbulence_asd"]), unit="N/sqrt(Hz)", min="0")
    _var(mv, "noise_std", VR["noise_std"], "parameter", "fixed", "standard deviation of the sensor noise",
         start=repr(START["noise_std"]), unit="m", displayUnit="um", min="0")
    _var(mv, "unbalance_node", VR["unbalance_node"], "parameter", "fixed", "node carrying the unbalance",
         kind="Integer", start=str(unbalance_node), min="0", max=str(model.n_nodes - 1))
    _var(mv, "turbulence_seed", VR["turbulence_seed"], "parameter", "fixed", "seed of the turbulence",
         kind="Integer", start="1")
    _var(mv, "noise_seed", VR["noise_seed"], "parameter", "fixed", "seed of the sensor noise",
         kind="Integer", start="2")
    _var(mv, "steady_start", VR["steady_start"], "parameter", "fixed",
         "start in the stationary response to the built-in excitation (else from rest)"
         + ("" if steady else "; this FMU was exported without it"), kind="Boolean",
         start="true" if steady else "false")  # fmt: skip
    for j, port in enumerate(ports):
        _var(mv, port.name, VR_INPUT0 + j, "input", "continuous", f"external force at {port.port} (held over a step)",
             start="0", unit="N")  # fmt: skip
    first_output = len(VR) + len(ports) + 1  # 1-based index in ModelVariables: parameters, inputs, outputs
    for i, channel in enumerate(ss.outputs):
        sensor = next((s for s in model.sensors if s.name == channel), None)
        where = f" at {sensor.location} (node {sensor.node})" if sensor else ""
        _var(mv, channel, VR_OUTPUT0 + i, "output", "continuous", f"proximeter displacement {channel}{where}",
             initial="calculated", unit="m", displayUnit="um")  # fmt: skip
    first_state = first_output + len(ss.outputs)
    n_states = 2 * form.n_modes
    for k in range(n_states):
        lam = form.poles[k // 2]
        what = (f"mode {k // 2 + 1} ({abs(lam.imag) / (2 * np.pi):.4g} Hz, damping ratio {-lam.real / abs(lam):.3g})"
                if lam.imag else f"real pole {k // 2 + 1} ({lam.real:.4g} 1/s)")  # fmt: skip
        _var(mv, f"z[{k // 2 + 1}].{'im' if k % 2 else 're'}", VR_STATE0 + k, "local", "continuous",
             f"{'imaginary' if k % 2 else 'real'} part of the modal coordinate of {what}: the mode's displacement "
             "at the sensor it moves most", unit="m", displayUnit="um")  # fmt: skip
    for k in range(n_states):
        _var(mv, f"der(z[{k // 2 + 1}].{'im' if k % 2 else 're'})", VR_DER0 + k, "local", "continuous",
             "its time derivative", derivative=str(first_state + k), unit="m/s")  # fmt: skip
    structure = ET.SubElement(root, "ModelStructure")
    outputs = ET.SubElement(structure, "Outputs")
    derivatives = ET.SubElement(structure, "Derivatives")
    initial = ET.SubElement(structure, "InitialUnknowns")
    states = " ".join(str(first_state + k) for k in range(n_states))
    inputs = [str(len(VR) + 1 + j) for j in range(len(ports))]
    for i in range(len(ss.outputs)):
        ET.SubElement(outputs, "Unknown", index=str(first_output + i), dependencies=states)
    for k in range(n_states):
        pair = f"{first_state + k - k % 2} {first_state + k - k % 2 + 1}"
        ET.SubElement(derivatives, "Unknown", index=str(first_state + n_states + k),
                      dependencies=" ".join([*inputs, pair]) if inputs else pair)  # fmt: skip
    for index in [first_output + i for i in range(len(ss.outputs))] + [first_state + k for k in range(2 * n_states)]:
        ET.SubElement(initial, "Unknown", index=str(index))
    ET.indent(root)
    return ET.tostring(root, encoding="UTF-8", xml_declaration=True)
