"""Random but physically plausible drives that hunt for lies: rows flagged valid beyond 3 sigma.

Why (issue 7): the product is scored on drives nobody here has seen, while the 138-row suite is
hand-made and the filter has been tuned on it. This draws whole scenarios at random from the
simulator's own building blocks (:class:`~ecu_daemon.sim.scenario.Scenario`, the manoeuvre
builders and their parameters, :class:`VehicleParams`, :class:`SensorParams`, :class:`GnssParams`,
configuration errors, the latency prior, bank / grade / friction, start state, heading) over the
ranges a real car, road and receiver have -- not over what the filter is known to handle -- and
scores each one with the suite's own code (:func:`ecu_daemon.suite.run_case`: simulate, replay with
the written ``config.toml``, :func:`ecu_daemon.evaluate._evaluate`), so there is no second scoring.

A drive whose simulated signals the chassis DBC cannot carry (a spinning car's wheels turning
backwards beyond the wheel-speed signals' range) is listed as *not encodable* and not scored: no
recording of it could exist. Any other error breaks the promise.

A drive *breaks the promise* when, for sideslip, heading or vx, fewer than 99 % of its valid rows
are within 3 reported sigma, or the sideslip is valid more than 2 deg off, or the heading valid
more than 5 deg off (the suite's ``cov-*`` / ``worst-*`` targets). Availability is printed but is
not a broken promise (invalid-while-right is the lesser defect).

Every drive is a pure function of ``(seed, GENERATOR_VERSION)``: :func:`draw` uses its own
``random.Random(seed)`` and nothing else; change a range or the order of draws and the version
goes up. The Scenario repr of each failing drive is printed so that it can be rebuilt by hand.

    python3 tools/random_drives.py --seeds 1-40 --jobs 2 --out /tmp/rd
    python3 tools/random_drives.py --seeds 7 --show          # the Scenario only, no run

The report (stdout, and ``OUT/random_drives.json``) holds per drive and overall: rows flagged
valid beyond 3 sigma (count and %), the worst error while valid, the valid fractions, and the
seeds that break the promise.
"""
from __future__ import annotations

import argparse
import json
import math
import random
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from pathlib import Path

from ecu_daemon.evaluate import public
from ecu_daemon.sim.scenario import Scenario
from ecu_daemon.sim.sensors import GnssParams, SensorParams
from ecu_daemon.sim.suite import SuiteCase
from ecu_daemon.sim.vehicle import G, VehicleParams
from ecu_daemon.suite import TARGETS, run_case

#: bump when a range, a choice or the order of the draws changes: (seed, version) names a drive
GENERATOR_VERSION = 1
DEG = 180.0 / math.pi
RAD = math.pi / 180.0
QUANTITIES = ("sideslip", "heading", "vx")
#: worst error allowed while valid (SI: rad, rad; vx has no such target)
WORST_LIMIT = {"sideslip": TARGETS["worst_sideslip_deg"] * RAD, "heading": TARGETS["worst_heading_deg"] * RAD}
UNIT = {"sideslip": ("deg", DEG), "heading": ("deg", DEG), "vx": ("m/s", 1.0)}

#: manoeuvre kinds and how often each is drawn; ``flying`` covers both flying starts (straight
#: and mid-corner), every other kind starts at rest
KINDS = (("straight", 1), ("j_turn", 1), ("double_lane_change", 1), ("slalom", 1), ("sine", 1),
         ("steady_circle", 2), ("brake_turn", 1), ("demo", 1), ("flying", 4), ("reversing", 1),
         ("low_speed", 1), ("road_course", 1))


def _pick(rng: random.Random, weighted) -> str:
    names = [k for k, _ in weighted]
    return rng.choices(names, weights=[w for _, w in weighted])[0]


def _r(x: float, nd: int = 4) -> float:
    """Rounded, so that the Scenario repr is short and rebuilds the same drive exactly."""
    return round(x, nd)


def _surface(rng: random.Random) -> float:
    """Peak friction: dry asphalt 0.9-1.1, wet 0.55-0.9, snow / ice-patched 0.2-0.5 (weights 2:1:1)."""
    band = _pick(rng, (("dry", 2), ("wet", 1), ("snow", 1)))
    lo, hi = {"dry": (0.9, 1.1), "wet": (0.55, 0.9), "snow": (0.2, 0.5)}[band]
    return _r(rng.uniform(lo, hi), 3)


def _vehicle(rng: random.Random) -> VehicleParams:
    """A passenger car from a small hatchback to a large SUV. Real cars understeer by design: the
    rear axle's cornering stiffness per unit load is drawn 1.1-1.6x the front's (the front lumps in
    steering compliance), which with the drawn CG position keeps the understeer gradient positive
    over the whole range."""
    mass = rng.uniform(1100.0, 2500.0)
    wheelbase = rng.uniform(2.4, 3.1)
    front_share = rng.uniform(0.52, 0.62)  # static load on the front axle (FWD-heavy .. balanced)
    lf = wheelbase * (1.0 - front_share)
    dyn_index = rng.uniform(0.8, 1.1)  # I / (m lf lr): cars cluster around 0.9-1.0
    ky1_f = rng.uniform(11.0, 18.0)
    ky1_r = ky1_f * rng.uniform(1.1, 1.6)
    base = VehicleParams()
    return replace(
        base, mass_kg=_r(mass, 1), yaw_inertia_kgm2=_r(mass * dyn_index * lf * (wheelbase - lf), 1),
        lf_m=_r(lf, 3), lr_m=_r(wheelbase - lf, 3), track_m=_r(rng.uniform(1.45, 1.70), 3),
        cg_height_m=_r(rng.uniform(0.45, 0.72), 3), wheel_radius_m=_r(rng.uniform(0.29, 0.36), 4),
        steering_ratio=_r(rng.uniform(13.0, 18.0), 2),
        roll_gradient_rad_per_g=_r(rng.uniform(2.0, 6.0) * RAD, 5),
        roll_stiffness_front_share=_r(rng.uniform(0.5, 0.65), 3),
        tyre_front=replace(base.tyre_front, ky1=_r(ky1_f, 2)),
        tyre_rear=replace(base.tyre_rear, ky1=_r(ky1_r, 2)),
        driven_axle=_pick(rng, (("front", 2), ("rear", 1), ("all", 1))),
        max_drive_power_w=_r(rng.uniform(60e3, 250e3), -3))


def _sensors(rng: random.Random) -> SensorParams:
    """Production ESC-cluster IMU, ABS wheel speeds and steering angle sensor, as a car has them:
    residual offsets after the ECU's own compensation, noise densities of automotive MEMS parts."""
    return SensorParams(
        jitter_s=_r(rng.uniform(0.0001, 0.001), 5),
        yaw_rate_bias_radps=_r(rng.uniform(-1.0, 1.0) * RAD, 6),
        accel_x_bias_mps2=_r(rng.uniform(-0.3, 0.3), 3),
        accel_y_bias_mps2=_r(rng.uniform(-0.3, 0.3), 3),
        wheel_scale=_r(rng.uniform(0.97, 1.03), 4),  # tyre wear, pressure, a different tyre size
        steering_offset_rad=_r(rng.uniform(-3.0, 3.0) * RAD, 5),
        yaw_rate_noise_radps=_r(rng.uniform(0.04, 0.2) * RAD, 6),
        accel_noise_mps2=_r(rng.uniform(0.02, 0.12), 3),
        wheel_speed_noise_mps=_r(rng.uniform(0.01, 0.05), 3),
        steering_noise_rad=_r(rng.uniform(0.05, 0.3) * RAD, 6),
        wheel_lag_s=_r(rng.choice((0.0, rng.uniform(0.0, 0.03))), 4))


def _gnss(rng: random.Random) -> GnssParams:
    """A single velocity receiver: automotive / consumer u-blox or NMEA parts, roof or dash antenna."""
    vel = rng.uniform(0.02, 0.15)
    return GnssParams(
        protocol=_pick(rng, (("ubx", 2), ("nmea", 1))),
        rate_hz=float(rng.choice((1, 2, 4, 5, 8, 10))),
        latency_s=_r(rng.uniform(0.05, 0.8), 3),
        latency_jitter_s=_r(rng.uniform(0.001, 0.02), 4),
        vel_noise_mps=_r(vel, 3),
        speed_acc_mps=_r(vel * rng.uniform(1.0, 3.0), 3),  # sAcc: receivers state it pessimistically
        lever_arm_m=(_r(rng.uniform(-1.0, 2.0), 2), _r(rng.uniform(-0.6, 0.6), 2)),
        pos_noise_m=_r(rng.uniform(0.5, 3.0), 2), pos_tau_s=_r(rng.uniform(10.0, 60.0), 1),
        num_sv=rng.randint(6, 20))


def _manoeuvre(rng: random.Random, kind: str, mu: float) -> tuple[tuple, float | None]:
    """Builder parameters (and a duration, None: the builder's own) within what a driver does on
    this friction: a corner's steady lateral acceleration up to 0.85 mu g (the limit of a
    careful-but-brisk driver; the builders with their own speed plans may go beyond)."""
    ay_max = 0.85 * mu * G
    if kind == "flying":
        v = rng.uniform(5.0, 45.0)
        radius = 0.0
        if rng.random() < 0.6:  # mid-corner
            ay = rng.uniform(0.05, 1.0) * ay_max
            radius = max(v * v / ay, 8.0)
        params = (("v", _r(v, 2)), ("radius_m", _r(radius, 1)), ("left", rng.random() < 0.5),
                  ("corner_s", _r(rng.uniform(4.0, 20.0), 1)))
        return params, _r(rng.uniform(30.0, 60.0), 1)
    if kind == "steady_circle":
        return (("radius_m", _r(rng.uniform(20.0, 150.0), 1)), ("left", rng.random() < 0.5)), None
    if kind == "brake_turn":
        return (("radius_m", _r(rng.uniform(40.0, 120.0), 1)),), None
    if kind == "reversing":
        return (("v_back", _r(rng.uniform(1.5, 6.0), 2)),), None
    if kind == "low_speed":
        radius = rng.uniform(9.0, 30.0)
        v_max = min(rng.uniform(7.0, 13.0), math.sqrt(ay_max * radius))
        return (("radius_m", _r(radius, 1)), ("v_max", _r(max(v_max, 5.5), 2))), None
    if kind == "road_course":
        return (("profile", rng.choice(("country", "handling"))),), None
    return (), None


def draw(seed: int) -> Scenario:
    """The drive of ``seed`` (for this GENERATOR_VERSION): every field drawn from ``random.Random(seed)``."""
    rng = random.Random(seed)
    kind = _pick(rng, KINDS)
    mu = _surface(rng)
    params, duration = _manoeuvre(rng, kind, mu)
    mu_change = None
    if rng.random() < 0.1:  # a shower or a wet patch: friction drops mid-drive, the plan stays
        mu_change = (_r(rng.uniform(10.0, 40.0), 1), _r(mu * rng.uniform(0.4, 0.8), 3))
    bank = grade = 0.0
    if rng.random() < 0.6:  # a cross slope (crossfall / superelevation, up to 7 %) and a grade (up to 8 %)
        bank = _r(math.atan(rng.uniform(-0.07, 0.07)), 5)
        grade = _r(math.atan(rng.uniform(-0.08, 0.08)), 5)
    vehicle = _vehicle(rng)
    sensors = _sensors(rng)
    gnss = _gnss(rng)
    errors = tuple((p, _r(rng.uniform(0.7, 1.3), 3)) for p in ("mass", "inertia", "cf", "cr") if rng.random() < 0.5)
    prior = None
    if rng.random() < 0.5:  # the user's latency prior from a datasheet, off by up to 0.3 s
        prior = _r(max(0.0, gnss.latency_s + rng.uniform(-0.3, 0.3)), 3)
    heading0 = _r(rng.uniform(0.0, 2.0 * math.pi), 5)
    return Scenario(
        name=f"random_v{GENERATOR_VERSION}_s{seed}", manoeuvre=kind, mu=mu, mu_change=mu_change,
        bank_rad=bank, grade_rad=grade, vehicle=vehicle, sensors=sensors, gnss=gnss, seed=seed,
        duration_s=duration, heading0_rad=heading0, params=params, config_errors=errors,
        latency_prior_s=prior, description=f"random drive seed {seed}, generator v{GENERATOR_VERSION}")


def _quantity(v: dict) -> dict:
    """The honesty figures of one quantity's ``validity`` block (evaluate.validity_metrics)."""
    n = v.get("valid_rows", 0)
    beyond = v.get("valid_beyond_3sigma", 0)

    def num(key: str) -> float:
        # evaluation.json writes a figure with no rows to take it over as null (a reversing drive
        # never above 5 m/s has no valid fraction there): NaN here, as every other missing figure
        x = v.get(key)
        return math.nan if x is None else x

    return {"valid_rows": n, "beyond_3sigma": beyond,
            "beyond_3sigma_pct": 100.0 * beyond / n if n else math.nan,
            "coverage_3sigma": num("coverage_3sigma"),
            "worst_error_valid": num("worst_error_valid"),
            "valid_fraction": num("valid_fraction"),
            "valid_fraction_above_5mps": num("valid_fraction_above_5mps")}


def broken(figures: dict) -> list[str]:
    """Which promises the drive breaks: ``cov-<q>`` (valid rows within 3 sigma < 99 %), ``worst-<q>``."""
    out = []
    for q in QUANTITIES:
        f = figures[q]
        if f["valid_rows"] and f["coverage_3sigma"] < TARGETS["coverage_3sigma"]:
            out.append(f"cov-{q}")
        if q in WORST_LIMIT and f["valid_rows"] and f["worst_error_valid"] > WORST_LIMIT[q]:
            out.append(f"worst-{q}")
    return out


def run_drive(seed: int, out_dir: str, max_duration_s: float | None = None) -> dict:
    """Draw, simulate, replay and score one drive with the suite's code; a JSON-able result."""
    sc = draw(seed)
    if max_duration_s is not None:
        sc = replace(sc, duration_s=min(sc.duration(), max_duration_s))
    row = run_case(SuiteCase(sc.name, "random", sc), out_dir)
    ev_path = Path(out_dir) / sc.name / "evaluation.json"
    error = next((f for f in row["failed"] if f.startswith("error:")), None)
    # the drive left what the chassis DBC can carry and the config would take the range end as a
    # measurement (a wheel speed beyond its range that the config's plausibility range drops is sent
    # saturated: sim/can_encoder.py): a limit of the recording, not of the estimator
    unencodable = error if error is not None and error.startswith("error: UnencodableValue") else None
    figures = {}
    if error is None:
        ev = json.loads(ev_path.read_text())["evaluation"]
        figures = {q: _quantity(ev[q].get("validity", {})) for q in QUANTITIES}
    return {"seed": seed, "version": GENERATOR_VERSION, "name": sc.name, "scenario": repr(sc),
            "manoeuvre": sc.manoeuvre, "spun_out": bool(row.get("spun_out", False)), "error": error,
            "suite_failed": [f for f in row["failed"] if not f.startswith("error:")],
            "unencodable": unencodable,
            "figures": figures, "broken": broken(figures) if figures else ([] if unencodable else ["error"]),
            "wall_s": row["wall_s"]}


def summary(drives: list[dict]) -> dict:
    """Overall figures: valid rows beyond 3 sigma summed over the drives, worst errors, mean valid
    fractions, and the seeds that break the promise."""
    out = {"drives": len(drives), "errors": [d["seed"] for d in drives if d["error"] and not d.get("unencodable")],
           "unencodable": [d["seed"] for d in drives if d.get("unencodable")],
           "breaking_seeds": [d["seed"] for d in drives if d["broken"]]}
    scored = [d for d in drives if d["figures"]]
    for q in QUANTITIES:
        fs = [d["figures"][q] for d in scored]
        n = sum(f["valid_rows"] for f in fs)
        b = sum(f["beyond_3sigma"] for f in fs)
        worst = [f["worst_error_valid"] for f in fs if f["valid_rows"]]
        vf = [f["valid_fraction_above_5mps"] for f in fs if math.isfinite(f["valid_fraction_above_5mps"])]
        out[q] = {"valid_rows": n, "beyond_3sigma": b, "beyond_3sigma_pct": 100.0 * b / n if n else math.nan,
                  "worst_error_valid": max(worst) if worst else math.nan,
                  "worst_seed": scored[[f["worst_error_valid"] for f in fs].index(max(worst))]["seed"] if worst else None,
                  "mean_valid_fraction_above_5mps": sum(vf) / len(vf) if vf else math.nan,
                  "drives_below_99pct": [d["seed"] for d in scored if d["figures"][q]["valid_rows"]
                                         and d["figures"][q]["coverage_3sigma"] < TARGETS["coverage_3sigma"]]}
    return out


def _fmt(x: float, scale: float = 1.0, f: str = "{:.2f}") -> str:
    return "-" if not isinstance(x, (int, float)) or not math.isfinite(x) else f.format(x * scale)


def format_report(drives: list[dict], overall: dict) -> str:
    """Per drive one line, the overall block, then the Scenario repr of every breaking drive."""
    lines = [f"random drives, generator v{GENERATOR_VERSION}: per quantity beyond-3-sigma valid rows"
             " (count/valid, %), worst error while valid, valid fraction above 5 m/s"]
    for d in drives:
        if d.get("unencodable"):
            lines.append(f"seed {d['seed']:>5} {d['manoeuvre']:<18} not scored: the simulated drive does not fit"
                         f" the chassis DBC ({d['error'][len('error: '):]})")
            continue
        if d["error"]:
            lines.append(f"seed {d['seed']:>5} {d['manoeuvre']:<18} {d['error']}")
            continue
        cells = []
        for q in QUANTITIES:
            f = d["figures"][q]
            unit, k = UNIT[q]
            cells.append(f"{q[:2]} {f['beyond_3sigma']}/{f['valid_rows']} ({_fmt(f['beyond_3sigma_pct'], 1, '{:.1f}')}%)"
                         f" worst {_fmt(f['worst_error_valid'], k)} {unit} val {_fmt(f['valid_fraction_above_5mps'], 100, '{:.0f}')}%")
        lines.append(f"seed {d['seed']:>5} {d['manoeuvre']:<18} " + " | ".join(cells)
                     + ("  BREAKS " + ",".join(d["broken"]) if d["broken"] else "")
                     + ("  [spun out]" if d["spun_out"] else ""))
    lines.append(f"overall: {overall['drives']} drives, {len(overall['breaking_seeds'])} break the promise"
                 f" (seeds {overall['breaking_seeds']}), errors {overall['errors']},"
                 f" not encodable in the chassis DBC (not scored) {overall['unencodable']}")
    for q in QUANTITIES:
        o = overall[q]
        unit, k = UNIT[q]
        lines.append(f"  {q}: {o['beyond_3sigma']} of {o['valid_rows']} valid rows beyond 3 sigma"
                     f" ({_fmt(o['beyond_3sigma_pct'], 1, '{:.2f}')} %), worst valid error"
                     f" {_fmt(o['worst_error_valid'], k)} {unit} (seed {o['worst_seed']}), mean valid fraction"
                     f" above 5 m/s {_fmt(o['mean_valid_fraction_above_5mps'], 100, '{:.1f}')} %,"
                     f" drives below 99 %: {o['drives_below_99pct']}")
    for d in drives:
        if d["broken"]:
            lines.append(f"seed {d['seed']} (v{d['version']}) {','.join(d['broken'])}: {d['scenario']}")
    return "\n".join(lines)


def parse_seeds(text: str) -> list[int]:
    """``1-40``, ``3,7,9`` or a mix: ``1-5,12``."""
    out = []
    for part in text.split(","):
        if "-" in part:
            a, b = part.split("-")
            out.extend(range(int(a), int(b) + 1))
        elif part:
            out.append(int(part))
    return out


def run(seeds: list[int], out_dir: str | Path, jobs: int = 1, max_duration_s: float | None = None,
        progress=None) -> tuple[list[dict], dict]:
    """Drives in seed order and the overall summary; writes ``out_dir/random_drives.json``."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    if jobs <= 1:
        drives = []
        for s in seeds:
            drives.append(run_drive(s, str(out), max_duration_s))
            if progress:
                progress(drives[-1])
    else:
        with ProcessPoolExecutor(max_workers=jobs) as pool:
            futures = [pool.submit(run_drive, s, str(out), max_duration_s) for s in seeds]
            drives = []
            for fut in futures:
                drives.append(fut.result())
                if progress:
                    progress(drives[-1])
    overall = summary(drives)
    doc = {"version": GENERATOR_VERSION, "max_duration_s": max_duration_s,
           "drives": [public({k: v for k, v in d.items() if k != "wall_s"}) for d in drives],
           "overall": public(overall)}
    (out / "random_drives.json").write_text(json.dumps(doc, indent=1, allow_nan=False) + "\n")
    return drives, overall


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", default="1-40", help="e.g. 1-40 or 3,7,12 (default 1-40)")
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--out", default="out/random_drives")
    ap.add_argument("--max-duration", type=float, default=None,
                    help="cut every drive to this many seconds (quick structure checks only)")
    ap.add_argument("--show", action="store_true", help="print the drawn Scenarios, run nothing")
    a = ap.parse_args(argv)
    seeds = parse_seeds(a.seeds)
    if a.show:
        for s in seeds:
            print(f"seed {s} (v{GENERATOR_VERSION}): {draw(s)!r}")
        return 0
    started = time.perf_counter()

    def tick(d):
        print(f"  seed {d['seed']} {d['manoeuvre']}: {'BREAKS ' + ','.join(d['broken']) if d['broken'] else 'ok'}"
              f" ({d['wall_s']:.1f} s)", file=sys.stderr, flush=True)

    drives, overall = run(seeds, a.out, a.jobs, a.max_duration, tick)
    print(format_report(drives, overall))
    print(f"{len(drives)} drive(s) in {time.perf_counter() - started:.0f} s; {Path(a.out) / 'random_drives.json'}",
          file=sys.stderr)
    return 1 if overall["breaking_seeds"] else 0


if __name__ == "__main__":
    sys.exit(main())
