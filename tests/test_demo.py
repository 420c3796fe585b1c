"""twin demo and the hidden-effect tests on FMU signals: simulate a truth, extract, diagnose, add, update."""

import json

import numpy as np
import pytest

from twin.cli import main
from twin.errors import TwinError
from twin.loop.demo import HIDDEN_EFFECTS, run_demo, truth_values


def test_demo_command_writes_the_report_and_the_error_falls(tmp_path, capsys):
    out = tmp_path / "demo"
    # 10 min instead of 20: the same loop at half the cost (the README's command runs the default)
    assert main(["demo", "--out", str(out), "--duration", "600", "--samples", "10"]) == 0
    printed = capsys.readouterr().out
    assert "diagnosis: missing effect (magnetic_pull)" in printed
    for name in ("report.md", "signals.nc", "modes.nc", "diagnosis.json", "history.csv", "history.png",
                 "stabilisation.png", "before_errors.png", "after_spectra.png", "hydro_unit.fmu"):  # fmt: skip
        assert (out / name).stat().st_size > 100, name
    report = (out / "report.md").read_text()
    assert "Verdict: **missing effect** (magnetic_pull)" in report and "![history](history.png)" in report
    ranking = json.loads((out / "diagnosis.json").read_text())["ranking"]
    assert ranking[0]["effect"] == "magnetic_pull"
    errors = np.loadtxt(out / "history.csv", delimiter=",", skiprows=1, usecols=1)
    assert errors[-1] < 0.2 * errors[0]


def test_demo_refuses_an_unknown_hidden_effect(tmp_path):
    with pytest.raises(TwinError, match="unknown hidden effect 'gravity'.*magnetic_pull"):
        run_demo(tmp_path, hidden="gravity", progress=False)
    assert not any(tmp_path.iterdir())


# The hidden-effect tests, on signals: each truth is simulated through its FMU for 20 min,
# the modes are extracted, and the twin without the effect is diagnosed and updated (Laplace update on the
# poles). The parameters listed per case are ones 20 min of signals do not pin to 10% (posterior std 9.5%
# for the tilt stiffness, 40-70% for the bearing stiffness changes, which the bearings' large
# cross-coupling hides): they are checked against their own posterior std (|z| < 3) instead.
HIDDEN_CASES = {
    "magnetic_pull": (), "fsi": (),
    "thrust_tilt:thrust": ("thrust.k_tilt_change",),
    "bearing_change:UGB": ("UGB.stiffness_change",),
    "bearing_change:LGB": ("LGB.stiffness_change",),
}  # fmt: skip


@pytest.mark.slow
@pytest.mark.parametrize("hidden", list(HIDDEN_CASES))
def test_hidden_effect_in_fmu_signals_is_found_and_identified(hidden, hydro_unit, tmp_path):
    r = run_demo(tmp_path, model=hydro_unit, hidden=hidden, progress=False)
    assert r.diagnosis.verdict == "missing effect" and r.diagnosis.missing == hidden
    first, last = r.twin.history[0].error, r.twin.history[-1].error
    assert last < 0.2 * first, (first, last)
    post = r.posterior
    assert sorted(post["parameter"].values) == sorted(r.truth)
    for k, name in enumerate(post["parameter"].values):
        value, std, truth = float(post["map"][k]), float(post["std"][k]), r.truth[str(name)]
        if name in HIDDEN_CASES[hidden]:
            assert abs(value - truth) < 3 * std, (name, value, std)
        else:
            assert value == pytest.approx(truth, rel=0.10), name


@pytest.mark.slow
def test_no_hidden_effect_in_fmu_signals_is_no_false_alarm(hydro_unit, tmp_path):
    from twin.extract import extract
    from twin.fmu.simulate import simulate
    from twin.loop import Twin

    signals = simulate(hydro_unit, duration_s=1200.0, seed=5, progress=False)
    tw = Twin(hydro_unit, extract(signals, samples=20, fmax_hz=60.0, progress=False))
    d = tw.diagnose()
    assert d.verdict == "nothing missing", d.summary
    assert truth_values(hydro_unit, HIDDEN_EFFECTS["fsi"]) == {"FSI.added_mass": 6e4, "FSI.added_damping": 2e6}
