"""python3 tools/limit_axles.py RD_OUT [SEED,...]: per random drive that reached its friction limit, how far each axle
slipped beyond its linear tyre law there, and the published sideslip's |error| / std (awd40, issue 7).

Why: the single-track pseudo-measurement asserts the rear axle's linear law; the one vy-free witness of an axle
beyond its law, the steering's misfit (L r - vx delta against the laws' front-minus-rear slip, core.LAW_EXCESS),
sees only the *difference* of the two axles' excesses. A car that leaves its law at both axles alike (near
neutral at its limit) passes unseen: random drive 1639 (j-turn, mu 0.206, all-wheel drive) had the front 2.7 and
the rear 1.9 deg beyond their laws (median over its limit rows), a difference of 0.8 deg, and its sideslip
published 3.2 sigma off (median; 727 valid rows beyond 3 sigma). This prints, over the rows where the truth's
|a| / (mu g) > 0.9 (|ay| > 0.5 m/s^2, vx > 5 m/s), the median front and rear slip beyond the law with the
*true* linear stiffness (truth.csv's slip angles against m ay l / L / C), their difference, and the
sideslip's |error| / std (all rows, and the valid ones).
"""
import json, math, os, statistics as st, sys

import numpy as np

from ecu_daemon.evaluate import ESTIMATE_REQUIRED, read_csv, same_time_rows
from ecu_daemon.plots import wrap

TRUTH_COLUMNS = ("t", "vx_mps", "ax_mps2", "ay_mps2", "mu", "sideslip_rad", "slip_angle_front_rad",
                 "slip_angle_rear_rad")


def quantile(v, p: float) -> float:
    """The sorted value at index int(p (n - 1)) (no interpolation), NaN when empty."""
    return float(np.sort(v)[int(p * (len(v) - 1))]) if len(v) else math.nan


base = sys.argv[1]
only = {int(s) for s in sys.argv[2].split(",")} if len(sys.argv) > 2 else None
for x in json.load(open(os.path.join(base, "random_drives.json")))["drives"]:
    d = os.path.join(base, x["name"])
    if (only and x["seed"] not in only) or not os.path.exists(os.path.join(d, "truth.csv")):
        continue
    sc = json.load(open(os.path.join(d, "scenario.json")))
    v = sc["vehicle"]; m = v["mass_kg"]; wb = v["lf_m"] + v["lr_m"]
    cf, cr = sc["true_cornering_stiffness_n_per_rad"]["front"], sc["true_cornering_stiffness_n_per_rad"]["rear"]
    tr = read_csv(os.path.join(d, "truth.csv"), TRUTH_COLUMNS, "truth CSV")
    ay = tr["ay_mps2"]
    limit = (tr["vx_mps"] >= 5) & (np.abs(ay) >= 0.5) & (np.hypot(tr["ax_mps2"], ay) / (tr["mu"] * 9.81) >= 0.9)
    if not limit.any():
        continue
    sgn = np.where(ay > 0, 1.0, -1.0)
    fe = sgn * np.degrees(tr["slip_angle_front_rad"] - m * ay * v["lr_m"] / wb / cf)
    re_ = sgn * np.degrees(tr["slip_angle_rear_rad"] - m * ay * v["lf_m"] / wb / cr)
    est = read_csv(os.path.join(d, "estimate.csv"), ESTIMATE_REQUIRED, "estimate CSV")
    ti, ei = same_time_rows(tr, est)
    ti, ei = ti[limit[ti]], ei[limit[ti]]
    sd = est["sideslip_std_rad"][ei]
    e = np.abs(wrap(est["sideslip_rad"][ei] - tr["sideslip_rad"][ti]))
    z = np.divide(e, sd, out=np.full(len(e), math.inf), where=sd > 0)
    zv = z[est["sideslip_valid"][ei] > 0.5]
    f_, r_ = st.median(fe[limit]), st.median(re_[limit])
    print(f"{x['seed']:5d} {x['manoeuvre']:14s} {v['driven_axle']:5s} mu={sc['mu']:.3f} limit rows {int(limit.sum()):5d}: beyond law "
          f"front {f_:+.2f} rear {r_:+.2f} diff {f_ - r_:+.2f} deg | |err|/std p50 {quantile(z, .5):.2f} max {z.max() if len(z) else math.nan:.2f}; "
          f"valid {len(zv)} max {zv.max() if len(zv) else 0:.2f}")
