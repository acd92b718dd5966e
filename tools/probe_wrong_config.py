"""Wrong-configuration probe (issue 7): one drive, many single config mistakes, who lies while valid.

The product is judged on held-out "wrong configurations": a user's config.toml with one plausible
mistake. This replays each simulated drive folder (``drive.log``, ``drive_gnss.log``, ``truth.csv``
and its right ``config.toml``, as ``ecu-daemon simulate`` or ``evaluate --suite --out`` leave them)
once per mistake in :data:`MISTAKES` (the config edited as a user would get it wrong) and prints per
quantity (sideslip deg, heading deg, vx m/s) ``valid rows beyond 3 sigma / valid rows, worst error
while valid``; each run's folder (``DRIVE/probe/MISTAKE``) keeps the config, the estimate, the log
(does a line name the mistake?) and ``row.json``. Rank by harm: rows beyond 3 sigma x error.

    python3 tools/probe_wrong_config.py ROOT dlc_dry,lowspeed_r15 [steer_sign,ax_ay_swapped]

(ROOT holds the drive folders; the mistakes default to all; two replays at a time.) The replays run
with ``python -P`` so they use the package of the interpreter that runs this script (its venv), the
same one this script imports, never an ``ecu_daemon`` folder that happens to be in the working
directory (run from another checkout, ``-m`` would import that tree and measure the wrong code).
"""
import copy, json, math, subprocess, sys, tomllib, os
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
import tomli_w
from ecu_daemon.evaluate import evaluate, public

PY = sys.executable
DEG = math.pi / 180
W = ["fl", "fr", "rl", "rr"]

def swap(c, a, b):
    ia, ib = c["inputs"][a], c["inputs"][b]
    ia["signal"], ib["signal"] = ib["signal"], ia["signal"]

def inp(name, **kv):
    def f(c): c["inputs"][name].update(kv)
    return f

def veh(key, fac):
    def f(c): c["vehicle"][key] *= fac
    return f

def chain(*fs):
    def f(c):
        for g in fs: g(c)
    return f

def lever(dx, dy):
    def f(c): c["gnss"]["lever_arm_m"] = [c["gnss"]["lever_arm_m"][0] + dx, c["gnss"]["lever_arm_m"][1] + dy]
    return f

def mounting_yaw(d):
    def f(c): c["imu"]["mounting_rpy_deg"] = [0.0, 0.0, d]
    return f

MISTAKES = {
    "right": lambda c: None,
    "steer_ratio_+15": veh("steering_ratio", 1.15),
    "steer_ratio_-15": veh("steering_ratio", 0.85),
    "steer_sign": inp("steering_wheel_angle", scale=-1.0),
    "steer_deg_as_rad": inp("steering_wheel_angle", scale=1 / DEG, min=-1000.0, max=1000.0),
    "steer_rad_as_deg": inp("steering_wheel_angle", scale=DEG),
    "wheelbase_+15": chain(veh("cg_to_front_axle_m", 1.15), veh("cg_to_rear_axle_m", 1.15)),
    "wheelbase_-15": chain(veh("cg_to_front_axle_m", 0.85), veh("cg_to_rear_axle_m", 0.85)),
    "lf_+15": veh("cg_to_front_axle_m", 1.15),
    "lr_-15": veh("cg_to_rear_axle_m", 0.85),
    "lf_lr_swapped": lambda c: c["vehicle"].update(cg_to_front_axle_m=c["vehicle"]["cg_to_rear_axle_m"],
                                                   cg_to_rear_axle_m=c["vehicle"]["cg_to_front_axle_m"]),
    "track_+15": veh("track_m", 1.15),
    "track_-15": veh("track_m", 0.85),
    "wheels_lr_swapped": lambda c: (swap(c, "wheel_speed_fl", "wheel_speed_fr"), swap(c, "wheel_speed_rl", "wheel_speed_rr")),
    "wheels_fr_swapped": lambda c: (swap(c, "wheel_speed_fl", "wheel_speed_rl"), swap(c, "wheel_speed_fr", "wheel_speed_rr")),
    "wheel_rl_is_rr": inp("wheel_speed_rl", signal="WHEEL_SPEED_RR"),
    "wheel_fl_is_fr": inp("wheel_speed_fl", signal="WHEEL_SPEED_FR"),
    "yaw_sign": inp("yaw_rate", scale=-1.0),
    "ax_ay_swapped": lambda c: (swap(c, "accel_x", "accel_y")),
    "gyro_deg_as_rad": inp("yaw_rate", scale=1 / DEG, min=-200.0, max=200.0),
    "gyro_rad_as_deg": inp("yaw_rate", scale=DEG),
    "latency_prior_0.1": lambda c: c["gnss"].update(delay_s=0.1),
    "latency_prior_0.1_fixed": lambda c: c["gnss"].update(delay_s=0.1, estimate_delay=False),
    "lever_x_+1m": lever(1.0, 0.0),
    "lever_y_+1m": lever(0.0, 1.0),
    "imu_yaw_+3deg": mounting_yaw(3.0),
    "imu_yaw_-3deg": mounting_yaw(-3.0),
    "wheel_offset_missing": lambda c: [c["inputs"][f"wheel_speed_{w}"].update(offset=10.016) for w in W],
}

def run(drive: Path, mistake: str):
    out = drive / "probe" / mistake
    out.mkdir(parents=True, exist_ok=True)
    data = tomllib.loads((drive / "config.toml").read_text())
    MISTAKES[mistake](data)
    (out / "config.toml").write_text(tomli_w.dumps(data))
    r = subprocess.run([PY, "-P", "-m", "ecu_daemon", "replay", "--config", str(out / "config.toml"),
                        "--can", str(drive / "drive.log"), "--gnss", str(drive / "drive_gnss.log"),
                        "--out-csv", str(out / "est.csv"), "--no-progress", "--log-level", "info"],
                       capture_output=True, text=True)
    (out / "stderr.log").write_text(r.stderr)
    row = {"drive": drive.name, "mistake": mistake, "rc": r.returncode}
    if not (out / "est.csv").exists():
        return row
    try:
        ev = public(evaluate(drive / "truth.csv", out / "est.csv"))
    except Exception as e:  # noqa
        row["error"] = str(e); return row
    for q, k in (("sideslip", 180 / math.pi), ("heading", 180 / math.pi), ("vx", 1.0)):
        v = ev[q].get("validity", {})
        row[q] = {"beyond3": v.get("valid_beyond_3sigma"), "valid_rows": v.get("valid_rows"),
                  "cov3": v.get("coverage_3sigma"),
                  "worst": None if v.get("worst_error_valid") is None else v["worst_error_valid"] * k,
                  "vf5": v.get("valid_fraction_above_5mps")}
    row["warnings"] = [l for l in r.stderr.splitlines() if " WARNING " in l or " ERROR " in l][:12]
    (out / "row.json").write_text(json.dumps(row, indent=1))
    return row

if __name__ == "__main__":
    ROOT = Path(sys.argv[1])
    drives = [ROOT / d for d in sys.argv[2].split(",")]
    mistakes = sys.argv[3].split(",") if len(sys.argv) > 3 else list(MISTAKES)
    jobs = [(d, m) for d in drives for m in mistakes]
    with ThreadPoolExecutor(2) as ex:
        for row in ex.map(lambda a: run(*a), jobs):
            s = lambda q: f"{row[q]['beyond3']}/{row[q]['valid_rows']} {row[q]['worst']:.2f}" if q in row and row[q]['worst'] is not None else "-"
            print(f"{row['drive']:24} {row['mistake']:24} b {s('sideslip'):>16} h {s('heading'):>16} vx {s('vx'):>16}", flush=True)
