"""Heading on a low-speed handling drive (issue 7): aligned from the launch's straight course, not
from the first course of the circle.

The suite's low-speed drives launch straight to 5 m/s and turn into a 10-25 m circle at once. With
the alignment waiting for 5 m/s, the first course came from inside the circle, where it is heading
plus sideslip plus yaw rate times the latency's error (0.5 rad/s x 0.15 s = 4.3 deg before the
latency is identified): the heading std stayed 2-4 deg for the whole circle and the heading became
valid only after it (lowspeed_r10: 42.2 s after the first good fix above 5 m/s; r15 11.4 s; r25 3.8 s,
main 2c22dbd). On the straight at 3-5 m/s the course is the heading (r = 0: no latency term, the
sideslip ~0), good to sigma_v / v (the alignment's variance says so), so the heading is known and
valid before the circle and the gyro carries it in.

Whole simulated drives through the suite's own path (simulate -> files -> replay -> evaluate).
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from ecu_daemon.evaluate import ESTIMATE_REQUIRED, read_csv
from ecu_daemon.sim.scenario import Scenario
from ecu_daemon.sim.suite import SUITE
from ecu_daemon.suite import run_case

from config_replay import replay_edited, simulated_drive

CASES = {c.name: c for c in SUITE}


@pytest.fixture(scope="module")
def out(tmp_path_factory):
    return tmp_path_factory.mktemp("low_speed_heading")


def test_heading_on_a_tight_low_speed_circle_is_valid_from_the_launch_and_keeps_its_promise(out):
    """lowspeed_r10 (a 10 m circle at 5-8 m/s, 0.84 rad/s): heading valid within 3 s of the first
    good fix above 5 m/s (main 2c22dbd: 42.2 s), and every valid row within 3 sigma and 5 deg."""
    row = run_case(CASES["lowspeed_r10"], out)
    assert not any(f.startswith("error") for f in row["failed"]), row["failed"]
    assert row["heading_time_to_valid_after_fix_s"] <= 3.0, row["heading_time_to_valid_after_fix_s"]
    assert row["heading_coverage_3sigma"] >= 0.99, row["heading_coverage_3sigma"]
    assert row["heading_worst_valid_deg"] <= 5.0, row["heading_worst_valid_deg"]
    est = read_csv(out / "lowspeed_r10" / "estimate.csv", ESTIMATE_REQUIRED, "estimate CSV")
    truth = read_csv(out / "lowspeed_r10" / "truth.csv", ("t", "speed_mps", "yaw_rate_radps"), "truth CSV")
    # aligned on the straight, below 5 m/s and before the turn-in (the first row turning at 0.1 rad/s)
    t = est["t"]
    speed = np.interp(t, truth["t"], truth["speed_mps"])
    r = np.interp(t, truth["t"], truth["yaw_rate_radps"])
    valid = est["heading_valid"] > 0.5
    first = int(np.argmax(valid))
    assert valid.any() and speed[first] < 5.0 and abs(r[first]) < 0.1, (speed[first], r[first])
    # and the heading std it starts the circle with is the straight's, not the circle's latency term
    turn_in = int(np.argmax(np.abs(r) > 0.1))
    assert est["heading_std_rad"][turn_in] < math.radians(1.5), math.degrees(est["heading_std_rad"][turn_in])


def test_no_low_speed_alignment_while_reversing(tmp_path_factory):
    """The 3-5 m/s alignment is for driving forwards (gnss_velocity.align_speed_ok). The reversing
    drive (10 m/s, stop, back at 4 m/s in a gentle curve, stop, forward) with the yaw rate's sign
    configured wrong: the heading diverges while reversing and is dropped (34-38 s). Allowed to align
    again from a course while reversing at 4 m/s, it did so 15-18 deg off with a 1.4 deg std and was
    valid for 8 s (41-49.6 s: 2081 heading rows beyond 3 sigma instead of 649). The rows of 30-34 s
    are the divergence before the drop, as on main (noticed, not this rule's)."""
    d = simulated_drive(tmp_path_factory, "reversing", Scenario("reversing", "reversing"))

    def edit(c):
        c["inputs"]["yaw_rate"]["scale"] = -c["inputs"]["yaw_rate"].get("scale", 1.0)
    e, t = replay_edited(d, edit, "yaw_sign")
    psi = np.interp(e["t"], t["t"], np.unwrap(t["heading_rad"]))
    err = np.abs((e["heading_rad"] - psi + math.pi) % (2 * math.pi) - math.pi)
    bad = e["heading_valid"].astype(bool) & (err > 3.0 * e["heading_std_rad"])
    after_drop = e["t"] - t["t"][0] >= 36.0
    assert not (bad & after_drop).any(), (np.sum(bad & after_drop), np.degrees(err[bad & after_drop].max()))
