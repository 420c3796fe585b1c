"""Sensor design (twin.design.sensors): the best place on a beam known by hand, the written layout, bad input."""

import json

import numpy as np
import pytest

from twin import load_model, shipped_model
from twin.design import Excitation, observability
from twin.design.sensors import candidate_nodes, design_sensors, write_layout
from twin.errors import ModelError

from tests.conftest import DATA

#: 5 min at 512 Hz: the beam's first two bending modes (25.5 and 101.7 Hz) are the targets up to 150 Hz.
BEAM_RECORD = Excitation(fs_hz=512.0, duration_s=300.0)


@pytest.fixture(scope="module")
def beam():
    return load_model(DATA / "beam.toml")


@pytest.fixture(scope="module")
def beam_design(beam):
    return design_sensors(beam, 1, fmax_hz=150.0, excitation=BEAM_RECORD, progress=False)


def test_the_pair_goes_to_an_antinode_of_the_mode_the_mid_span_sensor_cannot_see(beam_design):
    """Mid-span is the node of sin(2 pi z / L): the second mode (x and y) is invisible there.

    Its antinodes are the quarter points, nodes 2 and 6; both give the same amplitudes of
    the first two modes (|sin(pi/4)| and 1), so the design must choose one of them.
    """
    d = beam_design
    assert np.allclose(d.frequency, [25.49, 25.49, 101.71, 101.71], rtol=1e-3)
    assert d.observable[0].values.tolist() == [True, True, False, False]
    assert (d.best_snr_db[0, 2:] < -100).all()  # on the node: nothing
    assert np.isinf(d.frequency_rel_std[0, 2:]).all()  # a blind layout gets no finite std
    assert int(d.node[1]) in (2, 6)
    assert d.observable[1].values.all() and int(d.n_observable[1] - d.n_observable[0]) == 2
    assert float(d.criterion[1]) > float(d.criterion[0])


def test_the_noise_of_the_sensors_stays_the_same(beam, beam_design, tmp_path):
    """The written layout, judged with the design's noise std, gives the design's verdicts."""
    new = load_model(write_layout(beam, beam_design, tmp_path / "beam2.toml"))
    assert new.channels == ["MID_x", "MID_y", f"N{int(beam_design.node[1])}_x", f"N{int(beam_design.node[1])}_y"]
    ex = Excitation(fs_hz=512.0, duration_s=300.0, noise_std_m=beam_design.attrs["noise_std_m"])
    obs = observability(new, ex, fmax_hz=150.0, crb=False)
    assert obs.observable.values.all()
    assert np.allclose(obs.frequency_std / obs.frequency, beam_design.frequency_rel_std[1], rtol=1e-6)


def test_with_parameters_the_design_reports_their_std_at_every_step(beam):
    """Bearing A's stiffness: its expected std never grows with a pair added (more data, same model)."""
    d = design_sensors(beam, 1, names=["A.kxx"], fmax_hz=150.0, excitation=BEAM_RECORD, progress=False)
    assert list(d.parameter.values) == ["A.kxx"]
    assert d.relative_std.shape == (2, 1)
    assert float(d.relative_std[1, 0]) <= float(d.relative_std[0, 0])
    assert int(d.n_observable[1]) == 4


@pytest.mark.slow
def test_an_added_pair_never_raises_a_parameters_expected_std():
    """Case B's weak lower guide bearing, one-hour records of the paper's truth, pairs added at 0, 7 or 23.

    The record covariance of a mode is its Cramer-Rao bound raised by SSI's ratio above it. Judged
    on each layout, that ratio grows with the channels and LGB.kxx rose 8.1% -> 9.1% -> 9.6% (kyy
    16.2% -> 18.8%) as pairs were added; with the ratio of the starting layout kept, more channels
    can only add information.
    """
    from twin.fem.truthfile import paper_truth

    d = design_sensors(
        load_model(shipped_model("hydro_unit")),
        2,
        names=["LGB.kxx", "LGB.kyy"],
        candidates=[0, 7, 23],
        excitation=Excitation(duration_s=3600.0),
        truth=paper_truth(),
        progress=False,
    )
    rel = d.relative_std.values
    assert np.all(np.diff(rel, axis=0) <= 1e-9 * rel[:-1]), rel
    assert np.all(np.diff(d.n_observable.values) >= 0)


def test_candidates_and_bad_requests(beam):
    assert candidate_nodes(beam) == [0, 1, 2, 3, 5, 6, 7, 8]
    assert candidate_nodes(beam, [6, 2, 6]) == [6, 2]
    with pytest.raises(ModelError, match="already has a sensor"):
        candidate_nodes(beam, [4])
    with pytest.raises(ModelError, match="nodes 0..8"):
        candidate_nodes(beam, [9])
    with pytest.raises(ModelError, match="positive integer"):
        design_sensors(beam, 0)
    with pytest.raises(ModelError, match="only 2 candidate"):
        design_sensors(beam, 3, candidates=[1, 2])
    with pytest.raises(ModelError, match="NOPE"):
        design_sensors(beam, 1, names=["NOPE.k"])


def test_a_design_for_another_model_is_refused(beam, beam_design, tmp_path):
    unit = load_model(shipped_model("hydro_unit"))
    with pytest.raises(ModelError, match="for model 'beam'"):
        write_layout(unit, beam_design, tmp_path / "x.toml")
    assert not (tmp_path / "x.toml").exists()


def test_sensors_command_writes_the_model_and_prints_the_gains(tmp_path, capsys):
    from twin.cli import main

    out = tmp_path / "beam2.toml"
    assert (
        main(
            [
                "sensors",
                str(DATA / "beam.toml"),
                "--add",
                "1",
                "--fs",
                "512",
                "--duration",
                "300",
                "--fmax",
                "150",
                "-o",
                str(out),
                "--design",
                str(tmp_path / "d.nc"),
            ]
        )
        == 0
    )
    text = capsys.readouterr().out
    assert "+2" in text and "--noise-std" in text
    assert load_model(out).n_nodes == 9 and (tmp_path / "d.nc").is_file()


@pytest.mark.slow
def test_extraction_on_a_layout_with_an_added_pair_finds_what_the_table_promises(tmp_path):
    """Hydro unit plus a pair at the top of the shaft (node 0), 20 min records through the FMU, same sensor noise.

    The pair makes 16.2, 17.1 and 19.1 Hz observable (10 of 15 instead of 7). On three records (seeds 3-5)
    the extraction finds, on all 10 channels, every mode the table marks observable that is damped below
    5%, each within 4 standard errors of the model's pole (the records are simulated from the model
    itself). The 8.6%-damped 19.1 Hz mode, at 18 dB, is found in at least two of the three: whether a
    5-10%-damped mode clears the extraction's tolerance varies from record to record (seed 3 misses it).
    """
    from twin.design.observe import judge_targets
    from twin.extract import extract
    from twin.fmu.simulate import simulate
    from twin.loop.compare import compare

    unit = load_model(shipped_model("hydro_unit"))
    d = design_sensors(unit, 1, candidates=[0], progress=False)
    assert int(d.n_observable[0]) == 7 and int(d.n_observable[1]) == 10
    new = load_model(write_layout(unit, d, tmp_path / "unit.toml"))
    found_heavy = []
    for seed in (3, 4, 5):
        signals = simulate(new, duration_s=1200.0, seed=seed, noise_std_m=d.attrs["noise_std_m"], progress=False)
        assert signals.sizes["channel"] == 10
        modes = judge_targets(extract(signals, progress=False), signals)
        targets = json.loads(modes.attrs["target_observability"])
        assert sum(t["observable"] for t in targets) == 10
        light = [t for t in targets if t["observable"] and t["damping_ratio"] < 0.05]
        heavy = [t for t in targets if t["observable"] and t["damping_ratio"] >= 0.05]
        assert len(light) == 9 and all(t["found"] for t in light), (seed, light)
        found_heavy += [t["found"] for t in heavy]
        table = compare(new, modes)
        assert list(table.channel.values)[-2:] == ["N0_x", "N0_y"]
        seen = [t["frequency_hz"] for t in targets if t["observable"] and t["found"]]
        rows = [int(np.argmin(np.abs(table.measured_frequency.values - f))) for f in seen]
        assert np.all(np.abs(table.z_frequency.values[rows]) < 4)
        assert np.all(np.abs(table.z_damping.values[rows]) < 4)
    assert sum(found_heavy) >= 2, found_heavy


@pytest.mark.slow
def test_the_exciter_stub_modes_are_masked_at_every_node_and_the_turbine_shaft_pair_goes_to_its_node():
    """Paper's truth, 1 h, 100 nm sensors, candidates the shaft's top and the turbine shaft: the pair goes to node
    21, where 97.06 and 97.22 Hz stand out from the other modes; 94.6 and 97.5 Hz stay masked (below -4 dB
    without any noise), and the command's table says so. SSI finds what this promises (test_extraction_on_a_layout_with_an_added_pair_finds_what_the_table_promises)."""
    from twin.cli.design import sensors_text
    from twin.design.observe import PROMINENCE_LIMIT_DB
    from twin.fem.truthfile import paper_truth

    unit = load_model(shipped_model("hydro_unit"))
    d = design_sensors(
        unit,
        1,
        candidates=[1, 21],
        truth=paper_truth(),
        progress=False,
        excitation=Excitation(duration_s=3600.0, noise_std_m=1e-7),
    )
    f = d.frequency.values
    pair, stub = (np.abs(f - 97.14) < 0.1), (np.abs(f - 94.58) < 0.05) | (np.abs(f - 97.50) < 0.05)
    assert int(d.node[1]) == 21 and pair.sum() == 2 and stub.sum() == 2
    assert not d.observable[0, pair].any() and d.observable[1, pair].all()
    assert not d.observable[1, stub].any()
    assert (d.most_prominent_db.values[stub] < PROMINENCE_LIMIT_DB - 1).all()
    assert (d.best_snr_db[1, pair] > 15).all()
    text = sensors_text(d)
    assert text.count("masked at every node") == 2
