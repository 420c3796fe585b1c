"""Shared fixtures of the tests: synthetic records, paper cases and test data (the shipped models: ../conftest.py)."""

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
DATA = Path(__file__).resolve().parent / "data"


def modal_record(
    poles,
    shapes,
    *,
    fs_hz,
    duration_s,
    seed,
    noise_ratio=0.05,
    participation=None,
    sinusoid=None,
    channels=None,
    attrs=None,
):
    """A synthetic signals Dataset: a sum of modes driven by white noise, plus sensor noise.

    Mode ``k`` (pole ``lambda_k``, complex output shape ``phi_k``) has the modal
    coordinate ``q_k[t+1] = exp(lambda_k / fs) q_k[t] + e_k[t]`` and adds
    ``2 Re(phi_k q_k)`` to the outputs. ``e_k`` is independent complex white
    noise, or ``participation @ u`` for real white forces ``u`` (correlated
    modal forcing, as in a rotor driven at one node). ``sinusoid`` =
    ``(frequency_hz, amplitudes)`` adds a harmonic. The noise std is
    ``noise_ratio`` times the median channel std. Fixed ``seed``.
    """
    import numpy as np
    import scipy.signal as sg
    import xarray as xr

    rng = np.random.default_rng(seed)
    n = int(round(duration_s * fs_hz))
    poles, shapes = np.asarray(poles), np.asarray(shapes)
    if participation is None:
        e = rng.standard_normal((len(poles), n)) + 1j * rng.standard_normal((len(poles), n))
    else:
        e = np.asarray(participation) @ rng.standard_normal((np.shape(participation)[1], n))
    y = np.zeros((n, shapes.shape[1]))
    for lam, phi, ek in zip(poles, shapes, e):
        q = sg.lfilter([1.0], [1.0, -np.exp(lam / fs_hz)], ek)
        y += 2 * np.real(q[:, None] * phi[None, :])
    t = np.arange(n) / fs_hz
    if sinusoid is not None:
        f, amp = sinusoid
        y += np.cos(2 * np.pi * f * t)[:, None] * np.real(amp) - np.sin(2 * np.pi * f * t)[:, None] * np.imag(amp)
    y += noise_ratio * np.median(y.std(axis=0)) * rng.standard_normal(y.shape)
    names = channels or [f"ch{i}" for i in range(y.shape[1])]
    return xr.Dataset(
        {"displacement": (("time", "channel"), y, {"units": "m"})},
        coords={"time": ("time", t, {"units": "s"}), "channel": names},
        attrs={"sampling_rate": fs_hz, **(attrs or {})},
    )


@pytest.fixture(scope="session")
def make_record():
    """The synthetic record builder :func:`modal_record`."""
    return modal_record


@pytest.fixture(scope="session")
def shear_frame():
    """KOMA's 5-storey shear-frame record (fs = 12 Hz) and its reference modes."""
    import numpy as np
    import xarray as xr

    data = np.load(DATA / "shearframe.npz")
    ds = xr.Dataset(
        {"displacement": (("time", "channel"), data["response"])},
        coords={"channel": [f"storey{i + 1}" for i in range(5)]},
        attrs={"sampling_rate": 12.0},
    )
    return ds, data["omega_n"], data["xi_ref"], data["phi_ref"]


@pytest.fixture(scope="session")
def paper_truth_modes(hydro_unit):
    """The paper's Table 2 truth: mode i from the FEM altered by its own (m_i, c_i), on all DOFs."""
    from twin.fem.truthfile import paper_truth
    from twin.fmu.truth import truth_modes

    return truth_modes(hydro_unit, paper_truth())


@pytest.fixture(scope="session")
def paper_modes(hydro_unit):
    """Paper-style synthetic modal data (Figure 2 procedure), J = 100, seed 1."""
    from twin.update import synthesize_modes

    return synthesize_modes(hydro_unit, samples=100, seed=1)


@pytest.fixture(scope="session")
def case_b_posterior(hydro_unit, paper_modes):
    """The default sampler's posterior of paper Case B (16 bearings + per-mode FSI) on ``paper_modes``, 2 x 500.

    The model's own posterior (``adjust="none"``): what the Fisher std is compared with.
    """
    import warnings

    from twin.errors import TwinWarning
    from twin.update import update

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", TwinWarning)
        return update(
            hydro_unit,
            paper_modes,
            "bearings",
            fsi=True,
            options={"draws": 500, "chains": 2, "seed": 2, "progress": False},
        )


@pytest.fixture(scope="session")
def dask_local():
    """A client of a local Dask cluster: two worker processes, one thread each (as ``--scheduler local``)."""
    from twin.tasks import dask_client

    with dask_client("local", n_workers=2) as client:
        yield client


#: Sizes of the hand-built updating problem of the ``toy`` fixture: modes, pole samples, residual rows,
#: shape entries, perturbations.
TOY_SIZES = (2, 6, 3, 2, 2)


@pytest.fixture
def toy():
    """Two modes, one shared and one own parameter, 3 residual rows, z = (2 shape entries, 2 perturbations)."""
    import numpy as np

    from twin.update.chain import State
    from twin.update.problem import Problem, sparse_blocks

    I, J, N_R, N_PSI, N_E = TOY_SIZES
    rng = np.random.default_rng(3)
    H = rng.standard_normal((I, 3, J, N_R, N_PSI + N_E))
    H[:, 2, :, 0] = 0.0  # the own parameter does not touch row 0: blocks must handle it
    problem = Problem(
        H0=H[:, 0].copy(),
        blocks=sparse_blocks(H[:, 1:]),
        data_index=np.arange(N_PSI),
        eps_index=N_PSI + np.arange(N_E),
        psi_hat=rng.standard_normal((I, J, N_PSI)),
        psi_var=np.full((I, N_PSI), 0.3),
        global_names=["a"],
        global_scale=np.ones(1),
        global_nominal=np.ones(1),
        mode_names=["b"],
        mode_scale=np.ones((I, 1)),
        mode_nominal=np.zeros((I, 1)),
        modes=np.array([1, 2]),
        channels=["c"],
        method="stage 2",
        eps_std=0.2,
        margin=np.full(I, np.inf),
        resonance_hz=np.full(I, np.nan),
    )
    state = State(
        np.array([0.4]),
        np.array([[-0.3], [0.7]]),
        rng.standard_normal((I, N_PSI + N_E)),
        rng.uniform(0.5, 2.0, (I, N_R)),
    )
    return problem, state, H


@pytest.fixture(scope="module")
def small(hydro_unit):
    """The marginal model of modes 3, 4 and 10 of paper-style data (J = 30) for the LGB stiffnesses and per-mode
    FSI, and the data: ``(marginal, modes)``."""
    from twin.update import synthesize_modes
    from twin.update.marginal import marginal_problem
    from twin.update.problem import build_problem, select_parameters

    data = synthesize_modes(hydro_unit, samples=30, seed=7).isel(mode=[2, 3, 9])
    problem = build_problem(hydro_unit, data, select_parameters(hydro_unit, "LGB.k*"), fsi=True, pole_model="marginal")
    return marginal_problem(problem, data["pole"].values), data
