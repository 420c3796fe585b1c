"""Records the twin did not make: twin's extraction on its defaults beside pyOMA2's automatic SSI-cov.

The corpus (:func:`corpus`): synthetic records of structures that are not the
twin's (:mod:`twin.extract.corpus`: shear frames, a cantilever beam, the ROSS
reference rotor with its bearings' cross-coupling left out, two modes 1%
apart), 60 s to 1 h long, damping 0.1% to 10%, displacement, velocity,
acceleration and mixed channels, noise from 40 dB down to where modes sink
below the observability limit; and KOMA's measured-like shear-frame record
(``tests/data/shearframe.npz``). Per record, for ``twin.extract.extract`` with
its defaults and for pyOMA2's SSI-cov (its defaults but the block rows, twin's;
orders to 100; its automatic clustering presets ``Reynders`` and ``Neu``): the
visible modes found (frequency within 0.5%, or within three times the standard
error one record allows where that is wider, :func:`twin.extract.corpus.frequency_limit`;
MAC >= 0.95 in displacement), missed, the spurious estimates (2% from every
mode, or a second estimate of one) and the wall time. (pyOMA2's ``Magalhaes``
preset kept 130 to 200 clusters of noise poles on these records.)

Run:  python benchmarks/outside_records.py [--only NAME,...] [--no-pyoma] [--seed 1 | --seeds 2,3,...]
                                         [--algorithm ssi|plscf] [--json FILE]
Needs ``pip install pyOMA-2`` for pyOMA2's columns (left out with a note otherwise).
"""

from __future__ import annotations

import argparse
import json
import time
import warnings
from pathlib import Path

import numpy as np
import xarray as xr

from twin.errors import NoModeError
from twin.extract import extract
from twin.extract.corpus import (
    close_pair,
    cantilever,
    frequency_limit,
    from_matrices,
    score,
    shear_frame,
    simulate_record,
    truth_modes,
)
from twin.extract.quantities import derivative_orders
from twin.extract.signals import check_record

DATA = Path(__file__).resolve().parent.parent / "tests" / "data"
V, A = "velocity", "acceleration"


def ross_rotor():
    """The ROSS 2.3 reference rotor (28 DOF) at 14 rad/s; stiffness made symmetric (its bearings'
    cross-coupling makes the first forward mode unstable), proximeter pairs at nodes 1, 2, 4, 5."""
    d = np.load(DATA / "ross_rotor_28dof.npz")
    K = (d["K"] + d["K"].T) / 2
    sensors = {f"n{k}_{ax}": 4 * k + j for k in (1, 2, 4, 5) for j, ax in enumerate("xy")}
    forced = [4 * k + j for k in range(7) for j in (0, 1)]
    return from_matrices(
        "ROSS reference rotor", d["M"], d["C"], K, sensors, forced, G=d["G"], speed_rad_s=float(d["speed"][1])
    )


def corpus(seed: int = 1):
    """(name, structure or None, record, truth) per corpus record; structures are built lazily."""
    stiff = 1.6e8  # a shear frame 6.3 times stiffer: modes 5.7-38 Hz
    cases = [
        ("frame5 1% 600s disp 40dB", lambda: shear_frame(5, damping_ratio=0.01), 600, 20, 40, "displacement"),
        ("frame5 0.1% 1h vel 40dB", lambda: shear_frame(5, damping_ratio=0.001), 3600, 20, 40, V),
        (
            "frame10 0.2% 240s vel+acc 40dB",
            lambda: shear_frame(10, stiffness_n_m=stiff, damping_ratio=0.002),
            240,
            100,
            40,
            [V, V, V, A, A, V, V, V, A, A],
        ),
        ("frame8 5% 300s acc 30dB", lambda: shear_frame(8, damping_ratio=0.05), 300, 20, 30, A),
        (
            "frame5 0.5% 60s mixed 40dB",
            lambda: shear_frame(5, stiffness_n_m=stiff, damping_ratio=0.005),
            60,
            100,
            40,
            ["displacement", V, A, V, "displacement"],
        ),
        ("cantilever 2% 120s acc 40dB", lambda: cantilever(10, damping_ratio=0.02), 120, 400, 40, A),
        (
            "cantilever 10% 600s mixed 30dB",
            lambda: cantilever(10, damping_ratio=0.10),
            600,
            400,
            30,
            ["displacement", V, A, V, A],
        ),
        ("ROSS rotor 300s disp 30dB", ross_rotor, 300, 400, 30, "displacement"),
        (
            "two modes 1% apart 0.5% 1800s",
            lambda: close_pair(5.0, 0.01, 0.005, sensors=3),
            1800,
            20,
            40,
            "displacement",
        ),
        ("frame5 1% 600s disp 10dB", lambda: shear_frame(5, damping_ratio=0.01), 600, 20, 10, "displacement"),
        ("frame5 1% 600s disp 0dB", lambda: shear_frame(5, damping_ratio=0.01), 600, 20, 0, "displacement"),
    ]
    for k, (name, build, duration, fs, snr, quantities) in enumerate(cases):
        structure = build()
        ds = simulate_record(
            structure, duration_s=duration, fs_hz=fs, snr_db=snr, quantities=quantities, seed=1000 * seed + k
        )
        yield name, ds, truth_modes(structure, ds)
    yield ("KOMA shear frame 1200s", *koma())


def koma():
    """KOMA's 5-storey shear-frame record (12 Hz) and its reference modes (all taken as visible). The record
    was integrated with the trapezoidal rule at its sampling step: its poles are the reference ones mapped
    through ``z = (1 + lambda h / 2) / (1 - lambda h / 2)``."""
    d = np.load(DATA / "shearframe.npz")
    ds = xr.Dataset(
        {"displacement": (("time", "channel"), d["response"])},
        coords={"channel": [f"storey{i + 1}" for i in range(5)]},
        attrs={"sampling_rate": 12.0, "title": "KOMA shear frame"},
    )
    h, w, xi = 1 / 12.0, d["omega_n"], d["xi_ref"]
    lam = -xi * w + 1j * w * np.sqrt(1 - xi**2)
    lam = np.log((1 + lam * h / 2) / (1 - lam * h / 2)) / h
    fn = np.abs(lam) / (2 * np.pi)
    truth = xr.Dataset(
        {
            "frequency": ("mode", lam.imag / (2 * np.pi)),
            "damping_ratio": ("mode", -lam.real / np.abs(lam)),
            "sensor_shape": (("mode", "channel"), d["phi_ref"].T.astype(complex)),
            "visible": ("mode", fn < 0.4 * 12.0),
        }
    )
    truth["frequency_tolerance"] = (
        "mode",
        frequency_limit(truth.frequency.values, truth.damping_ratio.values, len(d["response"]) / 12.0),
    )
    return ds, truth


def run_twin(ds, algorithm: str = "ssi"):
    """twin's defaults (but the ``algorithm``) on the record: damped frequencies [Hz], shapes in displacement,
    the block rows and the wall time [s]; a record in which it finds no mode gives no estimate (all missed)."""
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            m = extract(ds, progress=False, algorithm=algorithm)
        except NoModeError as exc:
            return np.empty(0), np.empty((0, ds.sizes["channel"]), complex), exc.block_rows, time.perf_counter() - t0
    block_rows = json.loads(m.attrs["settings"])["block_rows"]
    return m.frequency.values, m.sensor_shape.values, block_rows, time.perf_counter() - t0


PRESETS = ("Reynders", "Neu")


def run_pyoma(ds, block_rows: int):
    """pyOMA2's SSI-cov (its defaults but the block rows, twin's) and each automatic clustering preset of
    :data:`PRESETS`, on the record in SI: per preset the damped frequencies [Hz], the shapes in
    displacement (None where the record mixes quantities: pyOMA2's real shapes lose the phase between a
    velocity and an acceleration channel, so its modes there are judged on frequency alone) and the time
    [s] (the SSI run's and the clustering's)."""
    import logging

    from pyoma2.algorithms.data.run_params import Clustering
    from pyoma2.algorithms.ssi import SSI
    from pyoma2.setup.single import SingleSetup

    logging.getLogger("pyoma2").setLevel(logging.WARNING)
    rec = check_record(ds)
    orders = derivative_orders(rec.quantities)
    t0 = time.perf_counter()
    setup = SingleSetup(rec.y, fs=rec.fs_hz)
    alg = SSI(name="ssicov", method="cov", br=block_rows, ordmax=100, step=2)
    setup.add_algorithms(alg)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        setup.run_by_name("ssicov")
    t_ssi = time.perf_counter() - t0
    out = {}
    for preset in PRESETS:
        t0 = time.perf_counter()
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                alg.add_clustering(Clustering(name=preset, quick=preset, freqlim=(1e-3, 0.4 * rec.fs_hz)))
                alg.run_clustering(preset)
        except Exception as exc:  # noqa: BLE001 (a failed clustering is a row of the table, not the end of it)
            out[preset] = (f"{type(exc).__name__}: {str(exc)[:80]}", None, t_ssi + time.perf_counter() - t0)
            continue
        dt = t_ssi + time.perf_counter() - t0
        res = alg.result.clustering_results[preset]
        fn, xi = np.atleast_1d(res.Fn), np.atleast_1d(res.Xi)
        phi = np.atleast_2d(res.Phi)
        phi = phi.T if phi.shape[0] == rec.y.shape[1] else phi
        damped = np.sqrt(np.clip(1 - xi**2, 0, None))  # pyOMA2 reports undamped natural frequencies
        lam = 2 * np.pi * fn * (-xi + 1j * damped)
        mixed = len(set(orders.tolist())) > 1
        out[preset] = (fn * damped, None if mixed else phi / lam[:, None] ** orders[None, :], dt)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--only", default=None, help="comma-separated substrings of record names to run")
    ap.add_argument("--no-pyoma", action="store_true")
    ap.add_argument("--seed", type=int, default=1, help="seed of the corpus (record k's seed is 1000 seed + k)")
    ap.add_argument(
        "--seeds",
        default=None,
        help="comma-separated seeds to run the corpus for, one after the "
        "other, with totals at the end (instead of --seed)",
    )
    ap.add_argument("--json", default=None)
    ap.add_argument(
        "--algorithm", default="ssi", choices=("ssi", "plscf"), help="twin's identification algorithm (default ssi)"
    )
    args = ap.parse_args()
    try:
        import pyoma2  # noqa: F401
        from importlib.metadata import version

        pyoma = None if args.no_pyoma else version("pyOMA-2")
    except ImportError:
        pyoma = None
        print("pyOMA2 not installed (pip install pyOMA-2): its columns are left out")
    head = f"{'record':34} {'visible':>7} | {'twin found':>10} {'missed':>6} {'spur':>4} {'time s':>6}"
    for preset in PRESETS if pyoma else ():
        head += f" | {preset[:8] + ' found':>14} {'spur':>4} {'time s':>6}"
    print(
        f"twin defaults ({args.algorithm}) vs pyOMA2 {pyoma or '-'} SSI-cov + automatic clustering; found = frequency within 0.5% "
        "(or 3 times its statistical limit), MAC >= 0.95 in displacement (* pyOMA2: frequency alone)"
    )
    print(head)
    rows, worse = [], 0
    seeds = [args.seed] if args.seeds is None else [int(x) for x in args.seeds.split(",")]
    for seed, (name, ds, truth) in ((s, r) for s in seeds for r in corpus(s)):
        name = name if len(seeds) == 1 else f"{name} s{seed}"
        if args.only and not any(s.strip() in name for s in args.only.split(",")):
            continue
        f_twin, shapes_twin, block_rows, dt = run_twin(ds, args.algorithm)
        tw = score(f_twin, shapes_twin, truth)
        line = (
            f"{name:34} {int(truth.visible.sum()):7d} | {len(tw['found']):10d} {len(tw['missed']):6d} "
            f"{len(tw['spurious']):4d} {dt:6.1f}"
        )
        row = {"record": name, "visible": int(truth.visible.sum()), "twin": {**tw, "time_s": dt}}
        if pyoma:
            best = 0
            for preset, (fd, phi, dp) in run_pyoma(ds, block_rows).items():
                if isinstance(fd, str):  # pyOMA2 failed on this record
                    line += f" | {'error':>14} {'':4} {dp:6.1f}"
                    row[f"pyoma2 {preset}"] = {"error": fd, "time_s": dp}
                    continue
                po = score(fd, phi, truth)
                star = "*" if phi is None else " "
                line += f" | {len(po['found']):13d}{star} {len(po['spurious']):4d} {dp:6.1f}"
                row[f"pyoma2 {preset}"] = {**po, "time_s": dp, "frequency_only": phi is None}
                best = max(best, len(po["found"]))
            worse += len(tw["found"]) < best
        print(line, flush=True)
        if tw["missed"] or tw["spurious"]:
            print(
                f"{'':34}   twin missed {np.round(tw['missed'], 3).tolist()} spurious "
                f"{np.round(tw['spurious'], 3).tolist()}"
            )
        rows.append(row)
    spurious = sum(len(r["twin"]["spurious"]) for r in rows)
    print(
        f"twin: {sum(len(r['twin']['found']) for r in rows)} of {sum(r['visible'] for r in rows)} visible modes "
        f"found, {spurious} spurious"
    )
    if pyoma:
        for row in rows:
            for key, value in row.items():
                if isinstance(value, dict) and "error" in value:
                    print(f"{key} on '{row['record']}': {value['error']}")
        found = (
            {
                k: sum(len(r[k]["found"]) for r in rows if "found" in r[k])
                for k in rows[0]
                if k != "record" and k != "visible"
            }
            if rows
            else {}
        )
        print(f"visible modes {sum(r['visible'] for r in rows)}, found: {found}")
        print(f"records where twin found fewer modes than pyOMA2's better preset: {worse} of {len(rows)}")
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
