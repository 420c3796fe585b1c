"""The posterior's spread calibrated on records simulated at its estimate (a parametric bootstrap of the loop).

A record errs in a way no resampling of its own blocks shows (SSI's error on a short record), and the twin
has what a statistic of one record lacks: the simulator that made it. So, after an update, the model at the
posterior's estimate is simulated ``records`` times through its FMU (fresh seeds, the measured record's
length and sampling rate), each record is extracted with the measured modes' settings, and the update's own
density (:func:`twin.update.samplers.hmc.marginal_setup`: the same parameters, priors and options) is fitted
to it: its mode ``θ_r`` and Laplace std ``s_r``. The records' errors ``θ_r - θ̂`` are what the measured
record's error would be if the estimate were the truth, so their RMS over the posterior's own std ``σ``,
``c = sqrt(mean_r (θ_r - θ̂)²) / σ``, is the ratio of the error the posterior should claim to the one it
claims. ``c²`` comes from ``R`` records, so the measured record's error is predicted by Student's t with
``R`` degrees of freedom and the factor is ``c · t_R / z`` at the 90% interval
(:func:`~twin.loop.pooling.predictive_widening`). The draws of every parameter the data determine are
stretched about their mean by it (:func:`twin.update.posterior.stretch`), narrowed as well as widened;
parameters the data do not determine keep their draws.

Twelve records give each parameter its own ``c`` only to about 20%, more than the parameters differ, so each
``c`` is first shrunk towards the determined parameters' pooled value as far as their spread is the records'
noise (:func:`~twin.loop.pooling.pooled_rms`, empirical Bayes on ``log c²``); parameters that really differ
keep their own. The RMS of each record's error in its own std, ``z_r = (θ_r - θ̂) / s_r``, is kept as the
diagnostic ``rms_z``: it answers for the measured record only where the records' ``s_r`` are its ``σ``.

A simulated record's modes are numbered as the measured ones (:func:`simulated_reference`,
:func:`matched_modes`). A parameter seen on too few records (:data:`~twin.loop.pooling.MIN_RECORDS`) is
seen on more: batches of ``R`` further records, up to :data:`~twin.defaults.MAX_BATCHES` in all.

A record and its extraction take about 12 s on one core, so this costs minutes per update;
:meth:`twin.loop.twin.Twin.update` does it by default for the sampler's update of extracted modes
(:data:`~twin.defaults.DEFAULT_RECORDS`, :func:`records_for`), as do ``twin loop``, ``twin demo`` and
``twin sweep``. Why, and what it was measured to do, is ``docs/decisions/loop-calibration.md``.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import warnings
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import xarray as xr

from twin.defaults import DEFAULT_RECORDS, MAX_BATCHES  # noqa: F401 (shared with the CLI)
from twin.errors import TwinError, UpdateError
from twin.fem.model import RotorModel
from twin.loop.pooling import MIN_RECORDS, pooled_rms, predictive_widening
from twin.modes.analysis import oscillating
from twin.modes.pairing import assign
from twin.tasks import mapper, one_blas_thread

log = logging.getLogger(__name__)

#: Keys of ``modes.nc``'s ``settings`` attr that are :func:`twin.extract.extract`'s own keywords.
EXTRACT_KEYS = (
    "samples",
    "shape_samples",
    "blocks",
    "fmin_hz",
    "fmax_hz",
    "block_rows",
    "shape_block_rows",
    "first_lag",
    "max_order",
    "delete_blocks",
    "order_spread",
    "orders_per_mode",
    "remove_harmonics",
    "differenced_above_hz",
    "algorithm",
)
#: A simulated record's mode is the measured mode whose simulated frequency (:func:`simulated_reference`) is
#: within this fraction of its own. The records' modes scatter about the system's: the 3.81 Hz mode of the
#: seal records (damped 13.6%) by 0.55% (std over twelve records), the others by 0.2% or less.
MATCH_TOLERANCE = 0.02
#: A measured mode is the simulated system's mode nearest in frequency only within this fraction of its own.
PAIR_LIMIT = 0.05


def check_records(records: int | None, method: str) -> None:
    """Refuse a bootstrap that cannot run: not a whole number >= 0, or given for a posterior not the sampler's.

    Examples
    --------
    >>> check_records(None, "laplace"), check_records(12, "hmc")
    (None, None)
    >>> check_records(5, "laplace")
    Traceback (most recent call last):
    twin.errors.UpdateError: bootstrap=5 calibrates the HMC sampler's posterior: it needs method='hmc'
    """
    if records is None:
        return
    if isinstance(records, bool) or int(records) != records or records < 0:
        raise UpdateError(f"bootstrap must be a whole number of records >= 0 (0: none), got {records!r}")
    if records and method != "hmc":
        raise UpdateError(f"bootstrap={records} calibrates the HMC sampler's posterior: it needs method='hmc'")


def records_for(records: int | None, modes: xr.Dataset, method: str) -> int:
    """The records a calibration runs on: ``records`` as given, or by default (None) :data:`~twin.defaults.DEFAULT_RECORDS`
    for the sampler's update of modes extracted from a record (their attr ``settings`` says how, as
    :func:`twin.extract.extract` writes it) and none otherwise: the Laplace fit, or modes with no record to
    repeat (:func:`twin.update.synthesize_modes`'s).

    Examples
    --------
    >>> import json, xarray as xr
    >>> extracted = xr.Dataset(attrs={"settings": json.dumps({"duration_s": 1200.0, "fs_hz": 256.0})})
    >>> records_for(None, extracted, "hmc"), records_for(None, extracted, "laplace"), records_for(3, extracted, "hmc")
    (12, 0, 3)
    >>> records_for(None, xr.Dataset(), "hmc")
    0
    """
    check_records(records, method)
    if records is not None:
        return int(records)
    if method != "hmc":
        return 0
    try:
        record_settings(modes)
    except TwinError:
        return 0
    return DEFAULT_RECORDS


def matched_modes(modes: xr.Dataset, reference: Mapping[int, float], tolerance: float = MATCH_TOLERANCE) -> xr.Dataset:
    """``modes`` renumbered as the reference modes (``{number: frequency [Hz]}``) they match.

    A mode matches a reference mode within ``tolerance`` of its frequency, one to one, by the assignment of
    least total frequency distance (:func:`twin.modes.pairing.assign`); modes that match none are left out. Per-mode parameters (``FSI.added_mass_<mode>``) then mean the same mode in a
    simulated record as in the measured one. The reference is the simulated system's frequency of each
    measured mode (:func:`simulated_reference`), about which the records' modes scatter.

    Examples
    --------
    >>> import numpy as np, xarray as xr
    >>> m = xr.Dataset({"frequency": ("mode", [2.9, 10.16, 30.0])}, coords={"mode": [1, 2, 3]})
    >>> matched_modes(m, {1: 1.1, 2: 2.91, 3: 3.8, 4: 10.15})["mode"].values.tolist()
    [2, 4]
    """
    known = np.array(list(reference), dtype=int)
    reference_hz = np.array([reference[n] for n in known], dtype=float)
    f = np.abs(modes["frequency"].values)
    distance = np.abs(f[:, None] - reference_hz[None, :])
    cols = assign(distance, distance <= tolerance * reference_hz[None, :])
    keep = np.flatnonzero(cols >= 0)
    numbers = known[cols[keep]]
    order = np.argsort(numbers)
    return modes.isel(mode=keep[order]).assign_coords(mode=[int(n) for n in numbers[order]])


def simulated_reference(poles: np.ndarray, modes: xr.Dataset, limit: float = PAIR_LIMIT) -> dict[int, float]:
    """``{measured mode: frequency [Hz]}`` of the simulated system's mode each measured mode is.

    The records simulated at the estimate scatter about the simulated system's frequencies, not about the
    measured ones: matched against the measured frequencies (which carry the measured record's own
    extraction error), a record's mode is dropped whenever the two errors add up beyond the tolerance, and
    the records that keep it are the ones extracted best, so the calibration's errors would come from
    records unlike the measured one. Each measured mode takes the frequency of the system's pole
    (``Im > 0``) assigned to it one to one (:func:`twin.modes.pairing.assign`: the most pairs, then the
    least total relative distance) within ``limit`` of its own; a measured mode the system has no pole near
    keeps its own frequency.

    Parameters
    ----------
    poles : (n,) complex
        The simulated system's poles [1/s] (:func:`twin.fmu.truth.model_state_space`).
    modes : xarray.Dataset
        The measured modes (``frequency`` [Hz] over ``mode``).
    limit : float
        The largest relative distance of a measured mode from its pole.

    Examples
    --------
    >>> import numpy as np, xarray as xr
    >>> poles = 2j * np.pi * np.array([3.81, 11.64, 17.15]) - 0.5
    >>> m = xr.Dataset({"frequency": ("mode", [3.759, 11.65, 30.0])}, coords={"mode": [3, 5, 8]})
    >>> {k: round(v, 2) for k, v in simulated_reference(poles, m).items()}
    {3: 3.81, 5: 11.64, 8: 30.0}
    """
    system_hz = poles[oscillating(poles)].imag / (2 * np.pi)
    labels = [int(m) for m in modes["mode"].values]
    measured_hz = np.abs(modes["frequency"].values).astype(float)
    reference = dict(zip(labels, map(float, measured_hz)))
    if not len(system_hz):
        return reference
    distance = np.abs(system_hz[None, :] / measured_hz[:, None] - 1.0)
    cols = assign(distance, distance <= limit)
    for i in np.flatnonzero(cols >= 0):
        reference[labels[i]] = float(system_hz[cols[i]])
    return reference


def target_numbered(model: RotorModel, modes: xr.Dataset) -> RotorModel:
    """The model with its per-mode FSI renumbered from measured modes to target modes, ready to simulate.

    An update's per-mode values belong to the measured modes (``FSI.added_mass_<label>``, label of
    ``modes``; :func:`twin.loop.compare.model_modes` reads them so), while a simulation's modal synthesis
    takes value ``i`` for the model's target mode ``i`` (:func:`twin.fmu.truth.synthesize_per_mode_fsi`).
    The two agree only when every target mode up to the last was measured. Each measured mode's values go to
    the target mode it pairs with (:func:`twin.loop.compare.pair_with_measured`). A target mode below the
    last one measured that no measured mode pairs with (one the sensors hardly see) gets the measured
    modes' median values: the water acts on it too, and left dry it would sit where the record's did not.
    (The decision log's loop-calibration page has the measurement behind the median.) A model without
    per-mode FSI is returned as it is.

    Examples
    --------
    >>> from twin.fem.effects import FluidAddedMassPerMode
    >>> from twin.update import synthesize_modes
    >>> model = hydro_unit
    >>> modes = synthesize_modes(model, samples=20, seed=1).sel(mode=[1, 2, 4])  # target mode 3 not measured
    >>> updated = model.with_effects(FluidAddedMassPerMode((1e5, 2e5, 4e5), (0.0, 0.0, 0.0)))
    >>> target_numbered(updated, modes.assign_coords(mode=[1, 2, 3])).effects[-1].added_mass  # 3: the median
    (100000.0, 200000.0, 200000.0, 400000.0)
    """
    from twin.fmu.truth import MAX_TARGET_DAMPING
    from twin.modes.analysis import damping_ratio
    from twin.modes.measured import channel_dofs, measured_modes, pair_with_measured
    from twin.modes.sensitivity import solve_modes

    per_mode = model.per_mode_effect
    if per_mode is None:
        return model
    meas = measured_modes(modes)
    sol = solve_modes(model)  # the single FEM: the per-mode values left out, as the synthesis's dry modes
    _, cols = pair_with_measured(sol, meas, channel_dofs(model, meas.channels))
    light = np.flatnonzero(damping_ratio(sol.poles) < MAX_TARGET_DAMPING)
    mass, damping = np.full(len(light), np.nan), np.full(len(light), np.nan)
    for label, col in zip(meas.mode, cols):
        if not 0 < label <= per_mode.n_modes:
            continue
        if col not in light:
            raise TwinError(
                f"measured mode {label} pairs with the model's mode at "
                f"{sol.poles[col].imag / (2 * np.pi):.3f} Hz, damped more than a target mode "
                f"({MAX_TARGET_DAMPING:.0%}): its per-mode FSI cannot be simulated"
            )
        j = int(np.flatnonzero(light == col)[0])
        mass[j], damping[j] = per_mode.added_mass[label - 1], per_mode.added_damping[label - 1]
    n = int(np.flatnonzero(np.isfinite(mass)).max(initial=-1)) + 1
    if n:
        mass[:n] = np.where(np.isfinite(mass[:n]), mass[:n], np.nanmedian(mass[:n]))
        damping[:n] = np.where(np.isfinite(damping[:n]), damping[:n], np.nanmedian(damping[:n]))
    effect = dataclasses.replace(
        per_mode, added_mass=tuple(map(float, mass[:n])), added_damping=tuple(map(float, damping[:n]))
    )
    dry = model.without_per_mode_effect()
    return dry.with_effects(effect) if n else dry


def record_settings(modes: xr.Dataset) -> tuple[float, float, dict[str, Any]]:
    """The record length [s], sampling rate [Hz] and :func:`twin.extract.extract` keywords the modes came from.

    Read from the attr ``settings`` that :func:`twin.extract.extract` writes.

    Examples
    --------
    >>> import json, xarray as xr
    >>> modes = xr.Dataset(attrs={"settings": json.dumps({"duration_s": 1200.0, "fs_hz": 256.0, "samples": 15,
    ...     "fmax_hz": 60.0, "block_rows": 32, "shape_block_rows": 32, "channels": ["A_x"]})})
    >>> record_settings(modes)
    (1200.0, 256.0, {'samples': 15, 'fmax_hz': 60.0, 'block_rows': 32})
    """
    try:
        settings = json.loads(modes.attrs["settings"])
        duration_s, fs_hz = float(settings["duration_s"]), float(settings["fs_hz"])
    except (KeyError, TypeError, ValueError) as err:
        raise TwinError(
            "the modes do not say how they were extracted (attr 'settings' with 'duration_s' and "
            f"'fs_hz', as twin.extract writes it): {err!r}"
        ) from None
    options = {k: settings[k] for k in EXTRACT_KEYS if settings.get(k) is not None}
    if options.get("shape_block_rows", 0) <= options.get("block_rows", 0):  # written resolved: the shapes' own
        options.pop("shape_block_rows", None)
    return duration_s, fs_hz, options


def record_seeds(seed: int | None, records: int) -> list[int]:
    """``records`` seeds of simulated records, drawn from ``seed`` (reproducible, far from small seeds).

    Examples
    --------
    >>> record_seeds(1, 2) == record_seeds(1, 2), len(set(record_seeds(1, 5)))
    (True, 5)
    """
    state = np.random.SeedSequence([0x7B0075, 0 if seed is None else int(seed)]).generate_state(records, np.uint32)
    return [int(s) % (2**31 - 1) + 1 for s in state]  # the FMU's seeds are 32-bit signed integers


@one_blas_thread
def _record_fit(
    seed: int,
    *,
    simulated: RotorModel,
    model: RotorModel,
    settings: Mapping[str, Any],
    duration_s: float,
    fs_hz: float,
    extraction: Mapping[str, Any],
    reference: Mapping[int, float],
    simulate_options: Mapping[str, Any],
) -> dict[str, tuple[float, float]] | str:
    """Simulate and extract one record of ``simulated``; fit the update's density (of ``model``) to it, its
    modes numbered as the measured ones (``reference``, :func:`matched_modes`).

    Returns ``{label: (mode, Laplace std)}`` [SI], or why the fit failed.
    """
    from twin.extract import extract
    from twin.fmu.simulate import simulate
    from twin.update.marginal import posterior_mode
    from twin.update.problem import UpdateError
    from twin.update.samplers.hmc import marginal_setup

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        signals = simulate(
            simulated, duration_s=duration_s, fs_hz=fs_hz, seed=seed, progress=False, **dict(simulate_options)
        )
        try:
            modes = matched_modes(extract(signals, progress=False, **dict(extraction)), reference)
            marg, prior = marginal_setup(model, modes, settings)
            theta, here = posterior_mode(marg, prior.parameter_mean, prior.parameter_precision)
            cov = np.linalg.inv(here.precision)
        except (TwinError, UpdateError, np.linalg.LinAlgError) as err:
            return f"record {seed}: {err}"
    problem = marg.problem
    scales = np.concatenate([problem.global_scale, problem.mode_scale.ravel()])
    std = np.sqrt(np.clip(np.diag(cov), 0.0, None)) * scales
    return {label: (float(t * s), float(e)) for label, t, s, e in zip(problem.parameter_labels, theta, scales, std)}


def bootstrap_factors(
    model: RotorModel,
    simulated: RotorModel,
    modes: xr.Dataset,
    posterior: xr.DataTree,
    estimate: Mapping[str, float],
    *,
    records: int = 20,
    seed: int | None = None,
    pooled: Sequence[str] | None = None,
    simulate_options: Mapping[str, Any] | None = None,
    tasks: Any = None,
    progress: bool = False,
) -> xr.Dataset:
    """Each parameter's error over records simulated at the posterior's estimate, in the posterior's std.

    Parameters
    ----------
    model : RotorModel
        The model the update started from (its priors' centre).
    simulated : RotorModel
        The model at the posterior's estimate (:func:`twin.update.apply_posterior`): what is simulated.
    modes : xarray.Dataset
        The measured modes (their record length, sampling rate and extraction settings are repeated).
    posterior : xarray.DataTree
        The update's posterior (marginal model): its ``settings`` give the density fitted to each record, and
        its draws the std ``σ`` the records' errors are compared with.
    estimate : mapping
        ``{label: value}`` [SI] of the estimate ``simulated`` holds, for every parameter of the posterior.
    records : int
        Records to simulate (each about 12 s on one core for 20 min at 256 Hz, with its extraction). When a
        ``pooled`` parameter's mode came out of at least one of them but of fewer than :data:`~twin.loop.pooling.MIN_RECORDS`,
        ``records`` more are simulated, up to :data:`~twin.defaults.MAX_BATCHES` batches in all: a mode the sensors
        hardly see may be found in one simulated record of six (per-mode FSI, the 17.1 Hz mode with its
        added mass estimated high), and without a factor its draws would stay uncalibrated.
    seed : int, optional
        Seed of the records' seeds (:func:`record_seeds`).
    pooled : sequence of str, optional
        The parameters whose RMS errors are shrunk towards their pooled value (:func:`~twin.loop.pooling.pooled_rms`): the
        ones the data determine (default: every parameter).
    simulate_options : mapping, optional
        More keywords of :func:`twin.fmu.simulate` (excitation, sensor noise); its defaults otherwise.
    tasks : optional
        Where the records run, one task each (:func:`twin.tasks.mapper`).

    Returns
    -------
    xarray.Dataset
        Over dimension (record, parameter): ``error`` ``θ_r - θ̂`` and ``laplace_std`` ``s_r`` [SI], and
        ``z`` = ``error / laplace_std``; NaN where a record's fit failed or lacks the parameter's mode.
        Over dimension parameter: ``records_used`` (the records whose fit has it); ``rms_error``
        ``sqrt(mean error²)``; ``posterior_std`` ``σ``, the std of ``posterior``'s draws;
        ``error_ratio`` ``rms_error / σ``; ``pooled_error_ratio``, that ratio shrunk towards the
        ``pooled`` parameters' common value (:func:`~twin.loop.pooling.pooled_rms`; attr ``between_parameter_variance``);
        ``factor``, ``pooled_error_ratio`` times :func:`~twin.loop.pooling.predictive_widening` of the records used; and
        ``rms_z`` ``sqrt(mean z²)``, a diagnostic (each record's error in its own std).
    """
    from twin.fmu.truth import model_state_space

    if int(records) != records or records < MIN_RECORDS:
        raise TwinError(f"bootstrap records must be an integer >= {MIN_RECORDS}, got {records}")
    settings = json.loads(posterior.attrs.get("settings", "{}"))
    duration_s, fs_hz, extraction = record_settings(modes)
    labels = posterior_labels(posterior)
    missing = [p for p in labels if p not in estimate]
    if missing:
        raise TwinError(f"the estimate lacks {', '.join(missing)}")
    records = int(records)
    seeds = record_seeds(seed, MAX_BATCHES * records)  # the first batch's seeds do not depend on MAX_BATCHES
    simulated = target_numbered(simulated, modes)
    members = np.ones(len(labels), dtype=bool) if pooled is None else np.isin(labels, list(pooled))
    run = mapper(tasks, progress=progress, desc="bootstrap records")
    reference = simulated_reference(model_state_space(simulated).poles, modes)
    shared = dict(
        simulated=simulated,
        model=model,
        settings=settings,
        duration_s=duration_s,
        fs_hz=fs_hz,
        extraction=extraction,
        reference=reference,
        simulate_options=dict(simulate_options or {}),
    )
    error, std = np.empty((0, len(labels))), np.empty((0, len(labels)))
    for batch in range(MAX_BATCHES):
        more = record_errors(run(_record_fit, seeds[len(error) : len(error) + records], **shared), labels, estimate)
        error, std = np.vstack([error, more[0]]), np.vstack([std, more[1]])
        z = error / std
        used = np.sum(np.isfinite(z), axis=0)
        short = members & (used > 0) & (used < MIN_RECORDS)
        if not short.any():
            break
        if batch + 1 < MAX_BATCHES:
            log.info(
                "bootstrap: %s seen on %s of %d records; %d more",
                ", ".join(np.array(labels)[short]),
                "/".join(map(str, used[short])),
                len(error),
                records,
            )
    seeds = seeds[: len(z)]
    if used.max(initial=0) < MIN_RECORDS:
        raise TwinError(
            f"the update's density was fitted on {used.max(initial=0)} of {len(z)} simulated records "
            f"(at least {MIN_RECORDS} are needed to calibrate)"
        )
    enough = np.where(used >= MIN_RECORDS, 1.0, np.nan)
    sampler_std = posterior_std(posterior)
    with np.errstate(invalid="ignore", divide="ignore"):
        rms = np.sqrt(np.nanmean(enough * z**2, axis=0))
        rms_error = np.sqrt(np.nanmean(enough * error**2, axis=0))
        ratio = np.where(sampler_std > 0, rms_error / sampler_std, np.nan)
    shrunk, tau2 = pooled_rms(ratio, used, members)
    factor = shrunk * predictive_widening(used)
    return xr.Dataset(
        {
            "z": (("record", "parameter"), z, {"long_name": "error of the record's estimate in its Laplace std"}),
            "error": (
                ("record", "parameter"),
                error,
                {"long_name": "the record's estimate minus the estimate simulated", "units": "SI (the parameter's)"},
            ),
            "laplace_std": (
                ("record", "parameter"),
                std,
                {"long_name": "the record's Laplace std", "units": "SI (the parameter's)"},
            ),
            "rms_z": (
                "parameter",
                rms,
                {"long_name": "RMS z over the records, each record's error in its own std (a diagnostic)"},
            ),
            "rms_error": (
                "parameter",
                rms_error,
                {"long_name": "RMS error over the records", "units": "SI (the parameter's)"},
            ),
            "posterior_std": (
                "parameter",
                sampler_std,
                {"long_name": "the std of the posterior's draws", "units": "SI (the parameter's)"},
            ),
            "error_ratio": ("parameter", ratio, {"long_name": "RMS error over the records in the posterior's std"}),
            "pooled_error_ratio": (
                "parameter",
                shrunk,
                {
                    "long_name": "error_ratio shrunk towards the pooled "
                    "parameters' common value (empirical Bayes, on its log "
                    "square)"
                },
            ),
            "factor": (
                "parameter",
                factor,
                {
                    "long_name": "the posterior std's calibration: the pooled error "
                    "ratio times the Student t widening of a variance from that many "
                    "records"
                },
            ),
            "records_used": ("parameter", used),
        },
        coords={"record": seeds, "parameter": labels},
        attrs={
            "duration_s": duration_s,
            "fs_hz": fs_hz,
            "extraction": json.dumps(extraction),
            "between_parameter_variance": tau2,
            "pooled": json.dumps([str(p) for p in np.array(labels)[members]]),
            "description": "parametric bootstrap at the posterior's estimate (twin.loop.bootstrap)",
        },
    )


def record_errors(
    fits: Sequence[Mapping[str, tuple[float, float]] | str], labels: Sequence[str], estimate: Mapping[str, float]
) -> tuple[np.ndarray, np.ndarray]:
    """Each record's error ``θ_r - θ̂`` and its Laplace std ``s_r`` [SI], (record, parameter); NaN where the
    fit failed (a string, logged) or lacks the parameter.

    Examples
    --------
    >>> error, std = record_errors([{"k": (3.0, 2.0)}, "record 7: no mode", {}], ["k"], {"k": 1.0})
    >>> (error / std).ravel().tolist()
    [1.0, nan, nan]
    """
    error, std = np.full((len(fits), len(labels)), np.nan), np.full((len(fits), len(labels)), np.nan)
    for r, fit in enumerate(fits):
        if isinstance(fit, str):
            log.warning("bootstrap %s", fit)
            continue
        for k, label in enumerate(labels):
            if label in fit and fit[label][1] > 0:
                error[r, k], std[r, k] = fit[label][0] - estimate[label], fit[label][1]
    return error, std


def posterior_std(posterior: xr.DataTree) -> np.ndarray:
    """The std of each parameter's draws over every chain [SI], in the order of :func:`posterior_labels`.

    Examples
    --------
    >>> import xarray as xr
    >>> post = xr.Dataset({"theta": (("chain", "draw", "parameter"), [[[1.0], [3.0]], [[1.0], [3.0]]])},
    ...                   coords={"parameter": ["k"]})
    >>> posterior_std(xr.DataTree.from_dict({"posterior": post})).tolist()
    [1.0]
    """
    from twin.update.posterior import parameter_draws

    return parameter_draws(posterior["posterior"].to_dataset()).std(("chain", "draw")).values


def posterior_labels(posterior: xr.DataTree) -> list[str]:
    """The posterior's parameter labels: shared ones, then ``FSI.<kind>_<mode>`` mode by mode."""
    from twin.update.posterior import parameter_draws

    return [str(p) for p in parameter_draws(posterior["posterior"].to_dataset())["parameter"].values]


def calibrated(posterior: xr.DataTree, factors: xr.Dataset, determined: Sequence[str]) -> xr.DataTree:
    """The posterior with the draws of each ``determined`` parameter stretched about their mean by its factor.

    Parameters without a finite factor, or not determined, are left alone. The applied factors are in the
    attr ``bootstrap_calibration`` (``{label: factor}``), the records' seeds in ``bootstrap_records``
    and ``factors`` itself (each record's errors, :func:`bootstrap_factors`) in the group ``bootstrap``;
    the summary diagnostics are recomputed.

    Examples
    --------
    >>> import numpy as np, xarray as xr
    >>> post = xr.Dataset({"theta": (("chain", "draw", "parameter"), [[[1.0], [3.0]]])}, coords={"parameter": ["k"]})
    >>> tree = xr.DataTree.from_dict({"/": xr.Dataset(), "posterior": post})
    >>> f = xr.Dataset({"factor": ("parameter", [2.0])}, coords={"parameter": ["k"], "record": [5, 6]})
    >>> calibrated(tree, f, ["k"])["posterior"]["theta"].values.ravel().tolist()
    [0.0, 4.0]
    """
    from twin.update.posterior import stretch

    applied = {}
    for p, c in zip(factors["parameter"].values, factors["factor"].values):
        if str(p) in determined and np.isfinite(c) and c > 0:
            applied[str(p)] = float(c)
    post = posterior["posterior"].to_dataset()
    labels = {"theta": [str(p) for p in post["parameter"].values] if "theta" in post else []}
    for kind in ("added_mass", "added_damping"):
        labels[kind] = [f"FSI.{kind}_{int(m)}" for m in post["mode"].values] if kind in post else []
    for name, names in labels.items():
        if names:  # draws (chain, draw, parameter or mode): one factor along the last axis
            f = np.array([applied.get(n, 1.0) for n in names])
            post[name] = post[name].copy(
                data=stretch(post[name].values.reshape(-1, len(f)), f).reshape(post[name].shape)
            )
    tree = posterior.copy()
    tree["posterior"] = xr.DataTree(post)
    tree.attrs["bootstrap_calibration"] = json.dumps({k: round(v, 4) for k, v in applied.items()})
    tree.attrs["bootstrap_records"] = json.dumps([int(s) for s in factors["record"].values])
    tree["bootstrap"] = xr.DataTree(factors)
    if "diagnostics" in tree.attrs:
        from twin.update.posterior import diagnostics_json, summary

        tree.attrs["diagnostics"] = diagnostics_json(summary(post))
    return tree
