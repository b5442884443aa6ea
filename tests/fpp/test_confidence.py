"""The per-pixel confidence of a fringe order (dptpu.fpp.confidence)."""
import numpy as np
import pytest

from dptpu.fpp.confidence import confident, network_confidence


def test_network_confidence_is_the_larger_of_its_own_margin_and_its_prior_agreement():
    continuous = np.array([[3.0, 3.25, 3.4, 5.0, 7.6, 2.0]])
    order = np.array([[3, 3, 3, 3, 3, 2]])
    prior = np.array([[3, 9, 9, 4, 9, 2]])
    valid = np.array([[True, True, True, True, True, False]])
    expected = [[1.0, 0.5, 0.2, 0.5, 0.0, 0.0]]  # own margin 1 - 2|c - k|; prior 1, 0.5 one order off, 0 further
    assert network_confidence(continuous, order, prior, valid) == pytest.approx(np.array(expected), abs=1e-6)


def test_confident_drops_and_counts():
    conf = np.array([0.0, 0.1, 0.2, 0.9])
    valid = np.array([True, True, True, False])
    kept, dropped = confident(conf, valid, 0.2)
    assert kept.tolist() == [False, False, True, False] and dropped == 2
    kept, dropped = confident(conf, valid, 0.0)
    assert kept.tolist() == valid.tolist() and dropped == 0
    with pytest.raises(ValueError, match="min_confidence"):
        confident(conf, valid, 1.5)
