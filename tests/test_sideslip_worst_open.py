"""Sideslip flagged valid just over 2 deg off (3.1-3.2 sigma at the validity line): two cases
(issue 7; tools/random_drives.py generator v1, the Scenarios written out), both fixed since. Diagnosed in /work/wt/_reports/slip35.md; neither is the driven-axle limit
fusion/drive_slip.py covers (both are all-wheel drive), and they are not one rule:

* drive 239 (all-wheel drive, j_turn on mu 0.245, 7.8 % downhill, spins out): at 21.9 s the car is
  on its limit (ay 2.37 m/s^2 = mu g, held) and both axles' slip grows alike (front 2 -> 5 deg,
  rear 1.3 -> 4.8 deg within 1.4 s): a neutral car leaving its law, which the steering's misfit
  cannot see, with no free axle to measure. The filter's sideslip error grows 0.1 -> 2.0 deg while
  its std grows 0.43 -> 0.66 deg: 3 rows valid at 2.00-2.04 deg (std 0.66-0.67). Fixed (brake37,
  core.BRAKE_GRIP): the car brakes downhill at its limit, the rear's load moves forward and its brakes
  take their share of its ellipse; widened for it, worst valid 0.74 deg (2.12 with BRAKE_GRIP off), so
  this case is a regression test now.
* drive 217 (all-wheel drive, dry road course, mu 0.95, latency prior 0.80 s for 0.64): the
  latency never leaves the prior (0.80 -> 0.78 s). In a 0.44 g turn-in at 24 m/s (yaw rate
  0.18 rad/s) the 0.16 s timing error turns the GNSS course by ~1.7 deg, which the filter puts
  into sideslip (heading error 0.15 deg): error -0.5 -> -2.1 deg within 1.2 s at a std of
  0.50 -> 0.67 deg: 12 rows valid at 2.03-2.12 deg. The latency prior's mode E (closing note 34,
  lat34), not the tyre law. Fixed (latstuck35): the all-wheel-drive wheels' traction slip led the
  car by ~0.1 s in the timing regression (latency.LatencyEstimator.observe), so this case is a
  regression test now.
"""
from __future__ import annotations

import pytest

from ecu_daemon.sim.scenario import Scenario
from ecu_daemon.sim.sensors import GnssParams, SensorParams
from ecu_daemon.sim.suite import SuiteCase
from ecu_daemon.sim.tyre import TyreParams
from ecu_daemon.sim.vehicle import VehicleParams
from ecu_daemon.suite import run_case

NEUTRAL_SLIDE_AWD = Scenario(name='random_v1_s239', manoeuvre='j_turn', mu=0.245, mu_change=None,
    bank_rad=-0.01851, grade_rad=-0.07773, vehicle=VehicleParams(mass_kg=2148.7,
    yaw_inertia_kgm2=2887.3, lf_m=1.022, lr_m=1.559, track_m=1.668, cg_height_m=0.481,
    wheel_radius_m=0.3068, wheel_inertia_kgm2=1.2, steering_ratio=17.18, ackermann=1.0,
    roll_stiffness_front_share=0.591, roll_gradient_rad_per_g=0.06815, suspension_lag_s=0.05,
    tyre_front=TyreParams(fz0_n=4000.0, ky1=14.93, ky2=2.0, kx1=18.0, shape_c=1.3, curv_e=-1.5,
    relaxation_length_m=0.0), tyre_rear=TyreParams(fz0_n=4000.0, ky1=16.61, ky2=2.0, kx1=18.0,
    shape_c=1.3, curv_e=-1.5, relaxation_length_m=0.0), driven_axle='all',
    max_drive_power_w=244000.0, max_drive_force_n=7000.0, brake_front_share=0.65, drag_area_m2=0.68,
    air_density=1.2, rolling_resistance=0.012), sensors=SensorParams(can_rate_hz=None,
    jitter_s=0.00078, usb_batch_s=0.0, yaw_rate_bias_radps=0.009053, accel_x_bias_mps2=0.151,
    accel_y_bias_mps2=-0.009, wheel_scale=1.0293, steering_offset_rad=-0.04284,
    yaw_rate_noise_radps=0.003355, accel_noise_mps2=0.076, wheel_speed_noise_mps=0.027,
    steering_noise_rad=0.001809, wheel_speed_min_mps=0.15, wheel_lag_s=0.0071, faults=(),
    magnetometer=None, roll_rate=False, roll_rate_bias_radps=0.005235987755982988,
    roll_rate_noise_radps=0.0013962634015954637, imu_position_m=(0.0, 0.0, 0.0),
    imu_mounting_rpy_deg=(0.0, 0.0, 0.0)), gnss=GnssParams(protocol='ubx', rate_hz=5.0,
    latency_s=0.495, latency_jitter_s=0.0049, vel_noise_mps=0.114, speed_acc_mps=0.292,
    lever_arm_m=(1.44, 0.55), pos_noise_m=2.39, pos_tau_s=32.0, num_sv=10, nmea_stagger_s=0.004,
    lat0_deg=48.137, lon0_deg=11.575, height_m=520.0, faults=(), dual_antenna=False, baseline_m=1.2,
    baseline_offset_deg=0.0, heading_noise_deg_1m=0.2, down_noise_m=0.007, fuse_elevation=False,
    alt_noise_m=1.2, nmea_altitude=True), gnss2=None, seed=239, duration_s=None,
    heading0_rad=0.95725, description='random drive seed 239, generator v1', params=(),
    config_errors=(('mass', 0.997), ('inertia', 0.885)), latency_prior_s=None, imu_in_config=True,
    relaxation_in_config=False)

LATE_PRIOR_TURN_IN = Scenario(name='random_v1_s217', manoeuvre='road_course', mu=0.95,
    mu_change=None, bank_rad=0.03477, grade_rad=0.02522, vehicle=VehicleParams(mass_kg=2344.9,
    yaw_inertia_kgm2=4165.5, lf_m=1.082, lr_m=1.703, track_m=1.687, cg_height_m=0.688,
    wheel_radius_m=0.2933, wheel_inertia_kgm2=1.2, steering_ratio=17.58, ackermann=1.0,
    roll_stiffness_front_share=0.645, roll_gradient_rad_per_g=0.05954, suspension_lag_s=0.05,
    tyre_front=TyreParams(fz0_n=4000.0, ky1=11.65, ky2=2.0, kx1=18.0, shape_c=1.3, curv_e=-1.5,
    relaxation_length_m=0.0), tyre_rear=TyreParams(fz0_n=4000.0, ky1=17.63, ky2=2.0, kx1=18.0,
    shape_c=1.3, curv_e=-1.5, relaxation_length_m=0.0), driven_axle='all',
    max_drive_power_w=121000.0, max_drive_force_n=7000.0, brake_front_share=0.65, drag_area_m2=0.68,
    air_density=1.2, rolling_resistance=0.012), sensors=SensorParams(can_rate_hz=None,
    jitter_s=0.00049, usb_batch_s=0.0, yaw_rate_bias_radps=0.015856, accel_x_bias_mps2=-0.087,
    accel_y_bias_mps2=0.216, wheel_scale=0.9935, steering_offset_rad=0.032,
    yaw_rate_noise_radps=0.001151, accel_noise_mps2=0.049, wheel_speed_noise_mps=0.022,
    steering_noise_rad=0.004748, wheel_speed_min_mps=0.15, wheel_lag_s=0.0018, faults=(),
    magnetometer=None, roll_rate=False, roll_rate_bias_radps=0.005235987755982988,
    roll_rate_noise_radps=0.0013962634015954637, imu_position_m=(0.0, 0.0, 0.0),
    imu_mounting_rpy_deg=(0.0, 0.0, 0.0)), gnss=GnssParams(protocol='ubx', rate_hz=4.0,
    latency_s=0.639, latency_jitter_s=0.0036, vel_noise_mps=0.145, speed_acc_mps=0.155,
    lever_arm_m=(-0.05, -0.03), pos_noise_m=1.71, pos_tau_s=29.0, num_sv=18, nmea_stagger_s=0.004,
    lat0_deg=48.137, lon0_deg=11.575, height_m=520.0, faults=(), dual_antenna=False, baseline_m=1.2,
    baseline_offset_deg=0.0, heading_noise_deg_1m=0.2, down_noise_m=0.007, fuse_elevation=False,
    alt_noise_m=1.2, nmea_altitude=True), gnss2=None, seed=217, duration_s=None,
    heading0_rad=4.6248, description='random drive seed 217, generator v1', params=(('profile',
    'country'),), config_errors=(), latency_prior_s=0.8, imu_in_config=True,
    relaxation_in_config=False)


@pytest.mark.parametrize("sc", [NEUTRAL_SLIDE_AWD, LATE_PRIOR_TURN_IN],
                         ids=["neutral_slide_awd_s239", "late_prior_turn_in_s217"])
def test_sideslip_valid_is_never_more_than_2_deg_off(sc, tmp_path):
    row = run_case(SuiteCase(sc.name, "random", sc), tmp_path)
    assert not any(f.startswith("error") for f in row["failed"]), row["failed"]
    assert row["sideslip_worst_valid_deg"] <= 2.0, row["sideslip_worst_valid_deg"]
