#!/usr/bin/env python3
"""Benchmark the CAN edge: log parsing, input decoding and output encoding (numbers, no asserts).

    python3 tools/bench_decode.py [candump.log]

Default log: the real Toyota RAV4 minute (``../shared/data/comma2k19-rav4/rav4_bus0_candump.log``),
else the vendored 5 s extract. Decoding uses ``examples/toyota_rav4.toml`` (opendbc DBC, strict=False)
and the default config on frames of our own input DBC (E2E CRC + counter checks on). Every figure
is the best of several repeats (the machine is shared; the minimum is the least disturbed run).
"""
from __future__ import annotations

import argparse
import logging
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import can  # noqa: E402

from ecu_daemon import config  # noqa: E402
from ecu_daemon.canlog import read_can_log  # noqa: E402
from ecu_daemon.diagnostics import Diagnostics  # noqa: E402
from ecu_daemon.estimator.estimate import Estimate  # noqa: E402
from ecu_daemon.integrity import e2e_p2_apply  # noqa: E402
from ecu_daemon.outputs import OutputEncoder  # noqa: E402
from ecu_daemon.signals import SignalDecoder  # noqa: E402

SHARED_LOG = ROOT.parent / "shared" / "data" / "comma2k19-rav4" / "rav4_bus0_candump.log"
VENDORED_LOG = ROOT / "tests" / "data" / "comma2k19" / "rav4_bus0_candump_5s.log"


def best(fn, repeat: int = 5) -> float:
    """Smallest wall time of ``repeat`` calls of ``fn`` (seconds)."""
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def bench_parse(path: Path) -> list:
    frames = list(read_can_log(path))
    n = len(frames)
    ours = best(lambda: sum(1 for _ in read_can_log(path)))
    theirs = best(lambda: sum(1 for _ in can.LogReader(str(path))), repeat=3)
    print(f"parse   {path.name}: {n} frames")
    print(f"        read_can_log          {ours / n * 1e6:6.2f} us/line  ({n / ours:,.0f} lines/s)")
    print(f"        python-can LogReader  {theirs / n * 1e6:6.2f} us/line  ({theirs / ours:.1f}x slower)")
    return frames


def bench_decode_rav4(frames: list) -> None:
    cfg = config.load(ROOT / "examples" / "toyota_rav4.toml")
    dec = SignalDecoder(cfg)
    wanted = {fid for fid, _ in dec.frame_ids}
    hit = [f for f in frames if f[1] in wanted and not f[3]]
    miss = [f for f in frames if f[1] not in wanted]

    def run(fs):
        d = dec.decode
        for t, fid, ext, err, data in fs:
            d(t, fid, data, ext)

    t_all = best(lambda: run(frames))
    t_hit = best(lambda: run(hit))
    t_miss = best(lambda: run(miss))
    samples = sum(len(dec.decode(t, fid, data, ext)) for t, fid, ext, err, data in hit)
    print(f"decode  RAV4 (opendbc DBC, {len(wanted)} of {len({f[1] for f in frames})} ids mapped, no CRC/counter)")
    print(f"        uninteresting frame   {t_miss / len(miss) * 1e6:6.2f} us  ({len(miss)} frames)")
    print(f"        decoded frame         {t_hit / len(hit) * 1e6:6.2f} us  ({len(hit)} frames, "
          f"{samples / len(hit):.2f} samples each)")
    print(f"        whole log             {t_all / len(frames) * 1e6:6.2f} us/frame, "
          f"{t_all * 1e3:.0f} ms for {frames[-1][0] - frames[0][0]:.0f} s of bus")
    for fid in sorted(wanted):
        fs = [f for f in hit if f[1] == fid]
        name = dec.db.get_message_by_frame_id(fid).name
        print(f"        0x{fid:03X} {name:<20} {best(lambda: run(fs)) / len(fs) * 1e6:6.2f} us")
    msg = dec.db.get_message_by_frame_id(0xAA)
    data = hit[0][4] if hit[0][1] == 0xAA else next(f[4] for f in hit if f[1] == 0xAA)
    n = 20000
    t = best(lambda: [msg.decode(data, decode_choices=False) for _ in range(n)])
    print(f"        (cantools Message.decode alone, WHEEL_SPEEDS: {t / n * 1e6:.2f} us)")


def bench_decode_ours() -> None:
    dec = SignalDecoder(config.load(None))
    db = dec.db
    frames = []
    for k in range(1024):  # a multiple of 16: the counters stay continuous across repeats
        for name, vals in (("WHEEL_SPEEDS", {"WHEEL_SPEED_FL": 10.0, "WHEEL_SPEED_FR": 10.1,
                                              "WHEEL_SPEED_RL": 9.9, "WHEEL_SPEED_RR": 10.0}),
                           ("STEERING", {"STEERING_WHEEL_ANGLE": 0.1}),
                           ("IMU", {"YAW_RATE": 0.05, "ACCEL_X": 0.3, "ACCEL_Y": -0.2})):
            m = db.get_message_by_name(name)
            v = {s.name: 0 for s in m.signals}
            v.update(vals, COUNTER=k & 15)
            p = bytearray(m.encode(v))
            e2e_p2_apply(p, m.frame_id & 0xFF)
            frames.append((k * 0.01, m.frame_id, bytes(p)))
    state = {"t0": 0.0}

    def run():
        d = dec.decode
        off = state["t0"]
        for t, fid, data in frames:
            d(t + off, fid, data)
        state["t0"] += 10.24

    t = best(run)
    errors = sum(sum(h.errors.values()) for h in dec.health.values())
    print(f"decode  our DBC (E2E CRC + counter checked): {t / len(frames) * 1e6:6.2f} us/frame"
          f" ({len(frames)} frames x 6 runs, {errors} errors)")


def bench_encode() -> None:
    enc = OutputEncoder(config.Config())
    e = Estimate(t=1.0, sideslip_rad=0.01, sideslip_std_rad=0.002, heading_rad=1.0, heading_std_rad=0.01,
                 vx_mps=20.0, vy_mps=0.2, vx_std_mps=0.05, vy_std_mps=0.1, yaw_rate_radps=0.1,
                 yaw_rate_bias_radps=-0.007, yaw_rate_bias_std_radps=0.001, accel_x_bias_mps2=0.1,
                 accel_x_bias_std_mps2=0.05, accel_y_bias_mps2=-0.1, accel_y_bias_std_mps2=0.05,
                 gnss_delay_s=0.2, wheel_scale=0.99, steering_offset_rad=0.01,
                 cornering_stiffness_front_n_per_rad=1e5, cornering_stiffness_rear_n_per_rad=1.2e5,
                 sideslip_valid=True, heading_valid=True, velocity_valid=True, biases_valid=True,
                 status=0, gnss_fused=7, gnss_rejected=1, gnss_late=0)
    d = Diagnostics()
    steps = 600
    nframes = sum(len(enc.frames(k, e, d)) for k in range(steps))
    t = best(lambda: [enc.frames(k, e, d) for k in range(steps)])
    msg = enc.db.get_message_by_name("EST_SIDESLIP")
    vals = {s.name: 0 for s in msg.signals}
    n = 20000
    t_ns = best(lambda: [msg.encode(vals, strict=False) for _ in range(n)])
    t_s = best(lambda: [msg.encode(vals) for _ in range(n)], repeat=3)
    print(f"encode  OutputEncoder.frames: {t / steps * 1e6:6.1f} us per 6 ms step ({nframes / steps:.1f} frames),"
          f" {t / nframes * 1e6:.1f} us per frame, {t / steps / 0.006 * 100:.2f} % of one core")
    print(f"        (cantools Message.encode alone: strict=False {t_ns / n * 1e6:.2f} us, strict=True {t_s / n * 1e6:.2f} us)")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("log", nargs="?", help="candump -L log (default: the RAV4 minute)")
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.WARNING)
    path = Path(args.log) if args.log else (SHARED_LOG if SHARED_LOG.exists() else VENDORED_LOG)
    print(f"python {sys.version.split()[0]}, python-can {can.__version__}")
    frames = bench_parse(path)
    bench_decode_rav4(frames)
    bench_decode_ours()
    bench_encode()
    return 0


if __name__ == "__main__":
    sys.exit(main())
