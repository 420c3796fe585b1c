"""Operating conditions and laws: the model file's tables, the model at an operating point, errors."""

import numpy as np
import pytest

from tests.conftest import ROOT
from twin import ModelError, ModelFileError, load_model, shipped_model
from twin.fem.operation import at_operating_point

ROSS = (ROOT / "models" / "ross_reference.toml").read_text()
CONDITION = """
[[condition]]
name = "temperature"
units = "degC"
reference = 40.0
range = [20.0, 60.0]
"""
LAW = """
[[law]]
parameter = "B0.kxx"
slopes = { temperature = -5.0e3 }
"""


def _load(tmp_path, text):
    path = tmp_path / "unit.toml"
    path.write_text(text)
    return load_model(path)


def test_the_hydro_unit_declares_its_operation_and_the_plain_model_has_none_of_its_effects():
    unit = load_model(shipped_model("hydro_unit"))
    op = unit.operation
    assert op.names == ("power", "reactive_power", "head", "oil_temperature")
    assert op.units == {"power": "MW", "reactive_power": "Mvar", "head": "m", "oil_temperature": "degC"}
    assert "MAG.stiffness" not in unit.parameter_names
    at_ref = at_operating_point(unit, {})
    assert at_ref.parameter("MAG.stiffness").nominal == -6.0e7
    assert at_ref.parameter("UGB.stiffness_change").nominal == 0.0  # the model's value: no change at 45 degC
    assert at_ref.parameter("UGB.kxx").nominal == unit.parameter("UGB.kxx").nominal


def test_a_law_is_affine_in_the_conditions():
    unit = load_model(shipped_model("hydro_unit"))
    a, b = {"power": 70.0, "oil_temperature": 33.0}, {"power": 200.0, "oil_temperature": 58.0}
    mid = {k: (a[k] + b[k]) / 2 for k in a}
    values = [at_operating_point(unit, p) for p in (a, b, mid)]
    for name in unit.operation.parameters:
        va, vb, vm = (m.parameter(name).nominal for m in values)
        assert vm == pytest.approx((va + vb) / 2, rel=1e-12, abs=1e-9)
    # MAG.stiffness: -6e7 - 1.2e5 N/m per MW from 180 MW
    assert values[0].parameter("MAG.stiffness").nominal == pytest.approx(-6.0e7 - 1.2e5 * (70.0 - 180.0))
    # the matrices follow: K at the generator's x DOF carries the pull
    k_ref = at_operating_point(unit, {}).matrices()["K"]
    k_low = values[0].matrices()["K"]
    dof = 4 * unit.regions["generator"][0]
    assert k_low[dof, dof] - k_ref[dof, dof] == pytest.approx(-1.2e5 * (70.0 - 180.0), rel=1e-9)


def test_an_operating_point_outside_the_range_or_unknown_is_refused_by_name():
    unit = load_model(shipped_model("hydro_unit"))
    with pytest.raises(ModelError, match=r"head = 170 m is outside the model's range \[120, 155\] m"):
        at_operating_point(unit, {"head": 170.0})
    with pytest.raises(ModelError, match="unknown operating condition 'load'.*power"):
        at_operating_point(unit, {"load": 100.0})
    with pytest.raises(ModelError, match="power must be a finite number"):
        at_operating_point(unit, {"power": float("nan")})
    with pytest.raises(ModelError, match="declares no operating conditions"):
        at_operating_point(load_model(shipped_model("ross_reference")), {})


def test_a_law_on_a_bearing_of_a_small_model(tmp_path):
    model = _load(tmp_path, ROSS + CONDITION + LAW)
    base = model.parameter("B0.kxx").nominal
    warm = at_operating_point(model, {"temperature": 50.0})
    assert warm.parameter("B0.kxx").nominal == pytest.approx(base - 5.0e4)
    assert np.allclose(at_operating_point(model, {}).matrices()["K"], model.matrices()["K"])


@pytest.mark.parametrize(
    "text, where, key, problem",
    [
        (CONDITION.replace('"degC"', '"degreez"'), "[[condition]] 'temperature'", "units", "not units pint reads"),
        (CONDITION.replace("40.0", "70.0"), "[[condition]] 'temperature'", "reference", "outside the range [20, 60]"),
        (CONDITION.replace("[20.0, 60.0]", "[60.0, 20.0]"), "[[condition]] 'temperature'", "range", "low < high"),
        (CONDITION + LAW.replace("B0.kxx", "B0.kxxx"), "[[law]] 'B0.kxxx'", "parameter", "no parameter 'B0.kxxx'"),
        (CONDITION + LAW.replace("temperature =", "temp ="), "[[law]] 'B0.kxx'", "slopes", "no condition 'temp'"),
        (
            CONDITION + LAW.replace("-5.0e3", "-5.0e5"),
            "[[law]] 'B0.kxx'",
            "slopes",
            "at temperature = 60 degC the law gives B0.kxx = -9e+06 N/m, outside its physical bounds (>= 0)",
        ),
        (LAW, "[[law]] #1", None, "declare them in [[condition]] tables"),
        (CONDITION + LAW + LAW, "[[law]] 'B0.kxx'", "parameter", "a second law for 'B0.kxx'"),
        (
            CONDITION + LAW.replace("slopes = { temperature = -5.0e3 }", "slopes = {}"),
            "[[law]] 'B0.kxx'",
            "slopes",
            "expected a table of slopes",
        ),
    ],
)
def test_operation_tables_errors_name_the_table_and_key(tmp_path, text, where, key, problem):
    with pytest.raises(ModelFileError) as info:
        _load(tmp_path, ROSS + text)
    err = info.value
    assert err.table == where and err.key == key and problem in err.problem, str(err)
