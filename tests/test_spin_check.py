"""A spinning car must not keep a valid vx / sideslip (issue 7, random drives 89, 166, 205, 239).

The unit tests drive :class:`SpinCheck` with the kinematics of a gripping corner, a stuck gyro and a
spin; the replay test runs random drive 89 (tools/random_drives.py, generator v1: a rear-driven
car's j-turn that spins out on dry asphalt) through the suite's own scoring. On integ32 (7222297)
that drive had vx valid 15.6 m/s off (392 of 6447 valid rows beyond 3 sigma, coverage 93.9 %).
"""
from __future__ import annotations

import math

import pytest

from tools_import import load_tool

from ecu_daemon.estimator.spin_check import GRIP_MPS2, GRIP_S, SLIDE_RAD, TAU_S, SpinCheck

DT = 0.006
TRACK = 1.6


def _run(check: SpinCheck, seconds: float, vx: float, r: float, ay: float, r_wheels: float | None = None,
         v_wheels: float | None = None, t0: float = 0.0) -> list[bool]:
    """Feed constant kinematics; the rear wheels turn with ``r_wheels`` (the gyro's r by default)."""
    rw = r if r_wheels is None else r_wheels
    v = vx if v_wheels is None else v_wheels
    rl, rr = v - 0.5 * TRACK * rw, v + 0.5 * TRACK * rw
    n = int(round(seconds / DT))
    return [check.step(t0 + i * DT, vx, r, ay, v, rl, rr, True) for i in range(n)]


def test_a_gripping_corner_at_the_grip_limit_does_not_fire():
    c = SpinCheck(DT, TRACK)
    # 1.1 g steady on dry asphalt at 25 m/s: ay = r vx
    r = 1.1 * 9.80665 / 25.0
    assert not any(_run(c, 5.0, 25.0, r, 1.1 * 9.80665))
    assert c.events == 0


def test_a_fast_weave_of_a_gripping_car_does_not_fire():
    # 50 m/s, yaw rate swinging 0.05-0.30 rad/s at 1.2 Hz around a 0.125 rad/s corner, ay lagging
    # (flying_50_r400r_h300's start): r vx up to 15 m/s^2, |ay - r vx| up to 8, but the sideslip
    # moves by ~1.5 deg: not a slide
    import math as m
    c = SpinCheck(DT, TRACK)
    out = []
    for i in range(int(5.0 / DT)):
        t = i * DT
        r = 0.125 + 0.175 * m.sin(2 * m.pi * 1.2 * t)
        ay = 50.0 * (0.125 + 0.175 * m.sin(2 * m.pi * 1.2 * (t - 0.04)))
        out.append(c.step(t, 50.0, r, ay, 50.0, 50.0 - 0.8 * r, 50.0 + 0.8 * r, True))
    assert max(abs(50.0 * (0.125 + 0.175)) for _ in (0,)) > GRIP_MPS2
    assert not any(out) and c.peak < 1.0


def test_a_yaw_rate_beyond_grip_the_rear_wheels_do_not_see_is_a_gyro_fault_not_a_spin():
    c = SpinCheck(DT, TRACK)
    # a gyro stuck at 60 deg/s on a straight at 20 m/s: r vx = 21 m/s^2 > 1.2 g, ay 0, wheels straight
    assert not any(_run(c, 3.0, 20.0, 1.05, 0.0, r_wheels=0.0))


def test_a_spin_fires_and_holds_until_the_wheels_show_grip_again():
    c = SpinCheck(DT, TRACK)
    _run(c, 1.0, 20.0, 0.3, 6.0)  # gripping corner: 0.3 rad/s x 20 m/s = 6 m/s^2
    assert not c.active
    # the rear breaks away: 1.5 rad/s at 15 m/s (22 m/s^2 of r vx) against 6.5 m/s^2 of ay
    assert 15.0 * 1.5 > GRIP_MPS2 and (15.0 * 1.5 - 6.5) / 15.0 * TAU_S > SLIDE_RAD
    out = _run(c, 1.0, 15.0, 1.5, 6.5, t0=1.0)
    assert out[-1] and c.events == 1
    # the filter's vx stays spoiled (18 m/s) but the wheels say 4 m/s, r 0.25, ay 1.0: gripping;
    # it takes GRIP_S (plus the low-pass settling) before the slide is called over
    held = _run(c, GRIP_S * 0.9, 18.0, 0.25, 1.0, v_wheels=4.0, t0=2.0)
    assert all(held) and not c.released
    released = False
    for i in range(int(round(1.0 / DT))):
        v = 4.0
        c.step(3.0 + i * DT, 18.0, 0.25, 1.0, v, v - 0.5 * TRACK * 0.25, v + 0.5 * TRACK * 0.25, True)
        released = released or c.released
    assert released and not c.active


def test_the_check_keeps_its_verdict_while_the_imu_is_stale():
    c = SpinCheck(DT, TRACK)
    _run(c, 1.0, 15.0, 1.5, 6.5)
    assert c.active
    for i in range(400):  # stale IMU: nothing judged, the slide is not over
        assert c.step(i * DT, 15.0, 0.0, 0.0, 4.0, 4.0, 4.0, False)


@pytest.fixture(scope="module")
def rd():
    return load_tool("random_drives")


def test_a_car_that_spins_out_keeps_no_valid_vx_beyond_its_std(rd, tmp_path):
    d = rd.run_drive(89, str(tmp_path))
    assert d["error"] is None and d["spun_out"]
    vx = d["figures"]["vx"]
    # integ32: 392 of 6447 valid rows beyond 3 sigma, worst 15.6 m/s while valid
    assert vx["valid_rows"] > 5000  # the rest of the drive is still promised
    assert vx["coverage_3sigma"] >= 0.99, vx
    assert vx["worst_error_valid"] < 2.0, vx
    ss = d["figures"]["sideslip"]
    assert ss["worst_error_valid"] <= math.radians(2.0), ss  # the sideslip's 2 deg promise


WHEELBASE = 2.513


def _spun(wheelbase: float = WHEELBASE) -> SpinCheck:
    c = SpinCheck(DT, TRACK, wheelbase)
    _run(c, 1.0, 15.0, 1.5, 6.5)  # the rear breaks away (as above): the check fires
    assert c.active
    return c


def _slide(c: SpinCheck, seconds: float, r: float, ay: float, front: float, rear: float, delta: float,
           t0: float = 2.0) -> bool:
    """Feed a car whose front wheels read ``front`` and rear ``rear`` (m/s, mean of the pair; the
    rear-driven car fuses the undriven fronts); True when the check released."""
    released = False
    for i in range(int(round(seconds / DT))):
        c.step(t0 + i * DT, 18.0, r, ay, front, rear - 0.5 * TRACK * r, rear + 0.5 * TRACK * r, True,
               delta, front - 0.5 * TRACK * r, front + 0.5 * TRACK * r)
        released = released or c.released
    return released


@pytest.mark.parametrize("front, rear, delta", [
    # random drive 4081 (RWD, mu 0.21) at 1232.5: 105 deg sideways (vy 3.5 m/s, both axles ~60 deg
    # of slip), countersteering 0.335 rad: the axles' slips alike (yaw misfit 0.73 m/s, within its
    # bound), the steered fronts 0.96 m/s off the rears
    (-1.95, -0.89, -0.335),
    # ... and at 1232.0, steering nearly straight: the fronts cannot tell, the yaw rate (L r 1.41 m/s
    # against v tan(delta) 0.2) can
    (-2.57, -2.20, -0.078),
])
def test_a_car_sliding_sideways_slowly_on_ice_does_not_grip_again(monkeypatch, front, rear, delta):
    import ecu_daemon.estimator.spin_check as sc
    r, ay = 0.56, -1.98
    # the wheels' test alone reads grip: |ay - r v_wheels| < RELEASE_MPS2 (mu g is 2.06 m/s^2 there)
    assert abs(ay - r * front) < sc.RELEASE_MPS2
    assert not _slide(_spun(), 3.0, r, ay, front, rear, delta)
    monkeypatch.setattr(sc, "RELEASE_STEERING", False)
    assert _slide(_spun(), 3.0, r, ay, front, rear, delta)  # main: released after GRIP_S


@pytest.mark.parametrize("v, delta", [(2.0, 0.3), (-2.0, -0.3), (8.0, 0.05), (1.5, 0.6)])
def test_a_car_that_grips_again_is_released_whatever_its_steering(v, delta):
    # both axles rolling along their wheels: L r = vx tan(delta), the fronts at vx / cos(delta)
    r = v * math.tan(delta) / WHEELBASE
    c = _spun()
    assert _slide(c, 2.0, r, r * v, v / math.cos(delta), v, delta) and not c.active


def test_without_the_steering_the_wheels_test_decides_as_before():
    c = _spun()
    assert _slide(c, 2.0, 0.56, -1.98, -1.95, -0.89, math.nan)


def test_a_slide_on_a_wet_road_fires_below_a_dry_roads_grip(monkeypatch):
    import ecu_daemon.estimator.spin_check as sc
    # random drive 4288 (AWD, mu 0.33) at 1222.7: r -0.49 rad/s at 21.9 m/s (r vx 10.7 m/s^2, below the
    # dry road's 1.2 g) against ay -3.35: the sideslip turns 30 deg in a second
    vx, r, ay = 21.9, -0.49, -3.35
    assert abs(r * vx) < GRIP_MPS2
    monkeypatch.setattr(sc, "SLIDE_ROAD_GRIP", True)
    c = SpinCheck(DT, TRACK)
    assert _run(c, 1.0, vx, r, ay)[-1] and c.events == 1
    monkeypatch.setattr(sc, "SLIDE_ROAD_GRIP", False)
    c = SpinCheck(DT, TRACK)
    assert not any(_run(c, 1.0, vx, r, ay))  # main 2a5eb36: never fired


def test_a_gripping_corner_on_snow_does_not_fire_on_the_roads_grip(monkeypatch):
    import ecu_daemon.estimator.spin_check as sc
    monkeypatch.setattr(sc, "SLIDE_ROAD_GRIP", True)
    c = SpinCheck(DT, TRACK)
    # 0.3 g at 15 m/s, ay = r vx (plus 0.5 m/s^2 of ay bias): no sideslip change
    r = 0.3 * 9.80665 / 15.0
    assert not any(_run(c, 5.0, 15.0, r, r * 15.0 - 0.5))
    assert c.events == 0
