"""Observability of modes (twin.design.observe): the spectrum model against a direct simulation, the bounds' scaling."""

import dataclasses

import numpy as np
import pytest
import scipy.signal as ss_signal

from twin import load_model, shipped_model
from twin.design import Excitation, observability
from twin.design.observe import (
    mode_clusters,
    mode_prominence,
    mode_snr,
    target_modes,
    target_summary,
    unobservable_text,
)
from twin.design.spectrum import Spectrum, spectrum
from twin.errors import ModelError
from twin.fmu.excitation import sensor_noise, turbulence_force
from twin.fem.excitation import machine_excitation
from twin.fmu.statespace import discretize, simulate_reference
from twin.fmu.truth import model_state_space


@pytest.fixture(scope="module")
def unit():
    return load_model(shipped_model("hydro_unit"))


@pytest.fixture(scope="module")
def table(unit):
    return observability(unit)


def test_spectrum_matches_a_direct_simulation_at_the_modes(unit):
    """Band power around four modes of a 10-min numpy simulation (the FMU's recursion) against the model."""
    ss = model_state_space(unit, "modal", 60.0)
    ex = Excitation(duration_s=600.0)
    sp = spectrum(ss, unit, ex)
    fs, n = ex.fs_hz, int(600 * ex.fs_hz)
    machine = machine_excitation(unit)
    ports = ss.node_ports(machine.broadband_node)
    zoh = np.zeros((n, len(ss.ports)))
    zoh[:, ports] = turbulence_force(n, machine.broadband_asd, seed=5, h=1 / fs)
    y = simulate_reference(discretize(ss, 1 / fs), ss.C, zoh=zoh)
    y += sensor_noise(n, y.shape[1], sp.noise_std_m, seed=6)
    f, pxx = ss_signal.welch(y, fs=fs, nperseg=8192, axis=0)
    model_psd = np.einsum("fcc->fc", sp.psd(f)).real
    for k in target_modes(sp.poles, 60.0)[[1, 2, 5, 7]]:  # 2.9, 10.2, 41.5, 51.7 Hz
        fk, half = sp.poles[k].imag / (2 * np.pi), -sp.poles[k].real / (2 * np.pi)
        band = np.abs(f - fk) < max(4 * half, 0.2)
        c = int(np.argmax(np.abs(sp.c[:, k])))
        ratio = pxx[band, c].sum() / model_psd[band, c].sum()
        assert abs(10 * np.log10(ratio)) < 1.0, (fk, ratio)  # 1 dB: Welch's scatter over ~140 averages is ~0.4 dB


def test_the_high_modes_are_not_observable_and_the_bearing_modes_are(table):
    f = table.frequency.values
    assert table.sizes["mode"] == 15
    assert not table.observable.values[f > 90].any()  # 94-97 Hz: exciter stub and turbine shaft, below the noise
    assert (table.best_snr_db.values[f > 90] < -15).all()
    assert table.observable.values[(f > 40) & (f < 55)].all()
    assert all(r for r, ok in zip(table.reason.values, table.observable.values) if not ok)


def test_close_modes_form_clusters_only_where_their_bands_overlap_and_their_stds_cannot_tell_them_apart():
    """Two modes 0.16% apart with stds of 0.08 Hz join; 0.28 Hz apart with 0.03 Hz stds do not; nor do modes with
    huge stds but disjoint half-power bands; a chain of close pairs is one cluster."""
    f = np.array([53.1, 94.6, 97.06, 97.22, 97.5])
    zeta = np.array([0.015, 0.026, 0.022, 0.022, 0.037])
    assert mode_clusters(f, zeta, np.array([0.01, 0.1, 0.08, 0.03, 0.03])).tolist() == [0, 0, 1, 1, 0]
    assert mode_clusters(f, zeta, np.array([0.01, 100.0, 0.08, 0.03, 0.03])).tolist() == [0, 1, 1, 1, 0]
    assert mode_clusters(f, zeta, np.full(5, 1e3)).tolist() == [0, 1, 1, 1, 1]  # 53.1 Hz: 41 Hz from 94.6 Hz
    assert mode_clusters(f, zeta, np.zeros(5)).tolist() == [0, 0, 0, 0, 0]


def test_the_high_modes_are_one_cluster_reported_as_such(table):
    """On the 8 sensors the four 94-97 Hz modes are one cluster; one extracted mode there counts for all four."""
    f = table.frequency.values
    assert (table.cluster.values[f > 90] == 1).all() and (table.cluster.values[f < 90] == 0).all()
    rows = target_summary(table, [2.92, 10.15, 96.0])
    high = [r for r in rows if r["cluster"]]
    assert [r["found"] for r in high] == [True] * 4 and high[0]["in_cluster"] == 1
    lines = unobservable_text(rows)
    assert any("one cluster: 94.59, 97.48, 97.49, 97.63 Hz" in line and "1 extracted mode(s)" in line for line in lines)
    none = unobservable_text(target_summary(table, [2.92]))  # nothing there: listed as not observable, cluster noted
    assert any("0 extracted mode(s)" in line for line in none) and any("97.63 Hz (peak" in line for line in none)


def test_noise_and_record_length_scale_as_they_must(unit, table):
    """Twice the noise std: every SNR falls by 20 log10(2) dB; nine times the record: the stds fall 3x (high SNR)."""
    noisy = observability(unit, Excitation(noise_ratio=0.10))
    assert np.allclose(table.snr_db - noisy.snr_db, 20 * np.log10(2), atol=1e-9)
    longer = observability(unit, Excitation(duration_s=9 * 1200.0))
    loud = table.best_snr_db.values > 20
    assert np.allclose(table.frequency_std.values[loud] / longer.frequency_std.values[loud], 3.0, rtol=1e-6)
    assert np.allclose(table.damping_ratio_crb.values[loud] / longer.damping_ratio_crb.values[loud], 3.0, rtol=1e-6)


def test_bad_settings_are_named(unit):
    with pytest.raises(ModelError, match="duration_s must be positive"):
        observability(unit, Excitation(duration_s=0.0))
    with pytest.raises(ModelError, match="noise_ratio"):
        observability(unit, Excitation(noise_ratio=-1.0))


def _two_mode_spectrum(strong: float) -> Spectrum:
    """One channel, one force port: modes at 10 Hz (1%) and 12 Hz (2%), the second ``strong`` times the first."""
    lam = np.array([-0.01 * 2 * np.pi * 10 + 2j * np.pi * 10, -0.02 * 2 * np.pi * 12 + 2j * np.pi * 12])
    poles = np.concatenate([lam, lam.conj()])
    c = np.array([[1.0, strong, 1.0, strong]], dtype=complex)
    b = np.ones((4, 1), dtype=complex)
    return Spectrum(poles, c, b, force_psd=1.0, noise_psd=1e-9, noise_std_m=1e-4, h=1 / 256)


def test_prominence_is_the_peak_against_the_other_mode_and_the_noise():
    """Without the other mode it is the peak-to-noise ratio; with it, the peak against that mode's response (both
    of its poles) and the noise at the first mode's frequency, computed by hand."""
    alone = _two_mode_spectrum(0.0)
    assert np.allclose(mode_prominence(alone, np.array([0])), mode_snr(alone, np.array([0])), atol=1e-9)
    sp = _two_mode_spectrum(30.0)
    f = sp.poles[0].imag / (2 * np.pi)
    s = 2j * np.pi * f
    other = 30.0 / (s - sp.poles[1]) + 30.0 / (s - sp.poles[3])
    background = np.abs(other) ** 2 * np.sinc(f * sp.h) ** 2 + sp.noise_psd
    expected = 10 * np.log10(np.sinc(f * sp.h) ** 2 / sp.poles[0].real ** 2 / background)
    assert np.allclose(mode_prominence(sp, np.array([0])), expected, atol=1e-9)
    assert mode_prominence(sp, np.array([0]))[0, 0] < mode_snr(sp, np.array([0]))[0, 0] - 20  # the flank masks it


def test_the_high_modes_are_masked_by_the_lower_modes_even_with_a_quiet_pair_at_the_top(unit):
    """With a 30 nm pair at the shaft's top (1 h, the paper's truth) the 94.6 and 97.5 Hz modes stand 15-22 dB above
    the noise but 4-7 dB below the other modes' response: where SSI did not find them (python benchmarks/extraction.py)."""
    from twin.fem.model import Sensor
    from twin.fem.truthfile import paper_truth

    top = dataclasses.replace(unit, sensors=[*unit.sensors, Sensor("TOP_x", 1, "x"), Sensor("TOP_y", 1, "y")])
    obs = observability(top, Excitation(noise_std_m=3e-8, duration_s=3600.0), truth=paper_truth(), crb=False)
    f = obs.frequency.values
    high = (np.abs(f - 94.58) < 0.05) | (np.abs(f - 97.50) < 0.05)
    assert high.sum() == 2 and (obs.best_snr_db.values[high] > 15).all()
    assert (obs.best_prominence_db.values[high] < -4).all()
    assert (obs.best_prominence_db.values[f < 60] > -3).all()  # the modes SSI finds on that record (and 19.1 Hz)


def test_judge_targets_marks_what_a_simulated_record_holds_and_leaves_a_measured_one(hydro_unit):
    """The judgement the comparison reads, made beside the extraction from the record's model and excitation."""
    import json

    import pytest
    import xarray as xr

    from twin import shipped_model
    from twin.design.observe import judge_targets
    from twin.errors import TwinError

    settings = {"channels": list(hydro_unit.channels), "duration_s": 1200.0, "fmin_hz": 0.0, "fmax_hz": 40.0}
    modes = xr.Dataset({"frequency": ("mode", [2.92, 10.15])}, attrs={"settings": json.dumps(settings)})
    simulated = xr.Dataset(
        attrs={
            "model_source": str(shipped_model("hydro_unit")),
            "settings": json.dumps({"turbulence_asd": 3000.0, "noise_std_m": 1e-6, "fs_hz": 256.0}),
        }
    )
    judged = judge_targets(modes, simulated)
    targets = {round(t["frequency_hz"], 1): t for t in json.loads(judged.attrs["target_observability"])}
    assert targets[2.9]["found"] and targets[10.1]["found"] and not targets[11.7]["found"]
    assert targets[11.7]["observable"] and "target_observability" not in modes.attrs  # the input is left as it is
    assert judge_targets(modes, xr.Dataset()) is modes  # a measured record names no model: nothing to judge
    with pytest.raises(TwinError, match="the modes do not say how they were extracted"):
        judge_targets(modes.assign_attrs(settings="{}"), simulated)
