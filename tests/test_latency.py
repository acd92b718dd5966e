"""The online GNSS latency identification (estimator/latency.py) on synthetic series whose latency
is known: it finds it, and it stays put when the series carries no timing information."""
from __future__ import annotations

import math

import numpy as np
import pytest

from ecu_daemon.estimator.history import AUX_WHEEL, StepHistory
from ecu_daemon.estimator.latency import PRIOR_STD_S, LatencyEstimator

DT = 0.006
FIX_EVERY = 33  # steps: GNSS at ~5 Hz


def run(speed, delay_s, prior_s=0.2, seconds=120.0, gnss_noise=0.0, wheel_scale=1.0, seed=1):
    """Feed a speed profile: wheels see speed(t) every step, GNSS reports speed(t - delay) at t.

    ``wheel_scale``: the wheels read scale * the true speed (a radius error must not bias timing).
    """
    rng = np.random.default_rng(seed)
    est = LatencyEstimator(DT, prior_s, max_s=0.8)
    hist = StepHistory(est.max_steps + 20)
    hist.reset(0)
    d_steps = round(delay_s / DT)
    for k in range(int(seconds / DT)):
        hist.aux[hist.slot(k), AUX_WHEEL] = wheel_scale * speed(k * DT)
        hist.last = k
        if k % FIX_EVERY == 0 and k > d_steps:
            # received just before step k + 1, valid at step k + 1 - d_steps (delay of d_steps)
            est.observe(k + 1, speed((k + 1 - d_steps) * DT) + gnss_noise * rng.normal(), hist)
    return est


def accelerating(t):
    """Speed changes of +-3 m/s over a few seconds, as in town: timing shows in the slopes."""
    return 15.0 + 3.0 * math.sin(2 * math.pi * t / 7.0) + 1.5 * math.sin(2 * math.pi * t / 2.9)


@pytest.mark.parametrize("delay_s", [0.12, 0.3, 0.48])
def test_finds_a_known_latency(delay_s):
    est = run(accelerating, delay_s, gnss_noise=0.03)
    assert est.delay_s == pytest.approx(delay_s, abs=0.012)  # two 6 ms steps
    assert est.std_s < 0.03


def test_a_wheel_radius_error_does_not_bias_the_timing():
    est = run(accelerating, 0.3, wheel_scale=1.04, gnss_noise=0.03)
    assert est.delay_s == pytest.approx(0.3, abs=0.012)


def test_steady_speed_carries_no_timing_information_and_the_prior_stands():
    est = run(lambda t: 22.0, 0.4, prior_s=0.2, gnss_noise=0.03)
    assert est.updates > 100  # the fixes were seen ...
    assert est.delay_s == 0.2  # ... and changed nothing
    assert est.std_s == PRIOR_STD_S


def test_below_walking_pace_nothing_is_learned():
    est = run(lambda t: 1.0 + 0.5 * math.sin(t), 0.4)
    assert est.updates == 0 and est.delay_s == 0.2


def test_disabled_keeps_the_configured_latency():
    est = LatencyEstimator(DT, 0.25, 0.8, enabled=False)
    hist = StepHistory(est.max_steps + 20)
    hist.reset(0)
    hist.last = est.max_steps + 10
    hist.aux[:, AUX_WHEEL] = 10.0
    est.observe(hist.last + 1, 12.0, hist)
    assert est.delay_s == 0.25 and est.updates == 0
