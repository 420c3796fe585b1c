"""The ``twin observe`` sub-command: what a sensor layout and a record can determine, before any data."""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np


def observe_text(obs, ident=None) -> str:
    """The observability table (and the identifiability table when given) as text."""
    ex = json.loads(obs.attrs["excitation"])
    lines = [f"{obs.attrs['model']}: {obs.sizes['mode']} target modes, {obs.sizes['channel']} channels, "
             f"{ex['duration_s']:g} s at {ex['fs_hz']:g} Hz, noise std {ex['noise_std_m']:.3g} m",
             f"{'mode':>4} {'f [Hz]':>8} {'zeta %':>7} {'best SNR dB':>11} {'std f %':>8} {'std zeta %':>10}  "
             f"{'best channel':<12} verdict"]  # fmt: skip
    for i in range(obs.sizes["mode"]):
        r = obs.isel(mode=i)
        f, z = float(r.frequency), float(r.damping_ratio)
        channel = str(obs.channel.values[int(np.argmax(r.snr_db.values))])
        verdict = "observable" if bool(r.observable) else f"not observable: {str(r.reason.values)}"
        lines.append(f"{int(r.mode):4d} {f:8.2f} {100 * z:7.2f} {float(r.best_snr_db):11.1f} "
                     f"{100 * float(r.frequency_std) / f:8.3g} {100 * float(r.damping_ratio_std) / z:10.3g}  "
                     f"{channel:<12} {verdict}")  # fmt: skip
    lines.append(f"{int(obs.observable.sum())} of {obs.sizes['mode']} target modes observable ({obs.attrs['rule']}); "
                 "std: single-mode Whittle bound (what SSI reaches, about 2x in practice)")  # fmt: skip
    if ident is not None:
        lines += ["", f"expected posterior std of the parameters ({ident.attrs['method']}; modes used "
                      f"{ident.attrs['modes_used']}):",
                  f"{'parameter':<24} {'scale':>10} {'std':>10} {'std %':>8}  verdict"]  # fmt: skip
        for p in ident.parameter.values:
            r = ident.sel(parameter=p)
            lines.append(f"{p:<24} {float(r.scale):10.3g} {float(r['std']):10.3g} {100 * float(r.relative_std):8.3g}  "
                         f"{'determined' if bool(r.determined) else 'NOT determined'}")  # fmt: skip
        lines.append(f"{int(ident.determined.sum())} of {ident.sizes['parameter']} parameters determined "
                     f"(std below 10% of the scale: |nominal|, or the effect's plausible size)")  # fmt: skip
    return "\n".join(lines)


def _observe(args: argparse.Namespace) -> int:
    from twin.design import Excitation, identifiability, observability
    from twin.fem import load_model
    from twin.fem.truthfile import load_truth
    from twin.update.problem import select_parameters

    model = load_model(args.model)
    truth = None if args.truth is None else load_truth(args.truth, model)
    excitation = Excitation(turbulence_asd=args.turbulence, noise_ratio=args.noise, duration_s=args.duration,
                            fs_hz=args.fs)  # fmt: skip
    command = " ".join(sys.argv)
    obs = observability(model, excitation, truth=truth, fmax_hz=args.fmax, command=command)
    ident = None
    if args.params or args.fsi:
        names = select_parameters(model, args.params) if args.params else []
        ident = identifiability(model, names, fsi=args.fsi, excitation=excitation, truth=truth, observability=obs,
                                fmax_hz=args.fmax, command=command)  # fmt: skip
    if args.output:
        from twin.netcdf import write_netcdf

        write_netcdf(obs, args.output)
    print(observe_text(obs, ident))
    return 0
