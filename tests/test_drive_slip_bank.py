"""Sideslip promised at a 0.3 deg std while 1 deg off: a rear-driven car's rear wheels spinning up a banked
hill on ice (issue 7, the worst defect; core.DRIVE_SLIP_TYRE_FORCE, fusion/tyre_lateral_force.py).

Found by tools/random_drives.py (generator v1, seed 1714, written out below so that it does not depend
on the generator). On main (b26daff; its estimator that of 72e47bf): a low-speed manoeuvre, rear drive,
mu 0.361 dropping to 0.162 at 14.2 s, +3.9 % grade, bank -1.9 deg. After a slide in the circle (rear slip
4 deg, correctly invalid) the car accelerates uphill (1256-1262 s) with the rear wheels 5-9 % ahead of the
free front, the rear axle's whole mu F_z spent on the drive (specific force ~0.7 m/s^2), and the tyres
holding the car against the bank (~0.3 m/s^2 of lateral force at a kinematic ay ~0): rear slip angle
-1 deg. The drive-slip rule (fusion/drive_slip.py) saw the slip but took the rear's lateral force from
the model's ay, the bank taken out with b_ay: its angle ~0.1 deg, no widening; the filter held the law's
0 at a 0.29-0.38 deg std: 117 of 1779 valid sideslip rows beyond 3 sigma, worst 4.63 deg.

Replayed end to end through the suite's own scoring (simulate, CAN/GNSS files, replay, evaluate).
With core.DRIVE_SLIP_TYRE_FORCE False (main) the end-to-end test fails (seen: 39 valid rows beyond 3
sigma in the uphill stretch 1257.5-1261.9 s, 117 in all).
"""
from __future__ import annotations

import csv

import numpy as np

from ecu_daemon.estimator.fusion.tyre_lateral_force import RearLateralForce
from ecu_daemon.sim.scenario import Scenario
from ecu_daemon.sim.sensors import GnssParams, SensorParams
from ecu_daemon.sim.suite import SuiteCase
from ecu_daemon.sim.tyre import TyreParams
from ecu_daemon.sim.vehicle import VehicleParams
from ecu_daemon.suite import run_case

UPHILL_ON_ICE_BANKED = Scenario(name='random_v1_s1714', manoeuvre='low_speed', mu=0.361, mu_change=(14.2,
    0.162), bank_rad=-0.03265, grade_rad=0.03943, vehicle=VehicleParams(mass_kg=1831.9, yaw_inertia_kgm2=2504.2,
    lf_m=1.135, lr_m=1.336, track_m=1.621, cg_height_m=0.486, wheel_radius_m=0.3376, wheel_inertia_kgm2=1.2,
    steering_ratio=15.95, ackermann=1.0, roll_stiffness_front_share=0.573, roll_gradient_rad_per_g=0.05311,
    suspension_lag_s=0.05, tyre_front=TyreParams(fz0_n=4000.0, ky1=14.64, ky2=2.0, kx1=18.0, shape_c=1.3,
    curv_e=-1.5, relaxation_length_m=0.0), tyre_rear=TyreParams(fz0_n=4000.0, ky1=19.06, ky2=2.0, kx1=18.0,
    shape_c=1.3, curv_e=-1.5, relaxation_length_m=0.0), driven_axle='rear', max_drive_power_w=103000.0,
    max_drive_force_n=7000.0, brake_front_share=0.65, drag_area_m2=0.68, air_density=1.2,
    rolling_resistance=0.012), sensors=SensorParams(can_rate_hz=None, jitter_s=0.00084, usb_batch_s=0.0,
    yaw_rate_bias_radps=-0.015677, accel_x_bias_mps2=0.136, accel_y_bias_mps2=0.253, wheel_scale=1.0,
    steering_offset_rad=0.02878, yaw_rate_noise_radps=0.003359, accel_noise_mps2=0.116,
    wheel_speed_noise_mps=0.02, steering_noise_rad=0.002003, wheel_speed_min_mps=0.15, wheel_lag_s=0.0011,
    faults=(), magnetometer=None, roll_rate=False, roll_rate_bias_radps=0.005235987755982988,
    roll_rate_noise_radps=0.0013962634015954637, imu_position_m=(0.0, 0.0, 0.0), imu_mounting_rpy_deg=(0.0, 0.0,
    0.0)), gnss=GnssParams(protocol='ubx', rate_hz=8.0, latency_s=0.704, latency_jitter_s=0.0127,
    vel_noise_mps=0.089, speed_acc_mps=0.211, lever_arm_m=(-0.88, 0.31), pos_noise_m=2.75, pos_tau_s=30.4,
    num_sv=18, nmea_stagger_s=0.004, lat0_deg=48.137, lon0_deg=11.575, height_m=520.0, faults=(),
    dual_antenna=False, baseline_m=1.2, baseline_offset_deg=0.0, heading_noise_deg_1m=0.2, down_noise_m=0.007,
    fuse_elevation=False, alt_noise_m=1.2, nmea_altitude=True), gnss2=None, seed=1714, duration_s=None,
    heading0_rad=5.85217, description='random drive seed 1714, generator v1', params=(('radius_m', 16.3),
    ('v_max', 7.0)), config_errors=(('mass', 0.865), ('inertia', 1.293)), latency_prior_s=None,
    imu_in_config=True, relaxation_in_config=False)


def _columns(path, names):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    head = rows[0]
    a = np.array(rows[1:], dtype=float)
    return {n: a[:, head.index(n)] for n in names}


def test_the_rear_force_is_the_specific_force_with_its_doubt():
    f = RearLateralForce(0.006, 1.135, 1.336, 1.367)
    # drive 1714 on its straight: 0.3 m/s^2 held against the bank, the offset known to 0.15 m/s^2
    for _ in range(200):
        fy = f.step(-0.31, 0.0, 0.15)
    assert abs(fy - 1.135 * 0.31 / 2.471) < 1e-9  # the rear's share lf / L, the regressor's sign
    assert abs(f.std - 1.135 * 0.15 / 2.471) < 1e-12
    # the rule's vy at 5.2 m/s, 5.5 % slip, 0.7 m/s^2 of drive: 1 sigma of the force is 0.028 m/s
    assert 0.025 < f.angle_var(5.2, 0.055, 0.7) ** 0.5 < 0.031
    # an unheard sample holds the force; no doubt, no variance
    assert f.step(float("nan"), 0.0, 0.0) == fy
    assert f.angle_var(5.2, 0.055, 0.7) == 0.0


def test_rear_wheels_spinning_up_a_banked_hill_on_ice_keep_the_promise(tmp_path):
    sc = UPHILL_ON_ICE_BANKED
    row = run_case(SuiteCase(sc.name, "random", sc), tmp_path)
    assert not any(f.startswith("error") for f in row["failed"]), row["failed"]
    e = _columns(tmp_path / sc.name / "estimate.csv", ("t", "sideslip_rad", "sideslip_std_rad", "sideslip_valid"))
    tr = _columns(tmp_path / sc.name / "truth.csv", ("t", "sideslip_rad"))
    beta = np.interp(e["t"], tr["t"], tr["sideslip_rad"])
    beyond = (e["sideslip_valid"] == 1) & (np.abs(e["sideslip_rad"] - beta) > 3.0 * e["sideslip_std_rad"])
    # the uphill stretch on the spinning rear wheels (before the spin at 1262 s): main 39 rows beyond
    uphill = (e["t"] >= 1257.5) & (e["t"] <= 1261.9)
    assert beyond[uphill].sum() == 0, e["t"][uphill & beyond][:5]
    # the whole drive: main 117 of 1779 (coverage 0.934); left: ~12 rows at 4.95 m/s, below the
    # drive-slip rule's 5 m/s floor, and 4 at the spin's onset (1262.0 s, a transient)
    assert beyond.sum() <= 20, beyond.sum()
