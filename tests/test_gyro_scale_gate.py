"""A gyro in deg/s mapped as rad/s (issue 7, wrong configurations): estimator/gyro_scale_gate.py
holds the gyro's scale against the rear wheels' (v_rr - v_rl) / track and ay / vx, promises no
sideslip on a gyro that has read a turn before a witness confirmed it, no velocity or heading on a
reading no car makes at its speed, and names ``[inputs.yaw_rate]`` once both witnesses contradict it.

Before the gate (integ27, 1a549c8), ``[inputs.yaw_rate] scale = 57.3`` on dlc_dry (the signal is
in rad/s): 126 of 129 valid sideslip rows beyond 3 sigma, up to 11.3 deg off, at the launch
(6.2-7.5 s), where the gyro's bias alone read 0.5 rad/s (tools/probe_wrong_config.py)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from ecu_daemon.estimator.gyro_scale_gate import GSC_QUIET, GSC_SLOW_SIGMA, GSC_UNCONFIRMED_SCALE_SD, GyroScaleGate
from ecu_daemon.sim.scenario import SCENARIOS, Scenario

from config_replay import replay_edited, simulated_drive

TRACK = 1.6
SAID = "[inputs.yaw_rate] scale"


@pytest.fixture(scope="module")
def dlc_drive(tmp_path_factory):
    return simulated_drive(tmp_path_factory, "gyro_dlc", SCENARIOS["dlc_dry"])


def _deg_as_rad(c):
    c["inputs"]["yaw_rate"].update(scale=180.0 / math.pi, min=-200.0, max=200.0)


def _bad_sideslip(e, t):
    beta = np.interp(e["t"], t["t"], t["sideslip_rad"])
    v = e["sideslip_valid"].astype(bool)
    return v & (np.abs(e["sideslip_rad"] - beta) > 3.0 * e["sideslip_std_rad"])


def test_a_gyro_read_57x_too_large_promises_no_sideslip(dlc_drive):
    e, t = replay_edited(dlc_drive, _deg_as_rad, "gyro_deg_as_rad")
    assert _bad_sideslip(e, t).sum() == 0
    vx = np.interp(e["t"], t["t"], t["vx_mps"])
    v = e["velocity_valid"].astype(bool)
    assert not (v & (np.abs(e["vx_mps"] - vx) > 3.0 * e["vx_std_mps"])).any()


def test_the_right_gyro_is_confirmed_in_the_lane_change_and_says_nothing(dlc_drive):
    lines: list[str] = []
    e, t = replay_edited(dlc_drive, lambda c: None, "right", log_level="warning", stderr=lines)
    assert not any(SAID in line for line in lines)
    assert _bad_sideslip(e, t).sum() == 0
    v = e["sideslip_valid"].astype(bool)
    # promised on the straight before the lane change and after it (the gate only withholds
    # between the turn-in and the witnesses' confirmation)
    assert v[(e["t"] - e["t"][0] > 8.0) & (e["t"] - e["t"][0] < 19.0)].mean() > 0.9
    assert v[e["t"] - e["t"][0] > 30.0].mean() > 0.9


# ---- synthetic series: the rear wheels and ay for a yaw rate r at speed vx, the gyro reading s r

def _feed(gate, s, r_of, vx=20.0, n=400, wheels_sign=1.0, bias=0.0, bank_ay=0.0):
    said = False
    for i in range(n):
        r = r_of(i * 0.06)
        rl = vx - 0.5 * r * TRACK * wheels_sign
        rr = vx + 0.5 * r * TRACK * wheels_sign
        g = s * r + bias
        said |= gate.step(rl, rr, g, r * vx + bank_ay, vx, 0.0, g)
    return said


def lane_change(t):
    return 0.15 * math.sin(2.0 * math.pi * t / 4.0)


def test_a_right_gyro_in_a_lane_change_is_confirmed():
    gate = GyroScaleGate(TRACK)
    assert not _feed(gate, 1.0, lane_change, bank_ay=0.5)
    assert gate.confirmed and gate.sideslip_ok() and gate.motion_ok()


@pytest.mark.parametrize("s", [180.0 / math.pi, math.pi / 180.0, -1.0])
def test_a_unit_error_or_a_flipped_sign_is_contradicted_and_named(s):
    gate = GyroScaleGate(TRACK)
    assert _feed(gate, s, lane_change)
    assert gate.contradicted and not gate.confirmed
    assert not gate.sideslip_ok() and not gate.motion_ok()
    assert SAID in gate.message()


def test_wheels_swapped_left_right_do_not_blame_a_right_gyro():
    """The wheels read -1x; ay confirms (either witness confirms, both must contradict)."""
    gate = GyroScaleGate(TRACK)
    assert not _feed(gate, 1.0, lane_change, wheels_sign=-1.0)
    assert gate.confirmed and not gate.contradicted


def test_a_straight_keeps_the_promise_and_a_turn_before_confirmation_withholds_it():
    gate = GyroScaleGate(TRACK)
    _feed(gate, 1.0, lambda t: 0.3 * GSC_QUIET, n=100)
    assert gate.sideslip_ok() and not gate.confirmed and not gate.exercised
    gate.step(20.0, 20.0, 2.0 * GSC_QUIET, 0.0, 20.0, 0.0, 2.0 * GSC_QUIET)  # a turn-in, unconfirmed
    assert gate.exercised and not gate.sideslip_ok()


def test_a_yaw_rate_no_car_makes_is_not_promised_on():
    """A 57x gyro's 0.009 rad/s bias at a launch (0.3 m/s): 0.5 rad/s is a 0.6 m circle."""
    gate = GyroScaleGate(TRACK)
    gate.step(0.3, 0.3, 0.5, 0.0, 0.3, 1.0, 0.5)
    assert gate.implausible and not gate.motion_ok()
    gate.step(0.3, 0.3, 0.05, 0.0, 0.3, 1.0, 0.05)  # 0.05 rad/s at 0.3 m/s: a 6 m circle
    assert not gate.implausible and gate.motion_ok()
    gate.step(30.0, 30.0, 0.3, 9.0, 30.0, 0.0, 0.3)  # 9 m/s^2 at 30 m/s
    assert not gate.implausible
    gate.step(30.0, 30.0, 11.0, 6.0, 30.0, 0.0, 11.0)  # a 57x gyro in a 150 m corner
    assert gate.implausible


# ---- reversing (issue 7): the rear wheels' witness in both directions, no heading on an unchecked gyro

@pytest.mark.parametrize("unsigned", [False, True], ids=["signed_wheels", "unsigned_wheels"])
@pytest.mark.parametrize("s", [-1.0, math.pi / 180.0], ids=["flipped", "rad_read_as_deg"])
def test_a_wrong_gyro_reversing_is_contradicted_by_both_witnesses(s, unsigned):
    """Reversing at 4 m/s: (|v_rr| - |v_rl|) sign(vx) is r T whether the wheels are signed or not;
    before, the wheels' witness was off at vx < 0 and ay alone can never contradict."""
    gate = GyroScaleGate(TRACK)
    said = False
    for i in range(400):
        r, vx = lane_change(i * 0.06), -4.0
        rl, rr = vx - 0.5 * r * TRACK, vx + 0.5 * r * TRACK
        if unsigned:
            rl, rr = abs(rl), abs(rr)
        said |= gate.step(rl, rr, s * r, r * vx, vx, 0.0, s * r)
    assert said and gate.contradicted and not gate.heading_ok()


@pytest.mark.parametrize("unsigned", [False, True], ids=["signed_wheels", "unsigned_wheels"])
def test_a_right_gyro_reversing_is_confirmed_by_the_wheels(unsigned):
    """ay switched off (NaN): the wheels alone confirm a right gyro reversing, either encoding."""
    gate = GyroScaleGate(TRACK)
    for i in range(400):
        r, vx = lane_change(i * 0.06), -4.0
        rl, rr = vx - 0.5 * r * TRACK, vx + 0.5 * r * TRACK
        if unsigned:
            rl, rr = abs(rl), abs(rr)
        assert not gate.step(rl, rr, r, math.nan, vx, 0.0, r)
    assert gate.confirmed and not gate.contradicted and gate.heading_ok()
    assert abs(gate.wheels.k - 1.0) < 0.05


def test_a_heading_is_not_promised_on_a_gyro_exercised_before_confirmation():
    gate = GyroScaleGate(TRACK)
    gate.step(1.0, 1.0, 0.5 * GSC_QUIET, 0.0, -1.0, 0.0, 0.5 * GSC_QUIET)  # quiet: still promised
    assert gate.heading_ok()
    gate.step(1.0, 1.0, 3.0 * GSC_QUIET, 0.0, -1.0, 0.0, 3.0 * GSC_QUIET)  # a turn, below the witnesses' speed
    assert gate.exercised and gate.motion_ok() and not gate.heading_ok()


@pytest.fixture(scope="module")
def reversing_drive(tmp_path_factory):
    return simulated_drive(tmp_path_factory, "gyro_reversing", Scenario("reversing", "reversing"))


def _heading(e, t):
    psi = np.interp(e["t"], t["t"], np.unwrap(t["heading_rad"]))
    err = np.abs((e["heading_rad"] - psi + math.pi) % (2.0 * math.pi) - math.pi)
    v = e["heading_valid"].astype(bool)
    return v, err, e["t"] - e["t"][0]


def test_a_flipped_gyro_on_the_reversing_drive_promises_no_heading_off(reversing_drive):
    """Before (integ28, fa2d927): 649 heading rows valid beyond 3 sigma, up to 52.5 deg, in the
    reverse curve (29-45 s), and no line named the gyro (tools/probe_wrong_config.py)."""
    lines: list[str] = []
    e, t = replay_edited(reversing_drive, lambda c: c["inputs"]["yaw_rate"].update(scale=-1.0),
                         "yaw_sign", log_level="warning", stderr=lines)
    v, err, _ = _heading(e, t)
    assert any(SAID in line for line in lines)
    # what remains: the rotation of the curve's first second, read below GSC_QUIET (2.4 deg
    # measured): nothing valid near the 5 deg a valid heading promises
    assert not (v & (err > math.radians(4.0))).any()


def test_a_flipped_gyro_reversing_is_never_valid_beyond_3_sigma(reversing_drive):
    """Before (main, ee24b24): 42 rows beyond 3 sigma, up to 1.73 deg at 0.33 deg std (30.1-30.35 s),
    the curve's first second read below GSC_QUIET; the heading's std now carries the rotation the
    unconfirmed gyro integrated (GyroScaleGate.heading_scale_sd)."""
    e, t = replay_edited(reversing_drive, lambda c: c["inputs"]["yaw_rate"].update(scale=-1.0), "yaw_sign_3sigma")
    v, err, _ = _heading(e, t)
    assert v.sum() > 3000  # the forward part before the curve keeps its heading
    assert not (v & (err > 3.0 * e["heading_std_rad"])).any()


def test_an_unconfirmed_gyro_owes_the_heading_a_flips_std():
    gate = GyroScaleGate(TRACK)
    assert gate.heading_scale_sd() == GSC_UNCONFIRMED_SCALE_SD
    _feed(gate, 1.0, lane_change)
    assert gate.confirmed and gate.heading_scale_sd() == 0.0


def test_a_gyro_in_rad_read_as_deg_reversing_is_named_and_not_promised_on(reversing_drive):
    """Before: 934 heading rows valid beyond 3 sigma, up to 38.4 deg, through 34 s."""
    lines: list[str] = []
    e, t = replay_edited(reversing_drive, lambda c: c["inputs"]["yaw_rate"].update(scale=math.pi / 180.0),
                         "gyro_rad_as_deg", log_level="warning", stderr=lines)
    v, err, rel = _heading(e, t)
    assert any(SAID in line for line in lines)
    # one second of witnesses at >= 3 m/s reversing (from 31.25 s) contradicts it
    assert not (v & (rel > 32.5) & (err > 3.0 * e["heading_std_rad"])).any()


def test_a_gyro_in_rad_read_as_deg_is_never_valid_beyond_3_sigma_reversing_slowly(reversing_drive):
    """Before (main, ee24b24): 212 rows beyond 3 sigma, up to 6.2 deg at 0.33 deg std (30.4-31.67 s):
    the gyro read 1/57 of the curve, "quiet", below the fits' 3 m/s. The rear wheels count the turn
    it missed (GyroScaleGate.heading_std)."""
    e, t = replay_edited(reversing_drive, lambda c: c["inputs"]["yaw_rate"].update(scale=math.pi / 180.0),
                         "gyro_rad_as_deg_3sigma")
    v, err, _ = _heading(e, t)
    assert v.sum() > 3000
    assert not (v & (err > 3.0 * e["heading_std_rad"])).any()


def _slow_reverse(gate, s, vx=-2.0, n=60, step=0.06):
    """Reversing at ``vx`` (below the fits' speed) through a curve of 0.08 rad/s, the gyro reading
    ``s`` r; the rear wheels as a DBC sends them (0.032 m/s quanta)."""
    q = 0.032
    for i in range(n):
        r = 0.08 * math.sin(math.pi * i / n)
        rl, rr = round((vx - 0.5 * r * TRACK) / q) * q, round((vx + 0.5 * r * TRACK) / q) * q
        gate.step(rl, rr, s * r, r * vx, vx, 0.0, s * r)
    return 0.08 * 2.0 / math.pi * n * step  # the curve's rotation (rad)


@pytest.mark.parametrize("s, owed", [(1.0, False), (math.pi / 180.0, True), (-1.0, True)])
def test_a_slow_turn_the_gyro_and_the_wheels_disagree_on_is_owed_to_the_heading(s, owed):
    gate = GyroScaleGate(TRACK)
    turn = _slow_reverse(gate, s)
    assert not gate.confirmed  # below GSC_MIN_SPEED: no fit
    if owed:  # the rotation the gyro missed (or doubled), at GSC_SLOW_SIGMA
        assert gate.heading_std() > 0.8 * abs(1.0 - s) * turn / GSC_SLOW_SIGMA
    else:  # the wheel quanta only
        assert gate.heading_std() < 0.1 * turn


def test_the_right_gyro_reversing_keeps_its_heading(reversing_drive):
    lines: list[str] = []
    e, t = replay_edited(reversing_drive, lambda c: None, "right", log_level="warning", stderr=lines)
    v, err, rel = _heading(e, t)
    assert not any(SAID in line for line in lines)
    assert not (v & (err > 3.0 * e["heading_std_rad"])).any()
    # withheld only from the curve's first reading to the witnesses' confirmation at 3 m/s
    assert v[(rel > 32.0) & (rel < 45.0)].all()
    assert v[(rel > 29.0) & (rel < 45.0)].mean() > 0.85


def test_a_wheel_the_abs_reports_as_0_is_no_slow_turn():
    """Below its minimum speed an ABS reports 0: one rear wheel at 0, the other at 0.3 m/s, is not
    a 0.19 rad/s turn the gyro missed."""
    gate = GyroScaleGate(TRACK)
    for _ in range(50):
        gate.step(0.0, 0.3, 0.0, 0.0, 0.25, 0.0, 0.0)
    assert gate.heading_std() == 0.0


def test_a_heading_set_from_a_course_owes_nothing_to_the_slow_turns_before_it():
    """A launch's slow metres come before any heading: a course alignment after them clears the
    debt (before, it withheld the noisy-wheel launches' heading 0.2 s longer)."""
    gate = GyroScaleGate(TRACK)
    _slow_reverse(gate, math.pi / 180.0)
    assert gate.heading_std() > 0.0
    gate.heading_set()
    assert gate.heading_std() == 0.0
    _slow_reverse(gate, math.pi / 180.0)  # a slow turn after it is owed again
    assert gate.heading_std() > 0.0
