"""The extraction's options: checked once when made, and a cache key that is their value."""

import pytest

from twin.errors import SignalError
from twin.extract import Criteria, ExtractOptions
from twin.extract.options import jackknife_plan


def test_bad_options_fail_when_made_naming_the_option():
    for fields, message in [
        ({"max_order": 1}, "max_order must be at least 2"),
        ({"samples": 1}, "samples must be at least 2"),
        ({"first_lag": 0}, "first_lag must be a whole number"),
        ({"order_spread": "some"}, "order_spread must be one of shapes, all, none"),
        ({"orders_per_mode": 0}, "orders_per_mode must be at least 1"),
        ({"shape_block_rows": "longer"}, "shape_block_rows must be 'auto' or at least 0"),
        ({"channels": "A_x"}, "channels must be a list of channel names"),
        ({"samples": 10, "shape_samples": 15}, "shape_samples must be a whole multiple of samples = 10"),
        ({"samples": 10, "blocks": 10, "delete_blocks": 10}, "delete_blocks:"),
    ]:
        with pytest.raises(SignalError, match=message):
            ExtractOptions(**fields)
    with pytest.raises(SignalError, match="the extraction has no option colour"):
        ExtractOptions.of({"samples": 10}, colour="red")


def test_the_key_is_the_options_that_differ_from_the_defaults():
    assert ExtractOptions().key() == "{}"
    assert ExtractOptions.of({"fmax_hz": 40.0}).key() == '{"fmax_hz": 40.0}'
    assert ExtractOptions(samples=10, fmax_hz=40.0).key() == ExtractOptions(fmax_hz=40.0, samples=10).key()
    assert ExtractOptions(fmax_hz=40.0).key() != ExtractOptions(fmax_hz=41.0).key()
    # a criteria mapping (a modes file's settings) is read as the Criteria it stands for
    strict = ExtractOptions.of(criteria={**ExtractOptions().settings()["criteria"], "dzeta": 0.05})
    assert isinstance(strict.criteria, Criteria) and '"dzeta": 0.05' in strict.key()
    # the same value whichever way it is given; options are values (equal and hashable)
    assert ExtractOptions.of(ExtractOptions(samples=10), fmax_hz=8.0) == ExtractOptions(samples=10, fmax_hz=8.0)
    assert len({ExtractOptions(channels=["A_x", "A_y"]), ExtractOptions(channels=("A_x", "A_y"))}) == 1


def test_the_jackknife_plan_of_given_blocks():
    plan = ExtractOptions(samples=10, shape_samples=40)
    assert jackknife_plan(plan.n_blocks, plan.n_samples, plan) == (1, 4)
    assert ExtractOptions(order_spread=False).order_spread == "none"
