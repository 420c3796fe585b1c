"""Benchmark of the automated modal extraction on the hydro unit.

In one run, on the same 1 h record (Table 2 truth, 256 Hz, turbulence + 1X
unbalance, 5% sensor noise, simulated through the FMU):

1. ``twin.extract.extract`` with its defaults (J = 100 jackknife samples):
   wall time and accuracy against the truth's modes (frequency, damping,
   MAC on the sensors);
2. pyOMA2 (PyPI ``pyOMA-2``) SSI-cov with the same block rows and orders and
   its automatic clustering (the Magalhães and Reynders presets), with and
   without its bootstrap uncertainty (``calc_unc``, 100 samples): wall time
   and accuracy;
3. with ``--seeds N``: the spread ratio, i.e. the mean jackknife standard
   error of each mode's frequency and damping (the statistical part of the
   samples' spread) against their standard deviation over N independent
   records (Monte Carlo over seeds), that Monte Carlo std against the
   Cramér-Rao bound of ``twin observe`` (:func:`twin.design.observability`,
   theory, no simulation), the bias against the Monte Carlo std, and the
   samples' whole standard error (jackknife and model-order spread) against
   the RMS error over the records (which includes the bias).

Run:  python benchmarks/extraction.py [--seeds 10] [--cache DIR] [--delete-half] [--order-spread shapes|all|none]
                                     [--duration 3600] [--samples J] [--blocks B] [--orders-per-mode N]
                                     [--keep-harmonics] [--fmax HZ] [--spread-only] [--workers N]
(simulated records are kept in DIR, default ``~/.cache/twin/bench``).
Needs ``pip install pyOMA-2`` for part 2 (skipped with a note otherwise).
"""

from __future__ import annotations

import argparse
import json
import time
import warnings
from concurrent.futures import ProcessPoolExecutor
from functools import partial
from pathlib import Path

import numpy as np
import xarray as xr
from extraction_options import add_extraction_options, extraction_options

from twin import load_model
from twin.design import Excitation, observability
from twin.extract import extract
from twin.fem.truthfile import paper_truth
from twin.fmu.simulate import simulate
from twin.fmu.truth import truth_state_space
from twin.modes.sensitivity import state_modes
from twin.modes.shapes import mac

MODEL = "models/hydro_unit.toml"
#: The spread ratio is calibrated when within this fraction of one (the spread over 12 records knows a std to about 21%).
SPREAD_TOLERANCE = 0.3


def truth_modes(model):
    """Poles and sensor shapes of the Table 2 truth (all its modes; the targets are the lightly damped ones)."""
    ss = truth_state_space(model, paper_truth())
    lam, right, _ = state_modes(ss.A)
    return lam, (ss.C @ right.T).T


def record(cache: Path, seed: int, duration_s: float = 3600.0) -> Path:
    name = "1h" if duration_s == 3600.0 else f"{duration_s:g}s"
    path = cache / f"hydro_paper_{name}_seed{seed}.nc"
    if not path.exists():
        simulate(
            load_model(MODEL),
            duration_s=duration_s,
            fs_hz=256.0,
            seed=seed,
            truth=paper_truth(),
            output=path,
            progress=False,
        )
    return path


def match(freq, zeta, shapes, lam_t, phi_t):
    """For every truth mode the extracted mode nearest in frequency + (1 - MAC), or None."""
    rows = []
    for j in range(len(lam_t)):
        ft, zt = lam_t[j].imag / (2 * np.pi), -lam_t[j].real / abs(lam_t[j])
        if len(freq) == 0:
            rows.append((ft, zt, None))
            continue
        d = np.abs(freq - ft) / ft + 1 - mac(shapes, phi_t[j])[:, 0]
        k = int(np.argmin(d))
        ok = abs(freq[k] / ft - 1) < 0.02 and mac(shapes[k], phi_t[j]) > 0.8
        rows.append((ft, zt, (freq[k], zeta[k], float(mac(shapes[k], phi_t[j]))) if ok else None))
    return rows


def spurious(freq, shapes, lam_t, phi_t):
    """Extracted modes that match no truth mode."""
    out = []
    for k in range(len(freq)):
        d = np.abs(lam_t.imag / (2 * np.pi) - freq[k]) / freq[k]
        if not np.any((d < 0.02) & (mac(phi_t, shapes[k])[:, 0] > 0.8)):
            out.append(float(freq[k]))
    return out


def table(name, rows, seconds, extra=""):
    print(f"\n{name}: {seconds:.1f} s {extra}")
    print(
        f"{'truth f [Hz]':>12} {'truth zeta %':>12} | {'f [Hz]':>9} {'f err %':>8} {'zeta %':>7} {'zeta err %':>10} {'MAC':>7}"
    )
    for ft, zt, got in rows:
        if got is None:
            print(f"{ft:12.3f} {100 * zt:12.2f} | {'not found':>9}")
        else:
            f, z, m = got
            print(
                f"{ft:12.3f} {100 * zt:12.2f} | {f:9.3f} {100 * (f / ft - 1):+8.3f} {100 * z:7.2f} "
                f"{100 * (z / zt - 1):+10.1f} {m:7.4f}"
            )


def run_twin(path, lam_t, phi_t):
    t0 = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        m = extract(path, progress=False)
    dt = time.perf_counter() - t0
    rows = match(m.frequency.values, m.damping_ratio.values, m.sensor_shape.values, lam_t, phi_t)
    harmonics = json.loads(m.attrs["harmonics"])
    extra = (
        f"({m.sizes['mode']} modes x {m.sizes['sample']} samples; harmonics rejected: "
        f"{[round(h['frequency_hz'], 3) for h in harmonics]}; spurious: "
        f"{spurious(m.frequency.values, m.sensor_shape.values, lam_t, phi_t)}; "
        f"{len(caught)} warning(s))"
    )
    return m, rows, dt, extra


def run_pyoma(path, lam_t, phi_t, preset, calc_unc, complex_ok):
    from pyoma2.algorithms.data.run_params import Clustering
    from pyoma2.algorithms.ssi import SSI
    from pyoma2.setup.single import SingleSetup

    ds = xr.load_dataset(path)
    data = ds.displacement.values
    fs = float(ds.attrs["sampling_rate"])
    t0 = time.perf_counter()
    setup = SingleSetup(data, fs=fs)
    # pyOMA2's default hard criteria drop poles with MPC < 0.5 or MPD > 0.5: complex modes
    hc = {"xi_max": 0.25, "mpc_lim": 0.0, "mpd_lim": 1e9, "CoV_max": np.inf} if complex_ok else None
    kw = {"hc": hc} if hc else {}
    alg = SSI(name="ssicov", method="cov", br=64, ordmax=100, step=2, calc_unc=calc_unc, nb=100, **kw)
    setup.add_algorithms(alg)
    setup.run_by_name("ssicov")
    alg.add_clustering(Clustering(name=preset, quick=preset, freqlim=(0.5, 102.4)))
    alg.run_clustering(preset)
    dt = time.perf_counter() - t0
    res = alg.result.clustering_results[preset]
    fn, xi, phi = np.atleast_1d(res.Fn), np.atleast_1d(res.Xi), np.atleast_2d(res.Phi)
    phi = phi.T if phi.shape[0] == data.shape[1] else phi
    # pyOMA2 reports undamped natural frequencies; compare damped ones like ours
    fd = fn * np.sqrt(np.clip(1 - xi**2, 0, None))
    rows = match(fd, xi, phi, lam_t, phi_t)
    spur = spurious(fd, phi, lam_t, phi_t)
    extra = f"({len(fn)} modes; {len(spur)} spurious, e.g. {[round(x, 3) for x in spur[:8]]})"
    return rows, dt, extra


def _record_estimates(seed, *, cache, duration_s, names, lam_t, phi_t, options):
    """Each truth mode's estimates ``names`` from the record of ``seed`` (NaN where it was not found)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        m = extract(record(cache, seed, duration_s), progress=False, **options)
    rows = match(m.frequency.values, m.damping_ratio.values, m.sensor_shape.values, lam_t, phi_t)
    ks = [None if g is None else int(np.argmin(np.abs(m.frequency.values - g[0]))) for _, _, g in rows]
    return {n: [np.nan if k is None else float(m[n][k]) for k in ks] for n in names}


def spread(cache, seeds, lam_t, phi_t, duration_s=3600.0, workers=1, **options):
    """Mean jackknife standard error against the std over independent records, and the total against the RMS error."""
    names = (
        "frequency",
        "damping_ratio",
        "frequency_se_jackknife",
        "damping_ratio_se_jackknife",
        "frequency_se",
        "damping_ratio_se",
    )
    task = partial(
        _record_estimates, cache=cache, duration_s=duration_s, names=names, lam_t=lam_t, phi_t=phi_t, options=options
    )
    if workers > 1:
        with ProcessPoolExecutor(workers) as pool:
            per_record = list(pool.map(task, range(1, seeds + 1)))
    else:
        per_record = [task(s) for s in range(1, seeds + 1)]
    f, z, jf, jz, tf, tz = (np.array([r[n] for r in per_record]) for n in names)
    obs = observability(load_model(MODEL), Excitation(duration_s=duration_s), truth=paper_truth())
    print(
        f"\nspread over {seeds} independent {duration_s:g} s records (seeds 1..{seeds}, {options}). Statistical "
        "part: the jackknife "
        "standard error (SE) / the Monte Carlo std, and the Monte Carlo std / the Cramer-Rao bound (CRB, "
        "twin observe). Total: the samples' standard error (jackknife and model-order spread) / the RMS error "
        "against the truth (which includes SSI's bias)"
    )
    print(
        f"{'truth f [Hz]':>12} {'found':>5} | {'MC std f [mHz]':>14} {'SE f':>7} {'ratio':>6} {'MC/CRB':>6} "
        f"{'bias/MC':>7} {'tot/RMSE':>8} | {'MC std zeta %':>13} {'SE zeta':>7} {'ratio':>6} {'MC/CRB':>6} "
        f"{'bias/MC':>7} {'tot/RMSE':>8}"
    )
    ratios = []
    for j in range(len(lam_t)):
        ok = np.isfinite(f[:, j])
        if ok.sum() < 3:
            continue
        ft, zt = lam_t[j].imag / (2 * np.pi), -lam_t[j].real / abs(lam_t[j])
        o = int(np.argmin(np.abs(obs.frequency.values - ft)))
        line = f"{ft:12.3f} {ok.sum():5d} |"
        for est, se, tot, truth, crb, unit in (
            (f, jf, tf, ft, float(obs.frequency_std[o]), 1e3),
            (z, jz, tz, zt, float(obs.damping_ratio_std[o]), 100.0),
        ):
            x = est[ok, j]
            mc, bias, rmse = np.std(x, ddof=1), np.mean(x) - truth, np.sqrt(np.mean((x - truth) ** 2))
            ratios.append(np.mean(se[ok, j]) / mc)
            line += (
                f" {unit * mc:{14 if unit == 1e3 else 13}.4f} {unit * np.mean(se[ok, j]):7.4f} "
                f"{ratios[-1]:6.2f} {mc / crb:6.2f} {bias / mc:7.2f} "
                f"{np.sqrt(np.mean(tot[ok, j] ** 2)) / rmse:8.2f} |"
            )
        print(line.rstrip(" |"))
    within = sum(abs(r - 1) <= SPREAD_TOLERANCE for r in ratios)
    print(
        f"jackknife SE / Monte Carlo std within +-{SPREAD_TOLERANCE:.0%}: {within} of {len(ratios)} "
        f"(frequency and damping ratio of the modes found on 3 or more records; {seeds} records know a std "
        f"to about +-{1 / np.sqrt(2 * (seeds - 1)):.0%})"
    )


def single_record(cache: Path, lam_t, phi_t) -> None:
    """Parts 1 and 2: twin.extract and pyOMA2 on the 1 h record of seed 1."""
    path = record(cache, 1)
    _, rows, dt, extra = run_twin(path, lam_t, phi_t)
    table("twin.extract (SSI-cov, 100 jackknife samples)", rows, dt, extra)
    try:
        from importlib.metadata import version

        import pyoma2  # noqa: F401 (only: is it installed?)
    except ImportError:
        print("\npyOMA2 not installed (pip install pyOMA-2): comparison skipped")
    else:
        import logging

        logging.getLogger("pyoma2").setLevel(logging.WARNING)
        for preset, unc, complex_ok in (
            ("Magalhaes", False, False),
            ("Magalhaes", False, True),
            ("Magalhaes", True, True),
            ("Reynders", False, True),
        ):
            name = (
                f"pyOMA2 {version('pyOMA-2')} SSI-cov br=64 orders<=100, clustering '{preset}', "
                f"{'complex-mode filters off' if complex_ok else 'default MPC/MPD filters'}"
                f"{', bootstrap uncertainty nb=100' if unc else ''}"
            )
            try:
                rows, dt, extra = run_pyoma(path, lam_t, phi_t, preset, unc, complex_ok)
            except Exception as exc:  # report a failure of the other tool, do not hide it
                print(f"\n{name}: failed with {type(exc).__name__}: {exc}")
                continue
            table(name, rows, dt, extra)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=0, help="records for the spread ratio (0: skip)")
    ap.add_argument("--cache", type=Path, default=Path.home() / ".cache" / "twin" / "bench")
    ap.add_argument(
        "--duration",
        type=float,
        default=3600.0,
        help="record length [s] of the spread's records (1200 with --samples 15: the loop's records)",
    )
    ap.add_argument(
        "--fmax",
        type=float,
        default=None,
        help="fmax [Hz] of the spread's extractions (default extract's, 102.4 Hz; the loop uses 60)",
    )
    ap.add_argument("--workers", type=int, default=1, help="records extracted at once for the spread (processes)")
    ap.add_argument(
        "--spread-only",
        action="store_true",
        help="only the spread over --seeds records (skip the single-record tables)",
    )
    add_extraction_options(ap)
    args = ap.parse_args()
    if args.spread_only and not args.seeds:
        ap.error("--spread-only needs --seeds N")
    options = extraction_options(args)
    if args.fmax:
        options["fmax_hz"] = args.fmax
    args.cache.mkdir(parents=True, exist_ok=True)
    model = load_model(MODEL)
    lam_t, phi_t = truth_modes(model)
    if not args.spread_only:
        single_record(args.cache, lam_t, phi_t)
    if args.seeds:
        spread(args.cache, args.seeds, lam_t, phi_t, args.duration, args.workers, **options)


if __name__ == "__main__":
    main()
