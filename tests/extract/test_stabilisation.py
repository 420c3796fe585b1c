"""Clustering of the stabilisation diagram's stable poles into modes (twin.extract.stabilisation)."""

import numpy as np

from twin.extract.stabilisation import Criteria, Diagram, cluster_poles, pole_distance


def _pole(f_hz: float, zeta: float) -> complex:
    w = 2 * np.pi * f_hz
    return complex(-zeta * w, w * np.sqrt(1 - zeta**2))


def _unit(*entries: complex) -> np.ndarray:
    v = np.array(entries, dtype=complex)
    return v / np.linalg.norm(v)


def _diagram(rows: list[tuple[np.ndarray, complex, np.ndarray]], seed: int = 0) -> Diagram:
    """All poles fully stable: (orders, pole, shape) per row, the poles jittered by 1e-4 relative."""
    rng = np.random.default_rng(seed)
    order, pole, shape = [], [], []
    for orders, lam, phi in rows:
        for n in orders:
            order.append(n)
            pole.append(lam * (1 + 1e-4 * rng.standard_normal()))
            shape.append(phi)
    n = len(order)
    return Diagram(
        order=np.array(order),
        pole=np.array(pole),
        shape=np.array(shape),
        status=np.full(n, 3, dtype=np.int8),
        cluster=np.full(n, -1),
    )


def test_fragments_of_one_mode_are_joined_and_a_neighbour_kept_apart():
    """A mode whose shape moves by 1 - MAC = 0.035 halfway up the orders is cut in two fragments of 9
    orders (under the 10 that 25% of 40 orders ask); joined, it is one mode of 18. A second mode at the
    same frequency, present at the same orders, with its own shape, stays a mode of its own."""
    t = np.arccos(np.sqrt(1 - 0.035))
    e1, a2 = _unit(1, 0, 0, 0), _unit(np.cos(t), np.sin(t), 0, 0)
    other = _unit(0, 0, 1, 1j)
    lam = _pole(10.0, 0.02)
    rows = [(np.arange(2, 20, 2), lam, e1), (np.arange(20, 38, 2), lam, a2), (np.arange(2, 38, 2), lam, other)]
    d = _diagram(rows)
    assert 0.03 < pole_distance(d.pole[:1], e1[None], d.pole[9:10], a2[None])[0, 0] < 0.045

    d, clusters = cluster_poles(d, 40, Criteria())
    assert sorted(len(c.members) for c in clusters) == [18, 18]
    joined = next(c for c in clusters if np.abs(d.shape[c.representative] @ other.conj()) < 0.5)
    assert sorted(d.order[joined.members]) == list(range(2, 38, 2))

    _, apart = cluster_poles(_diagram(rows), 40, Criteria(merge_distance=0.0))
    assert [len(c.members) for c in apart] == [18]  # without the join only the neighbour is a mode


def test_fragments_far_apart_in_shape_are_not_joined():
    """Two groups of 9 orders 0.06 apart (as the KOMA shear frame's spurious 1.62 Hz pole's fragments)
    stay below the 10 orders asked: no mode."""
    t = np.arccos(np.sqrt(1 - 0.06))
    lam = _pole(1.62, 0.022)
    rows = [(np.arange(2, 20, 2), lam, _unit(1, 0, 0)), (np.arange(20, 38, 2), lam, _unit(np.cos(t), np.sin(t), 0))]
    _, clusters = cluster_poles(_diagram(rows), 40, Criteria())
    assert clusters == []
