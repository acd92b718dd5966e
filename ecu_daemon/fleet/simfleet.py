"""A simulated fleet with known, different parameters per vehicle (``ecu-daemon fleet simulate``).

Each vehicle gets its own GNSS latency, wheel scale, front/rear cornering stiffness (the tyres'
ky1), steering offset and yaw-rate bias, drawn from a seeded generator; each of its drives is one
of the simulator's scenarios with its own seed and heading. The vehicle's ``config.toml`` is the
*nominal* car (nominal stiffness, a 0.3 s latency prior): what a fleet's calibration starts from.
Written as the fleet input tree: ``OUT/<vehicle>/config.toml``, ``OUT/<vehicle>/vehicle.json``
(the true parameters, with the wheel scale a rolling wheel shows: :func:`free_rolling_wheel_scale`) and ``OUT/<vehicle>/<drive>/{drive.log, drive_gnss.log, truth.csv}``.
"""
from __future__ import annotations

import json
import math
import os
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from ..config import to_toml
from ..sim import writer
from ..sim.run import simulate, vehicle_config
from ..sim.scenario import get

MANOEUVRES = ("demo", "dlc_dry", "slalom_dry", "circle_dry", "jturn_dry", "sine_dry")
NOMINAL_LATENCY_S = 0.3


def vehicle_truth(index: int, seed: int) -> dict:
    """The true parameters of vehicle ``index`` (the same for the same seed)."""
    rng = np.random.default_rng([seed, index])
    return {"gnss_latency_s": round(float(rng.uniform(0.1, 0.5)), 3),
            "wheel_scale": round(float(rng.uniform(0.98, 1.03)), 4),
            "cf_factor": round(float(rng.uniform(0.8, 1.25)), 3),
            "cr_factor": round(float(rng.uniform(0.8, 1.25)), 3),
            "steering_offset_rad": round(math.radians(float(rng.uniform(-3.0, 3.0))), 5),
            "yaw_rate_bias_radps": round(math.radians(float(rng.uniform(-0.8, 0.8))), 5)}


def free_rolling_wheel_scale(wheel_scale: float, vehicle) -> float:
    """The wheel scale the fused (non-driven) wheels show while rolling: ground speed over
    reported speed. The simulator's ``wheel_scale`` is the radius error alone, but a free-rolling
    wheel carries its rolling-resistance torque ``f_rr Fz R`` with a braking slip ``kappa = -f_rr /
    kx1`` (-0.067 % with 0.012 and 18), so it reads ``v (1 + kappa) / wheel_scale``: the estimator
    learns ``wheel_scale / (1 + kappa)`` (+0.067 %), and that is the factor the daemon needs to turn
    these wheels' readings into ground speed; braking adds more slip, but the wheel fusion
    de-weights it. A car driving all four wheels has no free-rolling pair: NaN."""
    tyre = {"front": vehicle.tyre_rear, "rear": vehicle.tyre_front}.get(vehicle.driven_axle)
    if tyre is None:
        return math.nan
    return wheel_scale / (1.0 - vehicle.rolling_resistance / tyre.kx1)


def drive_scenario(truth: dict, vehicle: int, drive: int, seed: int, duration_s: float | None):
    """The scenario of one drive of a vehicle with ``truth``."""
    base = get(MANOEUVRES[(vehicle + drive) % len(MANOEUVRES)])
    sc = base.with_(vehicle=base.vehicle.scaled(cf=truth["cf_factor"], cr=truth["cr_factor"]),
                    seed=seed * 100003 + vehicle * 101 + drive,
                    heading0_rad=math.radians((37.0 * vehicle + 71.0 * drive) % 360.0),
                    gnss_latency_s=truth["gnss_latency_s"], sensor_wheel_scale=truth["wheel_scale"],
                    sensor_steering_offset_rad=truth["steering_offset_rad"],
                    sensor_yaw_rate_bias_radps=truth["yaw_rate_bias_radps"])
    return sc.with_(duration_s=duration_s) if duration_s else sc


def _write_drive(args) -> str:
    truth, vehicle, drive, seed, duration_s, folder = args
    sc = drive_scenario(truth, vehicle, drive, seed, duration_s)
    result = simulate(sc, vehicle_config(sc))
    d = Path(folder)
    d.mkdir(parents=True, exist_ok=True)
    writer.write_can_log(d / writer.CAN_LOG, result)
    writer.write_gnss_log(d / writer.GNSS_LOG, result)
    writer.write_truth_csv(d / writer.TRUTH_CSV, result)
    return str(d)


def write_fleet(out_dir: str | Path, vehicles: int, drives: int, seed: int = 1, duration_s: float | None = None,
                jobs: int | None = None) -> list[dict]:
    """Write the fleet tree; returns per vehicle its name and true parameters."""
    out = Path(out_dir)
    nominal = get("demo").with_(gnss_latency_s=NOMINAL_LATENCY_S)
    work, fleet = [], []
    for v in range(vehicles):
        name = f"car{v + 1:02d}"
        truth = vehicle_truth(v, seed)
        sc = drive_scenario(truth, v, 0, seed, duration_s)
        cf, cr = sc.vehicle.axle_cornering_stiffness()
        truth.update(cornering_stiffness_front_n_per_rad=cf, cornering_stiffness_rear_n_per_rad=cr,
                     wheel_scale_free_rolling=round(free_rolling_wheel_scale(truth["wheel_scale"], sc.vehicle), 6))
        (out / name).mkdir(parents=True, exist_ok=True)
        (out / name / "config.toml").write_text(to_toml(writer.portable_config(vehicle_config(nominal))),
                                                encoding="utf-8")
        (out / name / "vehicle.json").write_text(json.dumps(truth, indent=1, sort_keys=True) + "\n", encoding="utf-8")
        fleet.append({"vehicle": name, **truth})
        work += [(truth, v, d, seed, duration_s, str(out / name / f"drive{d + 1:03d}")) for d in range(drives)]
    jobs = jobs or os.cpu_count() or 1
    if jobs <= 1:
        for w in work:
            _write_drive(w)
    else:
        with ProcessPoolExecutor(max_workers=jobs) as pool:
            list(pool.map(_write_drive, work))
    return fleet
