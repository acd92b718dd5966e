"""The estimate CSV (``replay --out-csv``, a recording's ``estimates.csv``): one row per step.

Its own module because the replay, the recorder and the benchmarks all write it, and none of them
should import another to do so.
"""
from __future__ import annotations

from .estimator.estimate import ESTIMATE_FIELDS

_BOOL_FIELDS = {"sideslip_valid", "heading_valid", "velocity_valid", "biases_valid", "bank_valid",
                "grade_valid", "roll_valid"}
_INT_FIELDS = {"status", "gnss_fused", "gnss_rejected", "gnss_late"}


def csv_header() -> str:
    return ",".join(ESTIMATE_FIELDS) + "\n"


def _row_format() -> str:
    parts = []
    for name in ESTIMATE_FIELDS:
        if name == "t":
            parts.append("%.6f")
        elif name in _BOOL_FIELDS or name in _INT_FIELDS:
            parts.append("%d")
        else:
            parts.append("%.9g")
    return ",".join(parts) + "\n"


ROW_FORMAT = _row_format()


def format_row(est) -> str:
    return ROW_FORMAT % tuple(est)
