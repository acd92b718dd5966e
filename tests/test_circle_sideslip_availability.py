"""Steady circle: sideslip invalid while right (issue 7, "the estimate is right, or it says it is not").

Found by tools/random_drives.py (generator v1, seed 1271, written out below so that it does not
depend on the generator). On main (88d1c19): a steady circle (21 m radius, right, front-driven,
mu 0.86, no configuration errors, one antenna at 2 Hz, 0.556 s latency against a 0.512 s prior)
ramped to 0.65 g. The sideslip is valid on 0.35 of the rows above 5 m/s; the 5972 invalid rows
above 5 m/s are 0.25 deg off (median, p95 0.41) at a published std of 0.92 deg (median), against
SIDESLIP_STD_VALID = 0.67 deg.

Diagnosis (circ40, /work/wt/_reports/circ40.md): the filter's own sideslip std in the circle is
the combination of two legs, each honest by its own physics: GNSS course through the latency's
uncertainty (a bias of r x latency std for the whole circle: 0.55 rad/s x 0.08-0.13 s at 2 Hz,
4-7 deg) and the single-track model at its configuration prior (m / C_r 40 %, the saturation
term 80 %: 0.15 + 0.12 m/s of vy at 0.64 g, ~1.0 deg at 11.5 m/s). This drive happens not to
exercise the model's prior (no configuration error), so the sideslip is right while its std
says it may not be. No fix was found in the time box: the test is a strict xfail, the target
the lead set (sideslip valid on >= 90 % of the rows above 5 m/s), with coverage kept.
"""
from __future__ import annotations

import pytest

from ecu_daemon.sim.scenario import Scenario
from ecu_daemon.sim.sensors import GnssParams, SensorParams
from ecu_daemon.sim.suite import SuiteCase
from ecu_daemon.sim.tyre import TyreParams
from ecu_daemon.sim.vehicle import VehicleParams
from ecu_daemon.suite import run_case

STEADY_CIRCLE_2HZ = Scenario(name='random_v1_s1271', manoeuvre='steady_circle', mu=0.86, mu_change=None,
    bank_rad=0.0, grade_rad=0.0, vehicle=VehicleParams(mass_kg=1250.5, yaw_inertia_kgm2=2169.2,
    lf_m=1.016, lr_m=1.578, track_m=1.669, cg_height_m=0.633, wheel_radius_m=0.3595,
    wheel_inertia_kgm2=1.2, steering_ratio=17.11, ackermann=1.0, roll_stiffness_front_share=0.589,
    roll_gradient_rad_per_g=0.04257, suspension_lag_s=0.05, tyre_front=TyreParams(fz0_n=4000.0,
    ky1=17.81, ky2=2.0, kx1=18.0, shape_c=1.3, curv_e=-1.5, relaxation_length_m=0.0),
    tyre_rear=TyreParams(fz0_n=4000.0, ky1=21.57, ky2=2.0, kx1=18.0, shape_c=1.3, curv_e=-1.5,
    relaxation_length_m=0.0), driven_axle='front', max_drive_power_w=88000.0,
    max_drive_force_n=7000.0, brake_front_share=0.65, drag_area_m2=0.68, air_density=1.2,
    rolling_resistance=0.012), sensors=SensorParams(can_rate_hz=None, jitter_s=0.00088,
    usb_batch_s=0.0, yaw_rate_bias_radps=-0.005676, accel_x_bias_mps2=-0.03, accel_y_bias_mps2=0.225,
    wheel_scale=0.973, steering_offset_rad=-0.02552, yaw_rate_noise_radps=0.001429,
    accel_noise_mps2=0.112, wheel_speed_noise_mps=0.031, steering_noise_rad=0.001666,
    wheel_speed_min_mps=0.15, wheel_lag_s=0.0, faults=(), magnetometer=None, roll_rate=False,
    roll_rate_bias_radps=0.005235987755982988, roll_rate_noise_radps=0.0013962634015954637,
    imu_position_m=(0.0, 0.0, 0.0), imu_mounting_rpy_deg=(0.0, 0.0, 0.0)),
    gnss=GnssParams(protocol='ubx', rate_hz=2.0, latency_s=0.556, latency_jitter_s=0.002,
    vel_noise_mps=0.114, speed_acc_mps=0.201, lever_arm_m=(-0.35, -0.27), pos_noise_m=0.54,
    pos_tau_s=41.5, num_sv=12, nmea_stagger_s=0.004, lat0_deg=48.137, lon0_deg=11.575,
    height_m=520.0, faults=(), dual_antenna=False, baseline_m=1.2, baseline_offset_deg=0.0,
    heading_noise_deg_1m=0.2, down_noise_m=0.007, fuse_elevation=False, alt_noise_m=1.2,
    nmea_altitude=True), gnss2=None, seed=1271, duration_s=None, heading0_rad=3.98903,
    description='random drive seed 1271, generator v1', params=(('radius_m', 21.2), ('left', False)),
    config_errors=(), latency_prior_s=0.512, imu_in_config=True, relaxation_in_config=False)


@pytest.mark.xfail(strict=True, reason="issue 7: steady circle at 2 Hz GNSS, sideslip std 3-4x its error "
                                       "(model prior + latency; circ40 found no fix in its time box)")
def test_a_steady_circle_that_is_right_says_so(tmp_path):
    sc = STEADY_CIRCLE_2HZ
    row = run_case(SuiteCase(sc.name, "random", sc), tmp_path)
    assert not any(f.startswith("error") for f in row["failed"]), row["failed"]
    # the promise first: no valid row beyond 3 sigma (main: coverage 1.0, 3817 valid rows)
    assert row["sideslip_coverage_3sigma"] >= 0.99, row["sideslip_coverage_3sigma"]
    # main: 0.35 valid above 5 m/s, the invalid rows 0.25 deg off (median) at a 0.92 deg std
    assert row["sideslip_valid_above_5mps"] >= 0.90, row["sideslip_valid_above_5mps"]
