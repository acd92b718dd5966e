"""A slow slide on ice that nothing else sees: sideslip and heading valid beyond 3 sigma (issue 7, slow44).

Never-seen random drive 2271 (generator v1: all-wheel drive, a 126 m circle on mu 0.22, 2.9 deg bank,
speeding up until it spins at ~52 s; main d1a0953): front and rear let go alike from ~42 s (slip -1.9/-1.3
deg at 1242 s, -4.9/-4.5 at 1244 s), the steering's misfit stays inside the law and ``slide_rate.py``'s gate
(the friction memory) never opens, so the single-track model holds vy: the sideslip was published valid at
1243.2-1244.8 s up to 5.5 deg off at 0.3-0.5 deg (257 rows beyond 3 sigma) and the heading, which the
courses moved by the sideslip's error, 2-4.3 deg off at 0.5-0.7 deg (709 rows, 1243.7-1248.0 s).
``fusion/course_slide.py`` (``core.COURSE_SLIDE``) reads the GNSS course's change less the gyro's turn
against the model's sideslip change and widens the model by what is beyond 3 sigma;
``core.COURSE_SLIDE_HEADING`` floors the heading's std at the sideslip's meanwhile. With both flags off the
drive test fails (709 heading rows beyond 3 sigma, sideslip 5.5 deg off); with them on the heading holds its
promise (44 rows, 0.9 %) and the sideslip's worst valid error is 2.4 deg. The rule fires 0.3-0.8 s after the
error has passed 3 sigma (a 3-sigma test on two courses cannot be quicker than the error it measures), so
122 sideslip rows beyond remain: the strict xfail.

Off by default since stop 44: with a GNSS latency configured fixed and far off (tests/test_latency_prior_wrong.py,
0.1 s for 0.8) the rule opened on the misaligned courses, and the widened model let those courses move the
sideslip: 86 rows valid beyond 3 sigma. The drive tests here run with both flags on.
"""
from __future__ import annotations

import math

import pytest
from tools_import import load_tool

SEED = 2271


@pytest.fixture(scope="module")
def drive_2271(tmp_path_factory):
    from ecu_daemon.estimator import core
    rd = load_tool("random_drives")
    with pytest.MonkeyPatch.context() as mp:  # off by default since stop 44 (core.py: a wrong fixed latency)
        mp.setattr(core, "COURSE_SLIDE", True)
        mp.setattr(core, "COURSE_SLIDE_HEADING", True)
        d = rd.run_drive(SEED, str(tmp_path_factory.mktemp("rd")))  # the whole 60 s drive (~30 s idle)
    assert d["error"] is None, d["error"]
    return d["figures"]


def test_a_slow_slide_on_ice_leaves_the_heading_honest(drive_2271):
    he, ss = drive_2271["heading"], drive_2271["sideslip"]
    assert he["valid_rows"] > 4000 and ss["valid_rows"] > 4000  # the promise is still made on this drive
    assert he["coverage_3sigma"] >= 0.99, he  # main: 709 rows beyond 3 sigma (0.872)
    assert math.degrees(ss["worst_error_valid"]) < 3.0, ss  # main: 5.5 deg


@pytest.mark.xfail(strict=True, reason="the course rule fires 0.3-0.8 s after the sideslip error passes 3 sigma: "
                   "122 of main's 257 rows beyond remain (1243.2-1244.0 s)")
def test_a_slow_slide_on_ice_is_not_promised(drive_2271):
    assert drive_2271["sideslip"]["beyond_3sigma"] == 0, drive_2271["sideslip"]


def _circle(slide_deg_s: float) -> float:
    """Largest excess (m/s) on a steady circle (r 0.1 rad/s, 14 m/s) with 10 Hz courses; the sideslip
    growing at ``slide_deg_s``; the course (clockwise) is the heading less the sideslip."""
    from ecu_daemon.estimator.fusion.course_slide import CourseSlide
    cs = CourseSlide()
    r, vx, dt, beta, worst = 0.1, 14.0, 0.1, 0.0, 0.0
    for n in range(100):
        t = n * dt
        cs.observe(t, -r * t - beta, 0.01, r * dt if n else 0.0, dt, 0.002, 0.001, 0.0, 0.003, r, vx, vx, 0.01,
                   0.005, t)
        beta += math.radians(slide_deg_s) * dt
        worst = max(worst, math.sqrt(cs.excess_var(t)))
    return worst


def test_the_course_against_the_gyro_measures_the_slide():
    """1 deg/s of sideslip growth over the 4 s window is 4.0 deg against a 3 sigma of 2.7 deg (two courses'
    0.57 deg each, the model's floor 0.3 deg, the gyro's bias 0.001 rad/s x 4 s): 1.3 deg beyond, x 14 m/s =
    0.34 m/s. A car that follows its model (the course turning with the gyro) leaves nothing; a bank (ay
    only) never enters."""
    assert _circle(0.0) == 0.0
    assert 0.30 < _circle(1.0) < 0.38, _circle(1.0)


def _straight_after_corner(scale_sd: float, s_br: float | None, bias_share: float = 1.0) -> float:
    """Largest excess (m/s) on a straight (true r 0, 14 m/s, courses constant) after a corner at
    0.5 rad/s in which the filter's bias state took ``bias_share`` of a -5 % gyro scale error
    (b_r = -S_br s with S_br = -0.5 bias_share rad/s per unit scale): the gyro reads nothing, the
    rule subtracts the older fix's bias, a slide the car does not have."""
    from ecu_daemon.estimator.fusion.course_slide import CourseSlide
    cs = CourseSlide()
    scale, vx, dt, worst = -0.05, 14.0, 0.1, 0.0
    sens = -0.5 * bias_share  # d b_r / d s
    b = -sens * scale  # the bias state's error: -0.025 rad/s (-1.4 deg/s) taken whole
    for n in range(100):
        t = n * dt
        # the stored yaw rates are bias-corrected: 0 - b
        cs.observe(t, 0.0, 0.01, -b * dt if n else 0.0, dt, b, 0.001, 0.0, 0.003, 0.0, vx, vx, 0.01,
                   scale_sd, t, s_br=None if s_br is None else sens)
        worst = max(worst, math.sqrt(cs.excess_var(t)))
    return worst


def test_a_scale_the_bias_state_took_in_the_corner_is_not_a_slide_on_the_straight():
    """stop 46 (core.COURSE_SLIDE_SCALE_SENS): the scale error the bias state took in a corner is b_r's
    error S_br s, and less the older fix's bias the rule measures S_br s W on the straight (5.7 deg over
    4 s here; the -5 % flying start: 7-9 deg). The stop-45 term, a scale std x the turn, is 0 there: it
    opened (at the scale check's 1 % for a true 5 %). Signed with the turn, the term covers it."""
    assert _straight_after_corner(0.01, None) > 0.7  # the stop-45 term: opens, 0.78 m/s
    assert _straight_after_corner(0.05, 0.0) == 0.0  # the unapplied scale's 5 % x the bias's share
    assert _straight_after_corner(0.012, 0.0) > 0.0  # the prior's 1.2 % does not cover a 5 % scale


def test_the_scale_term_cancels_where_the_bias_state_took_the_scale():
    """In a steady corner the turn and the bias's share have opposite signs (S_br ~ -r where b_r took the
    whole scale): a slide still opens the rule under an unapplied 5 % scale (2271's gain kept), as a
    scale std x the whole turn (0.4 rad, 3 sigma 3.4 deg more) would not."""
    from ecu_daemon.estimator.fusion.course_slide import CourseSlide

    def circle(s_br):
        cs = CourseSlide()
        r, vx, dt, beta, worst = 0.1, 14.0, 0.1, 0.0, 0.0
        for n in range(100):
            t = n * dt
            cs.observe(t, -r * t - beta, 0.01, r * dt if n else 0.0, dt, 0.002, 0.001, 0.0, 0.003, r, vx, vx,
                       0.01, 0.05, t, s_br=s_br)
            beta += math.radians(1.0) * dt
            worst = max(worst, math.sqrt(cs.excess_var(t)))
        return worst

    assert 0.30 < circle(-0.1) < 0.38, circle(-0.1)  # as with no scale term at all (_circle(1.0))
    assert circle(None) == 0.0  # 5 % x the whole turn: the slide hidden
