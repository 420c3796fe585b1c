"""The steady start: the FMU's records are stationary from their first sample."""

import fmpy
import numpy as np

from twin.fem.model import RPM_TO_RAD_S
from twin.fmu import discretize, export_fmu, full_state_space, truncated_state_space
from twin.fem.excitation import machine_excitation
from twin.fmu.steady import steady_start

H = 1.0 / 256.0


def test_the_first_seconds_have_the_stationary_variance(tmp_path, hydro_unit):
    """Over 60 seeds, the outputs' variance in the first second of a record started steady is the
    stationary variance C (P + Γ1 Σ Γ1ᵀ) Cᵀ (within the spread 60 records allow); started from rest it is
    a fraction of it."""
    fmu = export_fmu(hydro_unit, tmp_path / "m.fmu", basis="modal", fmax_hz=60.0, inputs=[])
    ss = truncated_state_space(full_state_space(hydro_unit), 60.0)
    disc = discretize(ss, H)
    ports = ss.node_ports(machine_excitation(hydro_unit).broadband_node)
    asd = 3000.0
    s = steady_start(disc, ss.speed_rpm * RPM_TO_RAD_S, ports)
    g1 = disc.gamma1[:, ports]
    P_x = asd**2 * (s.factor @ s.factor.T + g1 @ g1.T / (2 * H))
    stationary = np.real(np.diag(ss.C @ P_x @ ss.C.T))
    runs = {True: [], False: []}
    for steady in runs:
        for seed in range(60):
            res = fmpy.simulate_fmu(
                str(fmu),
                stop_time=1.0,
                step_size=H,
                output_interval=H,
                start_values={
                    "unbalance_me": 0.0,
                    "turbulence_asd": asd,
                    "turbulence_seed": seed,
                    "steady_start": steady,
                },
            )
            runs[steady].append(np.column_stack([res[c] for c in ss.outputs]))
    ratio = {k: np.var(np.array(v), axis=0).mean(axis=0) / stationary for k, v in runs.items()}
    # 60 records: each channel's variance is known to about sqrt(2/60) = 18%, less averaged over 1 s
    assert np.all(np.abs(ratio[True] - 1) < 0.4), ratio[True]
    assert abs(np.mean(ratio[True]) - 1) < 0.15, ratio[True]
    assert np.mean(ratio[False]) < 0.6, ratio[False]  # from rest the response has not built up in 1 s


def test_an_fmu_exported_without_a_steady_start_starts_from_rest(tmp_path, hydro_unit):
    fmu = export_fmu(hydro_unit, tmp_path / "rest.fmu", basis="modal", fmax_hz=60.0, steady_start=False)
    md = fmpy.read_model_description(str(fmu))
    assert next(v for v in md.modelVariables if v.name == "steady_start").start == "false"
    res = fmpy.simulate_fmu(str(fmu), stop_time=0.1, step_size=H, output_interval=H)
    assert np.all(np.column_stack([res[c] for c in res.dtype.names[1:]])[0] == 0.0)  # at rest at t = 0
    try:
        fmpy.simulate_fmu(str(fmu), stop_time=0.1, step_size=H, start_values={"steady_start": True})
    except Exception as exc:  # noqa: BLE001 (FMPy's own exception type)
        assert "fmi2SetBoolean" in str(exc)
    else:
        raise AssertionError("steady_start = true was accepted by an FMU without its matrices")
