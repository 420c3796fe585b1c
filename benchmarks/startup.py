"""Start-up of the ``twin`` command: ``twin --help`` and an argument error, as a ratio to ``python -c pass``.

Each command is run ``--repeat`` times as a fresh process (the first run of
each is a warm-up, not counted) and the median wall time is compared with the
median of ``python -c pass`` run the same way, in the same session: the ratio
is what the command's imports cost on top of starting Python.

    python benchmarks/startup.py [--repeat 15]

Results go to ``benchmarks/results/startup.md``.
"""

from __future__ import annotations

import argparse
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "benchmarks" / "results" / "startup.md"
#: What is timed: a label and the command line (``twin`` is the installed entry point).
COMMANDS = {
    "python -c pass (baseline)": [sys.executable, "-c", "pass"],
    "twin --help": ["twin", "--help"],
    "twin demo --duration 0 (an argument error)": ["twin", "demo", "--duration", "0"],
    "twin modal hydro_unit --speed -1 (an argument error)": ["twin", "modal", "hydro_unit", "--speed", "-1"],
}


def wall_times(argv: list[str], repeat: int) -> list[float]:
    """Wall times [s] of ``repeat`` fresh runs of ``argv``, after one warm-up run."""
    times = []
    for k in range(repeat + 1):
        t0 = time.perf_counter()
        subprocess.run(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=False)
        if k:
            times.append(time.perf_counter() - t0)
    return times


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=15)
    args = ap.parse_args(argv)
    if shutil.which("twin") is None:
        raise SystemExit("the twin command is not installed (pip install -e .)")
    medians = {label: statistics.median(wall_times(cmd, args.repeat)) for label, cmd in COMMANDS.items()}
    base = medians["python -c pass (baseline)"]
    rows = [f"| {label} | {1e3 * t:.0f} | {t / base:.2f} |" for label, t in medians.items()]
    text = "\n".join(
        [
            "# Start-up of the twin command",
            "",
            f"Command: `python benchmarks/startup.py --repeat {args.repeat}`; median wall time of {args.repeat} fresh "
            "processes each (after one warm-up), in one session.",
            "",
            "| command | median [ms] | ratio to python -c pass |",
            "| --- | --- | --- |",
            *rows,
            "",
        ]
    )
    RESULTS.write_text(text, encoding="utf-8")
    print(text)


if __name__ == "__main__":
    main()
