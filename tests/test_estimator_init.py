"""Initialisation in any state, divergence recovery and honest validity (issue 7 items 1 and 3).

Drives are simulated and cut so that the replay starts with the car already at speed (see
``flying_start.py``), the wheel-speed frames 0.5 s after everything else (a late ABS, the order
that left the old filter at vx = 0 while the wheels said 30 m/s). A valid flag is a promise: every
test checks that the rows flagged valid are right (worst error, and at least 99 % within 3
reported sigma) as well as how soon the flags come up.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from ecu_daemon import config as config_mod
from ecu_daemon.estimator import Estimator
from ecu_daemon.evaluate import read_csv
from ecu_daemon.estimator.core import VX_STD_VALID
from ecu_daemon.estimator.kinematic import PSI, VX
from ecu_daemon.replay import run_replay
from ecu_daemon.samples import INPUT_INDEX, GnssSample, InputSample
from ecu_daemon.sim import SCENARIOS
from ecu_daemon.sim.scenario import T0

import flying_start as fs

DEG = math.pi / 180.0


@pytest.fixture(scope="module")
def drives(tmp_path_factory):
    root = tmp_path_factory.mktemp("flying")
    cache: dict = {}

    def get(key, make):
        if key not in cache:
            cache[key] = fs.write_drive(make(), root / key)
        return cache[key]
    return get


def _promise_kept(r: dict) -> None:
    b, h = r["sideslip"], r["heading"]
    assert b["max_err_valid_deg"] <= 2.0, b
    assert h["max_err_valid_deg"] <= 5.0, h
    assert b["within_3sigma_valid"] >= 0.99, b
    assert h["within_3sigma_valid"] >= 0.99, h
    assert r["vx_max_err_valid"] < 1.0, r


@pytest.mark.parametrize("v, heading, t_cut", [(30.0, 35.0, 35.0), (50.0, 200.0, 40.0)])
def test_flying_start_straight_valid_within_3_s(drives, v, heading, t_cut):
    d = drives(f"s{v:g}", lambda: fs.straight(v, heading, t_at_speed=25.0 if v < 40 else 30.0))
    out, t_gnss = fs.replay_from(d, t_cut, wheels_late_s=0.5)
    r = fs.score(d / "truth.csv", out, t_gnss)
    _promise_kept(r)
    assert r["sideslip"]["time_to_valid_s"] <= 3.0
    assert r["heading"]["time_to_valid_s"] <= 3.0
    assert r["heading"]["fraction_valid_after_10s"] > 0.99


def test_flying_start_mid_corner_never_wrong_while_valid(drives):
    """30 m/s in a 110 m circle (15 deg/s, -2.5 deg sideslip), heading unknown, biases unknown.

    Without learned biases, heading and sideslip trade off in a steady circle (only the course
    is observed), so the flags wait for the data to separate them; what must hold is that they
    never promise what is not there.
    """
    d = drives("c30", lambda: fs.corner(30.0, 110.0, 300.0))
    out, t_gnss = fs.replay_from(d, 35.0, wheels_late_s=0.5)
    r = fs.score(d / "truth.csv", out, t_gnss)
    _promise_kept(r)
    assert r["heading"]["time_to_valid_s"] <= 15.0
    assert r["heading"]["fraction_valid_after_10s"] > 0.8


def test_restart_mid_corner_with_learned_state(drives, tmp_path):
    """A daemon restart mid-corner with its state file: a flying start with good priors (biases,
    wheel scale, latency and its uncertainty), so its flags come up no later than a cold start's."""
    d = drives("c30", lambda: fs.corner(30.0, 110.0, 300.0))
    t_cut = 35.0
    for name in ("drive.log", "drive_gnss.log"):
        with open(d / name, encoding="ascii") as f, open(tmp_path / name, "w", encoding="ascii") as g:
            g.writelines(line for line in f if float(line[1:line.index(")")]) < T0 + t_cut)
    cfg = config_mod.load(d / "config.toml")
    learned = run_replay(cfg, str(tmp_path / "drive.log"), str(tmp_path / "drive_gnss.log"))["learned"]
    assert "yaw_rate_bias_radps" in learned and "gnss_delay_std_s" in learned
    cold, t_gnss = fs.replay_from(d, t_cut)
    warm, _ = fs.replay_from(d, t_cut, tag="restart", learned=learned)
    r_cold = fs.score(d / "truth.csv", cold, t_gnss)
    r = fs.score(d / "truth.csv", warm, t_gnss)
    _promise_kept(r)
    assert r["heading"]["time_to_valid_s"] <= r_cold["heading"]["time_to_valid_s"]
    assert r["heading"]["rms_after_10s_deg"] < r_cold["heading"]["rms_after_10s_deg"]
    assert r["vx_max_err_valid"] < 0.3  # the wheel scale is known at once


def test_restart_mid_corner_after_a_drive_that_taught_the_stiffness(drives):
    """The state file of a double lane change (the car's stiffness learned from its transients,
    with the std it was learned to) restores a flying start mid-corner: in a steady corner only the
    single-track model observes sideslip, so a cold start waits for the corner to end (its 40 %
    stiffness prior is honest for a car nobody measured); with the learned stiffness and its
    uncertainty from the file the flags come up within 3 s of the first fix, and are right."""
    dlc = drives("dlc", lambda: SCENARIOS["dlc_dry"])
    cfg = config_mod.load(dlc / "config.toml")
    learned = run_replay(cfg, str(dlc / "drive.log"), str(dlc / "drive_gnss.log"))["learned"]
    assert learned["kappa_r_std"] < 0.2 * learned["kappa_r"]
    d = drives("c30r200", lambda: fs.corner(30.0, 200.0, 300.0))  # 0.46 g: where the drive learned the law
    assert config_mod.load(d / "config.toml").vehicle == cfg.vehicle  # the same car
    cold, t_gnss = fs.replay_from(d, 35.0)
    warm, _ = fs.replay_from(d, 35.0, tag="taught", learned=learned)
    r_cold = fs.score(d / "truth.csv", cold, t_gnss)
    r = fs.score(d / "truth.csv", warm, t_gnss)
    _promise_kept(r)
    assert r_cold["sideslip"]["time_to_valid_s"] > 3.0
    assert r["sideslip"]["time_to_valid_s"] <= 3.0
    assert r["heading"]["time_to_valid_s"] <= 3.0


def test_latency_identified_from_a_fast_start(drives):
    """Start at 25 m/s with a latency prior 0.2 s short (truth 0.4 s): identified within 0.03 s
    after 30 s of driving with speed changes, mid-corner, and no heading promised meanwhile."""
    d = drives("c30", lambda: fs.corner(30.0, 110.0, 300.0))
    cfg = config_mod.load(d / "config.toml")
    cfg.gnss.delay_s = 0.2
    out, t_gnss = fs.replay_from(d, 20.0, tag="prior0.2", cfg=cfg)
    r = fs.score(d / "truth.csv", out, t_gnss)
    assert r["delay_err_after_30s"] < 0.03
    _promise_kept(r)


def test_latency_steady_without_information(drives):
    """Constant speed gives no timing information: the delay must not wander from its prior."""
    d = drives("s30const", lambda: fs.straight(30.0, 35.0, speed_changes=False))
    cfg = config_mod.load(d / "config.toml")
    cfg.gnss.delay_s = 0.3
    out, _ = fs.replay_from(d, 28.0, tag="steady", cfg=cfg)  # 42 s at a constant 30 m/s
    est = read_csv(out, ("t", "gnss_delay_s"), "estimate")
    assert np.all(est["gnss_delay_s"] == 0.3)


def test_vx_honest_while_the_latency_prior_is_wrong(drives):
    """Start-up acceleration with GNSS latency 0.1 s and a 0.4 s prior: a GNSS speed 0.45 m/s off
    on every fix of the acceleration. It used to teach a wheel scale of 1.15 (truth 1.015) and
    put vx 0.9 m/s off, flagged valid (vx within 3 sigma on 85 % of the valid rows)."""
    d = drives("lat0.1", lambda: SCENARIOS["straight"].with_(gnss_latency_s=0.1))
    cfg = config_mod.load(d / "config.toml")
    cfg.gnss.delay_s = 0.4
    out, _ = fs.replay_from(d, 0.0, tag="prior0.4", cfg=cfg)
    est = read_csv(out, ("t", "vx_mps", "vx_std_mps", "velocity_valid", "wheel_scale"), "estimate")
    truth = read_csv(d / "truth.csv", ("t", "vx_mps"), "truth")
    err = est["vx_mps"] - np.interp(est["t"], truth["t"], truth["vx_mps"])
    valid = est["velocity_valid"] > 0.5
    assert np.mean(np.abs(err[valid]) <= 3 * est["vx_std_mps"][valid]) >= 0.99
    assert est["wheel_scale"].max() < 1.05


# ------------------------------------------------------------------------------------------ units
def _cfg():
    return config_mod.Config()


def _feed(est: Estimator, t: float, speed: float, yaw_rate: float = 0.0, half: float = 0.0) -> list:
    """One sample of every input at ``t``; the left wheels ``half`` slower, the right ones faster."""
    for name, v in (("wheel_speed_fl", speed - half), ("wheel_speed_fr", speed + half),
                    ("wheel_speed_rl", speed - half), ("wheel_speed_rr", speed + half)):
        est.push_input(InputSample(t, INPUT_INDEX[name], v))
    est.push_input(InputSample(t, INPUT_INDEX["steering_wheel_angle"], 0.0))
    est.push_input(InputSample(t, INPUT_INDEX["yaw_rate"], yaw_rate))
    est.push_input(InputSample(t, INPUT_INDEX["accel_x"], 0.0))
    est.push_input(InputSample(t, INPUT_INDEX["accel_y"], yaw_rate * speed))
    return est.advance_to(t)


def _feed_turning(est: Estimator, t: float, speed: float, yaw_rate: float) -> list:
    """As :func:`_feed`, each wheel at its own speed in the turn: ``speed -/+ yaw_rate x track / 2``
    (ISO 8855: the left wheels inside a left turn), what the gyro's check of the wheels' scale reads."""
    return _feed(est, t, speed, yaw_rate, 0.5 * est.cfg.vehicle.track_m * yaw_rate)


def _lane_change(est: Estimator, t: float, speed: float, seconds: float = 3.0) -> tuple[float, list]:
    """Straight for a second, then a lane change after another (0.3 rad/s peak, 2 s a period):
    enough turning for the gyro to confirm the wheels' scale (wheel_yaw_check.py)."""
    rows = []
    for j in range(int(round(seconds * 100))):
        tj = j * 0.01
        r = 0.3 * math.sin(math.pi * (tj - 1.0)) if tj >= 1.0 else 0.0
        rows += _feed_turning(est, t, speed, r)
        t += 0.01
    return t, rows


def test_waits_for_the_wheels_then_starts_at_their_speed():
    """Without GNSS yet, the wheels' velocity is published at once, and promised once a witness
    has checked their scale (here the gyro, in the first lane change): before, its std covers any
    unit error, more than the frame's VX_STD carries, and it is not promised."""
    est = Estimator(_cfg())
    t = 100.0
    for _ in range(20):  # IMU only: no velocity to start from, nothing valid
        est.push_input(InputSample(t, INPUT_INDEX["yaw_rate"], 0.0))
        est.push_input(InputSample(t, INPUT_INDEX["accel_x"], 0.0))
        est.push_input(InputSample(t, INPUT_INDEX["accel_y"], 0.0))
        for e in est.advance_to(t):
            assert not (e.velocity_valid or e.sideslip_valid or e.heading_valid)
        t += 0.01
    assert not est.initialized
    out = _feed(est, t, 31.0)
    assert est.initialized
    assert out[-1].vx_mps == pytest.approx(31.0, abs=0.1)
    assert not out[-1].heading_valid
    assert out[-1].heading_std_rad > 1.0  # no heading yet, and it says so
    # unchecked: a std that covers a unit error (4/3 of the speed), not promised (not on the frame)
    assert not out[-1].velocity_valid and out[-1].vx_std_mps > 31.0
    t, rows = _lane_change(est, t + 0.01, 31.0)
    assert est.wheel_scale_check.confirmed and est.wheel_yaw.confirmed
    valid = np.array([e.velocity_valid for e in rows])
    assert valid[-1] and rows[-1].vx_mps == pytest.approx(31.0, abs=0.2)
    # promised from the confirmation on (in the lane change's second half: 20 deg of turning), not
    # before, and only with a std the frame carries
    first = int(np.argmax(valid))
    assert valid[first:].all() and 2.0 < rows[first].t - rows[0].t < 3.0
    assert all(e.vx_std_mps <= VX_STD_VALID for e in rows if e.velocity_valid)


def test_diverged_velocity_is_reinitialised_from_the_wheels():
    """A filter whose vx has gone (vx -24 m/s, heading 150 deg off) while the wheels say 30 m/s
    re-initialises instead of publishing it, and does not call the diverged rows valid."""
    est = Estimator(_cfg())
    t, _ = _lane_change(est, 97.0, 30.0)  # the wheels' scale confirmed by the gyro
    assert est.wheel_scale_check.confirmed
    for _ in range(100):
        _feed(est, t, 30.0)
        t += 0.01
    h = est.hist
    i = h.slot(h.last)
    h.X[i, VX] = -24.0
    h.X[i, PSI] = (h.X[i, PSI] + 150 * DEG) % (2 * math.pi)
    rows = []
    for _ in range(150):
        rows += _feed(est, t, 30.0)
        t += 0.01
    assert est.resets == 1
    vx = np.array([e.vx_mps for e in rows])
    valid = np.array([e.velocity_valid for e in rows])
    assert np.all(np.abs(vx[valid] - 30.0) < 1.0)
    assert rows[-1].velocity_valid and abs(rows[-1].vx_mps - 30.0) < 0.2  # the check outlives a reset


DRIVE_START = 100.0


def _drive_straight(est: Estimator, t0: float, seconds: float, heading_deg: float, speed: float = 25.0,
                    gnss_factor=lambda t: 1.0, delay: float = 0.4) -> list:
    """Straight line at ``speed``: CAN at 100 Hz, GNSS at 5 Hz reporting ``delay`` s late."""
    rows = []
    c, s = math.cos(heading_deg * DEG), math.sin(heading_deg * DEG)
    n = int(round(seconds * 100))
    for j in range(n):
        t = t0 + j * 0.01
        if j % 20 == 0 and t - delay >= DRIVE_START:
            f = gnss_factor(t)
            est.push_gnss(GnssSample(t, f * speed * c, f * speed * s, 0.1, 3, True, 12, "ubx"))
        rows += _feed(est, t, speed)
    return rows


def _heading_errors(rows, heading_deg):
    return np.array([abs((e.heading_rad - heading_deg * DEG + math.pi) % (2 * math.pi) - math.pi) / DEG
                     for e in rows])


def test_gnss_glitch_is_not_accepted_after_a_run_of_rejections():
    """GNSS velocity tripled for 5 s disagrees with the wheels: rejected throughout (the old
    re-alignment accepted it after 10 rejections and learned a wheel scale of ~1.4)."""
    est = Estimator(_cfg())
    rows = _drive_straight(est, 100.0, 20.0, 60.0)
    assert rows[-1].heading_valid
    glitch = _drive_straight(est, 120.0, 5.0, 60.0, gnss_factor=lambda t: 3.0)
    after = _drive_straight(est, 125.0, 10.0, 60.0)
    for e in glitch + after:
        assert abs(e.wheel_scale - 1.0) < 0.01
        assert abs(e.vx_mps - 25.0) < 0.3
    err = _heading_errors(glitch + after, 60.0)
    valid = np.array([e.heading_valid for e in glitch + after])
    assert np.all(err[valid] < 2.0)
    assert after[-1].heading_valid and after[-1].gnss_fused > glitch[-1].gnss_fused


def test_diverged_heading_realigns_when_gnss_and_wheels_agree():
    est = Estimator(_cfg())
    rows = _drive_straight(est, 100.0, 20.0, 60.0)
    assert rows[-1].heading_valid
    h = est.hist
    for k in range(h.oldest(), h.last + 1):
        h.X[h.slot(k), PSI] = (h.X[h.slot(k), PSI] + 90 * DEG) % (2 * math.pi)
    after = _drive_straight(est, 120.0, 10.0, 60.0)
    err = _heading_errors(after, 60.0)
    valid = np.array([e.heading_valid for e in after])
    t = np.array([e.t for e in after])
    assert est.realignments == 1
    # valid and wrong only until the first GNSS fix after the jump (0.2 s at 5 Hz) is rejected
    assert np.all(err[valid & (t > 120.21)] < 5.0)
    assert valid[-1] and err[-1] < 1.0


def test_flying_start_in_a_corner_counts_the_latency_heading_error_once(tmp_path):
    """The suite's flying start at 50 m/s in a 6.6 deg/s corner: the heading aligned from a GNSS
    course carries r x (latency error), which ``_estimate`` publishes on top of P (``turn_lp``).
    With the same term also in P at alignment, the std was sqrt 2 times it for the first seconds
    and the heading, right all along, became valid 7.8 s after the first fix instead of 0.3 s."""
    from ecu_daemon.estimator.latency import PRIOR_STD_S
    from ecu_daemon.suite import SUITE, run_case

    row = run_case({c.name: c for c in SUITE}["flying_50_r400r_h300"], tmp_path)
    assert not any(f.startswith("error") for f in row["failed"]), row["failed"]
    assert row["heading_time_to_valid_after_fix_s"] <= 3.0, row["heading_time_to_valid_after_fix_s"]
    # valid early and still right: within 3 sigma, and well within the 5 deg
    assert row["heading_coverage_3sigma"] >= 0.99
    assert row["heading_worst_valid_deg"] < 1.0
    est = read_csv(tmp_path / "flying_50_r400r_h300" / "estimate.csv",
                   ("t", "heading_std_rad", "yaw_rate_radps"), "estimate")
    aligned = est["heading_std_rad"] < math.radians(90.0)
    # counted once, not dropped: the published std holds |r| x latency std (its prior) from the
    # first aligned row on. The yaw rate weaves (|r| x 0.15 s: 0.67-1.89 deg within these 3 s) and
    # the term is that of the aligning course's epoch, tracked through the filter's gains, so each
    # row is held to the turn's weakest |r|: the mean was met or missed (1.13 against 1.18 deg) by
    # the phase at which the first course came, later since fixes measured before the
    # filter's first step are left out (core.BEFORE_START).
    first = aligned & (est["t"] <= est["t"][aligned][0] + 3.0)
    turn = np.min(np.abs(est["yaw_rate_radps"][first])) * PRIOR_STD_S
    assert np.mean(np.abs(est["yaw_rate_radps"][first])) * PRIOR_STD_S > math.radians(0.9)  # the case does turn
    assert np.all(est["heading_std_rad"][first] >= turn)


@pytest.mark.parametrize("latency_s", [0.4, 0.55])
def test_heading_valid_within_1_s_of_a_flying_starts_corner_end(tmp_path, latency_s):
    """The suite's flying start at 6 m/s on a 9 m circle (42 deg/s, 8 deg sideslip) for its first
    12 s, then straight. Mid-corner every course is turned by yaw rate x latency error alike (the
    0.15 s prior: 6 deg), so the heading is rightly invalid; once the corner ends the straight's
    courses correct the heading at the rate the filter's own gains say, and what the heading still
    carries of the latency error is tracked through them (``latency_sensitivity.py``): valid
    within 1 s of the corner's end (a 5 s low-pass of |r| held it invalid 5.9 s). With the receiver
    0.15 s later than the config's prior (0.55 s against 0.4, the 1-sigma error), the heading
    that becomes valid carries part of the 6 deg: it must be inside what the std says."""
    from ecu_daemon.suite import SUITE, run_case
    from ecu_daemon.sim.suite import SuiteCase

    base = {c.name: c for c in SUITE}["flying_6_r9r_h250"]
    sc = base.scenario.with_(gnss_latency_s=latency_s, latency_prior_s=0.4)
    row = run_case(SuiteCase(base.name, base.family, sc), tmp_path)
    assert not any(f.startswith("error") for f in row["failed"]), row["failed"]
    assert row["heading_time_to_valid_after_fix_s"] <= 13.0  # the corner ends 12 s after the start
    assert row["heading_coverage_3sigma"] >= 0.99
    assert row["heading_worst_valid_deg"] < 5.0
    assert row["sideslip_coverage_3sigma"] >= 0.99 and row["sideslip_worst_valid_deg"] < 2.0


def test_wheels_checked_before_a_restart_need_no_new_check():
    """The learned state keeps the fingerprint of the wheel mapping a witness confirmed: a restart
    with the same mapping promises the wheels' velocity from its first step (restart_* of the
    suite waited for a fix); another mapping (a scale edited) is checked afresh."""
    est = Estimator(_cfg())
    t, _ = _lane_change(est, 100.0, 25.0)
    assert est.wheel_scale_check.confirmed
    learned = est.learned_state()
    assert "wheel_mapping_checked" in learned
    again = Estimator(_cfg(), learned)
    assert again.wheel_scale_check.confirmed
    out = _feed(again, 200.0, 25.0) + _feed(again, 200.01, 25.0)
    assert out[-1].velocity_valid and out[-1].vx_std_mps < 1.0
    assert "wheel_mapping_checked" in again.learned_state()  # kept for the next restart
    edited = _cfg()
    edited.inputs["wheel_speed_fl"].scale *= 3.6
    other = Estimator(edited, learned)
    assert not other.wheel_scale_check.confirmed
    out = _feed(other, 200.0, 25.0) + _feed(other, 200.01, 25.0)
    assert not out[-1].velocity_valid
    assert "wheel_mapping_checked" not in other.learned_state()


def test_a_gyro_confirmed_before_a_restart_needs_no_new_confirmation():
    """The learned state keeps the fingerprint of the yaw-rate mapping the gyro-scale gate
    confirmed: a restart with the same mapping (mid-corner: test_cut_starts) rests its heading on
    the gyro at once; another mapping (the sign flipped) is judged afresh, and a gate never
    confirmed records nothing."""
    est = Estimator(_cfg())
    assert "gyro_mapping_checked" not in est.learned_state()
    _lane_change(est, 100.0, 25.0)
    assert est.gyro_gate.confirmed
    learned = est.learned_state()
    assert "gyro_mapping_checked" in learned
    again = Estimator(_cfg(), learned)
    assert again.gyro_gate.confirmed and again.gyro_gate.heading_scale_sd() == 0.0
    assert "gyro_mapping_checked" in again.learned_state()  # kept for the next restart
    flipped = _cfg()
    flipped.inputs["yaw_rate"].scale *= -1.0
    other = Estimator(flipped, learned)
    assert not other.gyro_gate.confirmed
    assert other.learned_state().get("gyro_mapping_checked") != other._gyro_mapping


def test_wheels_taken_as_mapped_without_gnss_are_not_recorded_as_checked():
    """GNSS off: the wheels are taken as mapped (nothing would ever check them), not checked: the
    learned state must not tell a later run with GNSS that they were."""
    cfg = _cfg()
    cfg.gnss.port = ""
    est = Estimator(cfg)
    assert est.wheel_scale_check.confirmed
    _feed(est, 100.0, 20.0)
    _feed(est, 100.01, 20.0)
    assert "wheel_mapping_checked" not in est.learned_state()
