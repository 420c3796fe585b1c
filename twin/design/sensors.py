"""Where to add proximeters: greedy sensor design on mode observability and parameter identifiability.

Every candidate node gets a pair of proximeters (x and y). One state-space
eigen-solution of the system seen by *all* candidates serves every layout: a
layout is a subset of the output rows (:meth:`Spectrum.select`), and the
parameter Jacobian on any subset follows from one set of finite-difference
modes (:class:`~twin.design.identify.ModalPerturbations`). The sensor noise
[m] is the current layout's and stays the same on every added sensor.

Each step adds the pair that ranks first on, in order,

1. the number of target modes observable (:func:`twin.design.observability`'s rule);
2. with parameters: the number determined (expected std below 10% of the scale);
3. the D-optimal criterion: with parameters, ``−½ log det`` of their expected
   posterior covariance relative to their scales (a unit-scale prior keeps
   the directions no layout reaches finite and equal across layouts), per
   parameter; without, the mean over target modes of ``−log`` of the
   frequency and damping stds relative to their limits (the modal parameters'
   own D-criterion).

The gain of a pair is the change of each of the three.

The record covariance of a mode is its Cramér-Rao bound raised by the ratio
of its single-mode bound to its Cramér-Rao bound
(:func:`twin.design.identify.record_covariance`), that ratio taken once on the
layout the design starts from and kept for every layout judged: judged on each
layout, it grows as pairs are added (the Cramér-Rao bound falls faster than
the single-mode one), and a parameter's expected std could rise with a pair
added although the record holds more information.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np
import xarray as xr

from twin import __version__
from twin.design.identify import (
    DETERMINED_LIMIT,
    fisher_covariance,
    judged_columns,
    linearisation,
    modal_perturbations,
    record_data,
    record_ratio,
)
from twin.design.observe import (
    DAMPING_STD_LIMIT,
    FREQUENCY_STD_LIMIT,
    band_top,
    SNR_LIMIT_DB,
    mode_bounds,
    mode_prominence,
    mode_snr,
    target_modes,
    verdicts,
)
from twin.design.spectrum import Excitation, spectrum
from twin.errors import ModelError
from twin.fem.model import RotorModel, Sensor
from twin.fem.truthfile import Truth
from twin.modes.analysis import damping_ratio
from twin.netcdf import atomic_output
from twin.progress import bar

log = logging.getLogger(__name__)


def candidate_nodes(model: RotorModel, candidates: Sequence[int] | None = None) -> list[int]:
    """The nodes a pair may go to: ``candidates``, or every node without a sensor.

    Examples
    --------
    >>> m = hydro_unit
    >>> 2 in candidate_nodes(m), len(candidate_nodes(m)) == m.n_nodes - 4
    (False, True)
    """
    taken = {s.node for s in model.sensors}
    if candidates is None:
        return [n for n in range(model.n_nodes) if n not in taken]
    out = []
    for n in candidates:
        if not (isinstance(n, (int, np.integer)) and 0 <= n < model.n_nodes):
            raise ModelError(f"candidate node {n!r}: the model '{model.name}' has nodes 0..{model.n_nodes - 1}")
        if n in taken:
            raise ModelError(
                f"candidate node {n}: it already has a sensor "
                f"({', '.join(s.name for s in model.sensors if s.node == n)})"
            )
        if n not in out:
            out.append(int(n))
    if not out:
        raise ModelError("no candidate node to add a sensor to")
    return out


def sensor_name(model: RotorModel, node: int) -> str:
    """A name for a pair at ``node`` not used by the model: ``N<node>`` (``N<node>b``, ... if taken)."""
    used = {s.name.rsplit("_", 1)[0] for s in model.sensors}
    name, extra = f"N{node}", 0
    while name in used:
        extra += 1
        name = f"N{node}{chr(ord('a') + extra)}"
    return name


def _pair(model: RotorModel, node: int) -> list[Sensor]:
    name = sensor_name(model, node)
    where = f"node {node}, z = {model.node_z[node]:.3f} m (added by twin sensors)"
    return [Sensor(f"{name}_{d}", node, d, where) for d in "xy"]


def design_sensors(
    model: RotorModel,
    add: int,
    *,
    candidates: Sequence[int] | None = None,
    names: Sequence[str] = (),
    fsi: bool = False,
    excitation: Excitation | None = None,
    truth: Truth | None = None,
    fmax_hz: float | None = None,
    progress: bool = True,
    command: str = "",
) -> xr.Dataset:
    """Choose ``add`` proximeter pairs, one at a time, on the criterion of the module docstring.

    Parameters
    ----------
    model : RotorModel
        Its sensors are the layout to extend.
    add : int
        Number of pairs to add.
    candidates : sequence of int, optional
        Nodes a pair may go to (default: every node without a sensor).
    names : sequence of str
        Parameters that should be determined (any of the model's).
    fsi : bool
        Also per-mode added mass and damping of every observable mode.
    excitation : Excitation, optional
        Record judged (default: 20 min, ``twin simulate``'s excitation); its noise std is
        fixed from the current layout.
    truth : Truth, optional
        Judge the truth's system (and linearise there).
    fmax_hz : float, optional
        Highest target frequency [Hz] (default 100 Hz, at most 0.4 fs).

    Returns
    -------
    xarray.Dataset
        Over ``step`` (0: the current layout, then one per added pair): ``node``, ``sensor``,
        ``location``, ``n_observable``, ``n_determined``, ``criterion``; over ``(step, mode)``:
        ``observable``, ``frequency_rel_std``, ``damping_rel_std``, ``best_snr_db``; with
        parameters, over ``(step, parameter)``: ``relative_std``. Attrs: the noise std [m]
        to simulate the new layout with, the excitation and the candidates.

    Examples
    --------
    >>> d = design_sensors(hydro_unit, 1, candidates=[12, 20], progress=False)
    >>> int(d.sizes["step"]), int(d.node[1]) in (12, 20)
    (2, True)
    """
    from twin.fmu.simulate import system_for

    if not (isinstance(add, (int, np.integer)) and add >= 1):
        raise ModelError(f"the number of pairs to add must be a positive integer, got {add!r}")
    if not model.sensors:
        raise ModelError(f"model '{model.name}' declares no [[sensor]]: give it at least one to extend")
    for n in names:
        model.parameter(n)  # an unknown name is named
    nodes = candidate_nodes(model, candidates)
    if add > len(nodes):
        raise ModelError(f"{add} pairs asked for, but only {len(nodes)} candidate nodes")
    excitation = excitation or Excitation()
    excitation.check()
    top = band_top(fmax_hz, excitation)
    noise_std = spectrum(system_for(model, truth, "full", None), model, excitation).noise_std_m
    fixed = replace(excitation, noise_std_m=noise_std)

    pairs = {n: _pair(model, n) for n in nodes}
    everything = replace(model, sensors=list(model.sensors) + [s for n in nodes for s in pairs[n]])
    sp = spectrum(system_for(everything, truth, "full", None), everything, fixed)
    targets = target_modes(sp.poles, top)
    lam = sp.poles[targets]
    freq, zeta = lam.imag / (2 * np.pi), damping_ratio(lam)
    n_now = len(model.sensors)
    rows_of = {n: [n_now + 2 * j, n_now + 2 * j + 1] for j, n in enumerate(nodes)}

    pert = None
    if names or fsi:
        base, ident_targets, fsi_values = linearisation(everything, truth, fsi, top)
        pert = modal_perturbations(base, names, list(ident_targets), fsi=fsi, fsi_values=fsi_values)

    # SSI's distance above the Cramer-Rao bound, per mode, from the layout the design starts from
    ratios: dict[int, float] = {}
    if pert is not None:
        now = sp.select(list(range(n_now)))
        for k in map(int, targets):
            if (r := record_ratio(now, k, fixed.duration_s)) is not None:
                ratios[k] = r

    prominence_all = mode_prominence(sp, targets)  # a channel's own: the same in any layout

    def judge(rows: list[int]) -> dict:
        sub = sp.select(rows)
        snr, f_std, z_std, _, _ = mode_bounds(sub, targets, fixed.duration_s, crb=False)
        best = snr.max(axis=1)
        prominence = prominence_all[:, rows].max(axis=1)
        observable, _ = verdicts(best, f_std / freq, z_std / zeta, prominence)
        out = {
            "observable": observable,
            "f_rel": f_std / freq,
            "z_rel": z_std / zeta,
            "snr": best,
            "prominence": prominence,
            "n_observable": int(observable.sum()),
        }
        if pert is None:
            rel = np.clip([f_std / (FREQUENCY_STD_LIMIT * freq), z_std / (DAMPING_STD_LIMIT * zeta)], 1e-6, 1e6)
            margin = -0.5 * np.log(rel).sum(axis=0)  # a mode the layout is blind to counts as std = 10^6 limits
            out.update(n_determined=0, criterion=float(np.mean(margin)))
            return out
        used, precisions = record_data(pert.poles, sub, freq, observable, fixed.duration_s, ratios)
        rel = np.full(len(pert.columns), np.inf)
        if used:
            keep = judged_columns(len(names), len(pert.poles), used, fsi)
            J = pert.jacobian(rows)[used][:, :, keep]
            cov = fisher_covariance(J, precisions, pert.scales[keep])
            rel[keep] = np.sqrt(np.clip(np.diag(cov), 0, None)) / pert.scales[keep]
            prior = fisher_covariance(J, precisions, pert.scales[keep], prior_std=pert.scales[keep])
            rel_prior = prior / np.outer(pert.scales[keep], pert.scales[keep])
            # columns not judged keep their unit prior: log det contribution 0
            criterion = -0.5 * np.linalg.slogdet(rel_prior)[1] / len(pert.columns)
        else:
            criterion = 0.0
        out.update(relative_std=rel, n_determined=int(np.sum(rel < DETERMINED_LIMIT)), criterion=float(criterion))
        return out

    def rank(r: dict) -> tuple:
        return (r["n_observable"], r["n_determined"], r["criterion"])

    layout = list(range(n_now))
    steps = [judge(layout)]
    chosen: list[int] = []
    left = list(nodes)
    for _ in bar(range(add), progress=progress, desc="sensor design", unit="pair"):
        results = {n: judge(layout + rows_of[n]) for n in left}
        best = max(left, key=lambda n: rank(results[n]))
        chosen.append(best)
        left.remove(best)
        layout += rows_of[best]
        steps.append(results[best])
        log.info(
            "pair %d at node %d: %d modes observable, %d parameters determined, criterion %.3f",
            len(chosen),
            best,
            steps[-1]["n_observable"],
            steps[-1]["n_determined"],
            steps[-1]["criterion"],
        )

    # where each mode is seen best over every candidate, and the noise that would make its peak enough
    def best_channel(per_channel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per mode, the node of the channel (current or candidate) where ``per_channel`` is largest, and that value."""
        row = np.argmax(per_channel, axis=1)
        return np.array([everything.sensors[r].node for r in row]), per_channel[np.arange(len(targets)), row]

    best_node, best_snr = best_channel(mode_snr(sp, targets))
    noise_needed = noise_std * 10 ** ((best_snr - SNR_LIMIT_DB) / 20)
    # the other modes' response alone
    best_prominence_node, best_prominence = best_channel(mode_prominence(replace(sp, noise_psd=1e-300), targets))

    def stack(key: str) -> np.ndarray:
        return np.array([r[key] for r in steps])

    data = {
        "node": ("step", np.array([-1] + chosen), {"long_name": "node of the added pair (-1: the current layout)"}),
        "sensor": ("step", [""] + [pairs[n][0].name.rsplit("_", 1)[0] for n in chosen]),
        "location": ("step", [""] + [pairs[n][0].location for n in chosen]),
        "n_observable": ("step", stack("n_observable"), {"long_name": "target modes observable"}),
        "n_determined": ("step", stack("n_determined"), {"long_name": "parameters determined"}),
        "criterion": ("step", stack("criterion"), {"long_name": "D-optimal criterion (see twin.design.sensors)"}),
        "observable": (("step", "mode"), stack("observable")),
        "frequency_rel_std": (
            ("step", "mode"),
            stack("f_rel"),
            {"units": "1", "long_name": "expected frequency std / frequency"},
        ),
        "damping_rel_std": (
            ("step", "mode"),
            stack("z_rel"),
            {"units": "1", "long_name": "expected damping std / damping ratio"},
        ),
        "best_snr_db": (("step", "mode"), stack("snr"), {"units": "dB"}),
        "best_prominence_db": (
            ("step", "mode"),
            stack("prominence"),
            {"units": "dB", "long_name": "peak against the other modes' response and the noise, best channel"},
        ),
        "most_prominent_node": (
            "mode",
            best_prominence_node,
            {"long_name": "node (current or candidate) where the mode stands out most from the other modes' response"},
        ),
        "most_prominent_db": (
            "mode",
            best_prominence,
            {"units": "dB", "long_name": "its prominence there without sensor noise"},
        ),
        "best_node": ("mode", best_node, {"long_name": "node (current or candidate) where the mode's peak is highest"}),
        "best_node_snr_db": ("mode", best_snr, {"units": "dB", "long_name": "peak-to-noise ratio there"}),
        "noise_std_needed_m": (
            "mode",
            noise_needed,
            {
                "units": "m",
                "long_name": f"sensor noise std at which the peak there is {SNR_LIMIT_DB:g} dB above the noise",
            },
        ),
    }
    coords = {
        "step": np.arange(add + 1),
        "mode": np.arange(1, len(targets) + 1),
        "frequency": ("mode", freq, {"units": "Hz"}),
    }
    if pert is not None:
        data["relative_std"] = (
            ("step", "parameter"),
            stack("relative_std"),
            {"units": "1", "long_name": "expected posterior std / scale (inf: not judged)"},
        )
        coords["parameter"] = pert.columns
    settings = {**fixed.__dict__, "fmax_hz": top}
    return xr.Dataset(
        data,
        coords=coords,
        attrs={
            "title": f"sensor design for {model.name}",
            "producer": f"twin {__version__} twin.design.sensors",
            "model": model.name,
            "model_source": model.source,
            "command": command,
            "noise_std_m": noise_std,
            "excitation": json.dumps(settings),
            "candidates": json.dumps(nodes),
            "parameters": json.dumps(list(names)),
            "fsi": int(fsi),
            "method": "greedy: most modes observable, then most parameters determined, then D-optimal",
            **({"truth": truth.to_json()} if truth is not None else {}),
        },
    )


def sensor_entries(design: xr.Dataset) -> str:
    """The ``[[sensor]]`` tables of the pairs a design adds, as model-file text."""
    blocks = []
    for step in range(1, design.sizes["step"]):
        r = design.isel(step=step)
        blocks.append(
            f'[[sensor]]\nname = "{str(r.sensor.values)}"\nnode = {int(r.node)}\n'
            f'location = "{str(r.location.values)}"\n'
        )
    return "\n".join(blocks)


def write_layout(model: RotorModel, design: xr.Dataset, path: str | Path) -> Path:
    """Write ``model``'s file with the design's pairs appended as ``[[sensor]]`` entries; check it loads.

    Examples
    --------
    >>> import tempfile
    >>> from twin import load_model
    >>> m = hydro_unit
    >>> d = design_sensors(m, 1, candidates=[12], progress=False)
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     new = load_model(write_layout(m, d, f"{tmp}/unit.toml"))
    >>> new.channels[-2:]
    ['N12_x', 'N12_y']
    """
    from twin.fem import load_model

    if not model.source or not Path(model.source).is_file():
        raise ModelError(f"model '{model.name}' was not read from a file: there is no model file to extend")
    if design.attrs.get("model") != model.name:
        raise ModelError(f"the design is for model '{design.attrs.get('model')}', not '{model.name}'")
    text = Path(model.source).read_text()
    added = sensor_entries(design)
    header = (
        f"\n# Sensors added by twin sensors ({design.attrs['method']}); simulate this layout with "
        f"--noise-std {design.attrs['noise_std_m']:.4g} to keep the sensors' noise.\n"
    )
    with atomic_output(path, suffix=".toml") as part:
        part.write_text(text.rstrip("\n") + "\n" + header + added)
        new = load_model(part)
        have = {s.name for s in new.sensors}
        missing = [f"{s}_{d}" for s in design.sensor.values[1:] for d in "xy" if f"{s}_{d}" not in have]
        if missing:
            raise ModelError(f"the written model file does not declare the added channels {missing}")
    return Path(path)
