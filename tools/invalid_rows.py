"""Which rows a suite drive leaves invalid, what keeps them invalid, and how right they were.

Why (issue 7): "right while invalid" is the second worst defect. Before loosening a validity rule,
see for the rows the suite counts (above 5 m/s, from ``CONVERGE_S`` after the first good GNSS fix
above 5 m/s, as ``evaluate.validity_metrics``) whether the published std alone holds them (std at or
above ``core.SIDESLIP_STD_VALID`` / ``core.HEADING_STD_VALID``) or another rule does, and their
actual error against the reported std. A std many times the error is only needlessly wide if the
drive could not have been wrong by that much: replay a wrong-but-plausible config (a stiffness 30 %
off, a latency prior 1 sigma off) to see.

    python3 tools/invalid_rows.py /tmp/suite lowspeed_r10 lowspeed_r15 road_handling

(ROOT holds the drive folders of ``ecu-daemon evaluate --suite --out ROOT``: estimate.csv, truth.csv.)
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from ecu_daemon.estimator.core import HEADING_STD_VALID, SIDESLIP_STD_VALID  # noqa: E402
from ecu_daemon.evaluate import CONVERGE_S, VALID_SPEED_MPS, first_good_fix, read_csv  # noqa: E402

DEG = 180.0 / math.pi


def counted_rows(folder: Path) -> tuple:
    """The estimate's columns, the truth's, and the rows the suite counts (above 5 m/s, from
    ``CONVERGE_S`` after the first good fix: ``evaluate.validity_metrics``'s rule; withheld.py too)."""
    e = np.genfromtxt(folder / "estimate.csv", delimiter=",", names=True)
    tr = read_csv(folder / "truth.csv", ("t",), "truth CSV")
    t = e["t"]
    speed = np.interp(t, tr["t"], tr["speed_mps"])
    counted = (speed > VALID_SPEED_MPS) & (t <= tr["t"][-1])
    t_fix = first_good_fix(tr)
    if math.isfinite(t_fix):
        counted &= t >= t_fix + CONVERGE_S
    return e, tr, counted


def lines(folder: Path) -> list[str]:
    """One line per quantity (sideslip, heading) of the drive in ``folder``."""
    e, tr, counted = counted_rows(folder)
    t = e["t"]
    out = []
    for q, limit in (("sideslip", SIDESLIP_STD_VALID), ("heading", HEADING_STD_VALID)):
        truth = np.interp(t, tr["t"], np.unwrap(tr[q + "_rad"]))
        err = np.abs((e[q + "_rad"] - truth + math.pi) % (2.0 * math.pi) - math.pi) * DEG
        std = e[q + "_std_rad"] * DEG
        inv = counted & (e[q + "_valid"] < 0.5)
        n, k = int(counted.sum()), int(inv.sum())
        head = f"{folder.name:16s} {q:8s} counted {n:6d} invalid {k:6d} ({k / max(n, 1):6.1%})"
        if k == 0:
            out.append(head)
            continue
        by_std = int(np.sum(inv & (std >= limit * DEG)))
        out.append(f"{head}; held by the std {by_std:6d}, by another rule {k - by_std:6d}; |error| median "
                   f"{np.median(err[inv]):.3f} p95 {np.percentile(err[inv], 95):.3f} max {err[inv].max():.3f} deg;"
                   f" std median {np.median(std[inv]):.3f} p5 {np.percentile(std[inv], 5):.3f} deg;"
                   f" error/std median {np.median(err[inv] / std[inv]):.2f}")
    return out


def main(argv: list[str]) -> int:
    if len(argv) < 2:
        print(__doc__)
        return 2
    root = Path(argv[0])
    for case in argv[1:]:
        print("\n".join(lines(root / case)))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
