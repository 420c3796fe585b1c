"""twin demo and the hidden-effect tests on FMU signals: simulate a truth, extract, diagnose, add, update."""

import json
from pathlib import Path

import numpy as np
import pytest

from twin.cli import main
from twin.errors import TwinError
from twin.harness.demo import run_demo
from twin.harness.scenarios import parse_scenario
from twin.loop.history import read_history


@pytest.mark.slow
def test_demo_command_writes_the_report_and_the_error_falls(tmp_path, capsys):
    out = tmp_path / "demo"
    # 10 min instead of 20: the same loop at a fraction of the cost, on twice the reference pull so that it
    # stands five times above the noise floor of the shorter record. The posterior is calibrated on the demo's
    # default records (twin.harness.demo.DEMO_RECORDS), which run on the default local cluster
    assert (
        main(
            [
                "demo",
                "--out",
                str(out),
                "--duration",
                "600",
                "--samples",
                "10",
                "--hidden",
                "magnetic_pull@2",
                "--workers",
                "2",
            ]
        )
        == 0
    )
    printed = capsys.readouterr().out
    assert "round 1: missing effect (magnetic_pull)" in printed and "round 2: nothing missing" in printed
    for name in (
        "report.md",
        "signals.nc",
        "modes.nc",
        "diagnosis.json",
        "history.csv",
        "history.png",
        "stabilisation.png",
        "errors.png",
        "mac.png",
        "spectra.png",
        "hydro_unit.fmu",
    ):
        assert (out / name).stat().st_size > 100, name
    report = (out / "report.md").read_text()
    assert "Round 1: **missing effect** (magnetic_pull)" in report and "![history](history.png)" in report
    rounds = json.loads((out / "diagnosis.json").read_text())["rounds"]
    assert rounds[0]["ranking"][0]["effect"] == "magnetic_pull" and rounds[1]["verdict"] == "nothing missing"
    history = read_history(out / "history.csv")
    errors = history["error"].values
    assert len(errors) == 3 and errors[-1] < 0.2 * errors[0]
    # the update's E with its 90% interval over the posterior (E at the estimate: 0.0790%, in 0.0763-0.0828%)
    low, high = history["error_low"].values, history["error_high"].values
    assert np.isnan(low[:2]).all() and errors[-1] * 0.5 < low[-1] < high[-1] < 0.2 * errors[0]
    assert "| E, 90% over the posterior [%] |" in report
    # the update is the APerCEM sampler's (HMC on the marginal): its posterior, interval and diagnostics in the report
    assert (
        "jointly: APerCEM, HMC on the marginal (pole deviations and shapes integrated out), 4 chains x 500 draws"
        in report
    )
    row = next(line for line in report.splitlines() if line.startswith("| MAG.stiffness"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert " to " in cells[3] and float(cells[5]) <= 1.01 and float(cells[6]) >= 400, cells  # R-hat, bulk ESS
    assert "R-hat" in printed and "90% in" in printed
    assert "The intervals are calibrated on 4 records simulated at the estimate" in report
    assert "update MAG.stiffness, calibrated on 4 simulated records" in printed


def test_demo_refuses_an_unknown_hidden_effect(tmp_path):
    with pytest.raises(TwinError, match="unknown 'gravity'; choose from fsi, fsi_per_mode, magnetic_pull"):
        run_demo(tmp_path, hidden="gravity", progress=False)
    assert not any(tmp_path.iterdir())


# The hidden-effect tests, on signals: each truth is simulated through its FMU for 20 min,
# the modes are extracted, and the twin without the effect is diagnosed and updated (the APerCEM Gibbs
# sampler, the loop's default). Four effects meet the three criteria (named first, E falls by 80%
# or more, every parameter within 10% of its truth). The bearing changes' stiffness parameters are ones
# 20 min of signals do not pin to 10% (posterior std 15-60%: the bearings' large cross-coupling hides
# them); they are checked against their own posterior std (|z| < 3) instead.
# The scenarios run as one sweep, one Dask task each, on a local cluster of two workers.
HIDDEN_CASES = {
    "magnetic_pull": (),
    "fsi": (),
    "seal_cross_coupling": (),
    "thrust_tilt:thrust": (),
    "bearing_change:UGB": ("UGB.stiffness_change",),
    "bearing_change:LGB": ("LGB.stiffness_change",),
}
NO_EFFECT_SEED = 5


@pytest.fixture(scope="module")
def hidden_sweep(hydro_unit, dask_local, tmp_path_factory):
    from twin.harness.sweep import sweep

    scenarios = [(h, 1) for h in HIDDEN_CASES] + [("none", NO_EFFECT_SEED), ("shaft_stiffness_loss", 1)]
    out = tmp_path_factory.mktemp("sweep")
    table = sweep(scenarios, out, model=hydro_unit, tasks=dask_local, progress=False)
    return table.set_index(scenario="hidden").assign_attrs(out=str(out))


@pytest.mark.slow
@pytest.mark.parametrize("hidden", list(HIDDEN_CASES))
def test_hidden_effect_in_fmu_signals_is_found_and_identified(hidden, hidden_sweep, hydro_unit):
    r = hidden_sweep.sel(scenario=hidden)
    assert str(r.verdict.values) == "missing effect" and str(r.missing.values) == hidden
    assert float(r.error_after) < 0.2 * float(r.error_before), (float(r.error_before), float(r.error_after))
    truth = parse_scenario(hidden, hydro_unit).truth_values(hydro_unit)
    identified = r.where(np.isfinite(r["map"]), drop=True)
    assert sorted(identified["parameter"].values) == sorted(truth)
    for name in truth:
        value, std = float(identified["map"].sel(parameter=name)), float(identified["std"].sel(parameter=name))
        if name in HIDDEN_CASES[hidden]:
            assert abs(value - truth[name]) < 3 * std, (name, value, std)
        else:
            assert value == pytest.approx(truth[name], rel=0.10), name
    assert bool(r.passed) and (bool(r.passed_strict) or bool(HIDDEN_CASES[hidden]))


@pytest.mark.slow
def test_default_sampler_mixes_on_extracted_modes(hidden_sweep):
    # issue 18's regression test of the default (HMC on the marginal, 4 chains x 500 draws) on modes extracted
    # from FMU signals, fixed seeds: every parameter the data determine mixes (R-hat at most 1.01 to two
    # decimals, bulk ESS at least 100 per chain); the ones reported as not determined still have sane chains
    identified = hidden_sweep["r_hat"].notnull()
    assert int(identified.sum()) == 9  # pull, seal, tilt: one each; FSI, UGB and LGB changes: two each
    determined = identified & (hidden_sweep["determined"] == 1)
    r_hat = hidden_sweep["r_hat"].where(determined)
    ess = hidden_sweep["ess_bulk"].where(determined)
    assert float(r_hat.max()) < 1.015, r_hat.to_series().dropna().sort_values().tail(3)
    assert float(ess.min()) >= 400, ess.to_series().dropna().sort_values().head(3)
    loose = hidden_sweep["r_hat"].where(identified & ~determined).values
    assert np.all(loose[np.isfinite(loose)] < 1.1)


@pytest.mark.slow
def test_no_hidden_effect_in_fmu_signals_is_no_false_alarm(hidden_sweep, hydro_unit):
    r = hidden_sweep.sel(scenario="none")
    assert str(r.verdict.values) == "nothing missing" and int(r.seed) == NO_EFFECT_SEED
    assert bool(r.passed)
    assert parse_scenario("fsi", hydro_unit).truth_values(hydro_unit) == {
        "FSI.added_mass": 6e4,
        "FSI.added_damping": 2e6,
    }


@pytest.mark.slow
def test_change_outside_the_library_in_fmu_signals_is_unexplained_and_located(hidden_sweep):
    from twin.harness.sweep import folder_name

    # shaft element 18 at half its bending stiffness, simulated through the FMU: no library effect explains it
    r = hidden_sweep.sel(scenario="shaft_stiffness_loss")
    assert str(r.verdict.values) == "unexplained" and str(r.missing.values) == ""
    assert str(r.location.values) == "shaft_stiffness:18"
    assert bool(r.passed) and np.isnan(r["map"].values).all()  # nothing added, nothing updated
    report = (Path(hidden_sweep.attrs["out"]) / folder_name("shaft_stiffness_loss", 1) / "report.md").read_text()
    assert "Hidden in the truth: **shaft element 18 (nodes 18-19" in report
    assert "Round 1: **unexplained**" in report and "shaft element 18" in report
