"""Tests of twin.extract.orders: which model orders a mode is averaged over."""

from types import SimpleNamespace

import numpy as np

from twin.extract.orders import ORDERS_PER_MODE, orders_used


def test_orders_used_leave_out_unconverged_low_orders():
    """Poles far (robust z > 3) from the cluster's median are not averaged, even at the lowest orders."""
    orders = np.arange(10, 62, 2)
    rng = np.random.default_rng(0)
    pole = -0.15 + 2j * np.pi * (1.0 + 1e-4 * rng.standard_normal(len(orders)))
    pole[[0, 3]] += 2j * np.pi * 0.008  # orders 10 and 16: 0.8% high, not yet settled
    diag = SimpleNamespace(pole=pole, order=orders)
    use = orders_used(diag, SimpleNamespace(members=np.arange(len(orders))))
    assert len(use) == ORDERS_PER_MODE and 0 not in use and 3 not in use
    assert list(diag.order[use]) == [12, 14, 18, 20, 22, 24, 26, 28]  # the lowest settled ones
    every = orders_used(diag, SimpleNamespace(members=np.arange(len(orders))), None)  # all settled orders
    assert len(every) == len(orders) - 2 and 0 not in every and 3 not in every
    # a cluster whose poles all agree keeps its lowest orders
    diag = SimpleNamespace(pole=np.full(len(orders), -0.15 + 2j * np.pi), order=orders)
    assert list(orders_used(diag, SimpleNamespace(members=np.arange(len(orders))))) == list(range(ORDERS_PER_MODE))
