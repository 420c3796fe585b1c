"""Hidden-effect diagnosis on synthetic modes: rank, error fall, parameter error, time.

For each library effect, a truth with that effect hidden gives paper-style
modal samples (13 target modes, 100 samples, pole noise std 0.1 rad/s, 5%
shape noise; seeds 3, 4, ...); the hydro unit without the effect is
diagnosed. Also: no hidden effect (false alarms) and a local shaft stiffness
loss outside the library.

    python benchmarks/diagnosis.py [--seeds N]
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

import numpy as np

from twin import load_model
from twin.fem.effects import MagneticPull
from twin.fem.truthfile import Truth
from twin.loop.compare import measured_modes
from twin.loop.demo import HIDDEN_EFFECTS, truth_values
from twin.loop.diagnose import diagnose
from twin.update import synthesize_modes

ROOT = Path(__file__).resolve().parent.parent

HIDDEN = HIDDEN_EFFECTS


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=3)
    args = parser.parse_args()
    model = load_model(ROOT / "models" / "hydro_unit.toml")
    print(f"{'hidden effect':<22} {'seed':>4} {'verdict':<16} {'top':<22} {'lnB gap':>8} {'E before':>9} "
          f"{'E after':>8} {'fall':>6} {'time':>6}  parameter errors")  # fmt: skip
    cases = [(k, e) for k, e in HIDDEN.items()] + [("(none)", MagneticPull(0.0)), ("(shaft element 18 at 50%)", None)]
    for label, effect in cases:
        for seed in range(3, 3 + args.seeds):
            truth_model = model
            if effect is None:
                el = model.shaft[18]
                weak = dataclasses.replace(el, material=dataclasses.replace(el.material, E=0.5 * el.material.E,
                                                                            G=0.5 * el.material.G))  # fmt: skip
                truth_model = dataclasses.replace(model, shaft=tuple(weak if e.n == 18 else e for e in model.shaft))
            data = synthesize_modes(truth_model, Truth((effect or MagneticPull(0.0),)), n_modes=13, samples=100,
                                    seed=seed, pole_variance=(0.01, 0.01))  # fmt: skip
            meas = measured_modes(data)
            t0 = time.perf_counter()
            d = diagnose(model, meas)
            elapsed = time.perf_counter() - t0
            top, second = d.ranking[0], d.ranking[1]
            e0, e1 = top.error_before(meas), top.error_after(meas)
            errs = ""
            if effect is not None and label in HIDDEN and top.label == label:
                truth = truth_values(model, effect)
                fitted = dict(zip(top.names, top.values))
                errs = ", ".join(f"{n} {100 * (fitted[n] / v - 1):+.1f}%" for n, v in truth.items() if v)
            if d.locations and d.verdict != "missing effect":
                errs = f"located: element {d.locations[0].element} ({100 * d.locations[0].explained:.0f}% of chi2)"
            print(f"{label:<22} {seed:>4} {d.verdict:<16} {top.label:<22} "
                  f"{top.log_bayes_factor - second.log_bayes_factor:>8.1f} {100 * e0:>8.3f}% {100 * e1:>7.3f}% "
                  f"{100 * (1 - e1 / e0):>5.1f}% {elapsed:>5.1f}s  {errs}")  # fmt: skip


if __name__ == "__main__":
    np.seterr(all="ignore")
    main()
