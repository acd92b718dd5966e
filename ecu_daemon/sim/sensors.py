"""Truth -> what real sensors report: biased, noisy CAN input values and a delayed GNSS receiver.

Why a separate step: the estimator must cope with the errors real sensors have, so they are
added here explicitly and their true values written to ``truth.csv`` (the estimator's bias
states are scored against them).

Sensor errors (all configurable in :class:`SensorParams`):

* yaw rate: ``r + bias + noise`` (the gyro sits at the CG; body roll is ignored for it).
* accelerometers: specific force in the *rolled body* frame (so road bank, grade and body roll
  appear as gravity components) ``+ bias + noise``.
* IMU position and mounting (optional, ``imu_position_m`` / ``imu_mounting_rpy_deg``): by default
  the gyro and accelerometers sit at the CG on the body axes. Otherwise they report what a
  body-fixed IMU there measures (``imu_mounting.sensor_readings``): the lever arm's
  ``omega_dot x d + omega x (omega x d)`` from the truth's yaw and body-roll rates and their
  derivatives, all rotated into the sensor's axes; bias and noise are the sensor's, added after.
* wheel speeds: wheel spin times the radius the ABS believes, ``omega * R_true / wheel_scale``,
  so tyre slip and the radius error show up; below ``wheel_speed_min_mps`` the ABS reports 0
  (too few tooth edges), as real ones do.
* steering-wheel angle: true angle ``+ offset + noise`` (offset at the steering wheel).
* magnetometer (optional, :class:`MagParams`): the Earth's field (norm, inclination,
  declination) rotated into the body by heading, pitch (grade) and roll (bank + body roll), the
  sensor yawed by its mounting offset, white noise per axis, and disturbance events
  (:class:`MagEvent`: a passing truck's hard-iron field, a steel bridge's soft iron) that fade
  in and out.
* roll rate (optional, ``roll_rate``): the body roll's rate about x (plus a turn's share on a
  grade) ``+ bias + noise``.
* quantisation is done by the DBC encoding, not here.

CAN timing: each message is sent periodically with a random phase; it arrives after a small
half-normal jitter; optionally the adapter delivers frames in USB batches that share one
timestamp (as comma's panda does). The value in a frame is the truth at its *send* time.

GNSS: epochs on the UTC grid of ``1/rate_hz``; each reports the *antenna* velocity (lever arm;
vertical too, on a graded or banked road, in UBX velD) with white noise, and reaches the host ``latency_s`` (+ jitter) after its time of validity.
UBX: one NAV-PVT per epoch (its height the constant ``height_m``: velD carries the climb). NMEA:
RMC, VTG, GGA per epoch, each sentence a few ms after the previous one (serial transmission); the
GGA's altitude is the antenna's true height along the graded road plus a Gauss-Markov error.
A dual-antenna receiver (moving base + rover, ``dual_antenna``) adds the baseline's heading to every epoch (UBX NAV-RELPOSNED after the NAV-PVT, NMEA THS): the
vehicle's heading plus the mounting offset plus white noise that shrinks with the baseline length
(carrier-phase heading: ~0.2 deg at 1 m); RELPOSNED also carries the rover's height against the
base (relPosD: the baseline tilted by grade, bank and body roll, plus ``down_noise_m``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..gnss import encode
from ..imu_mounting import is_identity, sensor_readings
from .vehicle import G, TruthArrays

#: POSIX UTC = simulation time + this (sim t = 1200.0 s is 2024-06-01T08:00:00Z). An integer,
#: so GNSS epochs on the UTC grid are also on the simulation-time grid.
UTC_OFFSET_S = 1717228800 - 1200
EARTH_RADIUS_M = 6378137.0


@dataclass(frozen=True)
class Fault:
    """A sensor fault during ``[t_rel, t_rel + duration_s)`` seconds after the drive's start.

    CAN inputs (``input`` = an input name, or ``wheels`` for all four wheel speeds), ``kind``:
    ``stuck`` (holds the reading at the fault's start, or ``value`` when it is non-zero),
    ``zero``, ``offset`` (+ ``value``, SI),
    ``scaled`` (x ``value``), ``noisy`` (+ white noise of 1-sigma ``value``), ``intermittent``
    (reads 0 for 0.1 s out of every 0.3 s: a loose connector). GNSS (``input`` = ``gnss``):
    ``scaled`` (velocity x ``value``, a glitch), ``constant`` (north and east velocity both
    ``value``), ``dropout`` (no solutions), ``heading_offset`` (a dual antenna's heading + ``value``
    deg: a wrong carrier fix whose baseline length still looks right). Every value stays what the receiver or the DBC can
    carry: these are the implausible-but-in-range inputs only cross-checks can catch.
    """

    input: str
    kind: str
    t_rel: float
    duration_s: float
    value: float = 0.0

    def active(self, t: np.ndarray, t0: float) -> np.ndarray:
        return (t >= t0 + self.t_rel) & (t < t0 + self.t_rel + self.duration_s)


CAN_FAULT_KINDS = ("stuck", "zero", "offset", "scaled", "noisy", "intermittent")
GNSS_FAULT_KINDS = ("scaled", "constant", "dropout", "heading_offset")


def apply_fault(fault: Fault, t: np.ndarray, v: np.ndarray, t0: float, rng: np.random.Generator) -> np.ndarray:
    """``v`` (readings at times ``t``) with ``fault`` applied; a copy."""
    on = fault.active(t, t0)
    v = v.copy()
    if not on.any():
        return v
    k = fault.kind
    if k == "stuck":
        v[on] = fault.value if fault.value else v[on][0]
    elif k == "zero":
        v[on] = 0.0
    elif k == "offset":
        v[on] += fault.value
    elif k == "scaled":
        v[on] *= fault.value
    elif k == "noisy":
        v[on] += fault.value * rng.standard_normal(int(on.sum()))
    elif k == "intermittent":
        v[on & ((t - t0 - fault.t_rel) % 0.3 >= 0.2)] = 0.0
    else:
        raise ValueError(f"unknown sensor fault kind {k!r}; known: {', '.join(CAN_FAULT_KINDS)}")
    return v


@dataclass(frozen=True)
class MagEvent:
    """A magnetic disturbance during ``[t_rel, t_rel + duration_s)``: at its peak the body-axis
    field is ``soft_iron`` x the Earth's plus ``hard_iron_t`` (T, body x, y, z); it fades in and out
    over ``ramp_s`` (a truck passing: ramp = half the duration; a bridge: a short ramp, a plateau)."""

    t_rel: float
    duration_s: float
    hard_iron_t: tuple = (0.0, 0.0, 0.0)
    soft_iron: float = 1.0
    ramp_s: float = 0.5

    def weight(self, t: np.ndarray, t0: float) -> np.ndarray:
        a = t - (t0 + self.t_rel)
        b = t0 + self.t_rel + self.duration_s - t
        w = np.clip(np.minimum(a, b) / max(self.ramp_s, 1e-3), 0.0, 1.0)
        return np.sin(0.5 * np.pi * w) ** 2  # smooth edges


@dataclass(frozen=True)
class MagParams:
    field_t: float = 48e-6  # Earth's field norm (Munich, WMM: ~48 uT)
    inclination_deg: float = 64.0  # dip, positive down
    declination_deg: float = 3.5  # magnetic north east of true north
    mount_yaw_deg: float = 1.5  # sensor x axis turned left of the vehicle's (ISO, about z up)
    noise_t: float = 0.15e-6  # white, per axis
    events: tuple = ()  # MagEvent s


def magnetometer(truth: TruthArrays, p: MagParams, t: np.ndarray, rng: np.random.Generator,
                 bank_rad: float = 0.0, grade_rad: float = 0.0) -> np.ndarray:
    """Body-axis (ISO 8855) field of the magnetometer at times ``t``, shape (n, 3), tesla."""
    inc, dec = math.radians(p.inclination_deg), math.radians(p.declination_deg)
    m_ned = p.field_t * np.array([math.cos(inc) * math.cos(dec), math.cos(inc) * math.sin(dec), math.sin(inc)])
    psi = sample(truth, "psi", t)
    roll = sample(truth, "roll", t) + bank_rad  # ISO = NED roll sense (left side up)
    th = grade_rad  # NED pitch, nose up
    cps, sps = np.cos(psi), np.sin(psi)
    # Rz(psi)^T m_ned, then Ry(theta)^T, then Rx(roll)^T: the field in the FRD body frame
    x1 = cps * m_ned[0] + sps * m_ned[1]
    y1 = -sps * m_ned[0] + cps * m_ned[1]
    z1 = np.full_like(psi, m_ned[2])
    ct, st = _cos(th), _sin(th)
    x2, z2 = ct * x1 - st * z1, st * x1 + ct * z1
    cr, sr = np.cos(roll), np.sin(roll)
    y3, z3 = cr * y1 + sr * z2, -sr * y1 + cr * z2
    m = np.stack([x2, -y3, -z3], axis=1)  # FRD -> ISO (x forward, y left, z up)
    t0 = float(truth.t[0])
    for ev in p.events:
        w = ev.weight(t, t0)[:, None]
        m = m * (1.0 + (ev.soft_iron - 1.0) * w) + w * np.asarray(ev.hard_iron_t)[None, :]
    a = math.radians(p.mount_yaw_deg)  # the sensor's axes: the body's turned by a about z
    mx = math.cos(a) * m[:, 0] + math.sin(a) * m[:, 1]
    my = -math.sin(a) * m[:, 0] + math.cos(a) * m[:, 1]
    out = np.stack([mx, my, m[:, 2]], axis=1)
    return out + p.noise_t * rng.standard_normal(out.shape)


@dataclass(frozen=True)
class SensorParams:
    can_rate_hz: float | None = None  # None: the DBC's GenMsgCycleTime, else 100 Hz
    jitter_s: float = 0.0003  # 1-sigma of the half-normal arrival delay of a frame
    usb_batch_s: float = 0.0  # > 0: receive stamps rounded up to batches of this period
    yaw_rate_bias_radps: float = math.radians(0.5)
    accel_x_bias_mps2: float = 0.1
    accel_y_bias_mps2: float = 0.15
    wheel_scale: float = 1.015  # true wheel ground speed / reported (true radius 1.5 % larger)
    steering_offset_rad: float = math.radians(1.5)  # reading - true, at the steering wheel
    yaw_rate_noise_radps: float = math.radians(0.08)
    accel_noise_mps2: float = 0.05
    wheel_speed_noise_mps: float = 0.02
    steering_noise_rad: float = math.radians(0.1)
    wheel_speed_min_mps: float = 0.15
    #: > 0: the ABS ECU's first-order low-pass (time constant, s) on the wheel speeds before they
    #: reach CAN (pulse-window averaging and filtering): a low-frequency delay of about this much
    wheel_lag_s: float = 0.0
    faults: tuple = ()  # Fault s on the CAN inputs
    magnetometer: MagParams | None = None  # a magnetometer on CAN ([inputs.mag_x/y/z])
    roll_rate: bool = False  # a roll-rate gyro on CAN ([inputs.roll_rate])
    roll_rate_bias_radps: float = math.radians(0.3)
    roll_rate_noise_radps: float = math.radians(0.08)
    #: the IMU (yaw gyro, accelerometers) from the CG (x forward, y left, z up) and its axes'
    #: mounting [roll, pitch, yaw] (deg, z-y-x, ``imu_mounting.rotation``); zeros: at the CG
    imu_position_m: tuple = (0.0, 0.0, 0.0)
    imu_mounting_rpy_deg: tuple = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class GnssParams:
    protocol: str = "ubx"  # ubx | nmea
    rate_hz: float = 5.0
    latency_s: float = 0.4  # receive time - time of validity
    latency_jitter_s: float = 0.004  # 1-sigma, clipped to +-3 sigma
    vel_noise_mps: float = 0.05  # white, per axis (low-cost receiver)
    speed_acc_mps: float = 0.12  # what the receiver reports as sAcc (1-sigma, pessimistic)
    lever_arm_m: tuple = (0.7, 0.3)  # antenna from the CG, x forward, y left
    pos_noise_m: float = 0.8  # Gauss-Markov position error (1-sigma) ...
    pos_tau_s: float = 30.0  # ... and its correlation time
    num_sv: int = 14
    nmea_stagger_s: float = 0.004  # delay between the sentences of one NMEA epoch
    lat0_deg: float = 48.137  # position of the simulation origin
    lon0_deg: float = 11.575
    height_m: float = 520.0
    faults: tuple = ()  # Fault s with input "gnss"
    dual_antenna: bool = False  # moving-base pair: a heading per epoch
    baseline_m: float = 1.2  # antenna distance
    baseline_offset_deg: float = 0.0  # baseline heading minus vehicle heading (mounting yaw), clockwise
    heading_noise_deg_1m: float = 0.2  # 1-sigma heading noise for a 1 m baseline (scales with 1/baseline)
    #: 1-sigma of the rover's height against the base (relPosD): carrier-phase vertical noise is
    #: about twice the horizontal (0.2 deg at 1 m is 3.5 mm across the baseline)
    down_noise_m: float = 0.007
    fuse_elevation: bool = False  # the config fuses the baseline's elevation (bank / grade)
    #: 1-sigma of the receiver's height error (NMEA GGA altitude), a Gauss-Markov process with
    #: ``pos_tau_s`` like the horizontal one: receivers' vertical error is about 1.5x their horizontal
    alt_noise_m: float = 1.2
    nmea_altitude: bool = True  # False: a receiver whose GGA altitude field is empty


def sample(truth: TruthArrays, name: str, t: np.ndarray) -> np.ndarray:
    """Truth column ``name`` linearly interpolated at times ``t``."""
    return np.interp(t, truth.t, truth.col(name))


def road_at(truth: TruthArrays, t: np.ndarray | None = None):
    """(bank, grade) under the car: the road's constants (floats, so the constant-road drives
    stay bit for bit as they were), or with a :class:`~ecu_daemon.sim.road.RoadProfile` the truth
    columns at times ``t`` (``None``: every truth step) as arrays."""
    if truth.road.profile is None:
        return truth.road.bank_rad, truth.road.grade_rad
    if t is None:
        return truth.col("bank"), truth.col("grade")
    return sample(truth, "bank", t), sample(truth, "grade", t)


def _sin(x):
    return math.sin(x) if isinstance(x, float) else np.sin(x)


def _cos(x):
    return math.cos(x) if isinstance(x, float) else np.cos(x)


class CanSensors:
    """Measured values (SI, ISO 8855) of the estimator's inputs at arbitrary send times."""

    def __init__(self, truth: TruthArrays, params: SensorParams, rng: np.random.Generator,
                 bank_rad: float = 0.0, grade_rad: float = 0.0):
        self.truth = truth
        self.p = params
        self.rng = rng
        self.bank_rad, self.grade_rad = bank_rad, grade_rad
        self._mag: tuple | None = None  # (send times, field) of the last magnetometer frame times
        self._lagged: dict[str, np.ndarray] = {}  # corner -> wheel spin through the ABS lag

    def measure(self, name: str, t: np.ndarray) -> np.ndarray:
        v = self._healthy(name, t)
        for f in self.p.faults:
            if f.input == name or (f.input == "wheels" and name.startswith("wheel_speed_")):
                v = apply_fault(f, t, v, float(self.truth.t[0]), self.rng)
        return v

    def _healthy(self, name: str, t: np.ndarray) -> np.ndarray:
        p, tr, n = self.p, self.truth, len(t)
        noise = self.rng.standard_normal(n)
        if name.startswith("wheel_speed_"):
            radius = tr.params.wheel_radius_m / p.wheel_scale
            v = np.interp(t, tr.t, self._wheel_spin(name[-2:])) * radius
            v = v + p.wheel_speed_noise_mps * noise
            v[np.abs(v) < p.wheel_speed_min_mps] = 0.0
            return v
        if name == "steering_wheel_angle":
            return sample(tr, "steer_sw", t) + p.steering_offset_rad + p.steering_noise_rad * noise
        if name in ("yaw_rate", "accel_x", "accel_y") and not is_identity(p.imu_position_m, p.imu_mounting_rpy_deg):
            f, w = self._imu(t)
            if name == "yaw_rate":
                return w[:, 2] + p.yaw_rate_bias_radps + p.yaw_rate_noise_radps * noise
            if name == "accel_x":
                return f[:, 0] + p.accel_x_bias_mps2 + p.accel_noise_mps2 * noise
            return f[:, 1] + p.accel_y_bias_mps2 + p.accel_noise_mps2 * noise
        if name == "yaw_rate":
            return sample(tr, "r", t) + p.yaw_rate_bias_radps + p.yaw_rate_noise_radps * noise
        if name == "accel_x":
            return sample(tr, "acc_x", t) + p.accel_x_bias_mps2 + p.accel_noise_mps2 * noise
        if name == "accel_y":
            return sample(tr, "acc_y", t) + p.accel_y_bias_mps2 + p.accel_noise_mps2 * noise
        if name == "roll_rate" and p.roll_rate:
            # about the body's x axis: the body roll's rate (bank is constant here) plus the turn's
            # share on a grade (Euler kinematics: p = droll/dt + yaw rate * sin(grade))
            # (with a road profile the bank's rate along the road too)
            roll = tr.col("roll") if tr.road.profile is None else tr.col("roll") + tr.col("bank")
            rate = np.gradient(roll, tr.t)
            grade = self.grade_rad if tr.road.profile is None else sample(tr, "grade", t)
            return (np.interp(t, tr.t, rate) + sample(tr, "r", t) * _sin(grade)
                    + p.roll_rate_bias_radps + p.roll_rate_noise_radps * noise)
        if name in ("mag_x", "mag_y", "mag_z") and p.magnetometer is not None:
            # the three axes of one frame: one field vector per send time
            if self._mag is None or len(self._mag[0]) != n or not np.array_equal(self._mag[0], t):
                bank, grade = (self.bank_rad, self.grade_rad) if tr.road.profile is None else road_at(tr, t)
                self._mag = (t.copy(), magnetometer(tr, p.magnetometer, t, self.rng, bank, grade))
            return self._mag[1][:, "xyz".index(name[-1])].copy()
        raise KeyError(f"unknown input {name!r}")

    def _wheel_spin(self, corner: str) -> np.ndarray:
        """The wheel's spin (rad/s) on the truth steps, through the ABS ECU's first-order lag
        ``wheel_lag_s`` (exact discretisation per truth step; 0: the truth column itself)."""
        omega = self.truth.col("omega_" + corner)
        tau = self.p.wheel_lag_s
        if tau <= 0.0:
            return omega
        if corner not in self._lagged:
            t = self.truth.t
            out = np.empty_like(omega)
            out[0] = omega[0]  # settled at the start (a flying start is already at speed)
            a = np.exp(-np.diff(t) / tau)
            for i in range(1, len(omega)):
                out[i] = a[i - 1] * out[i - 1] + (1.0 - a[i - 1]) * omega[i]
            self._lagged[corner] = out
        return self._lagged[corner]

    def _imu(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(specific force, angular rate) in the sensor's axes of the IMU at ``imu_position_m``,
        mounted at ``imu_mounting_rpy_deg``, at times ``t``; each (n, 3), noise-free.

        The CG's specific force in the rolled body frame (z from the wheel loads, rolled like
        ``acc_y``), the body's angular rate ``(roll rate, 0, r)`` (pitch is not modelled) and its
        derivative by ``np.gradient`` on the 1 kHz truth."""
        tr = self.truth
        roll = tr.col("roll")
        fz = (tr.col("fz_fl") + tr.col("fz_fr") + tr.col("fz_rl") + tr.col("fz_rr")) / tr.params.mass_kg
        acc_z = fz * np.cos(roll) - tr.col("fy") * np.sin(roll)
        p_rate = np.gradient(roll if tr.road.profile is None else roll + tr.col("bank"), tr.t)
        r = tr.col("r")
        cols = (tr.col("acc_x"), tr.col("acc_y"), acc_z, p_rate, r, np.gradient(p_rate, tr.t), np.gradient(r, tr.t))
        ax, ay, az, p, r, pdot, rdot = (np.interp(t, tr.t, c) for c in cols)
        zero = np.zeros_like(t)
        return sensor_readings(np.stack([ax, ay, az], axis=1), np.stack([p, zero, r], axis=1),
                               np.stack([pdot, zero, rdot], axis=1), self.p.imu_position_m, self.p.imu_mounting_rpy_deg)


def send_times(t_start: float, t_end: float, period_s: float, rng: np.random.Generator) -> np.ndarray:
    """Periodic transmit times with a random phase in [0, period)."""
    first = t_start + rng.uniform(0.0, period_s)
    n = max(0, int(math.floor((t_end - first) / period_s)) + 1)
    return first + period_s * np.arange(n)


def receive_times(t_send: np.ndarray, params: SensorParams, rng: np.random.Generator) -> np.ndarray:
    """Host receive stamps: send time + half-normal jitter, optionally batched like a USB adapter."""
    t = t_send + np.abs(rng.standard_normal(len(t_send))) * params.jitter_s
    if params.usb_batch_s > 0:
        b = params.usb_batch_s
        t = np.ceil(t / b) * b
    return t


# --------------------------------------------------------------------------------- GNSS


@dataclass(frozen=True)
class GnssEpoch:
    """One receiver solution: truth-derived values with the receiver's errors, before encoding."""

    t_valid: float  # simulation time of validity
    t_rx: float  # host receive time of the first byte burst of this epoch
    vel_n: float
    vel_e: float
    lat_deg: float
    lon_deg: float
    good: bool = True  # False while a fault corrupts it (the truth's gnss_good column)
    heading_deg: float = math.nan  # baseline heading (dual antenna), clockwise from north
    vel_d: float = 0.0  # antenna velocity down (UBX velD)
    down_m: float = 0.0  # rover antenna below the base (dual antenna, NED down: relPosD)
    alt_m: float = math.nan  # antenna height above the start's height_m, with the receiver's error (NMEA GGA)


def antenna_height(truth: TruthArrays, lever_arm_m: tuple, tv: np.ndarray) -> np.ndarray:
    """The antenna's true height (m) above where the drive started, at times ``tv``: its up
    velocity (grade along x, bank along y, as velD's) integrated over the truth's steps."""
    lx, ly = lever_arm_m
    bank, grade = road_at(truth)
    sg, sb, cg = _sin(grade), _sin(bank), _cos(grade)
    r = truth.col("r")
    up = (truth.col("vx") - r * ly) * sg + (truth.col("vy") + r * lx) * sb * cg
    t = truth.t
    h = np.concatenate(([0.0], np.cumsum(0.5 * (up[1:] + up[:-1]) * np.diff(t))))
    return np.interp(tv, t, h)


def gnss_epochs(truth: TruthArrays, params: GnssParams, rng: np.random.Generator) -> list[GnssEpoch]:
    """Receiver solutions on the UTC grid, delayed by the latency; only those received in time."""
    t = truth.t
    period = 1.0 / params.rate_hz
    k0 = math.ceil(round(t[0] / period, 9))
    k1 = math.floor(round(t[-1] / period, 9))
    tv = np.arange(k0, k1 + 1) * period
    vx, vy, r, psi = (sample(truth, c, tv) for c in ("vx", "vy", "r", "psi"))
    north, east = sample(truth, "north", tv), sample(truth, "east", tv)
    lx, ly = params.lever_arm_m
    bank, grade = road_at(truth, tv)
    cb, cg = _cos(bank), _cos(grade)
    # antenna velocity in the body frame, then horizontal N/E (dpsi/dt = -r: heading is clockwise)
    ux, uy = (vx - r * ly) * cg, (vy + r * lx) * cb
    cps, sps = np.cos(psi), np.sin(psi)
    vn_true = ux * cps + uy * sps
    ve_true = ux * sps - uy * cps
    n = len(tv)
    noise = rng.standard_normal((n, 2)) * params.vel_noise_mps
    jitter = np.clip(rng.standard_normal(n), -3, 3) * params.latency_jitter_s
    # Gauss-Markov position error
    a = math.exp(-period / params.pos_tau_s)
    w = rng.standard_normal((n, 2)) * params.pos_noise_m * math.sqrt(1 - a * a)
    pe = np.zeros((n, 2))
    pe[0] = rng.standard_normal(2) * params.pos_noise_m
    for i in range(1, n):
        pe[i] = a * pe[i - 1] + w[i]
    pn = north + lx * cps + ly * sps + pe[:, 0]
    pe_ = east + lx * sps - ly * cps + pe[:, 1]
    lat = params.lat0_deg + np.degrees(pn / EARTH_RADIUS_M)
    lon = params.lon0_deg + np.degrees(pe_ / (EARTH_RADIUS_M * math.cos(math.radians(params.lat0_deg))))
    t_rx = tv + params.latency_s + jitter
    t_rx = np.maximum.accumulate(t_rx)  # a receiver never reorders its output
    vn, ve = vn_true + noise[:, 0], ve_true + noise[:, 1]
    # vertical: climbing a grade along x, a bank along y (positive bank: left side up). Its noise
    # (1.5 x horizontal, as receivers' vertical is) comes from its own stream seeded by the epoch
    # grid, so adding it left every horizontal draw, and thus every older drive, as it was.
    sg, sb = _sin(grade), _sin(bank)
    vd_true = -((vx - r * ly) * sg + (vy + r * lx) * sb * cg)
    vd = vd_true + 1.5 * params.vel_noise_mps * np.random.default_rng([int(k0), n, 4]).standard_normal(n)
    # height: the true climb plus a Gauss-Markov error (sigma alt_noise_m, pos_tau_s) from its own
    # stream (the drive's seed, spawned without drawing), so every other draw stays as it was
    # (GGA rounds it to 0.1 m)
    ss = getattr(rng.bit_generator, "seed_seq", None)
    rng_h = np.random.default_rng(np.random.SeedSequence(ss.entropy if ss is not None else 0,
                                                         spawn_key=(int(k0), n, 8)))
    he = np.zeros(n)
    he[0] = rng_h.standard_normal() * params.alt_noise_m
    wh = rng_h.standard_normal(n) * params.alt_noise_m * math.sqrt(1 - a * a)
    for i in range(1, n):
        he[i] = a * he[i - 1] + wh[i]
    alt = antenna_height(truth, params.lever_arm_m, tv) + he
    head = np.full(n, math.nan)
    down = np.zeros(n)
    if params.dual_antenna:
        sig = math.radians(params.heading_noise_deg_1m) / params.baseline_m
        head = np.degrees(psi + math.radians(params.baseline_offset_deg) + sig * rng.standard_normal(n)) % 360.0
        # the baseline tilts with the body: grade (nose up) and bank + body roll (left side up);
        # unit baseline in the body (x forward, y left) is (cos off, -sin off), off clockwise.
        # Noise from its own stream (as velD's), so the older draws stay as they were.
        off = math.radians(params.baseline_offset_deg)
        phi = bank + sample(truth, "roll", tv)
        gam = grade
        up = math.cos(off) * _sin(gam) - math.sin(off) * _cos(gam) * np.sin(phi)
        down = (-params.baseline_m * up
                + params.down_noise_m * np.random.default_rng([int(k0), n, 6]).standard_normal(n))
    good = np.ones(n, dtype=bool)
    sent = np.ones(n, dtype=bool)
    for f in params.faults:
        on = f.active(tv, float(t[0]))
        if f.kind == "scaled":
            vn[on] *= f.value
            ve[on] *= f.value
            vd[on] *= f.value
        elif f.kind == "constant":
            vn[on] = ve[on] = f.value
        elif f.kind == "dropout":
            sent &= ~on
        elif f.kind == "heading_offset":
            head[on] = (head[on] + f.value) % 360.0
        else:
            raise ValueError(f"unknown GNSS fault kind {f.kind!r}; known: {', '.join(GNSS_FAULT_KINDS)}")
        if f.kind != "heading_offset":  # the velocity stays good
            good &= ~on
    out = []
    for i in range(n):
        if t_rx[i] > t[-1]:
            break
        if sent[i]:
            out.append(GnssEpoch(float(tv[i]), float(t_rx[i]), float(vn[i]), float(ve[i]), float(lat[i]),
                                 float(lon[i]), bool(good[i]), float(head[i]), float(vd[i]), float(down[i]),
                                 float(alt[i])))
    return out


def encode_epoch(ep: GnssEpoch, params: GnssParams) -> list[tuple[float, bytes]]:
    """The byte messages of one epoch as ``(receive time, payload)``: UBX NAV-PVT or NMEA lines."""
    utc = ep.t_valid + UTC_OFFSET_S
    utc = round(utc * 1000.0) / 1000.0  # receivers stamp epochs on whole milliseconds
    speed = math.hypot(ep.vel_n, ep.vel_e)
    if params.protocol == "ubx":
        frame = encode.nav_pvt(**encode.utc_fields(utc), fix_type=3, fix_ok=True, num_sv=params.num_sv,
                               lat_deg=ep.lat_deg, lon_deg=ep.lon_deg, height_m=params.height_m,
                               h_acc_m=max(0.5, 1.5 * params.pos_noise_m),
                               vel_n_mps=ep.vel_n, vel_e_mps=ep.vel_e, vel_d_mps=ep.vel_d,
                               speed_acc_mps=params.speed_acc_mps)
        out = [(ep.t_rx, frame)]
        if math.isfinite(ep.heading_deg):
            acc = 1.5 * params.heading_noise_deg_1m / params.baseline_m  # receivers' accHeading: pessimistic
            horizontal = math.sqrt(max(params.baseline_m ** 2 - ep.down_m ** 2, 0.0))
            out.append((ep.t_rx + params.nmea_stagger_s, encode.nav_relposned(
                itow_ms=encode.utc_fields(utc)["itow_ms"], heading_deg=ep.heading_deg, baseline_m=horizontal,
                head_acc_deg=acc, down_m=ep.down_m, down_acc_m=1.5 * params.down_noise_m)))
        return out
    if params.protocol == "nmea":
        course = math.degrees(math.atan2(ep.vel_e, ep.vel_n)) % 360.0
        lines = [
            encode.nmea_rmc(utc=utc, lat_deg=ep.lat_deg, lon_deg=ep.lon_deg, speed_mps=speed, course_deg=course),
            encode.nmea_vtg(speed_mps=speed, course_deg=course),
            encode.nmea_gga(utc=utc, lat_deg=ep.lat_deg, lon_deg=ep.lon_deg, num_sv=params.num_sv,
                            alt_m=(params.height_m + (ep.alt_m if math.isfinite(ep.alt_m) else 0.0)
                                   if params.nmea_altitude else None)),
        ] + ([encode.nmea_ths(heading_deg=ep.heading_deg)] if math.isfinite(ep.heading_deg) else [])
        return [(ep.t_rx + i * params.nmea_stagger_s, (s + "\r\n").encode("ascii")) for i, s in enumerate(lines)]
    raise ValueError(f"unknown GNSS protocol {params.protocol!r} (ubx or nmea)")


def effective_accel_biases(sp: SensorParams, bank_rad: float, grade_rad: float,
                           roll_gradient_rad_per_g: float = 0.0) -> tuple[float, float]:
    """What the accelerometers read standing still on this road, noise-free.

    Sensor bias plus the constant gravity components of grade and bank, including the body roll
    the bank's lateral force causes: the value a constant-bias state converges to.
    """
    fy = G * _sin(bank_rad) * _cos(grade_rad)
    fz = G * _cos(bank_rad) * _cos(grade_rad)
    roll = roll_gradient_rad_per_g / G * fy
    return (sp.accel_x_bias_mps2 + G * _sin(grade_rad),
            sp.accel_y_bias_mps2 + fy * _cos(roll) + fz * _sin(roll))
