"""A scenario's record simulated in numpy with numpy's random numbers, beside the FMU's.

The FMU's record is the exact recursion of its state space (:func:`twin.fmu.simulate_reference`; the two agree
to 1e-9 of the response, ``tests/test_simulate.py``) driven by the runtime's splitmix64 and Box-Muller streams
(:mod:`twin.fmu.excitation`). :func:`numpy_signals` builds the same record (the same system, 1X unbalance,
turbulence level, warm-up and sensor noise level, forces linear between samples as the FMU takes them) from
numpy's generator instead (from rest through the warm-up of :func:`twin.fmu.simulate.default_warmup_s`, where the
FMU starts steady: both are stationary records of the same system): with ``--streams numpy`` the FMU dataset benchmarks check that what they find on FMU
records is no property of the runtime's streams (docs/decisions/extraction-differenced.md).
"""

from __future__ import annotations

import json

import numpy as np
import xarray as xr

STREAMS = ("fmu", "numpy")


def numpy_signals(model, truth, duration_s: float, seed: int, fs_hz: float = 256.0) -> xr.Dataset:
    """The ``signals.nc`` Dataset of :func:`twin.fmu.simulate.simulate` with its defaults, from numpy's streams.

    Turbulence (x and y at the runner), then the sensor noise, are drawn from ``numpy.random.default_rng(seed)``;
    everything else is the FMU's: its system for ``truth``, noise level and 1X unbalance; it starts from rest and
    discards :func:`twin.fmu.simulate.default_warmup_s`.

    Examples
    --------
    >>> from twin import load_model, shipped_model
    >>> ds = numpy_signals(load_model(shipped_model("hydro_unit")), None, duration_s=0.5, seed=3)
    >>> ds.displacement.dims, ds.sizes["time"], ds.attrs["streams"]
    (('time', 'channel'), 128, 'numpy')
    """
    from twin.fmu import discretize, simulate_reference
    from twin.fmu.excitation import excitation_forces
    from twin.fem.excitation import machine_excitation
    from twin.fmu.simulate import default_warmup_s, sensor_noise_std, system_for

    h = 1.0 / fs_hz
    ss = system_for(model, truth, "full", None)
    n_warm = int(np.ceil(default_warmup_s(ss) * fs_hz))
    n_rec = int(round(duration_s * fs_hz))
    total = n_warm + n_rec
    rng = np.random.default_rng(seed)
    machine = machine_excitation(model)
    turbulence_node = machine.broadband_node
    t = (np.arange(total) - n_warm) * h
    forces = excitation_forces(
        ss,
        t,
        machine.unbalance_node,
        machine.unbalance_me,
        turbulence_node,
        machine.broadband_asd / np.sqrt(2 * h) * rng.standard_normal((total, 2)),
    )
    turbulence = ss.node_ports(turbulence_node)
    y = simulate_reference(discretize(ss, h), ss.C, foh=forces)[n_warm:]
    noise = rng.standard_normal((total, y.shape[1]))[n_warm:]  # drawn over the warm-up too, as the FMU's
    y += sensor_noise_std(ss, h, machine.broadband_asd, turbulence, 0.05) * noise
    attrs = {
        "title": f"simulated proximeter signals of {model.name} (numpy's random streams)",
        "sampling_rate": float(fs_hz),
        "speed_rpm": float(ss.speed_rpm),
        "model": model.name,
        "seed": int(seed),
        "streams": "numpy",
        "settings": json.dumps({"duration_s": duration_s, "fs_hz": fs_hz, "seed": seed, "streams": "numpy"}),
    }
    if truth is not None:
        attrs.update(truth=ss.attrs["truth"], truth_modes=ss.attrs["truth_modes"])
    return xr.Dataset(
        {"displacement": (("time", "channel"), y, {"units": "m"})},
        coords={"time": ("time", np.arange(n_rec) * h, {"units": "s"}), "channel": list(ss.outputs)},
        attrs=attrs,
    )
