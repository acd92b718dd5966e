"""ECU_DAEMON_PURE_PYTHON=1 python tools/limit_witnesses.py RD_OUT SEED[,SEED...] [FIXES_DIR]: two candidate witnesses
of "both axles at the friction limit" per steady corner of a random drive, from a replay (awd41, issue 7).

Why: random drives 1639 and 1679 (all-wheel-drive j-turns on ice) publish a sideslip 3-7 sigma off through the
turn's steady part, both axles 3-4x their linear slip (awd40, tools/limit_axles.py). The rear law's vy is the
single-track pseudo-measurement; its one vy-free witness, the steering's misfit (core.LAW_EXCESS), sees the
axles' *difference*. This measures, at every fused GNSS velocity fix (the replay of RD_OUT/random_v1_sSEED's
drive.log, config.toml and drive_gnss.log, hooked at ``GnssVelocityFusion.fuse``):

* candidate (a), the course's across-track innovation (m/s; course = heading + sideslip in a steady corner),
  its mean over the corner's fixes against its std, with the GNSS noise averaging down and the heading's
  std (vx sigma_psi), the model's own claim (s_m) and the timing term (|ay| x the latency's std) as biases
  that do not (``za``), and the optimistic version with the timing counted as white (``za_w``);
* candidate (b), the steering's misfit over its own sigma (``zb``: ay below the linear single-track's ay
  for the steering and speed is the same relation, the same noise);
* and the truth: the model's vy error over its claim, the filter's sideslip error (deg).

A steady corner: fused fixes with vx > 5 m/s, |r| > 0.03 rad/s, |rdot| <= 0.2 rad/s^2, |ay| > 0.5 m/s^2, one
sign of r, < 1.5 s apart. Pure Python (the hooks patch Python classes). Per-fix rows go to FIXES_DIR/SEED.csv.
"""
import csv, math, os, sys

import numpy as np

from ecu_daemon import config as config_mod
from ecu_daemon.estimator import core
from ecu_daemon.estimator import generated as gen
from ecu_daemon.estimator.fusion import gnss_velocity as gv
from ecu_daemon.replay import run_replay

COLS = "t ok vx r ay rdot e sn spsi s_m vy_m vyt beta_err mis mis_sd delay_sd".split()


def fixes(drive_dir: str) -> list[dict]:
    """Replay one drive; one row per GNSS velocity update (before it), with the truth at its step."""
    truth = {round(float(r["t"]), 3): r for r in csv.DictReader(open(os.path.join(drive_dir, "truth.csv")))}
    rows, est = [], []
    oi, of = core.Estimator.__init__, gv.GnssVelocityFusion.fuse

    def init(self, *a, **kw):
        oi(self, *a, **kw)
        est.append(self)

    def fuse(self, hist, s, g, gate=True, delay_std_s=0.0, consider=None, along_std_s=None, along_accel=None):
        e_ = est[-1]
        i = hist.slot(s)
        X, P, aux = hist.X[i].copy(), hist.P[i].copy(), hist.aux[i].copy()
        args = (*X.tolist(), aux[core.AUX_R], self.lever_x, self.lever_y)
        vn, ve = gen.gnss_velocity(*args)
        sp = math.hypot(vn, ve)
        u = np.array((-ve / sp, vn / sp)) if sp > 0.5 else np.array((0.0, 1.0))
        y = np.array((g.vel_n_mps - vn, g.vel_e_mps - ve))
        ok = of(self, hist, s, g, gate, delay_std_s, consider, along_std_s, along_accel)
        vx, r, ay, rdot, delta = (float(X[core.VX]), float(aux[core.AUX_R]), float(aux[core.AUX_AY]),
                                  float(aux[core.AUX_RDOT]), float(aux[core.AUX_DELTA]))
        vy_m, s_m = e_.single_track.model_error(vx, r, ay, rdot)
        mis, mvar = e_.single_track._understeer_misfit(vx, r, ay, rdot, delta)
        t = s * e_.dt
        tr = truth.get(round(t, 3))
        rows.append(dict(t=t - 1200.0, ok=int(ok), vx=vx, r=r, ay=ay, rdot=rdot, e=float(u @ y),
                         sn=math.sqrt(float(u @ self._R2 @ u)), spsi=math.sqrt(P[core.PSI, core.PSI]), s_m=s_m,
                         vy_m=vy_m, vyt=float(tr["vy_mps"]) if tr else math.nan,
                         beta_err=math.degrees(math.atan2(X[core.VY], vx) - float(tr["sideslip_rad"])) if tr else math.nan,
                         mis=mis, mis_sd=math.sqrt(mvar), delay_sd=e_.latencies[0].std_s))
        return ok

    core.Estimator.__init__, gv.GnssVelocityFusion.fuse = init, fuse
    try:
        run_replay(config_mod.load(os.path.join(drive_dir, "config.toml")), os.path.join(drive_dir, "drive.log"),
                   os.path.join(drive_dir, "drive_gnss.log"))
    finally:
        core.Estimator.__init__, gv.GnssVelocityFusion.fuse = oi, of
    return rows


def corners(rows: list[dict]) -> list[dict]:
    """The steady corners' statistics (module docstring)."""
    out, cur = [], []

    def close():
        if not cur:
            return
        za, zw = [], []
        for n in range(1, len(cur) + 1):
            c, x = cur[:n], cur[n - 1]
            me = sum(y["e"] for y in c) / n
            tim2 = [(y["ay"] * y["delay_sd"]) ** 2 for y in c]
            white2 = sum(max(y["sn"] ** 2 - t2, 0.0) for y, t2 in zip(c, tim2)) / n
            bias = (x["vx"] * x["spsi"]) ** 2 + x["s_m"] ** 2
            za.append((abs(me) / math.sqrt(white2 / n + bias + tim2[-1]), x["t"]))
            zw.append((abs(me) / math.sqrt(sum(y["sn"] ** 2 for y in c) / n / n + bias), x["t"]))
        zb = sorted(abs(y["mis"]) / y["mis_sd"] for y in cur)
        out.append(dict(t0=cur[0]["t"], t1=cur[-1]["t"], n=len(cur), za=max(za), za_w=max(zw), zb_max=zb[-1],
                        zb_med=zb[len(zb) // 2], model_z=max(abs(y["vy_m"] - y["vyt"]) / y["s_m"] for y in cur),
                        beta_err=max(abs(y["beta_err"]) for y in cur), ay=max(abs(y["ay"]) for y in cur)))

    for x in rows:
        steady = x["ok"] and x["vx"] > 5 and abs(x["r"]) > 0.03 and abs(x["rdot"]) <= 0.2 and abs(x["ay"]) > 0.5
        if steady and cur and (x["r"] > 0) == (cur[-1]["r"] > 0) and x["t"] - cur[-1]["t"] < 1.5:
            cur.append(x)
        else:
            close()
            cur = [x] if steady else []
    close()
    return out


def main() -> None:
    base, seeds = sys.argv[1], [int(s) for s in sys.argv[2].split(",")]
    fix_dir = sys.argv[3] if len(sys.argv) > 3 else None
    for seed in seeds:
        rows = fixes(os.path.join(base, f"random_v1_s{seed}"))
        if fix_dir:
            os.makedirs(fix_dir, exist_ok=True)
            with open(os.path.join(fix_dir, f"{seed}.csv"), "w", newline="") as fh:
                w = csv.DictWriter(fh, COLS)
                w.writeheader()
                w.writerows(rows)
        for c in corners(rows):
            print(f"{seed} {c['t0']:6.2f}-{c['t1']:6.2f} n={c['n']:3d} za={c['za'][0]:.2f}@{c['za'][1]:.2f} "
                  f"za_w={c['za_w'][0]:.2f}@{c['za_w'][1]:.2f} zb_max={c['zb_max']:.2f} zb_med={c['zb_med']:.2f} | "
                  f"truth: model_err/s_m {c['model_z']:.1f} |beta_err| {c['beta_err']:.2f} deg |ay| {c['ay']:.2f}",
                  flush=True)


if __name__ == "__main__":
    main()
