"""The watch after the baseline, record by record, on pole parts made by the model itself (no extraction)."""

import datetime as dt
from pathlib import Path

import numpy as np

from twin.track import detect, explain
from twin.track.physics import LawFit, tracked_modes
from twin.track.records import RecordInfo
from twin.track.watch import Chart, Series, Watch


def test_a_step_alarms_after_its_onset_is_named_and_followed(hydro_unit):
    """A magnetic pull of -2.5e7 N/m (a quarter of its reference size) from record 30 on: one alarm at or after
    the onset naming it, a follower whose history is empty before the alarm and holds the truth in its interval
    at the end."""
    rng = np.random.default_rng(21)
    model = hydro_unit
    tracked = tracked_modes(model, tuple(model.channels), 40.0)
    m, n, onset, base = len(tracked.poles), 45, 30, 24
    truth = -2.5e7
    cands = [c for c in explain.candidates(model, tracked) if c.library]
    pull = next(c for c in cands if c.label == "magnetic_pull")
    quiet = explain.changed_poles(model, tracked, {}, [])[0]
    changed = explain.changed_poles(model, tracked, {}, [(pull, np.array([truth]))])[0]
    # standard errors as a record's jackknife gives them: 2e-4 of a frequency, 5% of a decay rate
    sig = np.tile(np.concatenate([0.05 * np.abs(quiet[:m]), 2e-4 * np.abs(quiet[m:])]), (n, 1))
    y = np.array([changed if t >= onset else quiet for t in range(n)]) + rng.normal(0.0, 1.0, (n, 2 * m)) * sig
    start = dt.datetime(2026, 1, 1, tzinfo=dt.timezone.utc)
    records = [RecordInfo(Path(f"r{t}.nc"), start + dt.timedelta(hours=6 * t), {}) for t in range(n)]
    days = np.arange(n) * 0.25
    residual = y - quiet
    laws = LawFit(np.zeros(0), np.zeros((0, 0)), np.zeros(2 * m), (), np.zeros(0))
    baseline = detect.learn_baseline(residual[:base], sig[:base])
    watched = detect.Baseline(baseline.center[m:], baseline.scale[m:], baseline.correlation[m:, m:], base)
    limit = detect.threshold(m, base, 4 * 365.25, 0.1)
    series = Series(records, days, y, sig, residual, np.zeros((n, m, 0)))

    watch = Watch(model, tracked, cands, series, Chart(baseline, watched, limit, laws)).run(base)

    assert np.isnan(watch.statistic[:base]).all() and np.isfinite(watch.statistic[base:]).all()
    assert len(watch.alarms) == 1
    alarm = watch.alarms[0]
    assert onset <= alarm.record <= onset + 2 and base <= alarm.onset <= alarm.record
    assert alarm.verdict.label == "magnetic_pull" and alarm.named is not None
    (follower,) = watch.followers
    assert follower.cand.label == "magnetic_pull" and follower.history.shape == (n, 1, 3)
    assert np.isnan(follower.history[: alarm.record]).all()
    value, low, high = follower.history[-1, 0]
    assert low < truth < high
    # the residual against the model with the change followed is back to the noise
    assert np.all(np.abs(watch.current[-1, m:] - baseline.center[m:]) < 5 * sig[-1, m:] * baseline.scale[m:])


def test_without_a_change_the_step_statistics_stay_below_their_limits(hydro_unit):
    """Records of the unchanged model, noise as stated: 160 records after the baseline raise no alarm from the
    omnibus chart or from the step statistics along the 44 candidates (each under 1 over its limit)."""
    rng = np.random.default_rng(8)
    model = hydro_unit
    tracked = tracked_modes(model, tuple(model.channels), 40.0)
    m, n, base = len(tracked.poles), 200, 40
    cands = explain.candidates(model, tracked)
    quiet = explain.changed_poles(model, tracked, {}, [])[0]
    sig = np.tile(np.concatenate([0.05 * np.abs(quiet[:m]), 2e-4 * np.abs(quiet[m:])]), (n, 1))
    sig *= rng.uniform(0.5, 2.0, size=(n, 1))  # records of other lengths and loads: their errors vary
    y = quiet + rng.normal(0.0, 1.0, (n, 2 * m)) * sig
    start = dt.datetime(2026, 1, 1, tzinfo=dt.timezone.utc)
    records = [RecordInfo(Path(f"r{t}.nc"), start + dt.timedelta(hours=6 * t), {}) for t in range(n)]
    laws = LawFit(np.zeros(0), np.zeros((0, 0)), np.zeros(2 * m), (), np.zeros(0))
    residual = y - quiet
    baseline = detect.learn_baseline(residual[:base], sig[:base])
    watched = detect.Baseline(baseline.center[m:], baseline.scale[m:], baseline.correlation[m:, m:], base)
    rate, share = 4 * 365.25, detect.DIRECTED_SHARE
    limit = detect.threshold(m, base, rate, (1 - share) * 0.1)
    each = share * 0.1 / (len(cands) * len(detect.ONSETS))
    directed = np.array([detect.threshold(len(c.parameters), base, rate, each, m) for c in cands])
    series = Series(records, np.arange(n) * 0.25, y, sig, residual, np.zeros((n, m, 0)))

    watch = Watch(model, tracked, cands, series, Chart(baseline, watched, limit, laws, directed)).run(base)

    assert not watch.alarms
    assert np.isnan(watch.directed[:base]).all()
    assert np.all((watch.directed[base:] >= 0) & (watch.directed[base:] < 1))
