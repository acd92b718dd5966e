#!/usr/bin/env python3
"""Benchmark the fleet runner on a simulated fleet (numbers, no asserts).

    .venv/bin/python tools/bench_fleet.py [--work /tmp/bench_fleet] [--vehicles 20] [--drives 20]
                                          [--scaling-drives 12] [--skip-scaling] [--skip-full]
                                          [--passes 2 [--second-pass-share F]] [--run NAME]

1. ``fleet simulate`` writes the fleet (reused when ``WORK/fleet`` exists): per vehicle its own
   GNSS latency, wheel scale and cornering stiffness, each drive a 45-70 s manoeuvre.
2. Scaling: the first ``--scaling-drives`` drives on a real ``dask.distributed.LocalCluster`` with 1
   and then 2 single-threaded worker processes (fresh result stores): drive-hours per wall-hour,
   and from Dask's task stream where the wall time goes: the tasks' own compute time (summed,
   and the first task on each worker, which pays the imports), the time before the first task
   starts, and the tail (one worker busy, the other idle at the end).
3. The whole fleet on the default local process pool (all cores): drive-hours per wall-hour and
   the replay cost per drive-hour (wall seconds in the jobs); ``--passes 2`` as ``fleet run
   --passes 2`` (both passes' drive-hours count).
4. Calibration against the truth: per vehicle the combined latency, wheel scale (against the
   free-rolling wheels' scale, and the radius error alone) and front/rear cornering stiffness vs
   ``vehicle.json``; how many vehicles meet issue 12's targets (0.02 s,
   0.2 %, 10 %).
Load averages are printed before and after each timed run (the machine is shared).
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from ecu_daemon.fleet.calibrate import vehicle_parameters  # noqa: E402
from ecu_daemon.fleet.cli import run_fleet  # noqa: E402
from ecu_daemon.fleet.manifest import discover  # noqa: E402
from ecu_daemon.fleet.simfleet import write_fleet  # noqa: E402
from ecu_daemon.fleet.tables import read_drives  # noqa: E402

TARGETS = {"gnss_delay_s": ("abs", 0.02), "wheel_scale": ("rel", 0.002),
           "cornering_stiffness_front_n_per_rad": ("rel", 0.10), "cornering_stiffness_rear_n_per_rad": ("rel", 0.10)}
#: parameters without a target whose std is checked against the truth too (z-scores only)
ALSO_Z = ("steering_offset_rad", "yaw_rate_bias_radps")


def true_value(truth: dict, name: str) -> float:
    """``vehicle.json``'s value of a parameter; the wheel scale as its rolling wheels show it
    (simfleet.free_rolling_wheel_scale)."""
    return truth["gnss_latency_s"] if name == "gnss_delay_s" else truth.get(f"{name}_free_rolling", truth[name])


def z_summary(z: list[float]) -> str:
    """Mean, mean square and largest |z| of finite z-scores (an honest std: mean square ~1)."""
    import math

    z = [x for x in z if math.isfinite(x)]
    if not z:
        return "no z"
    ms = sum(x * x for x in z) / len(z)
    return (f"z over {len(z)} vehicles: mean {sum(z) / len(z):+.2f}, mean square {ms:.2f}"
            f" (rms {math.sqrt(ms):.2f}), max |z| {max(abs(x) for x in z):.1f}")


def load() -> str:
    return "load %.2f %.2f %.2f" % os.getloadavg()


def timed(label: str, fn, passes: int = 1) -> tuple[float, list]:
    print(f"{label}: {load()} before", flush=True)
    t0 = time.perf_counter()
    recs = fn()
    wall = time.perf_counter() - t0
    hours = passes * sum(r.get("duration_s") or 0.0 for r in recs if r["status"] == "ok" and not r.get("cached")) / 3600
    job = sum(r.get("wall_s") or 0.0 for r in recs if not r.get("cached"))
    cpu = sum(r.get("cpu_s") or 0.0 for r in recs if not r.get("cached"))
    replay = sum(r.get("replay_s") or 0.0 for r in recs if not r.get("cached"))
    failed = sum(r["status"] != "ok" for r in recs)
    print(f"{label}: {len(recs)} drives ({failed} failed), {hours:.3f} drive-h in {wall:.1f} s wall ="
          f" {hours / (wall / 3600):.0f} drive-h/h; job time {job:.0f} s = {job / hours if hours else 0:.0f} s per"
          f" drive-hour, job CPU {cpu:.0f} s = {cpu / hours if hours else 0:.0f} CPU-s per drive-hour"
          f" ({cpu / wall:.2f} cores busy with them); of the job time {replay:.1f} s in the replay itself,"
          f" {job - replay:.1f} s around it (key, config, reading the estimate, scoring); {load()} after", flush=True)
    return wall, recs


def task_breakdown(tasks: list[dict], wall: float, workers: int) -> str:
    """Where a Dask run's wall time went, from the task stream: compute summed over the tasks
    (and the first task per worker, which imports the replay), the first start and last end
    relative to the earliest task event, the tail (last end minus the earliest of the workers'
    last ends) and the busy fraction workers x span."""
    spans = [(t["worker"], ss["start"], ss["stop"]) for t in tasks for ss in t["startstops"] if ss["action"] == "compute"]
    if not spans:
        return "  task stream: empty"
    t0 = min(s for _, s, _ in spans)
    t1 = max(e for _, _, e in spans)
    compute = sum(e - s for _, s, e in spans)
    by = {}
    for w, s, e in sorted(spans, key=lambda x: x[1]):
        by.setdefault(w, []).append(e - s)
    first = [d[0] for d in by.values()]
    rest = [x for d in by.values() for x in d[1:]]
    ends = [max(e for w2, _, e in spans if w2 == w) for w in by]
    return (f"  tasks {len(spans)}: compute {compute:.1f} s summed (first per worker {', '.join(f'{x:.2f}' for x in first)}"
            f" s, others mean {sum(rest) / max(len(rest), 1):.2f} s), task span {t1 - t0:.1f} s of {wall:.1f} s wall,"
            f" tail {t1 - min(ends):.1f} s, busy {compute / (workers * (t1 - t0)):.0%} of {workers} x span")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--work", default="/tmp/bench_fleet")
    ap.add_argument("--vehicles", type=int, default=20)
    ap.add_argument("--drives", type=int, default=20)
    ap.add_argument("--scaling-drives", type=int, default=12)
    ap.add_argument("--skip-scaling", action="store_true")
    ap.add_argument("--passes", type=int, default=1, choices=(1, 2), help="fleet run --passes for the whole fleet")
    ap.add_argument("--second-pass-share", type=float, default=1.0, help="fleet run --second-pass-share (with --passes 2)")
    ap.add_argument("--run", default="run", help="the whole fleet's output folder under WORK")
    ap.add_argument("--skip-full", action="store_true", help="scaling only (calibration from an earlier WORK/RUN)")
    args = ap.parse_args()
    work = Path(args.work)
    fleet = work / "fleet"
    if not fleet.exists():
        t0 = time.perf_counter()
        write_fleet(fleet, args.vehicles, args.drives)
        print(f"simulated {args.vehicles} x {args.drives} drives in {time.perf_counter() - t0:.0f} s", flush=True)
    drives = discover(fleet)
    if not args.skip_scaling:
        from distributed import Client, LocalCluster, get_task_stream

        sub = work / "scaling_manifest.toml"
        sub.write_text("".join(f'[[drive]]\nvehicle = "{d.vehicle}"\ndrive = "{d.drive}"\nconfig = "{d.config}"\n'
                               f'can = "{d.can}"\ngnss = {json.dumps(list(d.gnss))}\ntruth = "{d.truth}"\n\n'
                               for d in drives[:args.scaling_drives]))
        walls = {}
        for n in (1, 2):
            out = work / f"scaling_{n}"
            shutil.rmtree(out, ignore_errors=True)
            with LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=":0") as cl, \
                    Client(cl.scheduler_address) as client, get_task_stream(client) as ts:
                walls[n], _ = timed(f"LocalCluster {n} worker(s), {args.scaling_drives} drives",
                                    lambda: run_fleet(str(sub), out, scheduler=cl.scheduler_address, report=False))
            print(task_breakdown(ts.data, walls[n], n), flush=True)
        print(f"scaling 1 -> 2 workers: x{walls[1] / walls[2]:.2f}", flush=True)
    out = work / args.run
    if not args.skip_full:
        share = args.second_pass_share
        timed(f"local pool ({os.cpu_count()} processes), whole fleet, {args.passes} pass(es), share {share:g}",
              lambda: run_fleet(str(fleet), out, passes=args.passes, second_share=share), args.passes)
        t0 = time.perf_counter()
        run_fleet(str(fleet), out, report=False, passes=args.passes, second_share=share)
        print(f"rerun with every drive stored: {time.perf_counter() - t0:.1f} s", flush=True)
    rows = read_drives(out)
    hits = {k: 0 for k in TARGETS}
    worst = {k: ("", 0.0) for k in TARGETS}
    zs = {k: [] for k in (*TARGETS, *ALSO_Z)}
    radius_only = []
    vehicles = sorted({r["vehicle"] for r in rows})
    print(f"{'vehicle':8s} " + " ".join(f"{k[:34]:>36s}" for k in TARGETS))
    print("(each: combined value (truth) error, z = error / combined 1-sigma)")
    for v in vehicles:
        truth = json.loads((fleet / v / "vehicle.json").read_text())
        params, _ = vehicle_parameters([r for r in rows if r["vehicle"] == v])
        cells = []
        for k, (kind, tol) in TARGETS.items():
            # the wheel scale against what its rolling wheels show (simfleet.free_rolling_wheel_scale)
            t = true_value(truth, k)
            if k == "wheel_scale":
                radius_only.append(params[k]["value"] / truth[k] - 1.0)
            est = params[k]["value"]
            err = est - t if kind == "abs" else (est - t) / t
            hits[k] += abs(err) <= tol
            if not abs(err) <= abs(worst[k][1]):
                worst[k] = (v, err)
            z = (est - t) / params[k]["std"] if params[k]["std"] > 0 else float("nan")
            zs[k].append(z)
            cells.append(f"{est:.5g} ({t:.5g}) {err:+.4f} z{z:+.1f}".rjust(36))
        for k in ALSO_Z:
            zs[k].append((params[k]["value"] - true_value(truth, k)) / params[k]["std"])
        print(f"{v:8s} " + " ".join(cells))
    if radius_only:
        print(f"wheel_scale against the radius error alone (vehicle.json wheel_scale, no rolling slip):"
              f" {min(radius_only):+.4%} .. {max(radius_only):+.4%}")
    for k, (kind, tol) in TARGETS.items():
        print(f"{k}: {hits[k]} of {len(vehicles)} vehicles within {tol:g}{' (relative)' if kind == 'rel' else ' s'},"
              f" worst {worst[k][0]} {worst[k][1]:+.4f}; {z_summary(zs[k])}")
    for k in ALSO_Z:
        print(f"{k}: {z_summary(zs[k])}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
