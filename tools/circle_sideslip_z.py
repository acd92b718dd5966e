"""python3 tools/circle_sideslip_z.py RD_OUT: per steady circle of a random_drives.py output, |sideslip error| / published std
over the turning rows above 5 m/s (|r| > 0.17 rad/s), against the configuration's m / C_r error (circ40, issue 7)."""
import json, math, os, re, sys

import numpy as np

from ecu_daemon.evaluate import ESTIMATE_REQUIRED, TRUTH_REQUIRED, read_csv, same_time_rows
from ecu_daemon.plots import wrap


def quantile(v: np.ndarray, p: float) -> float:
    """The sorted value at index int(p (n - 1)) (no interpolation), NaN when empty."""
    return float(np.sort(v)[int(p * (len(v) - 1))]) if len(v) else math.nan


base = sys.argv[1]
d = json.load(open(os.path.join(base, "random_drives.json")))
for x in d["drives"]:
    if x["manoeuvre"] != "steady_circle":
        continue
    s = x["seed"]; dd = os.path.join(base, x["name"])
    sc = x["scenario"]
    ce = dict(re.findall(r"\('(\w+)', ([\d.]+)\)", sc[sc.find("config_errors="):sc.find(", latency_prior")]))
    mcr = float(ce.get("mass", 1)) / float(ce.get("cr", 1))
    scj = json.load(open(os.path.join(dd, "scenario.json")))
    truth = read_csv(os.path.join(dd, "truth.csv"), TRUTH_REQUIRED + ("yaw_rate_radps",), "truth CSV")
    est = read_csv(os.path.join(dd, "estimate.csv"), ESTIMATE_REQUIRED, "estimate CSV")
    ti, ei = same_time_rows(truth, est)
    turning = (np.abs(truth["vx_mps"][ti]) >= 5) & (np.abs(truth["yaw_rate_radps"][ti]) >= 0.17)
    ti, ei = ti[turning], ei[turning]
    e = np.abs(wrap(est["sideslip_rad"][ei] - truth["sideslip_rad"][ti]))
    sd = est["sideslip_std_rad"][ei]
    z = np.divide(e, sd, out=np.full(len(e), math.inf), where=sd > 0)
    zi = z[est["sideslip_valid"][ei] <= 0.5]
    print(f"{s} m/Cr_cfg/true={mcr:.2f} gnss={scj['gnss']['rate_hz']:.0f}Hz mu={scj['mu']:.2f} drop={scj['mu_change']} "
          f"vf5={x['figures']['sideslip']['valid_fraction_above_5mps']:.2f} | turning rows {len(z)}: |e|/sd p50 "
          f"{quantile(z, .5):.2f} p95 {quantile(z, .95):.2f} p99 {quantile(z, .99):.2f} max {z.max() if len(z) else math.nan:.2f}"
          f" | invalid rows {len(zi)} p95 {quantile(zi, .95):.2f}")
