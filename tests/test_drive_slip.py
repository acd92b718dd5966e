"""A rear-driven car with the power on at its limit on ice: sideslip flagged valid beyond 3 sigma
(issue 7, mode A with power on; fusion/drive_slip.py).

Found by tools/random_drives.py (generator v1; the Scenarios below are its drives, written out so
that they do not depend on the generator):

* drive 40 (rear drive, brake_turn on mu 0.21, power on through a 62 m corner): at 0.16 g and
  0.03 g of drive the rear tyres are on their friction limit (the drive force shares their grip)
  and slip 2.6-3.3 deg where the law says 0.6; the front is near its own limit too, so the
  steering's misfit (core.LAW_EXCESS) stays inside its 3 sigma. The model held vy 1.5-1.9 deg off
  at a 0.5 deg std (land34: 279 of 6313 valid rows beyond 3 sigma, coverage 0.956, worst 1.90 deg).
  The driven rear wheels ran 3.4 % ahead of the free front (a linear tyre: under 1 %).
* drive 55 (rear drive, j_turn on mu 0.245, spins out): 2 rows valid 2.05 deg off at the spin's
  onset (land34: worst 2.05 deg).

Replayed end to end through the suite's own scoring (simulate, CAN/GNSS files, replay, evaluate).
"""
from __future__ import annotations

import math

import pytest

from ecu_daemon.estimator.fusion import drive_slip
from ecu_daemon.estimator.fusion.drive_slip import DriveSlip
from ecu_daemon.sim.scenario import Scenario
from ecu_daemon.sim.sensors import GnssParams, SensorParams
from ecu_daemon.sim.suite import SuiteCase
from ecu_daemon.sim.tyre import TyreParams
from ecu_daemon.sim.vehicle import VehicleParams
from ecu_daemon.suite import run_case

ICE_POWER_ON = Scenario(name='random_v1_s40', manoeuvre='brake_turn', mu=0.21, mu_change=None,
    bank_rad=0.0, grade_rad=0.0, vehicle=VehicleParams(mass_kg=1279.7, yaw_inertia_kgm2=1987.6,
    lf_m=1.036, lr_m=1.607, track_m=1.482, cg_height_m=0.623, wheel_radius_m=0.3334,
    wheel_inertia_kgm2=1.2, steering_ratio=15.3, ackermann=1.0, roll_stiffness_front_share=0.526,
    roll_gradient_rad_per_g=0.10207, suspension_lag_s=0.05, tyre_front=TyreParams(fz0_n=4000.0,
    ky1=11.2, ky2=2.0, kx1=18.0, shape_c=1.3, curv_e=-1.5, relaxation_length_m=0.0),
    tyre_rear=TyreParams(fz0_n=4000.0, ky1=17.34, ky2=2.0, kx1=18.0, shape_c=1.3, curv_e=-1.5,
    relaxation_length_m=0.0), driven_axle='rear', max_drive_power_w=82000.0,
    max_drive_force_n=7000.0, brake_front_share=0.65, drag_area_m2=0.68, air_density=1.2,
    rolling_resistance=0.012), sensors=SensorParams(can_rate_hz=None, jitter_s=0.00097,
    usb_batch_s=0.0, yaw_rate_bias_radps=-0.012399, accel_x_bias_mps2=0.008, accel_y_bias_mps2=0.2,
    wheel_scale=1.023, steering_offset_rad=-0.04214, yaw_rate_noise_radps=0.003148,
    accel_noise_mps2=0.104, wheel_speed_noise_mps=0.023, steering_noise_rad=0.004173,
    wheel_speed_min_mps=0.15, wheel_lag_s=0.0, faults=(), magnetometer=None, roll_rate=False,
    roll_rate_bias_radps=0.005235987755982988, roll_rate_noise_radps=0.0013962634015954637,
    imu_position_m=(0.0, 0.0, 0.0), imu_mounting_rpy_deg=(0.0, 0.0, 0.0)),
    gnss=GnssParams(protocol='ubx', rate_hz=10.0, latency_s=0.67, latency_jitter_s=0.0098,
    vel_noise_mps=0.06, speed_acc_mps=0.18, lever_arm_m=(1.68, -0.35), pos_noise_m=1.58,
    pos_tau_s=13.2, num_sv=15, nmea_stagger_s=0.004, lat0_deg=48.137, lon0_deg=11.575,
    height_m=520.0, faults=(), dual_antenna=False, baseline_m=1.2, baseline_offset_deg=0.0,
    heading_noise_deg_1m=0.2, down_noise_m=0.007, fuse_elevation=False, alt_noise_m=1.2,
    nmea_altitude=True), gnss2=None, seed=40, duration_s=None, heading0_rad=5.48646,
    description='random drive seed 40, generator v1', params=(('radius_m', 62.6),),
    config_errors=(('mass', 1.176), ('inertia', 0.98), ('cf', 0.815), ('cr', 0.972)),
    latency_prior_s=0.753, imu_in_config=True, relaxation_in_config=False)

ICE_SPIN_ONSET = Scenario(name='random_v1_s55', manoeuvre='j_turn', mu=0.245, mu_change=None,
    bank_rad=0.0, grade_rad=0.0, vehicle=VehicleParams(mass_kg=2146.0, yaw_inertia_kgm2=3673.8,
    lf_m=1.162, lr_m=1.45, track_m=1.585, cg_height_m=0.555, wheel_radius_m=0.3184,
    wheel_inertia_kgm2=1.2, steering_ratio=16.6, ackermann=1.0, roll_stiffness_front_share=0.58,
    roll_gradient_rad_per_g=0.06485, suspension_lag_s=0.05, tyre_front=TyreParams(fz0_n=4000.0,
    ky1=17.76, ky2=2.0, kx1=18.0, shape_c=1.3, curv_e=-1.5, relaxation_length_m=0.0),
    tyre_rear=TyreParams(fz0_n=4000.0, ky1=25.42, ky2=2.0, kx1=18.0, shape_c=1.3, curv_e=-1.5,
    relaxation_length_m=0.0), driven_axle='rear', max_drive_power_w=180000.0,
    max_drive_force_n=7000.0, brake_front_share=0.65, drag_area_m2=0.68, air_density=1.2,
    rolling_resistance=0.012), sensors=SensorParams(can_rate_hz=None, jitter_s=0.00014,
    usb_batch_s=0.0, yaw_rate_bias_radps=-0.009403, accel_x_bias_mps2=0.123,
    accel_y_bias_mps2=0.042, wheel_scale=1.0203, steering_offset_rad=-0.04686,
    yaw_rate_noise_radps=0.001345, accel_noise_mps2=0.07, wheel_speed_noise_mps=0.04,
    steering_noise_rad=0.001724, wheel_speed_min_mps=0.15, wheel_lag_s=0.0229, faults=(),
    magnetometer=None, roll_rate=False, roll_rate_bias_radps=0.005235987755982988,
    roll_rate_noise_radps=0.0013962634015954637, imu_position_m=(0.0, 0.0, 0.0),
    imu_mounting_rpy_deg=(0.0, 0.0, 0.0)), gnss=GnssParams(protocol='ubx', rate_hz=1.0,
    latency_s=0.13, latency_jitter_s=0.0187, vel_noise_mps=0.042, speed_acc_mps=0.068,
    lever_arm_m=(0.09, -0.36), pos_noise_m=1.67, pos_tau_s=52.1, num_sv=9, nmea_stagger_s=0.004,
    lat0_deg=48.137, lon0_deg=11.575, height_m=520.0, faults=(), dual_antenna=False, baseline_m=1.2,
    baseline_offset_deg=0.0, heading_noise_deg_1m=0.2, down_noise_m=0.007, fuse_elevation=False,
    alt_noise_m=1.2, nmea_altitude=True), gnss2=None, seed=55, duration_s=None,
    heading0_rad=3.68106, description='random drive seed 55, generator v1', params=(),
    config_errors=(('mass', 0.797), ('inertia', 1.082)), latency_prior_s=None, imu_in_config=True,
    relaxation_in_config=False)


@pytest.mark.parametrize("sc", [ICE_POWER_ON, ICE_SPIN_ONSET], ids=["ice_power_on_s40", "ice_spin_onset_s55"])
def test_a_driven_rear_axle_at_its_limit_keeps_the_sideslip_promise(sc, tmp_path):
    row = run_case(SuiteCase(sc.name, "random", sc), tmp_path)
    assert not any(f.startswith("error") for f in row["failed"]), row["failed"]
    assert row["sideslip_coverage_3sigma"] >= 0.99, row["sideslip_coverage_3sigma"]
    assert row["sideslip_worst_valid_deg"] <= 2.0, row["sideslip_worst_valid_deg"]


DT = 0.006


def _settled(ds: DriveSlip, vx: float, kappa: float, fx: float, fy_rear: float, delta: float = 0.02) -> float:
    """Run ``ds`` for 1 s on a steady state: front wheels rolling free at vx (along their heading),
    the rear pair ``kappa`` ahead."""
    vf = vx * math.cos(delta)
    vr = vx * (1.0 + kappa)
    a = 0.0
    for _ in range(int(1.0 / DT)):
        a = ds.step(vx, vf, vf, vr, vr, delta, fx, fy_rear)
    return a


def test_drive_slip_reads_the_rear_slip_angle_from_the_friction_ellipse_only_at_the_limit():
    ds = DriveSlip(DT, "rear", 1.036, 1.607)
    share = 1.036 / 2.643
    # drive 40's corner: 3.4 % of slip at 0.33 m/s^2 of drive, 0.63 m/s^2 of rear lateral force
    a = _settled(ds, 10.0, 0.034, 0.33, 0.63)
    assert a == pytest.approx(math.atan(0.034 * 0.63 / 0.33), rel=1e-3)
    # a linear tyre's slip for the same force (C_x 15), and the radius tolerance: inside the grip
    lin = 0.33 / (9.81 * share) / 15.0
    inside = lin + 0.5 * drive_slip.KAPPA_TOL
    assert _settled(DriveSlip(DT, "rear", 1.036, 1.607), 10.0, inside, 0.33, 0.63) == 0.0
    # braking (the front brakes too: no free axle), a front- or all-wheel drive, no steering angle
    assert _settled(DriveSlip(DT, "rear", 1.036, 1.607), 10.0, -0.05, -2.0, 0.63) == 0.0
    assert _settled(DriveSlip(DT, "front", 1.036, 1.607), 10.0, 0.034, 0.33, 0.63) == 0.0
    assert _settled(DriveSlip(DT, "all", 1.036, 1.607), 10.0, 0.034, 0.33, 0.63) == 0.0
    assert _settled(DriveSlip(DT, "rear", 1.036, 1.607), 10.0, 0.034, 0.33, 0.63, math.nan) == 0.0
    # a hard launch on a dry road: 3 m/s^2 of drive at 4 % slip is a linear tyre's (C_x 15-20)
    assert _settled(DriveSlip(DT, "rear", 1.036, 1.607), 10.0, 0.04, 3.0, 0.63) == 0.0


def test_a_reset_empties_the_drive_slip_low_pass():
    """After a reset the rule starts from nothing: one step of the same slip is 6 % of it through
    the 0.1 s low-pass, inside the grip, where the state kept would fire at once."""
    ds = DriveSlip(DT, "rear", 1.036, 1.607)
    assert _settled(ds, 10.0, 0.034, 0.33, 0.63) > 0.0
    ds.reset()
    assert (ds.kappa, ds.fx, ds.alpha) == (0.0, 0.0, 0.0)
    vf = 10.0 * math.cos(0.02)
    assert ds.step(10.0, vf, vf, 10.34, 10.34, 0.02, 0.33, 0.63) == 0.0


def _rear_driven(name: str):
    import dataclasses

    from ecu_daemon.sim import SCENARIOS, vehicle_config
    sc = SCENARIOS[name]
    sc = dataclasses.replace(sc, vehicle=dataclasses.replace(sc.vehicle, driven_axle="rear"))
    return sc, vehicle_config(sc)


def test_a_filter_reinitialisation_empties_the_drive_slip():
    """core.Estimator._initialize (after a divergence, a logging gap, a spin's release) starts the
    rule afresh: the low-pass held the wheels of the state the filter has just given up (after a
    spin the slide's slip ratio, seconds of it at 0.1 s)."""
    from ecu_daemon.estimator import Estimator
    _, cfg = _rear_driven("dlc_dry")
    est = Estimator(cfg)
    assert est.drive_slip.on
    ds = est.drive_slip
    ds.kappa, ds.fx, ds.alpha = 0.2, 1.5, 0.05  # a spin's slip ratio, still in the low-pass
    est._reset(100)
    est._initialize(100, 10.0, 0.0, 0.0)
    assert (ds.kappa, ds.fx, ds.alpha) == (0.0, 0.0, 0.0)


def test_wheels_the_fault_detector_isolated_do_not_feed_the_rule():
    """A rear-driven car's free front pair reading 23 % low (a scale fault, the suite's size, for 5 s
    in the dry lane change at 22 m/s): the rear wheels run 30 % "ahead" of the front, which to the
    rule is a drive far beyond its grip (integ35: it fired on 788 steps, 68 deg of rear slip angle,
    all while the fault detector had the wheels isolated). Isolated wheels measure nothing: the rule
    must not fire while they are, nor from the low-pass they fed."""
    import dataclasses
    import sys

    from ecu_daemon.estimator import Estimator
    from ecu_daemon.estimator.fault_detection import WHEELS
    from ecu_daemon.sim import SCENARIOS, simulate, vehicle_config
    from ecu_daemon.sim.sensors import Fault
    sys.path.insert(0, "tests")
    from drive_samples import decoded_events

    sc = SCENARIOS["dlc_dry"]
    faults = tuple(Fault(w, "scaled", 22.0, 5.0, 0.77) for w in ("wheel_speed_fl", "wheel_speed_fr"))
    sc = dataclasses.replace(sc, vehicle=dataclasses.replace(sc.vehicle, driven_axle="rear"),
                             sensors=dataclasses.replace(sc.sensors, faults=faults))
    cfg = vehicle_config(sc)
    est = Estimator(cfg)
    ds = est.drive_slip
    step = ds.step
    fired_isolated = []

    def watched(*a):
        alpha = step(*a)
        if alpha > 0.0 and est.fdi.isolated & WHEELS:
            fired_isolated.append(alpha)
        return alpha

    ds.step = watched
    isolated_steps = 0
    for t, kind, s in decoded_events(cfg, simulate(sc, cfg)):
        (est.push_gnss if kind else est.push_input)(s)
        for _ in est.advance_to(t - 1e-6):
            if est.fdi.isolated & WHEELS:
                isolated_steps += 1
                assert ds.alpha == 0.0
    assert isolated_steps > 500  # the fault detector saw the fault (~1200 steps)
    assert fired_isolated == []
