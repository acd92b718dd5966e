#!/usr/bin/env python3
"""What sideslip, its reported std and its validity do around a GNSS outage (issue 7, avail-b).

Reads a suite case's ``estimate.csv`` and ``truth.csv`` (``ecu-daemon evaluate --suite --out DIR``
writes both under ``DIR/CASE/``) and prints, for the rows above 5 m/s of each phase (before, during,
0-10 s after, later) and of each ``--window`` seconds: the share flagged valid, the sideslip
error's RMS and max, the reported std's median and max, the share within 3 reported sigma, the 99th
percentile of |error| / std, the share invalid with the std above the validity threshold and
invalid for another rule (and of the invalid, how many were under 0.5 deg off), the share with
velocity invalid; then every run of invalid rows (|ay|, worst error, median std) and the first valid
row after the outage. The outage is the longest stretch without a fused GNSS fix (the cumulative
count standing still).

    python3 tools/outage_probe.py /tmp/suite/gnss_outage_30s [--window 2]
    python3 tools/outage_probe.py /tmp/suite/gnss_outage_30s --summary   # one line per phase

Why: the sideslip valid fraction of the outage cases (0.70-0.82) is a sum of three phases
(before, during, after the outage) with different causes; this splits it by phase and by rule.
"""
from __future__ import annotations

import argparse
import csv
import math
from pathlib import Path

import numpy as np

from ecu_daemon.estimator.core import SIDESLIP_STD_VALID
DEG = 180.0 / math.pi


def _read(path: Path) -> dict:
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    head, body = rows[0], np.array(rows[1:], dtype=float)
    return {h: body[:, i] for i, h in enumerate(head)}


def load(case_dir: Path) -> dict:
    """Estimate rows with the truth interpolated onto their times, and the outage's span."""
    est = _read(case_dir / "estimate.csv")
    tru = _read(case_dir / "truth.csv")
    t = est["t"]
    tt = tru["t"]
    beta_true = np.interp(t, tt, tru["sideslip_rad"])
    speed = np.interp(t, tt, tru["speed_mps"])
    # the outage: the longest stretch without a fused fix (the cumulative count standing still)
    fused = est["gnss_fused"]
    change = np.flatnonzero(np.diff(fused) != 0)
    if change.size >= 2:
        gaps = np.diff(t[change])
        i = int(np.argmax(gaps))
        out0, out1 = float(t[change[i]]), float(t[change[i + 1]])
    else:
        out0 = out1 = math.nan
    return {"t": t, "err": est["sideslip_rad"] - beta_true, "std": est["sideslip_std_rad"],
            "valid": est["sideslip_valid"] > 0.5, "speed": speed, "status": est["status"].astype(int),
            "vel_valid": est["velocity_valid"] > 0.5, "vy_std": est["vy_std_mps"],
            "ay_true": np.interp(t, tt, tru["ay_mps2"]), "out": (out0, out1), "t0": float(t[0])}


def phase_stats(d: dict, sel: np.ndarray) -> dict:
    sel = sel & (d["speed"] > 5.0)
    n = int(sel.sum())
    if n == 0:
        return {"n": 0}
    err, std, valid = d["err"][sel], d["std"][sel], d["valid"][sel]
    inside = np.abs(err) <= 3.0 * std
    over = std >= SIDESLIP_STD_VALID
    return {"n": n, "valid": valid.mean(), "rms": math.sqrt(np.mean(err ** 2)) * DEG,
            "max": np.max(np.abs(err)) * DEG, "std_med": np.median(std) * DEG, "std_max": np.max(std) * DEG,
            "cov3": inside.mean(), "err_over_std_p99": np.percentile(np.abs(err) / np.maximum(std, 1e-9), 99),
            "inv_std": (~valid & over).mean(), "inv_other": (~valid & ~over).mean(),
            "inv_small_err": (~valid & (np.abs(err) < math.radians(0.5))).mean(),
            "vel_invalid": (~d["vel_valid"][sel]).mean()}


def invalid_runs(d: dict, conv: np.ndarray, min_s: float = 0.3) -> list[tuple]:
    """(start, end, mean |ay| of the truth, max |error| deg, median std deg) of every run of invalid
    rows above 5 m/s at least ``min_s`` long (times from the drive's start)."""
    bad = conv & (d["speed"] > 5.0) & ~d["valid"]
    edges = np.flatnonzero(np.diff(np.concatenate(([0], bad.astype(int), [0]))))
    out = []
    for i0, i1 in zip(edges[::2], edges[1::2]):
        t = d["t"]
        if t[i1 - 1] - t[i0] < min_s:
            continue
        sl = slice(i0, i1)
        out.append((t[i0] - d["t0"], t[i1 - 1] - d["t0"], float(np.mean(np.abs(d["ay_true"][sl]))),
                    float(np.max(np.abs(d["err"][sl]))) * DEG, float(np.median(d["std"][sl])) * DEG))
    return out


def _fmt(name: str, s: dict) -> str:
    if s["n"] == 0:
        return f"{name:>14}  (no rows above 5 m/s)"
    return (f"{name:>14} n={s['n']:5d} valid={s['valid']:5.1%} rms={s['rms']:.3f} max={s['max']:.3f} "
            f"std med={s['std_med']:.3f} max={s['std_max']:.3f} cov3={s['cov3']:6.1%} "
            f"|e|/std p99={s['err_over_std_p99']:.2f} invalid: std>thr {s['inv_std']:5.1%} "
            f"other {s['inv_other']:5.1%} (|e|<0.5deg {s['inv_small_err']:5.1%}) vel-inv {s['vel_invalid']:5.1%}")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("case_dir", type=Path, nargs="+")
    ap.add_argument("--window", type=float, default=2.0, help="seconds per printed window")
    ap.add_argument("--summary", action="store_true", help="only the before / during / after phases")
    ap.add_argument("--settle", type=float, default=10.0, help="seconds from the start left out (as the suite)")
    a = ap.parse_args(argv)
    for case in a.case_dir:
        d = load(case)
        t = d["t"]
        o0, o1 = d["out"]
        conv = t >= d["t0"] + a.settle
        print(f"== {case.name}: outage {o0 - d['t0']:.1f}-{o1 - d['t0']:.1f} s after start "
              f"(threshold std {SIDESLIP_STD_VALID * DEG:.3f} deg)")
        print(_fmt("all", phase_stats(d, conv)))
        print(_fmt("before", phase_stats(d, conv & (t < o0))))
        print(_fmt("during", phase_stats(d, conv & (t >= o0) & (t <= o1))))
        print(_fmt("after 0-10s", phase_stats(d, (t > o1) & (t <= o1 + 10.0))))
        print(_fmt("after >10s", phase_stats(d, t > o1 + 10.0)))
        after = (t > o1) & d["valid"] & (d["speed"] > 5.0)
        if after.any():
            print(f"{'':>14} first valid row after the outage: +{t[after][0] - o1:.2f} s")
        for r0, r1, ay, emax, smed in invalid_runs(d, conv):
            r0a = r0 + d["t0"]
            where = "during" if o0 <= r0a <= o1 else ("after" if r0a > o1 else "before")
            print(f"{'':>14} invalid {r0:5.1f}-{r1:5.1f} s ({where:>6}): |ay| {ay:4.1f} m/s^2, "
                  f"max |error| {emax:.2f} deg, median std {smed:.2f} deg")
        if a.summary:
            continue
        w0 = d["t0"] + a.settle
        while w0 < t[-1]:
            sel = conv & (t >= w0) & (t < w0 + a.window)
            tag = "OUT" if (w0 + a.window > o0 and w0 < o1) else ""
            s = phase_stats(d, sel)
            if s["n"]:
                print(_fmt(f"{w0 - d['t0']:5.1f}s {tag}", s) + f" |ay|={np.mean(np.abs(d['ay_true'][sel])):.1f}")
            w0 += a.window


if __name__ == "__main__":
    main()
