"""A plain single-track (bicycle) observer, the yardstick the estimator must beat (``ecu_daemon.baseline``).

Writes a CSV with ``t, sideslip_rad`` (plus the columns ``evaluate`` requires, as NaN), so the
observer and the estimator can be scored against the same truth::

    python3 tools/baseline_single_track.py --config CFG --can drive.log --out-csv base.csv
    ecu-daemon evaluate --truth truth.csv --estimate base.csv
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from ecu_daemon import config as config_mod  # noqa: E402
from ecu_daemon.baseline import single_track_sideslip  # noqa: E402
from ecu_daemon.estimator.estimate import ESTIMATE_FIELDS  # noqa: E402


def run(cfg, can_path: str, out_csv: str) -> int:
    rows = 0
    cols = ["t", "sideslip_rad"] + [c for c in ESTIMATE_FIELDS if c not in ("t", "sideslip_rad")]
    with open(out_csv, "w") as f:
        f.write(",".join(cols) + "\n")
        for t, beta in single_track_sideslip(cfg, can_path):
            f.write(f"{t:.6f},{beta:.9g}" + ",nan" * (len(cols) - 2) + "\n")
            rows += 1
    return rows


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--config", required=True)
    p.add_argument("--can", required=True)
    p.add_argument("--out-csv", required=True)
    a = p.parse_args()
    n = run(config_mod.load(a.config), a.can, a.out_csv)
    print(f"{n} rows -> {a.out_csv}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
