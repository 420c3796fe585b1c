"""Model files: loading, and errors that name the file, the table and the key."""

import pytest

from twin import ModelFileError, load_model, shipped_model

from tests.conftest import ROOT

BASE = (ROOT / "models" / "ross_reference.toml").read_text()


def _load(tmp_path, text):
    path = tmp_path / "unit.toml"
    path.write_text(text)
    return load_model(path)


def _error(tmp_path, old, new, count=1):
    assert old in BASE, old
    with pytest.raises(ModelFileError) as info:
        _load(tmp_path, BASE.replace(old, new, count))
    return info.value


def test_shipped_models_load():
    for name in ("hydro_unit", "pelton_unit", "ross_reference"):
        model = load_model(ROOT / "models" / f"{name}.toml")
        assert model.name == name and model.source.endswith(f"{name}.toml")
        assert load_model(name).source == str(shipped_model(name)) and shipped_model(name).is_file()
    with pytest.raises(ModelFileError, match="no shipped model 'hydro'.*hydro_unit"):
        shipped_model("hydro")
    with pytest.raises(ModelFileError, match="no such file"):
        load_model("hydro")


@pytest.mark.parametrize(
    "old, new, table, key, problem",
    [
        ("kxx = 1.0e6\n", "", "[[bearing]] 'B0'", "kxx", "missing key"),
        ("kyy = 8.0e5", "kyyy = 8.0e5", "[[bearing]] 'B0'", "kyy", "missing key (the table has 'kyyy': a typo?)"),
        (
            "Ip = 0.18",
            "Ip = 0.18\nIq = 0.1",
            "[[disk]] 'D4'",
            "Iq",
            "unknown key; known keys: Id, Ip, mass, name, node",
        ),
        ('location = "disk D2"', 'locaton = "disk D2"', "[[sensor]] 'D2'", "locaton", "did you mean 'location'"),
        ("length = 1.5", "length = -1.5", "[[shaft]] #1", "length", "must be positive"),
        ("mass = 20.0", "mass = -20.0", "[[disk]] 'D4'", "mass", "must not be negative"),
        ("mass = 20.0", 'mass = "heavy"', "[[disk]] 'D4'", "mass", "expected a number"),
        ("mass = 20.0", "mass = true", "[[disk]] 'D4'", "mass", "expected a number"),
        ('name = "B6"\nnode = 6', 'name = "B6"\nnode = 7', "[[bearing]] 'B6'", "node", "node 7 does not exist"),
        (
            'name = "D2"\nnode = 2\nlocation',
            'name = "D2"\nnode = 12\nlocation',
            "[[sensor]] 'D2'",
            "node",
            "nodes 0..6",
        ),
        ("inner_diameter = 0.0", "inner_diameter = 0.06", "[[shaft]] #1", "inner_diameter", "smaller than"),
        ('material = "steel"', 'material = "stel"', "[[shaft]] #1", "material", "unknown material 'stel'"),
        ("speed_rpm = 134.0", "speed_rpm = -1.0", "[model]", "speed_rpm", "must not be negative"),
        ("speed_rpm = 134.0", "speed_rmp = 134.0", "[model]", "speed_rpm", "the table has 'speed_rmp'"),
        ('name = "D4"', 'name = "B0"', "[[bearing]] 'B0'", "name", "already the name of a disk"),
        ('name = "D4"', 'name = "D.4"', "[[disk]] #2", "name", "not a valid name"),
        ("G = 81.2e9", "G = 81.2e9\npoisson = 0.3", "[materials.steel]", "G", "exactly one"),
        ("[[bearing]]", "[[bearings]]", "(top level)", "bearings", "did you mean 'bearing'"),
        ("kxx = 1.0e6\n", "kxx = 0.0\n", "[[bearing]] 'B0'", "kxx", "must be positive"),
        ("kyy = 8.0e5", "kyy = -8.0e5", "[[bearing]] 'B0'", "kyy", "must be positive"),
    ],
)
def test_errors_name_file_table_and_key(tmp_path, old, new, table, key, problem):
    err = _error(tmp_path, old, new)
    assert err.path.endswith("unit.toml")
    assert err.table == table
    assert err.key == key
    assert problem in str(err)
    assert str(err).startswith(str(tmp_path / "unit.toml"))


def test_overlapping_and_missing_shaft_elements(tmp_path):
    split = BASE.replace("nodes = [0, 6]\nlength = 1.5", "nodes = [0, 3]\nlength = 0.75")
    overlap = (
        split
        + '\n[[shaft]]\nnodes = [2, 6]\nlength = 1.0\nouter_diameter = 0.05\ninner_diameter = 0.0\nmaterial = "steel"\n'
    )
    with pytest.raises(ModelFileError, match=r"\[\[shaft\]\] #2: key 'nodes': section \[2, 6\] overlaps"):
        _load(tmp_path, overlap)
    gap = (
        split
        + '\n[[shaft]]\nnodes = [4, 6]\nlength = 0.5\nouter_diameter = 0.05\ninner_diameter = 0.0\nmaterial = "steel"\n'
    )
    with pytest.raises(ModelFileError, match="gap: no shaft element joins nodes 3 and 4"):
        _load(tmp_path, gap)
    ok = (
        split
        + '\n[[shaft]]\nnodes = [3, 6]\nelement_lengths = [0.25, 0.25, 0.25]\nouter_diameter = 0.05\ninner_diameter = 0.0\nmaterial = "steel"\n'
    )
    assert _load(tmp_path, ok).n_nodes == 7
    bad_lengths = ok.replace("[0.25, 0.25, 0.25]", "[0.25, 0.25]")
    with pytest.raises(ModelFileError, match="span 3 elements, got 2 lengths"):
        _load(tmp_path, bad_lengths)


def test_file_level_errors(tmp_path):
    with pytest.raises(ModelFileError, match="no such file"):
        load_model(tmp_path / "missing.toml")
    with pytest.raises(ModelFileError, match="not valid TOML"):
        _load(tmp_path, BASE.replace("kxx = 1.0e6", "kxx = = 1.0e6", 1))
    with pytest.raises(ModelFileError, match=r"\[model\]: key 'name'"):
        _load(tmp_path, BASE.replace('name = "ross_reference"', "name = 3"))


def test_sensor_directions_and_regions(tmp_path):
    text = BASE.replace('location = "disk D2"', 'location = "disk D2"\ndirections = ["x"]')
    assert _load(tmp_path, text).channels == ["B0_x", "B0_y", "D2_x"]
    with pytest.raises(ModelFileError, match=r"\[\[sensor\]\] 'D2': key 'directions'"):
        _load(tmp_path, BASE.replace('location = "disk D2"', 'location = "disk D2"\ndirections = ["z"]'))
    with pytest.raises(ModelFileError, match=r"\[regions\]: key 'immersed': node 9 does not exist"):
        _load(tmp_path, BASE + "\n[regions]\nimmersed = [9]\n")


def test_effects_in_model_files(tmp_path):
    text = BASE + "\n[regions]\ngenerator = [2]\n\n[effects.magnetic_pull]\nstiffness = -1.0e5\n"
    model = _load(tmp_path, text)
    assert model.parameter("MAG.stiffness").nominal == -1.0e5
    with pytest.raises(
        ModelFileError, match=r"\[effects\]: key 'magnetic_pul': unknown effect; did you mean 'magnetic_pull'"
    ):
        _load(tmp_path, text.replace("effects.magnetic_pull", "effects.magnetic_pul"))
    with pytest.raises(ModelFileError, match="acts on region 'seal', which \\[regions\\] does not declare"):
        _load(tmp_path, BASE + "\n[effects.seal_cross_coupling]\nkxy = 1.0e5\n")
    with pytest.raises(ModelFileError, match="per-mode effect .* truth file"):
        _load(tmp_path, BASE + "\n[regions]\nimmersed = [6]\n\n[effects.fsi_per_mode]\nadded_mass = [1.0]\n")
    with pytest.raises(
        ModelFileError, match=r"\[effects.magnetic_pull\]: key 'stifness': unknown key; did you mean 'stiffness'"
    ):
        _load(tmp_path, text.replace("stiffness = ", "stifness = "))
    with pytest.raises(
        ModelFileError,
        match=r"\[effects.magnetic_pull\]: key 'stiffness': MAG.stiffness = 1e\+05 is outside "
        r"its physical bounds \(<= 0",
    ):
        _load(tmp_path, text.replace("-1.0e5", "1.0e5"))
    assert _load(tmp_path, text.replace("stiffness = -1.0e5", "")).parameter("MAG.stiffness").nominal == 0.0


def test_element_effects_in_model_files(tmp_path):
    table = "\n[effects.bearing_change]\nbearing = {}\nstiffness_change = -2.0e5\ndamping_change = 0.0\n"
    model = _load(tmp_path, BASE + table.format('"B6"'))
    assert model.parameter("B6.stiffness_change").nominal == -2.0e5
    # the label, as twin params and --effect name it, for the table; two bearings at once
    labelled = '\n[effects."bearing_change:B6"]\nstiffness_change = -2.0e5\n\n[effects."bearing_change:B0"]\ndamping_change = 5.0\n'
    model = _load(tmp_path, BASE + labelled)
    assert (
        model.parameter("B6.stiffness_change").nominal == -2.0e5 and model.parameter("B0.damping_change").nominal == 5.0
    )
    with pytest.raises(ModelFileError, match=r'\[effects."bearing_change:B6"\]: a second table for the effect'):
        _load(tmp_path, BASE + table.format('"B6"') + labelled)
    with pytest.raises(ModelFileError, match=r"key 'stiffness': unknown key; did you mean 'stiffness_change'"):
        _load(tmp_path, BASE + table.format('"B6"').replace("stiffness_change", "stiffness"))
    with pytest.raises(
        ModelFileError, match=r"\[effects.bearing_change\]: key 'bearing': no bearing named 'B7'.*'B0', 'B6'"
    ):
        _load(tmp_path, BASE + table.format('"B7"'))
    with pytest.raises(ModelFileError, match=r"\[effects.bearing_change\]: key 'bearing'"):
        _load(tmp_path, BASE + table.format("6"))
