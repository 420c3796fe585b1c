"""The twin object: the loop on a hidden magnetic pull, and its history."""

import pytest

from twin.fem.effects import MagneticPull
from twin.fem.truthfile import Truth
from twin.loop.twin import Twin
from twin.update import synthesize_modes


def test_the_loop_brings_the_error_down_and_keeps_the_history(hydro_unit, tmp_path):
    data = synthesize_modes(hydro_unit, Truth((MagneticPull(-1e8),)), n_modes=13, samples=100, seed=4,
                            pole_variance=(0.01, 0.01))  # fmt: skip
    tw = Twin(hydro_unit, data)
    d = tw.diagnose()
    assert d.missing == "magnetic_pull"
    tw.add_effect(d.missing)
    tree = tw.update(d.ranking[0].names, draws=300, chains=2, seed=2, progress=False)
    hist = tw.history_table()
    assert list(hist["action"].values) == ["start", "add magnetic_pull", "update MAG.stiffness"]
    assert hist["error"][1] == pytest.approx(hist["error"][0])  # a zero-valued effect changes nothing
    assert hist["error"][2] < 0.2 * hist["error"][0]  # the error falls by more than 80%
    assert tw.model.parameter("MAG.stiffness").nominal == pytest.approx(-1e8, rel=0.10)
    assert "theta" in tree["posterior"]
    assert tw.plot_history(tmp_path / "history.png").stat().st_size > 1000
