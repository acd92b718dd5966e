"""The GNSS velocity noise learned from along-track innovations (estimator/gnss_noise.py)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from ecu_daemon.estimator.gnss_noise import FLOOR_MPS, MIN_SAMPLES, GnssNoiseLearner


def _fed(innovations) -> GnssNoiseLearner:
    n = GnssNoiseLearner()
    for e in innovations:
        n.observe(float(e))
    return n


def test_the_receivers_figure_until_enough_fixes():
    n = _fed([0.0] * (MIN_SAMPLES - 1))
    assert n.sigma(0.3) == 0.3


def test_learns_the_real_scatter_below_a_pessimistic_receiver():
    # the Revs capture: 0.05 m/s of noise, sAcc 0.3 m/s
    n = _fed(np.random.default_rng(1).normal(0.0, 0.05, 500))
    assert 0.045 < n.sigma(0.3) < 0.08  # near the scatter, erring high (a rise counts more than a fall)


def test_never_more_trusting_than_the_receiver():
    n = _fed(np.random.default_rng(2).normal(0.0, 1.0, 200))
    assert n.sigma(0.3) == 0.3


def test_a_rising_scatter_is_believed_within_a_few_fixes():
    rng = np.random.default_rng(3)
    n = _fed(rng.normal(0.0, 0.05, 300))
    for e in rng.normal(0.0, 0.5, 10):  # multipath: ten times the scatter
        n.observe(float(e))
    assert n.sigma(0.3) > 0.2


def test_floor_and_non_finite_innovations():
    n = _fed([0.0] * 50 + [math.nan, math.inf])
    assert n.samples == 50
    assert n.sigma(0.3) == pytest.approx(FLOOR_MPS)
