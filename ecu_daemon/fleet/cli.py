"""``ecu-daemon fleet run | calibrate | simulate``.

    ecu-daemon fleet run INPUT --out DIR [--jobs N | --scheduler ADDRESS] [--passes 2 [--second-pass-share F]] [--no-report]
    ecu-daemon fleet calibrate --out DIR --vehicle V [--state FILE] > overrides.toml
    ecu-daemon fleet simulate --out DIR [--vehicles 20] [--drives 20] [--duration S] [--seed N]

``run`` writes ``DIR/drives.{parquet,csv}``, ``DIR/vehicles.{parquet,csv}``, ``DIR/report.md`` with
its PNGs, and keeps each drive's result in ``DIR/results/`` (a rerun skips the drives found there).
Exit status 1 when a drive failed (its row says why), 0 otherwise.
"""
from __future__ import annotations

import argparse
import logging
import sys
import time
from pathlib import Path

from ..errors import UserError

log = logging.getLogger("ecu_daemon.fleet")
RESULTS = "results"


def add_arguments(p: argparse.ArgumentParser) -> None:
    sub = p.add_subparsers(dest="fleet_command", metavar="ACTION", required=True)
    r = sub.add_parser("run", help="replay and score every drive; tables and report")
    r.add_argument("input", help="fleet folder tree (ROOT/<vehicle>/<drive>/) or a TOML manifest")
    r.add_argument("--out", "-o", required=True, help="output folder (results, tables, report)")
    r.add_argument("--jobs", "-j", type=int, help="local worker processes (default: all cores; 1: in this process)")
    r.add_argument("--scheduler", metavar="ADDRESS", help="run on this Dask scheduler (tcp://host:8786) instead")
    r.add_argument("--passes", type=int, default=1, choices=(1, 2),
                   help="2: replay every drive again starting from its vehicle's first-pass GNSS latency (above for"
                   " half of the drives, below for the rest); the calibration's latency and stiffness then do not"
                   " lean on the config's latency prior (twice the work)")
    r.add_argument("--second-pass-share", type=float, default=1.0, metavar="F",
                   help="with --passes 2: replay again only this share of each vehicle's drives (at least 2), the"
                   " most informative on latency and stiffness; the vehicle's latency and stiffness then come from"
                   " them alone (default 1: all)")
    r.add_argument("--no-report", action="store_true", help="tables only, no Markdown/PNG report")
    r.add_argument("--no-progress", action="store_true", help="no progress bar even on a terminal")
    c = sub.add_parser("calibrate", help="print a vehicle's config override (TOML) from a fleet run")
    c.add_argument("--out", "-o", required=True, help="the folder a 'fleet run' wrote")
    c.add_argument("--vehicle", "-V", required=True)
    c.add_argument("--state", metavar="FILE", help="also write the combination as a learned-state file"
                   " (the daemon's [daemon] state_file, replay --state): wheel scale, offsets, latency")
    s = sub.add_parser("simulate", help="write a simulated fleet with known per-vehicle parameters")
    s.add_argument("--out", "-o", required=True)
    s.add_argument("--vehicles", type=int, default=20)
    s.add_argument("--drives", type=int, default=20, help="drives per vehicle")
    s.add_argument("--duration", type=float, help="seconds per drive (default: each manoeuvre's length)")
    s.add_argument("--seed", type=int, default=1)
    s.add_argument("--jobs", "-j", type=int, help="simulation processes (default: all cores)")


def main(args: argparse.Namespace) -> int:
    return {"run": _run, "calibrate": _calibrate, "simulate": _simulate}[args.fleet_command](args)


def run_fleet(source: str, out: str | Path, jobs: int | None = None, scheduler: str | None = None,
              report: bool = True, progress: bool = False, passes: int = 1, second_share: float = 1.0) -> list[dict]:
    """The whole run; returns the drive records (with the run-dependent ``cached``/``wall_s``) of
    the last pass (``passes`` 2: see :func:`~ecu_daemon.fleet.calibrate.second_pass_starts`, with
    ``second_share``; a drive it leaves out is its stored first-pass record, no work)."""
    import dataclasses

    from .backends import run_all
    from .calibrate import second_pass_starts
    from .manifest import load_drives
    from .progress import FleetProgress
    from .tables import drive_rows, vehicle_rows, write_tables

    drives = load_drives(source)
    out = Path(out)
    (out / RESULTS).mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    replayed_s = 0.0  # drive time replayed now, over the passes
    with FleetProgress(len(drives) * passes, enabled=progress) as bar:
        records = run_all(drives, str((out / RESULTS).resolve()), jobs=jobs, scheduler=scheduler, on_done=bar.done)
        replayed_s += _replayed_s(records)
        for _ in range(passes - 1):
            first = records
            drives = [dataclasses.replace(d, start_latency_s=s) for d, s in zip(drives, second_pass_starts(drives, first, second_share))]
            records = run_all(drives, str((out / RESULTS).resolve()), jobs=jobs, scheduler=scheduler, on_done=bar.done)
            replayed_s += _replayed_s(records)
            for r, f in zip(records, first):  # the work of both passes counts
                for t in ("wall_s", "cpu_s", "replay_s"):
                    r[t] = (r.get(t) or 0.0) + (f.get(t) or 0.0)
                r["cached"] = bool(r.get("cached")) and bool(f.get("cached"))
    wall = time.perf_counter() - started
    write_tables(records, out)
    fresh = [r for r in records if not r.get("cached")]
    hours = replayed_s / 3600.0
    info = (f"{len(drives)} drive(s): {len(fresh)} replayed now ({hours:.2f} drive-hours in {wall:.0f} s wall,"
            f" {hours / (wall / 3600.0) if wall > 0 else 0:.0f} drive-h/h), {len(drives) - len(fresh)} already done,"
            f" {sum(r['status'] != 'ok' for r in records)} failed")
    log.info("%s", info)
    if report:
        from .report import write_report

        rows = drive_rows(records)
        write_report(rows, vehicle_rows(rows), out)
    return records


def _replayed_s(records: list[dict]) -> float:
    return sum(r.get("duration_s") or 0.0 for r in records if r["status"] == "ok" and not r.get("cached"))


def _run(args) -> int:
    if args.jobs is not None and args.jobs < 1:
        raise UserError(f"--jobs must be >= 1, got {args.jobs}")
    if not 0.0 < args.second_pass_share <= 1.0:
        raise UserError(f"--second-pass-share must be in (0, 1], got {args.second_pass_share}")
    records = run_fleet(args.input, args.out, jobs=args.jobs, scheduler=args.scheduler,
                        report=not args.no_report, progress=not args.no_progress, passes=args.passes,
                        second_share=args.second_pass_share)
    for r in records:
        if r["status"] != "ok":
            log.warning("drive %s/%s failed: %s", r["vehicle"], r["drive"], r["error"])
    return 1 if any(r["status"] != "ok" for r in records) else 0


def _calibrate(args) -> int:
    from .calibrate import override_toml
    from .tables import read_drives

    try:
        rows = read_drives(args.out)
    except (OSError, ValueError) as e:
        raise UserError(f"cannot read the drive table in {args.out} (run 'ecu-daemon fleet run' first): {e}") from None
    mine = [r for r in rows if r["vehicle"] == args.vehicle]
    if not mine:
        known = ", ".join(sorted({r["vehicle"] for r in rows}))
        raise UserError(f"no drives of vehicle {args.vehicle!r} in {args.out}; vehicles: {known}")
    sys.stdout.write(override_toml(args.vehicle, mine))
    if args.state:
        from ..io.state_store import save_state
        from .calibrate import learned_state

        try:
            save_state(args.state, learned_state(mine))
        except OSError as e:
            raise UserError(f"cannot write state file {args.state}: {e.strerror or e}") from None
    return 0


def _simulate(args) -> int:
    from .simfleet import write_fleet

    if args.vehicles < 1 or args.drives < 1:
        raise UserError("--vehicles and --drives must be >= 1")
    fleet = write_fleet(args.out, args.vehicles, args.drives, args.seed, args.duration, args.jobs)
    print(f"wrote {len(fleet)} vehicle(s) x {args.drives} drive(s) into {args.out}")
    return 0
