#!/usr/bin/env python3
"""Fuzz the config loader, the CAN signal decoder and compressed CAN logs with hypothesis.

    python3 tools/bench_fuzz.py [--n 100000] [--only config|decoder|gz]

Runs the targets of ``tests/fuzzing.py`` (the tests run the same ones briefly) on ``--n`` generated
inputs each and prints, per target, the count of each outcome and the rate. A property that fails
stops the run with hypothesis' minimal failing example. Numbers only, no timing asserts.
"""
from __future__ import annotations

import argparse
import collections
import logging
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]

from hypothesis import HealthCheck, Phase, given, settings  # noqa: E402

import fuzzing  # noqa: E402

TARGETS = {"config": (fuzzing.config_docs, fuzzing.check_config),
           "decoder": (fuzzing.can_frames(), fuzzing.check_frame),
           "gz": (fuzzing.gz_inputs(), fuzzing.check_gz)}


def run(name: str, n: int) -> None:
    strategy, check = TARGETS[name]
    counts: collections.Counter = collections.Counter()

    @settings(max_examples=n, deadline=None, database=None, phases=[Phase.generate, Phase.shrink],
              suppress_health_check=list(HealthCheck))
    @given(strategy)
    def target(x):
        counts[check(x)] += 1

    t0 = time.perf_counter()
    target()
    wall = time.perf_counter() - t0
    total = sum(counts.values())
    outcomes = ", ".join(f"{k} {v}" for k, v in sorted(counts.items(), key=lambda kv: -kv[1]))
    print(f"{name:8s}: {total} inputs in {wall:.1f} s ({total / wall:.0f}/s); {outcomes}", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=100_000, help="inputs per target")
    ap.add_argument("--only", choices=sorted(TARGETS), action="append", help="run only these targets")
    args = ap.parse_args()
    logging.getLogger("ecu_daemon").setLevel(logging.ERROR)  # the decoder's per-kind warnings: counted, not shown
    for name in args.only or TARGETS:
        run(name, args.n)


if __name__ == "__main__":
    main()
