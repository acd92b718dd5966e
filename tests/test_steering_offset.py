"""The steering-offset learner (estimator/steering_offset.py) on synthetic series with a known offset."""
import math

import numpy as np
import pytest

from ecu_daemon.estimator.steering_offset import GAIN_FLOOR, SteeringOffset

DT = 0.006
RATIO, L = 15.0, 2.7
OFFSET = math.radians(2.0)


def driver_noise(rng, n, std=math.radians(1.0), corr_s=1.0):
    """A driver's small corrections at the steering wheel: first-order correlated (corr_s)."""
    a = math.exp(-DT / corr_s)
    e = rng.normal(0.0, std * math.sqrt(1 - a * a), n)
    out = np.empty(n)
    v = rng.normal(0.0, std)
    for i in range(n):
        v = a * v + e[i]
        out[i] = v
    return out


def feed(so, readings, r, vx=20.0, ay=0.1, bias_std=1e-4):
    for z in readings:
        so.observe(float(z), r, vx, ay, bias_std)


def test_a_road_curving_one_way_does_not_drag_the_offset():
    # a gentle left-hand sweep (r = 0.008 rad/s at 20 m/s, ay 0.16): the driver holds
    # ratio * L * r / vx = 0.93 deg beyond the offset the whole time; a mean of the raw
    # reading would learn 2.93 deg
    r, vx = 0.008, 20.0
    readings = OFFSET + RATIO * L * r / vx + driver_noise(np.random.default_rng(1), 5000)
    so = SteeringOffset(DT, RATIO, L, None)
    feed(so, readings, r, vx, ay=r * vx)
    assert abs(math.degrees(so.offset - OFFSET)) < 0.3
    assert abs(math.degrees(float(np.mean(readings)) - OFFSET)) > 0.5  # what the raw mean gives


def test_the_kinematic_term_waits_for_a_known_yaw_rate_bias():
    # an unknown bias (std 0.005 rad/s) would move z by ratio * L * 0.005 / 8 = 1.4 deg: raw reading
    so = SteeringOffset(DT, RATIO, L, None)
    so.observe(OFFSET, 0.009, 10.0, 0.09, 0.005)
    assert so.offset == pytest.approx(OFFSET)
    so2 = SteeringOffset(DT, RATIO, L, None)
    so2.observe(OFFSET, 0.009, 10.0, 0.09, 1e-4)
    assert so2.offset == pytest.approx(OFFSET - RATIO * L * 0.009 / 10.0)


def test_the_first_drive_learns_the_whole_offset_in_seconds():
    # 5 s of straight driving from the config's 0: the old fixed gain (0.0005 per step) had
    # learned 1 - exp(-833 * 0.0005) = 34 % of it
    so = SteeringOffset(DT, RATIO, L, None)
    feed(so, OFFSET + np.random.default_rng(2).normal(0.0, math.radians(0.1), 833), 0.0)
    assert so.offset == pytest.approx(OFFSET, abs=math.radians(0.05))


def test_a_restored_offset_is_a_whole_memory_not_one_sample():
    so = SteeringOffset(DT, RATIO, L, OFFSET)
    so.observe(0.0, 0.0, 20.0, 0.0, 1e-4)
    assert so.offset == pytest.approx(OFFSET * (1.0 - GAIN_FLOOR))


@pytest.mark.parametrize("vx, r, ay", [(7.9, 0.0, 0.0), (20.0, 0.011, 0.2), (20.0, 0.0, 0.31)])
def test_outside_a_gentle_path_a_reading_is_no_evidence(vx, r, ay):
    so = SteeringOffset(DT, RATIO, L, OFFSET)
    assert not so.observe(0.3, r, vx, ay, 1e-4)
    assert so.offset == OFFSET


def test_no_evidence_no_std():
    assert math.isnan(SteeringOffset(DT, RATIO, L, None).std())


@pytest.mark.parametrize("seconds", [3.0, 20.0, 60.0])
def test_its_std_is_honest_for_correlated_corrections(seconds):
    # 300 drives with a driver correcting by 1 deg over ~1 s: the learned offsets' errors over
    # their own std have a mean square near 1 (a std from the samples as if independent would
    # give ~80 at 20 s)
    rng = np.random.default_rng(3)
    z = []
    for _ in range(300):
        so = SteeringOffset(DT, RATIO, L, None)
        feed(so, OFFSET + driver_noise(rng, int(seconds / DT)), 0.0)
        z.append((so.offset - OFFSET) / so.std())
    ms = float(np.mean(np.square(z)))
    assert 0.4 < ms < 1.6, ms
