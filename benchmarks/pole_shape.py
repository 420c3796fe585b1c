"""How a mode's pole and shape errors combine on the twin's own data: correlated, and what that does to the update.

For each scenario and seed (the FMU records of ``update_coverage_fmu.py``: 20-min records, default
extraction) and each added parameter, one at a time with the others at their truth, the update's data are
linearised about the truth: per mode, the parameter's estimate from the mode's shapes alone (their mean
against the truth's, weighted by the update's shrunk shape covariance) and from its pole alone (the pole
samples' covariance), each in its own stds (``z``). Over the records this gives each mode's information
from either, the RMS of each ``z``, and the correlation of the two errors, beside the correlation the
mode's own samples show (median over records); and the RMS ``z`` of the estimates from every mode's shapes,
every pole, and both taken as independent. Beside the error along the parameter, the error in every
direction: the mean over the records of the shape error's chi-square at the truth (the same covariance)
per degree of freedom (its entries that scatter less the unit norm's one), and of the pole's (both parts)
per part. A chi-square per degree of freedom near one with an RMS ``z`` well above one puts the excess
error along the parameter's own direction, where a mode's residual after the fit cannot show it.

Then each record is updated twice (:meth:`twin.loop.twin.Twin.update`, defaults otherwise): with each mode's
pole and shape errors combined by covariance intersection (``combine="intersection"``, the default) and as
independent (``"independent"``): RMS ``z`` (the std from the 90% interval's width) and 90% coverage.

    python benchmarks/pole_shape.py [--scenarios seal_cross_coupling,magnetic_pull] [--seeds 24]
                                    [--first-seed 601] [--workers 2] [--duration 1200] [--rows rows.json]
                                    [--streams {fmu,numpy}]
                                    [the extraction flags of update_coverage_fmu.py: --delete-half ...]

Results go to ``benchmarks/results/pole_shape.md``.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
from update_coverage_fmu import dataset_benchmark, scenario_order, scenario_record

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "benchmarks" / "results" / "pole_shape.md"
#: The standard normal's 95% point: a 90% interval is 2 of these stds wide.
Z95 = 1.6448536269514722
#: Relative step of the central differences of the truth's modes in each parameter.
STEP = 0.02
#: The update's two ways of combining a mode's pole and shape errors.
COMBINATIONS = ("intersection", "independent")


def stacked(shapes: np.ndarray) -> np.ndarray:
    """Complex shapes (last axis) as real numbers: real parts, then imaginary parts."""
    return np.concatenate([shapes.real, shapes.imag], axis=-1)


def truth_modes(tw, values: dict[str, float]) -> tuple[np.ndarray, np.ndarray]:
    """The model's partners of the measured modes at ``values``: stacked normalised shapes on the sensors
    ``(mode, 2 channels)`` and poles as ``(mode, [Re, Im])``."""
    from twin.extract.samples import normalise_at
    from twin.loop.compare import model_modes
    from twin.modes.measured import channel_dofs

    partners = model_modes(tw.model, tw.measured, values)
    reference = [tw.measured.channels.index(str(c)) for c in tw.modes["reference_channel"].values]
    shapes = normalise_at(partners.shapes[:, channel_dofs(tw.model, tw.measured.channels)], np.array(reference))
    return stacked(shapes), np.stack([partners.poles.real, partners.poles.imag], axis=-1)


def mode_terms(tw, truth: dict[str, float], name: str) -> list[dict]:
    """Per measured mode, the linearised estimates of ``name`` from the mode's shapes and from its pole."""
    from twin.update.shrinkage import scatters, shrunk_covariance

    shapes_t, poles_t = truth_modes(tw, truth)
    h = STEP * abs(truth[name])
    up, down = truth_modes(tw, {**truth, name: truth[name] + h}), truth_modes(tw, {**truth, name: truth[name] - h})
    g_shape, g_pole = [(a - b) / (2 * STEP) for a, b in zip(up, down)]  # per relative change of the parameter
    samples = stacked(tw.modes["shape"].transpose("mode", "sample", "channel").values)
    poles = tw.modes["pole"].transpose("mode", "sample").values
    J = samples.shape[1]
    out = []
    for i, (x, p) in enumerate(zip(samples, np.stack([poles.real, poles.imag], axis=-1))):
        moving = scatters(x.std(axis=0))
        x, g = x[:, moving], g_shape[i][moving]
        cov_s, cov_p = shrunk_covariance(x, x.var(axis=0, ddof=1)) / J, np.cov(p.T) / J
        w_s, w_p = np.linalg.solve(cov_s, g), np.linalg.solve(cov_p, g_pole[i])
        a_s, a_p = (x - x.mean(axis=0)) @ w_s, (p - p.mean(axis=0)) @ w_p
        e_s, e_p = x.mean(axis=0) - shapes_t[i][moving], p.mean(axis=0) - poles_t[i]
        out.append(
            {
                "frequency_hz": float(poles[i].mean().imag / (2 * np.pi)),
                "shape_a": float(w_s @ e_s),
                "shape_b": float(w_s @ g),
                "pole_a": float(w_p @ e_p),
                "pole_b": float(w_p @ g_pole[i]),
                "sample_corr": float(np.corrcoef(a_s, a_p)[0, 1]),
                "shape_chi2_dof": float(e_s @ np.linalg.solve(cov_s, e_s)) / (len(e_s) - 1),
                "pole_chi2_dof": float(e_p @ np.linalg.solve(cov_p, e_p)) / 2,
            }
        )
    return out


def one_dataset(
    job: tuple[str, int], duration_s: float, extraction: dict | None = None, streams: str = "fmu"
) -> list[dict]:
    """Simulate (``streams`` as :func:`update_coverage_fmu.scenario_record`'s) and extract one dataset
    (``extraction``: options of :func:`twin.extract.extract`); the linearised terms and the two updates; one row
    per parameter."""
    from twin.fem.effects import is_per_mode_name
    from twin.harness.demo import posterior_table

    name, seed = job
    tw, names, truth = scenario_record(job, duration_s, extraction, streams)
    if any(is_per_mode_name(n) for n in names):
        raise ValueError(f"{name}: per-mode parameters are not one shared direction; choose another scenario")
    tables = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for combine in COMBINATIONS:
            tables[combine] = posterior_table(tw.update(names, seed=seed, progress=False, combine=combine), tw.model)
        terms = {n: mode_terms(tw, truth, n) for n in names}
    rows = []
    for p in names:
        row = {"scenario": name, "seed": seed, "parameter": p, "truth": truth[p], "modes": terms[p]}
        for combine, table in tables.items():
            t = table.sel(parameter=p)
            row[combine] = {
                "map": float(t["map"]),
                "std": float(t["q95"] - t["q05"]) / (2 * Z95),
                "covered": bool(t["q05"] <= truth[p] <= t["q95"]),
            }
        rows.append(row)
    return rows


def rms(z) -> float:
    return float(np.sqrt(np.mean(np.square(z))))


def report(rows: list[dict]) -> list[str]:
    """Per parameter: each mode's line, then the records' RMS z of the linearised and the updated estimates."""
    lines = []
    for scenario, p in sorted({(r["scenario"], r["parameter"]) for r in rows}, key=lambda k: scenario_order(k[0])):
        sel = [r for r in rows if r["scenario"] == scenario and r["parameter"] == p]
        lines += [
            f"## {scenario}: {p} ({len(sel)} records)",
            "",
            "| mode [Hz] | records | information: shapes, pole | RMS z: shapes, pole, both independent | "
            "correlation of the shapes' and the pole's errors: over the records, in the samples | "
            "chi2 / dof in every direction: shapes, pole |",
            "| --- | --- | --- | --- | --- | --- |",
        ]
        centres = np.unique(np.round([m["frequency_hz"] for r in sel for m in r["modes"]], 0))
        for f in centres:
            ms = [min(r["modes"], key=lambda m: abs(m["frequency_hz"] - f)) for r in sel]
            ms = [m for m in ms if abs(m["frequency_hz"] - f) < 0.5]
            if len(ms) < 3:
                continue
            zs = np.array([m["shape_a"] / np.sqrt(m["shape_b"]) for m in ms])
            zp = np.array([m["pole_a"] / np.sqrt(m["pole_b"]) for m in ms])
            zb = [(m["shape_a"] + m["pole_a"]) / np.sqrt(m["shape_b"] + m["pole_b"]) for m in ms]
            lines.append(
                f"| {np.median([m['frequency_hz'] for m in ms]):.1f} | {len(ms)} | "
                f"{np.median([m['shape_b'] for m in ms]):.3g}, {np.median([m['pole_b'] for m in ms]):.3g} | "
                f"{rms(zs):.2f}, {rms(zp):.2f}, {rms(zb):.2f} | {np.corrcoef(zs, zp)[0, 1]:.2f}, "
                f"{np.median([m['sample_corr'] for m in ms]):.2f} | "
                f"{np.mean([m['shape_chi2_dof'] for m in ms]):.2f}, "
                f"{np.mean([m['pole_chi2_dof'] for m in ms]):.2f} |"
            )
        total = {
            k: np.array([[sum(m[f"{k}_{ab}"] for m in r["modes"]) for ab in "ab"] for r in sel])
            for k in ("shape", "pole")
        }
        z = {k: v[:, 0] / np.sqrt(v[:, 1]) for k, v in total.items()}
        both = (total["shape"][:, 0] + total["pole"][:, 0]) / np.sqrt(total["shape"][:, 1] + total["pole"][:, 1])
        lines += [
            "",
            f"Every mode, linearised: RMS z from the shapes {rms(z['shape']):.2f}, from the poles "
            f"{rms(z['pole']):.2f}, both as independent {rms(both):.2f}; correlation of the shapes' and the "
            f"poles' z over the records {np.corrcoef(z['shape'], z['pole'])[0, 1]:.2f}.",
            "",
        ]
        for combine in COMBINATIONS:
            zu = [(r[combine]["map"] - r["truth"]) / r[combine]["std"] for r in sel]
            lines.append(
                f"- update, `combine={combine!r}`: RMS z {rms(zu):.2f}, 90% interval covers "
                f"{np.mean([r[combine]['covered'] for r in sel]):.0%}, median std "
                f"{np.median([r[combine]['std'] / abs(r['truth']) for r in sel]):.2%} of the truth"
            )
        lines.append("")
    return lines


def main() -> None:
    dataset_benchmark(
        __doc__.splitlines()[0],
        "pole_shape.py",
        one_dataset,
        report,
        RESULTS,
        "A mode's pole and shape errors on FMU data",
        "",
        scenarios="seal_cross_coupling,magnetic_pull",
        seeds=24,
        first_seed=601,
    )


if __name__ == "__main__":
    main()
