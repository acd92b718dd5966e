"""Fault detection and isolation (estimator/fault_detection.py).

Unit tests drive each check with synthetic sample series; the end-to-end tests inject the faults
issue 7 reported into a simulated 22 m/s drive (frames re-encoded by ``fault_injection``) and
replay it through the replay contract: never wrong while valid, the right source isolated, the
filter valid and right again after the fault, the wheel scale unharmed.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from ecu_daemon import config as config_mod
from ecu_daemon.estimator import estimate as est_mod
from ecu_daemon.estimator import fault_detection as fd
from ecu_daemon.estimator.kinematic import BR, KW, NX, VX
from ecu_daemon.evaluate import read_csv
from ecu_daemon.replay import run_replay
from ecu_daemon.sim import SCENARIOS, simulate, vehicle_config
from ecu_daemon.sim.scenario import T0
from ecu_daemon.sim.writer import write_all
from fault_injection import fault_can, fault_gnss

DT = 0.006
TRACK = 1.58
DEG = math.pi / 180.0


def _state(vx: float = 22.0) -> np.ndarray:
    x = np.zeros(NX)
    x[VX] = vx
    x[KW] = 1.0
    return x


def _run(det: fd.FaultDetector, n: int, k0: int = 0, *, v=22.0, rl=None, rr=None, r=0.0, ax=0.0, ay=None,
         x=None) -> list[int]:
    """n steps of constant (or callable-of-step) inputs; returns the isolation mask per step."""
    x = _state() if x is None else x
    out = []
    for j in range(k0, k0 + n):
        val = lambda f: f(j) if callable(f) else f  # noqa: E731
        vv = val(v)
        rr_ = val(r)
        left = vv - rr_ * TRACK / 2 if rl is None else val(rl)
        right = vv + rr_ * TRACK / 2 if rr is None else val(rr)
        ay_ = rr_ * x[VX] if ay is None else val(ay)
        out.append(det.step(j, (left, right, left, right), True, val(r), val(ax), ay_, True, x, 1e-4, 4e-4))
    return out


# ------------------------------------------------------------------------------ unit: each check
def test_latch_needs_a_run_to_isolate_and_a_longer_run_to_return():
    latch = fd._Latch(3, 5)
    assert [latch.update(v) for v in (True, True, None, False, True, True, True)] == \
        [False, False, False, False, False, False, True]
    assert latch.events == 1
    assert [latch.update(v) for v in (False,) * 4 + (None, True) + (False,) * 5] == [True] * 10 + [False]


def test_state_as_list_or_array_and_a_slow_phase_give_the_same_checks():
    """``step`` takes the state as the core's list or as an array; the lateral window, emptied
    while slow, restarts as in a fresh detector (the core's fast paths must not change a verdict)."""
    def model_vy(vx, r, ay, rdot):
        return 0.02 * ay + 0.1 * r

    def series(det, as_list, k0=0, slow_first=False):
        out = []
        for j in range(k0, k0 + 600):
            slow = slow_first and j < k0 + 100
            vx = 3.0 if slow else 20.0 + math.sin(j * 0.01)
            x = _state(vx)
            r = 0.2 * math.sin(j * 0.02)
            ay = r * vx + (1.5 if j > k0 + 300 else 0.0)  # an ay offset the lateral check sees
            left, right = vx - r * TRACK / 2, vx + r * TRACK / 2
            out.append((det.step(j, (left, right, left, right), True, r, 0.0, ay, True,
                                 x.tolist() if as_list else x, 1e-4, 4e-4),
                        det.lat_residual, det.lat_excess, det.yaw_suspect, det.wheel_z))
        return out

    a = series(fd.FaultDetector(DT, TRACK, model_vy=model_vy), True)
    b = series(fd.FaultDetector(DT, TRACK, model_vy=model_vy), False)
    assert a == b and any(e[2] > 0.0 for e in a)
    det = fd.FaultDetector(DT, TRACK, model_vy=model_vy)
    series(det, True)  # fills the window; then slow, then fast again from step 700
    again = series(det, True, 600, slow_first=True)
    fresh = series(fd.FaultDetector(DT, TRACK, model_vy=model_vy), True, 600, slow_first=True)
    # the same window contents: no verdict until it has refilled, then the same residuals (up to the
    # rounding of the running integrals, which keep counting through the slow phase)
    assert [e[1] == 0.0 for e in again] == [e[1] == 0.0 for e in fresh]
    assert [e[1] for e in again] == pytest.approx([e[1] for e in fresh], rel=1e-9, abs=1e-12)


def test_consistent_driving_isolates_nothing():
    det = fd.FaultDetector(DT, TRACK)
    # accelerating at 2 m/s^2 while turning at a yaw rate that slowly changes sign
    masks = _run(det, 2000, v=lambda j: 10.0 + 2.0 * j * DT, ax=2.0, r=lambda j: 0.3 * math.sin(j * DT))
    assert not any(masks)


def test_wheels_dropping_to_zero_at_speed_are_isolated_not_the_accelerometer():
    det = fd.FaultDetector(DT, TRACK)
    assert not any(_run(det, 200))
    masks = _run(det, 300, 200, v=0.0)
    assert masks[10] == fd.WHEELS and masks[-1] == fd.WHEELS  # still isolated: 0 is not the filter's 22
    assert det.events["wheels"] == 1 and det.events["accel_x"] == 0
    assert not det.standstill_plausible(22.0, math.nan)  # and no zero-velocity update from them


def test_accelerometer_stuck_high_is_isolated_and_returns_when_it_agrees_again():
    det = fd.FaultDetector(DT, TRACK)
    _run(det, 200)
    masks = _run(det, 300, 200, ax=29.9)
    assert masks[1] == fd.ACCEL_X and masks[-1] == fd.ACCEL_X  # implausible: caught at once
    back = _run(det, 400, 500)
    assert back[0] == fd.ACCEL_X and back[-1] == 0  # agreement for ~1 s before it returns
    assert det.events == {"wheels": 0, "yaw_rate": 0, "accel_x": 1, "accel_y": 0, "gnss": 0, "wheel_speed": 0}


def test_accelerometer_offset_the_wheels_do_not_see_is_caught_by_the_window():
    det = fd.FaultDetector(DT, TRACK)
    _run(det, 200)
    masks = _run(det, 200, 200, ax=15.0)  # a plausible value, but steady wheels: d(wheel)/dt = 0
    assert masks[-1] == fd.ACCEL_X  # the accelerometer stepped, the wheels did not


def test_one_wrong_rear_wheel_is_replaced_by_its_partner():
    det = fd.FaultDetector(DT, TRACK, 1.2, "front", lambda fl, fr, rl, rr: 0.5 * (rl + rr))
    x = _state()
    r = 0.2  # turning left: the right wheels run faster by r * track
    w = (22.0 - r * TRACK / 2, 22.0 + r * TRACK / 2, 22.0 - r * TRACK / 2, 22.0 + r * TRACK / 2)
    bad = (w[0], w[1], w[2] + 2.0, w[3])  # rear-left reads 2 m/s high
    masks = [det.step(j, bad, True, r, 0.0, r * 22.0, True, x, 1e-4, 4e-4) for j in range(10)]
    assert masks[-1] == fd.WHEEL_SPEED and det.wheel_mask == 0b0100
    assert det.wheel_z == pytest.approx(22.0)  # the partner, corrected by r * track
    assert not det.isolated & fd.WHEELS and det.events["wheel_speed"] == 1


def test_gyro_stuck_is_isolated_by_the_wheels_and_ay():
    det = fd.FaultDetector(DT, TRACK)
    _run(det, 300)
    # true yaw rate 0 (wheels and ay say so), gyro reads 0.05 rad/s
    x = _state()
    masks = []
    for j in range(300, 900):
        masks.append(det.step(j, (22.0,) * 4, True, 0.05, 0.0, 0.0, True, x, 1e-4, 4e-4))
    assert masks[-1] == fd.YAW_RATE and det.events["yaw_rate"] == 1
    assert det.r_wheels == pytest.approx(0.0, abs=1e-3)  # the substitute the core predicts with


def test_yaw_disagreement_is_the_gyro_against_the_wheels_while_suspect_only():
    det = fd.FaultDetector(DT, TRACK)
    _run(det, 300, r=0.2)
    assert not det.yaw_suspect and det.yaw_disagreement == 0.0
    x = _state()
    seen = []
    for j in range(300, 330):  # gyro reads 0.3 rad/s, wheels and ay say 0.2: suspect before isolated
        left, right = 22.0 - 0.2 * TRACK / 2, 22.0 + 0.2 * TRACK / 2
        det.step(j, (left, right, left, right), True, 0.3, 0.0, 0.2 * 22.0, True, x, 1e-4, 4e-4)
        seen.append((det.yaw_suspect, det.yaw_disagreement))
    suspect = [e for s_, e in seen if s_]
    assert suspect and all(0.0 < e <= 0.1 + 1e-9 for e in suspect)
    assert all(e == 0.0 for s_, e in seen if not s_)


def _brake_in_a_corner(det, k0: int, n: int, gyro_extra: float, ax: float, slip_yaw: float = 0.4):
    """n steps in a 0.3 rad/s corner from 15 m/s decelerating at -ax, the inner (left) rear wheel
    slipping more than the outer so the rear pair reads ``slip_yaw`` rad/s more yaw rate than the car
    turns (imu_brake_turn: up to 0.65 at 5 m/s^2; here each wheel stays inside the wheels' own vote);
    ay = r vx, the gyro reads the true rate + ``gyro_extra``."""
    seen = []
    for j in range(k0, k0 + n):
        v = 15.0 + ax * (j - k0) * DT
        x = _state(v)
        left = v - 0.3 * TRACK / 2 - 0.75 * slip_yaw * TRACK
        right = v + 0.3 * TRACK / 2 + 0.25 * slip_yaw * TRACK
        mask = det.step(j, (v - 0.3 * TRACK / 2, v + 0.3 * TRACK / 2, left, right), True,
                        0.3 + gyro_extra, ax, 0.3 * v, True, x, 1e-4, 4e-4)
        seen.append((mask, det.yaw_suspect, det.yaw_disagreement, det.r_wheels))
    return seen


def test_braked_rear_wheels_do_not_judge_the_gyro():
    """Braking in a corner unloads the inner rear wheel, which then slips more than the outer one:
    their difference is no yaw rate (BRAKE_WITNESS_MPS2). imu_brake_turn: the gyro was suspect for
    3 s of each 5 m/s^2 braking, and its heading and vy stds widened by the wheels' 0.65 rad/s
    (25 deg, 1 m/s) while the heading was < 1 deg off and the sideslip invalid. The same wheels
    rolling free (no braking) still make the gyro suspect; ay / vx still judges it while braking."""
    det = fd.FaultDetector(DT, TRACK)
    _run(det, 300, v=15.0, r=0.3, x=_state(15.0))
    braking = _brake_in_a_corner(det, 300, 250, 0.0, -5.0)
    assert all(m == 0 and not s_ and e == 0.0 for m, s_, e, _ in braking)
    assert braking[-1][3] == pytest.approx(0.3 + 0.4, abs=0.05)  # still the isolated gyro's stand-in
    assert not det.yaw_suspect
    free = fd.FaultDetector(DT, TRACK)
    _run(free, 300, v=15.0, r=0.3, x=_state(15.0))
    rolling = _brake_in_a_corner(free, 300, 50, 0.0, -0.5)  # engine braking: the rear rolls free
    assert any(s_ for _, s_, _, _ in rolling)
    faulty = fd.FaultDetector(DT, TRACK)
    _run(faulty, 300, v=15.0, r=0.3, x=_state(15.0))
    gyro_off = _brake_in_a_corner(faulty, 300, 100, 0.3, -5.0)  # gyro 0.3 rad/s high: ay sees it
    assert any(s_ and e > 0.2 for _, s_, e, _ in gyro_off)


def test_gyro_bias_is_not_a_fault():
    det = fd.FaultDetector(DT, TRACK)
    x = _state()
    x[BR] = 0.05  # the filter knows the bias: bias-corrected rates agree
    masks = [det.step(j, (22.0,) * 4, True, 0.05, 0.0, 0.0, True, x, 1e-4, 4e-4) for j in range(600)]
    assert not any(masks)


def test_lateral_accelerometer_stuck_is_isolated_when_gyro_and_wheels_agree():
    det = fd.FaultDetector(DT, TRACK)
    _run(det, 300, r=0.2)
    masks = _run(det, 300, 300, r=0.2, ay=0.0)  # turning at 0.2 rad/s, 22 m/s: ay should be 4.4
    assert masks[-1] == fd.ACCEL_Y and det.events["yaw_rate"] == 0


def _lane_change(offset: float):
    """22 m/s through a 1 Hz lane change whose vy follows the single-track model exactly; ay
    carries ``offset`` from step 400 on. Returns lat_excess per step."""
    lr, vx, w = 1.5, 22.0, 2.0 * math.pi
    model = lambda vx_, r, ay, rdot: lr * r  # noqa: E731  (the model's constant shift cancels anyway)
    det = fd.FaultDetector(DT, TRACK, model_vy=model)
    r = lambda j: 0.3 * math.sin(w * j * DT)  # noqa: E731
    ay = lambda j: r(j) * vx + lr * 0.3 * w * math.cos(w * j * DT) + (offset if j >= 400 else 0.0)  # noqa: E731
    out = []
    for j in range(800):
        _run(det, 1, j, r=r, ay=ay)
        out.append(det.lat_excess)
    return np.array(out)


def test_lateral_window_sees_an_ay_offset_in_a_transient_not_a_bank():
    """dvy/dt is large in a lane change (the ay / vx check needs a wide tolerance there); the
    window integral compares ay with r * vx plus the model's change of vy, so a 2 m/s^2 offset
    shows within a second while a clean drive or a 6 % bank's gravity (0.6 m/s^2) does not."""
    assert not _lane_change(0.0).any()
    assert not _lane_change(0.6).any()
    excess = _lane_change(2.0)
    assert not excess[:400].any()
    first = int(np.argmax(excess > 0))
    assert 400 < first < 400 + 1.0 / DT and excess.max() > 0.5


def test_corner_exit_at_low_speed_is_not_an_ay_fault():
    """Leaving a 9 m circle at 6.5 m/s: vy = lr * r falls with r, so ay = r vx + lr * rdot and
    ay / vx is 0.3 rad/s off the gyro for half a second (flying_6_r9r isolated ay there, and
    sideslip and heading stayed invalid for the rest of the drive)."""
    lr, vx = 1.5, 6.5
    det = fd.FaultDetector(DT, TRACK, lr_m=lr)
    x = _state(vx)
    r0, ramp = 0.67, int(0.5 / DT)
    for j in range(600):
        rdot = -r0 / (ramp * DT) if 200 <= j < 200 + ramp else 0.0
        r = r0 if j < 200 else max(r0 - (j - 200) * r0 / ramp, 0.0)
        ay = r * vx + lr * rdot
        w = (vx - r * TRACK / 2, vx + r * TRACK / 2)
        det.step(j, (w[0], w[1], w[0], w[1]), True, r, 0.0, ay, True, x, 1e-4, 4e-4, 0.0, rdot)
    assert det.events["accel_y"] == 0 and det.events["yaw_rate"] == 0


def _turn_with_lagged_wheels(wheel_lag: float, gyro_scale: float = 1.0) -> int:
    """22 m/s, one 1 s turn (yaw rate 0 -> 0.4 -> 0 rad/s, 0.4 g); the wheels' yaw rate ``wheel_lag``
    late (the ABS ECU's filter; negative: ahead of the gyro), ay's witness 0.15 s late (the tyres'
    vy build-up it does not model); the core's rdot as it comes, 0.06 s late. Returns the gyro's
    isolation events."""
    lr, vx, w, t0 = 1.5, 22.0, 2.0 * math.pi, 2.0
    det = fd.FaultDetector(DT, TRACK, lr_m=lr)
    x = _state(vx)
    r = lambda t: 0.2 * (1.0 - math.cos(w * (t - t0))) if t0 <= t <= t0 + 1.0 else 0.0  # noqa: E731
    rdot = lambda t: 0.2 * w * math.sin(w * (t - t0)) if t0 <= t <= t0 + 1.0 else 0.0  # noqa: E731
    for j in range(int(5.0 / DT)):
        t = j * DT
        rw = r(t - wheel_lag)
        left, right = vx - rw * TRACK / 2, vx + rw * TRACK / 2
        det.step(j, (left, right, left, right), True, gyro_scale * r(t), 0.0, r(t - 0.15) * vx + lr * rdot(t),
                 True, x, 1e-4, 4e-4, 0.0, gyro_scale * rdot(t - 0.06))
    return det.events["yaw_rate"]


@pytest.mark.parametrize("lag", [0.0, 0.02, 0.04, 0.06, -0.04])
def test_wheels_lagging_the_gyro_are_not_a_gyro_scale_error(lag):
    """A lag tau of the wheels' yaw rate makes gyro - wheels = tau * rdot, which rides on r while a
    turn builds up: the scale test took it for a scaled gyro (main isolated a good gyro at 0.04
    and 0.06 s here, and on wheel_lag_0.04_dlc_1hz put the lag's disagreement into the heading,
    1.2 deg off). The test fits the timing term apart; a scaled gyro is still isolated."""
    assert _turn_with_lagged_wheels(lag) == 0
    assert _turn_with_lagged_wheels(lag, 1.3) >= 1
    assert _turn_with_lagged_wheels(lag, 0.7) >= 1


def test_gnss_disagreeing_with_trusted_wheels_is_isolated_then_returns():
    det = fd.FaultDetector(DT, TRACK)
    _run(det, 200)
    assert det.check_gnss(100, False, False) is False  # never fused
    assert not det.gnss_isolated
    assert det.check_gnss(133, False, False) is False
    assert det.gnss_isolated and det.step(201, (22.0,) * 4, True, 0.0, 0.0, 0.0, True, _state(), 1e-4,
                                          4e-4) == fd.GNSS
    for s in range(166, 166 + 33 * 4, 33):
        assert det.check_gnss(s, True, True) is True
    assert det.gnss_isolated  # four good fixes are not yet enough
    det.check_gnss(300, True, True)
    assert not det.gnss_isolated


def test_gnss_is_the_witness_while_wheels_and_accelerometer_disagree():
    det = fd.FaultDetector(DT, TRACK)
    _run(det, 200)
    _run(det, 20, 200, v=lambda j: 22.0 + 0.8 * (j - 200))  # wheels run away smoothly (no jump)
    assert det.isolated == fd.WHEELS | fd.ACCEL_X  # both suspects: neither fused
    # a fix taken after the onset agrees with the wheels: the accelerometer is the culprit
    assert det.check_gnss(210, True, True) is True
    assert _run(det, 1, 220, v=lambda j: 22.0 + 0.8 * (j - 200))[0] == fd.ACCEL_X


def test_standstill_needs_imu_and_gnss_to_agree():
    det = fd.FaultDetector(DT, TRACK)
    assert det.standstill_plausible(0.02, math.nan)
    assert det.standstill_plausible(0.02, 0.1)
    assert not det.standstill_plausible(0.02, 5.0)  # GNSS says we are moving
    assert not det.standstill_plausible(3.0, math.nan)  # the IMU-propagated speed says so


def test_learned_states_are_clamped_to_their_physical_range():
    x = np.zeros(NX)
    x[KW] = 1.39  # the wheel scale a GNSS glitch once taught the filter
    x[BR] = -0.5
    fd.clamp_learned(x)
    assert x[KW] == 1.05 and x[BR] == -0.1


# ------------------------------------------------------------------------- end to end, 22 m/s drive
FAULT_START, FAULT_END = T0 + 30.0, T0 + 35.0
WHEEL_INPUTS = ("wheel_speed_fl", "wheel_speed_fr", "wheel_speed_rl", "wheel_speed_rr")
FAULTS = {
    "wheels_zero": (lambda r: fault_can(r, WHEEL_INPUTS, FAULT_START, FAULT_END, lambda t, v: 0.0), fd.WHEELS),
    "yaw_rate_stuck": (lambda r: fault_can(r, ("yaw_rate",), FAULT_START, FAULT_END, lambda t, v: 0.05),
                       fd.YAW_RATE),
    "yaw_rate_stuck_in_lane_change": (
        lambda r: fault_can(r, ("yaw_rate",), T0 + 20.0, T0 + 25.0, lambda t, v: 0.05), fd.YAW_RATE),
    # an ay offset in the first lane change: vy drifts between the late GNSS fixes (issue 7: 2.7 deg
    # off while valid); the lateral window says so before the ay / vx vote isolates it
    "accel_y_offset": (lambda r: fault_can(r, ("accel_y",), T0 + 22.0, T0 + 27.0, lambda t, v: v + 2.0),
                       fd.ACCEL_Y),
    # all four wheels 2 m/s high: both suspects until a GNSS fix sides with the accelerometer; the
    # wheels must not return while 2 m/s off (they did once the isolation had widened the vx std)
    "wheels_offset": (lambda r: fault_can(r, WHEEL_INPUTS, FAULT_START, FAULT_END, lambda t, v: v + 2.0),
                      fd.WHEELS | fd.ACCEL_X),
    "accel_x_stuck_29.9": (lambda r: fault_can(r, ("accel_x",), FAULT_START, FAULT_END, lambda t, v: 29.9),
                           fd.ACCEL_X),
    "gnss_tripled": (lambda r: fault_gnss(r, FAULT_START, FAULT_END, lambda n, e: (3 * n, 3 * e)), fd.GNSS),
    "gnss_140_140": (lambda r: fault_gnss(r, FAULT_START, FAULT_END, lambda n, e: (140.0, 140.0)), fd.GNSS),
}


@pytest.fixture(scope="module")
def drive():
    sc = SCENARIOS["dlc_dry"]  # 22 m/s, two lane changes (20-30 s and 36-46 s)
    return simulate(sc, vehicle_config(sc))


def _replay(tmp_path, result):
    write_all(tmp_path, result, vehicle_config(result.scenario))
    cfg = config_mod.load(tmp_path / "config.toml")
    run_replay(cfg, str(tmp_path / "drive.log"), str(tmp_path / "drive_gnss.log"), str(tmp_path / "out.csv"))
    est = read_csv(tmp_path / "out.csv", ("t",), "estimate")
    truth = read_csv(tmp_path / "truth.csv", ("t",), "truth")
    t = est["t"]
    tr = {c: np.interp(t, truth["t"], truth[c]) for c in ("sideslip_rad", "vx_mps", "wheel_scale",
                                                           "yaw_rate_bias_radps", "accel_y_bias_eff_mps2")}
    tr["heading_rad"] = np.interp(t, truth["t"], np.unwrap(truth["heading_rad"]))
    return est, tr


def _wrap(a):
    return (a + math.pi) % (2 * math.pi) - math.pi


@pytest.mark.parametrize("name", list(FAULTS))
def test_fault_never_wrong_while_valid_and_recovers(tmp_path, drive, name):
    inject, source = FAULTS[name]
    est, tr = _replay(tmp_path, inject(drive))
    t = est["t"]
    run = t > T0 + 10.0  # after the drive's standstill and alignment
    e_beta = np.abs(_wrap(est["sideslip_rad"] - tr["sideslip_rad"]))
    e_psi = np.abs(_wrap(est["heading_rad"] - tr["heading_rad"]))
    e_vx = np.abs(est["vx_mps"] - tr["vx_mps"])
    valid = {k: (est[k] > 0.5) & run for k in ("sideslip_valid", "heading_valid", "velocity_valid")}
    assert not np.any(valid["sideslip_valid"] & (e_beta > 2 * DEG)), "sideslip wrong while valid"
    assert not np.any(valid["heading_valid"] & (e_psi > 5 * DEG)), "heading wrong while valid"
    assert not np.any(valid["velocity_valid"] & (e_vx > 3 * est["vx_std_mps"])), "vx wrong while valid"
    status = est["status"].astype(int)
    isolated = np.bitwise_or.reduce(status[run]) & sum(fd.SOURCE_BITS.values())
    assert isolated == source, f"isolated {isolated:#x}, expected {source:#x}"
    # recovered: valid and right again 10 s after the fault, the source back in
    after = t > FAULT_END + 10.0
    for k in valid:
        assert valid[k][after].mean() > 0.95, k
    assert not np.any(status[after] & isolated)
    assert e_beta[after].max() < 1 * DEG and e_psi[after].max() < 1 * DEG and e_vx[after].max() < 0.2
    # the wheel scale, learned in the first seconds of driving, is not dragged by the fault
    learned = t > T0 + 15.0
    assert np.max(np.abs(est["wheel_scale"][learned] - tr["wheel_scale"][learned])) < 0.01


#: gyro faults in the first lane change (22 m/s, up to 20 deg/s): the other sources hold the
#: estimate while the gyro is out
IMU_FAULTS = {
    # a gyro 5 deg/s off: with the gyro isolated, sideslip from the single-track model (on ay and
    # the wheels' yaw rate) instead of free integration of ay - r vx (1.7 deg RMS while isolated)
    "yaw_rate_offset": (("yaw_rate",), lambda t, v: v + 5.0 * DEG, fd.YAW_RATE),
    # a gyro stuck at its reading mid-corner (-19 deg/s): the ay bias is not taught the substitute's error
    "yaw_rate_stuck": (("yaw_rate",), lambda t, v: -19.0 * DEG, fd.YAW_RATE),
}


@pytest.mark.parametrize("name", list(IMU_FAULTS))
def test_imu_fault_in_a_lane_change_is_held_by_the_other_sources(tmp_path, drive, name):
    inputs, value, source = IMU_FAULTS[name]
    est, tr = _replay(tmp_path, fault_can(drive, inputs, T0 + 22.0, T0 + 27.0, value))
    t = est["t"]
    status = est["status"].astype(int)
    iso = (status & source) > 0
    assert iso.any() and not np.any(iso & (t < T0 + 22.0))
    e_beta = _wrap(est["sideslip_rad"] - tr["sideslip_rad"])
    assert np.sqrt(np.mean(e_beta[iso] ** 2)) < 0.6 * DEG, "sideslip while the source is isolated"
    valid = (est["sideslip_valid"] > 0.5) & (t > T0 + 10.0)
    assert not np.any(valid & (np.abs(e_beta) > 3.0 * est["sideslip_std_rad"])), "beyond 3 sigma while valid"
    # the heading the gyro drifted before it was isolated is taken back out (2.5-3.2 deg before)
    e_psi = _wrap(est["heading_rad"] - tr["heading_rad"])
    assert np.max(np.abs(e_psi[iso])) < 1.5 * DEG
    learned = t > T0 + 15.0  # learned quantities untouched by the fault
    assert np.max(np.abs(est["yaw_rate_bias_radps"] - tr["yaw_rate_bias_radps"])[learned]) < 0.05 * DEG
    # 0.0315 with core.MODEL_TYRE_FORCE's force (its comment), 0.035 beside the sideslip's latency term
    assert np.max(np.abs(est["accel_y_bias_mps2"] - tr["accel_y_bias_eff_mps2"])[learned]) < 0.04


def test_gyro_offset_that_stays_becomes_its_bias_and_the_gyro_returns(tmp_path, drive):
    """A step of the gyro's offset that does not go away (2 deg/s from 12 s to the end): FDI's job
    is the step (isolated within a second, the heading repaired), the bias state's the new
    constant: after RELEARN_S of a steady offset against the wheels the gyro is fused again with
    its new bias, and the estimate is valid and right on it."""
    offset = 2.0 * DEG
    est, tr = _replay(tmp_path, fault_can(drive, ("yaw_rate",), T0 + 12.0, T0 + 60.0, lambda t, v: v + offset))
    t = est["t"]
    status = est["status"].astype(int)
    iso = (status & fd.YAW_RATE) > 0
    assert iso[(t > T0 + 14.0) & (t < T0 + 12.0 + fd.RELEARN_S)].all(), "isolated until the bias is learned"
    end = t > t[-1] - 8.0
    assert not iso[end].any(), "the gyro is fused again"
    assert np.max(np.abs(est["yaw_rate_bias_radps"][end] - (tr["yaw_rate_bias_radps"][end] + offset))) < 0.1 * DEG
    e_beta = np.abs(_wrap(est["sideslip_rad"] - tr["sideslip_rad"]))
    e_psi = np.abs(_wrap(est["heading_rad"] - tr["heading_rad"]))
    valid_b = (est["sideslip_valid"] > 0.5) & (t > T0 + 10.0)
    valid_h = (est["heading_valid"] > 0.5) & (t > T0 + 10.0)
    assert not np.any(valid_b & (e_beta > 3.0 * est["sideslip_std_rad"])), "sideslip beyond 3 sigma while valid"
    assert not np.any(valid_h & (e_psi > 5.0 * DEG)), "heading wrong while valid"
    assert valid_h[end].all() and valid_b[end].mean() > 0.9 and e_psi[end].max() < 1.0 * DEG


def test_clean_drive_isolates_nothing(tmp_path, drive):
    est, _ = _replay(tmp_path, drive)
    assert not np.any(est["status"].astype(int) & sum(fd.SOURCE_BITS.values()))


def test_isolation_reaches_the_can_output(tmp_path, drive):
    """The EST_HEADING status bit a consumer reads on the bus, from the same replay."""
    from ecu_daemon.canlog import read_can_log
    from ecu_daemon.outputs import decode_output_frame
    from ecu_daemon.signals import load_dbc

    result = FAULTS["gnss_tripled"][0](drive)
    write_all(tmp_path, result, vehicle_config(result.scenario))
    cfg = config_mod.load(tmp_path / "config.toml")
    run_replay(cfg, str(tmp_path / "drive.log"), str(tmp_path / "drive_gnss.log"), out_can=str(tmp_path / "o.log"))
    db = load_dbc(cfg.output_dbc_path(), "out")
    hdg = db.get_message_by_name("EST_HEADING").frame_id
    import can

    bits = [decode_output_frame(db, can.Message(arbitration_id=fid, data=data, is_extended_id=ext))
            ["STATUS_GNSS_ISOLATED"] for t, fid, ext, err, data in read_can_log(str(tmp_path / "o.log"))
            if fid == hdg and FAULT_START < t < FAULT_END + 1.0]
    assert any(bits) and est_mod.STATUS_GNSS_ISOLATED == fd.GNSS


# ------------------------------------------------------------------------------ stuck readings
def _turning(j: int) -> float:
    """A lane-change-like yaw rate (rad/s): the witnesses of a stuck reading move."""
    return 0.3 * math.sin(2.0 * math.pi * 0.5 * j * DT)


def test_stuck_rear_wheel_inside_the_vote_tolerance_is_isolated_and_stays_out_until_it_moves():
    """A rear wheel frozen at its reading while the car weaves: it never leaves the wheel vote's
    tolerance (0.5 m/s + 3 %), only its yaw rate is wrong (the gyro and ay / vx outvote the
    wheels' yaw rate, which cannot say which wheel). Isolated within ~0.5 s, replaced by its
    partner, kept out even while the truth passes back through the frozen value."""
    det = fd.FaultDetector(DT, TRACK, 1.2, "front", lambda fl, fr, rl, rr: 0.5 * (rl + rr))
    x = _state()

    def wheels(j):
        r = _turning(j)
        return (22.0 - r * TRACK / 2, 22.0 + r * TRACK / 2, 22.0 - r * TRACK / 2, 22.0 + r * TRACK / 2)

    for j in range(300):
        det.step(j, wheels(j), True, _turning(j), 0.0, _turning(j) * 22.0, True, x, 1e-4, 4e-4)
    stuck = wheels(300)[2]
    masks = []
    for j in range(300, 1100):  # 4.8 s: the true rear-left speed crosses the frozen one again
        w = wheels(j)
        masks.append(det.step(j, (w[0], w[1], stuck, w[3]), True, _turning(j), 0.0, _turning(j) * 22.0,
                              True, x, 1e-4, 4e-4))
        assert abs(w[2] - stuck) < fd.WHEEL_TOL_MPS  # the vote alone cannot see it
    first = next(i for i, m in enumerate(masks) if m & fd.WHEEL_SPEED)
    assert first * DT < 0.6 and det.wheel_mask == 0b0100
    assert all(m & fd.WHEEL_SPEED for m in masks[first:]), "released while still frozen"
    assert not any(m & fd.YAW_RATE for m in masks), "the gyro is not blamed for the wheel"
    assert not det.yaw_suspect  # the wheels' yaw rate (now from the partner) agrees with the gyro
    back = [det.step(j, wheels(j), True, _turning(j), 0.0, _turning(j) * 22.0, True, x, 1e-4, 4e-4)
            for j in range(1100, 1500)]
    assert back[-1] == 0, "returns after it moves and agrees again"


def test_all_four_wheels_frozen_while_the_gyro_and_ay_turn_are_isolated():
    """A wheel-speed ECU repeating its last frame: four wheels agree with each other, so only
    the IMU can tell; the gyro and ay agree on a turn the frozen wheels do not show."""
    det = fd.FaultDetector(DT, TRACK)
    _run(det, 300)
    masks = _run(det, 200, 300, rl=22.0, rr=22.0, r=lambda j: _turning(j - 300))
    assert masks[-1] & fd.WHEELS and not any(m & fd.YAW_RATE for m in masks)
    assert next(i for i, m in enumerate(masks) if m & fd.WHEELS) * DT < 0.6


def test_stuck_lateral_accelerometer_stays_isolated_while_its_value_happens_to_agree():
    det = fd.FaultDetector(DT, TRACK)
    _run(det, 300)
    # ay frozen at 0 while the car turns and comes back straight (where 0 is right again)
    masks = _run(det, 1500, 300, r=lambda j: _turning(j - 300) if j < 300 + 333 else 0.0, ay=0.0)
    first = next(i for i, m in enumerate(masks) if m & fd.ACCEL_Y)
    assert first * DT < 0.5
    assert all(m & fd.ACCEL_Y for m in masks[first:]), "a frozen ay returned because it agreed"
    assert det.events["yaw_rate"] == 0


def test_lateral_check_with_the_gyro_isolated_judges_its_substitute():
    """A gyro frozen mid-corner is isolated; vy is then integrated with the wheels' yaw rate, and
    ay agrees with that: the lateral check must not report an ay fault of the size of the gyro's
    error times the speed (it did, 10 m/s^2, and sideslip stayed invalid the whole fault)."""
    lr = 1.5
    det = fd.FaultDetector(DT, TRACK, model_vy=lambda vx, r, ay, rdot: lr * r)
    excess = []
    for j in range(1200):
        r = _turning(j)
        gyro = r if j < 400 else _turning(400)
        left, right = 22.0 - r * TRACK / 2, 22.0 + r * TRACK / 2
        ay = r * 22.0 + lr * (_turning(j + 1) - r) / DT
        det.step(j, (left, right, left, right), True, gyro, 0.0, ay, True, _state(), 1e-4, 4e-4)
        excess.append((j, det.isolated, det.lat_excess))
    iso = [j for j, m, _ in excess if m & fd.YAW_RATE]
    assert iso and iso[0] < 400 + 100
    assert max(e for j, m, e in excess if j > iso[0] + int(fd.LAT_WINDOW_S / DT)) == 0.0
    assert not any(m & fd.ACCEL_Y for _, m, _ in excess)


def _frozen():
    """value(t, v) for fault_can: the reading at the fault's start, held."""
    held = []
    return lambda t, v: held[0] if held else held.append(v) or v


STUCK = {  # frozen at their reading in the first lane change (22 m/s): never wrong while valid,
    # and isolated fast enough that sideslip stays available (issue 7: >= 90 % once converged)
    "wheel_rl": ("wheel_speed_rl",),
    "wheel_rr": ("wheel_speed_rr",),
    "all_wheels": WHEEL_INPUTS,
    "yaw_rate": ("yaw_rate",),
    # its stand-in r vx rests on the gyro the wheels vouch for: valid on the straight after the lane change
    "accel_y": ("accel_y",),
}


#: availability misses measured on this version (strict: a fix shows as XPASS and is removed here)
STUCK_MISSES = {
    # 90.0 % before the single-track model's inputs shared one lag (Revs sideslip 0.304 -> 0.289 deg);
    # 89.8 % since: the std at the turn-ins is a little wider for ~0.1 s (as fault_accel_y_zero's)
    "accel_y": "sideslip valid on 89.8 % of the rows after the lane change (target 90 %)",
    # since stop 50 (core.SIDESLIP_LATENCY_SENS and MODEL_TYRE_FORCE withhold the lane change's peaks)
    "yaw_rate": "sideslip valid on 88.6 % of the rows after the lane change (target 90 %)",
}


@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.xfail(strict=True, reason=STUCK_MISSES[n]))
                                  if n in STUCK_MISSES else n for n in STUCK])
def test_stuck_input_in_a_lane_change_keeps_sideslip_available_and_honest(tmp_path, drive, name):
    result = drive
    for inp in STUCK[name]:  # each its own held value
        result = fault_can(result, (inp,), T0 + 22.0, T0 + 27.0, _frozen())
    est, tr = _replay(tmp_path, result)
    t = est["t"]
    speed = tr["vx_mps"]
    run = (t > T0 + 12.0) & (speed > 5.0)
    valid_b = est["sideslip_valid"] > 0.5
    e_beta = np.abs(_wrap(est["sideslip_rad"] - tr["sideslip_rad"]))
    e_vx = np.abs(est["vx_mps"] - tr["vx_mps"])
    assert valid_b[run].mean() >= 0.9, f"sideslip valid on {valid_b[run].mean():.0%} of the rows"
    vb = valid_b & run
    assert np.mean(e_beta[vb] <= 3.0 * est["sideslip_std_rad"][vb]) >= 0.99
    vv = (est["velocity_valid"] > 0.5) & run
    assert np.mean(e_vx[vv] <= 3.0 * est["vx_std_mps"][vv]) >= 0.99, "vx beyond 3 sigma while valid"


def test_wheels_at_rest_on_a_grade_are_not_stuck():
    """At rest on a 10 % grade the accelerometer reads ~1 m/s^2 and the wheels 0 for as long as
    the car stands: the integrated ax is no witness there (the wheels' dead band near 0 neither),
    so the stuck test does not judge the wheels below STUCK_MIN_SPEED_MPS."""
    det = fd.FaultDetector(DT, TRACK)
    masks = _run(det, 400, v=0.0, ax=0.98, x=_state(0.0))
    assert not any(masks) and not det.wheels_stuck


def _lane_change_rear_driven(driven_axle: str, gyro_scale: float = 1.0) -> int:
    """22 m/s, 2 s straight, then a 0.5 Hz lane change (r 0 -> +0.25 -> -0.25 -> 0 rad/s, ~0.55 g),
    then straight. The front wheels steer (delta = L r / vx; each reads its x speed x cos(delta)
    plus the lateral term (vy + lf r) sin(delta)) and roll free; the rear axle drives the car and
    slips, its inner wheel more than its outer (random seed 21: rear wheels' yaw rate 0.10 rad/s
    for a true 0.25), so their difference shows 0.4 r; ay's witness 0.15 s late (the sideslip's
    build-up). Returns the gyro's isolation events."""
    lr, lf, vx, w, t0 = 1.5, 1.25, 22.0, math.pi, 2.0
    det = fd.FaultDetector(DT, TRACK, lf, driven_axle, lambda fl, fr, rl, rr: 0.5 * (fl + fr), lr_m=lr)
    x = _state(vx)
    r = lambda t: 0.25 * math.sin(w * (t - t0)) if t0 <= t <= t0 + 2.0 else 0.0  # noqa: E731
    rdot = lambda t: 0.25 * w * math.cos(w * (t - t0)) if t0 <= t <= t0 + 2.0 else 0.0  # noqa: E731
    for j in range(int(6.0 / DT)):
        t = j * DT
        rt = r(t)
        delta = (lf + lr) * rt / vx
        c, s = math.cos(delta), math.sin(delta)
        fl, fr = (vx - rt * TRACK / 2) * c + lf * rt * s, (vx + rt * TRACK / 2) * c + lf * rt * s
        slip = 0.18 + 0.3 * abs(rt) * TRACK  # both wheels spin faster than they roll; the inner more
        rl = vx - rt * TRACK / 2 + slip + 0.3 * rt * TRACK
        rr = vx + rt * TRACK / 2 + slip - 0.3 * rt * TRACK
        det.step(j, (fl, fr, rl, rr), True, gyro_scale * rt, 0.0, r(t - 0.15) * vx + lr * rdot(t),
                 True, x, 1e-4, 4e-4, delta, gyro_scale * rdot(t - 0.06))
    return det.events["yaw_rate"]


def test_drive_slip_of_the_rear_axle_is_not_a_gyro_fault_on_a_rear_driven_car():
    """The yaw witness is the free-rolling axle (the front one of a rear-driven car, steering-
    corrected): its wheels' difference is kinematic. review32 took the rear wheels' drive slip
    (0.4 r) for a gyro scale at the turn-in, with ay / vx lagging, and isolated a good gyro; a
    scaled gyro is still isolated on the front wheels."""
    assert _lane_change_rear_driven("rear") == 0
    assert _lane_change_rear_driven("rear", 1.3) >= 1
    assert _lane_change_rear_driven("rear", 0.7) >= 1
    # the same wheels on a car whose front axle drives: the rear pair is its witness, and it says
    # the gyro is off (the inputs are physically the rear-driven car's: the witness choice matters)
    assert _lane_change_rear_driven("front") >= 1


def test_front_pair_at_large_steering_angles_does_not_judge_the_gyro():
    """A rear-driven car ploughing at the front axle's limit (random seed 131, mu 0.23): 11.5 m/s,
    r 0.14 rad/s, the driver winds the road-wheel angle up to 0.54 rad. Ackermann geometry steers
    the inner front wheel ~delta^2 T / L more than the outer, so the front pair's difference over
    cos(delta) reads several times r (seed 131: 0.77 rad/s). b1ecab4, without the limit, isolated
    the gyro here (seed 131: suspect, its heading std widened to 20 deg and GNSS re-aligned it
    through a wrong sideslip, 424 rows beyond 3 sigma); beyond FRONT_YAW_ACKERMANN_RADPS the pair does not judge, and the rear pair
    (rolling kinematically here) is what would substitute."""
    lr, lf, vx, r, T = 1.5, 1.25, 11.5, 0.14, TRACK
    L = lf + lr
    det = fd.FaultDetector(DT, T, lf, "rear", lambda fl, fr, rl, rr: 0.5 * (fl + fr), lr_m=lr)
    x = _state(vx)
    suspect = 0
    for j in range(int(4.0 / DT)):
        t = j * DT
        delta = min(0.06 + 0.3 * max(t - 1.0, 0.0), 0.54)
        cot = 1.0 / math.tan(delta)
        d_in, d_out = math.atan(1.0 / (cot - T / (2 * L))), math.atan(1.0 / (cot + T / (2 * L)))
        w = lf * r  # vy ~ 0
        fl = (vx - r * T / 2) * math.cos(d_in) + w * math.sin(d_in)
        fr = (vx + r * T / 2) * math.cos(d_out) + w * math.sin(d_out)
        rl, rr = vx - r * T / 2, vx + r * T / 2
        det.step(j, (fl, fr, rl, rr), True, r, 0.0, r * vx, True, x, 1e-4, 4e-4, delta, 0.0)
        suspect += det.yaw_suspect
    assert det.events["yaw_rate"] == 0
    assert suspect == 0
    assert abs(det.r_wheels - r) < 0.01  # the rear pair's, not the front's
