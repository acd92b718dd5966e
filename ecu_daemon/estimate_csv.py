"""The estimate CSV (``replay --out-csv``, a recording's ``estimates.csv``): one row per step.

Its own module because the replay, the recorder and the benchmarks all write it, and none of them
should import another to do so.
"""
from __future__ import annotations

from .estimator.estimate import ESTIMATE_FIELDS

try:
    from ._estimate_csv import format_rows as _format_rows_compiled  # setup.py builds it; optional
except ImportError:
    _format_rows_compiled = None

_BOOL_FIELDS = {"sideslip_valid", "heading_valid", "velocity_valid", "biases_valid", "bank_valid",
                "grade_valid", "roll_valid"}
_INT_FIELDS = {"status", "gnss_fused", "gnss_rejected", "gnss_late"}


def csv_header() -> str:
    return ",".join(ESTIMATE_FIELDS) + "\n"


def _kinds() -> list[str]:
    return ["%.6f" if name == "t" else "%d" if name in _BOOL_FIELDS or name in _INT_FIELDS else "%.9g"
            for name in ESTIMATE_FIELDS]


ROW_FORMAT = ",".join(_kinds()) + "\n"
_KINDS = bytes({"%.6f": 0, "%d": 1, "%.9g": 2}[k] for k in _kinds())  # for _estimate_csv.c


def format_row(est) -> str:
    return ROW_FORMAT % tuple(est)


def format_rows(rows: list) -> str:
    """``"".join(format_row(r) for r in rows)``, compiled where built (``_estimate_csv.c``: the
    replay writes a row per 6 ms step, and %-formatting was a tenth of its time)."""
    if _format_rows_compiled is not None:
        out = _format_rows_compiled(_KINDS, rows)
        if out is not NotImplemented:
            return out
    return "".join([ROW_FORMAT % tuple(r) for r in rows])
