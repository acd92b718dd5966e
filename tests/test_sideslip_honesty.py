"""Honest sideslip std and validity (issue 7 item 3): a valid sideslip is a promise (within 2 deg,
within 3 reported sigma), and a sideslip that is right is not needlessly invalid.

Whole simulated drives through the suite's own path (simulate -> files -> replay -> evaluate).
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from ecu_daemon.config import EstimatorSettings
from ecu_daemon.estimator.kinematic import VX, VY, KinematicModel
from ecu_daemon.evaluate import ESTIMATE_REQUIRED, read_csv
from ecu_daemon.estimator import estimate as est_mod
from ecu_daemon.estimator.core import SIDESLIP_STD_VALID
from ecu_daemon.sim.scenario import SCENARIOS
from ecu_daemon.sim.sensors import Fault
from ecu_daemon.sim.suite import SUITE, SuiteCase
from ecu_daemon.suite import run_case

CASES = {c.name: c for c in SUITE}
ISOLATED = (est_mod.STATUS_WHEELS_ISOLATED | est_mod.STATUS_YAW_RATE_ISOLATED | est_mod.STATUS_ACCEL_X_ISOLATED
            | est_mod.STATUS_ACCEL_Y_ISOLATED | est_mod.STATUS_GNSS_ISOLATED | est_mod.STATUS_WHEEL_SPEED_ISOLATED)
# not a suite row: the demo drive's 30 s GNSS outage (25-55 s) with rain from 35 s on (mu 0.67; the
# driver keeps the dry plan), so the outage's 0.64 g circle (44-56 s) runs at 94 % of the friction
# limit on a stiffness learned on the dry road below 0.47 g
CASES["rain_in_outage_30s"] = SuiteCase("rain_in_outage_30s", "gnss", SCENARIOS["demo"].with_(
    name="rain_in_outage_30s", mu_change=(35.0, 0.67), gnss_faults=(Fault("gnss", "dropout", 25.0, 30.0),)))


@pytest.fixture(scope="module")
def out(tmp_path_factory):
    return tmp_path_factory.mktemp("honesty")


def _run(name, out):
    row = run_case(CASES[name], out)
    assert not any(f.startswith("error") for f in row["failed"]), row["failed"]
    return row, read_csv(out / name / "estimate.csv", ESTIMATE_REQUIRED, "estimate CSV")


def test_lateral_noise_drives_vy_only():
    """vy has its own process noise; vx keeps the longitudinal one."""
    es = EstimatorSettings()
    m = KinematicModel(es.dt_s, es.accel_noise_mps2, es.yaw_rate_noise_radps, es.yaw_rate_bias_walk,
                       es.accel_bias_walk, es.wheel_scale_walk, lateral_accel_noise=es.lateral_accel_noise_mps2)
    assert m.Qd[VY, VY] == pytest.approx(es.lateral_accel_noise_mps2 ** 2 * es.dt_s)
    assert m.Qd[VX, VX] == pytest.approx(es.accel_noise_mps2 ** 2 * es.dt_s)
    assert es.lateral_accel_noise_mps2 < es.accel_noise_mps2


def test_right_sideslip_is_valid_and_within_its_sigma(out):
    """A slalom with the configured mass 30 % off: the sideslip is right (rms ~0.1 deg), so it must
    be valid on >= 90 % of the rows above 5 m/s (main a7dd231: 77 %, its std ~4x the error), and
    every valid row keeps the promise."""
    row, est = _run("config_mass_+30pct", out)
    assert row["sideslip_valid_above_5mps"] >= 0.90, row["sideslip_valid_above_5mps"]
    assert row["sideslip_coverage_3sigma"] >= 0.99
    assert row["sideslip_worst_valid_deg"] <= 2.0
    valid = est["sideslip_valid"] == 1
    # the rule itself: a valid row's 3 sigma lies inside the 2 deg a valid sideslip promises
    assert valid.any() and np.all(3.0 * est["sideslip_std_rad"][valid] <= math.radians(2.0) + 1e-9)


@pytest.mark.parametrize("name", ["fault_accel_y_scaled", "fault_accel_y_offset"])
def test_lateral_accelerometer_fault_is_never_valid_while_wrong(out, name):
    """ay x1.3 / +2 m/s^2 for 5 s in a lane change at 22 m/s: too small or too short for the fault
    tolerance (real bank and roll), so the lateral cross-check's residual beyond the filter's own
    noise must grow the std (without it: 2.2 deg off while valid with the lower lateral noise)."""
    row, _ = _run(name, out)
    assert row["sideslip_worst_valid_deg"] <= 2.0, row["sideslip_worst_valid_deg"]
    assert row["sideslip_coverage_3sigma"] >= 0.99, row["sideslip_coverage_3sigma"]


def test_steady_low_speed_circle_is_valid_where_the_model_vouches(out):
    """A 15 m circle at 5-10 m/s (0.7 g): in the steady corner GNSS course cannot separate heading
    from sideslip (yaw rate x latency std is degrees), so the single-track model holds vy; the
    filter's own vy std (its inflated model against the lateral random walk) was up to twice the
    model's own error, and the sideslip valid on 33 % of the rows above 5 m/s (main efdbdc9) while
    0.1 deg right. Bounded by the model's error (core.MODEL_BOUND), more of it is valid, and every
    valid row keeps the promise. The bound counts the tyre law's error once with the configuration's
    stiffness prior (single_track.AxleRls.predict): 56 % valid with both stacked (main 9ba8e61), 62 %.
    58 %, not 59: since a latency not yet identified weighs an accelerating fix by the receiver's range
    (timing_trust.py, integ27) the std sits 0.001 deg higher at the 0.667 deg edge of validity in two
    flickering spells (34-35 s, 64-66 s): 60.5 -> 59.0 %."""
    row, est = _run("lowspeed_r15", out)
    assert row["sideslip_valid_above_5mps"] >= 0.58, row["sideslip_valid_above_5mps"]
    assert row["sideslip_coverage_3sigma"] >= 0.99
    assert row["sideslip_worst_valid_deg"] <= 2.0
    valid = est["sideslip_valid"] == 1
    assert np.all(3.0 * est["sideslip_std_rad"][valid] <= math.radians(2.0) + 1e-9)


def test_model_bound_waits_for_a_steady_corner(out):
    """mu 0.3, GNSS back after an outage, a yaw-rate reversal while sliding: the model and the filter
    were 2 m/s off together while ay crossed zero (the model's std with it); bounding the std by the
    model there published a sideslip 7.2 deg off as valid. The bound waits for a steady corner."""
    row, _ = _run("mu03_outage_30s", out)
    assert row["sideslip_worst_valid_deg"] <= 2.0, row["sideslip_worst_valid_deg"]
    assert row["sideslip_coverage_3sigma"] >= 0.99, row["sideslip_coverage_3sigma"]


def _window(out, name, t0, t1):
    """The run's row, and sideslip |error|, std and validity from t0 to t1 s after the drive's start."""
    row, est = _run(name, out)
    truth = np.genfromtxt(out / name / "truth.csv", delimiter=",", names=True)
    t = est["t"]
    sel = (t >= truth["t"][0] + t0) & (t < truth["t"][0] + t1)
    err = np.abs(est["sideslip_rad"][sel] - np.interp(t[sel], truth["t"], truth["sideslip_rad"]))
    return row, err, est["sideslip_std_rad"][sel], est["sideslip_valid"][sel] == 1


def test_steady_corner_in_a_gnss_outage_is_valid_while_the_steering_confirms_the_model(out):
    """A 5 % banked circle ramping 0.29 -> 0.57 g through a 20 s GNSS outage (30-50 s): only the
    single-track model knows the sideslip level there, and it is 0.1-0.3 deg right. Its bound on the
    std (core.MODEL_BOUND) used to need fresh GNSS, so the std jumped from 0.5 to 0.67-0.92 deg when
    the GNSS stopped and the sideslip was valid on 9 % of the outage (main 8b9d466); with the steering
    confirming the tyre law (SingleTrackFusion.law_holds) it is valid until the model's own
    uncertainty (an unlearned stiffness: 40 %) passes 0.67 deg at ~0.45 g: 65 %, every row in 3 sigma."""
    row, err, std, valid = _window(out, "outage_circle_bank", 30.0, 50.0)
    assert valid.mean() >= 0.5, valid.mean()
    assert np.all(err[valid] <= 3.0 * std[valid])
    assert row["sideslip_coverage_3sigma"] >= 0.99
    assert row["sideslip_worst_valid_deg"] <= 2.0


def test_no_model_bound_at_the_friction_limit_in_a_gnss_outage(out):
    """The same outage on mu 0.5: its corner (~0.48 g) is the friction limit at a lateral force the
    model takes for its linear range, and the model is 0.9-1.2 deg off against its own 0.6 deg. Without
    GNSS the filter's vy is the model's, so the model's bound would vouch for itself: valid 1.2 deg off
    (1.9 sigma). The front axle's 22 deg beyond the law shows in the steering, so the bound stays off
    and the std (0.73-0.90 deg) keeps that corner invalid."""
    row, err, std, valid = _window(out, "mu05_outage_30s", 25.0, 55.0)
    assert valid.any() and np.max(err[valid]) < math.radians(1.0), math.degrees(np.max(err[valid]))
    assert row["sideslip_coverage_3sigma"] >= 0.99
    assert row["sideslip_worst_valid_deg"] <= 2.0


def test_rain_during_a_gnss_outage_keeps_the_sideslip_promise(out):
    """Why the dry outage's 0.64 g circle is invalid although 0.1-0.4 deg right (issue 7 avail-b,
    tools/outage_probe.py): without GNSS only the single-track model knows the sideslip level, and
    at 0.64 g it extrapolates the tyre law beyond the 0.47 g it was learned at. On a road that turned
    wet during the outage the same model is 0.5-0.9 deg off in the steady circle (1.7 deg at its
    entry) while the steering still agrees with the law (SingleTrackFusion.law_holds: the front's
    excess slip ~1 sigma), so its bound vouches for it with the same std as on the dry road
    (0.8-0.9 deg): the filter cannot tell the two roads apart, and the std that keeps this promise
    keeps the dry circle invalid too. Every invalid row is invalid by its std (no rule on the
    GNSS age; after the circle the sliding car's gyro is isolated for 2 s, a rule of its own); the
    valid rows keep the promise."""
    row, err, std, valid = _window(out, "rain_in_outage_30s", 44.0, 56.0)
    assert np.max(err) >= math.radians(0.8), math.degrees(np.max(err))  # the trap bites
    assert np.all(err[valid] <= 3.0 * std[valid])
    assert row["sideslip_coverage_3sigma"] >= 0.99, row["sideslip_coverage_3sigma"]
    assert row["sideslip_worst_valid_deg"] <= 2.0, row["sideslip_worst_valid_deg"]
    _, est = _run("rain_in_outage_30s", out)
    isolated = (est["status"].astype(int) & ISOLATED) != 0
    fast = (est["vx_mps"] > 5.0) & (est["t"] >= est["t"][0] + 10.0) & (est["velocity_valid"] == 1) & ~isolated
    invalid = fast & (est["sideslip_valid"] == 0)
    assert invalid.any() and np.all(est["sideslip_std_rad"][invalid] >= SIDESLIP_STD_VALID - 1e-9)
