"""The tracker: a folder of records in, ``track.nc`` out, with the alarms and what changed.

:func:`track` goes through the loop over time:

1. each record's modes are extracted once (:mod:`twin.track.records`; Dask over records);
2. each tracked mode of the model (:func:`twin.track.physics.tracked_modes`) is found in every record by
   pole distance and MAC against the model's prediction at the record's operating point;
3. over the baseline days the laws' slopes are learned through the model (:func:`twin.track.physics.fit_laws`);
4. what the operating conditions do not explain goes to a control chart (:mod:`twin.track.detect`);
5. at an alarm, the records since the onset name the change (:func:`twin.track.explain.diagnose`), which
   is then followed record by record (:class:`twin.track.explain.Follower`) and taken out of the residual,
   so a further change alarms again (:class:`twin.track.watch.Watch`).

Everything but the extraction is computed anew at each call from the cached modes, so records added to
the folder later give the same alarms as one run over all of them.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from twin import __version__
from twin.defaults import BASELINE_DAYS  # noqa: F401 (shared with the CLI)
from twin.errors import TwinError
from twin.extract.options import ExtractOptions
from twin.fem.model import RotorModel
from twin.fem.operation import operation_of
from twin.modes.measured import measured_modes
from twin.modes.pairing import assign, pairing_cost
from twin.netcdf import check_folder, one_writer, write_netcdf
from twin.progress import stage
from twin.tasks import mapper, one_blas_thread
from twin.track import detect, explain
from twin.track.physics import Tracked, fit_laws, parts, predict, tracked_modes, with_slopes
from twin.track.records import (
    GAP_INTERVALS,
    UnusableRecord,
    check_machine,
    extract_new,
    gaps_before,
    read_cached,
    records_in,
)
from twin.report.tracking import monitored_records, record_gaps, write_report
from twin.track.watch import Alarm, Chart, Series, Watch

log = logging.getLogger(__name__)

#: A measured mode is a tracked mode's when its pole is within this relative distance of the prediction.
IDENTITY_TOLERANCE = 0.05
#: ... and its shape's MAC with the model's is at least this.
IDENTITY_MAC = 0.6
#: A change may move a pole further than :data:`IDENTITY_TOLERANCE` (a guide bearing's damping moves the
#: first mode by a fifth): a measured mode is still the tracked one's when its shape's MAC is at least
#: :data:`IDENTITY_MAC_FAR` and its pole is closer than half the way to the nearest other tracked pole,
#: and within :data:`IDENTITY_REACH` of the prediction. Without this the chart would lose a mode exactly
#: when it changes most.
IDENTITY_MAC_FAR = 0.9
IDENTITY_REACH = 0.5
#: A tracked mode found in fewer of the baseline's records than this fraction is not tracked.
MIN_FOUND = 0.5


def reach(predicted: np.ndarray) -> np.ndarray:
    """How far (relative to its modulus) a tracked pole may have moved and still be recognised by a
    close shape: half the way to the nearest other tracked pole, at least :data:`IDENTITY_TOLERANCE` and
    at most :data:`IDENTITY_REACH`.

    Examples
    --------
    >>> np.round(reach(np.array([-0.05 + 7.0j, -1.3 + 17.2j, -0.6 + 324.7j, -0.6 + 333.5j])), 3)
    array([0.5  , 0.298, 0.05 , 0.05 ])
    """
    p = np.asarray(predicted)
    if p.size < 2:
        return np.full(p.shape, IDENTITY_REACH)
    gap = np.abs(p[:, None] - p[None, :])
    np.fill_diagonal(gap, np.inf)
    return np.clip(0.5 * gap.min(axis=1) / np.abs(p), IDENTITY_TOLERANCE, IDENTITY_REACH)


def _identify(meas, predicted: np.ndarray, shapes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Measured pole and its standard errors (real, imag) for each tracked mode, NaN where none matches.

    A measured mode is a tracked one's when its pole is within :data:`IDENTITY_TOLERANCE` of the
    prediction with a MAC of :data:`IDENTITY_MAC`, or within :func:`reach` with a MAC of
    :data:`IDENTITY_MAC_FAR`; each measured mode serves one tracked mode, by the assignment of least total
    pairing cost (:func:`twin.modes.pairing.assign`).
    """
    m = len(predicted)
    pole = np.full(m, np.nan + 1j * np.nan)
    sigma = np.full((m, 2), np.nan)
    if meas is None:
        return pole, sigma
    cost, mac = pairing_cost(predicted, shapes, meas.pole, meas.shape)
    dist = np.abs(meas.pole[None, :] - predicted[:, None]) / np.abs(predicted)[:, None]
    near = (dist < IDENTITY_TOLERANCE) & (mac >= IDENTITY_MAC)
    far = (dist < reach(predicted)[:, None]) & (mac >= IDENTITY_MAC_FAR)
    cols = assign(cost, near | far)
    found = cols >= 0
    pole[found], sigma[found] = meas.pole[cols[found]], meas.sigma[cols[found]]
    return pole, sigma


#: Records per task when the model's predictions go to Dask workers (each is one eigen-solution, ~0.1 s).
PREDICTIONS_PER_TASK = 40


def _predict_points(
    points: list[dict[str, float]], *, model: RotorModel, tracked: Tracked, with_jacobian: bool
) -> list:
    return [predict(model, tracked, p, with_jacobian=with_jacobian) for p in points]


def _predictions(
    model: RotorModel, tracked: Tracked, records: list, tasks: Any, progress: bool, *, with_jacobian: bool
) -> list:
    """:func:`twin.track.physics.predict` at each record's operating point, in order: the records in
    batches of :data:`PREDICTIONS_PER_TASK`, as independent tasks (``tasks``, :func:`twin.tasks.mapper`)."""
    points = [r.point for r in records]
    batches = [points[k : k + PREDICTIONS_PER_TASK] for k in range(0, len(points), PREDICTIONS_PER_TASK)]
    done = mapper(tasks, progress=progress, desc="predict")(
        _predict_points, batches, model=model, tracked=tracked, with_jacobian=with_jacobian
    )
    return [p for batch in done for p in batch]


@one_blas_thread  # many 232-state eigen-solutions: faster on one BLAS thread (twin.tasks.one_blas_thread)
def track(
    model: RotorModel,
    folder: str | Path,
    out: str | Path,
    *,
    baseline_days: float = BASELINE_DAYS,
    false_alarms_per_year: float = detect.FALSE_ALARMS_PER_YEAR,
    extract_options: ExtractOptions | Mapping[str, Any] | None = None,
    tasks: Any = None,
    progress: bool = True,
    report: bool = True,
    strict: bool = False,
) -> xr.Dataset:
    """Track a unit over a folder of records; write ``out/track.nc`` and ``out/report.html``; return the first.

    Parameters
    ----------
    model : RotorModel
        A model with operating conditions and laws (:mod:`twin.fem.operation`).
    folder : path
        The records (``*.nc`` with ``start_time`` and ``operating_point``), e.g. from ``twin campaign``.
    out : path
        The tracker's folder: ``modes/`` (each record's modes, extracted once) and ``track.nc``.
    baseline_days : float
        Days from the first record over which the laws are learned and the chart's scale is set; no alarm
        is raised in them.
    false_alarms_per_year : float
        The false-alarm rate the chart's limit is set for [per unit-year], at the baseline's cadence
        (its records over ``baseline_days``): records that come later, after an outage or at another
        rate, leave the limit and every earlier verdict as they were.
    extract_options : ExtractOptions or mapping, optional
        Options of :func:`twin.extract.extract` (:class:`twin.extract.options.ExtractOptions` or a mapping of
        its fields), checked before any record is read; a record's cached modes answer only for them.
    tasks : distributed.Client or mapper, optional
        Where the extractions run.
    progress : bool
        Progress bars.
    report : bool
        Write ``out/report.html`` too (:func:`twin.report.tracking.write_report`).
    strict : bool
        Stop at the first record that cannot be used (unreadable, without operating data or with data out of
        the model's ranges, starting with another, or with NaNs or a dead channel). By default such a record
        is set aside and the rest tracked; the attr ``set_aside`` of the result lists them with the reasons.

    Returns
    -------
    xarray.Dataset
        Over ``time`` (the records' starts) and ``mode`` (the tracked modes): ``frequency``,
        ``damping_ratio``, ``predicted_frequency`` (at the record's operating point), ``residual``
        (pole parts the conditions do not explain, over ``part``), ``statistic`` and ``limit`` of the
        chart, ``operating_point``; the alarms (``alarm``: time, ``alarm_day``, ``alarm_onset_day``,
        ``alarm_effect``, ``alarm_verdict``); the followed parameters (``parameter`` and its 5-95% interval).
    """
    if not (np.isfinite(baseline_days) and baseline_days > 0):
        raise TwinError(f"the baseline must be a positive number of days, got {baseline_days!r}")
    if not (np.isfinite(false_alarms_per_year) and false_alarms_per_year > 0):
        raise TwinError(
            f"the false-alarm rate must be a positive number per unit-year (a chart set for none could never "
            f"alarm), got {false_alarms_per_year!r}"
        )
    if Path(out).resolve() == Path(folder).resolve():
        raise TwinError(
            f"the tracker's folder {out} is the folder of records: its files (track.nc, the modes' cache) would be "
            "read as records on the next run; give another folder (-o)"
        )
    op = operation_of(model)
    options = ExtractOptions.of(extract_options)
    set_aside: list[tuple[str, str]] = []
    records = records_in(folder, op, None if strict else set_aside)
    check_machine(records, model.name, model.speed_rpm)
    out = check_folder(out, make=True)
    with one_writer(out, "twin track"):  # one tracker per folder; what a killed one left is cleaned
        with stage(f"extract the modes of {len(records)} records"):
            cache = extract_new(records, out / "modes", options=options, tasks=tasks, progress=progress, strict=strict)
        usable, measured = [], []
        for r, p in zip(records, cache):
            try:
                measured.append(read_cached(p))
            except UnusableRecord as exc:
                if strict:  # cached by an earlier run that was not strict
                    raise
                set_aside.append((r.path.name, str(exc)))
            else:
                usable.append(r)
        for name, reason in set_aside:
            log.warning("set aside: %s", reason if name in reason else f"{name}: {reason}")
        if not usable:
            raise TwinError(f"{folder}: no usable record ({len(set_aside)} set aside, the first: {set_aside[0][1]})")
        records = usable
        first = next((m for m in measured if m is not None), None)
        if first is None:
            raise TwinError(f"{folder}: no mode stood out of any record")
        meas0 = measured_modes(first)
        fmax = meas0.band_hz[1] if meas0.band_hz else 100.0
        tracked = tracked_modes(model, tuple(meas0.channels), fmax)
        t0 = records[0].start
        days = np.array([(r.start - t0).total_seconds() / 86400.0 for r in records])
        base = days < baseline_days
        if base.sum() < 3:
            raise TwinError(
                f"the baseline ({baseline_days:g} days) holds {int(base.sum())} records: at least 3 are needed"
            )

        with stage("find the tracked modes in each record"):
            poles, sigmas = [], []
            expected = _predictions(model, tracked, records, tasks, progress, with_jacobian=False)
            for r, md, (predicted, _) in zip(records, measured, expected):
                meas = None if md is None else measured_modes(md)
                if meas is not None and list(meas.channels) != list(tracked.channels):
                    raise TwinError(
                        f"{r.path}: channels {meas.channels} differ from the first record's {tracked.channels}"
                    )
                p, s = _identify(meas, predicted, tracked.shapes)
                poles.append(p)
                sigmas.append(s)
        poles, sigmas = np.array(poles), np.array(sigmas)
        found = np.isfinite(poles[base]).mean(axis=0)
        keep = found >= MIN_FOUND
        if not keep.any():
            raise TwinError("no tracked mode was found in half of the baseline's records")
        tracked = type(tracked)(tracked.poles[keep], tracked.shapes[keep], tracked.channels)
        poles, sigmas = poles[:, keep], sigmas[:, keep]
        y = parts(poles)
        sig = np.concatenate([sigmas[..., 0], sigmas[..., 1]], axis=1)

        with stage(f"learn the laws over {int(base.sum())} baseline records"):
            laws = fit_laws(model, tracked, [r.point for r, b in zip(records, base) if b], y[base], sig[base])
        learned = with_slopes(model, laws.slopes)
        with stage(f"predict the tracked modes of {len(records)} records with the laws learned"):
            predicted, by_slopes = zip(*_predictions(learned, tracked, records, tasks, progress, with_jacobian=True))
        predicted = np.array(predicted)
        # how each record's predicted frequencies move with the slopes, less the baseline's mean (which the
        # offsets absorb): with the slopes' covariance, the chart's share of the laws' uncertainty
        by_slopes = np.array(by_slopes).imag.reshape(len(records), len(tracked.poles), -1)
        drift = by_slopes - by_slopes[base].mean(axis=0)
        residual = y - parts(predicted) - laws.offsets

        # the chart watches the frequencies (the imaginary parts): the damping ratios scatter far more from record
        # to record and drift with what no law describes, which a false-alarm rate cannot hold
        m = len(tracked.poles)
        chart = detect.learn_baseline(residual[base], sig[base])
        watched = detect.Baseline(chart.center[m:], chart.scale[m:], chart.correlation[m:, m:], chart.n_records)
        # the cadence the limit is set for is the baseline's: records that arrive later (after an outage, or faster)
        # never move the limit, and so never an earlier verdict
        records_per_year = 365.25 * int(base.sum()) / baseline_days
        if int(base.sum()) <= m + 1:
            raise TwinError(
                f"the baseline ({baseline_days:g} days) holds {int(base.sum())} records: a chart of {m} "
                f"tracked modes needs more than {m + 1}; give a longer baseline (--baseline-days)"
            )
        if false_alarms_per_year >= records_per_year:
            raise TwinError(
                f"a false-alarm rate of {false_alarms_per_year:g} per year is one or more per record at "
                f"{records_per_year:.4g} records a year: give a rate below it"
            )
        # the false-alarm rate is shared between the omnibus chart and the step statistics along each candidate
        # change from each onset of the grid (a Bonferroni share each)
        n_base, share = int(base.sum()), detect.DIRECTED_SHARE
        limit = detect.threshold(m, n_base, records_per_year, (1.0 - share) * false_alarms_per_year)
        cands = explain.candidates(learned, tracked)
        directed_limits = np.array(
            [
                detect.threshold(
                    len(c.parameters),
                    n_base,
                    records_per_year,
                    share * false_alarms_per_year / (len(cands) * len(detect.ONSETS)),
                    m,
                )
                for c in cands
            ]
        )
        series = Series(records, days, y, sig, residual, drift)
        done = Watch(learned, tracked, cands, series, Chart(chart, watched, limit, laws, directed_limits)).run(n_base)
        values: dict[str, np.ndarray] = {}
        for f in done.followers:
            for j, name in enumerate(f.cand.parameters):
                values[name] = f.history[:, j, :]
        table = _dataset(
            records,
            days,
            tracked,
            poles,
            predicted,
            done.current,
            done.statistic,
            done.directed,
            limit,
            done.alarms,
            values,
            laws,
            op,
            baseline_days,
        )
        table.attrs.update(
            {
                "records": str(Path(folder).resolve()),
                "false_alarms_per_year": float(false_alarms_per_year),
                "set_aside": json.dumps([{"file": name, "reason": reason} for name, reason in set_aside]),
            }
        )
        table["pole_se"] = (
            ("time", "mode", "part"),
            np.stack([sigmas[..., 0], sigmas[..., 1]], axis=2),
            {"units": "1/s", "long_name": "standard error of the measured pole parts (jackknife)"},
        )
        write_netcdf(table, out / "track.nc")
        if report:
            with stage("write the report"):
                write_report(table, out, model=model)
        return table


def _dataset(
    records,
    days,
    tracked,
    poles,
    predicted,
    residual,
    statistic,
    directed,
    limit,
    alarms: list[Alarm],
    values,
    laws,
    op,
    baseline_days,
) -> xr.Dataset:
    m = len(tracked.poles)
    times = np.array([r.start.replace(tzinfo=None) for r in records], dtype="datetime64[ns]")
    gap, gap_threshold = gaps_before(days, int((days < baseline_days).sum()))
    freq = poles.imag / (2 * np.pi)
    zeta = -poles.real / np.abs(poles)
    ds = xr.Dataset(
        {
            "frequency": (("time", "mode"), freq, {"units": "Hz", "long_name": "measured damped frequency"}),
            "damping_ratio": (("time", "mode"), zeta, {"units": "1", "long_name": "measured damping ratio"}),
            "predicted_frequency": (
                ("time", "mode"),
                predicted.imag / (2 * np.pi),
                {"units": "Hz", "long_name": "the model's at the record's operating point"},
            ),
            "residual": (
                ("time", "mode", "part"),
                np.stack([residual[:, :m], residual[:, m:]], axis=2),
                {"units": "1/s", "long_name": "pole parts the operating conditions do not explain"},
            ),
            "statistic": ("time", statistic, {"units": "1", "long_name": "control chart statistic (MEWMA T2)"}),
            "limit": ((), limit, {"units": "1", "long_name": "control limit"}),
            "directed": (
                "time",
                directed,
                {
                    "units": "1",
                    "long_name": "largest step statistic over its limit (GLR along each candidate change)",
                    "comment": "an alarm above 1",
                },
            ),
            "operating_point": (("time", "condition"), np.array([[r.point[k] for k in op.names] for r in records])),
            "day": ("time", days, {"units": "d", "long_name": "days after the first record"}),
            "gap_before": (
                "time",
                gap,
                {
                    "units": "d",
                    "long_name": "time without records before this record where it is a gap, else 0",
                    "comment": f"a gap: more than {GAP_INTERVALS:g} times the baseline's median interval "
                    f"({gap_threshold:.4g} d)",
                },
            ),
            "record": ("time", [r.path.name for r in records]),
            "slope": ("slope_key", laws.slopes, {"long_name": "learned slopes of the laws (SI per condition unit)"}),
            "slope_std": ("slope_key", np.sqrt(laws.covariance.diagonal())),
            "slope_declared": ("slope_key", laws.declared),
            "alarm_time": ("alarm", np.array([times[a.record] for a in alarms], dtype="datetime64[ns]")),
            "alarm_day": ("alarm", [float(days[a.record]) for a in alarms], {"units": "d"}),
            "alarm_onset_day": ("alarm", [float(days[a.onset]) for a in alarms], {"units": "d"}),
            "alarm_named_day": (
                "alarm",
                [np.nan if a.named is None else float(days[a.named]) for a in alarms],
                {"units": "d", "long_name": "day the records told the change from the others"},
            ),
            "alarm_effect": ("alarm", [a.verdict.label for a in alarms]),
            "alarm_named": (
                "alarm",
                [bool(a.verdict.clear) for a in alarms],
                {"long_name": "whether the records named the change (alarm_effect) against every other"},
            ),
            "alarm_runner_up": ("alarm", [a.verdict.runner_up for a in alarms]),
            "alarm_verdict": ("alarm", [a.verdict.text for a in alarms]),
        },
        coords={
            "time": times,
            "mode": np.arange(1, m + 1),
            "part": ["real", "imag"],
            "model_frequency": ("mode", tracked.frequency_hz, {"units": "Hz"}),
            "condition": list(op.names),
            "condition_units": ("condition", [op.condition(k).units for k in op.names]),
            "slope_key": [f"{p}/{c}" for p, c in laws.keys],
        },
        attrs={
            "title": "tracking of a unit over its records",
            "producer": f"twin {__version__} twin.track",
            "baseline_days": float(baseline_days),
            "first_record": records[0].start.isoformat(),
        },
    )
    if values:
        names = sorted(values)
        arr = np.stack([values[n] for n in names], axis=1)
        ds["parameter"] = (("time", "tracked_parameter"), arr[..., 0], {"long_name": "followed change (SI)"})
        ds["parameter_low"] = (("time", "tracked_parameter"), arr[..., 1], {"long_name": "5% quantile"})
        ds["parameter_high"] = (("time", "tracked_parameter"), arr[..., 2], {"long_name": "95% quantile"})
        ds = ds.assign_coords(tracked_parameter=names)
    return ds


def alarms_json(table: xr.Dataset) -> dict:
    """The ``--json`` summary: ``{"records": N, "monitored": M, "gaps": [{"from", "to", "days"}], "set_aside":
    [{"file", "reason"}], "alarms": [{"time", "day", "effects", "verdict"}]}`` (``monitored``: the records after
    the baseline, :func:`monitored_records`; ``gaps``: the times without records, :func:`record_gaps`;
    ``set_aside``: the records that could not be used, and why)."""
    out = []
    for i in range(table.sizes.get("alarm", 0)):
        time = np.datetime_as_string(table.alarm_time.values[i], unit="s") + "Z"
        effects = [str(table.alarm_effect.values[i])] if bool(table.alarm_named.values[i]) else []
        named = float(table.alarm_named_day.values[i])
        out.append(
            {
                "time": time,
                "day": round(float(table.alarm_day.values[i]), 4),
                "onset_day": round(float(table.alarm_onset_day.values[i]), 4),
                "named_day": None if np.isnan(named) else round(named, 4),
                "effects": effects,
                "verdict": str(table.alarm_verdict.values[i]),
            }
        )
    return {
        "records": int(table.sizes["time"]),
        "monitored": monitored_records(table),
        "gaps": record_gaps(table),
        "set_aside": json.loads(table.attrs.get("set_aside", "[]")),
        "alarms": out,
    }
