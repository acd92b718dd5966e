"""The sideslip carries the gyro scale the heading owes (issue 7, bias47; ``core.SIDESLIP_SCALE_SENS``).

Found by tools/random_drives.py (generator v1, seed 2946, written out below so that it does not
depend on the generator): an accelerating steady circle, radius 140 m, 12 -> 30 m/s, mu 1.02, the
road banked -3.3 deg and graded -3.2 deg, one antenna at 10 Hz, C_f configured x0.82 and C_r x1.27.
The heading integrates r / cos(bank) with the bank road.py estimates (-1.3 .. -1.5 deg: with one
antenna it holds part of the 0.27 m/s^2 ay offset), so it turns 0.13 % of r too slowly, and the
yaw-rate bias learned at rest is 0.016 deg/s off (2.5 sigma of its 4.5 s of gyro noise): the heading
ends 0.9 deg off. The courses read heading - sideslip, so the sideslip is 1.0 deg off with it. The
heading's published std carried that (S_psi x the scale not applied yet, scale_sensitivity.py: 0.49
of its 0.68 deg); the sideslip's (0.33 deg, P alone) did not: on main (e0a190a) 534 valid rows beyond
3 sigma. With the sideslip's own share of the same consider term (|d beta / d s|, S_vy / vx, which
follows S_psi) 0 rows, valid above 5 m/s 98.1 -> 93.1 %. Off by default: it also withholds right
sideslips (the suite's mu03_outage_30s 91.9 -> 87.7 % valid above 5 m/s, target 90 %).
"""
from __future__ import annotations

import numpy as np
import pytest

from ecu_daemon.estimator import core
from ecu_daemon.estimator.kinematic import NX, PSI, VX, VY
from ecu_daemon.estimator.scale_sensitivity import ScaleSensitivity
from ecu_daemon.sim.scenario import Scenario
from ecu_daemon.sim.sensors import GnssParams, SensorParams
from ecu_daemon.sim.suite import SuiteCase
from ecu_daemon.sim.tyre import TyreParams
from ecu_daemon.sim.vehicle import VehicleParams
from ecu_daemon.suite import run_case

BANKED_CIRCLE = Scenario(name='random_v1_s2946', manoeuvre='steady_circle', mu=1.02, mu_change=None, bank_rad=-0.05787,
    grade_rad=-0.05617, vehicle=VehicleParams(mass_kg=1945.5, yaw_inertia_kgm2=3251.9, lf_m=1.115,
    lr_m=1.408, track_m=1.489, cg_height_m=0.473, wheel_radius_m=0.2969, wheel_inertia_kgm2=1.2,
    steering_ratio=15.34, ackermann=1.0, roll_stiffness_front_share=0.607, roll_gradient_rad_per_g=0.09909,
    suspension_lag_s=0.05, tyre_front=TyreParams(fz0_n=4000.0, ky1=11.93, ky2=2.0, kx1=18.0, shape_c=1.3,
    curv_e=-1.5, relaxation_length_m=0.0), tyre_rear=TyreParams(fz0_n=4000.0, ky1=15.01, ky2=2.0, kx1=18.0,
    shape_c=1.3, curv_e=-1.5, relaxation_length_m=0.0), driven_axle='front', max_drive_power_w=234000.0,
    max_drive_force_n=7000.0, brake_front_share=0.65, drag_area_m2=0.68, air_density=1.2,
    rolling_resistance=0.012), sensors=SensorParams(can_rate_hz=None, jitter_s=0.00027, usb_batch_s=0.0,
    yaw_rate_bias_radps=0.006031, accel_x_bias_mps2=-0.157, accel_y_bias_mps2=0.27, wheel_scale=0.9775,
    steering_offset_rad=0.02647, yaw_rate_noise_radps=0.002398, accel_noise_mps2=0.06,
    wheel_speed_noise_mps=0.032, steering_noise_rad=0.00494, wheel_speed_min_mps=0.15, wheel_lag_s=0.0002,
    faults=(), magnetometer=None, roll_rate=False, roll_rate_bias_radps=0.005235987755982988,
    roll_rate_noise_radps=0.0013962634015954637, imu_position_m=(0.0, 0.0, 0.0), imu_mounting_rpy_deg=(0.0,
    0.0, 0.0)), gnss=GnssParams(protocol='ubx', rate_hz=10.0, latency_s=0.311, latency_jitter_s=0.0025,
    vel_noise_mps=0.039, speed_acc_mps=0.076, lever_arm_m=(-0.41, -0.28), pos_noise_m=0.67, pos_tau_s=52.4,
    num_sv=13, nmea_stagger_s=0.004, lat0_deg=48.137, lon0_deg=11.575, height_m=520.0, faults=(),
    dual_antenna=False, baseline_m=1.2, baseline_offset_deg=0.0, heading_noise_deg_1m=0.2,
    down_noise_m=0.007, fuse_elevation=False, alt_noise_m=1.2, nmea_altitude=True), gnss2=None, seed=2946,
    duration_s=None, heading0_rad=5.08856, description='random drive seed 2946, generator v1',
    params=(('radius_m', 140.4), ('left', True)), config_errors=(('inertia', 1.024), ('cf', 0.818), ('cr',
    1.274)), latency_prior_s=None, imu_in_config=True, relaxation_in_config=False)


def test_the_sideslip_carries_the_scale_the_heading_owes_on_a_banked_circle(tmp_path, monkeypatch):
    """main: 534 valid sideslip rows beyond 3 sigma (94.7 %), worst 1.58 deg; with the term 0 (100 %).
    The flag is off by default (core.SIDESLIP_SCALE_SENS: the suite's mu03_outage_30s availability)."""
    monkeypatch.setattr(core, "SIDESLIP_SCALE_SENS", True)
    sc = BANKED_CIRCLE
    row = run_case(SuiteCase(sc.name, "random", sc), tmp_path)
    assert not any(f.startswith("error") for f in row["failed"]), row["failed"]
    assert row["sideslip_coverage_3sigma"] >= 0.99, row["sideslip_coverage_3sigma"]
    assert row["sideslip_worst_valid_deg"] < 2.0, row["sideslip_worst_valid_deg"]


def test_the_sideslips_sensitivity_is_vys_over_the_speed():
    """d beta / d s = (vx S_vy - vy S_vx) / (vx^2 + vy^2): S_vy / vx when vy = 0, and the vy term
    the state's own sensitivity."""
    sens = ScaleSensitivity(4, 0.006)
    S = np.zeros(NX)
    S[VX], S[VY], S[PSI] = 0.1, 0.6, 0.03
    sens.Sr[2][:] = S
    assert sens.sideslip(6, 20.0, 0.0) == pytest.approx(0.6 / 20.0)
    assert sens.sideslip(2, 20.0, 1.0) == pytest.approx(abs(20.0 * 0.6 - 1.0 * 0.1) / 401.0)
    assert sens.vy(2) == pytest.approx(0.6)
    assert sens.sideslip(1, 20.0, 1.0) == 0.0
