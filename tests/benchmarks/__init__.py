"""Tests of the benchmark scripts, which import each other as top-level modules from ``benchmarks/``."""

import sys
from pathlib import Path

#: The benchmarks folder, put on the import path as running a script from it does.
BENCHMARKS = Path(__file__).resolve().parents[2] / "benchmarks"
if str(BENCHMARKS) not in sys.path:
    sys.path.insert(0, str(BENCHMARKS))
