"""Plain-text tables of a comparison, a diagnosis and a sweep (what the ``twin`` command prints)."""

from __future__ import annotations

import numpy as np
import xarray as xr

from twin.design.observe import target_lines
from twin.loop.compare import ERROR_WEIGHTS, error_text
from twin.loop.diagnose import LN_B_KEY, Diagnosis
from twin.harness.sweep import MAX_PARAMETER_ERROR, MAX_Z, MIN_FALL
from twin.modes.measured import Measured


def comparison_text(table: xr.Dataset) -> str:
    """The per-mode and per-sensor table of :func:`twin.loop.compare.compare`, and the error.

    Examples
    --------
    >>> from twin.loop.compare import compare
    >>> from twin.update import synthesize_modes
    >>> model = hydro_unit
    >>> print(comparison_text(compare(model, synthesize_modes(model, samples=20, seed=1))).splitlines()[-1])
    ... # doctest: +NORMALIZE_WHITESPACE
    error E = 1.91% (15 measured modes; RMS over the measured modes of |model pole - measured pole| / |measured pole|,
    real and imaginary parts weighed by the inverse variance of the measured pole; unweighted RMS 6.61%)
    """
    lines = [
        f"{table.attrs['title']}",
        f"{'mode':>4} {'f meas [Hz]':>11} {'f model [Hz]':>12} {'df [%]':>7} {'z_f':>7} "
        f"{'zeta meas [%]':>13} {'zeta model [%]':>14} {'dzeta [pp]':>10} {'z_zeta':>7} {'MAC':>6} {'|dl|/|l| [%]':>12}",
    ]
    for k in range(table.sizes["mode"]):
        r = table.isel(mode=k)
        lines.append(
            f"{int(r['mode']):>4} {float(r.measured_frequency):>11.4f} {float(r.model_frequency):>12.4f} "
            f"{100 * float(r.frequency_error):>+7.2f} {float(r.z_frequency):>+7.1f} "
            f"{100 * float(r.measured_damping_ratio):>13.3f} {100 * float(r.model_damping_ratio):>14.3f} "
            f"{100 * float(r.damping_error):>+10.3f} {float(r.z_damping):>+7.1f} {float(r.mac):>6.3f} "
            f"{100 * float(r.pole_error):>12.3f}"
        )
    poorly = list(np.atleast_1d(table.attrs.get("poorly_paired", [])))
    if poorly:
        lines.append(
            f"measured mode(s) {', '.join(map(str, poorly))}: the model has no mode like them (partner MAC < "
            f"{table.attrs['min_mac']:g}); they count in the error like the others"
        )
    lines += target_lines(table.attrs)
    lines.append(
        "shape error per sensor (RMS over modes, unit-norm shapes): "
        + ", ".join(f"{c} {float(v):.3f}" for c, v in zip(table["channel"].values, table["channel_shape_error"].values))
    )
    lines.append(ERROR_WEIGHTS + ".")
    lines.append(f"error {error_text(table)}")
    return "\n".join(lines)


def diagnosis_text(d: Diagnosis, meas: Measured) -> str:
    """The verdict, the ranking with its reasons, and where the model fails."""
    lines = [f"verdict: {d.verdict}" + (f" ({', '.join(d.missing)})" if d.missing else ""), d.summary, ""]
    if d.final is not None and d.missing:
        f = d.final
        lines += (
            ["joint fit of " + ", ".join(d.missing) + ":"]
            + [
                f"  {n} = {v:.4g} ± {s:.2g} {u}" + (" (on its physical bound)" if n in f.at_bound else "")
                for n, v, s, u in zip(f.names, f.values, f.std, f.units)
            ][:12]
            + [""]
        )
    for loc in d.locations[:3]:
        lines.append(f"outside the library: {loc.text()}")
    if d.locations:
        lines.append("")
    width = max([22] + [len(f.label) for f in d.ranking])
    lines += [
        "every candidate fitted alone (round 1):",
        f"{'rank':>4} {'effect':<{width}} {'ln B':>10} {'E before [%]':>12} {'E after [%]':>11}  parameters",
    ]
    for k, f in enumerate(d.ranking, start=1):
        if len(f.names) <= 4:
            params = ", ".join(f"{n} = {v:.3g} ± {s:.2g} {u}" for n, v, s, u in zip(f.names, f.values, f.std, f.units))
        else:
            params = f"{len(f.names)} parameters"
        lines.append(
            f"{k:>4} {f.label:<{width}} {f.log_bayes_factor:>10.1f} {100 * f.error_before(meas):>12.3f} "
            f"{100 * f.error_after(meas):>11.3f}  {params}"
        )
    lines += [LN_B_KEY, "", "why:"] + [f"  {d.explanations[f.label]}" for f in d.ranking]
    return "\n".join(lines)


def _named(row: xr.Dataset) -> str:
    """The effects a scenario's loop named, or the local change it pointed to, or ``-``."""
    named = str(row.missing.values)
    location = str(row["location"].values)
    return " + ".join(x for x in (named, f"at {location}" if location else "") if x) or "-"


def _interval(row: xr.Dataset) -> str:
    """A sweep row's 90% interval of E after the update, in percent ('-' without the sampler's posterior)."""
    if "error_after_low" not in row or not np.isfinite(float(row.error_after_low)):
        return "-"
    return f"{100 * float(row.error_after_low):.3f}-{100 * float(row.error_after_high):.3f}%"


def sweep_text(table: xr.Dataset) -> str:
    """One line per scenario of :func:`twin.harness.sweep.sweep`: verdict, error fall, parameter errors.

    Parameters whose truth is known show ``MAP / truth - 1`` and, in brackets,
    the posterior std relative to the truth.
    """
    width = max([22] + [len(str(h)) for h in table["hidden"].values])
    lines = [
        f"{'hidden':<{width}} {'seed':>4} {'verdict':<17} {'named':<34} {'lnB lead':>8} {'E before':>9} "
        f"{'E after':>8} {'its 90% interval':>17} {'fall':>6} {'time':>6} {'passed':<6} {'strict':<6} "
        "parameter errors (std)"
    ]
    names = table["parameter"].values
    for k in range(table.sizes["scenario"]):
        r = table.isel(scenario=k)
        rhat = r["r_hat"].values if "r_hat" in r else np.full(len(names), np.nan)
        errs = ", ".join(
            f"{n} {100 * float(e):+.1f}% ({100 * float(s) / abs(float(t)):.1f}%"
            + (f", R-hat {h:.3f}" if np.isfinite(h) else "")
            + ")"
            for n, e, s, t, h in zip(names, r.relative_error.values, r["std"].values, r.truth.values, rhat)
            if np.isfinite(e)
        )
        lines.append(
            f"{str(r.hidden.values):<{width}} {int(r.seed):>4} {str(r.verdict.values):<17} "
            f"{_named(r):<34} {float(r.lead):>8.1f} {100 * float(r.error_before):>8.3f}% "
            f"{100 * float(r.error_after):>7.3f}% {_interval(r):>17} {100 * float(r.fall):>5.1f}% "
            f"{float(r.elapsed_s):>5.0f}s "
            f"{'yes' if bool(r.passed) else 'NO':<6} {'yes' if bool(r.passed_strict) else 'NO':<6} {errs}"
        )
    n = table.sizes["scenario"]
    lines.append(
        f"{int(table['passed'].sum())} of {n} scenarios passed (the right diagnosis, error fall >= "
        f"{MIN_FALL:.0%}, parameters within {MAX_PARAMETER_ERROR:.0%} or {MAX_Z:g} std of the truth) in "
        f"{table.attrs.get('elapsed_s', np.nan):.0f} s; {int(table['passed_strict'].sum())} strictly "
        f"(every parameter within {MAX_PARAMETER_ERROR:.0%})"
    )
    if "q05" in table:
        known = np.isfinite(table["truth"].values) & np.isfinite(table["q05"].values)
        if known.any():
            truth = table["truth"].values[known]
            inside = (table["q05"].values[known] <= truth) & (truth <= table["q95"].values[known])
            line = (
                f"posteriors: the 90% interval covers the truth for {int(inside.sum())} of {int(known.sum())} "
                "identified parameters"
            )
            determined = table["determined"].values[known] != 0 if "determined" in table else np.ones(len(truth), bool)
            rhat = np.where(determined, table["r_hat"].values[known], np.nan)
            if np.isfinite(rhat).any():
                ess = table["ess_bulk"].values[known][determined]
                line += (
                    f"; of the {int(determined.sum())} the data determine, R-hat <= 1.01 for "
                    f"{int((rhat[np.isfinite(rhat)] <= 1.01).sum())} of {int(np.isfinite(rhat).sum())} sampled, "
                    f"bulk ESS median {np.nanmedian(ess):.0f}, least {np.nanmin(ess):.0f}"
                )
            if (~determined).any():
                line += (
                    f"; {int((~determined).sum())} reported as not determined by the data, their interval "
                    f"covering the truth for {int(inside[~determined].sum())}"
                )
            lines.append(line)
    if "chi2_after" in table and "map" in table:
        # after a right update the residual has n - p degrees of freedom (p fitted parameters)
        fitted = np.isfinite(table["map"].values).sum(axis=-1)
        updated = table["found"].values.astype(bool) & (fitted > 0)
        dof = table["n_data"].values[updated] - fitted[updated]
        if updated.any() and dof.sum() > 0:
            ratio = float(table["chi2_after"].values[updated].sum() / dof.sum())
            lines.append(
                f"calibration: chi2 / (n - p) after the update = {ratio:.2f} over the {int(updated.sum())} "
                "scenarios diagnosed right and updated (about 1 when the measured-pole uncertainty is "
                "honest)"
            )
    return "\n".join(lines)
