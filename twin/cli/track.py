"""The ``twin`` sub-commands of the twin over time: campaign (and, to come, track)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path


def add_commands(sub, command, add_scheduler) -> None:
    """Add ``twin campaign`` to the sub-parsers ``sub`` (with the parser module's helpers)."""
    p = command(sub, "campaign", "simulate a campaign of records through the FMU under changing operation",
                "Simulates a record every few hours for days or years (the schedule: days, records_per_day,\n"
                "duration; how the operating conditions vary; hidden changes with their start day and ramp),\n"
                "each at its operating point with the model's laws applied. One record_<index>.nc per record in\n"
                "the folder, with its start time and operating data; records already there are kept, so an\n"
                "interrupted campaign goes on where it stopped.",
                ["twin campaign hydro_unit --schedule schedule.toml -o records --seed 1 --workers 2",
                 "twin campaign hydro_unit --schedule schedule.toml -o records --json"],
                _campaign)  # fmt: skip
    p.add_argument("model", help="model file with [[condition]] and [[law]] tables, or a shipped model's name")
    p.add_argument("--schedule", required=True, metavar="SCHEDULE.toml", help="the campaign's schedule")
    p.add_argument("-o", "--out", required=True, metavar="DIR", help="folder of the records")
    p.add_argument("--seed", type=int, default=1, help="seed of the operation's dispatch and of every record")
    p.add_argument("--json", action="store_true", help="print a summary as JSON")
    add_scheduler(p, "records")


def _campaign(args: argparse.Namespace) -> int:
    from twin.cli.loop import _tasks
    from twin.fem import load_model
    from twin.track import campaign, read_schedule

    model = load_model(args.model)
    schedule = read_schedule(args.schedule, model)
    with _tasks(args) as client:
        table = campaign(model, schedule, args.out, seed=args.seed, tasks=client, command=" ".join(sys.argv))
    made = int(table.made.sum())
    summary = {"records": int(table.sizes["record"]), "made": made, "kept": int(table.sizes["record"]) - made,
               "folder": str(Path(args.out)), "first": str(table.start_time.values[0]),
               "last": str(table.start_time.values[-1])}  # fmt: skip
    if args.json:
        print(json.dumps(summary))
    else:
        print(f"{summary['records']} records from {summary['first']} to {summary['last']} in {summary['folder']} "
              f"({made} simulated, {summary['kept']} there already)")  # fmt: skip
    return 0
