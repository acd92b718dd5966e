"""A car crabbing on a banked road at low grip, and one creeping below its wheel sensors' floor: errors small,
the promised std smaller still (issue 7, the honest std; core.MODEL_TYRE_FORCE, core.STANDSTILL_CREEP_STD).

Found by tools/random_drives.py (generator v1, seeds 3172 and 3219, written out below so that they do not
depend on the generator), on main e0a190a:

* 3172, flying straight at 35-42 m/s on mu 0.344 with a +3.6 deg bank: the tyres hold the car against the
  bank (specific force ~0.6 m/s^2 more than the kinematic ay), the rear slips for it and the car crabs
  (true sideslip -0.24..-0.73 deg at r ~ 0). The single-track model took the kinematic ay (b_ay holds the
  bank) and said ~0: sideslip valid 0.34-0.47 deg off at a 0.11-0.13 deg std, 270 of 4753 valid rows beyond
  3 sigma. With the tyres' force (the specific force less road.py's sensor offset) the model says the crab.
* 3219, a circle up a 4.4 deg grade whose friction drops to 0.149: at its end the driven front spins and the
  car slides back at 0.03-0.10 m/s, every wheel below its sensor's 0.15 m/s floor (reading 0): standstill
  declared, vx published valid 0.00 at a 0.01 m/s std, 197 rows beyond 3 sigma.

Replayed end to end through the suite's own scoring (simulate, CAN/GNSS files, replay, evaluate). With the
flags False (main) both end-to-end tests fail; MODEL_TYRE_FORCE is off by default, its test sets it (seen: 270 and 197 rows beyond 3 sigma).
"""
from __future__ import annotations

import csv
import math

import numpy as np

from ecu_daemon.estimator import core
from ecu_daemon.estimator.fusion.single_track import SingleTrackFusion
from ecu_daemon.sim.scenario import Scenario
from ecu_daemon.sim.sensors import GnssParams, SensorParams
from ecu_daemon.sim.suite import SuiteCase
from ecu_daemon.sim.tyre import TyreParams
from ecu_daemon.sim.vehicle import VehicleParams
from ecu_daemon.suite import run_case

FLYING_ON_A_BANK_AT_LOW_GRIP = Scenario(name='random_v1_s3172', manoeuvre='flying', mu=0.344, mu_change=None, bank_rad=0.06212,
    grade_rad=0.02704, vehicle=VehicleParams(mass_kg=2227.0, yaw_inertia_kgm2=3173.4, lf_m=1.205, lr_m=1.361,
    track_m=1.556, cg_height_m=0.611, wheel_radius_m=0.2997, wheel_inertia_kgm2=1.2, steering_ratio=16.17,
    ackermann=1.0, roll_stiffness_front_share=0.603, roll_gradient_rad_per_g=0.09278, suspension_lag_s=0.05,
    tyre_front=TyreParams(fz0_n=4000.0, ky1=11.04, ky2=2.0, kx1=18.0, shape_c=1.3, curv_e=-1.5,
    relaxation_length_m=0.0), tyre_rear=TyreParams(fz0_n=4000.0, ky1=16.09, ky2=2.0, kx1=18.0, shape_c=1.3,
    curv_e=-1.5, relaxation_length_m=0.0), driven_axle='front', max_drive_power_w=214000.0,
    max_drive_force_n=7000.0, brake_front_share=0.65, drag_area_m2=0.68, air_density=1.2,
    rolling_resistance=0.012), sensors=SensorParams(can_rate_hz=None, jitter_s=0.00088, usb_batch_s=0.0,
    yaw_rate_bias_radps=-0.011792, accel_x_bias_mps2=-0.114, accel_y_bias_mps2=-0.225, wheel_scale=0.9758,
    steering_offset_rad=0.04595, yaw_rate_noise_radps=0.000771, accel_noise_mps2=0.099,
    wheel_speed_noise_mps=0.031, steering_noise_rad=0.00116, wheel_speed_min_mps=0.15, wheel_lag_s=0.016,
    faults=(), magnetometer=None, roll_rate=False, roll_rate_bias_radps=0.005235987755982988,
    roll_rate_noise_radps=0.0013962634015954637, imu_position_m=(0.0, 0.0, 0.0), imu_mounting_rpy_deg=(0.0, 0.0,
    0.0)), gnss=GnssParams(protocol='nmea', rate_hz=10.0, latency_s=0.178, latency_jitter_s=0.0061,
    vel_noise_mps=0.091, speed_acc_mps=0.114, lever_arm_m=(-0.44, -0.21), pos_noise_m=2.14, pos_tau_s=50.4,
    num_sv=7, nmea_stagger_s=0.004, lat0_deg=48.137, lon0_deg=11.575, height_m=520.0, faults=(),
    dual_antenna=False, baseline_m=1.2, baseline_offset_deg=0.0, heading_noise_deg_1m=0.2, down_noise_m=0.007,
    fuse_elevation=False, alt_noise_m=1.2, nmea_altitude=True), gnss2=None, seed=3172, duration_s=42.6,
    heading0_rad=4.37864, description='random drive seed 3172, generator v1', params=(('v', 41.77), ('radius_m',
    0.0), ('left', False), ('corner_s', 14.3)), config_errors=(('cf', 1.043),), latency_prior_s=None,
    imu_in_config=True, relaxation_in_config=False)

CREEPING_BACK_DOWN_A_GRADE_ON_ICE = Scenario(name='random_v1_s3219', manoeuvre='steady_circle', mu=0.358, mu_change=(28.7, 0.149),
    bank_rad=-0.01755, grade_rad=0.07702, vehicle=VehicleParams(mass_kg=1155.0, yaw_inertia_kgm2=1673.9,
    lf_m=1.162, lr_m=1.312, track_m=1.651, cg_height_m=0.67, wheel_radius_m=0.3137, wheel_inertia_kgm2=1.2,
    steering_ratio=15.08, ackermann=1.0, roll_stiffness_front_share=0.629, roll_gradient_rad_per_g=0.07567,
    suspension_lag_s=0.05, tyre_front=TyreParams(fz0_n=4000.0, ky1=16.33, ky2=2.0, kx1=18.0, shape_c=1.3,
    curv_e=-1.5, relaxation_length_m=0.0), tyre_rear=TyreParams(fz0_n=4000.0, ky1=25.52, ky2=2.0, kx1=18.0,
    shape_c=1.3, curv_e=-1.5, relaxation_length_m=0.0), driven_axle='front', max_drive_power_w=232000.0,
    max_drive_force_n=7000.0, brake_front_share=0.65, drag_area_m2=0.68, air_density=1.2,
    rolling_resistance=0.012), sensors=SensorParams(can_rate_hz=None, jitter_s=0.0002, usb_batch_s=0.0,
    yaw_rate_bias_radps=0.006268, accel_x_bias_mps2=0.072, accel_y_bias_mps2=0.12, wheel_scale=0.9742,
    steering_offset_rad=0.01367, yaw_rate_noise_radps=0.000739, accel_noise_mps2=0.044,
    wheel_speed_noise_mps=0.028, steering_noise_rad=0.002044, wheel_speed_min_mps=0.15, wheel_lag_s=0.0164,
    faults=(), magnetometer=None, roll_rate=False, roll_rate_bias_radps=0.005235987755982988,
    roll_rate_noise_radps=0.0013962634015954637, imu_position_m=(0.0, 0.0, 0.0), imu_mounting_rpy_deg=(0.0, 0.0,
    0.0)), gnss=GnssParams(protocol='nmea', rate_hz=8.0, latency_s=0.69, latency_jitter_s=0.0012,
    vel_noise_mps=0.129, speed_acc_mps=0.298, lever_arm_m=(-0.78, 0.34), pos_noise_m=2.98, pos_tau_s=12.4,
    num_sv=12, nmea_stagger_s=0.004, lat0_deg=48.137, lon0_deg=11.575, height_m=520.0, faults=(),
    dual_antenna=False, baseline_m=1.2, baseline_offset_deg=0.0, heading_noise_deg_1m=0.2, down_noise_m=0.007,
    fuse_elevation=False, alt_noise_m=1.2, nmea_altitude=True), gnss2=None, seed=3219, duration_s=None,
    heading0_rad=0.38682, description='random drive seed 3219, generator v1', params=(('radius_m', 25.2),
    ('left', False)), config_errors=(('inertia', 1.295), ('cr', 1.094)), latency_prior_s=0.409,
    imu_in_config=True, relaxation_in_config=False)


def _run(sc, tmp_path):
    row = run_case(SuiteCase(sc.name, "random", sc), tmp_path)
    assert not any(f.startswith("error") for f in row["failed"]), row["failed"]
    return _columns(tmp_path / sc.name / "estimate.csv"), _columns(tmp_path / sc.name / "truth.csv")


def _columns(path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    a = np.array(rows[1:], dtype=float)
    return {n: a[:, i] for i, n in enumerate(rows[0])}


def test_the_models_force_doubt_is_the_offsets_through_the_rear_law():
    # drive 3172's car: m 2227 kg, C_r as configured 165 kN/rad, lf 1.205, lr 1.361
    st = SingleTrackFusion(2227.0, 3173.4, 1.205, 1.361, 120000.0, 165000.0, adapt=False)
    k = 2227.0 / 165000.0
    # at 40 m/s an offset known to 0.13 m/s^2 (a bank to 0.013 rad) moves the rear law's vy by
    # vx kappa lf / L x 0.13 = 0.033 m/s (0.05 deg of sideslip)
    s = math.sqrt(st.force_var(40.0, 0.13 ** 2))
    assert abs(s - 40.0 * k * 1.205 / 2.566 * 0.13) < 1e-12
    assert 0.03 < s < 0.036
    assert st.force_var(40.0, 0.0) == 0.0


def test_a_car_crabbing_on_a_banked_road_keeps_the_promise(tmp_path, monkeypatch):
    monkeypatch.setattr(core, "MODEL_TYRE_FORCE", True)  # off by default (its docstring: the suite's dual_circle)
    e, tr = _run(FLYING_ON_A_BANK_AT_LOW_GRIP, tmp_path)
    beta = np.interp(e["t"], tr["t"], tr["sideslip_rad"])
    err = np.abs(e["sideslip_rad"] - beta)
    valid = e["sideslip_valid"] == 1
    beyond = valid & (err > 3.0 * e["sideslip_std_rad"])
    # main: 270 of 4753 valid rows beyond 3 sigma, all in the crab while accelerating, 1230-1243 s
    assert beyond.sum() == 0, e["t"][beyond][:5]
    # and by the model, not by a wider std alone: the crab's error (main 0.34-0.47 deg) is halved
    crab = valid & (e["t"] >= 1233.6) & (e["t"] <= 1234.3)
    assert crab.sum() > 50
    assert np.degrees(err[crab].max()) < 0.3, np.degrees(err[crab].max())
    # the sideslip stays promised where main promised it (71 % of the drive above 5 m/s)
    assert valid.sum() >= 4700


def test_a_car_creeping_below_its_wheel_sensors_floor_keeps_the_vx_promise(tmp_path):
    e, tr = _run(CREEPING_BACK_DOWN_A_GRADE_ON_ICE, tmp_path)
    vx = np.interp(e["t"], tr["t"], tr["vx_mps"])
    valid = e["velocity_valid"] == 1
    beyond = valid & (np.abs(e["vx_mps"] - vx) > 3.0 * e["vx_std_mps"])
    # main: 197 valid rows beyond 3 sigma at 1264.3-1265.8 s (vx 0.00 +- 0.01 for a 0.04-0.10 m/s creep)
    creep = (e["t"] >= 1262.0) & (e["t"] <= 1268.0)
    assert valid[creep].all()  # still promised: 0.05 m/s is far inside the frame's 1.275
    assert beyond[creep].sum() == 0, e["t"][creep & beyond][:5]
    assert beyond.sum() == 0


def test_the_law_is_learned_on_the_force_the_model_is_given(tmp_path, monkeypatch):
    # the suite's dual_circle (flat, a 0.15 m/s^2 lateral offset: road.py calls it a 0.88 deg bank, which no
    # sensor tells from an offset): with MODEL_TYRE_FORCE the model takes the specific force less the offset,
    # and the learners (SingleTrackFusion.adapt_from, StiffnessRegression) must regress vy on that same force.
    # Learned on the kinematic ay they fitted a law to the other force, and the model missed by the
    # difference: sideslip RMS above 5 m/s 0.1003 deg (target 0.1; flag off 0.0910), 0.0964 learned alike.
    from ecu_daemon.sim.suite import SUITE
    from ecu_daemon.suite import TARGETS
    monkeypatch.setattr(core, "MODEL_TYRE_FORCE", True)
    case = {c.name: c for c in SUITE}["dual_circle"]
    row = run_case(case, tmp_path)
    assert not any(f.startswith("error") for f in row["failed"]), row["failed"]
    assert row["sideslip_rms_above_5mps_deg"] <= TARGETS["dual_antenna_sideslip_rms_above_5mps_deg"], row
