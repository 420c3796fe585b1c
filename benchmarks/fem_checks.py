"""Measure the FEM against ROSS 2.3 and time building + solving the hydro unit.

Run from the repository root:  python benchmarks/fem_checks.py
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent


def main() -> None:
    start = time.perf_counter()
    import twin

    import_s = time.perf_counter() - start
    ref = np.load(ROOT / "tests" / "data" / "ross_rotor_28dof.npz")
    model = twin.load_model(ROOT / "models" / "ross_reference.toml")
    mats = model.matrices()
    print("ROSS 2.3 reference rotor, largest relative deviation (max |ours - ROSS| / max |ROSS|):")
    for kind in ("M", "K", "C", "G"):
        print(f"  {kind}: {np.abs(mats[kind] - ref[kind]).max() / np.abs(ref[kind]).max():.2e}")
    for row, rpm in enumerate((0.0, 134.0)):
        expected = ref["eigenvalues"][row]
        poles = twin.modal(model, speed_rpm=rpm, n_modes=len(expected)).pole.values
        err = np.abs(poles - expected) / np.abs(expected)
        print(f"  eigenvalues at {rpm:5.1f} rpm: {err.max():.2e} (first forward mode Re = {poles[0].real:+.6f} 1/s)")

    path = ROOT / "models" / "hydro_unit.toml"
    times = []
    for _ in range(20):
        t0 = time.perf_counter()
        twin.modal(twin.load_model(path))
        times.append(time.perf_counter() - t0)
    print(
        f"hydro unit: import {import_s:.2f} s; load + assemble + modal (116 DOF, all modes): "
        f"median {1e3 * np.median(times):.0f} ms, max {1e3 * max(times):.0f} ms over 20 runs"
    )


if __name__ == "__main__":
    main()
