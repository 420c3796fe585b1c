"""The watch after the baseline: the control chart record by record, and at each alarm the change named,
updated and followed.

:class:`Watch` holds the state a tracker carries from one record to the next: the chart's recursion, the
followed changes (:class:`twin.track.explain.Follower`), the alarms (:class:`Alarm`) and the reading of
an alarm whose name the records cannot yet tell (:class:`Reading`). :meth:`Watch.step` takes one record:

1. every followed change is updated by the record (its extended Kalman filter);
2. a reading weighs the records since its onset again, and names the change when one stands out;
3. the record's residual against the model with the followed changes goes to the chart: the omnibus
   MEWMA, and the step statistic along each candidate change (:class:`twin.track.detect.StepGLR`);
4. above either's limit, the records since the onset (:func:`twin.track.detect.onset`) name the change, which
   is updated on them and followed; the chart starts again.

A name the records since the onset cannot yet tell from the others (its posterior odds against them all
below :data:`twin.track.explain.MIN_MARGIN`) is a reading: its change is followed, so the chart goes on
watching what it does not explain, and the records since the onset are weighed again as each one comes,
until one name stands out; the change is then updated anew if the name changed. A reading still open at
the next alarm ends with its best change followed but unnamed: a name is given only when the records
support it. A change that grows (a
ramp) alarms while it is small, when the records cannot yet say which it is. An alarm that names a change
already followed (one that grew faster than its filter's process noise lets it follow) re-estimates that
change as a whole on the records since the new onset, so one change has one follower.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from twin.fem.model import RotorModel
from twin.track import detect, explain
from twin.track.physics import LawFit, Tracked

log = logging.getLogger(__name__)

#: The diagnosis and the followed changes use the measured damping (the poles' real parts) beside the
#: frequencies; the chart watches the frequencies alone. See the decision log's "tracking-damping" page.
DIAGNOSE_WITH_DAMPING = True


@dataclass(frozen=True)
class Series:
    """The records as the watch reads them: ``n`` records, ``m`` tracked modes, pole parts real then imaginary.

    Attributes
    ----------
    records : list of Record
        The records (:func:`twin.track.records.records_in`), in time order.
    days : (n,) float
        Days after the first record.
    y, sig : (n, 2m) float
        Measured pole parts [1/s] and their standard errors (NaN where a mode was not found).
    residual : (n, 2m) float
        What the laws learned over the baseline do not explain (their prediction and offsets taken out).
    drift : (n, m, K) float
        Each record's frequency parts' sensitivity to the laws' ``K`` slopes, less the baseline's mean: the
        chart counts the slopes' uncertainty (:class:`twin.track.detect.MEWMA`).
    """

    records: list
    days: np.ndarray
    y: np.ndarray
    sig: np.ndarray
    residual: np.ndarray
    drift: np.ndarray


@dataclass(frozen=True)
class Chart:
    """What the baseline taught the chart: every pole part's baseline, the watched (frequency) parts'
    baseline, the control limit and the learned laws."""

    baseline: detect.Baseline
    watched: detect.Baseline
    limit: float
    laws: LawFit
    #: The limit of each candidate's step statistic (:class:`twin.track.detect.StepGLR`), in the order of the
    #: watch's candidates; None for the omnibus chart alone.
    directed_limits: np.ndarray | None = None


@dataclass
class Alarm:
    """An alarm: the record that raised it, the record its change began at (the onset), what it names, and
    the record at which the records told that change from the others (None while they could not)."""

    record: int
    onset: int
    verdict: explain.Verdict
    named: int | None = None


@dataclass
class Reading:
    """A change followed under a name the records could not yet tell from another's: its follower, the onset,
    the alarm it answers, the alarm's own verdict, each record's residual without the change, and the
    follower's state (mean, covariance, day) before the alarm if it was followed already."""

    follower: explain.Follower
    onset: int
    alarm: Alarm
    verdict: explain.Verdict
    without: np.ndarray
    before: tuple | None = None


@dataclass
class Watch:
    """The chart and the followed changes over the records after the baseline (module docstring).

    ``statistic`` (the chart's, per record), ``directed`` (the largest of the candidates' step statistics
    over its limit, per record: an alarm above 1), ``current`` (each record's residual against the model with
    the changes followed so far), ``followers`` and ``alarms`` are what a track keeps.
    """

    model: RotorModel
    tracked: Tracked
    candidates: list[explain.Linearised]
    series: Series
    chart: Chart
    statistic: np.ndarray = field(init=False)
    current: np.ndarray = field(init=False)
    followers: list[explain.Follower] = field(init=False, default_factory=list)
    alarms: list[Alarm] = field(init=False, default_factory=list)
    reading: Reading | None = field(init=False, default=None)
    #: The first record of the chart's current run: after the baseline, then after each alarm.
    start: int = field(init=False, default=0)

    def __post_init__(self) -> None:
        self.statistic = np.full(len(self.series.records), np.nan)
        self.directed = np.full(len(self.series.records), np.nan)
        self.current = self.series.residual.copy()
        drift = self.series.drift
        uncertain = self.chart.laws.covariance if drift.shape[2] else None
        self._smooth = detect.MEWMA(self.chart.watched, uncertain=uncertain)
        self._steps = (
            None
            if self.chart.directed_limits is None
            else detect.StepGLR(
                self.chart.watched.correlation,
                [c.jacobian[self.m :] for c in self.candidates],
                detect.level_variance(self.chart.watched.n_records),
                uncertain,
            )
        )

    @property
    def m(self) -> int:
        """The number of tracked modes (pole parts: real ``[:m]``, imaginary ``[m:]``)."""
        return len(self.tracked.poles)

    def run(self, start: int) -> Watch:
        """Every record from ``start`` (the first after the baseline) on."""
        self.start = start
        for t in range(start, len(self.series.records)):
            self.step(t)
        return self

    def observation(self, t: int) -> np.ndarray:
        """Record ``t``'s pole parts less the laws' offsets and the baseline's centre, as the diagnosis and the
        followers see them (the real parts NaN unless :data:`DIAGNOSE_WITH_DAMPING`)."""
        obs = self.series.y[t] - self.chart.laws.offsets - self.chart.baseline.center
        if not DIAGNOSE_WITH_DAMPING:
            obs[: self.m] = np.nan
        return obs

    def diagnosis(self, residuals: np.ndarray, k: int, t: int, others: list) -> explain.Verdict:
        """The candidates weighed on the residuals of records ``k..t`` pooled (the damping's parts left out unless
        :data:`DIAGNOSE_WITH_DAMPING`), the leading ones refitted on the full model at the records' mean
        operating point with the changes ``others`` (candidate, values) on it."""
        s = self.series
        mean, pooled_cov = detect.pooled(residuals[k : t + 1], s.sig[k : t + 1], self.chart.baseline)
        if not DIAGNOSE_WITH_DAMPING:
            mean[: self.m] = np.nan
        points = [s.records[i].point for i in range(k, t + 1)]
        point = {key: float(np.mean([p[key] for p in points])) for key in points[0]} if points else {}
        setting = explain.Setting(self.model, self.tracked, point, others)
        return explain.diagnose(mean, pooled_cov, self.candidates, setting)

    def _reading_others(self) -> list:
        """The changes on the model beside a reading's: the other followers, and its own as it was before."""
        reading = self.reading
        others = [(f.cand, f.mean) for f in self.followers if f is not reading.follower]
        if reading.before is not None:
            others.append((reading.follower.cand, reading.before[0]))
        return others

    def step(self, t: int) -> None:
        """One record: the followers updated, a reading weighed again, the chart, and an alarm if it rises."""
        s, m = self.series, self.m
        point, cov = s.records[t].point, detect.record_covariance(s.sig[t], self.chart.baseline)
        obs = self.observation(t)
        for f in self.followers:
            f.update(point, obs, cov, s.days[t], [(g.cand, g.mean) for g in self.followers if g is not f])
        if self.reading is not None:
            reading, others = self.reading, self._reading_others()
            g = explain.changed_poles(self.model, self.tracked, point, others)[0] if others else None
            reading.without[t] = s.residual[t] if g is None else s.y[t] - self.chart.laws.offsets - g
            self._settle(t, force=False)
        if self.followers:
            g, _ = explain.changed_poles(self.model, self.tracked, point, [(f.cand, f.mean) for f in self.followers])
            self.current[t] = s.y[t] - self.chart.laws.offsets - g
        watched = self.chart.watched
        z = detect.standardised(self.current[t, m:], s.sig[t, m:], watched)
        weight = np.nan_to_num(1.0 / (watched.scale * s.sig[t, m:]))  # 0 where the mode was not found
        g = np.nan_to_num(s.drift[t] * weight[:, None])
        self.statistic[t] = self._smooth.add(z, g)
        alarm = self.statistic[t] > self.chart.limit
        if self._steps is not None:
            self.directed[t] = float(np.max(self._steps.add(z, weight, g) / self.chart.directed_limits))
            alarm = alarm or self.directed[t] > 1.0
        if alarm:
            self._alarm(t)
            self._smooth.reset()
            if self._steps is not None:
                self._steps.reset()
            self.start = t + 1
        for f in self.followers:
            f.keep(t)

    def _alarm(self, t: int) -> None:
        """The alarm at record ``t`` (the chart's run started at :attr:`start`): the change named and followed."""
        s, m, start = self.series, self.m, self.start
        if self.reading is not None:
            self._settle(t, force=True)
        k = start + detect.onset(
            detect.standardised(self.current[start : t + 1, m:], s.sig[start : t + 1, m:], self.chart.watched),
            self.chart.watched,
        )
        verdict = self.diagnosis(self.current, k, t, [(f.cand, f.mean) for f in self.followers])
        alarm = Alarm(t, k, verdict)
        self.alarms.append(alarm)
        if verdict.log_evidence >= explain.MIN_LOG_EVIDENCE:
            cand = next(c for c in self.candidates if c.label == verdict.label)
            same = next((f for f in self.followers if f.cand is cand), None)
            before = None if same is None else (same.mean.copy(), same.cov.copy(), same.day)
            f = self._follow(cand, k, t)
            alarm.verdict = explain.named(verdict, f.cand, f.mean, f.cov)
            alarm.named = t if alarm.verdict.clear else None
            if not alarm.verdict.clear:
                self.reading = Reading(f, k, alarm, alarm.verdict, self.current.copy(), before)
        log.info(
            "alarm at %s (onset %s): %s",
            s.records[t].start.isoformat(),
            s.records[k].start.isoformat(),
            alarm.verdict.text,
        )

    def _observed(self, k: int, t: int) -> list:
        """``(point, observation, covariance)`` of the records ``k..t``."""
        s = self.series
        return [
            (s.records[i].point, self.observation(i), detect.record_covariance(s.sig[i], self.chart.baseline))
            for i in range(k, t + 1)
        ]

    def _follow(self, cand: explain.Linearised, k: int, t: int) -> explain.Follower:
        """The change ``cand`` updated on the records ``k..t``: a new follower, or, for a change already
        followed (a ramp that outran its filter), the same one re-estimated as a whole."""
        same = next((f for f in self.followers if f.cand.label == cand.label), None)
        others = [(f.cand, f.mean) for f in self.followers if f is not same]
        value, value_cov = explain.update(self.model, self.tracked, cand, self._observed(k, t), others)
        day = self.series.days[t]
        if same is not None:
            same.mean, same.cov, same.day = value, value_cov, day
            return same
        f = explain.Follower(self.model, self.tracked, cand, value, value_cov, day, len(self.series.records))
        self.followers.append(f)
        return f

    def _settle(self, t: int, force: bool) -> None:
        """Weigh the reading's records again; name the change when one stands out. With ``force`` (a new alarm
        comes) the reading ends either way: the best change is followed, but named only if it stands out, and
        the alarm otherwise keeps saying which changes the records cannot yet tell apart."""
        reading, s = self.reading, self.series
        verdict = self.diagnosis(reading.without, reading.onset, t, self._reading_others())
        if not verdict.clear and not force:
            return
        if verdict.log_evidence < explain.MIN_LOG_EVIDENCE:
            verdict = reading.verdict  # the evidence went: keep what the alarm said
        f = reading.follower
        if verdict.label != f.cand.label:
            if reading.before is None:
                self.followers.remove(f)
            else:  # a change followed before the alarm: back to what it was
                f.mean, f.cov, f.day = reading.before
            f = self._follow(next(c for c in self.candidates if c.label == verdict.label), reading.onset, t)
        note = (
            ""
            if verdict.label == reading.verdict.label
            else f"first read as {reading.verdict.label} on day {s.days[reading.alarm.record]:.2f}"
        )
        reading.alarm.verdict = explain.named(verdict, f.cand, f.mean, f.cov, note=note)
        reading.alarm.named = t if verdict.clear else None
        log.info(
            "the change since %s %s on %s: %s",
            "named" if verdict.clear else "still unnamed",
            s.records[reading.onset].start.isoformat(),
            s.records[t].start.isoformat(),
            reading.alarm.verdict.text,
        )
        self.reading = None
