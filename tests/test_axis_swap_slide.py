"""A slide is no evidence that the accelerometer's axes are swapped (core.AXIS_SWAP_SLIDE,
axis_swap_check.SWAP_RVY_MPS2; issue 7, random drive 499, tools/random_drives.py generator v1).

Why: the check's witness (ax = dv/dt, ay = r vx) leaves r vy out. Drive 499 (a j-turn on mu 0.35,
rear-driven) spins 180 deg to a stop: at 28.9-29.3 s vx 1.3 -> -0.4 m/s, vy 3.4-4.3 m/s, r -1 rad/s,
|r vy| ~4 m/s^2 against the check's tolerance of 1; five windows voted "swapped" after 26 as-mapped
ones and the verdict stood to the end of the drive (the straight that follows tells the mappings
nothing): heading valid above 5 m/s 0.500 (0.687 without the verdict), coverage 1.0. The filter's
|r| (|vy| + 3 std) was 4.5-5.2 m/s^2 there: beyond the tolerance the window judges nothing.
On holdrel37 with core.AXIS_SWAP_SLIDE = False the drive test fails (heading 0.500).
tests/test_accel_axes_swapped.py keeps what the check finds (a swapped circle, a swapped lane change).
"""
from __future__ import annotations

import math

from ecu_daemon.estimator.axis_swap_check import SWAP_RVY_MPS2, AxisSwapCheck
from ecu_daemon.sim.scenario import Scenario
from ecu_daemon.sim.sensors import GnssParams, SensorParams
from ecu_daemon.sim.suite import SuiteCase
from ecu_daemon.sim.tyre import TyreParams
from ecu_daemon.sim.vehicle import VehicleParams
from ecu_daemon.suite import run_case

SPIN_TO_A_STOP = Scenario(name='random_v1_s499', manoeuvre='j_turn', mu=0.35, mu_change=None, bank_rad=-0.05321,
    grade_rad=0.03671, vehicle=VehicleParams(mass_kg=1190.4, yaw_inertia_kgm2=2355.0, lf_m=1.217, lr_m=1.481,
    track_m=1.695, cg_height_m=0.57, wheel_radius_m=0.3469, wheel_inertia_kgm2=1.2, steering_ratio=14.56,
    ackermann=1.0, roll_stiffness_front_share=0.636, roll_gradient_rad_per_g=0.06206, suspension_lag_s=0.05,
    tyre_front=TyreParams(fz0_n=4000.0, ky1=16.39, ky2=2.0, kx1=18.0, shape_c=1.3, curv_e=-1.5,
    relaxation_length_m=0.0), tyre_rear=TyreParams(fz0_n=4000.0, ky1=24.1, ky2=2.0, kx1=18.0, shape_c=1.3,
    curv_e=-1.5, relaxation_length_m=0.0), driven_axle='rear', max_drive_power_w=219000.0,
    max_drive_force_n=7000.0, brake_front_share=0.65, drag_area_m2=0.68, air_density=1.2,
    rolling_resistance=0.012), sensors=SensorParams(can_rate_hz=None, jitter_s=0.00018, usb_batch_s=0.0,
    yaw_rate_bias_radps=0.009595, accel_x_bias_mps2=-0.19, accel_y_bias_mps2=-0.074, wheel_scale=1.0049,
    steering_offset_rad=-0.0322, yaw_rate_noise_radps=0.003149, accel_noise_mps2=0.057,
    wheel_speed_noise_mps=0.017, steering_noise_rad=0.003242, wheel_speed_min_mps=0.15, wheel_lag_s=0.014,
    faults=(), magnetometer=None, roll_rate=False, roll_rate_bias_radps=0.005235987755982988,
    roll_rate_noise_radps=0.0013962634015954637, imu_position_m=(0.0, 0.0, 0.0), imu_mounting_rpy_deg=(0.0,
    0.0, 0.0)), gnss=GnssParams(protocol='ubx', rate_hz=1.0, latency_s=0.459, latency_jitter_s=0.006,
    vel_noise_mps=0.138, speed_acc_mps=0.191, lever_arm_m=(-0.35, 0.14), pos_noise_m=2.64, pos_tau_s=43.0,
    num_sv=8, nmea_stagger_s=0.004, lat0_deg=48.137, lon0_deg=11.575, height_m=520.0, faults=(),
    dual_antenna=False, baseline_m=1.2, baseline_offset_deg=0.0, heading_noise_deg_1m=0.2, down_noise_m=0.007,
    fuse_elevation=False, alt_noise_m=1.2, nmea_altitude=True), gnss2=None, seed=499, duration_s=None,
    heading0_rad=4.61666, description='random drive seed 499, generator v1', params=(),
    config_errors=(('inertia', 1.224),), latency_prior_s=0.633, imu_in_config=True,
    relaxation_in_config=False)

DT = 0.006


def test_a_spin_to_a_stop_is_not_a_swapped_mapping(tmp_path):
    row = run_case(SuiteCase(SPIN_TO_A_STOP.name, "random", SPIN_TO_A_STOP), tmp_path)
    assert not any(f.startswith("error") for f in row["failed"]), row["failed"]
    assert row["heading_valid_above_5mps"] >= 0.6, row["heading_valid_above_5mps"]
    for q in ("sideslip", "heading", "vx"):
        assert row[f"{q}_coverage_3sigma"] >= 0.99, (q, row[f"{q}_coverage_3sigma"])


def test_windows_over_a_slide_vote_for_neither_mapping():
    """The synthetic swapped corner of test_accel_axes_swapped (ax reads r vx = 6, ay 0.2) convicts
    within a second; the same data with the filter's r vy bound beyond the tolerance never votes."""
    def run(rvy):
        chk = AxisSwapCheck(DT)
        said = 0
        for k in range(int(round(2.0 / DT))):
            said += chk.step(k, 10.0, 6.0, 0.2, 0.6, 10.0, rvy)
        return chk, said
    chk, said = run(0.5 * SWAP_RVY_MPS2)
    assert chk.swapped and said == 1
    chk, said = run(2.0 * SWAP_RVY_MPS2)
    assert not chk.swapped and said == 0 and chk.windows == [0, 0]
    assert all(x is None for x in chk._ring) and not math.isnan(chk.dt)
