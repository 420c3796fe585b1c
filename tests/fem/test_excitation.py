"""The machine's excitation: declared in its model file, or derived from its mass and speed."""

from pathlib import Path

import numpy as np
import pytest

from twin.errors import ModelError, ModelFileError
from twin.fem import load_model
from twin.fem.excitation import BROADBAND_PER_WEIGHT, GRAVITY, machine_excitation, rotor_mass
from twin.fmu.simulate import response_pp
from twin.fmu.truth import model_state_space

ROSS = Path("models/ross_reference.toml")


def fast_rotor(tmp_path: Path, extra: str = "") -> Path:
    """ROSS's two-disk rotor at 3000 rpm without its destabilising cross-coupling: a machine unlike the hydro unit."""
    text = ROSS.read_text().replace("speed_rpm = 134.0", "speed_rpm = 3000.0")
    text = text.replace("kxy = 1.5e5", "kxy = 0.0").replace("kyx = -1.5e5", "kyx = 0.0")
    path = tmp_path / "rotor.toml"
    path.write_text(text + extra)
    return path


def test_the_derived_unbalance_is_the_balance_grade_of_the_rotor(tmp_path):
    model = load_model(fast_rotor(tmp_path))
    ex = machine_excitation(model)
    omega = 3000 * np.pi / 30
    assert ex.unbalance_me == pytest.approx(2.5e-3 * rotor_mass(model) / omega, rel=1e-12)
    assert rotor_mass(model) == pytest.approx(75.59, abs=0.01)  # 1.5 m of 50 mm steel shaft and two disks
    assert ex.unbalance_node == 2 and ex.broadband_node == 2  # the heaviest disk, D2
    assert ex.broadband_asd == pytest.approx(BROADBAND_PER_WEIGHT * rotor_mass(model) * GRAVITY)
    assert ex.warn_response == pytest.approx(13200e-6 / np.sqrt(3000))  # ISO 20816-1 zone C/D
    assert "G2.5" in ex.sources["unbalance"]


def test_the_derived_excitation_drives_a_plausible_response(tmp_path):
    """At the derived excitation the shaft moves by micrometres, far below the zone C/D boundary; the hydro
    unit's 100 kg m would move it by metres, and the simulation refuses that before any work."""
    from twin.fmu.simulate import simulate

    model = load_model(fast_rotor(tmp_path))
    ex = machine_excitation(model)
    ss = model_state_space(model)
    pp = response_pp(ss, 1 / 1024, ex.unbalance_node, ex.unbalance_me, ex.broadband_node, ex.broadband_asd)
    assert 1e-8 < pp.max() < ex.warn_response
    hydro_like = response_pp(ss, 1 / 1024, ex.unbalance_node, 100.0, ex.broadband_node, 3000.0)
    assert hydro_like.max() > 1.0  # metres
    with pytest.raises(ModelError, match=r"ross_reference: the excitation would drive the shaft to .* \[excitation\]"):
        simulate(model, duration_s=1.0, fs_hz=1024.0, unbalance_me=100.0, progress=False)


def test_a_declared_excitation_wins_and_names_places(tmp_path):
    extra = '\n[excitation]\nunbalance_at = "D4"\nunbalance_me = 1e-3\nbroadband_at = 3\nbroadband_asd = 0.5\nmax_response = 1e-4\n'
    ex = machine_excitation(load_model(fast_rotor(tmp_path, extra)))
    assert (ex.unbalance_node, ex.unbalance_me, ex.broadband_node, ex.broadband_asd) == (4, 1e-3, 3, 0.5)
    assert ex.max_response == 1e-4 and ex.sources["unbalance"] == "declared"


@pytest.mark.parametrize(
    "table, message",
    [
        ('unbalance_at = "rotor"', "[excitation]: key 'unbalance_at': 'rotor' names no disk or region"),
        ("unbalance_me = -1.0", "[excitation]: key 'unbalance_me': must not be negative"),
        ("broadband_at = 12", "[excitation]: key 'broadband_at': node 12 does not exist"),
        ("balance_grad = 6.3", "[excitation]: key 'balance_grad': unknown key; did you mean 'balance_grade'?"),
    ],
)
def test_a_bad_excitation_table_is_refused_with_its_key(tmp_path, table, message):
    with pytest.raises(ModelFileError) as err:
        load_model(fast_rotor(tmp_path, f"\n[excitation]\n{table}\n"))
    assert message in str(err.value) and "rotor.toml" in str(err.value)


def test_the_hydro_unit_declares_what_it_always_had(hydro_unit):
    ex = machine_excitation(hydro_unit)
    assert (ex.unbalance_me, ex.unbalance_node, ex.broadband_asd, ex.broadband_node) == (100.0, 8, 3000.0, 28)
