"""The model orders a mode of the stabilisation diagram is averaged over.

SSI gives a mode once per model order at which it is stable. Its estimate
(and each jackknife sample of it) is the average of its poles over a few of
those orders: the lowest ones at which the pole has settled.

Low orders are the parsimonious realisations. At orders well above the
number of modes, the extra (noise) poles re-arrange from one reduced record
to the next and jostle the physical pole more than the data's own
variability does, so the jackknife spread comes out too wide (with the
delete-one jackknife on a one-mode record: 1.0 times the spread of
estimates over independent records at the true order, 1.4 times at four
times it, 1.7 at eight).

The lowest orders may not have converged yet, though: a pole that passes the
stability criteria between neighbouring orders can still sit apart from
where the mode settles at higher orders (the 1.09 Hz mode of the hydro unit:
orders 14-28 up to 0.9% high). Poles farther from the cluster's median pole
than :data:`OUTLIER_MADS` robust standard deviations (1.4826 times the
median distance) are left out before the lowest orders are taken.
"""

from __future__ import annotations

import numpy as np

from twin.defaults import ORDERS_PER_MODE

#: A cluster's poles farther than this many robust std from its median pole are not used (unconverged orders).
OUTLIER_MADS = 3.0


def orders_used(diag, cluster, n_orders: int | None = ORDERS_PER_MODE) -> np.ndarray:
    """Indices into ``diag`` of the ``n_orders`` (None: all) lowest model orders at which a cluster's mode
    is stable and settled.

    Parameters
    ----------
    diag
        The stabilisation diagram's poles: ``pole`` [1/s] and ``order``, per diagram pole.
    cluster
        A mode of the diagram: ``members``, the indices of its poles.
    n_orders : int or None
        How many orders (default :data:`twin.defaults.ORDERS_PER_MODE`); None: every settled one.

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> orders = np.arange(10, 40, 2)
    >>> pole = -2.0 + 1j * (60.0 + 0.01 * np.sin(np.arange(len(orders))))
    >>> pole[1] += 3j  # order 12: apart from where the mode settles
    >>> diag = SimpleNamespace(pole=pole, order=orders)
    >>> orders[orders_used(diag, SimpleNamespace(members=np.arange(len(orders))), 4)].tolist()
    [10, 14, 16, 18]
    """
    m = np.asarray(cluster.members)
    p = diag.pole[m]
    dist = np.abs(p - (np.median(p.real) + 1j * np.median(p.imag)))
    scale = 1.4826 * np.median(dist)
    if scale > 0:
        m = m[dist <= OUTLIER_MADS * scale]
    return m[np.argsort(diag.order[m], kind="stable")][:n_orders]


def mode_members(found, n_orders: int | None) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Each mode of an SSI pass (:class:`twin.extract.passes.SSIPass`) at the orders :func:`orders_used`
    chooses: (orders, poles [1/s], shapes)."""
    diag = found.diag
    used = (orders_used(diag, c, n_orders) for c in found.modes)
    return [(diag.order[u], diag.pole[u], diag.shape[u]) for u in used]
