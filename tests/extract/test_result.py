"""twin.extract.result: which modes the samples determine."""

import numpy as np

from twin.extract.result import pole_determined


def test_a_mode_without_counterparts_in_many_samples_is_judged_on_its_full_spread():
    """Orders without a counterpart keep the full-record pole, shrinking the spread by the fraction kept."""
    pole = np.array([-0.5 + 100j])
    d = np.random.default_rng(2).standard_normal((1, 16)) + 1j * np.random.default_rng(3).standard_normal((1, 16))
    d *= 0.6 * 0.5 * np.sqrt(16) / np.sqrt(np.var(d.real) * 16 / 15 + np.var(d.imag) * 16 / 15)  # se 0.6 of |Re|
    assert pole_determined(pole, pole[:, None] + d)
    # with half the (sample, order) pairs missing the spread stands for half of the real one: 1.2 bandwidths
    assert not pole_determined(pole, pole[:, None] + d, missing=np.array([0.5]))


def test_a_pole_whose_damping_the_blocks_cannot_tell_is_judged_on_its_frequency():
    rng = np.random.default_rng(1)
    p = np.array([-0.1 + 50j, -0.1 + 80j])
    # the first: damping scattering by 3 bandwidths, frequency pinned (a light mode in short blocks);
    # the second: the frequency wandering too (a noise pole)
    samples = (
        p[:, None]
        + np.array([[1.0], [1.0]]) * rng.standard_normal((2, 15))
        + 1j * np.array([[0.01], [1.0]]) * rng.standard_normal((2, 15))
    )
    assert pole_determined(p, samples).tolist() == [False, False]
    assert pole_determined(p, samples, damping_judged=np.array([False, False])).tolist() == [True, False]
