"""Write ROSS's own example rotors (``Rotor.save``) and ROSS's eigenvalues of them into ``tests/data/ross/``,
the reference of ``tests/fem/test_ross.py``, and the blower of the "Your own machine" notebook into
``notebooks/data/blower.toml``. Run with ROSS installed (``pip install -e '.[ross]'``):
``python benchmarks/ross_examples.py``. The test and the notebook need only the files it writes, not ROSS."""

import json
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
HERE = ROOT / "tests" / "data" / "ross"
NOTEBOOK_DATA = ROOT / "notebooks" / "data"
EXAMPLES = ("rotor_example", "rotor_example_with_damping")
SPEEDS_RPM = (0.0, 3000.0, 9000.0)
N_MODES = 16


def blower():
    """A two-stage blower as a ROSS user builds one: 1 m stepped steel shaft in 16 elements, two impellers between
    two anisotropic, cross-coupled bearings, a coupling hub overhung at the drive end."""
    import ross as rs

    steel = rs.Material(name="Steel", rho=7810, E=211e9, G_s=81.2e9)
    shaft = [
        rs.ShaftElement(
            L=0.0625,
            idl=0.0,
            odl=0.06 if i < 3 or i > 12 else 0.075,
            material=steel,
            shear_effects=True,
            rotary_inertia=True,
            gyroscopic=True,
        )
        for i in range(16)
    ]
    disks = [
        rs.DiskElement.from_geometry(n=6, material=steel, width=0.05, i_d=0.075, o_d=0.36, tag="impeller_1"),
        rs.DiskElement.from_geometry(n=10, material=steel, width=0.05, i_d=0.075, o_d=0.36, tag="impeller_2"),
        rs.DiskElement.from_geometry(n=16, material=steel, width=0.06, i_d=0.06, o_d=0.16, tag="coupling"),
    ]
    bearings = [
        rs.BearingElement(n=2, kxx=2.0e7, kyy=3.5e7, kxy=4e6, kyx=-4e6, cxx=4e3, cyy=6e3, tag="NDE"),
        rs.BearingElement(n=14, kxx=2.5e7, kyy=4.0e7, kxy=5e6, kyx=-5e6, cxx=5e3, cyy=7e3, tag="DE"),
    ]
    return rs.Rotor(shaft, disks, bearings)


def main() -> None:
    import ross as rs

    NOTEBOOK_DATA.mkdir(exist_ok=True)
    blower().save(NOTEBOOK_DATA / "blower.toml")

    reference = {"ross_version": rs.__version__, "speeds_rpm": list(SPEEDS_RPM), "rotors": {}}
    for name in EXAMPLES:
        rotor = getattr(rs, name)()
        rotor.save(HERE / f"{name}.toml")
        eigenvalues = {}
        for rpm in SPEEDS_RPM:
            modal = rotor.run_modal(speed=rpm * np.pi / 30, num_modes=2 * N_MODES)
            ev = np.asarray(modal.evalues)
            # the share of each mode's shape on the lateral DOFs (x, y and the two tilts of ROSS's six per node)
            vectors = np.asarray(modal.evectors)
            lateral = np.isin(np.arange(vectors.shape[0]) % rotor.number_dof, [0, 1, 3, 4])
            share = np.linalg.norm(vectors[lateral], axis=0) / np.linalg.norm(vectors, axis=0)
            eigenvalues[str(rpm)] = {"real": ev.real.tolist(), "imag": ev.imag.tolist(), "lateral": share.tolist()}
        reference["rotors"][name] = {"dof_per_node": int(rotor.number_dof), "eigenvalues": eigenvalues}
    (HERE / "eigenvalues.json").write_text(json.dumps(reference, indent=1))


if __name__ == "__main__":
    main()
