#!/usr/bin/env python3
"""Benchmark offline replay against a bare FilterPy EKF (numbers only, no pass/fail).

On one simulated drive (``demo`` extended to ``--duration`` s, 100 by default: the targets of
issues 10 and 12 are for a 100 s drive), for this checkout and, with ``--baseline DIR``, another
one (a checkout of main with its extensions built in place: ``python setup.py build_ext --inplace``)
run back to back in the same invocation, each in its own process:

* ``run_replay`` with ``--out-csv --out-can`` (and CSV only) as a multiple of real time, wall and
  process CPU time, per 6 ms step; process start-up and imports are not counted (the drive is
  replayed once untimed first), the best of ``--repeat`` runs is reported;
* the estimator alone on the same drive's pre-decoded samples, handed over as the replay does
  (``Estimator.advance_to`` per item's step): the part of the replay that is not I/O, decoding or
  encoding; the rest of the per-step cost is the difference;
* a bare FilterPy ``ExtendedKalmanFilter`` step (predict with the same 8-state kinematic model, F
  and Q as ``KinematicModel``, plus the wheel-speed update with the derived h and H) on the drive's
  own inputs: the yardstick of issue 10 (the whole replay's cost per step no more than this);
* fleet throughput (issue 12) from the replay's cost: drive-hours per hour on one core and on
  ``os.cpu_count()`` cores, assuming no other load;
* the rest alone: the replay again with the estimator's ``advance_to`` played back from a
  recorded run (same calls, same estimates), so its CPU time is everything but the estimator;
  with ``--stages``, one replay's time split by stage (each stage's function wrapped and timed).

    python3 tools/bench_replay.py [--duration 100] [--repeat 3] [--baseline /tmp/main_src] [--stages] [--json]

The machine is shared: the load average is printed with the results, and CPU time is printed next
to wall time (a wall figure far above the CPU one means other processes had the CPU).
"""
from __future__ import annotations

import argparse
import gc
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


# ------------------------------------------------------------------------------------------------
# the worker: runs in a fresh process with the checkout under test first on sys.path

def _filterpy_step_us(cfg, samples, steps: int) -> float:
    """Median wall time of one bare FilterPy EKF step (predict + wheel-speed update), on the
    inputs held at each of the drive's first ``steps`` steps."""
    import numpy as np
    from filterpy.kalman import ExtendedKalmanFilter

    from ecu_daemon.estimator import generated as gen
    from ecu_daemon.estimator.kinematic import BAX, BAY, BR, GAY, NX, PSI, TWO_PI, VX, VY, KinematicModel

    es = cfg.estimator
    model = KinematicModel(es.dt_s, es.accel_noise_mps2, es.yaw_rate_noise_radps, es.yaw_rate_bias_walk,
                           es.accel_bias_walk, es.wheel_scale_walk)
    dt = es.dt_s

    class KinematicEKF(ExtendedKalmanFilter):  # as tools/bench_estimator.py
        def predict_x(self, u=0):
            r_m, ax_m, ay_m = u
            x = self.x
            vx, vy = x[VX, 0], x[VY, 0]
            r = r_m - x[BR, 0]
            x[VX, 0] = vx + dt * (ax_m - x[BAX, 0] + r * vy)
            x[VY, 0] = vy + dt * (ay_m - x[BAY, 0] - x[GAY, 0] * ay_m - r * vx)
            x[PSI, 0] = (x[PSI, 0] - dt * r) % TWO_PI
            F = self.F
            F[VX, VY] = r * dt
            F[VX, BR] = -vy * dt
            F[VY, VX] = -r * dt
            F[VY, BR] = vx * dt
            F[VY, GAY] = -ay_m * dt

    ekf = KinematicEKF(dim_x=NX, dim_z=1)
    ekf.F = model.F.copy()
    ekf.Q = model.Qd.copy()
    ekf.x = np.zeros((NX, 1))
    ekf.x[VX, 0] = 10.0
    ekf.x[6, 0] = 1.0  # wheel scale
    ekf.P = np.diag([0.1, 0.1, 1.0, 1e-4, 0.01, 0.01, 1e-3, 1e-3])
    wh_cols = [j for _, j in gen.WHEEL_SPEED_H]
    lf = cfg.vehicle.cg_to_front_axle_m

    def hx(xc, r):
        return np.array([[gen.wheel_speed(*xc[:, 0], r, lf, 0.5, 0.0)[0]]])

    def h_jac(xc, r):
        H = np.zeros((1, NX))
        H[0, wh_cols] = gen.wheel_speed_H(*xc[:, 0], r, lf, 0.5, 0.0)
        return H

    from ecu_daemon.samples import INPUT_INDEX

    iy, iax, iay, irl = (INPUT_INDEX[n] for n in ("yaw_rate", "accel_x", "accel_y", "wheel_speed_rl"))
    held = [0.0] * len(INPUT_INDEX)
    inputs = []
    k = None
    for s in samples:
        kk = math.ceil(s.t / dt - 1e-6)
        if k is None:
            k = kk
        while k < kk and len(inputs) < steps:
            inputs.append((held[iy], held[iax], held[iay], held[irl]))
            k += 1
        held[s.index] = s.value
    Rw = np.array([[cfg.estimator.wheel_speed_noise_mps ** 2]])
    perf = time.perf_counter_ns
    out = []
    gc.collect()
    for u in inputs:
        t0 = perf()
        ekf.predict(u[:3])
        r = u[0] - ekf.x[BR, 0]
        ekf.update(np.array([[u[3]]]), h_jac, hx, R=Rw, args=(r,), hx_args=(r,))
        out.append(perf() - t0)
    return float(np.median(out)) / 1e3


#: stages of the replay timed one by one (``--stages``): (module, object, attribute, label); one
#: missing in a tree (an older checkout) is left out of its split
_STAGES = (
    ("ecu_daemon.pipeline", "Pipeline", "__init__", "start-up: Pipeline() (DBCs, plans, estimator)"),
    ("ecu_daemon.replay", None, "read_can_arrays", "read the CAN log into arrays"),
    ("ecu_daemon.batch_decoder", "BatchDecoder", "prepare", "decode every frame (numpy, samples)"),
    ("ecu_daemon.batch_decoder", "BatchDecoder", "take", "decode dirty frames one by one"),
    ("ecu_daemon.gnss.stream", "GnssStreamParser", "feed", "GNSS parse"),
    ("ecu_daemon.gnss.stream", "GnssStreamParser", "finish", "GNSS parse"),
    ("ecu_daemon.pipeline", "Pipeline", "_update_diagnostics", "EST_DIAG diagnostics + staleness"),
    ("ecu_daemon.outputs", "OutputEncoder", "payloads", "encode output frames"),
    ("ecu_daemon.replay", None, "format_rows", "CSV rows"),
    ("ecu_daemon.canlog", "CandumpWriter", "write_payloads", "candump lines"),
    ("ecu_daemon.canlog", "CandumpWriter", "write_steps", "candump lines"),
)


def _build_estimator_with(**methods) -> None:
    """Make the pipeline build an ``Estimator`` subclass with ``methods`` replaced (none: the real
    class again). Compiled, ``Estimator`` is an extension type (estimator/core.pxd) whose methods
    cannot be set on the class itself."""
    from ecu_daemon import pipeline
    from ecu_daemon.estimator import core

    pipeline.Estimator = type("Estimator", (core.Estimator,), methods) if methods else core.Estimator


def _play_back_estimator(run) -> tuple[float, int]:
    """CPU seconds of ``run()`` with ``Estimator.advance_to`` played back from a first, recorded
    run (the same calls return the same estimates): the replay's cost without the estimator,
    measured directly rather than as a difference of two noisy totals."""
    from ecu_daemon.estimator import core

    real = core.Estimator.advance_to
    record: list = []

    def recording(self, t):
        out = real(self, t)
        record.append((self.k, out))
        return out

    def playback(self, t):
        k, out = next(it)
        self.queue.clear()
        self.k = k
        return out

    try:
        _build_estimator_with(advance_to=recording)
        steps = run()["steps"]
        _build_estimator_with(advance_to=playback)
        it = iter(record)
        gc.collect()
        c0 = time.process_time()
        run()
        return time.process_time() - c0, steps
    finally:
        _build_estimator_with()


def _stage_split(run) -> dict:
    """CPU seconds per stage of one ``run()`` (each stage's function wrapped; the estimator's
    ``advance_to`` too): the wrappers cost ~0.3 us a call, so the split is a guide, the totals
    above are the numbers."""
    import functools
    import importlib

    acc: dict[str, float] = {}
    undo = []
    pc = time.process_time

    def wrap(owner, attr, label):
        f = owner.__dict__[attr] if isinstance(owner, type) else getattr(owner, attr)

        @functools.wraps(f)
        def timed(*a, **k):
            t0 = pc()
            try:
                return f(*a, **k)
            finally:
                acc[label] = acc.get(label, 0.0) + pc() - t0

        setattr(owner, attr, timed)
        undo.append((owner, attr, f))

    from ecu_daemon.estimator import core

    real = core.Estimator.advance_to

    def advance_to(self, t):
        t0 = pc()
        try:
            return real(self, t)
        finally:
            acc["estimator (advance_to)"] = acc.get("estimator (advance_to)", 0.0) + pc() - t0

    _build_estimator_with(advance_to=advance_to)
    undo.append((None, None, None))
    for mod, cls, attr, label in _STAGES:
        owner = importlib.import_module(mod)
        owner = getattr(owner, cls, None) if cls else owner
        if owner is not None and (attr in owner.__dict__ if isinstance(owner, type) else hasattr(owner, attr)):
            wrap(owner, attr, label)
    try:
        gc.collect()
        c0 = pc()
        r = run()
        total = pc() - c0
    finally:
        for owner, attr, f in reversed(undo):
            if owner is None:
                _build_estimator_with()
            else:
                setattr(owner, attr, f)
    acc["everything else (step loop, publish, emit, ...)"] = total - sum(acc.values())
    return {"steps": r["steps"], "total_s": total, "stages_s": acc}


def worker(tree: str, drive: str, repeat: int, stages: bool = False) -> dict:
    sys.path.insert(0, tree)
    import ecu_daemon
    from ecu_daemon import config as config_mod
    from ecu_daemon.canlog import read_can_log
    from ecu_daemon.estimator import Estimator
    from ecu_daemon.gnss.logfile import read_gnss_log
    from ecu_daemon.gnss.stream import GnssStreamParser
    from ecu_daemon.replay import run_replay
    from ecu_daemon.signals import SignalDecoder
    import logging

    logging.disable(logging.WARNING)
    d = Path(drive)
    cfg = config_mod.load(str(d / "config.toml"))
    can_path, gnss_path = str(d / "drive.log"), str(d / "drive_gnss.log")
    r = {"tree": tree, "package": str(Path(ecu_daemon.__file__).parent)}
    with tempfile.TemporaryDirectory(prefix="bench_replay_") as tmp:
        out_csv, out_can = str(Path(tmp) / "out.csv"), str(Path(tmp) / "out.log")
        run_replay(cfg, can_path, gnss_path, out_csv=out_csv, out_can=out_can)  # warm-up: imports, caches
        for label, oc in (("csv+can", out_can), ("csv", None)):
            best = None
            for _ in range(repeat):
                gc.collect()
                c0, t0 = time.process_time(), time.perf_counter()
                s = run_replay(cfg, can_path, gnss_path, out_csv=out_csv, out_can=oc)
                wall, cpu = time.perf_counter() - t0, time.process_time() - c0
                if best is None or wall < best["wall_s"]:
                    best = {"wall_s": wall, "cpu_s": cpu, "steps": s["steps"], "drive_s": s["duration_s"]}
            r[label] = best
        full = lambda: run_replay(cfg, can_path, gnss_path, out_csv=out_csv, out_can=out_can)  # noqa: E731
        rest = [_play_back_estimator(full) for _ in range(repeat)]
        r["rest_played_back"] = {"cpu_s": min(c for c, _ in rest), "steps": rest[0][1]}
        if stages:
            r["stages"] = _stage_split(full)
    # the estimator alone, on pre-decoded samples, handed over item by item as the replay does
    dec = SignalDecoder(cfg)
    events = []
    for t, fid, ext, err, data in read_can_log(can_path):
        if not err:
            events.extend((t, 0, s) for s in dec.decode(t, fid, data, ext))
    parser = GnssStreamParser(cfg.gnss.protocol)
    for t, _, payload in read_gnss_log(gnss_path):
        events.extend((t, 1, s) for s in parser.feed(t, payload))
    events.extend((s.t, 1, s) for s in parser.finish())
    events.sort(key=lambda e: (e[0], e[1]))
    best = None
    for _ in range(repeat):
        est = Estimator(cfg)
        dt = est.dt
        n = 0
        gc.collect()
        c0, t0 = time.process_time(), time.perf_counter()
        for t, kind, s in events:
            (est.push_gnss if kind else est.push_input)(s)
            kb = math.ceil(t / dt - 1e-6) - 1
            if est.k is None or kb >= est.k:
                n += len(est.advance_to(kb * dt))
        n += len(est.advance_to(events[-1][0]))
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        if best is None or wall < best["wall_s"]:
            best = {"wall_s": wall, "cpu_s": cpu, "steps": n}
    r["estimator"] = best
    r["filterpy_step_us"] = _filterpy_step_us(cfg, [s for _, k, s in events if not k], 5000)
    return r


# ------------------------------------------------------------------------------------------------

def _run_worker(tree: str, drive: Path, repeat: int, stages: bool) -> dict:
    out = subprocess.run([sys.executable, __file__, "--worker", tree, "--drive", str(drive), "--repeat", str(repeat)]
                         + (["--stages"] if stages else []), capture_output=True, text=True)
    if out.returncode != 0:
        sys.exit(f"worker for {tree} failed:\n{out.stderr}")
    return json.loads(out.stdout)


def _summary(r: dict) -> dict:
    full = r["csv+can"]
    steps = full["steps"]
    fp = r["filterpy_step_us"]
    est = r["estimator"]
    per = {k: 1e6 * full[k] / steps for k in ("wall_s", "cpu_s")}
    est_per = {k: 1e6 * est[k] / est["steps"] for k in ("wall_s", "cpu_s")}
    return {"x_real_time_wall": full["drive_s"] / full["wall_s"], "x_real_time_cpu": full["drive_s"] / full["cpu_s"],
            "x_real_time_csv_only": r["csv"]["drive_s"] / r["csv"]["wall_s"],
            "us_per_step_wall": per["wall_s"], "us_per_step_cpu": per["cpu_s"],
            "estimator_us_per_step_wall": est_per["wall_s"], "estimator_us_per_step_cpu": est_per["cpu_s"],
            "rest_us_per_step_wall": per["wall_s"] - est_per["wall_s"],
            "rest_us_per_step_cpu": per["cpu_s"] - est_per["cpu_s"],
            "rest_played_back_us_per_step_cpu": 1e6 * r["rest_played_back"]["cpu_s"] / r["rest_played_back"]["steps"],
            "filterpy_step_us": fp, "replay_over_filterpy": per["wall_s"] / fp,
            "drive_hours_per_hour_1_core": full["drive_s"] / full["cpu_s"],
            "drive_hours_per_hour_all_cores": (os.cpu_count() or 1) * full["drive_s"] / full["cpu_s"]}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=100.0, help="drive length in s (default 100)")
    ap.add_argument("--scenario", default="demo", help="simulator scenario (default demo)")
    ap.add_argument("--repeat", type=int, default=3, help="timed runs per measurement, best reported (default 3)")
    ap.add_argument("--baseline", metavar="DIR", help="another checkout to measure back to back (e.g. main)")
    ap.add_argument("--json", action="store_true", help="print JSON instead of the table")
    ap.add_argument("--stages", action="store_true", help="also time each stage of one replay (CPU, per step)")
    ap.add_argument("--worker", metavar="TREE", help=argparse.SUPPRESS)
    ap.add_argument("--drive", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        json.dump(worker(args.worker, args.drive, args.repeat, args.stages), sys.stdout)
        return 0
    load0 = os.getloadavg()
    with tempfile.TemporaryDirectory(prefix="bench_replay_drive_") as tmp:
        sys.path.insert(0, str(ROOT))
        from ecu_daemon.sim import SCENARIOS, simulate, vehicle_config
        from ecu_daemon.sim.writer import write_all

        sc = SCENARIOS[args.scenario].with_(duration_s=args.duration)
        write_all(tmp, simulate(sc, vehicle_config(sc)))
        trees = [("this checkout", str(ROOT))] + ([("baseline", args.baseline)] if args.baseline else [])
        results = {name: _run_worker(tree, Path(tmp), args.repeat, args.stages) for name, tree in trees}
    load1 = os.getloadavg()
    summary = {name: _summary(r) for name, r in results.items()}
    if args.json:
        json.dump({"loadavg_start": load0, "loadavg_end": load1, "results": results, "summary": summary},
                  sys.stdout, indent=2)
        print()
        return 0
    print(f"drive: {args.scenario} {args.duration:.0f} s; {os.cpu_count()} CPUs, load average "
          f"{load0[0]:.2f} {load0[1]:.2f} {load0[2]:.2f} (start) / {load1[0]:.2f} (end); best of {args.repeat}")
    names = list(summary)
    rows = [("replay --out-csv --out-can, x real time (wall)", "x_real_time_wall", ".1f"),
            ("  same, x real time (process CPU)", "x_real_time_cpu", ".1f"),
            ("replay --out-csv only, x real time (wall)", "x_real_time_csv_only", ".1f"),
            ("whole replay per 6 ms step, us (wall)", "us_per_step_wall", ".1f"),
            ("  same, process CPU", "us_per_step_cpu", ".1f"),
            ("  estimator alone per step, us (wall)", "estimator_us_per_step_wall", ".1f"),
            ("  estimator alone per step, us (CPU)", "estimator_us_per_step_cpu", ".1f"),
            ("  the rest (read, decode, encode, write), us (wall)", "rest_us_per_step_wall", ".1f"),
            ("  the rest, us (CPU)", "rest_us_per_step_cpu", ".1f"),
            ("  the rest measured alone (estimator played back), us (CPU)", "rest_played_back_us_per_step_cpu", ".1f"),
            ("bare FilterPy EKF step (predict + wheel update), us", "filterpy_step_us", ".1f"),
            ("whole replay step / FilterPy step", "replay_over_filterpy", ".2f"),
            ("drive-hours per hour, 1 core (CPU time)", "drive_hours_per_hour_1_core", ".0f"),
            (f"drive-hours per hour, {os.cpu_count()} cores (CPU time)", "drive_hours_per_hour_all_cores", ".0f")]
    print(f"{'':55s}" + "".join(f"{n:>16s}" for n in names))
    for label, key, fmt in rows:
        print(f"{label:55s}" + "".join(f"{format(summary[n][key], fmt):>16s}" for n in names))
    if args.stages:
        print("\nstage split of one replay --out-csv --out-can, CPU us per step (wrapped calls: a guide)")
        labels = list(dict.fromkeys(k for n in names for k in results[n]["stages"]["stages_s"]))
        for label in labels:
            print(f"  {label:53s}" + "".join(
                f"{1e6 * results[n]['stages']['stages_s'].get(label, math.nan) / results[n]['stages']['steps']:16.2f}"
                for n in names))
    return 0


if __name__ == "__main__":
    sys.exit(main())
