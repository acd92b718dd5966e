#!/usr/bin/env python3
"""Fuzz the config loader, the CAN signal decoder and compressed CAN logs.

    python3 tools/bench_fuzz.py [--n 100000] [--only config|decoder|gz] [--hypothesis] [--seed 1]

Runs the targets of ``tests/fuzzing.py`` (the tests run them briefly through hypothesis) on
``--n`` inputs each and prints, per target, the count of each outcome and the rate. By default
the inputs are drawn by a seeded ``random.Random`` from the same families as the hypothesis
strategies (hypothesis' engine manages ~100 inputs/s, too slow for 1e5); ``--hypothesis`` uses
the strategies themselves. A property that fails stops the run with the failing input.
Numbers only, no timing asserts.
"""
from __future__ import annotations

import argparse
import collections
import logging
import random
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]

from hypothesis import HealthCheck, Phase, given, settings  # noqa: E402

import fuzzing  # noqa: E402

TARGETS = {"config": (fuzzing.config_docs, fuzzing.random_config_doc, fuzzing.check_config),
           "decoder": (fuzzing.can_frames(), fuzzing.random_frame, fuzzing.check_frame),
           "gz": (fuzzing.gz_inputs(), fuzzing.random_gz, fuzzing.check_gz)}


def run(name: str, n: int, use_hypothesis: bool = False, seed: int = 1) -> None:
    strategy, draw, check = TARGETS[name]
    counts: collections.Counter = collections.Counter()

    @settings(max_examples=n, deadline=None, database=None, phases=[Phase.generate, Phase.shrink],
              suppress_health_check=list(HealthCheck))
    @given(strategy)
    def target(x):
        counts[check(x)] += 1

    t0 = time.perf_counter()
    if use_hypothesis:
        target()
    else:
        rng = random.Random(seed)
        for _ in range(n):
            x = draw(rng)
            try:
                counts[check(x)] += 1
            except Exception:
                print(f"{name}: failing input: {x!r}", file=sys.stderr)
                raise
    wall = time.perf_counter() - t0
    total = sum(counts.values())
    outcomes = ", ".join(f"{k} {v}" for k, v in sorted(counts.items(), key=lambda kv: -kv[1]))
    print(f"{name:8s}: {total} inputs in {wall:.1f} s ({total / wall:.0f}/s); {outcomes}", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=100_000, help="inputs per target")
    ap.add_argument("--only", choices=sorted(TARGETS), action="append", help="run only these targets")
    ap.add_argument("--hypothesis", action="store_true", help="draw through the hypothesis strategies")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    logging.getLogger("ecu_daemon").setLevel(logging.ERROR)  # the decoder's per-kind warnings: counted, not shown
    for name in args.only or TARGETS:
        run(name, args.n, args.hypothesis, args.seed)


if __name__ == "__main__":
    main()
