"""An IMU off the CG and turned (``imu_mounting.py``): the forward model against a brute-force
rigid body, its inverse at the estimator's edge, ``[imu]`` validation, and the simulator's sensors."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from ecu_daemon import config as config_mod
from ecu_daemon.config import ConfigError
from ecu_daemon.imu_mounting import G, ImuMount, rotation, sensor_readings
from ecu_daemon.samples import INPUT_INDEX

I_YAW, I_AX, I_AY = INPUT_INDEX["yaw_rate"], INPUT_INDEX["accel_x"], INPUT_INDEX["accel_y"]

arm = st.floats(-2.0, 2.0)
tilt = st.floats(-30.0, 30.0)
yaw = st.floats(-180.0, 180.0)


def _rigid_body(d, t0, psi_c, pos_c, h=1e-3):
    """World-frame specific force at the point ``d`` (body) of a body whose yaw is ``psi(t)`` and
    CG ``pos(t)`` (world, z up), by central differences of the point's world position."""
    def point(t):
        c, s = math.cos(psi_c(t)), math.sin(psi_c(t))
        rz = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        return pos_c(t) + rz @ np.asarray(d, float), rz
    acc = (point(t0 + h)[0] - 2.0 * point(t0)[0] + point(t0 - h)[0]) / (h * h)
    return acc + np.array([0.0, 0.0, G]), point(t0)[1]


@settings(max_examples=60, deadline=None)
@given(dx=arm, dy=arm, dz=arm, roll=tilt, pitch=tilt, yw=yaw, r0=st.floats(-1.0, 1.0), rdot=st.floats(-3.0, 3.0),
       ax=st.floats(-8.0, 8.0), ay=st.floats(-8.0, 8.0), vx=st.floats(0.0, 40.0), vy=st.floats(-3.0, 3.0))
def test_sensor_readings_are_a_body_fixed_imu_of_a_brute_force_rigid_body(dx, dy, dz, roll, pitch, yw, r0, rdot,
                                                                         ax, ay, vx, vy):
    """The lever arm and the mounting as a rigid body moves them: the point's world position
    differentiated twice, plus gravity, rotated into the body and then the sensor's axes."""
    d = (dx, dy, dz)
    psi = lambda t: 0.3 + r0 * t + 0.5 * rdot * t * t  # noqa: E731 - yaw, counter-clockwise (ISO z up)
    pos = lambda t: np.array([vx * t + 0.5 * ax * t * t, vy * t + 0.5 * ay * t * t, 0.0])  # noqa: E731
    t0 = 0.7
    f_world, rz = _rigid_body(d, t0, psi, pos)
    expected = rotation((roll, pitch, yw)).T @ (rz.T @ f_world)
    f_cg_world = np.array([ax, ay, G])
    f_cg = (rz.T @ f_cg_world)[None, :]
    w = r0 + rdot * t0
    f, omega = sensor_readings(f_cg, np.array([[0.0, 0.0, w]]), np.array([[0.0, 0.0, rdot]]), d, (roll, pitch, yw))
    assert f[0] == pytest.approx(expected, abs=1e-4)
    assert omega[0] == pytest.approx(rotation((roll, pitch, yw)).T @ np.array([0.0, 0.0, w]), abs=1e-12)


def test_rotation_turns_the_sensors_x_axis_left_for_a_positive_yaw_and_is_orthonormal():
    R = rotation((0.0, 0.0, 90.0))
    assert R @ np.array([1.0, 0.0, 0.0]) == pytest.approx([0.0, 1.0, 0.0], abs=1e-12)  # sensor x = body y (left)
    R = rotation((3.0, -7.0, 25.0))
    assert R.T @ R == pytest.approx(np.eye(3), abs=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0)


@settings(max_examples=60, deadline=None)
@given(dx=arm, dy=arm, roll=st.floats(-5.0, 5.0), pitch=st.floats(-5.0, 5.0), yw=yaw, r0=st.floats(-1.0, 1.0),
       rdot=st.floats(-3.0, 3.0), fx=st.floats(-9.0, 9.0), fy=st.floats(-9.0, 9.0))
def test_the_edge_conversion_inverts_the_forward_model_on_a_level_car(dx, dy, roll, pitch, yw, r0, rdot, fx, fy):
    """Yaw motion only, body z specific force = g (the edge's two assumptions): the gyro's yaw rate
    and the CG's ax, ay come back exactly; the yaw acceleration from the gyro samples' fitted slope."""
    mount = ImuMount((dx, dy, 0.0), (roll, pitch, yw), I_YAW, I_AX, I_AY)
    R = rotation((roll, pitch, yw))
    t = 100.0 + 0.01 * np.arange(8)
    r = r0 + rdot * (t - t[0])
    for tk, rk in zip(t, r):  # a gyro at 100 Hz with a constant yaw acceleration
        mount.convert(I_YAW, float(tk), float((R.T @ np.array([0.0, 0.0, rk]))[2]))
    assert mount.r == pytest.approx(r[-1], abs=1e-12)
    assert mount.rdot == pytest.approx(rdot, abs=1e-6)
    f, _ = sensor_readings(np.array([[fx, fy, G]]), np.array([[0.0, 0.0, r[-1]]]), np.array([[0.0, 0.0, rdot]]),
                           (dx, dy, 0.0), (roll, pitch, yw))
    mount.convert(I_AX, float(t[-1]), float(f[0, 0]))
    assert mount.convert(I_AY, float(t[-1]), float(f[0, 1])) == pytest.approx(fy, abs=1e-5)
    assert mount.convert(I_AX, float(t[-1]), float(f[0, 0])) == pytest.approx(fx, abs=1e-5)


def test_yaw_acceleration_is_causal_and_survives_batched_stamps():
    mount = ImuMount((0.5, 0.0, 0.0), (0.0, 0.0, 0.0), I_YAW, I_AX, I_AY)
    for k in range(5):
        mount.convert(I_YAW, 10.0 + 0.01 * k, 0.02 * k)  # 2 rad/s^2
    assert mount.rdot == pytest.approx(2.0)
    mount.convert(I_YAW, 10.04, 5.0)  # a step now: only samples at or before it count
    assert mount.rdot > 2.0
    same = ImuMount((0.5, 0.0, 0.0), (0.0, 0.0, 0.0), I_YAW, I_AX, I_AY)
    for _ in range(3):
        same.convert(I_YAW, 10.0, 0.1)  # one USB batch: no slope, no division by zero
    assert same.rdot == 0.0 and same.r == 0.1


def test_an_imu_at_the_cg_on_the_body_axes_converts_nothing():
    cfg = config_mod.from_dict({})
    assert cfg.imu.position_m == [0.0, 0.0, 0.0] and cfg.imu.mounting_rpy_deg == [0.0, 0.0, 0.0]
    assert ImuMount.from_config(cfg.imu, I_YAW, I_AX, I_AY) is None
    cfg = config_mod.from_dict({"imu": {"position_m": [0.6, 0.3, 0], "mounting_rpy_deg": [0, 0, 1.5]}})
    assert cfg.imu.position_m == [0.6, 0.3, 0.0]
    assert isinstance(ImuMount.from_config(cfg.imu, I_YAW, I_AX, I_AY), ImuMount)
    assert "[imu]" in config_mod.to_toml(cfg)


@pytest.mark.parametrize("table, message", [
    ({"position_m": [0.6, 0.3]}, "[imu] position_m must be [x, y, z] in metres"),
    ({"position_m": [0.6, True, 0.0]}, "[imu] position_m must be [x, y, z] in metres"),
    ({"position_m": "front"}, "[imu] position_m: expected a list"),
    ({"position_m": [0.0, 11.0, 0.0]}, "[imu] position_m y = 11.0 is out of range: allowed -10 to 10 m"),
    ({"position_m": [math.nan, 0.0, 0.0]}, "[imu] position_m x = nan is out of range"),
    ({"mounting_rpy_deg": [0.0, 45.0, 0.0]}, "[imu] mounting_rpy_deg pitch = 45.0 is out of range: allowed -30 to 30"),
    ({"mounting_rpy_deg": [0.0, 0.0, 200.0]}, "[imu] mounting_rpy_deg yaw = 200.0 is out of range: allowed -180"),
    ({"mounting_rpy_deg": [0.0, 0.0, math.inf]}, "[imu] mounting_rpy_deg yaw = inf is out of range"),
    ({"lever_arm_m": [0.0, 0.0, 0.0]}, "unknown key 'lever_arm_m' in [imu]"),
])
def test_imu_config_is_refused_in_one_line_naming_the_key(table, message):
    with pytest.raises(ConfigError) as e:
        config_mod.from_dict({"imu": table})
    assert message in str(e.value) and "\n" not in str(e.value)


def test_the_simulators_imu_reads_the_lever_arm_and_the_mounting_of_the_truth():
    """A slalom's first seconds, noise and biases off: the simulated accelerometers are the truth's
    CG specific force plus the lever arm (yaw acceleration x 0.6 m ahead dominates), turned 1.5 deg;
    with the IMU at the CG (the default) they are the truth's own columns, as before."""
    from ecu_daemon.sim.scenario import SCENARIOS
    from ecu_daemon.sim.sensors import CanSensors, SensorParams
    from ecu_daemon.sim.vehicle import Road, integrate
    from ecu_daemon.sim.manoeuvres import Driver
    from ecu_daemon.sim.scenario import T0

    sc = SCENARIOS["slalom_dry"].with_(duration_s=24.0)
    truth = integrate(sc.vehicle, Road(sc.mu), Driver(sc.build_manoeuvre(), sc.vehicle, sc.mu, T0), T0, sc.duration(),
                      psi0=sc.heading0_rad)
    quiet = dict(yaw_rate_bias_radps=0.0, accel_x_bias_mps2=0.0, accel_y_bias_mps2=0.0, yaw_rate_noise_radps=0.0,
                 accel_noise_mps2=0.0)
    t = truth.t[(truth.t > T0 + 20.5) & (truth.t < T0 + 23.5)]
    at_cg = CanSensors(truth, SensorParams(**quiet), np.random.default_rng(0))
    assert np.array_equal(at_cg.measure("accel_y", t), np.interp(t, truth.t, truth.col("acc_y")))
    off = CanSensors(truth, SensorParams(imu_position_m=(0.6, 0.3, 0.0), imu_mounting_rpy_deg=(0.0, 0.0, 1.5),
                                         **quiet), np.random.default_rng(0))
    r = np.interp(t, truth.t, truth.col("r"))
    rdot = np.interp(t, truth.t, np.gradient(truth.col("r"), truth.t))
    ax = np.interp(t, truth.t, truth.col("acc_x")) - rdot * 0.3 - r * r * 0.6
    ay = np.interp(t, truth.t, truth.col("acc_y")) + rdot * 0.6 - r * r * 0.3
    a = math.radians(1.5)
    lever_y = off.measure("accel_y", t)
    # the body roll's rate (left out here) adds r p dx: a few cm/s^2 at most
    assert lever_y == pytest.approx(-math.sin(a) * ax + math.cos(a) * ay, abs=0.05)
    assert np.max(np.abs(rdot * 0.6)) > 0.3  # the lever arm matters in this slalom
    assert off.measure("yaw_rate", t) == pytest.approx(r, abs=1e-12)  # turned about z: the yaw gyro is unchanged
