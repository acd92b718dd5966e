"""The fleet report: Markdown with PNG plots (matplotlib, Agg) beside it.

Per vehicle the learned parameters drive by drive with +-2 sigma bars, the combined value and the
truth when known (trends and outliers at a glance); across the fleet the validity fractions and
the GNSS latency; tables of failed and outlier drives.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .calibrate import vehicle_parameters
from .job import PARAMS

_DEG = 180.0 / math.pi
#: parameter -> (axis label, display value from SI)
DISPLAY = {
    "gnss_delay_s": ("GNSS latency [s]", lambda v: v),
    "wheel_scale": ("wheel scale - 1 [%]", lambda v: (v - 1.0) * 100.0),
    "cornering_stiffness_front_n_per_rad": ("C front [kN/rad]", lambda v: v / 1e3),
    "cornering_stiffness_rear_n_per_rad": ("C rear [kN/rad]", lambda v: v / 1e3),
    "steering_offset_rad": ("steering offset [deg]", lambda v: v * _DEG),
    "yaw_rate_bias_radps": ("yaw-rate bias [deg/s]", lambda v: v * _DEG),
}
_SCALE = {"wheel_scale": 100.0, "cornering_stiffness_front_n_per_rad": 1e-3,
          "cornering_stiffness_rear_n_per_rad": 1e-3, "steering_offset_rad": _DEG, "yaw_rate_bias_radps": _DEG}


def _f(v) -> np.ndarray:
    return np.array([math.nan if x is None else float(x) for x in v])


def _vehicle_plot(plt, vehicle: str, rows: list[dict], out: Path) -> Path:
    ok = [r for r in rows if r["status"] == "ok"]
    params, _ = vehicle_parameters(rows)
    fig, axes = plt.subplots(2, 3, figsize=(13, 6.5), constrained_layout=True)
    x = np.arange(len(ok))
    for ax, name in zip(axes.flat, PARAMS):
        label, show = DISPLAY[name]
        v = show(_f(r[name] for r in ok))
        s = _f(r[f"{name}_std"] for r in ok) * _SCALE.get(name, 1.0)
        bad = np.array([name in (r.get("outliers") or "").split(",") for r in ok], dtype=bool)
        ax.errorbar(x[~bad], v[~bad], yerr=2 * s[~bad], fmt="o", ms=3, capsize=2, label="drive +-2 sigma")
        if bad.any():
            ax.plot(x[bad], v[bad], "rx", ms=8, label="outlier")
        p = params[name]
        lines = []
        if math.isfinite(p["value"]):
            lines.append(show(p["value"]))
            ax.axhline(lines[-1], color="C1", label="combined")
        truth = {r.get(f"true_{name}") for r in ok} - {None}
        truth = {t for t in truth if math.isfinite(t)}
        if len(truth) == 1:
            lines.append(show(truth.pop()))
            ax.axhline(lines[-1], color="k", ls="--", label="truth")
        fin = np.concatenate([v[np.isfinite(v)], lines])
        if len(fin):  # a drive that learned nothing has a prior-wide bar: keep the values readable
            lo, hi = fin.min(), fin.max()
            pad = max(hi - lo, abs(hi) * 0.02, 1e-6)
            ax.set_ylim(lo - pad, hi + pad)
        ax.set_ylabel(label)
        ax.set_xlabel("drive (sorted by name)")
        ax.grid(alpha=0.3)
    axes.flat[0].legend(fontsize=7)
    fig.suptitle(f"{vehicle}: learned parameters per drive")
    path = out / f"params_{_safe(vehicle)}.png"
    fig.savefig(path, dpi=80)
    plt.close(fig)
    return path


def _fleet_plots(plt, vehicles: list[str], rows: list[dict], out: Path) -> list[Path]:
    ok = [r for r in rows if r["status"] == "ok"]
    fig, ax = plt.subplots(figsize=(max(6, 0.5 * len(vehicles) + 3), 4), constrained_layout=True)
    width = 0.2
    for j, v in enumerate(("sideslip_valid", "heading_valid", "velocity_valid", "biases_valid")):
        means = [np.nanmean(_f(r[f"{v}_fraction"] for r in ok if r["vehicle"] == veh) * 100) if any(
            r["vehicle"] == veh for r in ok) else math.nan for veh in vehicles]
        ax.bar(np.arange(len(vehicles)) + (j - 1.5) * width, means, width, label=v)
    ax.set_xticks(np.arange(len(vehicles)), vehicles, rotation=60, fontsize=7)
    ax.set_ylabel("valid rows [%] (mean over drives)")
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3, axis="y")
    p1 = out / "validity.png"
    fig.savefig(p1, dpi=80)
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(max(6, 0.5 * len(vehicles) + 3), 4), constrained_layout=True)
    for i, veh in enumerate(vehicles):
        mine = [r for r in ok if r["vehicle"] == veh]
        ax.errorbar(np.full(len(mine), i), _f(r["gnss_delay_s"] for r in mine),
                    yerr=2 * _f(r["gnss_delay_s_std"] for r in mine), fmt="o", ms=3, alpha=0.5, color="C0")
        t = {r.get("true_gnss_delay_s") for r in mine} - {None}
        if len(t) == 1 and math.isfinite(next(iter(t))):
            ax.plot([i - 0.3, i + 0.3], [t.pop()] * 2, "k--")
    ax.set_xticks(np.arange(len(vehicles)), vehicles, rotation=60, fontsize=7)
    ax.set_ylabel("learned GNSS latency [s] (+-2 sigma; dashed: truth)")
    ax.grid(alpha=0.3)
    p2 = out / "latency.png"
    fig.savefig(p2, dpi=80)
    plt.close(fig)
    return [p1, p2]


def _safe(name: str) -> str:
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in name)


def _fmt(v, spec: str) -> str:
    return "-" if v is None or (isinstance(v, float) and not math.isfinite(v)) else format(v, spec)


def write_report(drives: list[dict], vehicles: list[dict], out_dir: str | Path, run_info: str = "") -> Path:
    """``report.md`` and its PNGs in ``out_dir``; ``drives``/``vehicles``: the table rows."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    names = [v["vehicle"] for v in vehicles]
    ok = [r for r in drives if r["status"] == "ok"]
    hours = sum(r["duration_s"] for r in ok) / 3600.0
    md = ["# Fleet report", "", f"{len(drives)} drive(s) of {len(vehicles)} vehicle(s): {len(ok)} replayed,"
          f" {len(drives) - len(ok)} failed; {hours:.2f} drive-hours.", ""]
    if run_info:
        md += [run_info, ""]
    md += ["## Vehicles", "", "Combined over the drives (inverse-variance, outliers left out): value +- 1 sigma;"
           " truth in brackets where known. Valid: mean share of rows with sideslip / heading valid.", "",
           "| vehicle | drives | failed | outliers | latency s | wheel scale | Cf kN/rad | Cr kN/rad | steer off deg"
           " | yaw bias deg/s | valid b/h % |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    for v in vehicles:
        cells = []
        for name in PARAMS:
            s = _SCALE.get(name, 1.0) if name != "wheel_scale" else 1.0
            spec = ".4f" if name in ("gnss_delay_s", "wheel_scale", "steering_offset_rad", "yaw_rate_bias_radps") else ".1f"
            t = v.get(f"true_{name}")
            cells.append(f"{_fmt(v[name] * s, spec)} +- {_fmt(v[f'{name}_std'] * s, '.2g')}"
                         + (f" ({_fmt(t * s, spec)})" if t is not None and math.isfinite(t) else ""))
        md.append(f"| {v['vehicle']} | {v['drives']} | {v['failed']} | {v['outlier_drives']} | " + " | ".join(cells)
                  + f" | {_fmt(v['sideslip_valid_fraction'] * 100, '.0f')}/{_fmt(v['heading_valid_fraction'] * 100, '.0f')} |")
    failed = [r for r in drives if r["status"] != "ok"]
    md += ["", "## Failed drives", ""] + ([f"- {r['vehicle']}/{r['drive']}: {r['error']}" for r in failed] or ["none"])
    flagged = [r for r in ok if r.get("outliers")]
    md += ["", "## Outlier drives", ""] + ([f"- {r['vehicle']}/{r['drive']}: {r['outliers']}" for r in flagged] or ["none"])
    md += ["", "## Plots", ""]
    for p in _fleet_plots(plt, names, drives, out):
        md.append(f"![{p.stem}]({p.name})")
    for veh in names:
        p = _vehicle_plot(plt, veh, [r for r in drives if r["vehicle"] == veh], out)
        md.append(f"![{veh}]({p.name})")
    path = out / "report.md"
    path.write_text("\n".join(md) + "\n", encoding="utf-8")
    return path
