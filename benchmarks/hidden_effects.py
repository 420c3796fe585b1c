"""Hidden effects in FMU signals: the demo's loop per effect, with rank, error fall and parameter errors.

For each effect of ``twin.loop.demo.HIDDEN_EFFECTS``: simulate the truth
through its FMU (20 min at 256 Hz by default), extract the modes, diagnose the
hydro unit without the effect, add the top-ranked effect and update it
(Laplace). The report folders go to ``--out``.

    python benchmarks/hidden_effects.py [--effects a,b] [--duration S] [--samples J] [--seed N] [--out DIR]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from twin import load_model
from twin.loop.demo import HIDDEN_EFFECTS, default_model_path, run_demo


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--effects", default=",".join(HIDDEN_EFFECTS))
    parser.add_argument("--duration", type=float, default=1200.0)
    parser.add_argument("--samples", type=int, default=20)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--out", default="hidden-effects")
    args = parser.parse_args()
    model = load_model(default_model_path())
    print(f"{'hidden effect':<22} {'verdict':<16} {'top':<22} {'lnB lead':>9} {'E before':>9} {'E after':>8} "
          f"{'fall':>6} {'time':>6}  parameter errors (MAP, std)")  # fmt: skip
    for label in args.effects.split(","):
        t0 = time.perf_counter()
        r = run_demo(Path(args.out) / label.replace(":", "_"), model=model, hidden=label, duration_s=args.duration,
                     samples=args.samples, seed=args.seed, progress=False)  # fmt: skip
        elapsed = time.perf_counter() - t0
        d = r.diagnosis
        top, second = d.ranking[0], d.ranking[1]
        e0, e1 = r.twin.history[0].error, r.twin.history[-1].error
        errs = ""
        if r.posterior is not None:
            ident = r.identified()
            errs = ", ".join(
                f"{n} {100 * e:+.1f}% (std {100 * s / abs(t):.1f}%)"
                for n, e, s, t in zip(ident["parameter"].values, ident["relative_error"].values, ident["std"].values,
                                      ident["truth"].values)
                if np.isfinite(e)
            )  # fmt: skip
        print(f"{label:<22} {d.verdict:<16} {top.label:<22} {top.log_bayes_factor - second.log_bayes_factor:>9.1f} "
              f"{100 * e0:>8.3f}% {100 * e1:>7.3f}% {100 * (1 - e1 / e0):>5.1f}% {elapsed:>5.0f}s  {errs}")  # fmt: skip


if __name__ == "__main__":
    main()
