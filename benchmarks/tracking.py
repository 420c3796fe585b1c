"""Benchmark: the tracker over campaigns with hidden changes, without change, and at scale.

Three parts, each a set of ``twin campaign`` runs tracked by ``twin track`` (the Python functions), on
seeds no test uses (from 5000):

``detection``
    For each library effect at its reference size (the model file's ``[reference_changes]``, the
    per-mode FSI left out) and a local change (element 18's bending stiffness), at three sizes, as a step
    and as a ramp: a campaign of ``--baseline-days`` of baseline, one day more, then the change, tracked
    for ``--after-days``. The six cases of an effect share one seed (the same baseline and noise, so they
    differ by the change alone); the modes of their records before the onset, the same signals, are
    extracted once and shared. Per case: the delay of the first alarm after the onset [days], the effect named,
    the days after the onset when the records told it from the runner-up (``alarm_named_day``; "not yet" if
    they had not by the last record), and the followed parameters against the truth at the last record. Per effect: the smallest size
    detected within 7 days, beside the size the identifiability stage predicts before any data
    (:func:`twin.design.identify.identifiability` for one record of the campaign's length at the
    reference point, pooled over the records of 7 days, at three standard deviations).
``false-alarms``
    ``--runs`` campaigns of ``--days`` without change (seeds from ``--seed``, 5900): the alarms, as a rate per unit-year; each campaign's
    wall time (simulation, then one ``twin track`` call over all its records) and the track's size on disk.
``throughput``
    One campaign tracked on a Dask ``LocalCluster`` of 1 and of 2 workers: records per minute, the ratio;
    the track's memory (peak RSS) and its size on disk, scaled to a year. Then where the time goes per
    record, under cProfile: the extraction's steps in one process with one BLAS thread (a worker's
    setting), over 8 of the records, and the tracker's stages after the extraction over all of them
    (a second call on the cached modes, in process).

Run from the repository root (the whole benchmark takes hours on 2 cores):

    python benchmarks/tracking.py detection --out benchmarks/results/tracking_detection.md
    python benchmarks/tracking.py false-alarms --days 180 --runs 2 --out benchmarks/results/tracking_false_alarms.md
    python benchmarks/tracking.py throughput --days 30 --out benchmarks/results/tracking_throughput.md

Options: ``--records-per-day`` (4), ``--duration`` [s] (600), ``--baseline-days`` (14), ``--after-days`` (7),
``--effects`` (a subset of labels), ``--sizes`` (factors of the reference size), ``--workers`` (2),
``--keep DIR`` (keep the records and tracks there instead of a temporary folder), ``--track-into NAME`` (each
case's tracker folder, ``out``: with ``--keep``, a second name tracks the kept records again, beside the first,
without simulating them), ``--onset-day`` (the change's day, a day after the baseline by default: with a second
name, a shorter baseline over the same records, e.g. ``--baseline-days 10 --onset-day 15``).
"""

from __future__ import annotations

import argparse
import resource
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np
import xarray as xr

from twin.fem import load_model
from twin.fem.effects import effect_label, scaled
from twin.fem.effects import ShaftStiffnessChange
from twin.fem.operation import at_operating_point, with_parameters
from twin.tasks import dask_client
from twin.track import campaign, read_schedule, track
from twin.track.records import adopt
from twin.report.tracking import record_truth

SEED = 5000
SIZES = (0.25, 0.5, 1.0)
LOCAL = "shaft_stiffness:18"


def reference_effects(model) -> dict[str, object]:
    """The effects a detection case hides at size 1: those whose reference size the model file declares (not a
    per-mode one) and a local one."""
    out = {effect_label(e): e for e in model.reference_changes if not e.per_mode}
    out[LOCAL] = ShaftStiffnessChange(18, -0.5)
    return out


def truth_table(effect) -> str:
    """The ``[change.truth."<label>"]`` table of an effect (its number fields)."""
    import dataclasses

    label = effect_label(effect)
    lines = [f'[change.truth."{label}"]']
    for f in dataclasses.fields(effect):
        value = getattr(effect, f.name)
        if isinstance(value, float):
            lines.append(f"{f.name} = {value!r}")
    return "\n".join(lines) + "\n"


def schedule_text(days: float, per_day: int, duration: float, change: tuple[object, float, float] | None) -> str:
    text = f"days = {days:g}\nrecords_per_day = {per_day}\nduration = {duration:g}\n"
    if change is not None:
        effect, start, ramp = change
        text += f"[[change]]\nstart_day = {start:g}\nramp_days = {ramp:g}\n" + truth_table(effect)
    return text


def simulate(model, folder: Path, text: str, seed: int, client) -> None:
    """The campaign of the schedule ``text`` into ``folder/records`` (its records already there kept)."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "schedule.toml").write_text(text)
    campaign(
        model,
        read_schedule(folder / "schedule.toml", model),
        folder / "records",
        seed=seed,
        tasks=client,
        progress=False,
    )


def run_case(model, folder: Path, text: str, seed: int, baseline: float, client, rate: float):
    """One campaign and its tracking: the track's dataset and the seconds of each."""
    t0 = time.perf_counter()
    simulate(model, folder, text, seed, client)
    t1 = time.perf_counter()
    table = track(
        model,
        folder / "records",
        folder / "out",
        baseline_days=baseline,
        false_alarms_per_year=rate,
        tasks=client,
        progress=False,
    )
    return table, t1 - t0, time.perf_counter() - t1


def predicted_size(model, effect, duration: float, n_records: int) -> float:
    """The size factor (of ``effect``) three standard deviations of ``n_records`` records' Fisher information."""
    from twin.design.identify import identifiability
    from twin.design.spectrum import Excitation

    ref = at_operating_point(model, {})
    params = {p.name: p.nominal for p in effect.parameters(ref)}
    names = list(params)
    library = not effect.local
    base = with_parameters(ref, names) if library else ref.with_effects(effect)
    ident = identifiability(base, names, excitation=Excitation(duration_s=duration))
    std = ident["std"].values
    cov = ident.correlation.values * np.outer(std, std)
    v = np.array([params[n] for n in names])
    var = 1.0 / float(v @ np.linalg.pinv(cov) @ v)
    return 3.0 * np.sqrt(var / n_records)


def share_modes(donor: Path, case: Path) -> int:
    """Give ``case`` the cached modes of ``donor``'s records that carry the same signals (same seed, before
    the change): extraction is deterministic, so this spares the time and not the result. Returns how many."""
    (case / "out" / "modes").mkdir(parents=True, exist_ok=True)
    shared = 0
    for record in sorted((case / "records").glob("*.nc")):
        other, modes = donor / "records" / record.name, donor / "out" / "modes" / record.name
        if not (other.exists() and modes.exists()):
            continue
        with xr.open_dataset(record) as a, xr.open_dataset(other) as b:
            same = (
                a.attrs.get("start_time") == b.attrs.get("start_time")
                and a.displacement.equals(b.displacement)
                and a.operating_point.equals(b.operating_point)
            )
        if not same:
            continue
        target = case / "out" / "modes" / record.name
        shutil.copyfile(modes, target)
        adopt(target, record)
        shared += 1
    return shared


def detection(args, model, root: Path, client) -> list[str]:
    """Per effect one seed: its cases share the baseline and the noise, and differ only by the change."""
    effects = reference_effects(model)
    chosen = args.effects or list(effects)
    start = args.onset_day if args.onset_day is not None else args.baseline_days + 1.0
    days = start + args.after_days
    rows = [
        "| effect | seed | size | onset | delay [d] | named | named after [d] | followed at the end (truth) |",
        "| --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    smallest: dict[str, float] = {}
    for label in chosen:
        ref = effects[label]
        seed = SEED + 1 + list(effects).index(label)
        donor = None
        for size in args.sizes:
            for shape, ramp in (("step", 0.0), ("ramp", args.ramp_days)):
                effect = ShaftStiffnessChange(18, -0.5 * size) if label == LOCAL else scaled(ref, size)
                text = schedule_text(days, args.records_per_day, args.duration, (effect, start, ramp))
                case = root / f"{label.replace(':', '_')}_{size:g}_{shape}"
                if args.track_into == "out" or not (case / "records").is_dir():  # else the kept records, again
                    simulate(model, case, text, seed, client)
                if donor is not None and args.track_into == "out":
                    share_modes(donor, case)
                into = case / args.track_into
                if into != case / "out" and (case / "out" / "modes").is_dir() and not (into / "modes").exists():
                    # the same records, extracted with the same options: the tracker checks each by its content
                    shutil.copytree(case / "out" / "modes", into / "modes")
                table = track(
                    model,
                    case / "records",
                    into,
                    baseline_days=args.baseline_days,
                    false_alarms_per_year=args.false_alarms,
                    tasks=client,
                    progress=False,
                )
                donor = donor or case
                after = table.alarm_day.values[table.alarm_day.values >= start] if table.sizes.get("alarm") else []
                delay = float(after[0] - start) if len(after) else float("nan")
                first = int(np.argmax(table.alarm_day.values >= start)) if len(after) else None
                named = str(table.alarm_effect.values[first]) if first is not None else "-"
                settled = float(table.alarm_named_day.values[first]) - start if first is not None else np.nan
                ok = named == label and settled <= 7.0
                if first is not None and not bool(table.alarm_named.values[first]):
                    named = f"cannot yet tell: {named} or {table.alarm_runner_up.values[first]}"
                follow = "-"
                if "tracked_parameter" in table.dims:
                    names = [str(n) for n in table.tracked_parameter.values]
                    truth = record_truth(case / "records", names, model) or {}
                    follow = "; ".join(
                        f"{n} {float(table.parameter.sel(tracked_parameter=n).values[-1]):.3g} "
                        f"[{float(table.parameter_low.sel(tracked_parameter=n).values[-1]):.3g}, "
                        f"{float(table.parameter_high.sel(tracked_parameter=n).values[-1]):.3g}] "
                        f"({float(truth.get(n, np.zeros(1))[-1]):.3g})"
                        for n in names
                    )
                early = int((table.alarm_day.values < start).sum()) if table.sizes.get("alarm") else 0
                wrong = "" if named in (label, "-") or named.startswith("cannot yet tell") else " (wrong)"
                rows.append(
                    f"| {label} | {seed} | {size:g} | {shape} | {delay:.2f} | {named}{wrong}"
                    f"{f' ({early} alarm(s) before the onset)' if early else ''} | "
                    f"{'not yet' if np.isnan(settled) else f'{settled:.2f}'} | {follow} |"
                )
                if ok and shape == "step":
                    smallest[label] = min(smallest.get(label, np.inf), size)
                print(rows[-1], flush=True)
        if not args.keep:
            for case in root.glob(f"{label.replace(':', '_')}_*"):
                shutil.rmtree(case, ignore_errors=True)
    n7 = int(7 * args.records_per_day)
    rows += [
        "",
        "| effect | smallest step detected and named within 7 days | predicted before any data |",
        "| --- | --- | --- |",
    ]
    for label in chosen:
        pred = predicted_size(model, effects[label], args.duration, n7)
        rows.append(f"| {label} | {smallest.get(label, float('nan')):g} | {pred:.2g} |")
    return rows


def false_alarms(args, model, root: Path, client) -> list[str]:
    rows = [
        "| campaign | days | records | alarms | limit | largest statistic | campaign [s] | track [s] | track on disk [MB] |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    total_alarms, total_days = 0, 0.0
    for i in range(args.runs):
        case = root / f"none_{i}"
        text = schedule_text(args.days, args.records_per_day, args.duration, None)
        seed = args.seed + i
        table, t_campaign, t_track = run_case(model, case, text, seed, args.baseline_days, client, args.false_alarms)
        track_bytes = sum(p.stat().st_size for p in (case / "out").rglob("*") if p.is_file())
        n_alarms = int(table.sizes.get("alarm", 0))
        total_alarms += n_alarms
        total_days += args.days - args.baseline_days
        rows.append(
            f"| seed {seed} | {args.days:g} | {table.sizes['time']} | {n_alarms} | "
            f"{float(table.limit):.1f} | {float(np.nanmax(table.statistic.values)):.1f} | "
            f"{t_campaign:.0f} | {t_track:.0f} | {track_bytes / 1e6:.0f} |"
        )
        print(rows[-1], flush=True)
        if not args.keep:
            shutil.rmtree(case, ignore_errors=True)
    rate = total_alarms / (total_days / 365.25)
    alarms = f"{total_alarms} alarm{'' if total_alarms == 1 else 's'}"
    rows += [
        "",
        (
            f"{alarms} in {total_days:g} monitored days (after the baselines): "
            f"{rate:.2g} per unit-year, for a limit set at {args.false_alarms:g} per unit-year"
        ),
    ]
    return rows


def throughput(args, model, root: Path, _client) -> list[str]:
    rows = [
        "| workers | records | campaign [s] | track [s] | records tracked per minute |",
        "| --- | --- | --- | --- | --- |",
    ]
    times = {}
    for workers in (1, 2):
        case = root / f"scale_{workers}"
        text = schedule_text(args.days, args.records_per_day, args.duration, None)
        with dask_client("local", n_workers=workers) as client:
            table, t_campaign, t_track = run_case(
                model, case, text, SEED + 990, args.baseline_days, client, args.false_alarms
            )
        n = table.sizes["time"]
        times[workers] = t_track
        rows.append(f"| {workers} | {n} | {t_campaign:.0f} | {t_track:.0f} | {60 * n / t_track:.1f} |")
        print(rows[-1], flush=True)
        if workers == 2:
            track_bytes = sum(p.stat().st_size for p in (case / "out").rglob("*") if p.is_file())
            per_year = track_bytes * 365.25 / args.days
            year_minutes = 365.25 * args.records_per_day / (60 * n / t_track)
        if workers == 2:
            profile = profile_rows(model, case, args.baseline_days, args.false_alarms)
        if not args.keep:
            shutil.rmtree(case, ignore_errors=True)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    rows += [
        "",
        f"1 -> 2 workers: {times[1] / times[2]:.2f} x faster",
        (
            f"a year of {args.records_per_day} records of {args.duration:g} s a day: about {year_minutes:.0f} min to "
            f"track on 2 workers; the track (modes and track.nc) about {per_year / 1e6:.0f} MB on disk; "
            f"peak memory of this process {peak:.0f} MB"
        ),
        "",
        *profile,
    ]
    return rows


def _cumulative(stats, name: str, caller: str | None = None) -> float:
    """cProfile's cumulative time [s] of the functions called ``name`` (``file.py:name``: in that file only;
    only the calls from ``caller``)."""
    where, _, name = name.rpartition(":")
    total = 0.0
    for (file, _, fn), (_, _, _, ct, callers) in stats.stats.items():
        if fn != name or not file.endswith(where):
            continue
        if caller is None:
            total += ct
        else:
            total += sum(c[3] for (_, _, f), c in callers.items() if f == caller)
    return total


def profile_rows(model, case: Path, baseline_days: float, rate: float) -> list[str]:
    """Where a record's time goes: the extraction's steps and the tracker's stages, per record (cProfile)."""
    import cProfile
    import pstats

    from threadpoolctl import threadpool_limits

    from twin.extract.options import ExtractOptions
    from twin.track.records import _extract_one

    paths = sorted((case / "records").glob("*.nc"))[:8]
    profiler = cProfile.Profile()
    with tempfile.TemporaryDirectory() as cache, threadpool_limits(1, "blas"):
        _extract_one(str(paths[0]), cache=cache, options=ExtractOptions())  # imports and first calls
        profiler.enable()
        for path in paths:
            _extract_one(str(path), cache=cache, options=ExtractOptions())
        profiler.disable()
    st = pstats.Stats(profiler)
    n = len(paths)
    whole = _cumulative(st, "_extract_one")
    prepare, harmonics = _cumulative(st, "prepare"), _cumulative(st, "remove_running_harmonics")
    first, jack = _cumulative(st, "ssi_pass"), _cumulative(st, "jackknife")
    fits, eig = _cumulative(st, "fit", "jackknife"), _cumulative(st, "modes", "jackknife")
    extract, write = _cumulative(st, "extract"), _cumulative(st, "write_modes")
    steps = [
        ("read the record, its checks", prepare - harmonics),
        ("remove the running-speed lines", harmonics),
        ("first SSI pass: realisation, diagram, clusters", first),
        ("jackknife: each sample's singular vectors", fits),
        ("jackknife: each sample's eigen-solutions over the orders", eig),
        ("jackknife: matching and averaging the poles", jack - fits - eig),
        ("the modes' samples, shapes and checks", extract - prepare - first - jack),
        ("write the modes' file", write),
        ("hash the record, the cache's provenance", whole - extract - write),
    ]
    rows = [
        f"Where a record's time goes (cProfile, one process, one BLAS thread; {n} records, "
        f"{whole / n:.2f} s a record extracted):",
        "",
        "| extraction step | s a record | share |",
        "| --- | --- | --- |",
    ]
    rows += [f"| {name} | {t / n:.3f} | {100 * t / whole:.0f}% |" for name, t in steps]

    profiler = cProfile.Profile()
    profiler.enable()
    table = track(
        model, case / "records", case / "out", baseline_days=baseline_days, false_alarms_per_year=rate, progress=False
    )
    profiler.disable()
    st = pstats.Stats(profiler)
    n = table.sizes["time"]
    total = _cumulative(st, "tracker.py:track")
    predictions = _cumulative(st, "_predictions")
    stages = [
        ("check the cache (hash every record)", _cumulative(st, "extract_new")),
        ("read the cached modes", _cumulative(st, "read_cached")),
        ("the model's prediction at each record's point (twice)", predictions),
        ("find the tracked modes", _cumulative(st, "_identify")),
        ("learn the laws", _cumulative(st, "fit_laws")),
        ("the watch: chart, step statistics, naming, following", _cumulative(st, "watch.py:run")),
        ("write track.nc", _cumulative(st, "write_netcdf")),
        ("write the report", _cumulative(st, "write_report")),
    ]
    rows += [
        "",
        f"The tracker after the extraction ({n} records on their cached modes, in process: {total:.1f} s, "
        f"{1e3 * total / n:.0f} ms a record):",
        "",
        "| tracker stage | ms a record | share |",
        "| --- | --- | --- |",
    ]
    rows += [f"| {name} | {1e3 * t / n:.1f} | {100 * t / total:.0f}% |" for name, t in stages]
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("part", choices=["detection", "false-alarms", "throughput"])
    parser.add_argument("--records-per-day", type=int, default=4)
    parser.add_argument("--duration", type=float, default=600.0, help="record length [s]")
    parser.add_argument("--baseline-days", type=float, default=14.0)
    parser.add_argument("--after-days", type=float, default=7.0)
    parser.add_argument("--ramp-days", type=float, default=3.0)
    parser.add_argument("--days", type=float, default=90.0, help="false-alarms and throughput campaigns [days]")
    parser.add_argument("--runs", type=int, default=2)
    parser.add_argument("--seed", type=int, default=SEED + 900, help="false-alarms: the first campaign's seed")
    parser.add_argument("--effects", nargs="*")
    parser.add_argument("--sizes", type=float, nargs="*", default=list(SIZES))
    parser.add_argument("--false-alarms", type=float, default=0.1, help="the chart's rate [per unit-year]")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--keep", type=Path)
    parser.add_argument(
        "--onset-day",
        type=float,
        help="detection: the day each change begins (default: a day after the baseline); with --track-into, the "
        "kept campaigns' day, so a shorter baseline tracks the same records",
    )
    parser.add_argument(
        "--track-into",
        default="out",
        help="detection: each case's tracker folder (another name tracks the kept records again beside the first)",
    )
    parser.add_argument("--out", type=Path)
    args = parser.parse_args()
    model = load_model("hydro_unit")
    root = args.keep or Path(tempfile.mkdtemp(prefix="twin-tracking-"))
    command = "python benchmarks/tracking.py " + " ".join(__import__("sys").argv[1:])
    try:
        if args.part == "throughput":
            rows = throughput(args, model, root, None)
        else:
            with dask_client("local", n_workers=args.workers) as client:
                rows = (detection if args.part == "detection" else false_alarms)(args, model, root, client)
    finally:
        if not args.keep:
            shutil.rmtree(root, ignore_errors=True)
    text = "\n".join(
        [
            f"# Tracking: {args.part}",
            "",
            f"Command: `{command}`",
            "",
            (
                f"Records: {args.records_per_day} a day of {args.duration:g} s; baseline "
                f"{args.baseline_days:g} days; chart set for {args.false_alarms:g} false alarms per unit-year."
            ),
            "",
            *rows,
            "",
        ]
    )
    print(text)
    if args.out:
        args.out.write_text(text)


if __name__ == "__main__":
    main()
