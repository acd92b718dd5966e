"""Per-drive and per-vehicle tables from the drive records: Parquet (pyarrow) and CSV.

Columns are fixed and typed, rows sorted by vehicle and drive, and the run-dependent fields of a
record (wall time, cached) stay out, so the same drives give byte-identical files whatever the
backend or order of completion.
"""
from __future__ import annotations

import math
from pathlib import Path

from .calibrate import vehicle_parameters
from .job import PARAMS, SCORED, STIFFNESS_EXTRA, VALIDITY

_STR = ("vehicle", "drive", "status", "error", "outliers", "key", "version")
_INT = ("frames", "gnss_samples", "gnss_fused", "gnss_rejected", "gaps", "late_inputs", "steps")
DRIVE_COLUMNS = (
    _STR[:4] + ("duration_s",) + _INT + tuple(f"{v}_fraction" for v in VALIDITY)
    + tuple(c for p in PARAMS for c in (p, f"{p}_std")) + tuple(f"true_{p}" for p in PARAMS)
    + ("start_latency_s", "stiffness_latency_s") + tuple(f"{p}_{e}" for p in PARAMS if p.startswith("cornering") for e in STIFFNESS_EXTRA)
    + tuple(f"{c}_{m}" for c in SCORED.values() for m in ("rms", "coverage_3sigma")) + _STR[4:])


def drive_rows(records: list[dict]) -> list[dict]:
    """Records -> table rows (sorted; ``outliers``: the parameters in which the drive stands out)."""
    rows = sorted(records, key=lambda r: (r["vehicle"], r["drive"]))
    out = []
    for vehicle in sorted({r["vehicle"] for r in rows}):
        mine = [r for r in rows if r["vehicle"] == vehicle]
        _, flagged = vehicle_parameters(mine)
        for i, r in enumerate(mine):
            row = {c: r.get(c) for c in DRIVE_COLUMNS}
            row["outliers"] = ",".join(flagged.get(i, []))
            out.append(row)
    return out


def vehicle_rows(rows: list[dict]) -> list[dict]:
    out = []
    for vehicle in sorted({r["vehicle"] for r in rows}):
        mine = [r for r in rows if r["vehicle"] == vehicle]
        ok = [r for r in mine if r["status"] == "ok"]
        params, flagged = vehicle_parameters(mine)
        row = {"vehicle": vehicle, "drives": len(mine), "failed": len(mine) - len(ok),
               "drive_hours": sum(r["duration_s"] for r in ok) / 3600.0, "outlier_drives": len(flagged)}
        for v in VALIDITY:
            fr = [r[f"{v}_fraction"] for r in ok if r[f"{v}_fraction"] is not None]
            row[f"{v}_fraction"] = sum(fr) / len(fr) if fr else math.nan
        for name, p in params.items():
            row.update({name: p["value"], f"{name}_std": p["std"], f"{name}_spread": p["spread"],
                        f"{name}_drives": p["drives"]})
            truth = {r.get(f"true_{name}") for r in ok} - {None}
            row[f"true_{name}"] = truth.pop() if len(truth) == 1 else math.nan
        out.append(row)
    return out


def _table(rows: list[dict], columns: list[str]):
    import pyarrow as pa

    fields = []
    for c in columns:
        t = pa.string() if c in _STR else pa.int64() if c in _INT or c in ("drives", "failed", "outlier_drives") \
            or c.endswith("_drives") else pa.float64()
        fields.append(pa.field(c, t))
    data = {c: [_cell(r.get(c)) for r in rows] for c in columns}
    return pa.table(data, schema=pa.schema(fields))


def _cell(v):
    return None if isinstance(v, float) and math.isnan(v) else v


def write_tables(records: list[dict], out_dir: str | Path) -> dict[str, Path]:
    """``drives`` and ``vehicles`` as .parquet and .csv in ``out_dir``; returns the paths."""
    import pyarrow.csv as pacsv
    import pyarrow.parquet as pq

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    drives = drive_rows(records)
    vehicles = vehicle_rows(drives)
    paths = {}
    for name, rows, cols in (("drives", drives, list(DRIVE_COLUMNS)),
                             ("vehicles", vehicles, list(vehicles[0]) if vehicles else ["vehicle"])):
        table = _table(rows, cols)
        paths[f"{name}.parquet"] = out / f"{name}.parquet"
        paths[f"{name}.csv"] = out / f"{name}.csv"
        pq.write_table(table, paths[f"{name}.parquet"])
        pacsv.write_csv(table, paths[f"{name}.csv"])
    return paths


def read_drives(out_dir: str | Path) -> list[dict]:
    """The drive table a fleet run wrote (NaN for empty cells)."""
    import pyarrow.parquet as pq

    rows = pq.read_table(Path(out_dir) / "drives.parquet").to_pylist()
    return [{k: (math.nan if v is None and k not in _STR else v) for k, v in r.items()} for r in rows]
