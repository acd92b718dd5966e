"""The lateral accelerometer's white-noise density measured from its own samples (lateral_noise.py)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from ecu_daemon.estimator.lateral_noise import LateralNoise


def _feed(ln: LateralNoise, ay: np.ndarray, ts: float = 0.01, t0: float = 100.0) -> None:
    for i, v in enumerate(ay.tolist()):
        ln.observe(t0 + i * ts, v)


@pytest.mark.parametrize("sigma", [0.5, 1.5])
def test_white_noise_density_is_measured_over_a_turning_signal(sigma):
    """sigma per 100 Hz sample is a density of sigma * sqrt(0.01); the vehicle's own lateral
    acceleration (a 0.5 Hz lane change of +-4 m/s^2) does not pass for noise."""
    rng = np.random.default_rng(3)
    t = np.arange(3000) * 0.01
    ay = 4.0 * np.sin(2 * math.pi * 0.5 * t) + sigma * rng.standard_normal(t.size)
    ln = LateralNoise(0.01)
    _feed(ln, ay)
    assert ln.density == pytest.approx(sigma * 0.1, rel=0.2)


def test_quiet_sensor_keeps_the_configured_floor():
    """A simulated IMU's 0.05 m/s^2 per sample (0.005 m/s^2/sqrt(Hz)) never lowers the floor."""
    rng = np.random.default_rng(4)
    ln = LateralNoise(0.1)
    _feed(ln, 2.0 + 0.05 * rng.standard_normal(2000))
    assert ln.density == 0.1


def test_noise_that_appears_raises_the_density_and_gaps_restart_the_chain():
    """A noisy accelerometer (2 m/s^2 per sample, the suite's noisy fault) raises vy's noise within
    seconds; a logging gap between two samples is not read as a jump of the signal."""
    rng = np.random.default_rng(5)
    ln = LateralNoise(0.1)
    _feed(ln, np.zeros(500))
    assert ln.density == 0.1
    _feed(ln, np.full(500, 5.0), t0=110.0)  # 5 s later, another level: a gap, not noise
    assert ln.density == 0.1
    _feed(ln, 2.0 * rng.standard_normal(1000), t0=120.0)
    assert ln.density > 0.1
    assert ln.density == pytest.approx(0.2, rel=0.35)  # EMA over 10 s still catching up


def test_the_estimator_measures_its_accelerometer_through_its_step_loop():
    """The samples reach the measurement on the estimator's own path (``advance_to``, which applies
    input samples inline): a noisy lateral accelerometer raises vy's process noise above the floor,
    a quiet one leaves it at the configured value."""
    import random

    from ecu_daemon import config
    from ecu_daemon.estimator import Estimator
    from ecu_daemon.estimator.kinematic import VY
    from ecu_daemon.samples import INPUT_INDEX, InputSample

    def drive(sigma):
        est = Estimator(config.load(None))
        floor = est.lat_noise.floor
        rng = random.Random(1)
        for j in range(1500):  # 15 s at 100 Hz, straight at 15 m/s
            t = 1000.0 + 0.01 * j
            for name in INPUT_INDEX:
                v = 15.0 if name.startswith("wheel") else 0.0
                if name == "accel_y":
                    v = rng.gauss(0.0, sigma)
                est.push_input(InputSample(t, INPUT_INDEX[name], v))
            est.advance_to(t - 1e-9)
        return est, floor

    quiet, floor = drive(0.005)
    assert quiet.lat_noise.density == floor
    noisy, floor = drive(3.0)  # 0.3 m/s^2/sqrt(Hz): three times the default floor
    assert noisy.lat_noise.density == pytest.approx(0.3, rel=0.3)
    assert noisy.model.Qd[VY, VY] == pytest.approx(noisy.lat_noise.density ** 2 * noisy.dt)
