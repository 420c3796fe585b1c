"""twin.update.intersection: each mode's pole and shape errors combined by covariance intersection."""

import dataclasses
import json

import numpy as np
import pytest

from twin.update import synthesize_modes, update
from twin.update.intersection import WEIGHT_GRID, intersected, intersection_weights
from twin.update.marginal import residual_moments
from twin.update.problem import UpdateError


def psd_sqrt(a):
    """The symmetric square root of a positive semi-definite matrix."""
    w, v = np.linalg.eigh(a)
    return (v * np.sqrt(np.clip(w, 0.0, None))) @ v.T


def correlated_residual_cov(H, B, lam, C, coupling, shapes):
    """cov(H e_z + B e_λ) for errors with covariances ``lam`` and ``C``, the shape entries ``shapes`` of ``e_z``
    correlated with ``e_λ`` by ``lam_ψ^½ K C^½`` (``K`` of spectral norm ``coupling`` < 1, so that the joint
    covariance is one) and the rest of ``e_z`` (``ε``) with nothing."""
    rng = np.random.default_rng(11)
    u, _, vt = np.linalg.svd(rng.standard_normal((len(shapes), 2)), full_matrices=False)
    X = np.zeros((lam.shape[0], 2))
    X[shapes] = psd_sqrt(lam[np.ix_(shapes, shapes)]) @ (coupling * u @ vt) @ psd_sqrt(C)
    cross = H @ X @ B.T
    return H @ lam @ H.T + B @ C @ B.T + cross + cross.T


def test_the_intersected_residual_covariance_bounds_every_correlation_of_pole_and_shape_errors(small):
    marg, _ = small
    theta = np.random.default_rng(1).normal(0.0, 0.3, marg.size)
    _, V_independent, H, B = residual_moments(marg, theta)
    idx = marg.problem.data_index
    for w in (0.1, 0.5, 0.9):
        both = intersected(marg, np.full(marg.problem.n_modes, w))
        _, V, _, _ = residual_moments(both, theta)
        for i in range(marg.problem.n_modes):
            # the model's V is H Λ Hᵀ / ω + B C Bᵀ / (1 - ω) exactly (Λ: the shapes' block, over ω; ε as before)
            lam = marg.cov_z[i].copy()
            lam[np.ix_(idx, idx)] /= w
            expected = H[i] @ lam @ H[i].T + B[i] @ marg.pole_cov[i] @ B[i].T / (1 - w)
            np.testing.assert_allclose(V[i], expected, rtol=1e-10, atol=1e-12 * np.abs(expected).max())
            # and it bounds the residual's covariance whatever the correlation of the errors
            for coupling in (0.0, 0.5, 0.95):
                actual = correlated_residual_cov(H[i], B[i], marg.cov_z[i], marg.pole_cov[i], coupling, idx)
                scale = np.abs(V[i]).max()
                assert np.linalg.eigvalsh(V[i] - actual).min() > -1e-9 * scale
    # the bound never adds information: each mode's Fisher information about the parameters only shrinks
    A = marg.columns[:, 1:, 0]
    _, V_default, _, _ = residual_moments(intersected(marg), theta)
    for i in range(marg.problem.n_modes):
        loss = A[i] @ np.linalg.solve(V_independent[i], A[i].T) - A[i] @ np.linalg.solve(V_default[i], A[i].T)
        assert np.linalg.eigvalsh(loss).min() > -1e-9 * np.abs(loss).max()
    # taken as independent, a strong correlation breaks the bound on some mode (what the intersection is for)
    short = [
        np.linalg.eigvalsh(
            V_independent[i] - correlated_residual_cov(H[i], B[i], marg.cov_z[i], marg.pole_cov[i], 0.95, idx)
        ).min()
        < -1e-4 * np.abs(V_independent[i]).max()
        for i in range(marg.problem.n_modes)
    ]
    assert any(short)


def test_each_mode_is_read_mostly_from_whichever_of_pole_and_shape_carries_the_information(small):
    marg, _ = small
    w = intersection_weights(marg)
    assert w.shape == (3,) and np.all(np.isin(w, WEIGHT_GRID))
    # poles made uninformative (a million times their covariance): each mode leans on its shapes
    vague_poles = dataclasses.replace(marg, pole_cov=marg.pole_cov * 1e6)
    np.testing.assert_array_equal(intersection_weights(vague_poles), WEIGHT_GRID[-1])
    # poles made ten thousand times more precise: each mode leans on them at least as much as before
    sharp_poles = intersection_weights(dataclasses.replace(marg, pole_cov=marg.pole_cov * 1e-4))
    assert np.all(sharp_poles <= w) and np.all(sharp_poles < WEIGHT_GRID[-1])
    # the weight is the grid's best: no other weight keeps more of the mode's information
    theta = np.zeros(marg.size)
    _, _, H, B = residual_moments(marg, theta)
    A = marg.columns[:, 1:, 0]
    for i in range(3):
        S, P = H[i] @ marg.cov_z[i] @ H[i].T, B[i] @ marg.pole_cov[i] @ B[i].T
        ridge = 1e-9 * np.trace(A[i] @ np.linalg.solve(S + P, A[i].T)) / A.shape[1] * np.eye(A.shape[1])
        kept = [np.linalg.slogdet(A[i] @ np.linalg.solve(S / g + P / (1 - g), A[i].T) + ridge)[1] for g in WEIGHT_GRID]
        assert np.linalg.slogdet(A[i] @ np.linalg.solve(S / w[i] + P / (1 - w[i]), A[i].T) + ridge)[1] == max(kept)


def test_intersected_refuses_weights_outside_the_open_interval_and_a_singular_mode(small):
    marg, _ = small
    cov_z, pole_cov = marg.cov_z.copy(), marg.pole_cov.copy()
    cov_z[1], pole_cov[1] = 0.0, 0.0  # mode 4 without any scatter
    with pytest.raises(UpdateError, match="residual covariance of mode 4 is singular"):
        intersected(dataclasses.replace(marg, cov_z=cov_z, pole_cov=pole_cov))
    with pytest.raises(ValueError, match=r"one weight strictly between 0 and 1 per mode \(3\)"):
        intersected(marg, np.array([0.5, 1.0, 0.5]))
    with pytest.raises(ValueError, match="per mode"):
        intersected(marg, np.array([0.5, 0.5]))


def test_update_combines_by_intersection_by_default_and_records_the_weights(hydro_unit):
    data = synthesize_modes(hydro_unit, samples=30, seed=7).isel(mode=[2, 3, 9])
    tree = update(hydro_unit, data, "LGB.kxx", options={"draws": 60, "chains": 1, "seed": 0, "progress": False})
    assert json.loads(tree.attrs["settings"])["combine"] == "intersection"
    weights = json.loads(tree.attrs["intersection_weights"])
    assert sorted(weights) == ["10", "3", "4"] and all(0 < v < 1 for v in weights.values())
    plain = update(
        hydro_unit,
        data,
        "LGB.kxx",
        options={"draws": 60, "chains": 1, "seed": 0, "progress": False, "combine": "independent"},
    )
    assert "intersection_weights" not in plain.attrs
    with pytest.raises(UpdateError, match="combine must be one of intersection, independent"):
        update(hydro_unit, data, "LGB.kxx", options={"combine": "joint", "progress": False})
    with pytest.raises(UpdateError, match="the 'gibbs' sampler has no option combine"):
        update(
            hydro_unit,
            data,
            "LGB.kxx",
            method="gibbs",
            options={"combine": "intersection", "pole_model": "linear", "progress": False},
        )
