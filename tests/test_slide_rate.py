"""A car sliding on ice with both axles at their limit: sideslip valid 17.5 deg off (issue 7, the worst defect).

Found on the never-seen random drives 2161-2400 (generator v1, seed 2254, written out below so that it does
not depend on the generator, cut at 46 s, 2.5 s after the slide): an all-wheel-drive double lane change on
mu 0.208 dropping to 0.099 at 38.8 s. Sliding out of the lane change (front and rear slip both ~15 deg, vx
12 m/s, ay 0.87 m/s^2 against r vx 1.68: vy falling at 0.8 m/s^2), the steering passed through L r / vx at
1243.3 s, the steering's misfit (law_excess_var) fell from 0.96 to 0 (m/s)^2, and the single-track
pseudo-measurement, back at full weight (its std 10.3 -> 0.32 m/s), moved vy from -2.1 to -0.3 m/s (the model
said +0.12; true -2.9): sideslip -0.4 deg at 0.8 deg std. At 1244.14 s the yaw acceleration passed
MODEL_STEADY_RDOT and the held excess (the least of the steady stretch that held the zero crossing: 0) let
the model in again: published valid at 1244.30-1244.52 s, -0.2..+0.4 deg +- 0.6 for a true -17.6 (main
7f4496e: 40 of 4388 valid rows beyond 3 sigma, worst 17.5 deg). fusion/slide_rate.py (core.SLIDE_RATE)
measures the slide from the kinematics (vy changes at ay - r vx while the model's vy stands still) and widens
the model by it. With the flag off the drive test fails: worst valid sideslip error 17.5 deg (coverage 0.995 on the cut drive,
40 rows beyond 3 sigma of 4388 on the whole one).
"""
from __future__ import annotations

import math

from ecu_daemon.sim.scenario import Scenario
from ecu_daemon.sim.sensors import GnssParams, SensorParams
from ecu_daemon.sim.suite import SuiteCase
from ecu_daemon.sim.tyre import TyreParams
from ecu_daemon.sim.vehicle import VehicleParams
from ecu_daemon.suite import run_case

SLIDE_ON_ICE = Scenario(name='random_v1_s2254', manoeuvre='double_lane_change', mu=0.208, mu_change=(38.8, 0.099), bank_rad=0.0, grade_rad=0.0, vehicle=VehicleParams(mass_kg=1260.1, yaw_inertia_kgm2=2259.6, lf_m=1.18, lr_m=1.673, track_m=1.578, cg_height_m=0.488, wheel_radius_m=0.3275, wheel_inertia_kgm2=1.2, steering_ratio=17.91, ackermann=1.0, roll_stiffness_front_share=0.607, roll_gradient_rad_per_g=0.03704, suspension_lag_s=0.05, tyre_front=TyreParams(fz0_n=4000.0, ky1=15.28, ky2=2.0, kx1=18.0, shape_c=1.3, curv_e=-1.5, relaxation_length_m=0.0), tyre_rear=TyreParams(fz0_n=4000.0, ky1=22.49, ky2=2.0, kx1=18.0, shape_c=1.3, curv_e=-1.5, relaxation_length_m=0.0), driven_axle='all', max_drive_power_w=87000.0, max_drive_force_n=7000.0, brake_front_share=0.65, drag_area_m2=0.68, air_density=1.2, rolling_resistance=0.012), sensors=SensorParams(can_rate_hz=None, jitter_s=0.00017, usb_batch_s=0.0, yaw_rate_bias_radps=-0.008943, accel_x_bias_mps2=0.14, accel_y_bias_mps2=-0.089, wheel_scale=0.9932, steering_offset_rad=-0.04932, yaw_rate_noise_radps=0.001918, accel_noise_mps2=0.106, wheel_speed_noise_mps=0.019, steering_noise_rad=0.002172, wheel_speed_min_mps=0.15, wheel_lag_s=0.0, faults=(), magnetometer=None, roll_rate=False, roll_rate_bias_radps=0.005235987755982988, roll_rate_noise_radps=0.0013962634015954637, imu_position_m=(0.0, 0.0, 0.0), imu_mounting_rpy_deg=(0.0, 0.0, 0.0)), gnss=GnssParams(protocol='nmea', rate_hz=10.0, latency_s=0.554, latency_jitter_s=0.0033, vel_noise_mps=0.145, speed_acc_mps=0.401, lever_arm_m=(0.05, -0.45), pos_noise_m=0.89, pos_tau_s=59.6, num_sv=6, nmea_stagger_s=0.004, lat0_deg=48.137, lon0_deg=11.575, height_m=520.0, faults=(), dual_antenna=False, baseline_m=1.2, baseline_offset_deg=0.0, heading_noise_deg_1m=0.2, down_noise_m=0.007, fuse_elevation=False, alt_noise_m=1.2, nmea_altitude=True), gnss2=None, seed=2254, duration_s=46.0, heading0_rad=0.85316, description='random drive seed 2254, generator v1', params=(), config_errors=(('inertia', 1.174), ('cf', 0.832), ('cr', 0.861)), latency_prior_s=None, imu_in_config=True, relaxation_in_config=False)


def test_a_slide_with_both_axles_at_their_limit_is_not_promised(tmp_path):
    sc = SLIDE_ON_ICE
    row = run_case(SuiteCase(sc.name, "random", sc), tmp_path)
    assert not any(f.startswith("error") for f in row["failed"]), row["failed"]
    # main 7f4496e: 40 valid rows 17.5 deg off at 0.6 deg std
    assert row["sideslip_worst_valid_deg"] < 2.0, row["sideslip_worst_valid_deg"]
    assert row["sideslip_coverage_3sigma"] >= 0.99, row["sideslip_coverage_3sigma"]
    assert row["heading_coverage_3sigma"] >= 0.99, row["heading_coverage_3sigma"]


def test_the_kinematics_against_a_still_model_measure_the_slide():
    """The rule itself, at 2254's 1243.3 s: vx 12 m/s, r 0.137 rad/s, ay 0.92 m/s^2, the model's vy steady at
    +0.12 m/s (its own std 0.05): vy leaves the model at 0.72 m/s^2; integrated with the model's 2 s memory,
    after 2 s that is 0.91 m/s, 0.3 m/s beyond the residual offsets' and the model's 3 sigma (0.61 m/s);
    a gripping car in the same corner (ay = r vx) leaves nothing."""
    from ecu_daemon.estimator import core
    from ecu_daemon.estimator.fusion.slide_rate import SlideRate
    assert core.SLIDE_RATE
    dt = 0.006
    sliding, gripping = SlideRate(dt), SlideRate(dt)
    for _ in range(int(round(2.0 / dt))):
        v_s = sliding.step(12.0, 0.137, 0.92, 0.12, 0.05)
        v_g = gripping.step(12.0, 0.137, 0.137 * 12.0, 0.12, 0.05)
    assert v_g == 0.0
    assert 0.25 < math.sqrt(v_s) < 0.35, math.sqrt(v_s)
    # a restart (or the IMU substituted, or below 3 m/s) forgets it
    assert sliding.step(2.0, 0.137, 0.92, 0.12, 0.05) == 0.0 and sliding.e == 0.0
