"""Typed, timestamped samples: the only things that flow into the estimator core.

Everything here is already in SI units and ISO 8855 axes (x forward, y left, z up, yaw rate
positive turning left). Conversion from DBC physical values / NMEA / UBX happens once, at the
edge (``signals.py``, ``gnss/``), never inside the estimator.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

#: The scalar inputs the estimator understands (the names of the ``[inputs.NAME]`` tables).
INPUT_NAMES = (
    "wheel_speed_fl",
    "wheel_speed_fr",
    "wheel_speed_rl",
    "wheel_speed_rr",
    "steering_wheel_angle",
    "yaw_rate",
    "accel_x",
    "accel_y",
    # optional: a 3-axis magnetometer on CAN (tesla, ISO 8855 body axes), see fusion/magnetometer.py
    "mag_x",
    "mag_y",
    "mag_z",
    # optional: a roll-rate gyro (rad/s about x, positive left side up), see estimator/road.py
    "roll_rate",
)

#: The inputs every config must map (the magnetometer is optional).
REQUIRED_INPUTS = INPUT_NAMES[:8]
#: The magnetometer's three axes: mapped all together or not at all.
MAG_INPUTS = INPUT_NAMES[8:11]

#: The roll-rate gyro: optional.
ROLL_RATE_INPUT = INPUT_NAMES[11]

#: Integer index of each input, used by the estimator's fast path.
INPUT_INDEX = {name: i for i, name in enumerate(INPUT_NAMES)}


class InputSample(NamedTuple):
    """One scalar sensor value from CAN, in SI / ISO 8855, stamped with its receive time.

    ``t`` is seconds on the input time base (the log's clock in replay, the monotonic clock live).
    ``index`` is ``INPUT_INDEX[name]``. Units: wheel speeds m/s (ground speed of that wheel
    computed with the configured wheel radius), steering-wheel angle rad (positive left),
    yaw rate rad/s (positive left), accelerations m/s^2, magnetic flux density T (body axes),
    roll rate rad/s (positive left side up).
    """

    t: float
    index: int
    value: float


# GNSS fix types (same numbering as UBX NAV-PVT fixType).
FIX_NONE = 0
FIX_DR = 1
FIX_2D = 2
FIX_3D = 3
FIX_GNSS_DR = 4
FIX_TIME = 5


@dataclass(frozen=True, slots=True)
class GnssSample:
    """One GNSS velocity solution as received.

    ``t`` is the host receive time (same clock as the CAN inputs); the fix is valid earlier, at
    ``t - latency``; the estimator owns the latency estimate. Velocities are of the antenna,
    north/east (and down, when the protocol has it) in m/s. ``speed_acc_mps`` is the receiver's 1-sigma speed accuracy, or NaN when
    the protocol does not report it (NMEA RMC/VTG). ``fix_ok`` is the receiver's own validity
    (UBX gnssFixOK flag / NMEA status 'A' and mode not 'N').
    """

    t: float
    vel_n_mps: float
    vel_e_mps: float
    speed_acc_mps: float
    fix_type: int
    fix_ok: bool
    num_sv: int = 0
    protocol: str = ""  # "ubx" | "nmea"
    fix_time_utc_s: float = float("nan")  # receiver's epoch (UTC seconds) when known
    head_acc_rad: float = float("nan")
    lat_deg: float = float("nan")
    lon_deg: float = float("nan")
    h_acc_m: float = float("nan")
    course_known: bool = True
    ground_speed_mps: float = float("nan")  # only when course_known is False
    source: int = 0  # index of the receiver in the config's receiver list
    vel_d_mps: float = float("nan")  # antenna velocity down (UBX NAV-PVT / NAV-VELNED velD; NMEA has none)
    #: antenna altitude above mean sea level (NMEA GGA / GNS) and the UTC seconds of the epoch it
    #: belongs to: the GGA of an epoch follows its RMC, so it is usually the previous epoch's
    alt_m: float = float("nan")
    alt_time_utc_s: float = float("nan")

    @property
    def speed_mps(self) -> float:
        """Ground speed, m/s (NaN when the sample has none)."""
        return math.hypot(self.vel_n_mps, self.vel_e_mps) if self.course_known else self.ground_speed_mps


@dataclass(frozen=True, slots=True)
class GnssHeadingSample:
    """One dual-antenna heading as received (u-blox NAV-RELPOSNED, NMEA HDT / THS).

    ``heading_rad`` is the heading of the antenna baseline (main/moving-base antenna to the
    rover antenna), clockwise from true north in [0, 2pi); the estimator turns it into the
    vehicle's heading with the configured mounting offset. ``t`` is the host receive time, as for
    :class:`GnssSample` (valid at ``t - latency``). ``heading_acc_rad`` is the receiver's 1-sigma
    (NaN when the protocol has none: NMEA), ``baseline_m`` the measured antenna distance (NaN when
    unknown: NMEA, or a normalised RELPOSNED). ``valid`` is the receiver's own verdict (RELPOSNED
    gnssFixOK, relPosValid and relPosHeadingValid; NMEA THS mode A/D; HDT a non-empty field).
    ``carr_soln`` is the carrier-phase solution (0 none, 1 float, 2 fixed; -1 unknown: NMEA).
    ``down_m`` / ``horizontal_m`` (RELPOSNED relPosD, hypot(relPosN, relPosE)): the rover antenna
    below the base (NED down) and the baseline's horizontal length, so its elevation is
    ``atan2(-down_m, horizontal_m)``; ``down_acc_m`` the receiver's 1-sigma of relPosD (accD);
    NaN when the protocol has none (NMEA) or the vector is normalised.
    """

    t: float
    heading_rad: float
    heading_acc_rad: float
    baseline_m: float
    valid: bool
    carr_soln: int = -1
    protocol: str = ""  # "ubx" | "nmea"
    fix_time_utc_s: float = float("nan")
    source: int = 0  # index of the receiver in the config's receiver list
    down_m: float = float("nan")
    horizontal_m: float = float("nan")
    down_acc_m: float = float("nan")
