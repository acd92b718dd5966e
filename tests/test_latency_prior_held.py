"""A GNSS latency held at a wrong prior while its std narrows (issue 7, "a valid flag is a promise"):
known open, a strict xfail.

Found by tools/random_drives.py on the never-seen seeds 1681-1920 (generator v1, seed 1786, written out
below so that it does not depend on the generator): a demo drive on a dry road, rear wheels driven at
219 kW, the configuration's GNSS latency 0.0 s for a true 0.104 s. The identification never refuted the
prior (the rear-driven wheels' profile, sharp and biased, kept the summed best at 0.014-0.076 s, and
the accelerometer, the clock without slip or lag, is broad: its 4-sigma set 0.26-0.29 s wide), but the
accelerometer's best sat at 0.090 s, 1.7-2.2 sigma from 0, while the latency's std narrowed to 0.018 s
(latency.py ``_refine``: the std is the summed profile's width and the distance to its best). In the
0.39 rad/s turn at 16 m/s that delay error is r x 0.104 s = 2.3 deg of sideslip: main published it
2.2 deg off as valid at a 0.66 deg std, 456 of 7096 valid rows beyond 3 sigma (coverage 0.936).

Tried this stop (branch judge41, not landed): the std at least the distance to the accelerometer's best
whenever that puts the held delay outside the accelerometer's own 1-sigma set. It fixed this drive
(0 rows beyond) and cost nothing on 45 drives of 1441-1680 or 42 suite cases, but on the never-seen
1681-1920 it withheld right rows on steady circles whose configured delay was the truth (1800: sideslip
valid above 5 m/s 0.964 -> 0.645, 1834 0.639 -> 0.330): a 1-sigma test fires on a third of a broad
profile's draws by chance, and 1786's own disagreement is under 2.2 sigma. What separates the two is
not in one clock's profile. When an estimator change keeps this drive's promise, this XPASSes: remove
the xfail.

lat42 measured the clocks one by one (a plain-Python replay printing each reference's profile; the
driven axle swapped in the replay's config to read the other pair), and the hypothesis that the
driven axle reads early is wrong twice over: the wheels that time this drive are already the
undriven front pair (fusion/wheel_speed.py), and a driven pair reads *late*, as latency.py's slip
model says (a wheel that leads the car puts the delay later): on this drive the rear pair's best
was 0.16-0.20 s for a true 0.104. The undriven front pair's best sat at 0.012-0.048 s through the
corners (0.072-0.078 on the straight at the end), the accelerometer's at 0.090 s (1-sigma set
0.048-0.132, holding the truth). Not the wheels' lag alone: the same drive with wheel_lag_s 0 still
put their best at 0.018-0.072 mid-drive. Not the antenna-to-wheel ratio's placement at the held
delay either: taken at the true delay instead, their best did not move (0.012-0.048). What
separates this drive from judge41's steady circles is where the truth sits, not a profile: on 1834
the accelerometer was the biased clock (best 0.438 s, 1-sigma set 0.366-0.474, for a true 0.588,
while the undriven rear pair said 0.50-0.63), on 1800 it was flat (1-sigma 0.006-0.264, 4-sigma the
whole grid), here it was right and the undriven wheels were 0.03-0.09 s early. Much of that is the
GNSS fixes' own: the first 40 s time the GNSS by one speed change (1210-1220 s, 0.8 m/s^2; the corner
after it is at constant speed), and against the error-free antenna speed of truth.csv the same fixes
put the delay at 0.084 s there and 0.054 s over 1200-1240 s (0.102 over the rest), the wheels at 0.048:
the profile's 6 ms 1-sigma set promised far more than one acceleration's worth of white GNSS noise.

Kept since stop 50 (latency.INFORMATION_STD, the std at least what the timing information supports):
coverage 0.941 -> 1.000, worst valid sideslip 2.55 -> 1.03 deg; the delay still held at 0.0 (latency
error -0.104 s, `lat` still fails), and the wider std costs sideslip valid above 5 m/s 0.709 -> 0.662,
heading 1.000 -> 0.827.
"""
from __future__ import annotations

from ecu_daemon.sim.scenario import Scenario
from ecu_daemon.sim.sensors import GnssParams, SensorParams
from ecu_daemon.sim.suite import SuiteCase
from ecu_daemon.sim.tyre import TyreParams
from ecu_daemon.sim.vehicle import VehicleParams
from ecu_daemon.suite import run_case

DEMO_LATENCY_PRIOR_ZERO = Scenario(name='random_v1_s1786', manoeuvre='demo', mu=0.907, mu_change=None,
    bank_rad=0.0, grade_rad=0.0, vehicle=VehicleParams(mass_kg=1939.3, yaw_inertia_kgm2=3475.3, lf_m=1.195,
    lr_m=1.408, track_m=1.457, cg_height_m=0.632, wheel_radius_m=0.3342, wheel_inertia_kgm2=1.2,
    steering_ratio=16.05, ackermann=1.0, roll_stiffness_front_share=0.502, roll_gradient_rad_per_g=0.09354,
    suspension_lag_s=0.05, tyre_front=TyreParams(fz0_n=4000.0, ky1=13.08, ky2=2.0, kx1=18.0, shape_c=1.3,
    curv_e=-1.5, relaxation_length_m=0.0), tyre_rear=TyreParams(fz0_n=4000.0, ky1=16.56, ky2=2.0, kx1=18.0,
    shape_c=1.3, curv_e=-1.5, relaxation_length_m=0.0), driven_axle='rear', max_drive_power_w=219000.0,
    max_drive_force_n=7000.0, brake_front_share=0.65, drag_area_m2=0.68, air_density=1.2,
    rolling_resistance=0.012), sensors=SensorParams(can_rate_hz=None, jitter_s=0.00013, usb_batch_s=0.0,
    yaw_rate_bias_radps=0.004505, accel_x_bias_mps2=-0.295, accel_y_bias_mps2=0.053, wheel_scale=1.0035,
    steering_offset_rad=0.01583, yaw_rate_noise_radps=0.002929, accel_noise_mps2=0.032,
    wheel_speed_noise_mps=0.028, steering_noise_rad=0.001641, wheel_speed_min_mps=0.15, wheel_lag_s=0.029,
    faults=(), magnetometer=None, roll_rate=False, roll_rate_bias_radps=0.005235987755982988,
    roll_rate_noise_radps=0.0013962634015954637, imu_position_m=(0.0, 0.0, 0.0), imu_mounting_rpy_deg=(0.0,
    0.0, 0.0)), gnss=GnssParams(protocol='ubx', rate_hz=4.0, latency_s=0.104, latency_jitter_s=0.0115,
    vel_noise_mps=0.108, speed_acc_mps=0.317, lever_arm_m=(-0.79, 0.18), pos_noise_m=2.58, pos_tau_s=32.0,
    num_sv=14, nmea_stagger_s=0.004, lat0_deg=48.137, lon0_deg=11.575, height_m=520.0, faults=(),
    dual_antenna=False, baseline_m=1.2, baseline_offset_deg=0.0, heading_noise_deg_1m=0.2, down_noise_m=0.007,
    fuse_elevation=False, alt_noise_m=1.2, nmea_altitude=True), gnss2=None, seed=1786, duration_s=None,
    heading0_rad=2.82001, description='random drive seed 1786, generator v1', params=(),
    config_errors=(('inertia', 0.807), ('cr', 1.127)), latency_prior_s=0.0, imu_in_config=True,
    relaxation_in_config=False)


def test_a_latency_held_at_a_wrong_prior_is_not_promised_narrow(tmp_path, monkeypatch):
    """Kept since latency.INFORMATION_STD (stop 50): the std is at least 1 / sqrt(timing information),
    which one acceleration's worth of GNSS noise keeps wide (on: coverage 1.000, worst 1.03 deg,
    sideslip valid above 5 m/s 0.709 -> 0.662; off, main before it: the numbers below)."""
    import ecu_daemon.estimator.latency as L

    monkeypatch.setattr(L, "INFORMATION_STD", True)
    sc = DEMO_LATENCY_PRIOR_ZERO
    row = run_case(SuiteCase(sc.name, "random", sc), tmp_path)
    assert not any(f.startswith("error") for f in row["failed"]), row["failed"]
    # main: 0.936 (456 of 7096 valid rows beyond 3 sigma), worst 2.54 deg
    assert row["sideslip_coverage_3sigma"] >= 0.99, row["sideslip_coverage_3sigma"]
    assert row["sideslip_worst_valid_deg"] < 1.5, row["sideslip_worst_valid_deg"]
