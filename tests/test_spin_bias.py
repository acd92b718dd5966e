"""A spin's re-initialisation keeps the gyro's bias (issue 7, random drive 424; core.SPIN_KEEPS_GYRO_BIAS).

Found by tools/random_drives.py (generator v1, seed 424, written out below so that it does not
depend on the generator): a rear-driven car (111 kW) runs the demo drive on mu 0.415, spins in the
slalom (23-31 s), stops, and drives on after the friction has dropped to 0.235 (30.7 s): a 40 m
circle at 5-6.5 m/s up a 5.6 % grade, the rear on its limit (rear slip 4-5.7 deg, the law's 0.4).
The spin's re-initialisation started the yaw-rate bias from the warm-restart prior (std 0.3 deg/s)
although the filter had it within 0.004 deg/s (std 0.007) when the slide began. In the circle
GNSS course alone cannot split heading from sideslip, the rear law pulled vy to its 0.4 deg,
and the filter learned the bias 0.3 deg/s wrong to reconcile them: the heading drifted 6 deg off
at a 1.4 deg std, flagged valid (review35: heading coverage 0.614, 1906 of 4941 valid rows beyond 3
sigma, worst 6.48 deg; bias 0.36 deg/s off).

Replayed end to end through the suite's own scoring (simulate, CAN/GNSS files, replay, evaluate).
"""
from __future__ import annotations

import math

import numpy as np

from ecu_daemon.evaluate import read_csv
from ecu_daemon.sim.scenario import Scenario
from ecu_daemon.sim.sensors import GnssParams, SensorParams
from ecu_daemon.sim.suite import SuiteCase
from ecu_daemon.sim.tyre import TyreParams
from ecu_daemon.sim.vehicle import VehicleParams
from ecu_daemon.suite import run_case

SPIN_THEN_LIMIT_CIRCLE = Scenario(name='random_v1_s424', manoeuvre='demo', mu=0.415, mu_change=(30.7, 0.235), bank_rad=-0.04789,
    grade_rad=0.05565, vehicle=VehicleParams(mass_kg=2146.5, yaw_inertia_kgm2=3748.9, lf_m=1.317,
    lr_m=1.546, track_m=1.518, cg_height_m=0.692, wheel_radius_m=0.3213, wheel_inertia_kgm2=1.2,
    steering_ratio=17.8, ackermann=1.0, roll_stiffness_front_share=0.625,
    roll_gradient_rad_per_g=0.06146, suspension_lag_s=0.05, tyre_front=TyreParams(fz0_n=4000.0,
    ky1=13.82, ky2=2.0, kx1=18.0, shape_c=1.3, curv_e=-1.5, relaxation_length_m=0.0),
    tyre_rear=TyreParams(fz0_n=4000.0, ky1=19.53, ky2=2.0, kx1=18.0, shape_c=1.3, curv_e=-1.5,
    relaxation_length_m=0.0), driven_axle='rear', max_drive_power_w=111000.0, max_drive_force_n=7000.0,
    brake_front_share=0.65, drag_area_m2=0.68, air_density=1.2, rolling_resistance=0.012),
    sensors=SensorParams(can_rate_hz=None, jitter_s=0.00062, usb_batch_s=0.0,
    yaw_rate_bias_radps=0.000281, accel_x_bias_mps2=-0.067, accel_y_bias_mps2=0.115, wheel_scale=0.9954,
    steering_offset_rad=0.03304, yaw_rate_noise_radps=0.002464, accel_noise_mps2=0.077,
    wheel_speed_noise_mps=0.045, steering_noise_rad=0.003565, wheel_speed_min_mps=0.15,
    wheel_lag_s=0.0068, faults=(), magnetometer=None, roll_rate=False,
    roll_rate_bias_radps=0.005235987755982988, roll_rate_noise_radps=0.0013962634015954637,
    imu_position_m=(0.0, 0.0, 0.0), imu_mounting_rpy_deg=(0.0, 0.0, 0.0)),
    gnss=GnssParams(protocol='ubx', rate_hz=10.0, latency_s=0.268, latency_jitter_s=0.0127,
    vel_noise_mps=0.042, speed_acc_mps=0.106, lever_arm_m=(1.6, -0.24), pos_noise_m=2.0, pos_tau_s=17.4,
    num_sv=16, nmea_stagger_s=0.004, lat0_deg=48.137, lon0_deg=11.575, height_m=520.0, faults=(),
    dual_antenna=False, baseline_m=1.2, baseline_offset_deg=0.0, heading_noise_deg_1m=0.2,
    down_noise_m=0.007, fuse_elevation=False, alt_noise_m=1.2, nmea_altitude=True), gnss2=None,
    seed=424, duration_s=None, heading0_rad=1.60512, description='random drive seed 424, generator v1',
    params=(), config_errors=(('mass', 1.02), ('inertia', 1.186), ('cf', 0.932), ('cr', 1.048)),
    latency_prior_s=None, imu_in_config=True, relaxation_in_config=False)


def test_after_a_spin_the_heading_keeps_its_promise_on_the_gyro_bias_learned_before_it(tmp_path):
    sc = SPIN_THEN_LIMIT_CIRCLE
    row = run_case(SuiteCase(sc.name, "random", sc), tmp_path)
    assert not any(f.startswith("error") for f in row["failed"]), row["failed"]
    assert row["spun_out"]
    # review35: 0.614 and 6.48 deg (the bias learned 0.3 deg/s wrong in the circle after the spin)
    assert row["heading_coverage_3sigma"] >= 0.95, row["heading_coverage_3sigma"]
    assert row["heading_worst_valid_deg"] <= 3.0, row["heading_worst_valid_deg"]
    d = tmp_path / sc.name
    est = read_csv(d / "estimate.csv", ("t", "yaw_rate_bias_radps"), "estimate")
    truth = read_csv(d / "truth.csv", ("t", "yaw_rate_bias_radps"), "truth")
    t = est["t"] - est["t"][0]
    after = (t > 35.0) & (t < 60.0)  # re-initialised at ~31 s; the limit circle is 45-60 s
    err = est["yaw_rate_bias_radps"][after] - np.interp(est["t"][after], truth["t"], truth["yaw_rate_bias_radps"])
    # review35: up to 0.36 deg/s off; the bias before the slide was 0.004 deg/s off
    assert np.max(np.abs(err)) < math.radians(0.05), math.degrees(np.max(np.abs(err)))
