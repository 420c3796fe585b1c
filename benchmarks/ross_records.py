"""Benchmark: records simulated by ROSS itself, brought into twin as a plant's CSV would be.

A rotor that no test or page uses (a fan on a stepped shaft: two disks between two anisotropic bearings, a
third overhung, 6000 rpm) is built in ROSS and saved; ``twin from-ross`` makes its model file, with a third
proximeter pair beside the overhung fan added as a user would. For each case ROSS's own time response
(``Rotor.run_time_response``: broad-band force at the fan, 1X unbalance at the first disk, 3% sensor noise)
of the rotor with one bearing's ``kxx`` and ``kyy`` scaled by one factor (a proportional change) is written as
a CSV in µm, then ``twin.extract.import_record``, ``extract`` and the loop (HMC, calibrated on records
simulated through the model's FMU with its declared excitation) run on it. The table says which modes were
found against ROSS's modes of the changed rotor, what the loop named and how far the error fell.

Needs ROSS (``pip install -e '.[ross]'``)::

    python benchmarks/ross_records.py --out benchmarks/results/ross_records.md
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

SPEED_RPM = 6000.0
FS_HZ = 1024.0
DURATION_S = 200.0
WARMUP_S = 20.0
FMAX_HZ = 250.0
BROADBAND_ASD = 1.3  # N/sqrt(Hz), one-sided, x and y, at the fan (node 18): about twice twin's derived default
UNBALANCE_ME = 1.0e-3  # kg m at the first disk (node 8): G2.5 for the rotor is 8.6e-4
NOISE = 0.03  # sensor noise std, fraction of each channel's RMS
PROBES = {"inboard": 2, "outboard": 14, "fan": 17}
#: (bearing whose kxx and kyy are scaled, factor, seed of the forces and the noise); factor 1: unchanged
CASES = (("outboard", 0.7, 5), ("inboard", 0.75, 9), ("outboard", 1.0, 6), ("inboard", 0.85, 11))


def fan(inboard: float = 1.0, outboard: float = 1.0):
    """The fan rotor in ROSS, its bearings' direct stiffnesses scaled by ``inboard`` and ``outboard``."""
    import ross as rs

    steel = rs.Material(name="Steel", rho=7810, E=211e9, G_s=81.2e9)
    lengths = [0.1] * 4 + [0.12] * 10 + [0.1] * 4
    diameters = [0.07] * 4 + [0.09] * 10 + [0.07] * 4
    shaft = [
        rs.ShaftElement(L=le, idl=0.0, odl=d, material=steel, shear_effects=True, rotary_inertia=True, gyroscopic=True)
        for le, d in zip(lengths, diameters)
    ]
    disks = [
        rs.DiskElement.from_geometry(n=8, material=steel, width=0.06, i_d=0.09, o_d=0.40),
        rs.DiskElement.from_geometry(n=11, material=steel, width=0.05, i_d=0.09, o_d=0.32),
        rs.DiskElement.from_geometry(n=18, material=steel, width=0.04, i_d=0.07, o_d=0.50),
    ]
    bearings = [
        rs.BearingElement(n=2, kxx=6e7 * inboard, kyy=9e7 * inboard, cxx=3.0e4, cyy=4.5e4, tag="inboard"),
        rs.BearingElement(n=14, kxx=5e7 * outboard, kyy=8e7 * outboard, cxx=2.5e4, cyy=4.0e4, tag="outboard"),
    ]
    return rs.Rotor(shaft, disks, bearings)


def ross_record(rotor, path: Path, seed: int) -> None:
    """ROSS's time response of ``rotor`` at the proximeters, written as a CSV in µm with a time column."""
    rng = np.random.default_rng(seed)
    omega = SPEED_RPM * np.pi / 30.0
    t = np.arange(int((DURATION_S + WARMUP_S) * FS_HZ)) / FS_HZ
    nd = rotor.number_dof
    force = np.zeros((len(t), rotor.ndof))
    std = BROADBAND_ASD * np.sqrt(FS_HZ / 2.0)
    force[:, nd * 18 + 0] = rng.normal(0.0, std, len(t))
    force[:, nd * 18 + 1] = rng.normal(0.0, std, len(t))
    force[:, nd * 8 + 0] += UNBALANCE_ME * omega**2 * np.cos(omega * t)
    force[:, nd * 8 + 1] += UNBALANCE_ME * omega**2 * np.sin(omega * t)
    y = rotor.run_time_response(omega, force, t).yout
    keep = t >= WARMUP_S
    columns, data = ["time [s]"], [t[keep] - WARMUP_S]
    for name, node in PROBES.items():
        for k, axis in enumerate("xy"):
            columns.append(f"{name}_{axis} [um]")
            data.append(1e6 * y[keep, nd * node + k])
    table = np.array(data).T
    table[:, 1:] += rng.normal(0.0, 1.0, table[:, 1:].shape) * NOISE * table[:, 1:].std(axis=0)
    np.savetxt(path, table, delimiter=",", header=",".join(columns), comments="", fmt=["%.6f"] + ["%.6g"] * 6)


def ross_modes_hz(rotor, n: int) -> np.ndarray:
    """The damped frequencies [Hz] of ROSS's ``n`` lowest lateral-looking modes (axial and torsional ones, which
    are undamped here, left out)."""
    modal = rotor.run_modal(speed=SPEED_RPM * np.pi / 30.0, num_modes=2 * n + 8)
    fd, zeta = np.asarray(modal.wd) / (2 * np.pi), np.asarray(modal.damping_ratio)
    keep = (np.abs(zeta) > 1e-6) & (fd < FMAX_HZ)
    return fd[keep][:n]


def run_case(model_file: Path, bearing: str, factor: float, seed: int, work: Path) -> dict:
    import twin
    from twin.extract import extract
    from twin.extract.importing import import_record
    from twin.loop import Twin

    rotor = fan(**{bearing: factor})
    csv = work / f"{bearing}_{factor:g}_{seed}.csv"
    started = time.perf_counter()
    ross_record(rotor, csv, seed)
    ross_s = time.perf_counter() - started
    model = twin.load_model(model_file)
    signals = import_record(csv)
    assert set(signals["units"].values) == {"um"}, "the CSV holds every channel in um"
    pp_um = float((signals.signal.max("time") - signals.signal.min("time")).max())
    started = time.perf_counter()
    modes = extract(signals, fmax_hz=FMAX_HZ, progress=False)
    tw = Twin(model, modes)
    tw.run(method="hmc", seed=seed, progress=False)
    loop_s = time.perf_counter() - started
    found = modes["frequency"].values
    truth_hz = ross_modes_hz(rotor, len(found) + 4)
    first, last = tw.history[0].error, tw.history[-1].error
    return {
        "case": f"{bearing} kxx, kyy x {factor:g}" if factor != 1.0 else "unchanged",
        "seed": seed,
        "found": ", ".join(f"{f:.2f}" for f in found),
        "ross": ", ".join(f"{f:.2f}" for f in truth_hz),
        "named": " + ".join(tw.added) or "-",
        "rounds": " / ".join(d.verdict for d in tw.diagnoses),
        "error": f"{100 * first:.3f}% -> {100 * last:.3f}%"
        + (f" ({100 * (1 - last / first):.0f}% less)" if tw.added else ""),
        "calibrated": "yes" if any("calibrated" in h.action for h in tw.history) else "no",
        "pp": f"{pp_um:.0f}",
        "time": f"{ross_s:.0f} / {loop_s:.0f}",
    }


def simulate_text(model_file: Path) -> str:
    """What ``twin simulate`` would drive the twin's model to with its derived excitation, against the zone C/D."""
    import twin
    from twin.fem.excitation import machine_excitation
    from twin.fmu.simulate import response_pp
    from twin.fmu.truth import model_state_space

    model = twin.load_model(model_file)
    ex = machine_excitation(model)
    pp = response_pp(
        model_state_space(model), 1.0 / FS_HZ, ex.unbalance_node, ex.unbalance_me, ex.broadband_node, ex.broadband_asd
    )
    return (
        f"`twin simulate` on the model file (its excitation derived: {ex.unbalance_me * 1e3:.3g} g m at node "
        f"{ex.unbalance_node}, {ex.broadband_asd:.3g} N/√Hz at node {ex.broadband_node}): expected largest "
        f"peak-to-peak {1e6 * pp.max():.0f} µm, against the zone C/D boundary's {1e6 * ex.warn_response:.0f} µm."
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="benchmarks/results/ross_records.md")
    args = parser.parse_args()
    from twin.fem.ross import read_ross, ross_model_text

    with tempfile.TemporaryDirectory(prefix="twin-ross-records-") as tmp:
        work = Path(tmp)
        fan().save(work / "fan.toml")
        text = ross_model_text(read_ross(work / "fan.toml", SPEED_RPM), source="fan.toml")
        text += '\n[[sensor]]\nname = "fan"\nnode = 17\nlocation = "proximeter pair beside the fan"\n'
        model_file = work / "fan_twin.toml"
        model_file.write_text(text)
        rows = [run_case(model_file, *case, work) for case in CASES]
        plausible = simulate_text(model_file)
    header = (
        "| case | seed | modes found [Hz] | ROSS's modes [Hz] | named | rounds | error E | calibrated "
        "| largest p-p [µm] | ROSS / twin [s] |"
    )
    lines = [
        "# Records simulated by ROSS itself",
        "",
        f"`python benchmarks/ross_records.py --out {args.out}` (ROSS installed; see the script's docstring for the "
        "rotor, the forces and the cases).",
        f"Records of {DURATION_S:g} s at {FS_HZ:g} Hz, {SPEED_RPM:g} rpm; modes extracted up to {FMAX_HZ:g} Hz; "
        "largest p-p: the largest peak-to-peak displacement of the record (ISO 20816-1 zone C/D at 6000 rpm: "
        "170 µm).",
        "",
        header,
        "|" + "|".join(["---"] * (header.count("|") - 1)) + "|",
    ]
    lines[4:4] = [plausible]
    for r in rows:
        lines.append(
            f"| {r['case']} | {r['seed']} | {r['found']} | {r['ross']} | {r['named']} | {r['rounds']} | "
            f"{r['error']} | {r['calibrated']} | {r['pp']} | {r['time']} |"
        )
    Path(args.out).write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
