#!/usr/bin/env python3
"""Is the live daemon as good as the replay of the same drive? Runs ``ecu-daemon demo`` N times
(recorded) and compares each live run with offline replays of the same drive.

Why this tool: the demo's sideslip RMS moved 0.11-0.22 deg between runs of the same code while a
replay gave one number. A single replay number is not the reference: the replay's result depends on
where the 6 ms step grid falls between the drive's sample times (which step each input lands in), and
a live run starts at an arbitrary phase of that grid. So the reference is the spread of replays over
``--phases`` grid phases, and each live run is taken apart by replaying it with one cause at a time:

* ``replay(drive)``: the drive's own receive times at the live run's start (``c0``), time rule;
* ``replay(rec CAN + drive GNSS)``: the CAN frames as the daemon stamped them (recording);
* ``replay(drive CAN + rec GNSS)``: the GNSS chunks as the daemon stamped them (read time on the loop);
* ``replay(rec)``: the whole recording by the time rule (no late samples, no overruns);
  the live run itself = the recording replayed with its tick record (``tests/test_daemon_replay.py``).

Printed per run: load average, RMS sideslip / heading error over valid steps (live and each replay),
late samples, tick lateness (p50/p99/max, overruns), and how far the recorded receive times are from
the drive's (CAN frames; GNSS: the chunk completing each message), in ms. Wall-clock numbers: report
the load average with them.

    python3 tools/live_vs_replay.py [--runs 3] [--phases 12] [--late-gnss 0 1 3] [--duration S] [--out DIR]
"""
from __future__ import annotations

import argparse
import io
import json
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from ecu_daemon.canlog import read_can_log  # noqa: E402
from ecu_daemon.demo import DemoSession, TruthTracker  # noqa: E402
from ecu_daemon.gnss.logfile import read_gnss_log  # noqa: E402
from ecu_daemon.pipeline import Pipeline  # noqa: E402
from ecu_daemon.sim import SCENARIOS, simulate, vehicle_config  # noqa: E402

DEG = 180.0 / np.pi


def replay(cfg, items) -> list:
    """The time rule, item by item: ``items`` (t, kind 0 CAN / 1 GNSS, id, data) in time order."""
    pl = Pipeline(cfg, encode=False, gnss_connected=True)
    out = []
    for t, kind, fid, data in items:
        if kind == 0:
            pl.push_can(t, fid, data)
        else:
            pl.push_gnss(t, data, "gnss")
        out += [s.estimate for s in pl.feed(t)]
    out += [s.estimate for s in pl.finish(items[-1][0])]
    return out


def score(sim, c0: float, ests) -> tuple[float, float]:
    """(sideslip, heading) RMS error in deg over the valid steps, daemon time ``c0`` = drive start."""
    tr = TruthTracker(sim, lambda t: t - c0 + sim.t0)
    tr.add(ests)
    return round(tr.rms_sideslip_deg(), 4), round(tr.rms_heading_deg(), 4)


def drive_items(sim, c0: float):
    """The drive's CAN frames and GNSS messages on the daemon clock (start ``c0``), 1 us as recorded."""
    at = lambda t: float("%.6f" % (t - sim.t0 + c0))  # noqa: E731
    return ([(at(t), 0, fid, bytes(d)) for t, fid, d in sim.can_frames],
            [(at(t), 1, None, p) for t, p in sim.gnss_messages])


def pct(a, qs=(50, 99)) -> list[float]:
    a = np.asarray(a)
    return [round(float(np.percentile(a, q)), 3) for q in qs] + [round(float(a.max()), 3)] if len(a) else []


def late_gnss_replay(cfg, sim, lag_steps: int) -> dict:
    """The drive ticked as live (``Pipeline.tick``), every GNSS message reaching the tick thread
    ``lag_steps`` steps after its step: what late GNSS alone does (fused count, learned latency)."""
    from ecu_daemon.step_grid import last_step_at, step_of

    dt = cfg.estimator.dt_s
    c0 = 1000.0
    can_items, gnss_items = drive_items(sim, c0)
    events = sorted(can_items + gnss_items, key=lambda e: (e[0], e[1]))
    due = [step_of(t, dt) + (lag_steps if kind else 0) for t, kind, _, _ in events]
    order = sorted(range(len(events)), key=lambda j: (due[j], j))
    pl = Pipeline(cfg, encode=False, gnss_connected=True)
    ests, i = [], 0
    for k in range(step_of(events[0][0], dt), last_step_at(events[-1][0], dt) + lag_steps + 2):
        while i < len(order) and due[order[i]] <= k:
            t, kind, fid, data = events[order[i]]
            i += 1
            if kind == 0:
                pl.push_can(t, fid, data)
            else:
                pl.push_gnss(t, data, "gnss")
        ests += [st.estimate for st in pl.tick(k)]
    est = pl.estimator
    return {"gnss_lag_steps": lag_steps, "late": pl.late_items, "fused": est.receivers[0].fused,
            "latency_s": round(est.latency.delay_s, 4), "rms": score(sim, c0, ests)}


def one_live_run(sim, scenario, rec: Path) -> dict:
    cfg = vehicle_config(scenario)
    session = DemoSession(cfg, sim, speed=1.0, tui=False, record_dir=rec, out=io.StringIO())
    load0 = os.getloadavg()[0]
    session.run()
    load1 = os.getloadavg()[0]
    d, f = session.daemon, session.feeder
    c0 = f.c0
    ts = d.tick_stats
    snap = ts.snapshot()
    res = {"load": [round(load0, 2), round(load1, 2)],
           "live": [round(session.truth.rms_sideslip_deg(), 4), round(session.truth.rms_heading_deg(), 4)],
           "late_samples": d.late_samples,
           "tick_us": [round(ts.total_percentile(50) * 1e6), round(ts.total_percentile(99) * 1e6),
                       round(snap.late_max_total_s * 1e6)],
           "overruns": snap.overruns, "skipped": snap.skipped,
           "feeder_late_ms": pct(np.array(f._player.stats.lateness) * 1e3)}
    # recorded receive times against the drive's
    rec_can = [(t, 0, fid, bytes(data)) for t, fid, *_, data in read_can_log(rec / "can.log")]
    chunks = list(read_gnss_log(rec / "gnss.log"))
    rec_gnss = [(t, 1, None, data) for t, _, data in chunks]
    sim_can, sim_gnss = drive_items(sim, c0)
    by_id: dict = {}
    for t, _, fid, _ in sim_can:
        by_id.setdefault(fid, []).append(t)
    seen: dict = {}
    off = []
    for t, _, fid, _ in rec_can:
        i = seen.get(fid, 0)
        seen[fid] = i + 1
        if i < len(by_id.get(fid, ())):
            off.append((t - by_id[fid][i]) * 1e3)
    res["can_offset_ms"] = pct(off)
    ends = np.cumsum([len(c[2]) for c in chunks])
    idx = np.searchsorted(ends, np.cumsum([len(p) for _, _, _, p in sim_gnss]))
    ok = idx < len(chunks)
    goff = (np.array([c[0] for c in chunks])[idx[ok]] - np.array([t for t, *_ in sim_gnss])[ok]) * 1e3
    res["gnss_offset_ms"] = pct(goff)
    key = lambda e: (e[0], e[1])  # noqa: E731
    res["replay(drive)"] = score(sim, c0, replay(cfg, sorted(sim_can + sim_gnss, key=key)))
    res["replay(rec CAN + drive GNSS)"] = score(sim, c0, replay(cfg, sorted(rec_can + sim_gnss, key=key)))
    res["replay(drive CAN + rec GNSS)"] = score(sim, c0, replay(cfg, sorted(sim_can + rec_gnss, key=key)))
    res["replay(rec)"] = score(sim, c0, replay(cfg, sorted(rec_can + rec_gnss, key=key)))
    return res


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=3, help="live demo runs (default 3)")
    ap.add_argument("--phases", type=int, default=12, help="offline replays at this many step-grid phases (0: none)")
    ap.add_argument("--duration", type=float, help="only the first S seconds of the demo drive")
    ap.add_argument("--out", help="keep the recordings here (default: a temporary directory)")
    ap.add_argument("--late-gnss", type=int, nargs="*", default=[], metavar="STEPS",
                    help="also tick the drive with every GNSS message STEPS steps late (e.g. 0 1 3)")
    args = ap.parse_args()
    from ecu_daemon.io.logging_setup import setup_logging

    setup_logging("error")
    scenario = SCENARIOS["demo"]
    if args.duration:
        scenario = scenario.with_(duration_s=args.duration)
    sim = simulate(scenario, vehicle_config(scenario))
    if args.phases:
        cfg = vehicle_config(scenario)
        got = []
        for i in range(args.phases):
            c0 = 1000.0 + cfg.estimator.dt_s * i / args.phases
            can_items, gnss_items = drive_items(sim, c0)
            got.append(score(sim, c0, replay(cfg, sorted(can_items + gnss_items, key=lambda e: (e[0], e[1])))))
        beta = [g[0] for g in got]
        print(json.dumps({"replay phases": len(got), "sideslip": beta, "heading": [g[1] for g in got]}))
        print(f"replay over {len(got)} grid phases: sideslip RMS {min(beta):.3f}-{max(beta):.3f} deg"
              f" (median {np.median(beta):.3f}), heading {min(g[1] for g in got):.3f}-{max(g[1] for g in got):.3f}"
              f" deg; load {os.getloadavg()[0]:.2f}", flush=True)
    for lag in args.late_gnss:
        print(json.dumps(late_gnss_replay(vehicle_config(scenario), sim, lag)), flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        base = Path(args.out) if args.out else Path(tmp)
        runs = []
        for i in range(args.runs):
            res = one_live_run(sim, scenario, base / f"run{i}")
            runs.append(res)
            print(json.dumps(res), flush=True)
        if runs:
            live = [r["live"][0] for r in runs]
            print(f"live over {len(runs)} runs: sideslip RMS {min(live):.3f}-{max(live):.3f} deg, heading"
                  f" {min(r['live'][1] for r in runs):.3f}-{max(r['live'][1] for r in runs):.3f} deg;"
                  f" late samples {[r['late_samples'] for r in runs]}; tick p99 {[r['tick_us'][1] for r in runs]} us;"
                  f" load {[r['load'] for r in runs]}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
