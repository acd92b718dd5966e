"""Replay one simulated drive at several step-grid phases and show what differs between them.

Why: a live run starts at an arbitrary phase of the 6 ms step grid, and live11 found the demo
drive's sideslip RMS to depend on that phase (0.115-0.195 deg over 12 phases). This tool shifts
every CAN and GNSS time stamp by ``dt * i / phases`` (the drive itself is unchanged) and prints,
per phase, the sideslip/heading RMS, the sideslip RMS per 5 s bin and the GNSS latency
identification's decisions (when the delay moved off its prior, where to, and the likelihood
ratio of the current delay at that moment), so the mechanism behind the spread can be read off.

``--fixed-latency`` replays with ``gnss.estimate_delay = false`` (the latency held at its prior,
which the simulator makes the true one): the spread that remains is the rest of the estimator's.

What it found on the demo drive (12 phases): the spread is the latency identification's
refutation test. After 20 s only the wheels' profile judges (the accelerometer's has none), and
its likelihood ratio at the true 0.4 s wanders between ~3 and ~16 = LR_REJECT; the phase decides
when it first crosses (26.8-58.4 s). From then the delay moves to 0.407-0.415 s (the wheels'
best: 0.414-0.438 s), the cornering compliances follow, and the circle's last 15 s carry a
sideslip bias of -0.31/-0.34 deg (early move) instead of -0.16/-0.19 (late move). Sideslip RMS
0.165-0.195 deg where it moved before 49 s, 0.115-0.127 where after 56 s; with
``--fixed-latency`` 0.136-0.146 at every phase.

    python3 tools/grid_phase.py [--scenario demo] [--phases 12] [--only 0,3,6,9] [--fixed-latency]
"""
from __future__ import annotations

import argparse
import math
import os
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from ecu_daemon.demo import TruthTracker  # noqa: E402
from ecu_daemon.estimator import latency as latency_module  # noqa: E402
from ecu_daemon.io.logging_setup import setup_logging  # noqa: E402
from ecu_daemon.pipeline import Pipeline  # noqa: E402
from ecu_daemon.sim import SCENARIOS, simulate, vehicle_config  # noqa: E402

DEG = 180.0 / math.pi
NOW = [0.0]  # drive time of the item being fed (for the latency log)
LATENCY_LOG: list = []  # (drive t, delay before, LR of the current delay per reference, delay after)


def _record_refinements() -> None:
    """Wrap the latency identification's decision step to log its inputs and outcome (read-only:
    the statistics are memoised, so computing the profiles first changes nothing)."""
    orig = latency_module.LatencyEstimator._refine

    def _refine(self) -> None:
        if self.owner is not None or not self.enabled:
            orig(self)
            return
        d0 = self.delay_s
        cur = int(round(d0 / self.dt)) - 1
        lrs = []
        for p in (ref._profile() for ref in self.references):
            lrs.append(None if p is None else round(float(p[0][min(cur, len(p[0]) - 1)]), 1))
        orig(self)
        LATENCY_LOG.append((NOW[0], d0, lrs, self.delay_s))

    latency_module.LatencyEstimator._refine = _refine


def replay_at_phase(sim, cfg, c0: float) -> list:
    at = lambda t: float("%.6f" % (t - sim.t0 + c0))  # noqa: E731  (1 us, as recorded)
    items = sorted([(at(t), 0, fid, bytes(d)) for t, fid, d in sim.can_frames]
                   + [(at(t), 1, None, p) for t, p in sim.gnss_messages], key=lambda e: (e[0], e[1]))
    pl = Pipeline(cfg, encode=False, gnss_connected=True)
    out = []
    for t, kind, fid, data in items:
        NOW[0] = round(t - c0, 3)
        if kind == 0:
            pl.push_can(t, fid, data)
        else:
            pl.push_gnss(t, data, "gnss")
        out += [s.estimate for s in pl.feed(t)]
    return out + [s.estimate for s in pl.finish(items[-1][0])]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="demo")
    ap.add_argument("--phases", type=int, default=12)
    ap.add_argument("--only", help="comma-separated phase indices (default: all)")
    ap.add_argument("--fixed-latency", action="store_true", help="gnss.estimate_delay = false")
    args = ap.parse_args()
    setup_logging("error")
    _record_refinements()
    sc = SCENARIOS[args.scenario]
    sim = simulate(sc, vehicle_config(sc))
    cfg = vehicle_config(sc)
    if args.fixed_latency:
        cfg.gnss.estimate_delay = False
        cfg.gnss.delay_monitor = False
    dt = cfg.estimator.dt_s
    which = [int(i) for i in args.only.split(",")] if args.only else range(args.phases)
    for i in which:
        c0 = 1000.0 + dt * i / args.phases
        LATENCY_LOG.clear()
        ests = replay_at_phase(sim, cfg, c0)
        tr = TruthTracker(sim, lambda t: t - c0 + sim.t0)
        tr.add(ests)
        err = []
        for e in ests:
            s = e.t - c0 + sim.t0
            if e.sideslip_valid and tr.t[0] <= s <= tr.t[-1]:
                err.append((e.t - c0, (e.sideslip_rad - tr.truth_at(s)["sideslip_rad"]) * DEG))
        err = np.array(err)
        bins = " ".join(f"{b}:{math.sqrt(np.mean(err[m, 1] ** 2)):.3f}" for b in range(0, int(err[-1, 0]) + 5, 5)
                        if (m := (err[:, 0] >= b) & (err[:, 0] < b + 5)).any())
        moves = [(t, d0, lr, d1) for t, d0, lr, d1 in LATENCY_LOG if d1 != d0]
        first = moves[0] if moves else None
        print(f"phase {i:2d} ({dt * i / args.phases * 1e3:.2f} ms): sideslip RMS {tr.rms_sideslip_deg():.4f} deg,"
              f" heading {tr.rms_heading_deg():.4f} deg; per 5 s: {bins}")
        print(f"   latency: {len(moves)} moves, final {LATENCY_LOG[-1][3] if LATENCY_LOG else float('nan'):.4f} s"
              + (f", first at {first[0]:.2f} s (LR of the current delay per reference {first[2]})" if first else "")
              + f"; max per-reference LR of the prior before the first move (the decision may use the slip-free profile instead) {max((max(x for x in lr if x is not None) for t, d0, lr, d1 in LATENCY_LOG if (not first or t < first[0]) and any(x is not None for x in lr)), default=float('nan'))}"
              f"; load {os.getloadavg()[0]:.1f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
