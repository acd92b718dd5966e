#!/usr/bin/env python3
"""Benchmark the GNSS edge: cost per message of GnssStreamParser, the capture log and the encoders.

    python3 tools/bench_gnss.py [--repeat 5]

Numbers only, no asserts. Every figure is the best of ``--repeat`` runs (the machine is shared; the
minimum is the least disturbed run). A calibration line (a pure-Python loop) is printed first so
figures from a loaded machine can be put in proportion.
"""
from __future__ import annotations

import argparse
import logging
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from pyubx2 import GET, VALNONE, UBXMessage, UBXReader  # noqa: E402

from ecu_daemon.gnss import GnssLogWriter, GnssStreamParser, read_gnss_log, samples_from_log  # noqa: E402
from ecu_daemon.gnss import encode as enc  # noqa: E402

DATA = ROOT / "tests" / "data" / "gnss"
T0 = 1700000000.0


def best(fn, n: int, repeat: int) -> float:
    """Best-of-``repeat`` seconds per call of ``fn`` run ``n`` times."""
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        for _ in range(n):
            fn()
        times.append((time.perf_counter() - t) / n)
    return min(times)


def row(label: str, value: float, unit: str) -> None:
    print(f"{label:44s}: {value:8.1f} {unit}")


def epoch_sentences(k: int) -> list[bytes]:
    t = T0 + 0.1 * k
    return [s.encode() + b"\r\n" for s in (
        enc.nmea_rmc(utc=t, lat_deg=48.1, lon_deg=11.5, speed_mps=20.0, course_deg=45.0),
        enc.nmea_vtg(speed_mps=20.0, course_deg=45.0),
        enc.nmea_gga(utc=t, lat_deg=48.1, lon_deg=11.5),
        "$GNGSA,A,3,13,16,21,15,10,29,27,20,,,,,1.05,0.64,0.83,1*03",
        "$GPGSV,3,3,12,26,04,276,,27,15,218,31,29,24,004,13,30,00,159,,1*69",
        enc.nmea_gst(utc=t),
    )]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    logging.disable(logging.WARNING)
    r = args.repeat
    us = 1e6

    calib = best(lambda: sum(range(1000)), 2000, r)
    print(f"calibration: sum(range(1000)) = {calib * us:.1f} us (an idle modern x86 core: ~10 us)")

    pvt = enc.nav_pvt(**enc.utc_fields(T0), lat_deg=48.1, lon_deg=11.5, vel_n_mps=20.0, vel_e_mps=-3.0)
    parser = GnssStreamParser()
    row("UBX NAV-PVT, one frame per feed()", best(lambda: parser.feed(1.0, pvt), 500, r) * us, "us/frame")
    row("  of which pyubx2 UBXReader.parse",
        best(lambda: UBXReader.parse(pvt, msgmode=GET, validate=VALNONE), 500, r) * us, "us/frame")
    unsupported = UBXMessage("NAV", "NAV-CLOCK", GET).serialize()
    row("UBX frame not used (framing + checksum)", best(lambda: parser.feed(1.0, unsupported), 2000, r) * us,
        "us/frame")

    rmc = epoch_sentences(0)[0]
    nparser = GnssStreamParser(protocol="nmea")
    row("NMEA RMC, one sentence per feed()", best(lambda: nparser.feed(1.0, rmc), 2000, r) * us, "us/sentence")
    epochs = [epoch_sentences(k) for k in range(50)]
    flat = [s for e in epochs for s in e]

    def run_epochs():
        p = GnssStreamParser(protocol="nmea")
        for s in flat:
            p.feed(1.0, s)
    per = best(run_epochs, 1, r) / len(flat)
    row("NMEA u-blox epoch (RMC VTG GGA GSA GSV GST)", per * us, f"us/sentence, {per * 6 * us:.0f} us/epoch")

    data = b"".join(l for l in (DATA / "pyubx2" / "pygpsdata-MIXED.log").read_bytes().splitlines(keepends=True))

    def run_mixed():
        p = GnssStreamParser()
        p.feed(0.0, data)
        return p
    p = run_mixed()
    msgs = p.stats["ubx_frames"] + p.stats["nmea_sentences"]
    t_mixed = best(run_mixed, 1, r)
    print(f"pygpsdata-MIXED.log ({len(data)} B, {msgs} msgs, {p.stats['samples']} NAV-PVT), one feed: "
          f"{t_mixed * 1e3:.1f} ms = {t_mixed / msgs * us:.1f} us/msg, {len(data) / t_mixed / 1e6:.2f} MB/s")

    # garbage made of frame headers that each claim a long frame: resynchronising must stay linear
    for label, unit in (("repeated UBX sync+header, 8191 B claimed", b"\xb5\x62\x01\x07\xff\x1f"),
                        ("repeated RTCM3 header, 1023 B claimed", b"\xd3\x03\xff")):
        for size in (60_000, 240_000):
            junk = unit * (size // len(unit))

            def run_junk():
                p = GnssStreamParser()
                for i in range(0, len(junk), 256):  # 256-byte reads, as from a serial port
                    p.feed(i * 1e-5, junk[i:i + 256])
                p.finish()
            row(f"{label}, {size // 1000} kB", len(junk) / best(run_junk, 1, r) / 1e3, "kB/s")

    with tempfile.TemporaryDirectory() as tmp:
        log = Path(tmp) / "gnss.log"
        with GnssLogWriter(log) as w:
            for k in range(200):
                w.write(100.0 + 0.1 * k, enc.nav_pvt(**enc.utc_fields(T0 + 0.1 * k), lat_deg=48.1,
                                                     lon_deg=11.5, vel_n_mps=20.0, vel_e_mps=1.0))
                for s in epoch_sentences(k):
                    w.write(100.0 + 0.1 * k + 0.01, s)
        lines = 200 * 7
        t_read = best(lambda: sum(1 for _ in read_gnss_log(log)), 1, r)
        row("read_gnss_log", t_read / lines * us, "us/line")
        t_replay = best(lambda: sum(1 for _ in samples_from_log(log)), 1, r)
        row("samples_from_log (UBX + NMEA epochs)", t_replay / lines * us,
            f"us/line ({t_replay / 200 * 1e3:.2f} ms per 100 ms epoch)")

        def write_log():
            with GnssLogWriter(Path(tmp) / "w.log") as w:
                for _ in range(200):
                    w.write(1.0, pvt)
                    w.write(1.0, rmc)
        row("GnssLogWriter.write", best(write_log, 1, r) / 400 * us, "us/message")

    fields = enc.utc_fields(T0)
    row("encode.nav_pvt (pyubx2 UBXMessage)",
        best(lambda: enc.nav_pvt(**fields, lat_deg=1, lon_deg=2, vel_n_mps=1, vel_e_mps=2), 200, r) * us, "us")
    row("encode.nmea_rmc (pynmea2 render)",
        best(lambda: enc.nmea_rmc(utc=T0, lat_deg=1, lon_deg=2, speed_mps=1, course_deg=2), 2000, r) * us, "us")


if __name__ == "__main__":
    main()
