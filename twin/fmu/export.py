"""Export a rotor model as an FMU: FMI 2.0 or 3.0, co-simulation, model exchange or both.

The FMU holds

* ``modelDescription.xml`` (:mod:`twin.fmu.description`): inputs (forces at named nodes), outputs (the
  sensor channels), parameters of the built-in excitation, the modal states and their derivatives;
* ``resources/twin_lti.bin``: the system's modal form (:mod:`twin.fmu.modal`: poles, input and output
  rows), the port map, the GUID, the real parameters' start values and the steady start's factor
  (:mod:`twin.fmu.steady`);
* ``binaries/<platform>/<modelIdentifier>.<so|dylib|dll>``: the generic runtime, compiled once per
  platform (:mod:`twin.fmu.build`); one binary serves FMI 2.0 and 3.0 (platform ``linux64`` and
  ``x86_64-linux``);
* ``sources/``: the runtime's C sources and the FMI headers, so the FMU can be rebuilt on another
  platform (with ``-DFMI2_FUNCTION_PREFIX=<modelIdentifier>_`` or ``-DFMI3_FUNCTION_PREFIX=...`` for
  static linking beside other FMUs; an FMI 3.0 FMU has its ``buildDescription.xml``);
* ``documentation/index.html``: what the FMU is (model, truth, variables and units).

The modelName is the model's (and its truth's) name, the modelIdentifier that
name as a C identifier. The FMU's state can be got, set and serialized.

The file is written to a temporary name and renamed when complete, so a
failed export never leaves half an FMU behind.
"""

from __future__ import annotations

import hashlib
import logging
import re
import struct
import uuid
import zipfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from twin.errors import ModelError, TwinError
from twin.fem.excitation import machine_excitation
from twin.fem.model import RPM_TO_RAD_S, RotorModel
from twin.fmu import build
from twin.fmu.description import (
    fmi2_description,
    fmi3_build_description,
    fmi3_description,
    start_values,
    variables,
)
from twin.fmu.documentation import documentation_html
from twin.fmu.modal import modal_form
from twin.fmu.statespace import StateSpace, check_stable, discretize
from twin.fmu.steady import steady_start as stationary_start
from twin.fmu.truth import model_state_space
from twin.netcdf import atomic_output

log = logging.getLogger(__name__)

#: The resource file's format, shared with twin_lti.c (MAGIC).
RESOURCE_MAGIC = b"TWINLTI5"
#: The FMI interfaces an export declares, by its ``kind``.
KINDS = {"both": ("cs", "me"), "cs": ("cs",), "me": ("me",)}
#: The FMI versions an export can be written in.
FMI_VERSIONS = (2, 3)


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
    >>> [p.name for p in resolve_inputs(hydro_unit, ["runner.x", "12.y"])]
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
            raise ModelError(
                f"force input '{item}': no node, disk, bearing or sensor called '{where}' "
                f"(names: {', '.join(sorted(named))})"
            )
        out.append(Port(f"F_{where}_{axis}", f"{node}.{axis}"))
    if len({p.name for p in out}) != len(out):
        raise ModelError(f"force inputs are given twice: {list(inputs)}")
    return out


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
    fmi_version: int = 2,
    cross: bool = True,
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
        Default node of the 1X unbalance (a parameter of the FMU) and node of the broad-band
        force (fixed); defaults: the machine's (:func:`twin.fem.excitation.machine_excitation`).
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
    fmi_version : {2, 3}
        FMI 2.0 or FMI 3.0 (the same runtime binary serves both).
    cross : bool
        Also ship the binaries of the platforms a cross compiler on the PATH builds for
        (:data:`twin.fmu.build.CROSS_TARGETS`: win64 with Debian's ``gcc-mingw-w64-x86-64``), compiled
        once and cached like this machine's.

    Returns
    -------
    Path
        The FMU written.

    Examples
    --------
    >>> from twin.fmu import export_fmu
    >>> import tempfile, pathlib
    >>> out = pathlib.Path(tempfile.mkdtemp()) / "unit.fmu"
    >>> export_fmu(hydro_unit, out, basis="modal", fmax_hz=50.0).name
    'unit.fmu'
    """
    path = Path(path)
    if kind not in KINDS:
        raise TwinError(f"kind must be one of {', '.join(KINDS)} (FMI interfaces), got {kind!r}")
    if fmi_version not in FMI_VERSIONS:
        raise TwinError(f"fmi_version must be 2 or 3, got {fmi_version!r}")
    if not path.parent.is_dir():
        raise TwinError(f"cannot write {path}: folder {path.parent} does not exist")
    if state_space is None:
        state_space = model_state_space(model, basis, fmax_hz)
    ports = resolve_inputs(model, inputs)
    excitation = machine_excitation(model)
    unbalance_node = excitation.unbalance_node if unbalance_node is None else int(unbalance_node)
    turbulence_node = excitation.broadband_node if turbulence_node is None else int(turbulence_node)
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
    body = b"".join(
        [
            np.asarray(in_ports, dtype="<i4").tobytes(),
            *(np.ascontiguousarray(a, dtype="<c16").tobytes() for a in (form.poles, form.wb.T, form.cv)),
            *([] if steady is None else [np.ascontiguousarray(form.left @ steady.factor, dtype="<c16").tobytes()]),
        ]
    )
    name = model.name if name is None else str(name)
    identifier = model_identifier(name)
    guid = "{" + str(uuid.UUID(hashlib.sha256(body + name.encode()).hexdigest()[:32])) + "}"
    n, p = state_space.B.shape
    dims = (form.n_modes, n, p, state_space.C.shape[0], len(ports), *turb, unbalance_node, int(steady is not None))
    start = start_values(model)
    starts = list(start.values())
    head = RESOURCE_MAGIC + struct.pack("<9i6d", *dims, step_s, omega, *starts)
    resource = head + guid.encode().ljust(64, b"\0") + body

    vs = variables(model, state_space, form, ports, unbalance_node, steady is not None, start)
    text = description or (
        f"{model.name} at {state_space.speed_rpm:g} rpm, {state_space.basis} basis, "
        f"{state_space.n_states} states (twin linear rotor)"
    )
    write = fmi2_description if fmi_version == 2 else fmi3_description
    xml = write(
        model,
        state_space,
        vs,
        guid=guid,
        identifier=identifier,
        name=name,
        description=text,
        step_s=step_s,
        kinds=KINDS[kind],
    )
    library = build.compiled_runtime()
    plat = build.platform_folder() if fmi_version == 2 else build.platform_tuple()
    headers = build.fmi_headers()  # sources/ compile without a prefix to both APIs: both versions' headers
    with atomic_output(path, ".fmu.part") as tmp, zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("modelDescription.xml", xml)
        z.writestr("documentation/index.html", documentation_html(xml, state_space.attrs, step_s))
        z.writestr("resources/twin_lti.bin", resource)
        z.write(library, f"binaries/{plat}/{identifier}{build.shared_library_suffix()}")
        for target in build.available_cross_targets() if cross else []:
            folder = target.fmi2_folder if fmi_version == 2 else target.fmi3_folder
            z.write(build.compiled_runtime(target=target), f"binaries/{folder}/{identifier}{target.suffix}")
        for file_name, source in {**build.runtime_sources(), **headers}.items():
            z.writestr(f"sources/{file_name}", source)
        if fmi_version == 3:
            z.writestr("sources/buildDescription.xml", fmi3_build_description(identifier))
    log.info(
        "wrote %s: %d states, %d inputs, %d outputs, step %g s", path, n, len(ports), len(state_space.outputs), step_s
    )
    return path


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
