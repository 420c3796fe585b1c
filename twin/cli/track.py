"""The ``twin`` sub-commands of the twin over time: campaign and track."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from twin.cli.common import add_algorithm, add_scheduler, command, tasks
from twin.defaults import BASELINE_DAYS, FALSE_ALARMS_PER_YEAR


def add_commands(sub) -> None:
    """Add ``twin campaign`` and ``twin track`` to the sub-parsers ``sub``."""
    p = command(
        sub,
        "campaign",
        "simulate a campaign of records through the FMU under changing operation",
        "Simulates a record every few hours for days or years (the schedule: days, records_per_day,\n"
        "duration; how the operating conditions vary; hidden changes with their start day and ramp),\n"
        "each at its operating point with the model's laws applied. One record_<index>.nc per record in\n"
        "the folder, with its start time and operating data; records already there are kept, so an\n"
        "interrupted campaign goes on where it stopped, and the same schedule with more days simulates\n"
        "only the days added.",
        [
            "twin campaign hydro_unit --schedule schedule.toml -o records --seed 1 --workers 2",
            "twin campaign hydro_unit --schedule schedule.toml -o records --json",
        ],
        _campaign,
    )
    p.add_argument("model", help="model file with [[condition]] and [[law]] tables, or a shipped model's name")
    p.add_argument("--schedule", required=True, metavar="SCHEDULE.toml", help="the campaign's schedule")
    p.add_argument("-o", "--out", required=True, metavar="DIR", help="folder of the records")
    p.add_argument("--seed", type=int, default=1, help="seed of the operation's dispatch and of every record")
    p.add_argument("--json", action="store_true", help="print a summary as JSON")
    add_scheduler(p, "records")

    p = command(
        sub,
        "track",
        "track a unit over a folder of records: trends, alarms, what changed",
        "Extracts each record's modes once (records added later are processed on the next call), finds\n"
        "the model's modes in each, learns over the baseline days how the operating conditions move them\n"
        "through the model's laws, watches what the conditions do not explain on a control chart, and at\n"
        "an alarm names the change (a library effect, or where outside it) and follows it. Writes\n"
        "OUT/track.nc, OUT/report.html and OUT/modes/.",
        [
            "twin track hydro_unit records -o tracking --baseline-days 14",
            "twin track hydro_unit records -o tracking --json",
        ],
        _track,
    )
    p.add_argument("model", help="model file with [[condition]] and [[law]] tables, or a shipped model's name")
    p.add_argument("folder", help="folder of the records (*.nc with start_time and operating_point)")
    p.add_argument("-o", "--out", required=True, metavar="OUT", help="the tracker's folder")
    p.add_argument(
        "--baseline-days",
        type=float,
        default=BASELINE_DAYS,
        help=f"days from the first record over which the laws are learned; no alarm in them "
        f"(default {BASELINE_DAYS:g})",
    )
    p.add_argument(
        "--false-alarms",
        type=float,
        default=FALSE_ALARMS_PER_YEAR,
        metavar="PER_YEAR",
        help=f"false-alarm rate the control limit is set for, per unit-year (default {FALSE_ALARMS_PER_YEAR:g})",
    )
    p.add_argument(
        "--strict",
        action="store_true",
        help="stop at the first record that cannot be used (by default it is set aside with the reason, "
        "and the rest tracked)",
    )
    add_algorithm(p)
    p.add_argument(
        "--json",
        action="store_true",
        help='print {"records": N, "alarms": [{"time", "day", "onset_day", "named_day", "effects", "verdict"}]}',
    )
    add_scheduler(p, "extractions")


def _track(args: argparse.Namespace) -> int:
    from twin.fem import load_model
    from twin.track.tracker import alarms_json, track

    model = load_model(args.model)
    with tasks(args) as client:
        table = track(
            model,
            args.folder,
            args.out,
            baseline_days=args.baseline_days,
            false_alarms_per_year=args.false_alarms,
            tasks=client,
            strict=args.strict,
            extract_options={"algorithm": args.algorithm},
        )
    summary = alarms_json(table)
    if args.json:
        print(json.dumps(summary))
        return 0
    for aside in summary["set_aside"]:
        print(f"set aside {aside['file']}: {aside['reason']}")
    if summary["monitored"] == 0:
        print(
            f"{summary['records']} records, all in the {args.baseline_days:g}-day baseline: none monitored yet, "
            "so no alarm could be raised"
        )
    else:
        print(
            f"{summary['records']} records tracked, {summary['monitored']} after the baseline; "
            f"{len(summary['alarms'])} alarm(s)"
        )
    for a in summary["alarms"]:
        print(f"  {a['time']} (day {a['day']:g}, onset day {a['onset_day']:g}): {a['verdict']}")
    print(f"wrote {Path(args.out) / 'track.nc'} and {Path(args.out) / 'report.html'}")
    return 0


def _campaign(args: argparse.Namespace) -> int:
    from twin.fem import load_model
    from twin.track import campaign, read_schedule
    from twin.track.campaign import campaign_json

    model = load_model(args.model)
    schedule = read_schedule(args.schedule, model)
    with tasks(args) as client:
        table = campaign(model, schedule, args.out, seed=args.seed, tasks=client, command=" ".join(sys.argv))
    summary = campaign_json(table, args.out)
    if args.json:
        print(json.dumps(summary))
    else:
        print(
            f"{summary['records']} records from {summary['first']} to {summary['last']} in {summary['folder']} "
            f"({summary['made']} simulated, {summary['kept']} there already)"
        )
    return 0
