"""``report.html`` of a tracking: trends, the chart with its limit and alarms, followed changes, verdicts.

One self-contained page (figures embedded, :mod:`twin.report.html`) beside ``track.nc``:

* the measured frequency and damping ratio of each tracked mode over time, coloured by an operating
  condition, with the model's prediction at each record's operating point;
* what the conditions do not explain (the frequency residuals) and the chart's statistic against its limit,
  the alarms marked and the estimated onsets shaded;
* each followed parameter with its 5-95% interval and, for a simulated campaign, the truth the records
  carry in their attrs (read here for display only: the tracker never reads it);
* the verdict at each alarm.
"""

from __future__ import annotations

import html
import json
import logging
import tempfile
from pathlib import Path

import numpy as np
import xarray as xr

from twin.report.figures import pyplot
from twin.report.html import markdown_to_html
from twin.netcdf import atomic_output

log = logging.getLogger(__name__)


def record_truth(
    folder: str | Path, names: list[str], model, records: list[str] | None = None
) -> dict[str, np.ndarray] | None:
    """The hidden changes' values of parameters ``names`` per record of a simulated campaign, or None.

    Reads each record's ``truth`` attr (what ``twin campaign`` put there), for the file names ``records`` in
    their order (a track's ``record``, which is in time order; default every ``*.nc`` by name); a folder of
    measured records has none, and the report then shows no truth.
    """
    from twin.fem.truthfile import truth_from_json

    paths = [Path(folder) / r for r in records] if records is not None else sorted(Path(folder).glob("*.nc"))
    out = {n: np.zeros(len(paths)) for n in names}
    seen = False
    for i, path in enumerate(paths):
        try:
            with xr.open_dataset(path) as ds:
                text = ds.attrs.get("truth")
        except (OSError, ValueError):
            return None
        if not text:
            continue
        seen = True
        for effect in truth_from_json(text).effects:
            params = getattr(effect, "parameters", None)
            if params is None:
                continue
            for p in params(model):
                if p.name in out:
                    out[p.name][i] += p.nominal
    return out if seen else None


def _colour_condition(table: xr.Dataset, colour_by: str | None) -> str:
    names = [str(c) for c in table.condition.values]
    if colour_by is not None and colour_by not in names:
        raise ValueError(f"colour_by {colour_by!r} is not one of the operating conditions {names}")
    return colour_by or names[0]


def _trends(table: xr.Dataset, colour_by: str, path: Path, quantity: str) -> None:
    plt = pyplot()
    m = table.sizes["mode"]
    cols = min(3, m)
    rows = -(-m // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 2.5 * rows), sharex=True, squeeze=False)
    day = table.day.values
    c = table.operating_point.sel(condition=colour_by).values
    units = str(table.condition_units.sel(condition=colour_by).values)
    scatter = None
    for i, ax in enumerate(axes.flat):
        if i >= m:
            ax.set_visible(False)
            continue
        if quantity == "frequency":
            y = table.frequency.values[:, i]
            ax.plot(
                *_broken(table, day, table.predicted_frequency.values[:, i]),
                color="0.6",
                lw=0.8,
                label="model at the point",
            )
            ax.set_ylabel("Hz")
        else:
            y = 100 * table.damping_ratio.values[:, i]
            ax.set_ylabel("%")
        scatter = ax.scatter(day, y, c=c, s=6, cmap="viridis")
        ax.set_title(f"mode {i + 1} ({float(table.model_frequency.values[i]):.2f} Hz)", fontsize=9)
        for d in np.atleast_1d(table.alarm_day.values):
            ax.axvline(d, color="tab:red", lw=0.8)
        _shade_gaps(table, [ax])
    for ax in axes[-1]:
        ax.set_xlabel("days")
    if scatter is not None:
        fig.colorbar(scatter, ax=axes, shrink=0.6, label=f"{colour_by} [{units}]")
    fig.suptitle(f"measured {'frequency' if quantity == 'frequency' else 'damping ratio'} by {colour_by}")
    fig.savefig(path, dpi=90)
    plt.close(fig)


def _chart(table: xr.Dataset, path: Path) -> None:
    plt = pyplot()
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
    day = table.day.values
    res = table.residual.sel(part="imag").values / (2 * np.pi) * 1e3
    for i in range(table.sizes["mode"]):
        top.plot(day, res[:, i], ".", ms=3, label=f"mode {i + 1}")
    top.set_ylabel("frequency residual [mHz]")
    top.legend(fontsize=7, ncol=5)
    stat = np.maximum(table.statistic.values, 1e-3)
    bottom.semilogy(*_broken(table, day, stat), ".-", ms=3, lw=0.6, label="statistic")
    if "directed" in table:  # the step statistics share the limit's line: each over its own limit, times this one
        steps = np.maximum(table.directed.values * float(table.limit), 1e-3)
        bottom.semilogy(
            *_broken(table, day, steps), ".-", ms=2, lw=0.5, color="tab:green", label="step along a change (scaled)"
        )
    _shade_gaps(table, [bottom, top], label=True)
    bottom.axhline(float(table.limit), color="tab:red", ls="--", label="limit")
    bottom.axvspan(day[0], float(table.attrs.get("baseline_days", 0.0)), color="0.9", label="baseline")
    for d, k in zip(np.atleast_1d(table.alarm_day.values), np.atleast_1d(table.alarm_onset_day.values)):
        for ax in (top, bottom):
            ax.axvspan(k, d, color="tab:red", alpha=0.12)
            ax.axvline(d, color="tab:red", lw=0.8)
    bottom.set_ylabel("chart statistic")
    bottom.set_xlabel("days")
    bottom.legend(fontsize=8)
    fig.savefig(path, dpi=90)
    plt.close(fig)


def _parameters(table: xr.Dataset, truth: dict[str, np.ndarray] | None, path: Path) -> None:
    plt = pyplot()
    names = [str(n) for n in table.tracked_parameter.values]
    fig, axes = plt.subplots(len(names), 1, figsize=(10, 2.6 * len(names)), sharex=True, squeeze=False)
    day = table.day.values
    for ax, name in zip(axes[:, 0], names):
        v = table.parameter.sel(tracked_parameter=name).values
        lo = table.parameter_low.sel(tracked_parameter=name).values
        hi = table.parameter_high.sel(tracked_parameter=name).values
        d, v, lo, hi = _broken(table, day, v, lo, hi)
        ax.fill_between(d, lo, hi, color="tab:blue", alpha=0.25, lw=0, label="5-95%")
        ax.plot(d, v, color="tab:blue", lw=1, label="followed")
        _shade_gaps(table, [ax])
        if truth is not None and name in truth and len(truth[name]) == len(day):
            ax.plot(*_broken(table, day, truth[name]), color="k", ls="--", lw=1, label="truth (simulated)")
        ax.set_ylabel(name, fontsize=8)
        ax.legend(fontsize=7)
    axes[-1, 0].set_xlabel("days")
    fig.savefig(path, dpi=90)
    plt.close(fig)


def report_markdown(table: xr.Dataset, truth: dict[str, np.ndarray] | None, colour_by: str) -> str:
    """The report's text (Markdown) for the figures ``frequency.png``, ``damping.png``, ``chart.png``,
    ``parameters.png`` (the last only when a change is followed)."""
    n = table.sizes["time"]
    lines = [
        "# Tracking report",
        "",
        (
            f"{n} records from {table.attrs.get('first_record', '')} over {float(table.day.values[-1]):.2f} days; "
            f"baseline {float(table.attrs.get('baseline_days', 0)):g} days; {table.sizes['mode']} tracked modes; "
            f"control limit {float(table.limit):.1f} for {float(table.attrs.get('false_alarms_per_year', np.nan)):g} "
            "false alarms per year."
        ),
        "",
        "## Alarms",
        "",
    ]
    set_aside = json.loads(table.attrs.get("set_aside", "[]"))
    if monitored_records(table) == 0:
        lines.append(
            f"No record monitored yet: every record is in the {float(table.attrs['baseline_days']):g}-day baseline, "
            "which sets the chart; an alarm can come only from the records after it."
        )
    elif table.sizes.get("alarm", 0) == 0:
        lines.append("No alarm: what the operating conditions do not explain stayed within the control limit.")
    else:
        lines += [
            "| time (UTC) | day | onset day | effect | named on day | verdict |",
            "| --- | --- | --- | --- | --- | --- |",
        ]
        named_day = table.get("alarm_named_day", xr.full_like(table.alarm_day, np.nan)).values
        for i in range(table.sizes["alarm"]):
            t = np.datetime_as_string(table.alarm_time.values[i], unit="s")
            effect = str(table.alarm_effect.values[i]) if bool(table.alarm_named.values[i]) else "(not named)"
            verdict = html.escape(str(table.alarm_verdict.values[i])).replace("|", "\\|")
            named = "not yet" if np.isnan(named_day[i]) else f"{named_day[i]:.2f}"
            lines.append(
                f"| {t} | {float(table.alarm_day.values[i]):.2f} | "
                f"{float(table.alarm_onset_day.values[i]):.2f} | {effect} | {named} | {verdict} |"
            )
    gaps = record_gaps(table)
    if gaps:
        lines += [
            "",
            "## Gaps in the records",
            "",
            "Times without records (hatched in the figures; the chart goes on across them, so a change made "
            "during a gap shows as a step at the first record after it):",
            "",
            "| last record before (UTC) | first record after (UTC) | days |",
            "| --- | --- | --- |",
        ]
        lines += [f"| {g['from']} | {g['to']} | {g['days']:.2f} |" for g in gaps]
    if set_aside:
        lines += ["", "## Records set aside", "", "| record | why |", "| --- | --- |"]
        lines += [f"| {html.escape(a['file'])} | {html.escape(a['reason'])} |" for a in set_aside]
    lines += [
        "",
        f"## Trends, coloured by {colour_by}",
        "",
        '<img src="frequency.png">',
        "",
        '<img src="damping.png">',
        "",
        "## What the operating conditions do not explain",
        "",
        (
            "Frequency residuals after the learned laws and the followed changes, and the chart's statistic "
            "(MEWMA) against its limit, beside the largest step statistic along a candidate change scaled to "
            "the same limit; alarms in red, from the estimated onset."
        ),
        "",
        '<img src="chart.png">',
    ]
    if "tracked_parameter" in table.dims:
        lines += [
            "",
            "## Followed changes",
            "",
            "Each named change, updated from the records since its onset and followed record by record "
            "(5-95% intervals)" + ("; the dashed line is the simulated campaign's truth." if truth else "."),
            "",
            '<img src="parameters.png">',
        ]
    return "\n".join(lines) + "\n"


def monitored_records(table: xr.Dataset) -> int:
    """How many of a track's records came after its baseline: the records a chart watched (none, and no alarm
    could have been raised).

    Examples
    --------
    >>> t = xr.Dataset(coords={"day": ("time", [0.0, 5.0, 10.0, 15.0])}, attrs={"baseline_days": 14.0})
    >>> monitored_records(t)
    1
    """
    return int((table["day"].values >= float(table.attrs["baseline_days"])).sum())


def record_gaps(table: xr.Dataset) -> list[dict]:
    """The gaps in a track's records (``gap_before``, :func:`twin.track.records.gaps_before`): per gap the last
    record's time before it (``from``), the first after it (``to``), both ISO 8601 UTC, and its length in ``days``.

    Examples
    --------
    >>> t = xr.Dataset(
    ...     {"gap_before": ("time", [0.0, 0.0, 2.5])},
    ...     coords={"time": np.array(["2027-01-01T00", "2027-01-01T06", "2027-01-03T18"], dtype="datetime64[ns]")},
    ... )
    >>> record_gaps(t)
    [{'from': '2027-01-01T06:00:00Z', 'to': '2027-01-03T18:00:00Z', 'days': 2.5}]
    """
    times = table.time.values
    return [
        {
            "from": np.datetime_as_string(times[i - 1], unit="s") + "Z",
            "to": np.datetime_as_string(times[i], unit="s") + "Z",
            "days": round(float(table.gap_before.values[i]), 4),
        }
        for i in _after_gaps(table)
    ]


def _after_gaps(table: xr.Dataset) -> np.ndarray:
    """The indices of the records that come after a gap (none in a track written before gaps were stated)."""
    return np.flatnonzero(table.gap_before.values > 0) if "gap_before" in table else np.array([], dtype=int)


def _gap_spans(table: xr.Dataset) -> list[tuple[float, float]]:
    """The gaps as ``(day before, day after)``, for the figures."""
    day = table.day.values
    return [(float(day[i - 1]), float(day[i])) for i in _after_gaps(table)]


def _broken(table: xr.Dataset, day: np.ndarray, *ys: np.ndarray) -> tuple[np.ndarray, ...]:
    """``day`` and each series with a NaN inserted at every gap, so that a line is drawn broken there."""
    at = _after_gaps(table)
    return tuple(np.insert(np.asarray(v, dtype=float), at, np.nan, axis=0) for v in (day, *ys))


def _shade_gaps(table: xr.Dataset, axes, label: bool = False) -> None:
    """Hatch the gaps on each of ``axes`` (the first labelled "no records" when ``label``)."""
    for j, (a, b) in enumerate(_gap_spans(table)):
        for k, ax in enumerate(axes):
            ax.axvspan(
                a,
                b,
                facecolor="none",
                edgecolor="0.6",
                hatch="//",
                lw=0,
                label="no records" if label and j == 0 and k == 0 else None,
            )


def write_report(
    table: xr.Dataset, out: str | Path, *, model=None, records: str | Path | None = None, colour_by: str | None = None
) -> Path:
    """Write ``out/report.html`` of a tracking (``track.nc``'s dataset), atomically; returns its path.

    Parameters
    ----------
    table : xarray.Dataset
        What :func:`twin.track.tracker.track` returns.
    out : path
        The tracker's folder.
    model : RotorModel, optional
        The model, to read a simulated campaign's truth in its parameters' terms.
    records : path, optional
        The records' folder (default the dataset's ``records`` attr), for the truth.
    colour_by : str, optional
        The operating condition the trends are coloured by (default the model's first).
    """
    colour = _colour_condition(table, colour_by)
    truth = None
    folder = records if records is not None else table.attrs.get("records")
    if model is not None and folder and "tracked_parameter" in table.dims:
        truth = record_truth(
            folder, [str(n) for n in table.tracked_parameter.values], model, [str(r) for r in table.record.values]
        )
    target = Path(out) / "report.html"
    with tempfile.TemporaryDirectory() as tmp:
        figures = Path(tmp)
        _trends(table, colour, figures / "frequency.png", "frequency")
        _trends(table, colour, figures / "damping.png", "damping")
        _chart(table, figures / "chart.png")
        if "tracked_parameter" in table.dims:
            _parameters(table, truth, figures / "parameters.png")
        page = markdown_to_html(report_markdown(table, truth, colour), figures, "tracking report")
    with atomic_output(target, ".html.part") as tmp_path:
        tmp_path.write_text(page, encoding="utf-8")
    log.info("wrote %s", target)
    return target
