"""The wheels' scale checked against the gyro without GNSS (estimator/wheel_yaw_check.py): the rear
axle's right-minus-left speed is ``s r T + c v``; a right mapping (s = 1) is confirmed within a turn
or a lane change, no unit error of WSC_UNITS and no wrong gyro ever is."""
from __future__ import annotations

import math

import numpy as np
import pytest

from ecu_daemon.estimator.input_consistency import WSC_UNITS, WheelScaleCheck
from ecu_daemon.estimator.wheel_yaw_check import WYC_EVERY, WheelYawCheck

DT = 0.006 * WYC_EVERY
TRACK = 1.58


def _drive(r_of_t, v_of_t, seconds, wheel_scale=1.0, gyro_scale=1.0, radius_diff=0.0, track_true=TRACK,
           seed=1, noise=0.02, gyro_noise=0.003, ax=0.0, unsigned=False):
    """(rl, rr, r, ax, vx) samples every DT: rear wheels rolling along the body x axis at
    vx -/+ r T / 2, the right tyre ``radius_diff`` larger (it reads slower), the wheel speeds as
    mapped x ``wheel_scale`` (their magnitudes if ``unsigned``, as most ABS DBCs send them), the
    gyro x ``gyro_scale``; vx the true one (the filter's direction of travel)."""
    rng = np.random.default_rng(seed)
    out = []
    for j in range(int(seconds / DT)):
        t = j * DT
        r, v = r_of_t(t), v_of_t(t)
        rl = (v - r * track_true / 2) + noise * rng.standard_normal()
        rr = (v + r * track_true / 2) / (1.0 + radius_diff) + noise * rng.standard_normal()
        if unsigned:
            rl, rr = abs(rl), abs(rr)
        out.append((wheel_scale * rl, wheel_scale * rr, gyro_scale * r + gyro_noise * rng.standard_normal(), ax, v))
    return out


def _lane_change(t):
    """A straight, then a double lane change at 20 m/s (yaw rate +-0.25 rad/s), then straight."""
    if 4.0 <= t < 8.0:
        return 0.25 * math.sin(2 * math.pi * (t - 4.0) / 2.0)
    return 0.0


def _junction(t):
    """A straight, a 90 deg left turn over 6 s, a straight."""
    return math.pi / 2 / 6.0 * math.sin(math.pi * (t - 5.0) / 6.0) * math.pi / 2 if 5.0 <= t < 11.0 else 0.0


def _run(samples):
    chk = WheelYawCheck(TRACK)
    first = None
    for j, (rl, rr, r, ax, vx) in enumerate(samples):
        if chk.step(rl, rr, r, ax, DT, vx) and first is None:
            first = j * DT
    return chk, first


@pytest.mark.parametrize("r_of_t, v", [(_lane_change, 20.0), (_junction, 8.0)])
def test_a_right_mapping_is_confirmed_within_the_first_turn(r_of_t, v):
    chk, first = _run(_drive(r_of_t, lambda t: v, 15.0, radius_diff=0.01, track_true=TRACK * 1.08))
    assert chk.confirmed and first is not None
    assert first < (8.0 if r_of_t is _lane_change else 11.0)  # before the turn is over
    assert abs(chk.scale - 1.0) < 0.12  # the 8 % track error, not the radius difference
    assert chk.offset == pytest.approx(-0.01, abs=0.003)  # c: the right tyre 1 % larger


@pytest.mark.parametrize("factor", [q for q, _ in WSC_UNITS] + [2.2, 0.28, 1.5, 0.7])
@pytest.mark.parametrize("r_of_t", [_lane_change, _junction])
def test_no_unit_error_is_ever_confirmed(factor, r_of_t):
    chk, first = _run(_drive(r_of_t, lambda t: 15.0, 30.0, wheel_scale=factor, radius_diff=0.01))
    assert not chk.confirmed
    assert abs(chk.scale - factor) < 0.1 * factor  # it sees the factor (GNSS names it)


@pytest.mark.parametrize("gyro", [-1.0, 180 / math.pi, math.pi / 180, 2.0, 0.5])
def test_a_wrong_gyro_confirms_nothing(gyro):
    chk, _ = _run(_drive(_lane_change, lambda t: 20.0, 30.0, gyro_scale=gyro))
    assert not chk.confirmed


def test_a_steady_circle_or_a_straight_confirms_nothing():
    """A flying start in a circle: r T and v in proportion, s and the tyres' radius difference
    cannot be told apart; a straight has no turn at all: both are left to GNSS."""
    chk, _ = _run(_drive(lambda t: 0.3, lambda t: 12.0, 60.0, radius_diff=0.01))
    assert not chk.confirmed
    chk, _ = _run(_drive(lambda t: 0.0, lambda t: 25.0, 60.0))
    assert not chk.confirmed and chk.turn == 0.0


def test_slow_speed_hard_acceleration_and_stale_inputs_are_not_judged():
    chk = WheelYawCheck(TRACK)
    for rl, rr, r, ax, vx in _drive(_lane_change, lambda t: 2.0, 15.0):  # below WYC_MIN_SPEED
        chk.step(rl, rr, r, ax, DT, vx)
    for rl, rr, r, ax, vx in _drive(_lane_change, lambda t: 20.0, 15.0, ax=4.0):  # wheel spin / ABS
        chk.step(rl, rr, r, ax, DT, vx)
    for rl, rr, r, ax, vx in _drive(_lane_change, lambda t: 20.0, 15.0):
        chk.step(math.nan, rr, r, ax, DT, vx)  # a stale or isolated wheel
    assert chk.n == 0 and not chk.confirmed


def test_the_wheel_scale_check_takes_the_gyros_confirmation_but_not_over_a_gnss_verdict():
    wsc = WheelScaleCheck()
    wsc.confirm()
    assert wsc.confirmed
    wsc = WheelScaleCheck()
    for _ in range(2):  # two fixes at 3.6x: GNSS found the mapping wrong
        wsc.observe(36.0, 10.0)
    assert wsc.wrong
    wsc.confirm()
    assert not wsc.confirmed and wsc.wrong



def _reverse_curve(t):
    """Reversing at 4 m/s through a gentle curve: yaw rate up to 0.3 rad/s over 6 s (~60 deg)."""
    return 0.3 * math.sin(math.pi * (t - 2.0) / 6.0) if 2.0 <= t < 8.0 else 0.0


@pytest.mark.parametrize("unsigned", [False, True])
def test_a_right_mapping_is_confirmed_reversing_with_signed_or_unsigned_wheel_speeds(unsigned):
    """Reversing, an unsigned wheel speed (the ABS's magnitude) reads ``v_rr - v_rl = -r T``:
    fitted as it comes, a right gyro read s = -1 there and the wheels were never confirmed
    (rear_axle_yaw.py: signed by the filter's direction of travel, s = 1 either way)."""
    chk, first = _run(_drive(_reverse_curve, lambda t: -4.0, 12.0, radius_diff=0.01, unsigned=unsigned))
    assert chk.confirmed and first is not None and first < 8.0
    assert abs(chk.scale - 1.0) < 0.05
    assert chk.offset == pytest.approx(-0.01, abs=0.005)  # the same tyre, either way


def test_reversing_on_unsigned_wheels_does_not_spoil_the_forward_turn_after_it():
    """The reversing samples stay in the fit: taken as -1x, a right mapping's forward lane change
    after them fitted s between -1 and 1 and confirmed nothing."""
    samples = (_drive(_reverse_curve, lambda t: -4.0, 10.0, unsigned=True)
               + _drive(_lane_change, lambda t: 20.0, 15.0, seed=2, unsigned=True))
    chk, _ = _run(samples)
    assert chk.confirmed and abs(chk.scale - 1.0) < 0.05


@pytest.mark.parametrize("unsigned", [False, True])
def test_a_flipped_gyro_reversing_confirms_nothing(unsigned):
    chk, _ = _run(_drive(_reverse_curve, lambda t: -4.0, 12.0, gyro_scale=-1.0, unsigned=unsigned))
    assert not chk.confirmed and chk.scale == pytest.approx(-1.0, abs=0.1)
