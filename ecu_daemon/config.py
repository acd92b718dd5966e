"""TOML configuration -> validated, typed settings.

One place for defaults and for error messages: a typo or a wrong type in the file is reported
as one line naming the key (``ConfigError``), never as a traceback from deep inside the program.
``show-config`` prints :func:`to_toml` of the effective settings, so everything printed here is
also accepted back.
"""
from __future__ import annotations

import dataclasses
import difflib
import importlib.resources
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import tomli_w

from .samples import INPUT_NAMES, MAG_INPUTS, REQUIRED_INPUTS

#: ``[inputs.NAME] checksum`` values (implemented in checksums.py)
CHECKSUM_SCHEMES = ("none", "e2e_p2", "toyota", "honda", "subaru", "hyundai_canfd", "hyundai_bitcount",
                    "hyundai_nibble", "hyundai_bytesum", "fca_giorgio")


class ConfigError(ValueError):
    """A configuration problem, phrased for the person who wrote the file."""


def find_data_file(name: str, base: Path | None = None) -> Path:
    """Resolve a data file (DBC): absolute; else relative to ``base`` (the config file's
    directory, the current directory without one); else our own copy shipped in the package.

    A user's own file shadows ours; ``dbc/ecu_daemon_inputs.dbc`` (the default, and what existing
    configs say) finds the package data (``ecu_daemon/dbc/``) wherever the package is installed.
    """
    p = Path(name).expanduser()
    if p.is_absolute():
        return p
    own = (base if base is not None else Path.cwd()) / p
    if own.exists():
        return own
    shipped = importlib.resources.files("ecu_daemon").joinpath(*p.parts)
    if shipped.is_file():
        return Path(str(shipped))  # a real file: the package is installed from a wheel or in place
    return own


def off_if_none(value: str) -> str:
    """A port or file setting written as ``none`` (any case) is off, like an empty string."""
    return "" if value.strip().lower() == "none" else value


@dataclass
class CanSettings:
    interface: str = "virtual"
    channel: str = "ecu-daemon"
    bitrate: int = 500000
    dbc: str = "dbc/ecu_daemon_inputs.dbc"
    output_dbc: str = "dbc/ecu_daemon_outputs.dbc"
    send_outputs: bool = True
    #: extra keyword arguments handed to ``can.Bus`` unchanged (python-can's own conventions)
    bus_kwargs: dict = field(default_factory=dict)


#: what a receiver is used for: its velocity (and its heading, if it sends one), or only its heading
RECEIVER_ROLES = ("velocity", "heading")
#: the keys of one receiver; in a single-receiver config they sit in [gnss] itself
RECEIVER_KEYS = ("port", "baudrate", "protocol", "delay_s", "lever_arm_m", "heading_offset_deg", "baseline_m",
                 "fuse_baseline_elevation", "baseline_elevation_deg", "baseline_elevation_std_deg")


@dataclass
class GnssReceiver:
    """One ``[[gnss.receiver]]``: its port, protocol, antenna position, latency prior and role.

    ``heading_offset_deg`` / ``baseline_m`` describe its dual-antenna baseline (when it sends a
    heading: NAV-RELPOSNED, HDT, THS), as the same keys of ``[gnss]`` do for a single receiver;
    ``fuse_baseline_elevation`` / ``baseline_elevation_deg`` / ``baseline_elevation_std_deg`` its
    tilt (RELPOSNED relPosD: bank along a lateral baseline, grade along a longitudinal one).
    """

    port: str = "/dev/ttyACM0"
    baudrate: int = 115200
    protocol: str = "auto"  # auto | ubx | nmea
    role: str = "velocity"  # velocity | heading
    delay_s: float = 0.2
    lever_arm_m: list = field(default_factory=lambda: [0.0, 0.0])
    heading_offset_deg: float = 0.0
    baseline_m: float = 0.0
    fuse_baseline_elevation: bool = False
    baseline_elevation_deg: float = 0.0
    baseline_elevation_std_deg: float = 0.1


@dataclass
class GnssSettings:
    port: str = "/dev/ttyACM0"
    baudrate: int = 115200
    protocol: str = "auto"  # auto | ubx | nmea
    delay_s: float = 0.2  # latency prior: receive time minus time of validity
    lever_arm_m: list = field(default_factory=lambda: [0.0, 0.0])  # antenna position from CG, x fwd, y left
    estimate_delay: bool = True
    # with estimate_delay = false: the fixed delay is still checked against the data, and a refuted
    # one gets a wider std (estimator/latency.py); off only for a latency known independently (PPS)
    delay_monitor: bool = True
    max_delay_s: float = 0.8  # ring-buffer horizon; later samples are clamped to it and counted
    min_fix_type: int = 2
    max_speed_acc_mps: float = 1.0
    nmea_speed_acc_mps: float = 0.15  # assumed 1-sigma when the protocol gives none (NMEA)
    timeout_s: float = 2.0
    # dual-antenna heading (NAV-RELPOSNED, HDT, THS), used whenever the receiver sends it
    heading_offset_deg: float = 0.0  # baseline heading minus vehicle heading, clockwise (antennas across, left to right: 90)
    baseline_m: float = 0.0  # antenna distance as mounted; 0: not checked
    baseline_tol_m: float = 0.05  # a measured baseline further off is a wrong carrier fix: not used
    max_heading_acc_deg: float = 2.0  # headings the receiver rates worse than this are not used
    nmea_heading_acc_deg: float = 0.3  # assumed 1-sigma when the protocol gives none (NMEA)
    # the baseline's tilt (UBX NAV-RELPOSNED relPosD; estimator/road.py): its elevation is body roll
    # + bank along a lateral baseline, pitch + grade along a longitudinal one
    fuse_baseline_elevation: bool = False  # off: relPosD is not used
    baseline_elevation_deg: float = 0.0  # the baseline's elevation on a level car (rover above base +)
    baseline_elevation_std_deg: float = 0.1  # how well that mounting elevation is known (a bias: a floor)
    #: ``[[gnss.receiver]]`` tables (GnssReceiver); empty: one receiver described by the keys above
    receiver: list = field(default_factory=list)

    def receivers(self) -> list[GnssReceiver]:
        """Every receiver, in order: the ``[[gnss.receiver]]`` list, or the single one of ``[gnss]``
        (whose port may be empty: GNSS off)."""
        if self.receiver:
            return list(self.receiver)
        return [GnssReceiver(self.port, self.baudrate, self.protocol, "velocity", self.delay_s,
                             list(self.lever_arm_m), self.heading_offset_deg, self.baseline_m,
                             self.fuse_baseline_elevation, self.baseline_elevation_deg,
                             self.baseline_elevation_std_deg)]


@dataclass
class VehicleSettings:
    mass_kg: float = 1600.0
    yaw_inertia_kgm2: float = 2600.0
    cg_to_front_axle_m: float = 1.2
    cg_to_rear_axle_m: float = 1.5
    track_m: float = 1.58
    wheel_radius_m: float = 0.32
    steering_ratio: float = 15.0
    cornering_stiffness_front_n_per_rad: float = 100000.0
    cornering_stiffness_rear_n_per_rad: float = 120000.0
    cg_height_m: float = 0.55
    #: the tyres' lateral relaxation length (m): their force lags the slip by this distance rolled.
    #: 0 (default): the single-track model takes tyre forces as instant (see estimator/fusion/single_track.py)
    tyre_relaxation_length_m: float = 0.0
    driven_axle: str = "front"  # front | rear | all (wheel slip: which wheels to trust for speed)


@dataclass
class InputMapping:
    message: Any = None  # message name or frame id (int); None: not given (any type passes _coerce)
    signal: str = ""
    signals: list = field(default_factory=list)
    scale: float = 1.0
    offset: float = 0.0
    min: float = -math.inf  # plausibility range of the SI value
    max: float = math.inf
    timeout_s: float = 0.0  # 0: ten times the observed cycle time
    counter: str = ""  # name of a rolling-counter signal in the message to check, "" = none
    checksum: str = "none"  # one of CHECKSUM_SCHEMES
    #: e2e_p2 data id: one byte, or 16 (one per counter value, VW MQB); None: the DBC's E2EDataId, else id & 0xFF
    data_id: Any = None
    #: sign-magnitude signals (VW's ESP_Gierrate + ESP_VZ_Gierrate): a signal (or sign bit) in the
    #: same message whose non-zero value makes the magnitude negative, before ``scale``/``offset``
    sign_signal: str = ""

    def signal_names(self) -> list[str]:
        return list(self.signals) if self.signals else [self.signal]


def magnetometer_inputs() -> dict[str, InputMapping]:
    """The magnetometer's mapping on our chassis DBC (message MAGNETOMETER, microtesla -> T);
    not in the defaults: a car without one maps nothing and gets no magnetometer aid."""
    return {n: InputMapping(message="MAGNETOMETER", signal=n.upper(), scale=1e-6, min=-1e-3, max=1e-3,
                            counter="COUNTER", checksum="e2e_p2") for n in MAG_INPUTS}


def roll_rate_input() -> dict[str, InputMapping]:
    """The roll-rate gyro's mapping on our chassis DBC (message IMU_ROLL, rad/s); optional like
    the magnetometer's (estimator/road.py integrates it into the body roll)."""
    return {"roll_rate": InputMapping(message="IMU_ROLL", signal="ROLL_RATE", min=-3.0, max=3.0,
                                      counter="COUNTER", checksum="e2e_p2")}


def _default_inputs() -> dict[str, InputMapping]:
    """The mapping for our own chassis DBC (``dbc/ecu_daemon_inputs.dbc``), already SI."""
    m = {}
    for corner in ("fl", "fr", "rl", "rr"):
        m[f"wheel_speed_{corner}"] = InputMapping(
            message="WHEEL_SPEEDS", signal=f"WHEEL_SPEED_{corner.upper()}", min=-5.0, max=120.0,
            counter="COUNTER", checksum="e2e_p2")
    m["steering_wheel_angle"] = InputMapping(message="STEERING", signal="STEERING_WHEEL_ANGLE",
                                             min=-15.0, max=15.0, counter="COUNTER", checksum="e2e_p2")
    m["yaw_rate"] = InputMapping(message="IMU", signal="YAW_RATE", min=-3.0, max=3.0,
                                 counter="COUNTER", checksum="e2e_p2")
    m["accel_x"] = InputMapping(message="IMU", signal="ACCEL_X", min=-30.0, max=30.0,
                                counter="COUNTER", checksum="e2e_p2")
    m["accel_y"] = InputMapping(message="IMU", signal="ACCEL_Y", min=-30.0, max=30.0,
                                counter="COUNTER", checksum="e2e_p2")
    return m


#: m/s^2, the default of ``estimator.accel_offset_std_mps2``: the 1-sigma zero offset of a production
#: IMU's accelerometers as the car carries it (issue 7, stop 48). Was 0.1 (~10 mg). Bosch's automotive
#: inertial sensors are specified to an offset stability of +-50 mg (ADAS / comfort class, SMI700/710)
#: and +-100 mg (ESP class) over temperature and life (eeNews Automotive, 2014, on the SMI7 family),
#: i.e. ~0.16-0.33 m/s^2 if those bounds are 3 sigma, before the module's mounting tilt (g sin 1 deg =
#: 0.17 m/s^2 per degree). With one antenna this prior *is* the bank's std at rest (road.py cannot
#: split a constant bank from the ay offset): at 0.1 the bank's z at the first row above 5 m/s had
#: rms 1.42 over the random drives 3121-3360 (which draw offsets uniform +-0.3 m/s^2, std 0.17).
ACCEL_OFFSET_STD_MPS2 = 0.2


@dataclass
class EstimatorSettings:
    dt_s: float = 0.006
    delay_compensation: bool = True
    adapt_cornering_stiffness: bool = True
    gnss_gate_sigma: float = 5.0
    # process noise (continuous-time spectral densities)
    accel_noise_mps2: float = 0.5  # m/s^2/sqrt(Hz), drives vx: sensor noise + pitch / grade changes the ax bias state lags
    # m/s^2/sqrt(Hz), drives vy: the floor under the accelerometer's white noise, which the estimator
    # measures from the signal itself and takes when larger (estimator/lateral_noise.py: Revs 0.07-0.10,
    # the simulated sensor 0.005), plus what the roll-gain and bias states leave of roll / bank and what
    # a low-pass in the sensor hides from that measurement. The coloured errors (IMU lever arm x yaw
    # acceleration, yaw-rate scale x r vx) grow the vy std on their own (core.IMU_LEVER_STD_M, YAW_SCALE_STD).
    lateral_accel_noise_mps2: float = 0.1
    yaw_rate_noise_radps: float = 0.0005
    yaw_rate_bias_walk: float = 2e-5
    accel_bias_walk: float = 1.5e-3
    wheel_scale_walk: float = 2e-5
    wheel_speed_noise_mps: float = 0.08
    # magnetometer heading aid (only with [inputs.mag_x/y/z]; estimator/fusion/magnetometer.py)
    mag_tilt: str = "accel"  # "accel": roll/pitch from the accelerometers' gravity part; "level": none
    mag_noise_deg: float = 1.0  # white heading noise of one sample (sensor noise, vibration)
    mag_bias_deg: float = 0.5  # slowly varying heading error left after the learned offset (soft iron...)
    mag_tilt_std_deg: float = 0.5  # tilt error the accelerometers cannot tell from their bias
    mag_norm_tol: float = 0.015  # |field norm / nominal - 1| above this: disturbed (thesis 5.3.1)
    mag_dip_tol_deg: float = 2.0  # inclination this far off its nominal value: disturbed
    mag_gate_sigma: float = 3.0  # innovation gate of the magnetometer's heading
    # 1-sigma zero offset of the accelerometers, mounting tilt included (ACCEL_OFFSET_STD_MPS2): what
    # separates road grade / bank from sensor offset until GNSS vertical velocity measures grade
    accel_offset_std_mps2: float = field(default_factory=lambda: ACCEL_OFFSET_STD_MPS2)


_MAG_TILT = ("accel", "level")


@dataclass
class ImuSettings:
    """Where the IMU (yaw gyro, accelerometers) sits and how it is turned (``imu_mounting.py``).

    The defaults, an IMU at the CG on the body axes, pass the samples unchanged.
    """

    position_m: list = field(default_factory=lambda: [0.0, 0.0, 0.0])  # from the CG: x forward, y left, z up
    mounting_rpy_deg: list = field(default_factory=lambda: [0.0, 0.0, 0.0])  # sensor axes: roll, pitch, yaw (z-y-x)


@dataclass
class DaemonSettings:
    state_file: str = "/var/lib/ecu-daemon/state.json"
    log_level: str = "info"
    realtime_priority: int = 0  # SCHED_FIFO priority of the tick thread, 0 = leave as is


@dataclass
class Config:
    can: CanSettings = field(default_factory=CanSettings)
    gnss: GnssSettings = field(default_factory=GnssSettings)
    vehicle: VehicleSettings = field(default_factory=VehicleSettings)
    inputs: dict = field(default_factory=_default_inputs)
    estimator: EstimatorSettings = field(default_factory=EstimatorSettings)
    imu: ImuSettings = field(default_factory=ImuSettings)
    daemon: DaemonSettings = field(default_factory=DaemonSettings)
    #: directory of the config file, for resolving relative paths (not part of the TOML)
    base_dir: Path | None = None

    def dbc_path(self) -> Path:
        return find_data_file(self.can.dbc, self.base_dir)

    def output_dbc_path(self) -> Path:
        return find_data_file(self.can.output_dbc, self.base_dir)


_SECTIONS = {"can": CanSettings, "gnss": GnssSettings, "vehicle": VehicleSettings,
             "estimator": EstimatorSettings, "imu": ImuSettings, "daemon": DaemonSettings}


def _did_you_mean(word: str, options) -> str:
    close = difflib.get_close_matches(word, list(options), n=1)
    return f" (did you mean '{close[0]}'?)" if close else ""


def _coerce(where: str, default: Any, value: Any) -> Any:
    """Check a TOML value against the type of its default; ints are accepted for floats."""
    if isinstance(default, bool):
        if not isinstance(value, bool):
            raise ConfigError(f"{where}: expected true or false, got {value!r}")
        return value
    if isinstance(default, float):
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(f"{where}: expected a number, got {value!r}")
        return float(value)  # NaN and the range: _validate, which knows the allowed range
    if isinstance(default, int):
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(f"{where}: expected an integer, got {value!r}")
        return value
    if isinstance(default, str):
        if not isinstance(value, str):
            raise ConfigError(f"{where}: expected a string, got {value!r}")
        return value
    if isinstance(default, list):
        if not isinstance(value, list):
            raise ConfigError(f"{where}: expected a list, got {value!r}")
        return value
    if isinstance(default, dict):
        if not isinstance(value, dict):
            raise ConfigError(f"{where}: expected a table, got {value!r}")
        return value
    return value


def _fill(cls, where: str, table: Any, base=None):
    if not isinstance(table, dict):
        raise ConfigError(f"[{where}] must be a table")
    obj = base if base is not None else cls()
    names = {f.name for f in dataclasses.fields(cls)}
    for key, value in table.items():
        if key not in names:
            raise ConfigError(f"unknown key '{key}' in [{where}]{_did_you_mean(key, names)}")
        setattr(obj, key, _coerce(f"[{where}] {key}", getattr(obj, key), value))
    return obj


#: Allowed range of every number in the file, ``(section, key) -> (low, high, unit)``, checked after
#: the types. Wide enough for any road vehicle and receiver, narrow enough that nothing downstream
#: overflows, divides by zero or allocates without bound (a 1e-320 s step, a 1e20 s ring buffer).
RANGES: dict[tuple[str, str], tuple[float, float, str]] = {
    ("can", "bitrate"): (1_000, 10_000_000, "bit/s"),
    ("gnss", "baudrate"): (300, 4_000_000, "baud"),
    ("gnss", "delay_s"): (0.0, 5.0, "s"),
    ("gnss", "max_delay_s"): (0.001, 10.0, "s"),
    ("gnss", "min_fix_type"): (0, 5, ""),
    ("gnss", "max_speed_acc_mps"): (0.001, 100.0, "m/s"),
    ("gnss", "nmea_speed_acc_mps"): (0.001, 100.0, "m/s"),
    ("gnss", "timeout_s"): (0.01, 3600.0, "s"),
    ("gnss", "heading_offset_deg"): (-360.0, 360.0, "deg"),
    ("gnss", "baseline_m"): (0.0, 100.0, "m"),
    ("gnss", "baseline_tol_m"): (0.001, 10.0, "m"),
    ("gnss", "baseline_elevation_deg"): (-45.0, 45.0, "deg"),
    ("gnss", "baseline_elevation_std_deg"): (0.0, 45.0, "deg"),
    ("gnss", "max_heading_acc_deg"): (0.001, 180.0, "deg"),
    ("gnss", "nmea_heading_acc_deg"): (0.001, 180.0, "deg"),
    ("vehicle", "mass_kg"): (10.0, 100_000.0, "kg"),
    ("vehicle", "yaw_inertia_kgm2"): (1.0, 10_000_000.0, "kg m^2"),
    ("vehicle", "cg_to_front_axle_m"): (0.05, 20.0, "m"),
    ("vehicle", "cg_to_rear_axle_m"): (0.05, 20.0, "m"),
    ("vehicle", "track_m"): (0.1, 5.0, "m"),
    ("vehicle", "wheel_radius_m"): (0.05, 2.0, "m"),
    ("vehicle", "steering_ratio"): (-100.0, 100.0, ""),
    ("vehicle", "cornering_stiffness_front_n_per_rad"): (100.0, 10_000_000.0, "N/rad"),
    ("vehicle", "cornering_stiffness_rear_n_per_rad"): (100.0, 10_000_000.0, "N/rad"),
    ("vehicle", "cg_height_m"): (0.0, 5.0, "m"),
    ("vehicle", "tyre_relaxation_length_m"): (0.0, 5.0, "m"),
    ("estimator", "dt_s"): (0.001, 0.1, "s"),
    ("estimator", "gnss_gate_sigma"): (1.0, 1000.0, ""),
    ("estimator", "accel_noise_mps2"): (1e-6, 100.0, "m/s^2/sqrt(Hz)"),
    ("estimator", "lateral_accel_noise_mps2"): (1e-6, 100.0, "m/s^2/sqrt(Hz)"),
    ("estimator", "yaw_rate_noise_radps"): (1e-9, 10.0, "rad/s/sqrt(Hz)"),
    ("estimator", "yaw_rate_bias_walk"): (0.0, 1.0, "rad/s/sqrt(s)"),
    ("estimator", "accel_bias_walk"): (0.0, 10.0, "m/s^2/sqrt(s)"),
    ("estimator", "wheel_scale_walk"): (0.0, 1.0, "1/sqrt(s)"),
    ("estimator", "wheel_speed_noise_mps"): (1e-4, 100.0, "m/s"),
    ("estimator", "mag_noise_deg"): (0.001, 90.0, "deg"),
    ("estimator", "mag_bias_deg"): (0.0, 90.0, "deg"),
    ("estimator", "mag_tilt_std_deg"): (0.0, 90.0, "deg"),
    ("estimator", "mag_norm_tol"): (1e-4, 1.0, ""),
    ("estimator", "mag_dip_tol_deg"): (0.01, 90.0, "deg"),
    ("estimator", "mag_gate_sigma"): (1.0, 1000.0, ""),
    ("estimator", "accel_offset_std_mps2"): (1e-4, 10.0, "m/s^2"),
    ("daemon", "realtime_priority"): (0, 99, ""),
    # per [inputs.NAME]
    ("inputs", "scale"): (-1e12, 1e12, ""),
    ("inputs", "offset"): (-1e12, 1e12, ""),
    ("inputs", "timeout_s"): (0.0, 3600.0, "s"),
}
LEVER_ARM_MAX_M = 20.0
#: an IMU further than this from the CG is not on the car's body (a typo, or millimetres)
IMU_POSITION_MAX_M = 10.0
#: mounting roll / pitch beyond this: the sensor's z axis is not the yaw axis any more (its yaw
#: gyro reads cos(tilt) of the yaw rate plus the roll / pitch rates, which the bus does not carry);
#: a sensor mounted upside down is a negative ``scale`` of its inputs instead
IMU_TILT_MAX_DEG = 30.0
MIN_STEERING_RATIO = 0.5
MIN_ABS_SCALE = 1e-12


def _check_range(where: str, key: str, value, rng: tuple) -> None:
    lo, hi, unit = rng
    if not lo <= value <= hi:  # also NaN
        raise ConfigError(f"{where} {key} = {value!r} is out of range: allowed {lo:g} to {hi:g}"
                          + (f" {unit}" if unit else ""))


def _validate(cfg: Config) -> None:
    for (section, key), rng in RANGES.items():
        if section != "inputs":
            _check_range(f"[{section}]", key, getattr(getattr(cfg, section), key), rng)
    if abs(cfg.vehicle.steering_ratio) < MIN_STEERING_RATIO:
        raise ConfigError(f"[vehicle] steering_ratio = {cfg.vehicle.steering_ratio!r} is out of range: allowed"
                          f" {MIN_STEERING_RATIO:g} to 100 (negative flips the sign)")
    if cfg.estimator.mag_tilt not in _MAG_TILT:
        raise ConfigError(f"[estimator] mag_tilt must be {' or '.join(_MAG_TILT)}, got {cfg.estimator.mag_tilt!r}")
    if cfg.vehicle.driven_axle not in ("front", "rear", "all"):
        raise ConfigError(f"[vehicle] driven_axle must be front, rear or all, got {cfg.vehicle.driven_axle!r}")
    _validate_imu(cfg.imu)
    g = cfg.gnss
    _validate_receiver("[gnss]", g)
    for n, rx in enumerate(g.receiver):
        where = f"[[gnss.receiver]] #{n + 1}"
        for key in RECEIVER_KEYS:
            if ("gnss", key) in RANGES:
                _check_range(where, key, getattr(rx, key), RANGES[("gnss", key)])
        _validate_receiver(where, rx)
        if rx.role not in RECEIVER_ROLES:
            raise ConfigError(f"{where} role must be {' or '.join(RECEIVER_ROLES)}, got {rx.role!r}")
    if g.receiver:
        ports = [rx.port for rx in g.receiver]
        if len(set(ports)) != len(ports):
            raise ConfigError(f"[[gnss.receiver]] ports must differ, got {ports}")
        if not any(rx.role == "velocity" for rx in g.receiver):
            raise ConfigError("[[gnss.receiver]]: at least one receiver needs role = \"velocity\"")
        # the single-receiver keys of [gnss] describe the first velocity receiver (what code and
        # tools written for one receiver read)
        first = next(rx for rx in g.receiver if rx.role == "velocity")
        for key in RECEIVER_KEYS:
            setattr(g, key, getattr(first, key))
    # the ring buffer must reach back past every latency prior (and what it may be identified as)
    g.max_delay_s = max(g.max_delay_s, round(max(rx.delay_s for rx in g.receivers()) + 0.3, 3))
    if cfg.daemon.log_level.lower() not in ("debug", "info", "warning", "error"):
        raise ConfigError(f"[daemon] log_level must be debug, info, warning or error, got {cfg.daemon.log_level!r}")
    for name, m in cfg.inputs.items():
        if isinstance(m.message, bool) or not isinstance(m.message, (str, int)) or m.message in ("", None):
            raise ConfigError(f"[inputs.{name}] message must be a message name or a frame id")
        if m.signals and m.signal:
            raise ConfigError(f"[inputs.{name}] give either 'signal' or 'signals', not both")
        if not m.signals and not m.signal:
            raise ConfigError(f"[inputs.{name}] needs 'signal' (or 'signals = [...]')")
        if not all(isinstance(s, str) and s for s in m.signal_names()):
            raise ConfigError(f"[inputs.{name}] signals must be non-empty strings")
        for (section, key), rng in RANGES.items():
            if section == "inputs":
                _check_range(f"[inputs.{name}]", key, getattr(m, key), rng)
        if abs(m.scale) < MIN_ABS_SCALE:
            raise ConfigError(f"[inputs.{name}] scale = {m.scale!r} is out of range: allowed {MIN_ABS_SCALE:g} to"
                              " 1e+12 in magnitude (negative flips the axis)")
        if m.checksum not in CHECKSUM_SCHEMES:
            raise ConfigError(f"[inputs.{name}] checksum must be one of {', '.join(CHECKSUM_SCHEMES)},"
                              f" got {m.checksum!r}")
        if m.data_id is not None:
            _check_data_id(name, m)
        if not m.min < m.max:  # also NaN
            raise ConfigError(f"[inputs.{name}] min = {m.min!r}, max = {m.max!r}: min must be below max"
                              " (either may be inf)")
    missing = [n for n in REQUIRED_INPUTS if n not in cfg.inputs]
    if missing:
        raise ConfigError("missing input mapping(s): " + ", ".join(f"[inputs.{n}]" for n in missing))
    mags = [n for n in MAG_INPUTS if n in cfg.inputs]
    if mags and len(mags) != len(MAG_INPUTS):
        raise ConfigError(", ".join(f"[inputs.{n}]" for n in MAG_INPUTS if n not in cfg.inputs)
                          + " missing: a magnetometer needs all three axes mapped")


def _validate_receiver(where: str, rx) -> None:
    """Protocol and lever arm of one receiver ([gnss] itself, or one [[gnss.receiver]])."""
    if rx.protocol not in ("auto", "ubx", "nmea"):
        raise ConfigError(f"{where} protocol must be auto, ubx or nmea, got {rx.protocol!r}")
    arm = rx.lever_arm_m
    if len(arm) != 2 or not all(isinstance(a, (int, float)) and not isinstance(a, bool) for a in arm):
        raise ConfigError(f"{where} lever_arm_m must be [x, y] in metres, got {arm!r}")
    rx.lever_arm_m = [float(a) for a in arm]
    if not all(abs(a) <= LEVER_ARM_MAX_M for a in rx.lever_arm_m):
        raise ConfigError(f"{where} lever_arm_m = {arm!r} is out of range: allowed -{LEVER_ARM_MAX_M:g} to"
                          f" {LEVER_ARM_MAX_M:g} m each")


def _validate_imu(imu: ImuSettings) -> None:
    """[imu] position_m = [x, y, z] and mounting_rpy_deg = [roll, pitch, yaw], finite, in range."""
    for key, limits, unit in (("position_m", (IMU_POSITION_MAX_M,) * 3, "m"),
                              ("mounting_rpy_deg", (IMU_TILT_MAX_DEG, IMU_TILT_MAX_DEG, 180.0), "deg")):
        v = getattr(imu, key)
        what = "[x, y, z] in metres" if unit == "m" else "[roll, pitch, yaw] in degrees"
        if len(v) != 3 or not all(isinstance(a, (int, float)) and not isinstance(a, bool) for a in v):
            raise ConfigError(f"[imu] {key} must be {what}, got {v!r}")
        v = [float(a) for a in v]
        for a, lim, axis in zip(v, limits, ("x", "y", "z") if unit == "m" else ("roll", "pitch", "yaw")):
            if not -lim <= a <= lim:  # also NaN
                raise ConfigError(f"[imu] {key} {axis} = {a!r} is out of range: allowed -{lim:g} to {lim:g} {unit}")
        setattr(imu, key, v)


def _check_data_id(name: str, m: InputMapping) -> None:
    def byte(v) -> bool:
        return isinstance(v, int) and not isinstance(v, bool) and 0 <= v <= 255

    if m.checksum != "e2e_p2":
        raise ConfigError(f"[inputs.{name}] data_id is for checksum = \"e2e_p2\", not {m.checksum!r}")
    ids = m.data_id
    if not (byte(ids) or (isinstance(ids, list) and len(ids) == 16 and all(byte(v) for v in ids))):
        raise ConfigError(f"[inputs.{name}] data_id must be a byte (0..255) or a list of 16 bytes, one per"
                          f" counter value; got {ids!r}")


def _fill_gnss(g: GnssSettings, table: Any) -> None:
    """[gnss], with its optional [[gnss.receiver]] list (then the per-receiver keys go there only)."""
    if not isinstance(table, dict):
        raise ConfigError("[gnss] must be a table")
    receivers = table.get("receiver", [])
    if not isinstance(receivers, list) or not all(isinstance(r, dict) for r in receivers):
        raise ConfigError("[gnss] receiver must be a list of [[gnss.receiver]] tables")
    both = [k for k in RECEIVER_KEYS if k in table] if receivers else []
    if both:
        raise ConfigError(f"[gnss] {', '.join(both)}: with [[gnss.receiver]] tables these go in each receiver")
    _fill(GnssSettings, "gnss", {k: v for k, v in table.items() if k != "receiver"}, base=g)
    g.receiver = [_fill(GnssReceiver, f"gnss.receiver #{n + 1}", r) for n, r in enumerate(receivers)]
    for rx in g.receiver:
        rx.port = off_if_none(rx.port)


def from_dict(data: dict, base_dir: Path | None = None) -> Config:
    """Build a validated Config from a parsed TOML document (missing keys take defaults)."""
    cfg = Config(base_dir=base_dir)
    for key, table in data.items():
        if key == "inputs":
            if not isinstance(table, dict):
                raise ConfigError("[inputs] must be a table of [inputs.NAME] tables")
            for name, sub in table.items():
                if name not in INPUT_NAMES:
                    raise ConfigError(f"unknown input [inputs.{name}]{_did_you_mean(name, INPUT_NAMES)};"
                                      f" known: {', '.join(INPUT_NAMES)}")
                # A user table replaces our default mapping for that input entirely.
                m = InputMapping(min=-math.inf, max=math.inf)
                cfg.inputs[name] = _fill(InputMapping, f"inputs.{name}", sub, base=m)
        elif key == "gnss":
            _fill_gnss(cfg.gnss, table)
        elif key in _SECTIONS:
            _fill(_SECTIONS[key], key, table, base=getattr(cfg, key))
        else:
            raise ConfigError(f"unknown section [{key}]{_did_you_mean(key, list(_SECTIONS) + ['inputs'])}")
    cfg.gnss.port = off_if_none(cfg.gnss.port)
    cfg.daemon.state_file = off_if_none(cfg.daemon.state_file)
    _validate(cfg)
    return cfg


def load(path: str | Path | None) -> Config:
    """Load and validate a TOML file; ``None`` gives the defaults (our own DBCs, virtual bus)."""
    if path is None:
        cfg = Config()
        _validate(cfg)
        return cfg
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as e:
        raise ConfigError(f"cannot read config {p}: {e.strerror or e}") from None
    except UnicodeDecodeError:
        raise ConfigError(f"config {p} is not UTF-8 text") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(f"config {p} is not valid TOML: {e}") from None
    return from_dict(data, base_dir=p.resolve().parent)


def to_dict(cfg: Config) -> dict:
    out: dict[str, Any] = {}
    for key in ("can", "gnss", "vehicle", "estimator", "imu", "daemon"):
        out[key] = dataclasses.asdict(getattr(cfg, key))
    g = out["gnss"]
    if g["receiver"]:  # the per-receiver keys live in the receivers (as the file had them)
        for k in RECEIVER_KEYS:
            del g[k]
    else:
        del g["receiver"]
    inputs = {}
    for name in (n for n in INPUT_NAMES if n in cfg.inputs):
        d = dataclasses.asdict(cfg.inputs[name])
        d = {k: v for k, v in d.items()
             if not ((k in ("signals", "signal", "sign_signal") and not v) or (k == "data_id" and v is None)
                     or (k in ("min", "max") and math.isinf(v)))}
        inputs[name] = d
    out["inputs"] = inputs
    return out


def to_toml(cfg: Config) -> str:
    return tomli_w.dumps(to_dict(cfg))
