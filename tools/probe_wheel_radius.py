"""Probe (issue 7, kw26): a wheel radius / wheel-speed scale a few % to 20 % off in the config.

Simulates a few drives with their right configuration, replays each through the real command line
with all four ``[inputs.wheel_speed_*] scale`` multiplied by a factor (a wrong tyre size), and
prints, per drive and factor: vx rows valid beyond 3 sigma, sideslip rows valid beyond 3 sigma,
the worst |vx error| among valid rows, the share of rows with vx valid, the final learned wheel
scale against the one the factor calls for, and whether the log named the wheel mapping.

    python3 tools/probe_wheel_radius.py --out /tmp/kw26_probe [--jobs 2] [--factors 0.88,1.12]
"""
from __future__ import annotations

import argparse
import math
import subprocess
import sys
import tomllib
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
import tomli_w

from ecu_daemon.sim import simulate, vehicle_config
from ecu_daemon.sim.scenario import SCENARIOS, Scenario
from ecu_daemon.sim.writer import write_all

WHEELS = ("wheel_speed_fl", "wheel_speed_fr", "wheel_speed_rl", "wheel_speed_rr")
FACTORS = (0.82, 0.88, 0.94, 0.97, 1.0, 1.03, 1.06, 1.12, 1.18)


def drives() -> dict[str, Scenario]:
    def flying(v, radius, left, heading):
        shape = "straight" if radius == 0 else f"r{radius:.0f}{'l' if left else 'r'}"
        name = f"flying_{v:g}_{shape}_h{heading:g}"
        return name, Scenario(name, "flying", params=(("v", v), ("radius_m", radius), ("left", left)),
                              heading0_rad=math.radians(heading))
    out = {"dlc_dry": SCENARIOS["dlc_dry"]}
    for args in ((30.0, 0.0, True, 0.0), (30.0, 150.0, True, 100.0), (6.0, 9.0, False, 250.0)):
        name, sc = flying(*args)
        out[name] = sc
    return out


def _simulate(d: Path, sc: Scenario) -> None:
    if not (d / "truth.csv").exists():
        d.mkdir(parents=True, exist_ok=True)
        write_all(d, simulate(sc, vehicle_config(sc)))


def _one(d: Path, factor: float) -> dict:
    data = tomllib.loads((d / "config.toml").read_text())
    for n in WHEELS:
        data["inputs"][n].update(scale=data["inputs"][n]["scale"] * factor)
    cfg = d / f"x{factor:g}.toml"
    cfg.write_text(tomli_w.dumps(data))
    out = cfg.with_suffix(".csv")
    r = subprocess.run([sys.executable, "-m", "ecu_daemon", "replay", "--config", str(cfg),
                        "--can", str(d / "drive.log"), "--gnss", str(d / "drive_gnss.log"),
                        "--out-csv", str(out), "--no-progress", "--log-level", "warning"],
                       capture_output=True, text=True)
    if r.returncode:
        return {"drive": d.name, "factor": factor, "error": r.stderr[-500:]}
    e = np.genfromtxt(out, delimiter=",", names=True)
    t = np.genfromtxt(d / "truth.csv", delimiter=",", names=True)
    vx = np.interp(e["t"], t["t"], t["vx_mps"])
    beta = np.interp(e["t"], t["t"], t["sideslip_rad"])
    v = e["velocity_valid"].astype(bool)
    b = e["sideslip_valid"].astype(bool)
    err_v = np.abs(e["vx_mps"] - vx)
    err_b = np.abs(e["sideslip_rad"] - beta)
    true_kw = float(np.interp(e["t"][-1], t["t"], t["wheel_scale"])) / factor
    named = [ln for ln in r.stderr.splitlines() if "wheel radius / scale in the config is off" in ln]
    return {"drive": d.name, "factor": factor,
            "bad_vx": int((v & (err_v > 3.0 * e["vx_std_mps"])).sum()),
            "bad_beta": int((b & (err_b > 3.0 * e["sideslip_std_rad"])).sum()),
            "worst_vx": float(err_v[v].max()) if v.any() else 0.0,
            "worst_beta_deg": math.degrees(float(err_b[b].max())) if b.any() else 0.0,
            "vx_valid": float(v.mean()), "beta_valid": float(b.mean()),
            "kw": float(e["wheel_scale"][-1]), "kw_true": true_kw, "named": len(named),
            "line": named[0][:160] if named else ""}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--factors", default=",".join(f"{f:g}" for f in FACTORS))
    ap.add_argument("--only", default="")
    a = ap.parse_args()
    factors = [float(f) for f in a.factors.split(",")]
    ds = {n: sc for n, sc in drives().items() if a.only in n}
    with ProcessPoolExecutor(a.jobs) as ex:
        list(ex.map(_simulate, [a.out / n for n in ds], list(ds.values())))
        rows = list(ex.map(_one, [a.out / n for n in ds for _ in factors], [f for _ in ds for f in factors]))
    print(f"{'drive':24s} {'factor':>6s} {'bad vx':>6s} {'bad b':>6s} {'worst vx':>8s} {'worst b':>8s} "
          f"{'vx val':>6s} {'b val':>6s} {'kw':>6s} {'kw true':>7s} named")
    tot_v = tot_b = 0
    for r in rows:
        if "error" in r:
            print(r["drive"], r["factor"], "ERROR", r["error"])
            continue
        tot_v += r["bad_vx"]
        tot_b += r["bad_beta"]
        print(f"{r['drive']:24s} {r['factor']:6.2f} {r['bad_vx']:6d} {r['bad_beta']:6d} {r['worst_vx']:8.2f} "
              f"{r['worst_beta_deg']:8.2f} {r['vx_valid']:6.2f} {r['beta_valid']:6.2f} {r['kw']:6.3f} "
              f"{r['kw_true']:7.3f} {r['named']}")
    print(f"total: vx rows valid beyond 3 sigma {tot_v}, sideslip rows {tot_b}")
    for r in rows:
        if r.get("line"):
            print(f"{r['drive']} x{r['factor']:g}: {r['line']}")
            break


if __name__ == "__main__":
    main()
