"""Accelerometer x and y mapped to each other's signal (issue 7, wrong configurations; of 27
single config mistakes in tools/probe_wrong_config.py the most harmful to sideslip and heading, and
unlogged): estimator/axis_swap_check.py holds each axis against its own witness (the wheels' dv/dt,
the gyro's r vx) and, once they say swapped, names both keys and withholds sideslip, heading and
velocity.

Before the check (integ26, 861cfa8), with ``accel_x`` and ``accel_y`` exchanged and nothing
logged: on the 15 m circle (lowspeed_r15) the heading was promised up to 9.6 deg off (2334 valid
rows beyond 3 sigma) and sideslip 3.6 deg (227 rows); in dlc_dry's acceleration the heading 6.8
deg (100 rows); a flying start at 30 m/s in a 150 m corner 4.1 deg (80 rows)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from ecu_daemon.estimator.axis_swap_check import SWAP_EVERY, AxisSwapCheck
from ecu_daemon.sim.scenario import SCENARIOS, Scenario

from config_replay import replay_edited, simulated_drive

LOW = Scenario("lowspeed_r15", "low_speed", params=(("radius_m", 15.0), ("v_max", 10.0)))  # 75 s
SAID = "[inputs.accel_x] / [inputs.accel_y]"


def _swap(c):
    ix, iy = c["inputs"]["accel_x"], c["inputs"]["accel_y"]
    ix["signal"], iy["signal"] = iy["signal"], ix["signal"]


def _beyond_3_sigma(e, t):
    """Valid rows beyond 3 published std: {quantity: boolean row mask}."""
    out = {}
    for q, tc, ec, vc, sc in (("sideslip", "sideslip_rad", "sideslip_rad", "sideslip_valid", "sideslip_std_rad"),
                              ("heading", "heading_rad", "heading_rad", "heading_valid", "heading_std_rad"),
                              ("vx", "vx_mps", "vx_mps", "velocity_valid", "vx_std_mps")):
        ref = np.interp(e["t"], t["t"], np.unwrap(t[tc]) if q != "vx" else t[tc])
        err = e[ec] - ref
        if q != "vx":
            err = (err + math.pi) % (2 * math.pi) - math.pi
        out[q] = e[vc].astype(bool) & (np.abs(err) > 3.0 * e[sc])
    return out


@pytest.fixture(scope="module")
def low_drive(tmp_path_factory):
    return simulated_drive(tmp_path_factory, "axes_low", LOW)


@pytest.fixture(scope="module")
def dlc_drive(tmp_path_factory):
    return simulated_drive(tmp_path_factory, "axes_dlc", SCENARIOS["dlc_dry"])


def test_swapped_axes_on_a_circle_are_named_and_not_promised_after_the_first_turn_in(low_drive):
    """The first 0.9 s of the first turn-in are the evidence (a 0.6 s window, five votes): the
    sideslip there is the one thing still promised wrong; the heading never is."""
    lines: list[str] = []
    e, t = replay_edited(low_drive, _swap, "swapped", log_level="warning", stderr=lines)
    bad = _beyond_3_sigma(e, t)
    assert not bad["heading"].any(), int(bad["heading"].sum())
    turn_in = t["t"][np.argmax(np.abs(t["yaw_rate_radps"]) > 0.1)]
    late = e["t"] > turn_in + 1.0
    for q in ("sideslip", "vx"):
        assert not (bad[q] & late).any(), (q, int((bad[q] & late).sum()))
    assert not e["sideslip_valid"][late].any() and not e["heading_valid"][late].any()
    said = [ln for ln in lines if SAID in ln and "swapped" in ln]
    assert len(said) == 1, lines


def test_swapped_axes_in_a_lane_change_drive_are_found_in_the_acceleration(dlc_drive):
    """dlc_dry accelerates at 2.2 m/s^2 before its lane change: the longitudinal witness alone
    tells the two mappings apart, before the heading is aligned from a wrong sideslip."""
    e, t = replay_edited(dlc_drive, _swap, "swapped")
    bad = _beyond_3_sigma(e, t)
    assert not bad["heading"].any() and not bad["sideslip"].any()
    assert not e["heading_valid"].any()


@pytest.mark.parametrize("which", ["low", "dlc", "demo"])
def test_right_axes_say_nothing_and_keep_their_promise(low_drive, dlc_drive, demo_drive, which):
    drive = {"low": low_drive, "dlc": dlc_drive, "demo": demo_drive}[which]
    lines: list[str] = []
    e, t = replay_edited(drive, lambda c: None, "right", log_level="warning", stderr=lines)
    assert not [ln for ln in lines if SAID in ln], lines
    bad = _beyond_3_sigma(e, t)
    assert not bad["heading"].any() and not bad["sideslip"].any()
    assert e["heading_valid"].any() and e["sideslip_valid"].any() and e["velocity_valid"].any()


# --- the check itself, on synthetic means (dt 6 ms)
DT = 0.006


def _run(chk, seconds, v0, dvdt, ax, ay, rv, k0=0):
    """Feed ``seconds`` of a constant acceleration (wheels' dv/dt), accelerometer and r vx (vx 10)."""
    said = 0
    n = int(round(seconds / DT))
    for i in range(n):
        k = k0 + i
        said += chk.step(k, v0 + dvdt * i * DT, ax, ay, rv / 10.0, 10.0)
    return said, k0 + n


def test_a_steady_corner_as_mapped_is_never_swapped_and_a_swapped_one_is():
    ok = AxisSwapCheck(DT)
    said, _ = _run(ok, 5.0, 10.0, 0.0, 0.2, 6.0, 6.0)
    assert not ok.swapped and said == 0 and ok.windows[0] > 0 and ok.windows[1] == 0
    bad = AxisSwapCheck(DT)
    said, _ = _run(bad, 1.0, 10.0, 0.0, 6.0, 0.2, 6.0)
    assert bad.swapped and said == 1  # within the window (0.6 s) and five votes (0.3 s)


def test_a_turn_as_hard_as_the_acceleration_tells_nothing():
    """At 45 deg the two mappings predict the same: no vote either way."""
    chk = AxisSwapCheck(DT)
    _run(chk, 3.0, 10.0, 3.0, 3.0, 3.0, 3.0)
    assert chk.windows == [0, 0] and not chk.swapped


def test_bias_grade_and_bank_within_tolerance_do_not_vote_swapped():
    chk = AxisSwapCheck(DT)
    # accelerating 2 m/s^2 up a 10 % grade (ax reads 3) on a 6 % bank (ay 0.6)
    _run(chk, 5.0, 5.0, 2.0, 3.0, 0.6, 0.0)
    assert chk.windows[1] == 0 and not chk.swapped


def test_a_right_mapping_seen_again_takes_the_verdict_back_and_a_gap_restarts_the_window():
    chk = AxisSwapCheck(DT)
    _, k = _run(chk, 1.0, 10.0, 0.0, 6.0, 0.2, 6.0)
    assert chk.swapped
    _, k = _run(chk, 3.0, 10.0, 0.0, 0.0, 0.0, 0.0, k)  # a straight: no evidence, the verdict stands
    assert chk.swapped
    chk.step(k, math.nan, 0.0, 0.0, 0.0, 10.0)  # wheels out: the window restarts
    assert all(x is None for x in chk._ring)
    _run(chk, 1.5, 10.0, 0.0, 0.2, 6.0, 6.0, k + SWAP_EVERY)
    assert not chk.swapped
