"""The estimator's per-step output record (one per 6 ms step)."""
from __future__ import annotations

import math
from typing import NamedTuple

# status bits (Estimate.status)
STATUS_STANDSTILL = 1 << 0  # vehicle at rest: zero-velocity and gyro-bias updates active
STATUS_GNSS_FRESH = 1 << 1  # a GNSS velocity was fused within the last second
STATUS_KINEMATIC_OBSERVABLE = 1 << 2  # yaw excitation makes the kinematic sideslip observable
STATUS_MODEL_FALLBACK = 1 << 3  # sideslip leans on the single-track model (straight / mild driving)
STATUS_INPUT_STALE = 1 << 4  # at least one required CAN input is stale
STATUS_RESET = 1 << 5  # the filter was re-initialised at this step (divergence / non-finite)
STATUS_HEADING_ALIGNED = 1 << 6  # heading initialised from GNSS course
STATUS_GNSS_REJECTED = 1 << 7  # the last GNSS sample failed its quality check or innovation gate
# fault isolation (estimator/fault_detection.py): the source disagrees with the others, is not fused
STATUS_WHEELS_ISOLATED = 1 << 8
STATUS_YAW_RATE_ISOLATED = 1 << 9
STATUS_ACCEL_X_ISOLATED = 1 << 10
STATUS_ACCEL_Y_ISOLATED = 1 << 11
STATUS_GNSS_ISOLATED = 1 << 12
STATUS_WHEEL_SPEED_ISOLATED = 1 << 13  # one fused wheel disagrees with the others: its axle partner stands in
STATUS_GNSS_HEADING = 1 << 14  # a dual-antenna GNSS heading was fused within the last second
STATUS_MAGNETOMETER = 1 << 15  # a magnetometer heading was fused within the last second


class Estimate(NamedTuple):
    t: float
    sideslip_rad: float
    sideslip_std_rad: float
    heading_rad: float  # clockwise from true north, [0, 2pi)
    heading_std_rad: float
    vx_mps: float
    vy_mps: float
    vx_std_mps: float
    vy_std_mps: float
    yaw_rate_radps: float  # bias-corrected
    yaw_rate_bias_radps: float  # measured = true + bias
    yaw_rate_bias_std_radps: float
    accel_x_bias_mps2: float
    accel_x_bias_std_mps2: float
    accel_y_bias_mps2: float  # includes the gravity component of road bank
    accel_y_bias_std_mps2: float
    gnss_delay_s: float  # current latency estimate (receive time minus time of validity)
    wheel_scale: float  # true wheel speed / speed from the configured radius
    steering_offset_rad: float  # steering-wheel angle reading when driving straight
    cornering_stiffness_front_n_per_rad: float
    cornering_stiffness_rear_n_per_rad: float
    sideslip_valid: bool
    heading_valid: bool
    velocity_valid: bool
    biases_valid: bool
    status: int
    gnss_fused: int  # cumulative count of GNSS samples fused
    gnss_rejected: int  # cumulative count rejected (quality or gate)
    gnss_late: int  # cumulative count older than the ring buffer (clamped to its oldest step; older than the filter's first step: left out)
    # road and body attitude (estimator/road.py); rad, ISO signs: bank left side up, grade uphill
    # ahead, roll = the body on its suspension relative to the road plane, left side up
    bank_rad: float = 0.0
    bank_std_rad: float = math.pi
    grade_rad: float = 0.0
    grade_std_rad: float = math.pi
    roll_rad: float = 0.0
    roll_std_rad: float = math.pi
    bank_valid: bool = False
    grade_valid: bool = False
    roll_valid: bool = False


ESTIMATE_FIELDS = Estimate._fields
