"""Stabilisation diagram and automatic clustering of its stable poles into physical modes.

A pole of order ``n`` is *stable* when the previous order has a pole within
``df`` in frequency, ``dzeta`` in damping ratio (both relative) and with a
complex MAC above ``1 - dmac``. Stable poles are grouped by average-linkage
hierarchical clustering on the distance::

    d_ij = |lambda_i - lambda_j| / max(|lambda_i|, |lambda_j|) + 1 - MAC_ij

(Magalhães et al. 2009, with the complex MAC so that the phase of the shapes
counts), cut at ``cluster_distance``. A weakly excited mode's shape scatters
from order to order by about that much, and the cut can split its poles into
fragments that each persist over too few orders; fragments whose orders are
disjoint (one mode has one pole per order, two modes share orders) and whose
average distance is under ``merge_distance`` are joined again. A cluster is
a physical mode when poles of at least ``min_fraction`` of the orders belong
to it; noise poles do not persist over orders. Shapes stay complex
throughout.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from scipy.cluster.hierarchy import fcluster, linkage
from scipy.spatial.distance import squareform

from twin.modes.analysis import damping_ratio
from twin.modes.shapes import mac, normalise_shapes

if TYPE_CHECKING:
    from twin.extract.algorithms import Fit


#: Absolute tolerance on the damping change between orders (relative tests fail near zeta = 0).
DZETA_FLOOR = 5e-4
#: Poles down to this negative damping ratio are clustered (harmonics have zeta = 0).
HARMONIC_ZETA_TOLERANCE = 0.01
#: Two clusters are one mode when their poles lie closer than this fraction of their decay rate (deep inside
#: each other's half-power band, where no record tells two modes apart) and their shapes agree to
#: :data:`DUPLICATE_MAC`: a heavily damped mode's poles scatter over the orders more than the clustering
#: distance allows and may fall into two clusters (the Pelton unit's 31.5 Hz mode, 7% damped, as two at 31.52
#: and 31.56 Hz with MAC 0.96: one of them then paired with another model mode).
DUPLICATE_DECAY_FRACTION = 0.25
#: The MAC two clusters' shapes need to be one mode by :data:`DUPLICATE_DECAY_FRACTION` (two modes at one
#: frequency with other shapes, as a rotor's x and y modes, stay two).
DUPLICATE_MAC = 0.8


@dataclass(frozen=True)
class Criteria:
    """Stabilisation and clustering settings (see the module docstring).

    ``dzeta`` is 10%, twice the 5% often quoted: a heavily damped mode's
    damping estimate moves by more than 5% from one order to the next (the
    hydro unit's 19.1 Hz mode, 8.6% damped: 0.083 to 0.094), and its
    stable orders then fell short of ``min_fraction`` on some records.
    Noise poles that the looser test lets in are dropped after the jackknife
    when their samples scatter beyond their own bandwidth (:func:`twin.extract.result.pole_determined`).

    ``merge_distance`` joins fragments of one mode (disjoint orders) that the
    cut at ``cluster_distance`` separated: the hydro unit's 16.2 Hz mode
    (2.4% damped, weakly excited) has shapes 1 - MAC = 0.025 apart between
    orders, and the cut split its 26 orders into fragments of 7, 10 and 9,
    0.033-0.038 apart. At 0.06 the KOMA shear frame's spurious 1.62 Hz pole
    (fragments 0.055-0.059 apart, over orders 64-100 only) became a mode;
    0.045 lies between the two.
    """

    df: float = 0.01
    dzeta: float = 0.1
    dmac: float = 0.02
    zeta_max: float = 0.25
    cluster_distance: float = 0.03
    merge_distance: float = 0.045
    min_fraction: float = 0.25


@dataclass(frozen=True)
class Diagram:
    """All poles of a stabilisation diagram (``Im lambda > 0``), order by order.

    ``status``: 0 new pole, 1 stable in frequency only, 2 stable in frequency and
    damping, 3 fully stable (frequency, damping and shape); ``cluster`` is the
    mode a pole was assigned to (``-1`` for none).
    """

    order: np.ndarray
    pole: np.ndarray
    shape: np.ndarray  # (n_poles, n_channels), normalised
    status: np.ndarray
    cluster: np.ndarray

    @property
    def frequency_hz(self) -> np.ndarray:
        return self.pole.imag / (2 * np.pi)

    @property
    def damping_ratio(self) -> np.ndarray:
        return damping_ratio(self.pole)


def pole_distance(p1: np.ndarray, s1: np.ndarray, p2: np.ndarray, s2: np.ndarray) -> np.ndarray:
    """Clustering distance between two sets of poles and shapes, shape ``(len(p1), len(p2))``."""
    dp = np.abs(p1[:, None] - p2[None, :]) / np.maximum(np.abs(p1)[:, None], np.abs(p2)[None, :])
    return dp + 1.0 - mac(s1, s2)


def diagram(real: Fit, orders: np.ndarray, fmin_hz: float, fmax_hz: float, crit: Criteria) -> Diagram:
    """Poles of every order with their stability status (no clustering yet)."""
    rows_order, rows_pole, rows_shape, rows_status = [], [], [], []
    prev_p = prev_s = None
    for n in orders:
        lam, phi = real.modes(int(n))
        f = lam.imag / (2 * np.pi)
        keep = (f >= fmin_hz) & (f <= fmax_hz)
        lam, phi = lam[keep], normalise_shapes(phi[:, keep].T)
        status = np.zeros(len(lam), dtype=np.int8)
        if prev_p is not None and len(prev_p) and len(lam):
            rel = np.abs(lam[:, None] - prev_p[None, :]) / np.abs(lam)[:, None]
            j = np.argmin(rel, axis=1)
            q, qs = prev_p[j], prev_s[j]
            ok_f = np.abs(lam.imag - q.imag) <= crit.df * lam.imag
            z, zq = damping_ratio(lam), damping_ratio(q)
            ok_z = np.abs(z - zq) <= np.maximum(crit.dzeta * np.abs(z), DZETA_FLOOR)
            ok_m = np.abs(np.einsum("ij,ij->i", qs.conj(), phi)) ** 2 >= 1.0 - crit.dmac  # unit-norm shapes
            status = np.where(ok_f, 1, 0) + np.where(ok_f & ok_z, 1, 0) + np.where(ok_f & ok_z & ok_m, 1, 0)
        rows_order.append(np.full(len(lam), n))
        rows_pole.append(lam)
        rows_shape.append(phi)
        rows_status.append(status)
        prev_p, prev_s = lam, phi
    n_ch = real.n_channels
    shape = np.concatenate(rows_shape) if rows_shape else np.zeros((0, n_ch), complex)
    pole = np.concatenate(rows_pole) if rows_pole else np.zeros(0, complex)
    return Diagram(
        order=np.concatenate(rows_order).astype(int),
        pole=pole,
        shape=shape.reshape(-1, n_ch),
        status=np.concatenate(rows_status).astype(np.int8),
        cluster=np.full(len(pole), -1),
    )


@dataclass(frozen=True)
class Cluster:
    """One physical mode found in the diagram: its member poles and the representative one."""

    members: np.ndarray  # indices into the diagram, one per order
    representative: int  # index of the medoid member


def cluster_poles(d: Diagram, n_orders: int, crit: Criteria) -> tuple[Diagram, list[Cluster]]:
    """Group the fully stable, physically damped poles into modes; returns the diagram with ``cluster`` set.

    Modes are sorted by frequency. Each keeps one pole per order (the closest
    to the cluster's median pole) and its medoid as representative.
    """
    z = d.damping_ratio
    # slightly negative damping is let in: a harmonic's pole sits at zeta = 0 +- estimation error
    cand = np.flatnonzero((d.status == 3) & (z > -HARMONIC_ZETA_TOLERANCE) & (z < crit.zeta_max))
    labels = np.full(len(d.pole), -1)
    if len(cand) < 2:
        return dataclasses.replace(d, cluster=labels), []
    dist = pole_distance(d.pole[cand], d.shape[cand], d.pole[cand], d.shape[cand])
    dist = 0.5 * (dist + dist.T)
    np.fill_diagonal(dist, 0.0)
    tree = linkage(squareform(np.clip(dist, 0, None), checks=False), method="average")
    groups = fcluster(tree, t=crit.cluster_distance, criterion="distance")
    clusters = []
    for g in _join_fragments(groups, d.order[cand], dist, crit.merge_distance):
        idx = cand[g]
        if len(np.unique(d.order[idx])) < crit.min_fraction * n_orders:
            continue
        median = np.median(d.pole[idx].real) + 1j * np.median(d.pole[idx].imag)
        members = []
        for n in np.unique(d.order[idx]):
            at_n = idx[d.order[idx] == n]
            members.append(at_n[np.argmin(np.abs(d.pole[at_n] - median))])
        members = np.array(members)
        dm = pole_distance(d.pole[members], d.shape[members], d.pole[members], d.shape[members])
        rep = int(members[np.argmin(dm.sum(axis=1))])
        clusters.append(Cluster(members=members, representative=rep))
    clusters = _merge_duplicates(d, clusters, crit)
    clusters.sort(key=lambda c: d.pole[c.representative].imag)
    for k, c in enumerate(clusters):
        labels[c.members] = k
    return dataclasses.replace(d, cluster=labels), clusters


def _join_fragments(groups: np.ndarray, order: np.ndarray, dist: np.ndarray, merge_distance: float) -> list[np.ndarray]:
    """Index sets of the groups after joining fragments of one mode.

    Two groups are joined, closest first (average distance of their poles,
    as in the linkage), while that distance is under ``merge_distance`` and
    no order has a pole in both: a mode appears once per order, so fragments
    of it are disjoint in order, while two distinct modes close in
    frequency and shape appear side by side at the same orders.

    Examples
    --------
    >>> d = np.array([[0, .04, .5], [.04, 0, .5], [.5, .5, 0]])
    >>> [g.tolist() for g in _join_fragments(np.array([1, 2, 3]), np.array([2, 4, 4]), d, 0.06)]
    [[0, 1], [2]]
    >>> [g.tolist() for g in _join_fragments(np.array([1, 2, 3]), np.array([2, 2, 4]), d, 0.06)]
    [[0], [1], [2]]
    """
    labels = np.unique(groups)
    member = groups[None, :] == labels[:, None]  # (group, pole)
    sums = member @ dist @ member.T.astype(float)  # summed distances between groups
    size = member.sum(axis=1).astype(float)
    _, order_index = np.unique(order, return_inverse=True)
    present = np.zeros((len(labels), order_index.max() + 1), dtype=bool)
    for g in range(len(labels)):
        present[g, order_index[member[g]]] = True
    alive = np.ones(len(labels), dtype=bool)
    while True:
        mean = sums / np.outer(size, size)
        blocked = (present.astype(int) @ present.T.astype(int) > 0) | ~np.outer(alive, alive)
        mean[blocked] = np.inf
        a, b = np.unravel_index(np.argmin(mean), mean.shape)
        if not mean[a, b] < merge_distance:
            break
        member[a] |= member[b]
        present[a] |= present[b]
        sums[a] += sums[b]
        sums[:, a] += sums[:, b]
        size[a] += size[b]
        alive[b] = False
    return [np.flatnonzero(member[g]) for g in np.flatnonzero(alive)]


def _merge_duplicates(d: Diagram, clusters: list[Cluster], crit: Criteria) -> list[Cluster]:
    """Keep the larger of two clusters that describe the same mode: within the clustering distance, or with
    poles within :data:`DUPLICATE_DECAY_FRACTION` of their decay rate and shapes alike (:data:`DUPLICATE_MAC`)."""
    clusters = sorted(clusters, key=lambda c: -len(c.members))
    kept: list[Cluster] = []
    for c in clusters:
        p, s = d.pole[[c.representative]], d.shape[[c.representative]]
        if any(_same_mode(p, s, d.pole[[k.representative]], d.shape[[k.representative]], crit) for k in kept):
            continue
        kept.append(c)
    return kept


def _same_mode(p1: np.ndarray, s1: np.ndarray, p2: np.ndarray, s2: np.ndarray, crit: Criteria) -> bool:
    """Whether two representative poles ``(1,)`` with unit shapes ``(1, channels)`` are one mode.

    Examples
    --------
    >>> s = np.array([[1.0, 0.2j]])
    >>> p = np.array([-14.2 + 198.0j])
    >>> _same_mode(p, s, p + 0.3j, s * 0.98 + [[0.0, 0.2]], Criteria())  # 7% damped: 0.3 rad/s is nothing
    True
    >>> _same_mode(p / 20, s, p / 20 + 0.3j, s * 0.98 + [[0.0, 0.2]], Criteria())  # the same step, 20 times slower
    False
    >>> _same_mode(p, s, p + 0.3j, np.array([[0.2j, 1.0]]), Criteria())  # another shape at the same pole
    False
    """
    if pole_distance(p1, s1, p2, s2)[0, 0] < crit.cluster_distance:
        return True
    decay = min(-p1[0].real, -p2[0].real)
    return bool(abs(p1[0] - p2[0]) < DUPLICATE_DECAY_FRACTION * decay and mac(s1, s2)[0, 0] >= DUPLICATE_MAC)
