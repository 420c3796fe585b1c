"""Hidden-change diagnosis on synthetic modes: verdict, error fall, parameter errors, time.

For each scenario (:mod:`twin.harness.scenarios`: every library effect at its
reference size, two at once, local changes outside the library, nothing), a
truth hiding it gives paper-style modal samples (13 target modes, 100
samples, pole noise std 0.1 rad/s, 5% shape noise; seeds 3, 4, ...); the
hydro unit without it is diagnosed. The FMU-signal version of this table is
``twin sweep --scenarios benchmarks/loop_suite.txt``.

    python benchmarks/diagnosis.py [--seeds N] [--hidden SPEC,...]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from twin import load_model
from twin.fem.effects import MagneticPull
from twin.fem.truthfile import Truth
from twin.loop.diagnose import diagnose
from twin.fem.effects import effect_label
from twin.harness.scenarios import parse_scenario
from twin.modes.measured import measured_modes

ROOT = Path(__file__).resolve().parent.parent
#: Besides every effect whose reference size the model file declares (not the per-mode FSI):
MORE = [
    "magnetic_pull@1.5+seal_cross_coupling@0.8",
    "shaft_stiffness:18@0.5",
    "disk_mass:generator@1.1",
    "none",
]


def main() -> None:
    from twin.update import synthesize_modes

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--hidden", default=None, help="comma-separated specs (default: every declared one and more)")
    args = parser.parse_args()
    model = load_model(ROOT / "models" / "hydro_unit.toml")
    declared = [effect_label(e) for e in model.reference_changes if not e.per_mode]
    args.hidden = args.hidden or ",".join(declared + MORE)
    print(
        f"{'hidden':<44} {'seed':>4} {'verdict':<17} {'named':<38} {'E before':>9} {'E after':>8} {'fall':>6} "
        f"{'time':>6}  parameter errors / place"
    )
    for spec in args.hidden.split(","):
        scenario = parse_scenario(spec, model)
        truth = scenario.truth_values(model)
        for seed in range(3, 3 + args.seeds):
            effects = scenario.truth().effects or (MagneticPull(0.0),)
            data = synthesize_modes(
                model, Truth(effects), n_modes=13, samples=100, seed=seed, pole_variance=(0.01, 0.01)
            )
            meas = measured_modes(data)
            t0 = time.perf_counter()
            d = diagnose(model, meas)
            elapsed = time.perf_counter() - t0
            f = d.final
            e0 = d.ranking[0].error_before(meas)
            e1 = f.error_after(meas) if (f is not None and d.missing) else e0
            detail = (
                ", ".join(f"{n} {100 * (v / truth[n] - 1):+.1f}%" for n, v in zip(f.names, f.values) if truth.get(n))
                if (f is not None and d.missing)
                else ""
            )
            if d.locations and not d.missing:
                detail = d.locations[0].text()
            right = d.verdict == scenario.expected().split(":")[0].split(",")[0] and set(d.missing) == set(
                scenario.labels
            )
            print(
                f"{spec:<44} {seed:>4} {d.verdict:<17} {'+'.join(d.missing) or '-':<38} {100 * e0:>8.3f}% "
                f"{100 * e1:>7.3f}% {100 * (1 - e1 / e0):>5.1f}% {elapsed:>5.1f}s  {'' if right else 'WRONG '}{detail}"
            )


if __name__ == "__main__":
    np.seterr(all="ignore")
    main()
