"""Run an FMI 2.0 co-simulation FMU through FMPy and record its outputs at every communication point.

``fmpy.simulate_fmu`` is general (inputs, events, recorders) and costs about 12 µs of Python per step,
several times what the FMU's own step costs. A record of a sensor array is the simplest case: no inputs,
one output sample per step. :func:`record_outputs` instantiates and initialises the FMU with FMPy's own
FMU2Slave and start-value handling, then runs the steps from a loop in C (``c/record.c``, compiled once
and cached like the FMU runtime) that calls the FMU's own ``fmi2DoStep`` and ``fmi2GetReal``, writes into
one preallocated array and checks the status of every call.
"""

from __future__ import annotations

import ctypes
import shutil
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from twin.errors import TwinError

#: Steps per call of the recording loop (the progress display's granularity).
CHUNK = 4096


def _recorder():
    """``twin_record`` of the compiled ``c/record.c`` with its argument types."""
    from twin.fmu.build import compiled_recorder

    lib = ctypes.CDLL(str(compiled_recorder()))
    f = lib.twin_record
    f.argtypes = [
        ctypes.c_void_p,
        ctypes.c_void_p,
        ctypes.c_void_p,
        ctypes.c_double,
        ctypes.c_double,
        ctypes.c_long,
        ctypes.c_long,
        ctypes.c_void_p,
        ctypes.c_size_t,
        ctypes.c_void_p,
        ctypes.c_void_p,
    ]
    f.restype = ctypes.c_long
    return f


def record_outputs(
    fmu: str | Path,
    *,
    outputs: Sequence[str],
    n_samples: int,
    step_s: float,
    start_time: float = 0.0,
    start_values: dict | None = None,
    on_progress: Callable[[int], None] | None = None,
) -> np.ndarray:
    """The outputs of a co-simulation FMU at ``start_time + k step_s``, ``k = 0 .. n_samples - 1``.

    Parameters
    ----------
    fmu : path
        The ``.fmu`` file.
    outputs : list of str
        Output variables to record, in this order.
    n_samples : int
        Samples to record (the first at ``start_time``, after initialisation).
    step_s : float
        Communication step [s].
    start_time : float
        Start of the experiment [s].
    start_values : dict, optional
        Parameter values by name (set in initialisation mode, as ``fmpy.simulate_fmu`` does).
    on_progress : callable, optional
        Called with the number of steps done since its last call, every ``CHUNK`` steps and at the end.

    Returns
    -------
    (n_samples, len(outputs)) array

    Raises
    ------
    TwinError
        An output name is not in the FMU, or an FMU call failed (with what the FMU logged).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from twin.fmu import export_fmu
    >>> fmu = export_fmu(hydro_unit, pathlib.Path(tempfile.mkdtemp()) / "u.fmu")
    >>> record_outputs(fmu, outputs=["UGB_x", "UGB_y"], n_samples=256, step_s=1 / 256).shape
    (256, 2)
    """
    import fmpy
    from fmpy.fmi2 import FMU2Slave, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE
    from fmpy.simulation import apply_start_values

    md = fmpy.read_model_description(str(fmu))
    by_name = {v.name: v for v in md.modelVariables}
    missing = [name for name in outputs if name not in by_name]
    if missing:
        raise TwinError(
            f"{fmu}: no variable {', '.join(missing)} (outputs: "
            f"{', '.join(v.name for v in md.modelVariables if v.causality == 'output')})"
        )
    messages: list[str] = []

    def logger(env, instance, status, category, message):
        messages.append(message.decode(errors="replace").replace("%%", "%"))

    callbacks = fmi2CallbackFunctions()
    callbacks.logger = fmi2CallbackLoggerTYPE(logger)  # kept alive until the end of the run
    unzipped = fmpy.extract(str(fmu))
    slave = FMU2Slave(guid=md.guid, unzipDirectory=unzipped, modelIdentifier=md.coSimulation.modelIdentifier)
    out = np.empty((n_samples, len(outputs)))
    try:
        slave.instantiate(callbacks=callbacks)
        slave.setupExperiment(startTime=start_time)
        slave.enterInitializationMode()
        apply_start_values(slave, md, dict(start_values or {}))
        slave.exitInitializationMode()
        recorder = _recorder()
        vr = (ctypes.c_uint * len(outputs))(*[by_name[name].valueReference for name in outputs])
        functions = [ctypes.cast(slave.dll[f], ctypes.c_void_p) for f in ("fmi2DoStep", "fmi2GetReal")]
        status = ctypes.c_int(0)
        for k0 in range(0, n_samples, CHUNK):
            n = min(CHUNK, n_samples - k0)
            done = recorder(
                *functions,
                slave.component,
                start_time,
                step_s,
                k0,
                n,
                vr,
                len(outputs),
                out[k0:].ctypes.data,
                ctypes.byref(status),
            )
            if done < n:
                k = k0 + done
                call = "fmi2GetReal" if status.value >= 10 else f"fmi2DoStep to t = {start_time + k * step_s:.6g} s"
                raise TwinError(f"{fmu}: {call} failed: " + ("; ".join(messages) or "the FMU logged nothing"))
            if on_progress is not None:
                on_progress(n)
        slave.terminate()
    except fmpy.fmi1.FMICallException as exc:
        raise TwinError(f"{fmu}: {exc}: " + ("; ".join(messages) or "the FMU logged nothing")) from None
    finally:
        if getattr(slave, "component", None):
            slave.freeInstance()
        shutil.rmtree(unzipped, ignore_errors=True)
    return out
