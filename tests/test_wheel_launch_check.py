"""The wheels' scale checked against the integrated accelerometer on a launch from rest
(estimator/wheel_launch_check.py): a right mapping is confirmed within the first metre per second
of the launch, no unit error of WSC_UNITS and no wrong accelerometer ever is."""
from __future__ import annotations

import math

import numpy as np
import pytest

from ecu_daemon.estimator.input_consistency import WSC_UNITS
from ecu_daemon.estimator.wheel_launch_check import WheelLaunchCheck

DT = 0.006


def _launch(accel=2.0, wheel_scale=1.0, ax_scale=1.0, ax_error=0.0, dead_zone=0.15, rest=1.0, seconds=8.0,
            bax_std=0.01, v0=0.0, seed=3):
    """Run a check over a launch: at rest for ``rest`` s (from ``v0``), then ``accel`` up to 20 m/s;
    the wheels as mapped (x ``wheel_scale``, 0 below ``dead_zone``, held at 100 Hz, 0.02 m/s noise),
    ax x ``ax_scale`` plus ``ax_error`` (a pitch or grade the bias does not hold). Returns the
    check and the true speed at its confirmation (None: never)."""
    rng = np.random.default_rng(seed)
    chk = WheelLaunchCheck()
    held, at = 0.0, -1.0
    for k in range(int(seconds / DT)):
        t = k * DT
        v = min(v0 + accel * max(t - rest, 0.0), 20.0)
        a = accel if rest < t and v < 20.0 else 0.0
        if t - at >= 0.01:  # a new CAN sample
            at = t
            held = v + 0.02 * rng.standard_normal()
            held = 0.0 if held < dead_zone else wheel_scale * held
        if chk.step(held, ax_scale * a + ax_error + 0.05 * rng.standard_normal(), bax_std, DT):
            return chk, v
    return chk, None


@pytest.mark.parametrize("dead_zone", [0.15, 0.5, 0.8])
@pytest.mark.parametrize("accel, ax_error", [(2.0, 0.0), (1.0, 0.1), (3.0, -0.2), (2.0, 0.3)])
def test_a_right_mapping_is_confirmed_early_in_the_launch(dead_zone, accel, ax_error):
    """Whatever the sensor's dead zone, with a pitch or grade error up to 0.3 m/s^2 (15 % of a
    2 m/s^2 launch): confirmed by 2 m/s, where the unchecked std (4/3 v) is still within ~2.7."""
    chk, v = _launch(accel=accel, ax_error=ax_error, dead_zone=dead_zone)
    assert chk.confirmed and v < 2.0, (chk.scale, v)


@pytest.mark.parametrize("factor", [q for q, _ in WSC_UNITS] + [2.2, 0.28, 1.5, 0.7])
@pytest.mark.parametrize("accel", [1.0, 2.0, 4.0])
def test_no_unit_error_is_ever_confirmed(factor, accel):
    chk, v = _launch(accel=accel, wheel_scale=factor, ax_error=0.2)
    assert not chk.confirmed, (factor, accel, chk.scale)


@pytest.mark.parametrize("ax_scale", [-1.0, 1 / 9.81, 9.81])
def test_a_wrong_accelerometer_confirms_nothing(ax_scale):
    chk, _ = _launch(ax_scale=ax_scale)
    assert not chk.confirmed


def test_what_cannot_be_judged_is_left_to_gnss():
    # a flying start: the wheels never read a standstill
    chk, _ = _launch(v0=10.0)
    assert not chk.confirmed and math.isnan(chk.scale)
    # a bias nobody learned (no standstill before): its integral is not precise enough
    chk, _ = _launch(bax_std=0.3)
    assert not chk.confirmed and math.isnan(chk.scale)
    # a crawl: 1 m/s over more than WLC_MAX_S
    chk, _ = _launch(accel=0.15, seconds=20.0)
    assert not chk.confirmed and math.isnan(chk.scale)
    # stale wheels throughout
    chk = WheelLaunchCheck()
    for k in range(2000):
        chk.step(math.nan, 2.0, 0.01, DT)
    assert not chk.confirmed and math.isnan(chk.scale)
