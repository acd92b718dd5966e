"""Named, reproducible test drives: manoeuvre x road friction x bank, with sensor and GNSS settings.

Naming: ``<manoeuvre>_<surface>[_bank]`` with manoeuvres ``straight``, ``jturn``, ``dlc``,
``slalom``, ``sine``, ``circle`` and surfaces ``dry`` (mu 1.0) and ``mu03`` (mu 0.3);
``straight`` alone is ``straight_dry``. ``_bank`` is a 5 % cross slope: for the circle it is
banked *into* the (left-hand) turn, i.e. ``bank_rad < 0`` (inside lower; sign convention in
:mod:`ecu_daemon.sim.vehicle`); for the other manoeuvres the road falls to the right
(``bank_rad > 0``, a crowned road's right half). Plus ``demo``: about 65 s of straight, lane
change, slalom and circle on a dry flat road.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

from .manoeuvres import BUILDERS, Manoeuvre
from .sensors import GnssParams, SensorParams
from .vehicle import VehicleParams

#: simulation clock at the start of every drive (s): non-zero like a real receive clock, and a
#: multiple of the estimator's 6 ms step so truth rows and estimates share a grid
T0 = 1200.0
BANK_5_PERCENT = math.atan(0.05)


@dataclass(frozen=True)
class Scenario:
    name: str
    manoeuvre: str  # key of manoeuvres.BUILDERS
    mu: float = 1.0
    #: ``(t_s, mu)``: the friction becomes ``mu`` ``t_s`` after the drive's start (rain on a dry
    #: road); the driver keeps the plan it made for ``mu`` (None: ``mu`` throughout)
    mu_change: tuple | None = None
    bank_rad: float = 0.0
    grade_rad: float = 0.0
    vehicle: VehicleParams = field(default_factory=VehicleParams)
    sensors: SensorParams = field(default_factory=SensorParams)
    gnss: GnssParams = field(default_factory=GnssParams)
    gnss2: GnssParams | None = None  # a second receiver (own antenna, latency, rate), own capture file
    seed: int = 1
    duration_s: float | None = None  # None: the manoeuvre's own length
    heading0_rad: float = math.radians(35.0)  # initial heading, clockwise from north
    description: str = ""
    params: tuple = ()  # (keyword, value) pairs for the manoeuvre builder
    #: (parameter, factor) pairs: the config handed to the estimator has these wrong (mass,
    #: inertia, cf, cr), the simulated car does not
    config_errors: tuple = ()
    latency_prior_s: float | None = None  # the config's GNSS latency prior (None: the true latency)
    #: the config states the IMU's position and mounting (``sensors.imu_*``); False: it says "at the
    #: CG, on the body axes" whatever the car has (the wrong configuration a user will produce)
    imu_in_config: bool = True
    #: the config states the tyres' relaxation length (``[vehicle] tyre_relaxation_length_m``, the
    #: front axle's); False (default): it says 0, instant tyres, what a user who never measured it writes
    relaxation_in_config: bool = False

    def build_manoeuvre(self) -> Manoeuvre:
        return BUILDERS[self.manoeuvre](self.mu, **dict(self.params))

    def duration(self) -> float:
        return self.duration_s if self.duration_s is not None else self.build_manoeuvre().duration_s

    def with_(self, **changes) -> "Scenario":
        """A copy with fields replaced; ``gnss_*`` / ``gnss2_*`` / ``sensor_*`` keys go into the nested
        params (``gnss2_*`` start from the first receiver's params when there is no second yet)."""
        g = {k[5:]: v for k, v in changes.items() if k.startswith("gnss_")}
        g2 = {k[6:]: v for k, v in changes.items() if k.startswith("gnss2_")}
        s = {k[7:]: v for k, v in changes.items() if k.startswith("sensor_")}
        rest = {k: v for k, v in changes.items() if not k.startswith(("gnss_", "gnss2_", "sensor_"))}
        out = replace(self, **rest)
        if g:
            out = replace(out, gnss=replace(out.gnss, **g))
        if s:
            out = replace(out, sensors=replace(out.sensors, **s))
        if g2:
            out = replace(out, gnss2=replace(out.gnss2 or out.gnss, **g2))
        return out


#: GNSS set-ups a scenario can be given (``simulate --gnss``, ``demo --gnss``): Scenario.with_ changes
GNSS_SETUPS = {
    "velocity": {},  # one receiver: velocity only
    # a moving-base pair, antennas across the car (left to right): the heading, at standstill too,
    # and from the baseline's tilt the bank
    "dual-antenna": {"gnss_dual_antenna": True, "gnss_baseline_m": 1.2, "gnss_baseline_offset_deg": 90.0,
                     "gnss_fuse_elevation": True},
    # two velocity receivers front and rear, 2.5 m apart, unsynchronised (own latency each)
    "front-rear": {"gnss_lever_arm_m": (1.5, 0.0), "gnss2_lever_arm_m": (-1.0, 0.0), "gnss2_latency_s": 0.33},
}


_KINDS = {
    "straight": ("straight", "straight driving with gentle speed changes, standstill at both ends"),
    "jturn": ("j_turn", "step steer left and right at constant speed (ISO 7401-like)"),
    "dlc": ("double_lane_change", "two ISO 3888-1-like double lane changes"),
    "slalom": ("slalom", "open-loop sinusoidal slalom steering"),
    "sine": ("sine", "two single-period sine steers"),
    "circle": ("steady_circle", "left-hand 40 m circle, speed ramped to ~0.65 g (dry) / ~0.26 g (mu 0.3)"),
}


def _registry() -> dict[str, Scenario]:
    out = {}
    for prefix, (kind, text) in _KINDS.items():
        for surface, mu in (("dry", 1.0), ("mu03", 0.3)):
            for banked in (False, True):
                name = f"{prefix}_{surface}" + ("_bank" if banked else "")
                if prefix == "straight" and surface == "dry" and not banked:
                    name = "straight"
                bank = 0.0
                if banked:
                    bank = -BANK_5_PERCENT if prefix == "circle" else BANK_5_PERCENT
                desc = f"{text}; mu {mu}" + (f"; 5 % bank ({math.degrees(bank):+.2f} deg)" if banked else "")
                out[name] = Scenario(name, kind, mu=mu, bank_rad=bank, description=desc)
    # short aliases that read naturally
    out["circle_bank"] = replace(out["circle_dry_bank"], name="circle_bank")
    out["straight_dry"] = replace(out["straight"], name="straight_dry")
    out["brake_turn_dry"] = Scenario("brake_turn_dry", "brake_turn",
                                     description="braking 18 -> 8 m/s at 5 m/s^2 twice in a 60 m left circle")
    out["demo"] = Scenario("demo", "demo", description="~65 s: straight, lane change, slalom, circle (dry, flat)")
    # roads whose bank and grade vary along the distance (sim/road.py): crossfall on the straights,
    # superelevation into the curves over their transitions, grade up and down
    out["road_country"] = Scenario("road_country", "road_course", params=(("profile", "country"),),
                                   description="~2.5 km country road, alternating curves R 120-250 m at 15-25 m/s; "
                                               "2.5 % crossfall, 4-7 % superelevation, grade +-5 %")
    out["road_handling"] = Scenario("road_handling", "road_course", params=(("profile", "handling"),),
                                    description="low-speed handling course, curves R 25-45 m at 6-11 m/s; "
                                                "6-8 % superelevation, grade +-6 %")
    return out


#: every named scenario
SCENARIOS: dict[str, Scenario] = _registry()


def get(name: str) -> Scenario:
    """The scenario called ``name``; ``KeyError`` with the list of names otherwise."""
    try:
        return SCENARIOS[name]
    except KeyError:
        raise KeyError(f"unknown scenario '{name}'; known: {', '.join(sorted(SCENARIOS))}") from None
