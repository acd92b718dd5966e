"""The course-slide rule must not read a mistimed course as a slide (issue 7, stop 45: COURSE_SLIDE was
off because of tests/test_latency_prior_wrong.py[fixed]).

dlc_dry simulated with a 0.8 s receiver and replayed with ``delay_s = 0.1``, ``estimate_delay = false``:
each course is 0.7 s older than fused, so it carries the heading turned over those 0.7 s. In the lane
changes the yaw rate is ~0 at two fixes 4 s apart while it was 0.3 rad/s 0.7 s before each: the course
less the gyro's turn was 7-10 deg (t 1221-1245 s) where the rule's 3 sigma, the fixed delay's std
(0.01 s, widened to 0.15 s by its monitor) times r's change *at the two fixes*, was 1.7-2 deg. The rule
opened (48 of 215 fixes), the model's pseudo-measurement was loosened, and the mistimed courses moved vy:
the sideslip was published 5-7 deg off at a 0.3-0.65 deg std, valid (86 rows, 1225.2-1241.3 s).
``core.COURSE_SLIDE_TIMING`` counts the latency as far as the data vouch for it
(``timing_trust.along_track_std``: the receiver's range for a fixed delay) and r's largest change between
the instants the two courses may really be from: 3 sigma 26-49 deg there, the rule stays shut.
"""
from __future__ import annotations

import math

import pytest

from ecu_daemon.estimator import core
from ecu_daemon.estimator.fusion.course_slide import CourseSlide
from ecu_daemon.sim.scenario import SCENARIOS

from config_replay import replay_edited_here, simulated_drive, wrong_valid_rows


@pytest.fixture(scope="module")
def dlc_lat08(tmp_path_factory):
    s = SCENARIOS["dlc_dry"]
    return simulated_drive(tmp_path_factory, "dlc_lat08", s.with_(name="dlc_lat08", gnss_latency_s=0.8))


def _fixed_far_off(c):
    c["gnss"]["delay_s"] = 0.1
    c["gnss"]["estimate_delay"] = False


@pytest.mark.parametrize("timing", [False, True], ids=["stop44_term", "timing_term"])
def test_a_mistimed_lane_change_does_not_open_the_course_rule(dlc_lat08, monkeypatch, timing):
    monkeypatch.setattr(core, "COURSE_SLIDE", True)
    monkeypatch.setattr(core, "COURSE_SLIDE_TIMING", timing)
    if not timing:  # the stop-44 mechanism as it was: the sideslip's latency term (stop 50) now covers it too
        monkeypatch.setattr(core, "SIDESLIP_LATENCY_SENS", False)
    e, t = replay_edited_here(dlc_lat08, _fixed_far_off, f"cs_timing_{timing}")
    bad_v, bad_b, share = wrong_valid_rows(e, t)
    if timing:
        assert (bad_v, bad_b) == (0, 0)
        assert share > 0.7
    else:  # the mechanism, kept checked: the stop-44 term promised the mistimed courses' sideslip
        assert bad_b > 20


def _rate(t):
    """One lane change: a full sine of r, 0.3 rad/s over 3 s from t 10 s, straight before and after."""
    return 0.3 * math.sin(2.0 * math.pi * (t - 10.0) / 3.0) if 10.0 <= t <= 13.0 else 0.0


def _yaw(t):
    """The heading (counter-clockwise) the rate turns: its integral from 0."""
    if t <= 10.0:
        return 0.0
    u = min(t, 13.0) - 10.0
    return 0.3 * 3.0 / (2.0 * math.pi) * (1.0 - math.cos(2.0 * math.pi * u / 3.0))


def _lane_change_fixes(delay_err, lat_std, r_window):
    """The rule's largest excess over 5 Hz fixes through the lane change, each course ``delay_err``
    old; the model's sideslip (0) and the gyro are right. ``r_window``: r's range over +- that (s)
    is passed (None: r at the fix alone, the stop-44 term)."""
    cs = CourseSlide()
    dt = 0.2
    prev = None
    worst = 0.0
    for i in range(80):
        t = 6.0 + i * dt
        course = -_yaw(t - delay_err)  # clockwise: the heading of delay_err before
        ysum = None if prev is None else _yaw(t) - _yaw(prev)
        lo = hi = None
        if r_window is not None:
            rs = [_rate(t - r_window + j * r_window / 20.0) for j in range(41)]
            lo, hi = min(rs), max(rs)
        cs.observe(t, course, 0.002, 0.0 if ysum is None else ysum, 0.0 if prev is None else dt, 0.0, 0.0,
                   0.0, 0.005, _rate(t), 20.0, 20.0, lat_std, 0.0, t, lo, hi)
        worst = max(worst, cs.var)
        prev = t
    return worst


def test_the_timing_term_counts_r_where_the_course_may_be_from():
    # r at the two fixes alone, a fixed delay's widened std: a 0.7 s error opens the rule, nothing slides
    assert _lane_change_fixes(0.7, 0.15, None) > 0.0
    # the receiver's range and r's range over the instants the course may be from: it stays shut
    assert _lane_change_fixes(0.7, 0.55, 1.65) == 0.0
    # a right timing leaves it shut with the narrow term too
    assert _lane_change_fixes(0.0, 0.01, None) == 0.0
