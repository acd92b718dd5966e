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
import csv, json, math, os, statistics as st, sys

base = sys.argv[1]
only = {int(s) for s in sys.argv[2].split(",")} if len(sys.argv) > 2 else None
for x in json.load(open(os.path.join(base, "random_drives.json")))["drives"]:
    d = os.path.join(base, x["name"])
    if (only and x["seed"] not in only) or not os.path.exists(os.path.join(d, "truth.csv")):
        continue
    sc = json.load(open(os.path.join(d, "scenario.json")))
    v = sc["vehicle"]; m = v["mass_kg"]; wb = v["lf_m"] + v["lr_m"]
    cf, cr = sc["true_cornering_stiffness_n_per_rad"]["front"], sc["true_cornering_stiffness_n_per_rad"]["rear"]
    est = {r["t"]: r for r in csv.DictReader(open(os.path.join(d, "estimate.csv")))}
    fe, re_, z, zv = [], [], [], []
    for t in csv.DictReader(open(os.path.join(d, "truth.csv"))):
        f = lambda k: float(t[k])
        ay = f("ay_mps2")
        if f("vx_mps") < 5 or abs(ay) < 0.5 or math.hypot(f("ax_mps2"), ay) / (f("mu") * 9.81) < 0.9:
            continue
        s = 1.0 if ay > 0 else -1.0
        fe.append(s * math.degrees(f("slip_angle_front_rad") - m * ay * v["lr_m"] / wb / cf))
        re_.append(s * math.degrees(f("slip_angle_rear_rad") - m * ay * v["lf_m"] / wb / cr))
        r = est.get(t["t"])
        if r:
            sd = float(r["sideslip_std_rad"])
            e = abs(math.remainder(float(r["sideslip_rad"]) - f("sideslip_rad"), 2 * math.pi)) / sd if sd > 0 else math.inf
            z.append(e)
            if r["sideslip_valid"] == "1":
                zv.append(e)
    if not fe:
        continue
    q = lambda xs, p: sorted(xs)[int(p * (len(xs) - 1))] if xs else float("nan")
    f_, r_ = st.median(fe), st.median(re_)
    print(f"{x['seed']:5d} {x['manoeuvre']:14s} {v['driven_axle']:5s} mu={sc['mu']:.3f} limit rows {len(fe):5d}: beyond law "
          f"front {f_:+.2f} rear {r_:+.2f} diff {f_ - r_:+.2f} deg | |err|/std p50 {q(z, .5):.2f} max {max(z):.2f}; "
          f"valid {len(zv)} max {max(zv) if zv else 0:.2f}")
