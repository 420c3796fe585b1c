"""The tracker: a folder of records in, ``track.nc`` out, with the alarms and what changed.

:func:`track` goes through the loop over time:

1. each record's modes are extracted once (:mod:`twin.track.records`; Dask over records);
2. each tracked mode of the model (:func:`twin.track.physics.tracked_modes`) is found in every record by
   pole distance and MAC against the model's prediction at the record's operating point;
3. over the baseline days the laws' slopes are learned through the model (:func:`twin.track.physics.fit_laws`);
4. what the operating conditions do not explain goes to a control chart (:mod:`twin.track.detect`);
5. at an alarm, the records since the onset name the change (:func:`twin.track.explain.diagnose`), which
   is then followed record by record (:class:`twin.track.explain.Follower`) and taken out of the residual,
   so a further change alarms again.

Everything but the extraction is computed anew at each call from the cached modes, so records added to
the folder later give the same alarms as one run over all of them.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from twin import __version__
from twin.errors import TwinError
from twin.fem.model import RotorModel
from twin.fem.operation import operation_of
from twin.modes.measured import measured_modes
from twin.modes.pairing import pairing_cost
from twin.netcdf import check_folder, write_netcdf
from twin.progress import stage
from twin.tasks import mapper, one_blas_thread
from twin.track import detect, explain
from twin.track.physics import Tracked, fit_laws, parts, predict, tracked_modes, with_slopes
from twin.track.records import extract_new, read_cached, records_in
from twin.track.report import write_report

log = logging.getLogger(__name__)

#: Baseline length [days] by default.
BASELINE_DAYS = 14.0
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
#: The diagnosis and the followed changes use the measured damping (the poles' real parts) beside the
#: frequencies; the chart watches the frequencies alone. See the decision log's "tracking-damping" page.
DIAGNOSE_WITH_DAMPING = True
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
    :data:`IDENTITY_MAC_FAR`; each measured mode serves one tracked mode, the best pairs first.
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
    cost = np.where(near | far, cost, np.inf)
    taken: set[int] = set()
    for flat in np.argsort(cost, axis=None):
        i, j = np.unravel_index(flat, cost.shape)
        if not np.isfinite(cost[i, j]):
            break
        if np.isfinite(pole[i]) or j in taken:
            continue
        pole[i], sigma[i] = meas.pole[j], meas.sigma[j]
        taken.add(int(j))
    return pole, sigma


#: Records per task when the model's predictions go to Dask workers (each is one eigen-solution, ~0.1 s).
PREDICTIONS_PER_TASK = 40


def _predict_points(points: list[dict[str, float]], *, model: RotorModel, tracked: Tracked,
                    with_jacobian: bool) -> list:  # fmt: skip
    return [predict(model, tracked, p, with_jacobian=with_jacobian) for p in points]


def _predictions(model: RotorModel, tracked: Tracked, records: list, tasks: Any, progress: bool, *,
                 with_jacobian: bool) -> list:  # fmt: skip
    """:func:`twin.track.physics.predict` at each record's operating point, in order: the records in
    batches of :data:`PREDICTIONS_PER_TASK`, as independent tasks (``tasks``, :func:`twin.tasks.mapper`)."""
    points = [r.point for r in records]
    batches = [points[k:k + PREDICTIONS_PER_TASK] for k in range(0, len(points), PREDICTIONS_PER_TASK)]
    done = mapper(tasks, progress=progress, desc="predict")(_predict_points, batches, model=model, tracked=tracked,
                                                             with_jacobian=with_jacobian)  # fmt: skip
    return [p for batch in done for p in batch]


@one_blas_thread  # many 232-state eigen-solutions: faster on one BLAS thread (twin.tasks.one_blas_thread)
def track(
    model: RotorModel,
    folder: str | Path,
    out: str | Path,
    *,
    baseline_days: float = BASELINE_DAYS,
    false_alarms_per_year: float = detect.FALSE_ALARMS_PER_YEAR,
    extract_settings: dict[str, Any] | None = None,
    tasks: Any = None,
    progress: bool = True,
    report: bool = True,
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
        The false-alarm rate the chart's limit is set for [per unit-year].
    extract_settings : dict, optional
        Options of :func:`twin.extract.extract`.
    tasks : distributed.Client or mapper, optional
        Where the extractions run.
    progress : bool
        Progress bars.
    report : bool
        Write ``out/report.html`` too (:func:`twin.track.report.write_report`).

    Returns
    -------
    xarray.Dataset
        Over ``time`` (the records' starts) and ``mode`` (the tracked modes): ``frequency``,
        ``damping_ratio``, ``predicted_frequency`` (at the record's operating point), ``residual``
        (pole parts the conditions do not explain, over ``part``), ``statistic`` and ``limit`` of the
        chart, ``operating_point``; the alarms (``alarm``: time, ``alarm_day``, ``alarm_onset_day``,
        ``alarm_effect``, ``alarm_verdict``); the followed parameters (``parameter`` and its 5-95% interval).
    """
    op = operation_of(model)
    records = records_in(folder, op)
    out = check_folder(out, make=True)
    with stage(f"extract the modes of {len(records)} records"):
        cache = extract_new(records, out / "modes", settings=extract_settings, tasks=tasks, progress=progress)
    measured = [read_cached(p) for p in cache]
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
        raise TwinError(f"the baseline ({baseline_days:g} days) holds {int(base.sum())} records: at least 3 are needed")

    with stage("find the tracked modes in each record"):
        poles, sigmas = [], []
        expected = _predictions(model, tracked, records, tasks, progress, with_jacobian=False)
        for r, md, (predicted, _) in zip(records, measured, expected):
            meas = None if md is None else measured_modes(md)
            if meas is not None and list(meas.channels) != list(tracked.channels):
                raise TwinError(f"{r.path}: channels {meas.channels} differ from the first record's {tracked.channels}")
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
    watch = detect.Baseline(chart.center[m:], chart.scale[m:], chart.correlation[m:, m:], chart.n_records)
    records_per_year = 365.25 * len(records) / max(days[-1] - days[0], 1e-9) if len(records) > 1 else 365.25
    if int(base.sum()) <= m + 1:
        raise TwinError(f"the baseline ({baseline_days:g} days) holds {int(base.sum())} records: a chart of {m} "
                        f"tracked modes needs more than {m + 1}; give a longer baseline (--baseline-days)")  # fmt: skip
    limit = detect.threshold(m, int(base.sum()), records_per_year, false_alarms_per_year)
    cands = explain.candidates(learned, tracked)
    statistic, alarms, followers, current = _watch(learned, tracked, records, days, y, sig, residual, laws, chart,
                                                   watch, limit, cands, int(base.sum()), drift)  # fmt: skip
    values: dict[str, np.ndarray] = {}
    for f in followers:
        for j, name in enumerate(f.cand.parameters):
            values[name] = f.history[:, j, :]
    table = _dataset(records, days, tracked, poles, predicted, current, statistic, limit, alarms, values, laws, op,
                     baseline_days)  # fmt: skip
    table.attrs.update({"records": str(Path(folder).resolve()), "false_alarms_per_year": float(false_alarms_per_year)})
    table["pole_se"] = (("time", "mode", "part"), np.stack([sigmas[..., 0], sigmas[..., 1]], axis=2),
                        {"units": "1/s", "long_name": "standard error of the measured pole parts (jackknife)"})
    write_netcdf(table, out / "track.nc")
    if report:
        with stage("write the report"):
            write_report(table, out, model=model)
    return table


def _observation(y: np.ndarray, offsets: np.ndarray, center: np.ndarray, m: int) -> np.ndarray:
    """A record's pole parts less the laws' offsets and the baseline's centre, as the diagnosis and the
    followers see them (the real parts NaN unless :data:`DIAGNOSE_WITH_DAMPING`)."""
    obs = y - offsets - center
    if not DIAGNOSE_WITH_DAMPING:
        obs[:m] = np.nan
    return obs


def _watch(learned, tracked, records, days, y, sig, residual, laws, chart, watch, limit, cands, start, drift):
    """The chart over the records after the baseline; at each alarm the change named, updated and followed.

    A name the records since the onset cannot yet tell from the runner-up's (their log evidences closer
    than :data:`twin.track.explain.MIN_MARGIN`) is a reading: its change is followed, so the chart goes on
    watching what it does not explain, and the records since the onset are weighed again as each one comes,
    until one name stands out; the change is then updated anew if the name changed
    (:class:`_Reading`). A change that grows (a ramp) alarms while it is small, when the records cannot
    yet say which it is. An alarm that names a change already followed (one that grew faster than its
    filter's process noise lets it follow) re-estimates that change as a whole on the records since the
    new onset, so one change has one follower.

    ``drift`` holds each record's frequency parts' sensitivity to the laws' slopes less the baseline's mean
    (``(n, m, K)``): the chart counts the slopes' uncertainty (:class:`twin.track.detect.MEWMA`).

    Returns the chart's statistic, the alarms ``[record, onset record, verdict, record named]``, the
    followers (each with its ``history``: value, 5% and 95% quantile per record) and each record's
    residual against the model with the changes followed so far.
    """
    n, m = len(records), len(tracked.poles)
    statistic = np.full(n, np.nan)
    current = residual.copy()
    followers: list[explain.Follower] = []
    alarms: list[list] = []
    reading: _Reading | None = None
    smooth = detect.MEWMA(watch, uncertain=laws.covariance if drift.shape[2] else None)

    def observed(k: int, t: int) -> list:
        return [(records[i].point, _observation(y[i], laws.offsets, chart.center, m),
                 detect.record_covariance(sig[i], chart)) for i in range(k, t + 1)]  # fmt: skip

    def follow(cand, k: int, t: int) -> explain.Follower:
        """The change ``cand`` updated on the records ``k..t``: a new follower, or, for a change already
        followed (a ramp that outran its filter), the same one re-estimated as a whole."""
        same = next((f for f in followers if f.cand.label == cand.label), None)
        others = [(f.cand, f.mean) for f in followers if f is not same]
        value, value_cov = explain.update(learned, tracked, cand, observed(k, t), others)
        if same is not None:
            same.mean, same.cov, same.day = value, value_cov, days[t]
            return same
        f = explain.Follower(learned, tracked, cand, value, value_cov, days[t])
        f.history = np.full((n, len(value), 3), np.nan)
        followers.append(f)
        return f

    def settle(t: int, force: bool) -> None:
        """Weigh the reading's records again; name the change when one stands out (or ``force``)."""
        nonlocal reading
        verdict = _diagnosis(reading.without[reading.onset:t + 1], sig[reading.onset:t + 1], chart, cands, m)
        if verdict.log_evidence - verdict.runner_up_evidence < explain.MIN_MARGIN and not force:
            return
        if verdict.log_evidence < explain.MIN_LOG_EVIDENCE:
            verdict = reading.verdict  # the evidence went: keep what the alarm said
        f = reading.follower
        if verdict.label != f.cand.label:
            if reading.before is None:
                followers.remove(f)
            else:  # a change followed before the alarm: back to what it was
                f.mean, f.cov, f.day = reading.before
            f = follow(next(c for c in cands if c.label == verdict.label), reading.onset, t)
        note = "" if verdict.label == reading.verdict.label else \
            f"first read as {reading.verdict.label} on day {days[reading.alarm_record]:.2f}"  # fmt: skip
        verdict = explain.named(verdict, f.cand, f.mean, f.cov, note=note)
        alarms[reading.alarm][2:] = [verdict, t]
        log.info("the change since %s named on %s: %s", records[reading.onset].start.isoformat(),
                 records[t].start.isoformat(), verdict.text)  # fmt: skip
        reading = None

    for t in range(start, n):
        point, cov = records[t].point, detect.record_covariance(sig[t], chart)
        obs = _observation(y[t], laws.offsets, chart.center, m)
        for f in followers:
            f.update(point, obs, cov, days[t], [(g.cand, g.mean) for g in followers if g is not f])
        if reading is not None:
            others = [(f.cand, f.mean) for f in followers if f is not reading.follower]
            if reading.before is not None:
                others.append((reading.follower.cand, reading.before[0]))
            g = explain.changed_poles(learned, tracked, point, others)[0] if others else None
            reading.without[t] = residual[t] if g is None else y[t] - laws.offsets - g
            settle(t, force=False)
        if followers:
            g, _ = explain.changed_poles(learned, tracked, point, [(f.cand, f.mean) for f in followers])
            current[t] = y[t] - laws.offsets - g
        z = detect.standardised(current[t, m:], sig[t, m:], watch)
        g = np.nan_to_num(drift[t] / (watch.scale * sig[t, m:])[:, None])  # 0 where the mode was not found
        statistic[t] = smooth.add(z, g)
        if statistic[t] > limit:
            if reading is not None:
                settle(t, force=True)
            k = start + detect.onset(detect.standardised(current[start:t + 1, m:], sig[start:t + 1, m:], watch), watch)
            verdict = _diagnosis(current[k:t + 1], sig[k:t + 1], chart, cands, m)
            alarms.append([t, k, verdict, None])
            if verdict.log_evidence >= explain.MIN_LOG_EVIDENCE:
                cand = next(c for c in cands if c.label == verdict.label)
                same = next((f for f in followers if f.cand is cand), None)
                before = None if same is None else (same.mean.copy(), same.cov.copy(), same.day)
                f = follow(cand, k, t)
                verdict = explain.named(verdict, f.cand, f.mean, f.cov)
                clear = verdict.log_evidence - verdict.runner_up_evidence >= explain.MIN_MARGIN
                alarms[-1][2:] = [verdict, t if clear else None]
                if not clear:
                    reading = _Reading(f, k, len(alarms) - 1, t, verdict, current.copy(), before)
            log.info("alarm at %s (onset %s): %s", records[t].start.isoformat(), records[k].start.isoformat(),
                     verdict.text)  # fmt: skip
            smooth.reset()
            start = t + 1
        for f in followers:
            half = 1.645 * np.sqrt(f.cov.diagonal())  # the 5-95% interval
            f.history[t] = np.stack([f.mean, f.mean - half, f.mean + half], axis=1)
    return statistic, [tuple(a) for a in alarms], followers, current


@dataclass
class _Reading:
    """A change followed under a name the records could not yet tell from another's: its follower, the
    onset, the alarm it answers (its index and record), the alarm's verdict, each record's residual
    without it, and the follower's state (mean, covariance, day) before the alarm if it was followed
    already."""

    follower: explain.Follower
    onset: int
    alarm: int
    alarm_record: int
    verdict: explain.Verdict
    without: np.ndarray
    before: tuple | None = None


def _diagnosis(residuals: np.ndarray, se: np.ndarray, chart: detect.Baseline, cands, m: int) -> explain.Verdict:
    """The candidates weighed on records' residuals pooled (the damping's parts left out unless
    :data:`DIAGNOSE_WITH_DAMPING`)."""
    mean, pooled_cov = detect.pooled(residuals, se, chart)
    if not DIAGNOSE_WITH_DAMPING:
        mean[:m] = np.nan
    return explain.diagnose(mean, pooled_cov, cands)


def _dataset(records, days, tracked, poles, predicted, residual, statistic, limit, alarms, values, laws, op,
             baseline_days) -> xr.Dataset:  # fmt: skip
    m = len(tracked.poles)
    times = np.array([r.start.replace(tzinfo=None) for r in records], dtype="datetime64[ns]")
    freq = poles.imag / (2 * np.pi)
    zeta = -poles.real / np.abs(poles)
    ds = xr.Dataset(
        {
            "frequency": (("time", "mode"), freq, {"units": "Hz", "long_name": "measured damped frequency"}),
            "damping_ratio": (("time", "mode"), zeta, {"units": "1", "long_name": "measured damping ratio"}),
            "predicted_frequency": (("time", "mode"), predicted.imag / (2 * np.pi),
                                    {"units": "Hz", "long_name": "the model's at the record's operating point"}),
            "residual": (("time", "mode", "part"), np.stack([residual[:, :m], residual[:, m:]], axis=2),
                         {"units": "1/s", "long_name": "pole parts the operating conditions do not explain"}),
            "statistic": ("time", statistic, {"units": "1", "long_name": "control chart statistic (MEWMA T2)"}),
            "limit": ((), limit, {"units": "1", "long_name": "control limit"}),
            "operating_point": (("time", "condition"), np.array([[r.point[k] for k in op.names] for r in records])),
            "day": ("time", days, {"units": "d", "long_name": "days after the first record"}),
            "record": ("time", [r.path.name for r in records]),
            "slope": ("slope_key", laws.slopes, {"long_name": "learned slopes of the laws (SI per condition unit)"}),
            "slope_std": ("slope_key", np.sqrt(laws.covariance.diagonal())),
            "slope_declared": ("slope_key", laws.declared),
            "alarm_time": ("alarm", np.array([times[t] for t, _, _, _ in alarms], dtype="datetime64[ns]")),
            "alarm_day": ("alarm", [float(days[t]) for t, _, _, _ in alarms], {"units": "d"}),
            "alarm_onset_day": ("alarm", [float(days[k]) for _, k, _, _ in alarms], {"units": "d"}),
            "alarm_named_day": ("alarm", [np.nan if w is None else float(days[w]) for _, _, _, w in alarms],
                                {"units": "d", "long_name": "day the records told the change from the others"}),
            "alarm_effect": ("alarm", [v.label for _, _, v, _ in alarms]),
            "alarm_named": ("alarm", [bool(v.log_evidence >= explain.MIN_LOG_EVIDENCE) for _, _, v, _ in alarms]),
            "alarm_verdict": ("alarm", [v.text for _, _, v, _ in alarms]),
        },
        coords={
            "time": times, "mode": np.arange(1, m + 1), "part": ["real", "imag"],
            "model_frequency": ("mode", tracked.frequency_hz, {"units": "Hz"}),
            "condition": list(op.names), "condition_units": ("condition", [op.condition(k).units for k in op.names]),
            "slope_key": [f"{p}/{c}" for p, c in laws.keys],
        },
        attrs={"title": "tracking of a unit over its records", "producer": f"twin {__version__} twin.track",
               "baseline_days": float(baseline_days), "first_record": records[0].start.isoformat()},
    )  # fmt: skip
    if values:
        names = sorted(values)
        arr = np.stack([values[n] for n in names], axis=1)
        ds["parameter"] = (("time", "tracked_parameter"), arr[..., 0], {"long_name": "followed change (SI)"})
        ds["parameter_low"] = (("time", "tracked_parameter"), arr[..., 1], {"long_name": "5% quantile"})
        ds["parameter_high"] = (("time", "tracked_parameter"), arr[..., 2], {"long_name": "95% quantile"})
        ds = ds.assign_coords(tracked_parameter=names)
    return ds


def alarms_json(table: xr.Dataset) -> dict:
    """The ``--json`` summary: ``{"records": N, "alarms": [{"time", "day", "effects", "verdict"}]}``."""
    out = []
    for i in range(table.sizes.get("alarm", 0)):
        time = np.datetime_as_string(table.alarm_time.values[i], unit="s") + "Z"
        effects = [str(table.alarm_effect.values[i])] if bool(table.alarm_named.values[i]) else []
        named = float(table.alarm_named_day.values[i])
        out.append({"time": time, "day": round(float(table.alarm_day.values[i]), 4),
                    "onset_day": round(float(table.alarm_onset_day.values[i]), 4),
                    "named_day": None if np.isnan(named) else round(named, 4), "effects": effects,
                    "verdict": str(table.alarm_verdict.values[i])})  # fmt: skip
    return {"records": int(table.sizes["time"]), "alarms": out}
