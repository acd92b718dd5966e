"""``ecu-daemon evaluate --suite``: the runner's pieces, and a short subset scored against issue 7's targets.

The subset runs the real pipeline (simulate -> files -> ``run_replay`` -> evaluate). Each target
of each case is its own test; the ones the current estimator misses are ``xfail(strict=True)``
with the measured figure, so whoever fixes one sees an XPASS and flips it here.
"""
from __future__ import annotations

import json
import logging
import math

import pytest

from ecu_daemon.cli import main as cli_main
from ecu_daemon.sim.suite import SUITE, SuiteCase
from ecu_daemon.suite import COLUMNS, failed_targets, format_table, run_case, select


def _row(**changes):
    row = {key: 0.0 for _, key, _ in COLUMNS}
    row.update(scenario="x", family="f", sideslip_coverage_3sigma=1.0, heading_coverage_3sigma=1.0,
               vx_coverage_3sigma=1.0,
               sideslip_valid_above_5mps=1.0, heading_valid_above_5mps=1.0, has_fix=True, ratio_to_baseline=0.5,
               sideslip_rms_deg=0.2, road_coverage_3sigma=1.0)
    row.update(changes)
    return row


def test_targets_are_the_issues_limits():
    case = SuiteCase("x", "f", SUITE[0].scenario)
    low = SuiteCase("x", "f", SUITE[0].scenario, low_speed=True)
    assert failed_targets(_row(), case) == []
    assert failed_targets(_row(sideslip_coverage_3sigma=0.989), case) == ["cov-b"]
    assert failed_targets(_row(heading_coverage_3sigma=0.99), case) == []
    assert failed_targets(_row(sideslip_worst_valid_deg=2.01, heading_worst_valid_deg=5.0), case) == ["worst-b"]
    assert failed_targets(_row(heading_worst_valid_deg=5.01), case) == ["worst-h"]
    assert failed_targets(_row(vx_coverage_3sigma=0.98), case) == ["cov-v"]
    assert failed_targets(_row(vx_coverage_3sigma=math.nan), case) == []  # never valid: no promise made
    assert failed_targets(_row(sideslip_valid_above_5mps=0.89), case) == ["avail-b"]
    assert failed_targets(_row(sideslip_valid_above_5mps=math.nan), case) == ["avail-b"]  # never a silent pass
    assert failed_targets(_row(heading_time_to_valid_after_fix_s=3.1), case) == ["ttv-h"]
    assert failed_targets(_row(sideslip_time_to_valid_after_fix_s=math.nan), case) == ["ttv-b"]  # never valid
    assert failed_targets(_row(sideslip_time_to_valid_after_fix_s=math.nan, has_fix=False), case) == []
    assert failed_targets(_row(latency_error_s=-0.031), case) == ["lat"]
    assert failed_targets(_row(ratio_to_baseline=0.7), case) == []
    assert failed_targets(_row(ratio_to_baseline=0.7), low) == ["rms-b"]
    assert failed_targets(_row(sideslip_rms_deg=0.31), low) == ["rms-b"]
    assert failed_targets(_row(road_coverage_3sigma=0.989), case) == ["cov-r"]
    assert failed_targets(_row(road_coverage_3sigma=math.nan), case) == []  # never valid: no promise made
    graded = SuiteCase("x", "road", SUITE[0].scenario.with_(grade_rad=0.1))
    banked = SuiteCase("x", "road", SUITE[0].scenario.with_(bank_rad=0.06))
    assert failed_targets(_row(grade_rms_deg=0.49, bank_rms_deg=0.9), graded) == []
    assert failed_targets(_row(grade_rms_deg=0.51), graded) == ["rms-g"]
    assert failed_targets(_row(grade_rms_deg=0.1, bank_rms_deg=0.51), banked) == ["rms-k"]
    assert failed_targets(_row(bank_rms_deg=math.nan), banked) == ["rms-k"]  # never a silent pass


def test_select_by_glob_substring_family_and_lists():
    names = lambda p: [c.name for c in select(p)]  # noqa: E731
    assert names(None) == [c.name for c in SUITE]
    assert names("flying_30_straight_h0") == ["flying_30_straight_h0"]
    assert set(names("latency")) == {"latency_0.1", "latency_0.25", "latency_0.6", "latency_0.8"}
    assert len(names("fault")) == 9 * 6 + 2 + 1  # every CAN input (and all wheels) x every kind, 2 stuck-at,
    # and (a substring of its name) the dual antenna's wrong carrier fix
    assert names("gnss_1hz,reversing") == ["reversing", "gnss_1hz"]  # suite order
    assert names("nothing-like-this") == []


def test_table_has_one_row_per_case_with_dashes_and_failed_codes():
    rows = [_row(scenario="good"), _row(scenario="bad", sideslip_time_to_valid_after_fix_s=math.nan,
                                        failed=["ttv-b"])]
    rows[0]["failed"] = []
    text = format_table(rows)
    lines = text.splitlines()
    assert lines[0].split()[0] == "scenario" and lines[0].split()[-1] == "result"
    assert lines[1].startswith("good") and lines[1].endswith("pass")
    assert lines[2].startswith("bad") and lines[2].endswith("FAIL ttv-b") and " - " in lines[2]
    assert "1 of 2 scenarios meet every target" in lines[3]


def test_a_case_that_cannot_run_is_a_row_not_a_crash(tmp_path):
    broken = SuiteCase("broken", "f", SUITE[0].scenario, encoding="no-such-car")
    row = run_case(broken, tmp_path)
    assert row["scenario"] == "broken" and row["failed"] == ["error: ValueError: unknown suite encoding 'no-such-car'"]
    assert "FAIL error" in format_table([row])


def test_cli_options_are_checked_in_one_line(capsys):
    assert cli_main(["evaluate", "--suite", "--only", "nothing-like-this"]) == 2
    assert cli_main(["evaluate", "--suite", "--truth", "t.csv"]) == 2
    assert cli_main(["evaluate"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 3 and "matches no scenario" in err[0] and "--suite makes its own drives" in err[1]
    assert "give --truth and --estimate" in err[2]


# ----------------------------------------------------------------------------- the subset
TARGETS = ("cov-b", "cov-h", "cov-v", "worst-b", "worst-h", "avail-b", "ttv-b", "ttv-h", "lat", "cov-r",
           "rms-b5", "rms-g")
#: the subset and what the estimator on this branch misses (measured; see README "Scenario suite")
SUBSET = {
    # latency +0.032 s off before the accelerometer timed GNSS too (estimator/latency.py); 0.000 now
    "flying_30_straight_h0": {},
    # a mid-corner flying start (R 150 m, 11.5 deg/s, 0.57 g): in a steady corner only the single-track
    # model observes the sideslip (its stiffness prior: 1.05 deg, 1 sigma, here); against the vy random
    # walk of the accelerometer noise the filter settles at ~1.2 deg, so sideslip and heading (course
    # less sideslip, plus yaw rate x latency std) stay invalid -- and right -- until the corner ends 12 s in
    # (the scenario's corner length: with a 4 or 8 s corner both are valid 4.0-4.4 / 8.0-8.2 s after the fix)
    "flying_30_r150l_h100": {"avail-b": "sideslip valid on 78 % above 5 m/s",
                             "ttv-b": "sideslip valid 12.0 s after the first fix",
                             "ttv-h": "heading valid 12.2 s after the first fix"},
    # latency +0.036 s off before the wheels' regression took the antenna's geometry and braking slip apart
    "flying_10_r14l_h45": {"avail-b": "sideslip valid on 78 % above 5 m/s",
                           "ttv-b": "sideslip valid 12.0 s after the first fix",
                           # 16.0 s while a 5 s low-pass of |r| stood for the heading's latency error;
                           # tracked through the filter's gains (latency_sensitivity.py) 0.4 s after the corner
                           "ttv-h": "heading valid 12.4 s after the first fix"},
    # vx within 3 sigma needs the wheel-slip bias under braking in the published std (89 % without)
    # latency +0.123 s off from braking slip, +0.030 with the accelerometer, +0.032 since the braked
    # wheel fixes are judged apart; +0.008 since the accelerometer, while it has a profile, must
    # refute the delay itself or be sharp and agree (its broad profile passed the braked wheels)
    "flying_50_straight_h200": {},
    # the state file saved 8 s into the same steady corner holds nothing about the stiffness (only
    # transients teach it: kappa_r at the config's, its std at the 40 % prior), so this is a cold
    # mid-corner start; valid at the corner's end, 4.3 s after the restart. From a state file that
    # did learn it: test_estimator_init.py::test_restart_mid_corner_after_a_drive_that_taught_the_stiffness
    # The heading: its file's latency is still at the 0.15 s prior (a steady corner does not teach it),
    # so every course is turned by up to 11.5 deg/s x 0.15 s = 1.7 deg alike, above the 1.5 deg a valid
    # heading allows, until the corner ends (the std published it only after seconds before)
    "restart_flying_30_r150": {"ttv-b": "sideslip valid 4.4 s after the first fix",
                               "ttv-h": "heading valid 4.6 s after the first fix"},
    # sideslip valid on 80 % above 5 m/s while its std was 3-10x its error (vy's own process noise now)
    "vw_mqb_sign_magnitude": {},
    # the three issue-7 faults below meet every target since fault detection (fault_detection.py)
    "gnss_constant": {},
    "fault_wheels_zero": {},
    # a gyro x1.3: isolated in the corners since both witnesses' disagreement has a slope against r
    # (fault_detection.py, _scale_test); before, only the stds grew by the disagreement (2.4 deg off, valid)
    # since stop 50 (core.SIDESLIP_LATENCY_SENS: the unconfirmed latency's share; core.MODEL_TYRE_FORCE: the law's doubt at the tyres' force):
    # 0.893 -> 0.887 above 5 m/s (SIDESLIP_LATENCY_SENS alone 0.899), every valid row within 3 sigma
    "fault_yaw_rate_scaled": {"avail-b": "sideslip valid on 88.7 % above 5 m/s"},
    # the same: 0.901 -> 0.888 (MODEL_TYRE_FORCE alone 0.894)
    "fault_yaw_rate_offset": {"avail-b": "sideslip valid on 88.8 % above 5 m/s"},
    "fault_accel_x_stuck_at_29.9mps2": {},
    # a 2 m/s^2 ax offset for 5 s at a steady speed: a bias, not a scale error (input_consistency.py);
    # the longitudinal check withheld sideslip for 10 s (78 % valid) before it learned the difference
    "fault_accel_x_offset": {},
    # an isolated ay's stand-in r vx leaves out the vy rate the model expects from the gyro's yaw
    # acceleration: sideslip is valid on the straight after the lane change, not in it (85-86 % before,
    # when any ay isolation held it invalid and a generic 2 m/s^2 random walk widened vy)
    # b_ay's walk per change of road curvature (estimator/bank_walk.py, road17): valid 90.3 -> 89.4 %
    "fault_accel_y_stuck": {"avail-b": "sideslip valid on 89.4 % above 5 m/s"},
    # ay reading 0 for 5 s in a lane change: 90.1 % valid before the single-track model's inputs shared
    # one lag (acc10: Revs sideslip 0.304 -> 0.290 deg); since, the std at two turn-ins is 0.67-0.85 deg
    # for ~0.1 s where it was 0.60-0.65 (30 of 7106 rows), and the sideslip RMS fell 0.202 -> 0.165 deg
    "fault_accel_y_zero": {"avail-b": "sideslip valid on 89.7 % above 5 m/s"},
    # since stop 50 (SIDESLIP_LATENCY_SENS and MODEL_TYRE_FORCE, each alone 0.904-0.906): 0.893
    "fault_accel_y_offset": {"avail-b": "sideslip valid on 89.3 % above 5 m/s"},
    # a 30 s outage on mu 0.3 with a corner at the limit: sideslip 0.4-0.7 deg off while the model alone
    # holds it, within its std (0.6 deg): the honesty guard for any rule that narrows the outage std;
    # since stop 50 the sideslip's latency term withholds more after the outage: 0.919 -> 0.888
    "mu03_outage_30s": {"avail-b": "sideslip valid on 88.8 % above 5 m/s"},
    # the same outage on mu 0.5: the corner (~0.48 g) is the friction limit at a lateral force the model
    # takes for linear; sideslip 0.9-1.2 deg off at up to 1.6 sigma, invalid there (std 0.73-0.90 deg)
    "mu05_outage_30s": {"avail-b": "sideslip valid on 80 % above 5 m/s"},
    # grade +10 % with NMEA: grade rms 0.55 deg on the offset's prior alone; GGA altitude over the
    # distance travelled (estimator/altitude_grade.py) measures it now
    "grade_+10pct_nmea": {},
    # dual antenna, 40 m circle ramped to 0.65 g: course - heading is the sideslip at any latency once
    # the receiver's latency error is one state shared by its velocity and heading (latency_consider.py;
    # 7 % valid as white noise on each fix); the rest is the entry at 8-10 m/s, where the lateral
    # accelerometer noise's random walk over the 0.4 s latency holds vy's std at 0.10-0.12 m/s
    # latency: +0.033 s when latency.py's delay moved as the car slowed out of the circle; the latency
    # error state knew better (-0.037 s), and its sum is what is published now (-0.005 s).
    # sideslip rms>5 0.14 deg while the heading took its receive time, 4 ms after its epoch's velocity
    # (the latency-error state absorbed the stagger); dated by the NAV-PVT of its iTOW: 0.10 deg
    # and 98.8 % since vy's process noise is the accelerometer's own (measured, over a 0.1 floor)
    # with the coloured lateral errors as linear std growth (core.IMU_LEVER_STD_M, YAW_SCALE_STD)
    "dual_circle": {},
    # the same on a 6 % banked circle: with the latency error a state, its remaining variance still turns
    # every fix's heading alike, so yaw rate x its std stays in the published heading std (99.0 % of
    # valid headings within 3 sigma without it, 0.55 deg off with a 0.18 deg std at 15.5 m/s)
    # (valid on 81 % with a fixed vy noise of 0.2; 98.9 % with the noise by source, as dual_circle)
    "dual_bank_circle": {},
    # the IMU 0.6 m ahead / 0.3 m left of the CG, turned 1.5 deg, in the slalom: with [imu] as accurate
    # as at the CG (0.08 deg rms); without it 0.18 deg rms, 0.6 deg worst, every valid row within 3 sigma
    "imu_slalom": {},
    "imu_slalom_unconfigured": {},
    # 5 m/s^2 braking twice in a 0.55 g circle: the unloaded inner rear wheel slips, and the rear
    # wheels' yaw rate, 0.65 rad/s off, held the (right) gyro suspect for 3 s each time, widening the
    # heading std to 25 deg and vy's to 1 m/s (sideslip valid on 79 % above 5 m/s); braked wheels
    # judge no gyro since (fault_detection.BRAKE_WITNESS_MPS2)
    # b_ay's walk per change of road curvature (estimator/bank_walk.py, road17): the 60 m circle's
    # entries widen it; valid 91.3 -> 89.0 % (sideslip rms 0.165 -> 0.157 deg)
    "imu_brake_turn": {"avail-b": "sideslip valid on 89.0 % above 5 m/s"},
    # the wheel speeds 0.04 s late (the ABS ECU's filter): the scale test took the lag's disagreement
    # with the gyro for a gyro scale error in the lane change, isolated the gyro and 'repaired' the
    # heading by it (1.2 deg off; heading RMS 0.32, sideslip valid 82 %); its timing term since
    # since stop 50 (MODEL_TYRE_FORCE; without it 0.906): 0.892
    "wheel_lag_0.04_dlc_1hz": {"avail-b": "sideslip valid on 89.2 % above 5 m/s"},
}


@pytest.fixture(scope="module")
def subset_rows(tmp_path_factory):
    out = tmp_path_factory.mktemp("suite")
    cases = {c.name: c for c in SUITE}
    return {name: run_case(cases[name], out) for name in SUBSET}, out


def _params():
    for name, misses in SUBSET.items():
        for target in TARGETS:
            marks = ()
            if target in misses:
                marks = pytest.mark.xfail(strict=True, reason=f"estimator misses it: {misses[target]}")
            yield pytest.param(name, target, marks=marks, id=f"{name}-{target}")


@pytest.mark.parametrize("name, target", list(_params()))
def test_subset_meets_target(subset_rows, name, target):
    rows, _ = subset_rows
    row = rows[name]
    assert not any(f.startswith("error") for f in row["failed"]), row["failed"]
    assert target not in row["failed"], {k: row[k] for k in row if k not in ("failed",)}


def test_subset_rows_are_on_disk_as_strict_json(subset_rows):
    rows, out = subset_rows
    for name in rows:
        doc = json.loads((out / name / "evaluation.json").read_text(),
                         parse_constant=lambda c: pytest.fail(f"non-JSON constant {c}"))
        assert doc["row"]["scenario"] == name and "validity" in doc["evaluation"]["sideslip"]


def test_cli_suite_runs_through_the_process_pool_and_writes_strict_json(tmp_path, capsys):
    rc = cli_main(["evaluate", "--suite", "--only", "gnss_glitch", "--jobs", "2", "--out", str(tmp_path)])
    out = capsys.readouterr().out.splitlines()
    assert rc == 0  # every target met: exit 0 (a miss exits 1)
    assert out[1].startswith("gnss_glitch") and out[1].endswith("pass")
    doc = json.loads((tmp_path / "suite.json").read_text(), parse_constant=lambda c: pytest.fail(c))
    assert [r["scenario"] for r in doc] == ["gnss_glitch"] and doc[0]["failed"] == []
    assert (tmp_path / "gnss_glitch" / "estimate.csv").exists()


def test_suite_prints_one_line_per_case_not_each_replays_input_table(tmp_path, capsys):
    """The per-input table of every replay (nine INFO lines, two to four replays a case) stays
    out of the suite's output; the case's own line is there."""
    rc = cli_main(["evaluate", "--suite", "--only", "gnss_glitch", "--jobs", "1", "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert rc == 0
    assert "gnss_glitch: pass" in err
    assert "inputs at the end of the replay" not in err and "wheel_speed_fl" not in err
    assert logging.getLogger("ecu_daemon.replay").level == logging.NOTSET  # restored for what runs next
