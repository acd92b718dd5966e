"""The model's bound holds only up to the grip the drive has shown its law at (issue 7, mstd47;
``core.MODEL_BOUND_GRIP_SHOWN``, ``AxleRls.n2_shown``).

Found by tools/random_drives.py (generator v1, seed 3332, written out below so that it does not
depend on the generator): a J-turn at 14.6 m/s on mu 0.255, the car's first corner, exact
configuration. Both axles reach the road's limit alike (front 4.8 deg, rear 3.3 deg of slip, each
~3x its linear law's): the steering's misfit, which sees only the difference, stayed at 1.4 of its
sigmas, while the rear law (lateral force normalised by g, 0.25 g: "linear") put vy 2.1 deg of
sideslip off at its own 0.5 deg. On main (e0a190a) the model's bound published 0.55 deg where the
filter's own std was 0.76: 112 valid rows beyond 3 sigma, worst 2.03 deg, coverage 0.980.
"""
from __future__ import annotations

import pytest

from ecu_daemon.estimator import core
from ecu_daemon.estimator.fusion.single_track import AxleRls
from ecu_daemon.sim.scenario import Scenario
from ecu_daemon.sim.sensors import GnssParams, SensorParams
from ecu_daemon.sim.suite import SuiteCase
from ecu_daemon.sim.tyre import TyreParams
from ecu_daemon.sim.vehicle import VehicleParams
from ecu_daemon.suite import run_case

J_TURN_AT_THE_LIMIT = Scenario(name='random_v1_s3332', manoeuvre='j_turn', mu=0.255, mu_change=None,
    bank_rad=0.0, grade_rad=0.0, vehicle=VehicleParams(mass_kg=2154.4, yaw_inertia_kgm2=3151.8, lf_m=1.225,
    lr_m=1.35, track_m=1.537, cg_height_m=0.659, wheel_radius_m=0.3586, wheel_inertia_kgm2=1.2,
    steering_ratio=14.17, ackermann=1.0, roll_stiffness_front_share=0.588, roll_gradient_rad_per_g=0.04066,
    suspension_lag_s=0.05, tyre_front=TyreParams(fz0_n=4000.0, ky1=13.57, ky2=2.0, kx1=18.0, shape_c=1.3,
    curv_e=-1.5, relaxation_length_m=0.0), tyre_rear=TyreParams(fz0_n=4000.0, ky1=18.6, ky2=2.0, kx1=18.0,
    shape_c=1.3, curv_e=-1.5, relaxation_length_m=0.0), driven_axle='front', max_drive_power_w=73000.0,
    max_drive_force_n=7000.0, brake_front_share=0.65, drag_area_m2=0.68, air_density=1.2,
    rolling_resistance=0.012), sensors=SensorParams(can_rate_hz=None, jitter_s=0.00029, usb_batch_s=0.0,
    yaw_rate_bias_radps=-0.002406, accel_x_bias_mps2=-0.163, accel_y_bias_mps2=0.099, wheel_scale=0.9865,
    steering_offset_rad=0.03503, yaw_rate_noise_radps=0.003234, accel_noise_mps2=0.075,
    wheel_speed_noise_mps=0.01, steering_noise_rad=0.003966, wheel_speed_min_mps=0.15, wheel_lag_s=0.0159,
    faults=(), magnetometer=None, roll_rate=False, roll_rate_bias_radps=0.005235987755982988,
    roll_rate_noise_radps=0.0013962634015954637, imu_position_m=(0.0, 0.0, 0.0), imu_mounting_rpy_deg=(0.0,
    0.0, 0.0)), gnss=GnssParams(protocol='nmea', rate_hz=4.0, latency_s=0.498, latency_jitter_s=0.0079,
    vel_noise_mps=0.141, speed_acc_mps=0.261, lever_arm_m=(1.92, -0.32), pos_noise_m=2.94, pos_tau_s=16.7,
    num_sv=13, nmea_stagger_s=0.004, lat0_deg=48.137, lon0_deg=11.575, height_m=520.0, faults=(),
    dual_antenna=False, baseline_m=1.2, baseline_offset_deg=0.0, heading_noise_deg_1m=0.2,
    down_noise_m=0.007, fuse_elevation=False, alt_noise_m=1.2, nmea_altitude=True), gnss2=None, seed=3332,
    duration_s=None, heading0_rad=2.7485, description='random drive seed 3332, generator v1', params=(),
    config_errors=(), latency_prior_s=None, imu_in_config=True, relaxation_in_config=False)


def test_a_first_corner_at_the_roads_limit_is_not_vouched_for_by_the_model(tmp_path, monkeypatch):
    """main: 112 valid rows beyond 3 sigma (coverage 0.980), worst 2.03 deg; with the gate 0 rows
    (the flag is off by default: core.MODEL_BOUND_GRIP_SHOWN says why)."""
    monkeypatch.setattr(core, "MODEL_BOUND_GRIP_SHOWN", True)
    sc = J_TURN_AT_THE_LIMIT
    row = run_case(SuiteCase(sc.name, "random", sc), tmp_path)
    assert not any(f.startswith("error") for f in row["failed"]), row["failed"]
    assert row["sideslip_coverage_3sigma"] >= 0.99, row["sideslip_coverage_3sigma"]
    assert row["sideslip_worst_valid_deg"] < 2.0, row["sideslip_worst_valid_deg"]


def test_the_grip_shown_is_where_a_data_told_vy_found_the_law():
    """An update whose vy the law explains (within its 3 sigma) raises the grip shown to its
    |ay|; one where the tyre slipped 3x its law (a saturated axle) does not; nor does a lower |ay|
    lower it."""
    k1 = 1500.0 / 100000.0
    axle = AxleRls(k1)
    assert axle.n2_shown == 0.0
    phi, n = -20.0 * 1.2 * 2.0 / 2.7, 0.2  # a 0.2 g corner at 20 m/s
    y_law, _ = axle.predict(phi, n * n, True)
    axle.update(phi, n * n, y_law, 0.05 ** 2)
    assert axle.n2_shown == pytest.approx(n * n)
    axle.update(phi, 0.1 ** 2, y_law / 2.0, 0.05 ** 2)
    assert axle.n2_shown == pytest.approx(n * n)
    n2 = 0.25 ** 2
    y_sat, _ = axle.predict(phi * 1.25, n2, True)
    axle.update(phi * 1.25, n2, 3.0 * y_sat, 0.05 ** 2)  # the brush tyre at full utilisation: 3x
    assert axle.n2_shown == pytest.approx(n * n)
