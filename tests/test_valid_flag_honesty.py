"""Valid flags and standard deviations that do not lie (issue 7, "honest validity"): each test
reproduces a case where the published std left out an error the data could not rule out."""
from __future__ import annotations

import math

import numpy as np

from ecu_daemon import config as config_mod
from ecu_daemon.estimator import Estimator
from ecu_daemon.evaluate import read_csv
from ecu_daemon.samples import INPUT_INDEX, InputSample
from ecu_daemon.io.state_store import load_state
from ecu_daemon.suite import SUITE, run_case


def test_restart_mid_corner_publishes_the_latency_heading_error_from_the_first_fix(tmp_path):
    """The suite's restart 8 s into a steady 11.5 deg/s corner, with a state file whose latency is
    still at its 0.15 s prior: a latency error dd turns every course by r dd, the same on every fix,
    so the published heading std holds |r| x latency std from the first aligned row (it started at
    0 and built up over seconds, publishing 1.35 deg where the latency alone is worth 1.7)."""
    row = run_case({c.name: c for c in SUITE}["restart_flying_30_r150"], tmp_path)
    assert not any(f.startswith("error") for f in row["failed"]), row["failed"]
    d = tmp_path / "restart_flying_30_r150"
    delay_std = load_state(d / "state.json")["gnss_delay_std_s"]
    est = read_csv(d / "estimate.csv", ("t", "heading_std_rad", "yaw_rate_radps"), "estimate")
    aligned = est["heading_std_rad"] < math.radians(90.0)
    t_align = est["t"][aligned][0]
    first = aligned & (est["t"] <= t_align + 3.0)
    turn = np.abs(est["yaw_rate_radps"][first]) * delay_std
    assert turn.max() > math.radians(1.5)  # the case does turn: the term matters
    short = est["heading_std_rad"][first] < 0.9 * turn
    assert not short.any(), (est["t"][first][short][:3], np.degrees(est["heading_std_rad"][first][short][:3]))


def _can(est: Estimator, t: float, wheel: float, ax: float) -> list:
    for name in ("wheel_speed_fl", "wheel_speed_fr", "wheel_speed_rl", "wheel_speed_rr"):
        est.push_input(InputSample(t, INPUT_INDEX[name], wheel))
    for name, v in (("steering_wheel_angle", 0.0), ("yaw_rate", 0.0), ("accel_x", ax), ("accel_y", 0.0)):
        est.push_input(InputSample(t, INPUT_INDEX[name], v))
    return est.advance_to(t)


def test_moving_off_while_the_wheels_still_read_zero_is_not_a_standstill():
    """Wheel-speed sensors give no pulses below ~0.15 m/s: a car moving off at 2 m/s^2 reads 0 on
    every wheel for its first ~80 ms while the accelerometer reads its acceleration. The
    zero-velocity update (std 0.01 m/s) held vx at 0 then, 0.13 m/s off and valid (dlc_dry at
    5.03-5.09 s); the accelerometer outside the gate of its bias at rest ends the standstill."""
    est = Estimator(config_mod.Config())
    t, rows = 100.0, []
    for _ in range(300):  # 3 s at rest: the standstill learns the accelerometer bias
        rows += _can(est, t, 0.0, 0.0)
        t += 0.01
    assert rows[-1].status & 1  # STATUS_STANDSTILL
    t_go, moving = t, []
    for _ in range(10):  # 2 m/s^2 from rest; the wheels still read 0
        moving += _can(est, t, 0.0, 2.0)
        t += 0.01
    for e in moving:
        v = 2.0 * max(e.t - t_go, 0.0)
        assert not e.velocity_valid or abs(e.vx_mps - v) <= 3.0 * e.vx_std_mps + 0.025, (e.t - t_go, e.vx_mps, v)
    assert not moving[-1].status & 1


def _fault_window(tmp_path, name: str, quantity: str, col: str, truth_col: str, wrap: bool):
    """Run suite case ``name``; (errors, stds, valid) of ``quantity`` over its fault's 5 s."""
    row = run_case({c.name: c for c in SUITE}[name], tmp_path)
    assert not any(f.startswith("error") for f in row["failed"]), row["failed"]
    d = tmp_path / name
    truth = np.genfromtxt(d / "truth.csv", delimiter=",", names=True)
    est = np.genfromtxt(d / "estimate.csv", delimiter=",", names=True)
    t = est["t"]
    ref = np.interp(t, truth["t"], np.unwrap(truth[truth_col]) if wrap else truth[truth_col])
    err = est[col] - ref
    if wrap:
        err = (err + math.pi) % (2 * math.pi) - math.pi
    sel = (t >= truth["t"][0] + 22.0) & (t <= truth["t"][0] + 27.0)  # FAULT_T_S, FAULT_S of sim/suite.py
    std_col = col.replace("_rad", "_std_rad").replace("_mps", "_std_mps")
    return err[sel], est[std_col][sel], est[f"{quantity}_valid"][sel] > 0.5


def test_gyro_offset_heading_std_covers_the_drift_before_the_vote(tmp_path):
    """A 5 deg/s gyro offset in a lane change: the yaw test fails a filter lag (~0.2 s) after the
    fault began, and the heading drifted 1 deg meanwhile; the std grew only from the failure on
    (1.17 deg off with a 0.36 deg std, valid). What the gyro integrated against the wheels over
    that lag now goes into the heading std at the first failure."""
    err, std, valid = _fault_window(tmp_path, "fault_yaw_rate_offset", "heading", "heading_rad", "heading_rad", True)
    assert valid.any()
    # the steps before the fast test fails: nothing can tell before it. 10 rows to 3.6 sigma before this
    # rule; 1 at 3.06 while a 5 s low-pass of |r| x latency std stood for the heading's latency error
    # (it widened the std by accident in the lane change); 4 to 3.3 since that term follows the filter's
    # gains (latency_sensitivity.py). Over the whole drive 99.93 % of valid heading rows are within 3
    # sigma; here, in the 0.28 s the heading stays valid, the last 4 steps before the vote are not.
    z = np.abs(err[valid]) / std[valid]
    assert np.sum(z > 3.0) <= 4 and z.max() < 3.5
    assert np.degrees(np.abs(err[valid]).max()) < 1.5  # 2.35 deg before (valid until the isolation)


def test_noisy_rear_wheel_before_its_isolation_keeps_vx_within_3_sigma(tmp_path):
    """A rear wheel (fused pair of a front-driven car) with 1 m/s of noise at 22 m/s: inside the
    vote's slip tolerance (0.5 m/s + 3 %) it is fused for ~0.9 s before the vote isolates it, and
    the pair's mean carried half of it into vx (0.38 m/s off with a 0.07 m/s std, valid). The
    pair's own disagreement beyond its configured noise now widens the wheel measurement."""
    err, std, valid = _fault_window(tmp_path, "fault_wheel_speed_rl_noisy", "velocity", "vx_mps", "vx_mps", False)
    assert valid.all()
    assert np.all(np.abs(err) <= 3.0 * std), (np.abs(err) - 3 * std).max()


def test_scaled_gyro_is_isolated_in_the_corners_and_only_during_its_fault(tmp_path):
    """A gyro reading 1.3 times the truth disagrees with the wheels' yaw rate and ay / vx by 0.3 r,
    inside the level tests' tolerances (they grow with |r|): it was never isolated, and the heading
    was valid 2.4 deg off. Both witnesses' disagreement grows with the yaw rate (a slope of 0.3,
    against a few % from track, radius or roll): it is isolated in the corners of its fault, and
    never outside it."""
    name = "fault_yaw_rate_scaled"
    row = run_case({c.name: c for c in SUITE}[name], tmp_path)
    assert not any(f.startswith("error") for f in row["failed"]), row["failed"]
    truth = np.genfromtxt(tmp_path / name / "truth.csv", delimiter=",", names=True)
    est = np.genfromtxt(tmp_path / name / "estimate.csv", delimiter=",", names=True)
    t = est["t"] - truth["t"][0]
    iso = (est["status"].astype(int) & (1 << 9)) > 0  # STATUS_YAW_RATE_ISOLATED
    assert iso[(t >= 22.0) & (t <= 27.0)].any()
    assert not iso[(t < 22.0) | (t > 28.0)].any()
    ref = np.interp(est["t"], truth["t"], np.unwrap(truth["heading_rad"]))
    err = np.degrees(np.abs((est["heading_rad"] - ref + math.pi) % (2 * math.pi) - math.pi))
    valid = est["heading_valid"] > 0.5
    assert err[valid].max() < 1.5
