#!/usr/bin/env python3
"""Benchmark the checksum schemes against the libraries they are checked with (numbers, no asserts).

    python3 tools/bench_checksums.py

Per frame: our table CRCs (``ecu_daemon/checksums.py``, ``integrity.py``) against crccheck's and
cantools' implementations of the same CRC, and each scheme's bound check. Best of 5 repeats
(the machine is shared; the minimum is the least disturbed run).
"""
from __future__ import annotations

import sys
import timeit
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import crccheck.crc  # noqa: E402
from cantools.autosar.end_to_end import compute_profile2_crc  # noqa: E402

from ecu_daemon.checksums import FrameChecksum, crc16_xmodem  # noqa: E402

D8 = bytes(range(8))
D32 = bytes(range(32))
CASES = [
    ("CRC-16/XMODEM, 32 B: our table", lambda: crc16_xmodem(D32)),
    ("CRC-16/XMODEM, 32 B: crccheck", lambda: crccheck.crc.Crc16Xmodem.calc(D32)),
    ("E2E P2 CRC8H2F, 8 B: cantools", lambda: compute_profile2_crc(D8, 5)),
    ("check e2e_p2 (one data id), 8 B", FrameChecksum("e2e_p2", 0xB0, False, (0xB0,)).check),
    ("check e2e_p2 (16 data ids), 8 B", FrameChecksum("e2e_p2", 0xFD, False, tuple(range(16))).check),
    ("check toyota, 8 B", FrameChecksum("toyota", 0xAA).check),
    ("check honda, 8 B", FrameChecksum("honda", 0x1A6).check),
    ("check subaru, 8 B", FrameChecksum("subaru", 0x119).check),
    ("check hyundai_canfd, 32 B", FrameChecksum("hyundai_canfd", 0x1CF).check),
    ("check hyundai_bitcount, 8 B", FrameChecksum("hyundai_bitcount", 0x386).check),
    ("check hyundai_nibble, 8 B", FrameChecksum("hyundai_nibble", 0x394).check),
    ("check hyundai_bytesum, 8 B", FrameChecksum("hyundai_bytesum", 0x220).check),
    ("check fca_giorgio, 8 B", FrameChecksum("fca_giorgio", 0xFE).check),
]


def main() -> None:
    n = 20000
    for name, f in CASES:
        arg = () if name.startswith(("CRC", "E2E")) else (D32 if "32 B" in name else D8,)
        t = min(timeit.repeat(lambda: f(*arg), number=n, repeat=5)) / n
        print(f"{name:36s} {t * 1e6:6.2f} us/frame")


if __name__ == "__main__":
    main()
