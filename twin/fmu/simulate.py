"""Simulate proximeter signals: export the (truth) model as an FMU and run it through FMPy.

The output is the ``signals.nc`` Dataset (``docs/guide/fmu.md``): ``displacement``
[m] over ``time`` and ``channel`` with per-channel ``node``, ``direction`` and
``location``, the ``sampling_rate`` [Hz] and the provenance (settings, seed,
and for synthetic data the truth that made it) in the attrs.
"""

from __future__ import annotations

import json
import logging
import tempfile
import warnings
from pathlib import Path

import numpy as np
import scipy.linalg as sla
import xarray as xr

from twin import __version__
from twin.defaults import NOISE_RATIO, SAMPLING_RATE_HZ
from twin.errors import ModelError, TwinWarning
from twin.fem.excitation import MachineExcitation, machine_excitation
from twin.fem.model import RPM_TO_RAD_S, RotorModel
from twin.fem.truthfile import Truth
from twin.fmu.export import export_fmu
from twin.fmu.run import record_outputs
from twin.fmu.statespace import StateSpace, check_stable, discretize
from twin.fmu.truth import MAX_TARGET_DAMPING, hidden_effects, model_state_space, truth_state_space
from twin.modes.analysis import damping_ratio, oscillating
from twin.netcdf import check_writable, write_netcdf
from twin.progress import bar

log = logging.getLogger(__name__)

#: The warm-up lasts this many of the slowest mode's time constants (at most MAX_WARMUP_S).
WARMUP_TIME_CONSTANTS = 5.0
MAX_WARMUP_S = 300.0


def fmu_name(model: RotorModel, ss: StateSpace) -> str:
    """The modelName of the FMU that simulates ``ss``: the model's name, and for a truth its hidden effects.

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> ss = SimpleNamespace(attrs={"truth": '{"source": "t.toml", "effects": {"magnetic_pull": {}}}'})
    >>> fmu_name(SimpleNamespace(name="hydro_unit"), ss)
    'hydro_unit truth: magnetic_pull'
    """
    effects = hidden_effects(ss.attrs)
    if effects is None:
        return model.name
    return f"{model.name} truth: {', '.join(effects) or 'nothing hidden'}"


def system_for(model: RotorModel, truth: Truth | None, basis: str, fmax_hz: float | None) -> StateSpace:
    """The state space to simulate: the truth's, or the model's (full or modal basis)."""
    if truth is not None:
        return truth_state_space(model, truth, basis=basis, fmax_hz=fmax_hz)
    return model_state_space(model, basis, fmax_hz)


def output_rms(ss: StateSpace, h: float, turbulence_asd: float, turbulence_ports: list[int]) -> np.ndarray:
    """Steady-state RMS [m] of each output under the turbulence alone (discrete Lyapunov equation)."""
    if not turbulence_ports or turbulence_asd <= 0:
        return np.zeros(len(ss.outputs))
    disc = discretize(ss, h)
    g = disc.gamma0[:, turbulence_ports]
    q = (turbulence_asd**2 / (2 * h)) * g @ g.T
    sigma = sla.solve_discrete_lyapunov(disc.phi, q)
    return np.sqrt(np.clip(np.einsum("ij,jk,ik->i", ss.C, sigma, ss.C), 0, None))


def default_warmup_s(ss: StateSpace) -> float:
    """The warm-up [s] :func:`simulate` discards by default: ``WARMUP_TIME_CONSTANTS`` time constants of the
    slowest mode, at most ``MAX_WARMUP_S``.

    Examples
    --------
    >>> from twin.fmu.statespace import StateSpace
    >>> ss = StateSpace(np.array([[-0.5]]), np.array([[1.0]]), np.array([[1.0]]), ["0.x"], ["y"], 0.0)
    >>> default_warmup_s(ss)  # five time constants of 2 s
    10.0
    """
    slowest = 1.0 / np.min(-ss.poles.real)
    return float(min(MAX_WARMUP_S, WARMUP_TIME_CONSTANTS * slowest))


def sensor_noise_std(
    ss: StateSpace,
    h: float,
    turbulence_asd: float,
    turbulence_ports: list[int],
    noise_ratio: float,
    noise_std_m: float | None = None,
) -> float:
    """Sensor noise std [m] per sample: ``noise_std_m`` when given, else ``noise_ratio`` times the
    median channel RMS of the turbulence response (computed only then)."""
    if noise_std_m is not None:
        return float(noise_std_m)
    rms = output_rms(ss, h, turbulence_asd, turbulence_ports)
    return noise_ratio * float(np.median(rms)) if rms.any() else 0.0


def response_pp(
    ss: StateSpace, h: float, unbalance_node: int, unbalance_me: float, node: int, asd: float
) -> np.ndarray:
    """Expected peak-to-peak displacement [m] of each output: twice the 1X unbalance response's amplitude plus
    six times the broad-band response's RMS (±3 sigma); infinite at an undamped resonance.

    Examples
    --------
    >>> from twin.fmu.truth import model_state_space
    >>> pp = response_pp(model_state_space(hydro_unit), 1 / 256, 8, 100.0, 28, 3000.0)
    >>> pp.shape, bool(pp.max() < 1e-3)  # m, well below a millimetre
    ((8,), True)
    """
    omega = ss.speed_rpm * RPM_TO_RAD_S
    one_x = np.zeros(ss.C.shape[0])
    if unbalance_me > 0 and omega > 0:
        force = np.zeros(ss.B.shape[1], dtype=complex)
        x, y = ss.node_ports(unbalance_node)
        force[x], force[y] = unbalance_me * omega**2, -1j * unbalance_me * omega**2  # forward: cos, sin
        try:
            state = np.linalg.solve(1j * omega * np.eye(ss.n_states) - ss.A, ss.B @ force)
        except np.linalg.LinAlgError:
            return np.full(ss.C.shape[0], np.inf)
        one_x = np.abs(ss.C @ state)
    return 2.0 * one_x + 6.0 * output_rms(ss, h, asd, ss.node_ports(node))


def check_response(
    name: str, ss: StateSpace, h: float, excitation: MachineExcitation, unbalance_me: float, asd: float
) -> None:
    """Refuse an excitation that would drive the shaft beyond ``excitation.max_response``, and warn above
    ``excitation.warn_response`` (a damaging vibration), before anything is simulated."""
    pp = response_pp(ss, h, excitation.unbalance_node, unbalance_me, excitation.broadband_node, asd)
    worst = int(np.argmax(pp))
    what = (
        f"the excitation would drive the shaft to {1e6 * pp[worst]:.3g} um peak to peak at {ss.outputs[worst]} "
        f"({unbalance_me:.4g} kg m of 1X unbalance at node {excitation.unbalance_node}, a broad-band force of "
        f"{asd:.4g} N/sqrt(Hz) at node {excitation.broadband_node})"
    )
    if not pp[worst] <= excitation.max_response:
        raise ModelError(
            f"{name}: {what}, beyond the {1e6 * excitation.max_response:.4g} um the machine allows "
            f"({excitation.sources['max_response']}): set the machine's excitation in its model file's "
            "[excitation] table (or a larger max_response there)"
        )
    if pp[worst] > excitation.warn_response:
        warnings.warn(
            f"{name}: {what}, above the {1e6 * excitation.warn_response:.4g} um of ISO 20816-1's zone C/D "
            "boundary, where vibration damages a machine",
            TwinWarning,
            stacklevel=3,
        )


def simulate(
    model: RotorModel,
    *,
    duration_s: float,
    fs_hz: float = SAMPLING_RATE_HZ,
    seed: int = 1,
    truth: Truth | None = None,
    turbulence_asd: float | None = None,
    unbalance_me: float | None = None,
    unbalance_phase_rad: float = 0.0,
    noise_ratio: float = NOISE_RATIO,
    noise_std_m: float | None = None,
    basis: str = "full",
    fmax_hz: float | None = None,
    warmup_s: float | None = None,
    steady_start: bool | None = None,
    output: str | Path | None = None,
    progress: bool = True,
    command: str = "",
) -> xr.Dataset:
    """Simulate the proximeter signals of the model (or a truth variant) through its FMU.

    Parameters
    ----------
    model : RotorModel
    duration_s : float
        Length of the record [s] (after the warm-up).
    fs_hz : float
        Sampling rate [Hz]; also the FMU's communication step ``1/fs``.
    seed : int
        Seed of the turbulence; the sensor noise uses ``seed + 7919``.
    truth : Truth, optional
        Hidden effects (see :func:`twin.fem.truthfile.load_truth`).
    turbulence_asd : float, optional
        One-sided amplitude spectral density of the broad-band force (turbulence, process forces), x and y
        [N/√Hz], at the machine's node for it; the machine's by default
        (:func:`twin.fem.excitation.machine_excitation`).
    unbalance_me, unbalance_phase_rad : float, optional
        1X unbalance [kg m] (the machine's by default, at its node) and its phase [rad].
    noise_ratio : float
        Sensor noise std as a fraction of the median channel RMS of the broad-band response.
    noise_std_m : float, optional
        Sensor noise std [m] per sample, instead of ``noise_ratio`` (keeps the noise of the
        sensors the same when the layout changes, e.g. after ``twin sensors``).
    basis, fmax_hz
        System for a model without per-mode truth: ``"full"`` FEM or ``"modal"`` up to ``fmax_hz``.
    warmup_s : float, optional
        Start from rest instead and discard this much simulated time [s] before the record, so the start
        transient has died out (:func:`default_warmup_s` gives five time constants of the slowest mode).
    steady_start : bool, optional
        Start the FMU in the stationary response to its excitation (its steady start,
        :mod:`twin.fmu.steady`), so the record is stationary from its first sample with no warm-up: the
        default unless ``warmup_s`` is given. False without ``warmup_s``: from rest with
        :func:`default_warmup_s`.
    output : path, optional
        NetCDF file to write (written to a temporary name, then renamed).
    progress : bool
        Show a progress bar.

    Returns
    -------
    xarray.Dataset
        ``displacement`` (time, channel) [m].

    Examples
    --------
    >>> ds = simulate(hydro_unit, duration_s=1.0, fs_hz=256.0, progress=False)
    >>> ds.displacement.dims, ds.sizes["time"], ds.attrs["sampling_rate"]
    (('time', 'channel'), 256, 256.0)

    A response the machine could not survive is refused before any work (the limit is the model file's
    ``[excitation] max_response``, by default ten times ISO 20816-1's zone C/D boundary), a damaging one
    warned about:

    >>> simulate(hydro_unit, duration_s=1.0, unbalance_me=1e5, progress=False)
    Traceback (most recent call last):
    ...
    twin.errors.ModelError: hydro_unit: the excitation would drive the shaft to 1.83e+05 um peak to peak at GEN_x ...
    """
    excitation = machine_excitation(model)
    turbulence_asd = excitation.broadband_asd if turbulence_asd is None else float(turbulence_asd)
    unbalance_me = excitation.unbalance_me if unbalance_me is None else float(unbalance_me)
    if not (np.isfinite(duration_s) and duration_s > 0):
        raise ModelError(f"duration must be positive, got {duration_s} s")
    if not (np.isfinite(fs_hz) and fs_hz > 0):
        raise ModelError(f"sampling rate must be positive, got {fs_hz} Hz")
    if noise_ratio < 0 or turbulence_asd < 0 or unbalance_me < 0:
        raise ModelError("noise_ratio, turbulence_asd and unbalance_me must not be negative")
    if noise_std_m is not None and not (np.isfinite(noise_std_m) and noise_std_m >= 0):
        raise ModelError(f"noise_std_m must not be negative, got {noise_std_m} m")
    if output is not None:
        output = check_writable(output)
    h = 1.0 / fs_hz
    ss = system_for(model, truth, basis, fmax_hz)
    check_stable(ss, model.name)  # before any work on a system that would diverge
    poles = ss.poles[oscillating(ss.poles)]
    light = poles[damping_ratio(poles) < MAX_TARGET_DAMPING]
    f_interest = (
        fmax_hz if fmax_hz is not None else min(100.0, float(np.max(light.imag)) / (2 * np.pi)) if light.size else 0.0
    )
    if fs_hz < 2.5 * f_interest:
        warnings.warn(
            f"fs = {fs_hz:g} Hz is low for modes up to {f_interest:.1f} Hz: use at least "
            f"{2.5 * f_interest:.0f} Hz (2.5 samples per period at the highest mode)",
            TwinWarning,
            stacklevel=2,
        )
    steady = warmup_s is None if steady_start is None else bool(steady_start)
    if steady and warmup_s is not None:
        raise ModelError("a steady start needs no warm-up: give steady_start or warmup_s, not both")
    if warmup_s is None:
        warmup_s = 0.0 if steady else default_warmup_s(ss)
    if not (np.isfinite(warmup_s) and warmup_s >= 0):
        raise ModelError(f"the warm-up must be a non-negative time, got {warmup_s} s")
    n_warm = int(np.ceil(warmup_s * fs_hz))
    n_rec = int(round(duration_s * fs_hz))
    if n_rec < 2:
        raise ModelError(f"{duration_s} s at {fs_hz} Hz gives fewer than two samples")

    turb_node = excitation.broadband_node
    turb_ports = ss.node_ports(turb_node)
    check_response(model.name, ss, h, excitation, unbalance_me, turbulence_asd)
    noise_std = sensor_noise_std(ss, h, turbulence_asd, turb_ports, noise_ratio, noise_std_m)
    start_values = {
        "unbalance_me": unbalance_me,
        "unbalance_phase": unbalance_phase_rad,
        "turbulence_asd": turbulence_asd,
        "noise_std": noise_std,
        "turbulence_seed": int(seed),
        "noise_seed": int(seed) + 7919,
        "steady_start": steady,
    }
    import fmpy

    with tempfile.TemporaryDirectory() as tmp:
        fmu = export_fmu(
            model,
            Path(tmp) / f"{model.name}.fmu",
            step_s=h,
            state_space=ss,
            inputs=[],
            name=fmu_name(model, ss),
            steady_start=steady,
            cross=False,
        )
        n_total = n_warm + n_rec
        with bar(
            total=n_total, desc=f"simulate {model.name}", unit="step", progress=progress, mininterval=0.5
        ) as steps:
            data = record_outputs(
                fmu,
                outputs=ss.outputs,
                n_samples=n_total,
                step_s=h,
                start_time=-n_warm * h,
                start_values=start_values,
                on_progress=steps.update,
            )[n_warm:]
    time = np.arange(n_rec) * h

    sensors = {s.name: s for s in model.sensors}
    settings = {
        "duration_s": duration_s,
        "fs_hz": fs_hz,
        "seed": seed,
        "turbulence_asd": turbulence_asd,
        "turbulence_node": turb_node,
        "unbalance_me": unbalance_me,
        "unbalance_phase_rad": unbalance_phase_rad,
        "unbalance_node": excitation.unbalance_node,
        "noise_ratio": noise_ratio,
        "noise_std_m": noise_std,
        "basis": ss.basis,
        "fmax_hz": fmax_hz,
        "warmup_s": n_warm * h,
        "steady_start": steady,
        "n_states": ss.n_states,
    }
    attrs = {
        "title": f"simulated proximeter signals of {model.name}",
        "sampling_rate": float(fs_hz),
        "sampling_rate_units": "Hz",
        "speed_rpm": float(ss.speed_rpm),
        "model": model.name,
        "model_source": str(Path(model.source).resolve()) if model.source else "",
        "producer": f"twin {__version__} twin.fmu.simulate (FMI 2.0 co-simulation, loaded by FMPy {fmpy.__version__})",
        "command": command,
        "settings": json.dumps(settings),
        "seed": int(seed),
    }
    if truth is not None:
        attrs["truth"] = ss.attrs["truth"]
        attrs["truth_modes"] = ss.attrs["truth_modes"]
    ds = xr.Dataset(
        {"displacement": (("time", "channel"), data, {"units": "m", "long_name": "proximeter displacement"})},
        coords={
            "time": ("time", time, {"units": "s", "long_name": "time from the start of the record"}),
            "channel": ("channel", list(ss.outputs), {"long_name": "proximeter (sensor name)"}),
            "node": (
                "channel",
                [sensors[c].node for c in ss.outputs],
                {"units": "1", "long_name": "FEM node the proximeter faces (0 at the shaft's first node)"},
            ),
            "direction": (
                "channel",
                [sensors[c].direction for c in ss.outputs],
                {"units": "1", "long_name": "measuring direction in the plane of the node (x or y)"},
            ),
            "location": (
                "channel",
                [sensors[c].location for c in ss.outputs],
                {"units": "1", "long_name": "what the proximeter faces (bearing, disk or region)"},
            ),
        },
        attrs=attrs,
    )
    if output is not None:
        write_netcdf(ds, output)
    return ds
