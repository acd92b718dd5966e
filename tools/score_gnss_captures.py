#!/usr/bin/env python3
"""Score GnssStreamParser against gpsd's answer keys on every gpsd capture.

    .venv/bin/python tools/score_gnss_captures.py [DIR] [--tol 0.05] [-v]

DIR defaults to ``../shared/data/gnss-captures/gpsd`` (beside the repository). For each
``NAME.log`` with its ``NAME.log.chk`` (gpsd's regression output), a *speed epoch* is a distinct
TPV time that carries a ``speed``; gpsd's answer for it is the last such TPV of that time. It is
*matched* when the parser produced a sample with the same UTC epoch (to 10 ms, modulo 1024 GPS weeks) whose ground speed
is within ``--tol`` m/s. Prints one line per log with misses (all logs with ``-v``) and the total.
Numbers only, no pass/fail: the test suite holds the bound.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from datetime import datetime
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from ecu_daemon.gnss import GnssStreamParser  # noqa: E402
from ecu_daemon.gnss.logfile import raw_capture_bytes as capture_bytes  # noqa: E402

DEFAULT_DIR = ROOT.parent / "shared" / "data" / "gnss-captures" / "gpsd"


#: gpsd moves receiver dates it believes are pre-rollover forward by 1024 GPS weeks (neo-m8n's
#: 2015 fixes come out in 2034); epochs are compared modulo that.
_ROLLOVER_CS = 1024 * 7 * 86400 * 100


def _epoch_key(utc_s: float) -> int:
    return round(utc_s * 100) % _ROLLOVER_CS


def gpsd_speed_epochs(chk: Path) -> dict[int, float]:
    """gpsd's final TPV speed per epoch (key: UTC in units of 10 ms)."""
    out: dict[int, float] = {}
    for line in chk.read_text(errors="replace").splitlines():
        if not line.startswith('{"class":"TPV"'):
            continue
        d = json.loads(line)
        if "time" in d and "speed" in d:
            out[_epoch_key(datetime.fromisoformat(d["time"].replace("Z", "+00:00")).timestamp())] = d["speed"]
    return out


def score_log(log: Path, tol: float) -> tuple[int, int]:
    """(gpsd speed epochs, matched) for one capture."""
    want = gpsd_speed_epochs(log.with_name(log.name + ".chk"))
    parser = GnssStreamParser()
    got: dict[int, list[float]] = {}
    for s in parser.feed(0.0, capture_bytes(log)) + parser.finish():
        if math.isfinite(s.fix_time_utc_s) and math.isfinite(s.speed_mps):
            got.setdefault(_epoch_key(s.fix_time_utc_s), []).append(s.speed_mps)
    matched = sum(any(abs(v - speed) <= tol for v in got.get(k, ())) for k, speed in want.items())
    return len(want), matched


def score_dir(directory: Path, tol: float = 0.05) -> dict[str, tuple[int, int]]:
    """Per log name: (gpsd speed epochs, matched), for every log that has an answer key."""
    return {log.stem: score_log(log, tol) for log in sorted(directory.glob("*.log"))
            if log.with_name(log.name + ".chk").exists()}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dir", nargs="?", type=Path, default=DEFAULT_DIR)
    ap.add_argument("--tol", type=float, default=0.05, help="speed tolerance, m/s (default 0.05)")
    ap.add_argument("-v", "--verbose", action="store_true", help="one line per log, not only the misses")
    args = ap.parse_args(argv)
    if not args.dir.is_dir():
        print(f"no captures at {args.dir}", file=sys.stderr)
        return 2
    import logging
    logging.disable(logging.WARNING)  # the captures are full of deliberate damage
    scores = score_dir(args.dir, args.tol)
    total = sum(n for n, _ in scores.values())
    hit = sum(m for _, m in scores.values())
    for name, (n, m) in scores.items():
        if args.verbose or m < n:
            print(f"{name:36s} {m:4d} / {n:4d}")
    print(f"{len(scores)} logs, {sum(n > 0 for n, _ in scores.values())} with speed epochs: "
          f"{hit} of {total} gpsd speed epochs matched ({100.0 * hit / max(total, 1):.1f} %), tol {args.tol} m/s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
