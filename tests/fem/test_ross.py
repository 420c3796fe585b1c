"""The ROSS bridge: ROSS's own example rotors, saved by ROSS 2.3, read without ROSS and checked against ROSS's
modal analysis of them (``benchmarks/ross_examples.py`` wrote the files and the eigenvalues)."""

import json
from pathlib import Path

import numpy as np
import pytest

from twin.errors import ModelFileError
from twin.fem.modelfile import load_model
from twin.fem.ross import from_ross, load_ross, read_ross, ross_model_text
from twin.modes.analysis import modal

DATA = Path(__file__).parent.parent / "data" / "ross"
REFERENCE = json.loads((DATA / "eigenvalues.json").read_text())
CASES = [(name, rpm) for name in REFERENCE["rotors"] for rpm in REFERENCE["speeds_rpm"]]
N_MODES = 12


@pytest.mark.parametrize("name, rpm", CASES)
def test_the_modes_are_ross_s(name, rpm):
    """Every lateral mode ROSS finds below twin's twelfth, and no other, to 1e-7 (ROSS's torsional and axial
    modes are left out: twin's model is lateral)."""
    ref = REFERENCE["rotors"][name]["eigenvalues"][str(float(rpm))]
    ross = np.array(ref["real"]) + 1j * np.array(ref["imag"])
    ross = ross[(ross.imag > 0) & (np.array(ref["lateral"]) > 0.5)]
    poles = modal(load_ross(DATA / f"{name}.toml", rpm), n_modes=N_MODES)["pole"].values
    ross = np.sort_complex(ross[ross.imag < poles.imag.max() * (1 + 1e-6)])
    assert len(ross) == len(poles) == N_MODES
    ross = ross[np.argsort(ross.imag)]
    assert np.max(np.abs(poles - ross) / np.abs(ross)) < 1e-7


def test_the_model_file_it_writes_reads_back_to_the_same_model(tmp_path):
    data = read_ross(DATA / "rotor_example_with_damping.toml", 3000.0)
    path = tmp_path / "machine.toml"
    path.write_text(ross_model_text(data, "rotor_example_with_damping.toml"))
    written, direct = load_model(path), load_ross(DATA / "rotor_example_with_damping.toml", 3000.0)
    for kind in ("M", "C", "G", "K"):
        assert np.array_equal(written.matrices()[kind], direct.matrices()[kind]), kind
    assert written.rayleigh == (8.0501, 1e-05) and written.channels == direct.channels
    assert [s.name for s in written.sensors] == ["Bearing_0_x", "Bearing_0_y", "Bearing_1_x", "Bearing_1_y"]


def test_from_ross_reads_what_the_rotor_saves():
    class Saved:
        def save(self, path):
            Path(path).write_text((DATA / "rotor_example.toml").read_text())

    model = from_ross(Saved(), 3000.0, name="rig")
    assert model.name == "rig" and model.n_nodes == 7 and len(model.bearings) == 2
    with pytest.raises(TypeError, match="ross.Rotor"):
        from_ross(object(), 3000.0)


def _edited(tmp_path, old, new, count=1):
    text = (DATA / "rotor_example.toml").read_text()
    assert old in text
    path = tmp_path / "edited.toml"
    path.write_text(text.replace(old, new, count))
    return path


@pytest.mark.parametrize(
    "old, new, message",
    [
        ("idr = 0.0\nodr = 0.05\nn = 2", "idr = 0.0\nodr = 0.06\nn = 2", r"Shaft Element 2.*'odr'.*tapered"),
        ("n = 3\naxial_force = 0", "n = 2\naxial_force = 0", r"Shaft Element 3.*second shaft element at position 2"),
        ("n = 1\naxial_force = 0", "n = 1\naxial_force = 1000.0", r"Shaft Element 1.*'axial_force'"),
        ("mxx = [ 0,]", "mxx = [ 2.0,]", r"Bearing 0.*'mxx'.*mass"),
        ('tag = "Bearing 1"', 'tag = "Bearing 1"\nn_link = 7', r"Bearing 1.*'n_link'.*support"),
        ("kxx = [ 1000000.0,]", "kxx = [ 1e6, 2e6,]\nfrequency = [ 100.0, 200.0,]", r"Bearing 0.*'frequency'.*314"),
        ('ross_version = "2.3.0"', "", r"'ross_version'.*not a file saved by ROSS"),
    ],
)
def test_what_twin_cannot_hold_is_refused_naming_the_element(tmp_path, old, new, message):
    with pytest.raises(ModelFileError, match=message):
        load_ross(_edited(tmp_path, old, new), 3000.0)


def test_speed_dependent_coefficients_are_taken_at_the_speed(tmp_path):
    path = _edited(tmp_path, "kxx = [ 1000000.0,]", "kxx = [ 1e6, 2e6,]\nfrequency = [ 300.0, 400.0,]")
    b = read_ross(path, 3000.0)["bearing"][0]  # 314.16 rad/s
    assert b["kxx"] == pytest.approx(1e6 + 1e6 * (100 * np.pi - 300) / 100, rel=1e-12)
