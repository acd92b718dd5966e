"""python3 tools/circle_sideslip_z.py RD_OUT: per steady circle of a random_drives.py output, |sideslip error| / published std
over the turning rows above 5 m/s (|r| > 0.17 rad/s), against the configuration's m / C_r error (circ40, issue 7)."""
import csv, json, math, re, sys
base = sys.argv[1]
d = json.load(open(base + "/random_drives.json"))
for x in d["drives"]:
    if x["manoeuvre"] != "steady_circle":
        continue
    s = x["seed"]; dd = f"{base}/random_v1_s{s}"
    sc = x["scenario"]
    ce = dict(re.findall(r"\('(\w+)', ([\d.]+)\)", sc[sc.find("config_errors="):sc.find(", latency_prior")]))
    mcr = float(ce.get("mass", 1)) / float(ce.get("cr", 1))
    scj = json.load(open(dd + "/scenario.json"))
    tr = {r["t"]: r for r in csv.DictReader(open(dd + "/truth.csv"))}
    z = []; zi = []
    for r in csv.DictReader(open(dd + "/estimate.csv")):
        t = tr.get(r["t"])
        if not t or abs(float(t["vx_mps"])) < 5 or abs(float(t["yaw_rate_radps"])) < 0.17:
            continue
        e = abs(math.remainder(float(r["sideslip_rad"]) - float(t["sideslip_rad"]), 2 * math.pi))
        sd = float(r["sideslip_std_rad"])
        z.append(e / sd if sd > 0 else math.inf)
        if r["sideslip_valid"] != "1":
            zi.append(e / sd if sd > 0 else math.inf)
    q = lambda v, p: sorted(v)[int(p * (len(v) - 1))] if v else float("nan")
    print(f"{s} m/Cr_cfg/true={mcr:.2f} gnss={scj['gnss']['rate_hz']:.0f}Hz mu={scj['mu']:.2f} drop={scj['mu_change']} "
          f"vf5={x['figures']['sideslip']['valid_fraction_above_5mps']:.2f} | turning rows {len(z)}: |e|/sd p50 {q(z,.5):.2f} p95 {q(z,.95):.2f} p99 {q(z,.99):.2f} max {max(z) if z else float('nan'):.2f}"
          f" | invalid rows {len(zi)} p95 {q(zi,.95):.2f}")
