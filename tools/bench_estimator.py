#!/usr/bin/env python3
"""Benchmark the estimator core and offline replay (numbers only, no pass/fail).

What is measured, all on one simulated drive (``dlc_dry`` extended with steady driving so it lasts
``--steps`` estimator steps after an 8 s warm-up (standstill, start, heading alignment); GNSS latency 0.5 s in the simulator *and* in the
config, ``[gnss] delay_s = 0.5``, ``estimate_delay = false`` so every rewind is 0.5 s = 83 steps):

1. step cost: the simulator's frames go through the real ``SignalDecoder`` and UBX bytes through
   the real ``GnssStreamParser``; before each step the samples due at it are pushed (a deque
   append, not timed), then ``Estimator.advance_to(k * dt)`` -- exactly one 6 ms step, including
   applying the pushed samples to the held inputs -- is timed. Steps that applied a GNSS sample
   are reported apart from the plain steps.
2. GNSS fusion with a 0.5 s rewind: ``Estimator._on_gnss`` and ``StepHistory.correct`` are timed in
   place (instance-attribute wrappers; the estimator code is untouched), for fixes fused as 2-D
   velocity after heading alignment; also the extra time of the steps that fused one.
3. replay speed: ``ecu_daemon.replay.run_replay`` on the drive written with the simulator's writer
   (config with online delay estimation on, as a user would run it), CSV only and CSV + ``--out-can``,
   as a multiple of real time; breakdown from separate timings of each stage on the same files.
4. FilterPy: ``filterpy.kalman.ExtendedKalmanFilter`` with ``predict_x`` overridden by the same
   8-state kinematic model and the same F and Q as ``KinematicModel``; its ``predict()`` vs
   ``KinematicModel.predict`` and vs the whole estimator step, on the same inputs; and a bare
   FilterPy EKF step of the same problem (predict + the wheel-speed update, derived h and H),
   the yardstick for the whole replay's cost per step.
5. ``--reference``: the step and GNSS rows again with the pure-Python reference kernels
   (``backend.select(False)``), in the same run, for a before/after at the same load.
6. ``--online-latency``: the step and GNSS rows again with the replay's config (online latency
   identification on: two latency estimators per velocity receiver run at every fix, which the
   main rows leave out to keep every rewind at 0.5 s).

    python3 tools/bench_estimator.py [--steps 20000] [--quick] [--json] [--profile] [--reference] [--online-latency]

The machine is shared: the load average is printed with the results. Wall-clock percentiles include
preemption by other processes and GC pauses; the thread-CPU-time rows of the same steps do not
(they still include GC), so a wall p99 far above the CPU p99 means the box was busy, not the filter.
"""
from __future__ import annotations

import argparse
import copy
import cProfile
import gc
import heapq
import io
import json
import math
import os
import platform
import pstats
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import numpy as np
from filterpy.kalman import ExtendedKalmanFilter

from ecu_daemon import config as config_mod
from ecu_daemon.canlog import CandumpWriter, read_can_log
from ecu_daemon.estimator import Estimator, backend
from ecu_daemon.estimator import generated as gen
from ecu_daemon.estimator.kinematic import (
    BAX,
    BAY,
    BR,
    GAY,
    NX,
    PSI,
    TWO_PI,
    VX,
    VY,
    KinematicModel,
)
from ecu_daemon.gnss.logfile import read_gnss_log
from ecu_daemon.gnss.stream import GnssStreamParser
from ecu_daemon.outputs import OutputEncoder
from ecu_daemon.estimate_csv import csv_header, format_rows
from ecu_daemon.replay import run_replay
from ecu_daemon.samples import INPUT_INDEX
from ecu_daemon.signals import SignalDecoder
from ecu_daemon.sim import SCENARIOS, simulate, vehicle_config
from ecu_daemon.sim.writer import write_all

GNSS_DELAY_S = 0.5
WARMUP_S = 8.0  # dlc_dry stands still for 5 s; heading aligns ~7.4 s in
I_YAW, I_AX, I_AY = INPUT_INDEX["yaw_rate"], INPUT_INDEX["accel_x"], INPUT_INDEX["accel_y"]


def stats_us(ns) -> dict:
    """median / p90 / p99 / max / n of a list of nanosecond durations, in microseconds."""
    if len(ns) == 0:
        return {"n": 0, "median": math.nan, "p90": math.nan, "p99": math.nan, "max": math.nan}
    a = np.asarray(ns, dtype=float) / 1e3
    p50, p90, p99 = np.percentile(a, [50, 90, 99])
    return {"n": int(a.size), "median": float(p50), "p90": float(p90), "p99": float(p99),
            "max": float(a.max())}


# ------------------------------------------------------------------------------------------------
# the drive

def build_drive(scenario_name: str, steps: int):
    """Simulate the drive; return (sim, bench config, replay config, time-ordered samples)."""
    base = SCENARIOS[scenario_name]
    duration = WARMUP_S + steps * 0.006 + 1.0
    sc = base.with_(duration_s=duration, gnss=replace(base.gnss, latency_s=GNSS_DELAY_S))
    cfg_replay = vehicle_config(sc)  # delay prior 0.5 s, online estimation on (the default)
    sim = simulate(sc, cfg_replay)
    cfg = copy.deepcopy(cfg_replay)
    cfg.gnss.delay_s = GNSS_DELAY_S
    cfg.gnss.estimate_delay = False
    cfg.gnss.delay_monitor = False  # no identification at all in these rows (see --online-latency)
    config_mod._validate(cfg)  # 0.5 s must sit inside max_delay_s
    decoder = SignalDecoder(cfg)
    events = []
    for t, fid, data in sim.can_frames:
        for s in decoder.decode(t, fid, data, fid in sim.extended_ids):
            events.append((t, 0, s))
    parser = GnssStreamParser(cfg.gnss.protocol)
    for t, payload in sim.gnss_messages:
        for s in parser.feed(t, payload):
            events.append((s.t, 1, s))
    for s in parser.finish():
        events.append((s.t, 1, s))
    events.sort(key=lambda e: (e[0], e[1]))
    return sim, cfg, cfg_replay, events


# ------------------------------------------------------------------------------------------------
# 1 + 2: step cost and GNSS fusion

def bench_steps(cfg, events, steps: int, profile: bool = False) -> dict:
    est = Estimator(cfg)
    dt = est.dt
    perf = time.perf_counter_ns
    gnss_calls = []  # (ns, fused_2d)
    correct_calls = []  # (ns, rewind steps)

    on_gnss = est._on_gnss  # bound method; wrapped through an instance attribute

    def timed_on_gnss(g, k):
        aligned = est.aligned
        fused0 = est.gnss.fused
        t0 = perf()
        on_gnss(g, k)
        t1 = perf()
        gnss_calls.append((t1 - t0, aligned and est.gnss.fused > fused0))

    hist = est.hist
    correct = hist.correct

    def timed_correct(s, dx, M):
        depth = hist.last - s
        t0 = perf()
        ok = correct(s, dx, M)
        t1 = perf()
        correct_calls.append((t1 - t0, depth))
        return ok

    est._on_gnss = timed_on_gnss
    hist.correct = timed_correct

    k = math.ceil(events[0][0] / dt - 1e-9)
    warm_k = k + round(WARMUP_S / dt)
    end_k = warm_k + steps
    n_ev = len(events)
    i = 0
    plain, with_gnss, gnss_fused_steps = [], [], []
    plain_cpu, gnss_cpu = [], []  # thread CPU time of the same steps (excludes preemption)
    cpu = time.thread_time_ns
    inputs = []  # (r_m, ax_m, ay_m, wheel speed) held at each measured step, for the FilterPy comparison
    held = est.held
    prof = cProfile.Profile() if profile else None
    gc.collect()
    while k < end_k:
        tk = k * dt
        pushed_gnss = False
        while i < n_ev and events[i][0] <= tk + 1e-9:
            _, kind, s = events[i]
            if kind:
                est.push_gnss(s)
                pushed_gnss = True
            else:
                est.push_input(s)
            i += 1
        ncalls = len(gnss_calls)
        if prof is not None and k >= warm_k:
            prof.enable()
        c0 = cpu()
        t0 = perf()
        out = est.advance_to(tk)
        t1 = perf()
        c1 = cpu()
        if prof is not None:
            prof.disable()
        if len(out) != 1:
            raise RuntimeError(f"advance_to ran {len(out)} steps at k={k}")
        if k >= warm_k:
            if pushed_gnss:
                with_gnss.append(t1 - t0)
                if any(f for _, f in gnss_calls[ncalls:]):
                    gnss_fused_steps.append(t1 - t0)
                    gnss_cpu.append(c1 - c0)
            else:
                plain.append(t1 - t0)
                plain_cpu.append(c1 - c0)
            inputs.append((held[I_YAW], held[I_AX], held[I_AY], est.wheels.measured_speed(*held[:4])))
        k += 1
    # timer overhead: two back-to-back reads
    ovh = []
    for _ in range(10000):
        a = perf()
        b = perf()
        ovh.append(b - a)
    n0 = sum(1 for _ in gnss_calls)  # includes warm-up calls
    fused2d = [ns for ns, f in gnss_calls if f]
    depths = [d for _, d in correct_calls]
    res = {
        "steps_measured": len(plain) + len(with_gnss),
        "plain_step_us": stats_us(plain),
        "all_steps_us": stats_us(plain + with_gnss),
        "gnss_step_us": stats_us(gnss_fused_steps),
        "plain_step_cpu_us": stats_us(plain_cpu),
        "gnss_step_cpu_us": stats_us(gnss_cpu),
        "timer_overhead_us": float(np.median(ovh)) / 1e3,
        "gnss": {
            "samples_seen": n0,
            "fused_2d": len(fused2d),
            "fused_total": est.gnss.fused,
            "rejected": est.gnss.rejected,
            "on_gnss_fused_2d_us": stats_us(fused2d),
            "correct_us": stats_us([ns for ns, _ in correct_calls]),
            "rewind_steps_median": float(np.median(depths)) if depths else math.nan,
            "rewind_steps_min": int(min(depths)) if depths else -1,
            "rewind_steps_max": int(max(depths)) if depths else -1,
            "delay_s": est.latency.delay_s,
        },
        "late_inputs": est.late_inputs,
        "resets": est.resets,
        "final_x": est.hist.X[est.hist.slot(est.hist.last)].copy(),
        "final_P": est.hist.P[est.hist.slot(est.hist.last)].copy(),
        "inputs": inputs,
        "wheel_frac": est.wheels.frac,
        "wheel_noise2": est.wheels.noise2,
        "kernels": backend.active(),
    }
    res["gnss"]["extra_step_us"] = res["gnss_step_us"]["median"] - res["plain_step_us"]["median"]
    if prof is not None:
        buf = io.StringIO()
        pstats.Stats(prof, stream=buf).sort_stats("tottime").print_stats(18)
        res["profile"] = buf.getvalue()
    return res


# ------------------------------------------------------------------------------------------------
# 4: FilterPy

class KinematicEKF(ExtendedKalmanFilter):
    """FilterPy EKF with the estimator's kinematic model as ``predict_x`` (u = (r_m, ax_m, ay_m))."""

    def __init__(self, model: KinematicModel, x0, P0):
        super().__init__(dim_x=NX, dim_z=2)
        self.dt = model.dt
        self.F = model.F.copy()
        self.Q = model.Qd.copy()
        self.x = np.array(x0, dtype=float).reshape(NX, 1)
        self.P = np.array(P0, dtype=float)

    def predict_x(self, u=0):
        r_m, ax_m, ay_m = u
        dt = self.dt
        x = self.x
        vx = x[VX, 0]
        vy = x[VY, 0]
        r = r_m - x[BR, 0]
        x[VX, 0] = vx + dt * (ax_m - x[BAX, 0] + r * vy)
        x[VY, 0] = vy + dt * (ay_m - x[BAY, 0] - x[GAY, 0] * ay_m - r * vx)
        x[PSI, 0] = (x[PSI, 0] - dt * r) % TWO_PI
        F = self.F
        rdt = r * dt
        F[VX, VY] = rdt
        F[VX, BR] = -vy * dt
        F[VY, VX] = -rdt
        F[VY, BR] = vx * dt
        F[VY, GAY] = -ay_m * dt


def bench_filterpy(cfg, x0, P0, inputs, frac: float, wheel_r: float) -> dict:
    es = cfg.estimator
    model = KinematicModel(es.dt_s, es.accel_noise_mps2, es.yaw_rate_noise_radps,
                           es.yaw_rate_bias_walk, es.accel_bias_walk, es.wheel_scale_walk)
    ekf = KinematicEKF(model, x0, P0)
    perf = time.perf_counter_ns
    fp, ours = [], []
    x = np.array(x0, dtype=float)
    Pa = np.array(P0, dtype=float)
    Pb = np.empty_like(Pa)
    gc.collect()
    for u in inputs:
        t0 = perf()
        ekf.predict(u[:3])
        t1 = perf()
        fp.append(t1 - t0)
        t0 = perf()
        model.predict(x, Pa, Pb, u[0], u[1], u[2])
        t1 = perf()
        ours.append(t1 - t0)
        Pa, Pb = Pb, Pa
    dx = float(np.max(np.abs(ekf.x[:, 0] - x)))
    dP = float(np.max(np.abs(ekf.P - Pa)))

    # a bare FilterPy EKF of the same problem: predict, then the wheel-speed update (derived h, H)
    wh_cols = [j for _, j in gen.WHEEL_SPEED_H]
    lf = cfg.vehicle.cg_to_front_axle_m

    def hx(xc, r):
        return np.array([[gen.wheel_speed(*xc[:, 0], r, lf, frac, 0.0)[0]]])

    def h_jac(xc, r):
        H = np.zeros((1, NX))
        H[0, wh_cols] = gen.wheel_speed_H(*xc[:, 0], r, lf, frac, 0.0)
        return H

    ekf = KinematicEKF(model, x0, P0)
    full = []
    Rw = np.array([[wheel_r]])
    gc.collect()
    for u in inputs:
        t0 = perf()
        ekf.predict(u[:3])
        if math.isfinite(u[3]):
            r = u[0] - ekf.x[BR, 0]
            ekf.update(np.array([[u[3]]]), h_jac, hx, R=Rw, args=(r,), hx_args=(r,))
        t1 = perf()
        full.append(t1 - t0)
    return {"filterpy_predict_us": stats_us(fp), "kinematic_predict_us": stats_us(ours),
            "filterpy_step_us": stats_us(full), "max_abs_diff_x": dx, "max_abs_diff_P": dP}


# ------------------------------------------------------------------------------------------------
# 3: replay

def bench_replay(sim, cfg_replay, tmp: Path) -> dict:
    paths = write_all(tmp, sim, cfg_replay)
    cfg = config_mod.load(paths["config"])
    can_path, gnss_path = str(paths["can"]), str(paths["gnss"])
    out = {"drive_s": sim.t_end - sim.t0}
    for label, out_can in (("csv", None), ("csv+out_can", str(tmp / "out.log"))):
        gc.collect()
        t0 = time.perf_counter()
        c0 = time.process_time()
        s = run_replay(cfg, can_path, gnss_path, out_csv=str(tmp / "out.csv"), out_can=out_can)
        cpu = time.process_time() - c0
        wall = time.perf_counter() - t0
        out[label] = {"wall_s": wall, "realtime_factor": s["duration_s"] / wall, "steps": s["steps"],
                      "frames": s["frames"], "gnss_samples": s["gnss_samples"],
                      "cpu_s": cpu, "realtime_factor_cpu": s["duration_s"] / cpu if cpu > 0 else math.inf}

    # breakdown: each stage alone, the same work run_replay does
    parts = {}
    gc.collect()
    t0 = time.perf_counter()
    decoder = SignalDecoder(cfg)
    can_ev = []
    for t, fid, ext, err, data in read_can_log(can_path):
        if not err:
            for smp in decoder.decode(t, fid, data, ext):
                can_ev.append((t, 0, smp))
    parts["can_parse_decode"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    gnss_ev = []
    parsers = {}
    for t, port, payload in read_gnss_log(gnss_path):
        p = parsers.get(port)
        if p is None:
            p = parsers[port] = GnssStreamParser(cfg.gnss.protocol)
        gnss_ev.extend((smp.t, 1, smp) for smp in p.feed(t, payload))
    for p in parsers.values():
        gnss_ev.extend((smp.t, 1, smp) for smp in p.finish())
    parts["gnss_parse"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    est = Estimator(cfg)
    estimates = []
    t_last = None
    for t, kind, smp in heapq.merge(can_ev, gnss_ev, key=lambda e: (e[0], e[1])):
        if kind:
            est.push_gnss(smp)
        else:
            est.push_input(smp)
        if t_last is None or t > t_last:
            t_last = t
            estimates.extend(est.advance_to(t - 2e-9))
    estimates.extend(est.advance_to(t_last))
    parts["estimator"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    with open(tmp / "bd.csv", "w", encoding="ascii", newline="\n") as f:
        f.write(csv_header())
        w = f.write
        for e in estimates:
            w(format_rows([e]))  # as the replay writes them (a step or two per call)
    parts["csv_write"] = time.perf_counter() - t0

    enc = OutputEncoder(cfg)  # set-up (loading the DBC) is start-up, not per-step cost
    t0 = time.perf_counter()
    wr = CandumpWriter(tmp / "bd.log")
    dt = cfg.estimator.dt_s
    for e in estimates:
        for msg in enc.frames(round(e.t / dt), e, None):
            wr.write(msg)
    wr.close()
    parts["out_can_encode_write"] = time.perf_counter() - t0
    out["breakdown_s"] = parts
    out["breakdown_steps"] = len(estimates)
    return out


# ------------------------------------------------------------------------------------------------

def machine() -> dict:
    with open("/proc/uptime") as f:
        up = float(f.read().split()[0])
    return {"cpus": os.cpu_count(), "loadavg": list(os.getloadavg()), "uptime_s": up,
            "python": platform.python_version(), "numpy": np.__version__}


def print_table(r: dict) -> None:
    m = r["machine"]
    print(f"machine: {m['cpus']} CPUs, load average {m['loadavg'][0]:.2f} {m['loadavg'][1]:.2f} "
          f"{m['loadavg'][2]:.2f} (start) / {r['machine_end']['loadavg'][0]:.2f} (end), "
          f"Python {m['python']}, numpy {m['numpy']}")
    s = r["steps"]
    print(f"drive: {r['scenario']} {r['drive_s']:.0f} s, {s['steps_measured']} steps measured after "
          f"{WARMUP_S:.0f} s warm-up; timer overhead {s['timer_overhead_us']:.2f} us (not subtracted)")
    print()
    hdr = f"{'':44s} {'median':>8s} {'p90':>8s} {'p99':>8s} {'max':>8s} {'n':>7s}"
    print(hdr)

    def row(name, st):
        print(f"{name:44s} {st['median']:8.1f} {st['p90']:8.1f} {st['p99']:8.1f} {st['max']:8.1f} {st['n']:7d}")

    row("estimator step, no GNSS [us]", s["plain_step_us"])
    row("estimator step, all steps [us]", s["all_steps_us"])
    row("estimator step fusing GNSS (0.5 s) [us]", s["gnss_step_us"])
    row("  same steps, thread CPU time, no GNSS [us]", s["plain_step_cpu_us"])
    row("  same steps, thread CPU time, GNSS [us]", s["gnss_step_cpu_us"])
    g = s["gnss"]
    row("  Estimator._on_gnss, 2-D fused [us]", g["on_gnss_fused_2d_us"])
    row("  StepHistory.correct [us]", g["correct_us"])
    f = r["filterpy"]
    row("KinematicModel.predict [us]", f["kinematic_predict_us"])
    row("FilterPy EKF predict (same F, Q) [us]", f["filterpy_predict_us"])
    row("FilterPy EKF step: predict + wheel update [us]", f["filterpy_step_us"])
    if "online_latency" in r:
        ol = r["online_latency"]
        print("with online latency identification on (the config replay and the daemon run by default), same drive:")
        row("  estimator step, no GNSS [us]", ol["plain_step_us"])
        row("  estimator step fusing GNSS (0.5 s) [us]", ol["gnss_step_us"])
        row("  same steps, thread CPU time, GNSS [us]", ol["gnss_step_cpu_us"])
        row("  Estimator._on_gnss, 2-D fused [us]", ol["gnss"]["on_gnss_fused_2d_us"])
    if "reference" in r:
        ref = r["reference"]
        print(f"with the pure-Python reference kernels (same run), vs compiled ({s['kernels']}):")
        row("  estimator step, no GNSS [us]", ref["plain_step_us"])
        row("  estimator step, all steps [us]", ref["all_steps_us"])
        row("  estimator step fusing GNSS (0.5 s) [us]", ref["gnss_step_us"])
        row("  Estimator._on_gnss, 2-D fused [us]", ref["gnss"]["on_gnss_fused_2d_us"])
        row("  StepHistory.correct [us]", ref["gnss"]["correct_us"])
    print()
    print(f"GNSS: {g['fused_2d']} fixes fused 2-D ({g['fused_total']} fused, {g['rejected']} rejected), "
          f"rewind {g['rewind_steps_median']:.0f} steps (min {g['rewind_steps_min']}, max "
          f"{g['rewind_steps_max']}) at delay {g['delay_s']:.3f} s; extra time of a fusing step "
          f"{g['extra_step_us']:.0f} us (median difference)")
    print(f"medians side by side: estimator step {s['plain_step_us']['median']:.1f} us | "
          f"KinematicModel.predict {f['kinematic_predict_us']['median']:.1f} us | "
          f"FilterPy EKF.predict {f['filterpy_predict_us']['median']:.1f} us "
          f"(same result: max |dx| {f['max_abs_diff_x']:.1e}, |dP| {f['max_abs_diff_P']:.1e}); "
          f"6 ms budget = 6000 us")
    rp = r["replay"]
    print()
    print(f"replay of {rp['drive_s']:.0f} s drive ({rp['csv']['frames']} frames, "
          f"{rp['csv']['gnss_samples']} GNSS samples, {rp['csv']['steps']} steps):")
    for label in ("csv", "csv+out_can"):
        x = rp[label]
        print(f"  run_replay --out-csv{' --out-can' if 'out_can' in label else '':11s} "
              f"{x['wall_s']:6.2f} s wall  x{x['realtime_factor']:.1f} real time"
              f"  ({x['cpu_s']:.2f} s process CPU: x{x['realtime_factor_cpu']:.1f})")
    bd = rp["breakdown_s"]
    tot = sum(bd.values())
    print(f"  breakdown (each stage timed alone, sum {tot:.2f} s):")
    for name, v in bd.items():
        print(f"    {name:24s} {v:6.2f} s {100 * v / tot:5.1f} %  "
              f"{1e6 * v / max(rp['breakdown_steps'], 1):6.1f} us/step")
    x = rp["csv+out_can"]
    per_step = 1e6 * x["wall_s"] / max(x["steps"], 1)
    fp_step = f["filterpy_step_us"]["median"]
    print(f"  whole replay (--out-csv --out-can) {per_step:.1f} us per step = {per_step / fp_step:.1f} x a bare "
          f"FilterPy EKF step ({fp_step:.1f} us, median, this run)")
    cpu_step = 1e6 * x["cpu_s"] / max(x["steps"], 1)
    print(f"  same, process CPU time {cpu_step:.1f} us per step = {cpu_step / fp_step:.1f} x (the wall figure"
          f" includes time the busy machine gave to other processes)")
    if "profile" in s:
        print()
        print("cProfile of the measured steps (tottime):")
        print(s["profile"])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=20000, help="measured estimator steps (default 20000)")
    ap.add_argument("--scenario", default="dlc_dry", help="simulator scenario (default dlc_dry)")
    ap.add_argument("--quick", action="store_true", help="short run (2000 steps, < 20 s)")
    ap.add_argument("--json", action="store_true", help="print JSON instead of the table")
    ap.add_argument("--profile", action="store_true", help="also cProfile the measured steps")
    ap.add_argument("--reference", action="store_true",
                    help="also time the steps with the pure-Python reference kernels")
    ap.add_argument("--online-latency", action="store_true",
                    help="also time the steps with online GNSS latency identification on (as replay runs;"
                         " the main rows fix the latency so that every rewind is 0.5 s)")
    args = ap.parse_args()
    steps = 2000 if args.quick else args.steps
    if steps < 100:
        ap.error("--steps must be at least 100")

    r = {"machine": machine(), "scenario": args.scenario, "quick": args.quick}
    t_start = time.perf_counter()
    sim, cfg, cfg_replay, events = build_drive(args.scenario, steps)
    r["drive_s"] = sim.t_end - sim.t0
    r["sim_wall_s"] = time.perf_counter() - t_start
    st = bench_steps(cfg, events, steps)
    if args.profile:
        r["profile"] = bench_steps(cfg, events, steps, profile=True)["profile"]
    if args.online_latency:
        ol = bench_steps(cfg_replay, events, steps)
        r["online_latency"] = {k: ol[k] for k in ("plain_step_us", "gnss_step_us", "gnss_step_cpu_us", "gnss")}
    if args.reference:
        backend.select(False)
        ref = bench_steps(cfg, events, steps)
        backend.select(True)
        r["reference"] = {k: ref[k] for k in ("plain_step_us", "all_steps_us", "gnss_step_us", "gnss")}
    r["filterpy"] = bench_filterpy(cfg, st.pop("final_x"), st.pop("final_P"), st.pop("inputs"),
                                   st.pop("wheel_frac"), st.pop("wheel_noise2"))
    r["steps"] = st
    if args.profile:
        st["profile"] = r.pop("profile")
    with tempfile.TemporaryDirectory(prefix="bench_estimator_") as tmp:
        r["replay"] = bench_replay(sim, cfg_replay, Path(tmp))
    r["machine_end"] = machine()
    r["total_wall_s"] = time.perf_counter() - t_start
    if args.json:
        json.dump(r, sys.stdout, indent=2)
        print()
    else:
        print_table(r)
        print(f"\n(total {r['total_wall_s']:.1f} s, of which simulation {r['sim_wall_s']:.1f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
