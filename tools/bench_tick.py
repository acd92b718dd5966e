#!/usr/bin/env python3
"""Benchmark: tick timing and CPU use of the live daemon under realistic bus load.

The real daemon code path (``ecu_daemon.daemon.Daemon``) runs on a python-can ``virtual`` bus and
a pseudo-terminal GNSS port. A feeder thread plays the simulated ``demo`` drive (3 chassis
messages at 100 Hz, UBX NAV-PVT at 5 Hz) plus filler frames of ids the daemon does not consume,
for a total of ``--rate`` frames/s, in real time. The daemon sends its own outputs (~900 frames/s).

Printed: tick lateness p50/p99/max (whole run, 10 us histogram bins), overruns and skipped
deadlines, samples that missed their step, and CPU time per thread (``/proc/self/task``): the
daemon's own (every thread but the feeder's, which stands in for the kernel and would not exist
on a vehicle), split into the tick thread, the event loop and the rest, and the feeder's.

    python3 tools/bench_tick.py [--seconds 20] [--rate 2000] [--realtime-priority 10]
"""
from __future__ import annotations

import argparse
import asyncio
import os
import sys
import threading
import time
from dataclasses import replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from ecu_daemon.daemon import Daemon  # noqa: E402
from ecu_daemon.demo import Feeder, open_gnss_pty  # noqa: E402
from ecu_daemon.io.health import thread_cpu_s  # noqa: E402
from ecu_daemon.io.logging_setup import setup_logging  # noqa: E402
from ecu_daemon.sim import SCENARIOS, simulate, vehicle_config  # noqa: E402


def with_filler(sim, total_rate: float):
    """The drive plus frames of unconsumed ids, evenly spread, up to ``total_rate`` frames/s."""
    dur = sim.t_end - sim.t0
    extra = max(0.0, total_rate - len(sim.can_frames) / dur)
    n = int(extra * dur)
    ids = (0x120, 0x1A0, 0x2C4, 0x3E9, 0x410, 0x5F0)
    filler = [(sim.t0 + (i + 0.5) * dur / n, ids[i % len(ids)], bytes([i & 0xFF] * 8)) for i in range(n)]
    frames = sorted(sim.can_frames + filler, key=lambda f: f[0])
    return replace(sim, can_frames=frames)


def threads_cpu_s() -> dict[int, float]:
    """CPU seconds of every thread of this process now, by native thread id."""
    out = {}
    for name in os.listdir("/proc/self/task"):
        out[int(name)] = thread_cpu_s(int(name))
    return out


def cpu_used(before: dict[int, float], after: dict[int, float]) -> dict[int, float]:
    """CPU seconds per thread between two snapshots (threads that ended in between are lost:
    the daemon's threads all live through the measurement)."""
    return {tid: c - before.get(tid, 0.0) for tid, c in after.items() if c == c}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=20.0, help="length of the run (default 20)")
    ap.add_argument("--rate", type=float, default=2000.0, help="received frames per second (default 2000)")
    ap.add_argument("--realtime-priority", type=int, default=0, help="SCHED_FIFO priority of the tick thread")
    args = ap.parse_args()

    scenario = SCENARIOS["demo"].with_(duration_s=args.seconds + 3.0)
    cfg = vehicle_config(scenario)
    sim = with_filler(simulate(scenario, cfg), args.rate)
    master, port = open_gnss_pty()
    channel = f"bench-{os.getpid()}"
    cfg.can.interface, cfg.can.channel = "virtual", channel
    cfg.gnss.port = port
    cfg.daemon.state_file = ""
    cfg.daemon.realtime_priority = args.realtime_priority
    setup_logging("warning")
    daemon = Daemon(cfg, bus_config={"interface": "virtual", "channel": channel})
    feeder = Feeder(sim, channel, master)
    result = {}

    async def run():
        task = asyncio.create_task(daemon.run())
        while not daemon.ready.is_set():
            await asyncio.sleep(0.01)
        await asyncio.sleep(0.5)  # warm-up: imports, first allocations
        daemon.tick_stats.__init__()  # measure the steady state only
        feeder.start()
        await asyncio.sleep(0.2)
        tick_id, feed_id = daemon.tick.native_id, feeder.native_id
        w0, c0 = time.monotonic(), time.process_time()
        threads0 = threads_cpu_s()
        rx0, tx0 = daemon.canio.rx_frames + daemon.canio.rx_ignored, daemon.frames_sent
        late0 = daemon.late_samples
        spun0, ticks0 = daemon.tick.spun_s, daemon.tick_stats.ticks
        await asyncio.sleep(args.seconds)
        used = cpu_used(threads0, threads_cpu_s())
        w = time.monotonic() - w0
        pct = {tid: c / w * 100 for tid, c in used.items()}
        feeder_cpu = pct.pop(feed_id, 0.0)
        result.update(
            wall=w, cpu=(time.process_time() - c0) / w * 100, daemon_cpu=sum(pct.values()),
            tick_cpu=pct.get(tick_id, 0.0), loop_cpu=pct.get(threading.main_thread().native_id, 0.0),
            feeder_cpu=feeder_cpu,
            rx_rate=(daemon.canio.rx_frames + daemon.canio.rx_ignored - rx0) / w,
            tx_rate=(daemon.frames_sent - tx0) / w, late=daemon.late_samples - late0,
            spin=(daemon.tick.spun_s - spun0) / max(1, daemon.tick_stats.ticks - ticks0), lead=daemon.tick.lead.lead_s)
        daemon.request_stop()
        await task

    asyncio.run(run())
    feeder.stop()
    os.close(master)
    st = daemon.tick_stats
    snap = st.snapshot()
    load = os.getloadavg()
    print(f"bench_tick: {result['wall']:.1f} s, {os.cpu_count()} CPUs, load average {load[0]:.2f},"
          f" tick thread {'SCHED_FIFO ' + str(args.realtime_priority) if daemon.tick.realtime else 'SCHED_OTHER'}")
    print(f"  bus load: {result['rx_rate']:.0f} frames/s received, {result['tx_rate']:.0f} frames/s sent,"
          f" GNSS {len(sim.gnss_messages) / (sim.t_end - sim.t0):.0f} msg/s")
    print(f"  ticks: {st.ticks}; lateness p50 {st.total_percentile(50) * 1e6:.0f} us,"
          f" p99 {st.total_percentile(99) * 1e6:.0f} us, p99.9 {st.total_percentile(99.9) * 1e6:.0f} us,"
          f" max {snap.late_max_total_s * 1e6:.0f} us")
    print(f"  overruns {snap.overruns}, skipped deadlines {snap.skipped},"
          f" tick work p99 {snap.work_p99_s * 1e6:.0f} us, samples late for their step {result['late']}")
    print(f"  spin before the deadline {result['spin'] * 1e6:.0f} us per tick (wake-up lead now {result['lead'] * 1e6:.0f} us)")
    other = max(0.0, result["daemon_cpu"] - result["tick_cpu"] - result["loop_cpu"])
    print(f"  CPU: daemon {result['daemon_cpu']:.1f} % of one core (tick thread {result['tick_cpu']:.1f} %,"
          f" event loop {result['loop_cpu']:.1f} %, other threads {other:.1f} %);"
          f" feeder standing in for the kernel {result['feeder_cpu']:.1f} %; process {result['cpu']:.1f} %")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
