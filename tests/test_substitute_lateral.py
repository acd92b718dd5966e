"""An isolated lateral accelerometer (estimator/core.py ``_widen``, fusion/single_track.py
``substitute_vy_rate``): its stand-in ay = r vx says vy is steady, so what vy may do unseen is
the vy rate the single-track model expects from the gyro's yaw acceleration -- small on a
straight (sideslip stays available there), large in a lane change (it does not)."""
from __future__ import annotations

import math

import numpy as np

from ecu_daemon import config
from ecu_daemon.estimator.core import ISO_ACCEL_NOISE, ISO_LATERAL_FLOOR, Estimator
from ecu_daemon.estimator.fault_detection import ACCEL_Y, YAW_RATE
from ecu_daemon.estimator.fusion.single_track import SingleTrackFusion
from ecu_daemon.estimator.kinematic import VY

M, IZ, LF, LR, CF, CR = 1500.0, 2500.0, 1.2, 1.5, 100e3, 120e3


def test_the_substitute_leaves_out_twice_the_steady_state_vy_rate_of_the_model():
    st = SingleTrackFusion(M, IZ, LF, LR, CF, CR, adapt=False)
    st.rear.k[1] = 0.0  # the linear law: its steady-state vy is linear in r
    vx, rdot, dr = 22.0, 0.8, 1e-3
    # d vy / d r of the steady state (ay = r vx, r_dot = 0), by finite difference of the model itself
    grad = (st.model_vy(vx, dr, dr * vx, 0.0) - st.model_vy(vx, -dr, -dr * vx, 0.0)) / (2.0 * dr)
    assert math.isclose(st.substitute_vy_rate(vx, rdot), 2.0 * abs(grad * rdot), rel_tol=1e-9)
    assert st.substitute_vy_rate(vx, -rdot) == st.substitute_vy_rate(vx, rdot)
    assert st.substitute_vy_rate(vx, 0.0) == 0.0  # a straight: only the floor is left
    # at the neutral-steer speed the sideslip does not move with the yaw rate
    v_neutral = math.sqrt(LR * (LF + LR) / (st.rear.k[0] * LF))
    assert st.substitute_vy_rate(v_neutral, rdot) < 1e-9


def _growth(iso: int, rdot: float, vx: float = 22.0) -> float:
    est = Estimator(config.load(None))
    est.fdi.new_isolation = 0  # a lasting isolation: the random walk alone
    est.rdot = rdot
    P = np.eye(len(est.hist.Xr[0])) * 1e-4
    p0 = P[VY, VY]
    est._widen(iso, P, vx)
    return (P[VY, VY] - p0) / est.dt


def test_an_isolated_ay_widens_vy_by_the_yaw_acceleration_the_gyro_shows():
    straight = _growth(ACCEL_Y, 0.0)
    lane_change = _growth(ACCEL_Y, 1.0)
    assert math.isclose(straight, ISO_LATERAL_FLOOR ** 2, rel_tol=1e-6)
    assert straight < 0.1 * ISO_ACCEL_NOISE ** 2  # was ISO_ACCEL_NOISE's random walk whatever the car did
    assert lane_change > 4.0 * straight  # ~2.5 m/s^2 per rad/s^2 at 22 m/s (twice the model's)
    # with the gyro out as well, nothing bounds the rate: the generic random walk stays
    assert math.isclose(_growth(ACCEL_Y | YAW_RATE, 0.0), ISO_ACCEL_NOISE ** 2, rel_tol=1e-6)
