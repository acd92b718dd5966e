"""One simulated drive end to end: physics -> sensors -> CAN frames and GNSS messages (in memory).

``simulate(scenario)`` is the Python API used by the live demo and the tests; ``writer`` puts a
:class:`SimResult` on disk in the formats ``ecu-daemon replay`` reads. Deterministic: the same
scenario (incl. seed) and config give identical frames and bytes.
"""
from __future__ import annotations

import copy
import logging
import math
from dataclasses import dataclass, field

import numpy as np

from ..config import Config, GnssReceiver, magnetometer_inputs, roll_rate_input
from ..samples import MAG_INPUTS
from . import sensors as sens
from .can_encoder import FrameEncoder
from .manoeuvres import Circle, Driver
from .scenario import T0, Scenario
from .vehicle import Road, TruthArrays, integrate, steady_cornering

log = logging.getLogger("ecu_daemon.simulate")

#: scale factors of the deliberately wrong vehicle parameters (``--wrong-params``)
WRONG_FACTORS = {"mass": 1.3, "inertia": 0.7, "cf": 0.7, "cr": 1.3}
TRUTH_DECIMATION = 6  # truth.csv: every 6th 1 kHz step = the estimator's 6 ms grid


@dataclass
class SimResult:
    scenario: Scenario
    truth: TruthArrays  # every 1 ms
    can_frames: list  # (receive time, arbitration id, data bytes), time-ordered
    gnss_messages: list  # (receive time, payload bytes), time-ordered
    config: Config  # the config whose DBC + mapping encoded the frames
    extended_ids: set = field(default_factory=set)  # arbitration ids that are 29-bit
    gnss_good_rx: list = field(default_factory=list)  # receive times of the fault-free GNSS solutions
    gnss2_messages: list = field(default_factory=list)  # the second receiver's (scenario.gnss2), time-ordered

    @property
    def t0(self) -> float:
        return float(self.truth.t[0])

    @property
    def t_end(self) -> float:
        return float(self.truth.t[-1])

    @property
    def spun_out(self) -> bool:
        return self.truth.spin_time is not None

    def truth_table(self, step: int = TRUTH_DECIMATION) -> dict[str, np.ndarray]:
        """The ``truth.csv`` columns (SI, ISO 8855; heading clockwise from north in [0, 2 pi))."""
        tr, sc = self.truth, self.scenario
        sp, gp = sc.sensors, sc.gnss
        sl = slice(None, None, step)
        c = lambda name: tr.col(name)[sl]  # noqa: E731
        n = len(c("t"))
        const = lambda v: np.full(n, float(v))  # noqa: E731
        vx, vy = c("vx"), c("vy")
        bank, grade = sens.road_at(tr)
        if tr.road.profile is not None:  # the road under the car, row by row
            bank, grade = bank[sl], grade[sl]
        bx, by = sens.effective_accel_biases(sp, bank, grade, sc.vehicle.roll_gradient_rad_per_g)
        cf, cr = sc.vehicle.axle_cornering_stiffness()
        psi = c("psi")
        cps, sps = np.cos(psi), np.sin(psi)
        radius = sc.vehicle.wheel_radius_m
        t = c("t")
        gnss_good = np.zeros(n)
        if self.gnss_good_rx:
            gnss_good[np.minimum(np.searchsorted(t, self.gnss_good_rx), n - 1)] = 1.0
        return {
            "t": c("t"),
            "sideslip_rad": np.arctan2(vy, vx),
            "heading_rad": np.mod(psi, 2 * math.pi),
            "vx_mps": vx,
            "vy_mps": vy,
            "yaw_rate_radps": c("r"),
            "ax_mps2": c("ax"),
            "ay_mps2": c("ay"),
            "yaw_rate_bias_radps": const(sp.yaw_rate_bias_radps),
            "accel_x_bias_mps2": const(sp.accel_x_bias_mps2),
            "accel_y_bias_mps2": const(sp.accel_y_bias_mps2),
            "accel_x_bias_eff_mps2": const(bx) if np.ndim(bx) == 0 else bx,
            "accel_y_bias_eff_mps2": const(by) if np.ndim(by) == 0 else by,
            "wheel_scale": const(sp.wheel_scale),
            "steering_offset_rad": const(sp.steering_offset_rad),
            "gnss_delay_s": const(gp.latency_s),
            "bank_rad": const(bank) if np.ndim(bank) == 0 else bank,
            "grade_rad": const(grade) if np.ndim(grade) == 0 else grade,
            "mu": const(sc.mu) if tr.road.mu_change is None else np.where(t >= tr.road.mu_change[0],
                                                                          tr.road.mu_change[1], sc.mu),
            "speed_mps": np.hypot(vx, vy),
            "vel_n_mps": vx * cps + vy * sps,
            "vel_e_mps": vx * sps - vy * cps,
            "north_m": c("north"),
            "east_m": c("east"),
            "steering_wheel_angle_rad": c("steer_sw"),
            "road_wheel_angle_rad": c("delta"),
            "spec_force_x_mps2": c("acc_x"),
            "spec_force_y_mps2": c("acc_y"),
            "roll_rad": c("roll"),
            "slip_angle_front_rad": c("alpha_f"),
            "slip_angle_rear_rad": c("alpha_r"),
            **{f"wheel_speed_{w}_mps": c(f"omega_{w}") * radius for w in ("fl", "fr", "rl", "rr")},
            "cornering_stiffness_front_n_per_rad": const(cf),
            "cornering_stiffness_rear_n_per_rad": const(cr),
            "gnss_good": gnss_good,  # 1 on the row where a fault-free GNSS solution arrived
        }


def vehicle_config(scenario: Scenario, base: Config | None = None, wrong: bool = False) -> Config:
    """A config for this car: ``base`` (DBC, mapping, ...) with the vehicle and GNSS sections set.

    ``wrong``: mass +30 %, yaw inertia -30 %, front cornering stiffness -30 %, rear +30 %, and a
    GNSS delay prior 0.2 s off (so adaptation has something to do).
    """
    cfg = copy.deepcopy(base) if base is not None else Config()
    vp = scenario.vehicle
    cf, cr = vp.axle_cornering_stiffness()
    f = dict(WRONG_FACTORS) if wrong else {"mass": 1.0, "inertia": 1.0, "cf": 1.0, "cr": 1.0}
    for key, factor in scenario.config_errors:
        if key not in f:
            raise ValueError(f"config error on unknown parameter {key!r}; known: {', '.join(f)}")
        f[key] *= factor
    v = cfg.vehicle
    v.mass_kg = round(vp.mass_kg * f["mass"], 3)
    v.yaw_inertia_kgm2 = round(vp.yaw_inertia_kgm2 * f["inertia"], 3)
    v.cg_to_front_axle_m = vp.lf_m
    v.cg_to_rear_axle_m = vp.lr_m
    v.track_m = vp.track_m
    v.wheel_radius_m = vp.wheel_radius_m
    v.steering_ratio = vp.steering_ratio
    v.cornering_stiffness_front_n_per_rad = round(cf * f["cf"], 1)
    v.cornering_stiffness_rear_n_per_rad = round(cr * f["cr"], 1)
    v.cg_height_m = vp.cg_height_m
    v.driven_axle = vp.driven_axle
    if scenario.relaxation_in_config:
        v.tyre_relaxation_length_m = vp.tyre_front.relaxation_length_m
    if scenario.sensors.magnetometer is not None and not any(n in cfg.inputs for n in MAG_INPUTS):
        cfg.inputs.update(magnetometer_inputs())  # on our chassis DBC's MAGNETOMETER message
    if scenario.sensors.roll_rate and "roll_rate" not in cfg.inputs:
        cfg.inputs.update(roll_rate_input())  # IMU_ROLL
    if scenario.imu_in_config:
        cfg.imu.position_m = [float(a) for a in scenario.sensors.imu_position_m]
        cfg.imu.mounting_rpy_deg = [float(a) for a in scenario.sensors.imu_mounting_rpy_deg]
    g = cfg.gnss
    g.protocol = scenario.gnss.protocol
    g.lever_arm_m = [float(a) for a in scenario.gnss.lever_arm_m]
    if scenario.gnss.dual_antenna:
        g.heading_offset_deg = scenario.gnss.baseline_offset_deg
        g.baseline_m = scenario.gnss.baseline_m
        g.fuse_baseline_elevation = scenario.gnss.fuse_elevation
    lat = scenario.gnss.latency_s
    prior = lat if scenario.latency_prior_s is None else scenario.latency_prior_s
    if wrong:
        prior = lat - 0.2 if lat >= 0.3 else lat + 0.2
    g.delay_s = round(prior, 3)
    g.max_delay_s = max(g.max_delay_s, round(lat + 0.3, 3))
    if scenario.gnss2 is not None:  # two receivers: the list form, the first one as above
        g2 = scenario.gnss2
        lat2 = g2.latency_s if scenario.latency_prior_s is None else scenario.latency_prior_s
        g.receiver = [
            GnssReceiver("/dev/ttyACM0", g.baudrate, g.protocol, "velocity", g.delay_s, list(g.lever_arm_m),
                         g.heading_offset_deg, g.baseline_m, g.fuse_baseline_elevation),
            GnssReceiver("/dev/ttyACM1", g.baudrate, g2.protocol, "velocity", round(lat2, 3),
                         [float(a) for a in g2.lever_arm_m], g2.baseline_offset_deg if g2.dual_antenna else 0.0,
                         g2.baseline_m if g2.dual_antenna else 0.0, g2.dual_antenna and g2.fuse_elevation)]
        g.max_delay_s = max(g.max_delay_s, round(g2.latency_s + 0.3, 3))
    return cfg


def with_mapped_sensors(scenario: Scenario, cfg: Config) -> Scenario:
    """The scenario with the optional sensors ``cfg`` maps (``[inputs.roll_rate]``,
    ``[inputs.mag_x/y/z]``) fitted to the car when it has none.

    Why: a user simulating with their car's config (``simulate --config car.toml``) whose IMU has a
    roll-rate gyro or a magnetometer had a KeyError traceback ("unknown input 'roll_rate'"): the
    encoder sends every mapped input, the scenario's car had no such sensor. The sensor gets the
    defaults of :class:`~ecu_daemon.sim.sensors.SensorParams` / :class:`~ecu_daemon.sim.sensors.MagParams`
    (no disturbance events); a scenario that has one is left as it is.
    """
    changes = {}
    if "roll_rate" in cfg.inputs and not scenario.sensors.roll_rate:
        changes["sensor_roll_rate"] = True
    if any(n in cfg.inputs for n in MAG_INPUTS) and scenario.sensors.magnetometer is None:
        changes["sensor_magnetometer"] = sens.MagParams()
    if not changes:
        return scenario
    log.info("the config maps %s: the simulated car gets %s", ", ".join(
        n for n in ("roll_rate", *MAG_INPUTS) if n in cfg.inputs),
        " and ".join(w for k, w in (("sensor_roll_rate", "a roll-rate gyro"),
                                    ("sensor_magnetometer", "a magnetometer")) if k in changes))
    return scenario.with_(**changes)


def simulate(scenario: Scenario, config: Config | None = None) -> SimResult:
    """Run ``scenario``; frames are encoded with ``config``'s DBC + mapping (default: ours), the
    optional sensors it maps fitted to the car (:func:`with_mapped_sensors`)."""
    cfg = config if config is not None else Config()
    scenario = with_mapped_sensors(scenario, cfg)
    man = scenario.build_manoeuvre()
    duration = scenario.duration()
    mu_change = None if scenario.mu_change is None else (T0 + scenario.mu_change[0], scenario.mu_change[1])
    road = Road(scenario.mu, scenario.bank_rad, scenario.grade_rad, man.road, mu_change)
    driver = Driver(man, scenario.vehicle, scenario.mu, T0, scenario.grade_rad)
    v0 = man.speed(0.0)[0]
    vy0 = r0 = steer0 = 0.0
    first = man.phases[0].steer
    if v0 > 0 and isinstance(first, Circle):  # flying start mid-corner: steady cornering
        vy0, r0, steer0 = steady_cornering(scenario.vehicle, v0, first.radius_m, first.left)
    truth = integrate(scenario.vehicle, road, driver, T0, duration, psi0=scenario.heading0_rad,
                      v0=v0, vy0=vy0, r0=r0, steer0=steer0)
    seq = np.random.SeedSequence(scenario.seed)
    rng_values, rng_timing, rng_gnss = (np.random.default_rng(s) for s in seq.spawn(3))
    sensors = sens.CanSensors(truth, scenario.sensors, rng_values, scenario.bank_rad, scenario.grade_rad)
    encoder = FrameEncoder(cfg)
    frames = []
    extended = set()
    for order, plan in enumerate(encoder.plans):
        t_send = sens.send_times(T0, truth.t[-1], plan.cycle_s(scenario.sensors.can_rate_hz), rng_timing)
        t_rx = sens.receive_times(t_send, scenario.sensors, rng_timing)
        keep = t_rx <= truth.t[-1]
        t_send, t_rx = t_send[keep], t_rx[keep]
        values = {name: sensors.measure(name, t_send) for name, *_ in plan.inputs}
        fid = plan.frame_id
        if plan.is_extended:
            extended.add(fid)
        for k in range(len(t_send)):
            data = encoder.encode(plan, {name: float(v[k]) for name, v in values.items()})
            frames.append((float(t_rx[k]), float(t_send[k]), order, fid, data))
    frames.sort(key=lambda f: (f[0], f[1], f[2]))
    can_frames = [(f[0], f[3], f[4]) for f in frames]
    gnss = []
    good_rx = []
    for ep in sens.gnss_epochs(truth, scenario.gnss, rng_gnss):
        gnss.extend(m for m in sens.encode_epoch(ep, scenario.gnss) if m[0] <= truth.t[-1])
        if ep.good:
            good_rx.append(ep.t_rx)
    gnss.sort(key=lambda m: m[0])
    gnss2 = []
    if scenario.gnss2 is not None:  # its own noise (a fourth child of the seed: the others unchanged)
        rng_gnss2 = np.random.default_rng(seq.spawn(1)[0])
        for ep in sens.gnss_epochs(truth, scenario.gnss2, rng_gnss2):
            gnss2.extend(m for m in sens.encode_epoch(ep, scenario.gnss2) if m[0] <= truth.t[-1])
        gnss2.sort(key=lambda m: m[0])
    return SimResult(scenario, truth, can_frames, gnss, cfg, extended, good_rx, gnss2)
