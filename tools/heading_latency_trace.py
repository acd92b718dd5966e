#!/usr/bin/env python3
"""Where a dual-antenna drive's heading error comes from: the augmented latency error ``d`` (issue 11).

Replays a suite case (``ecu-daemon evaluate --suite --out DIR`` writes ``DIR/CASE/`` with
``config.toml``, ``drive.log``, ``drive_gnss.log``, ``truth.csv``) in plain Python with two hooks
(``LatencyConsider.commit`` and ``GnssHeadingFusion.fuse``) and prints per ``--window`` seconds:
the true yaw rate, the output heading error (estimate - truth), the latency-error state ``d`` and
its std (``latency_consider.py``; absent until the augmentation starts), ``-r d`` (the heading error
a wrong ``d`` leaves: the baseline heading is predicted as ``psi + r d``), and the measured baseline
heading minus the truth at the step it was fused at (its dating).

    python3 tools/heading_latency_trace.py /tmp/suite/dual_circle [--window 5]

Why: on the suite's dual_circle (seed 1, main 2a5eb36) the heading error grows with r (err / r =
8-10 ms) while the baseline headings are dated right (-0.04..+0.03 deg per 10 s): ``d`` is set from
the first fixes after the augmentation starts mid-turn (-0.0114 s at 21.2 s, r = 12 deg/s), and a
steady circle cannot correct it (r d looks like a heading offset, a linear r ramp like a gyro-bias
ramp): -r d = 0.11 / 0.15 / 0.19 deg against 0.11 / 0.16 / 0.21 measured at 25 / 40 / 55 s.
"""
from __future__ import annotations

import argparse
import math
import os
import sys
from pathlib import Path

os.environ["ECU_DAEMON_PURE_PYTHON"] = "1"  # the hooks patch plain-Python classes

import numpy as np  # noqa: E402

DEG = 180.0 / math.pi


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("case_dir")
    ap.add_argument("--window", type=float, default=5.0)
    a = ap.parse_args()
    d = Path(a.case_dir)

    from ecu_daemon.cli import main as cli_main
    from ecu_daemon.estimator import latency_consider as lc
    from ecu_daemon.estimator.fusion import gnss_heading as gh
    from ecu_daemon.estimator.kinematic import wrap_pi

    tr = np.genfromtxt(d / "truth.csv", delimiter=",", names=True)
    t_psi = np.unwrap(tr["heading_rad"])
    dt = [math.nan]
    cons_log: list[tuple[float, float, float]] = []  # (time, d, std) after each committed update
    meas_log: list[tuple[float, float]] = []  # (time, baseline heading - truth at the fused step)

    commit0 = lc.LatencyConsider.commit

    def commit(self, hist, s, update):
        commit0(self, hist, s, update)
        cons_log.append((s * dt[0], self.d, math.sqrt(self.var)))

    fuse0 = gh.GnssHeadingFusion.fuse

    def fuse(self, hist, s, g, *args, **kw):
        t_s = s * dt[0]
        meas_log.append((t_s, wrap_pi(self.vehicle_heading(g) - np.interp(t_s, tr["t"], t_psi))))
        return fuse0(self, hist, s, g, *args, **kw)

    lc.LatencyConsider.commit = commit
    gh.GnssHeadingFusion.fuse = fuse
    import tomllib
    dt[0] = tomllib.loads((d / "config.toml").read_text())["estimator"]["dt_s"]
    out = d / "heading_latency_trace.csv"
    cli_main(["replay", "-C", str(d / "config.toml"), "--can", str(d / "drive.log"), "--gnss",
              str(d / "drive_gnss.log"), "--out-csv", str(out), "--no-progress", "--log-level", "warning"])
    e = np.genfromtxt(out, delimiter=",", names=True)
    err = np.array([wrap_pi(x) for x in e["heading_rad"] - np.interp(e["t"], tr["t"], t_psi)]) * DEG
    r = np.interp(e["t"], tr["t"], tr["yaw_rate_radps"])
    c = np.array(cons_log) if cons_log else np.zeros((0, 3))
    m = np.array(meas_log) if meas_log else np.zeros((0, 2))
    t0 = float(e["t"][0])
    print(f"{'window s':>10} {'r deg/s':>8} {'h err':>7} {'d ms':>7} {'d std':>6} {'-r d':>7} {'meas-tr':>8}")
    lo = 0.0
    while t0 + lo < e["t"][-1]:
        w = (e["t"] >= t0 + lo) & (e["t"] < t0 + lo + a.window)
        wc = (c[:, 0] >= t0 + lo) & (c[:, 0] < t0 + lo + a.window) if len(c) else np.zeros(0, bool)
        wm = (m[:, 0] >= t0 + lo) & (m[:, 0] < t0 + lo + a.window) if len(m) else np.zeros(0, bool)
        rr = float(np.mean(r[w])) * DEG
        dd, ds = (float(np.mean(c[wc, 1])), float(np.mean(c[wc, 2]))) if wc.any() else (math.nan, math.nan)
        mm = float(np.mean(m[wm, 1])) * DEG if wm.any() else math.nan
        print(f"{lo:4.0f}-{lo + a.window:<5.0f} {rr:8.2f} {np.mean(err[w]):+7.3f} {dd * 1e3:+7.2f} {ds * 1e3:6.2f} "
              f"{-rr * dd:+7.3f} {mm:+8.3f}")
        lo += a.window
    return 0


if __name__ == "__main__":
    sys.exit(main())
