"""Write ROSS's own example rotors (``Rotor.save``) and ROSS's eigenvalues of them into ``tests/data/ross/``,
the reference of ``tests/fem/test_ross.py``. Run with ROSS installed (``pip install -e '.[ross]'``):
``python benchmarks/ross_examples.py``. The test needs only the files it writes, not ROSS."""

import json
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent.parent / "tests" / "data" / "ross"
EXAMPLES = ("rotor_example", "rotor_example_with_damping")
SPEEDS_RPM = (0.0, 3000.0, 9000.0)
N_MODES = 16


def main() -> None:
    import ross as rs

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
