"""``ecu-daemon evaluate``: score a replay's estimate CSV against the simulator's ``truth.csv``.

Truth is interpolated onto the estimate times (heading unwrapped first, errors wrapped to
[-pi, pi)). The first ``settle_s`` seconds of the estimate are excluded from every statistic
(filters converge). Accelerometer biases are compared with ``accel_*_bias_eff_mps2`` when the
truth has it: what the sensor reads standing still on that road (bias plus gravity via bank,
grade and the body roll the bank causes), which is what a bias state can observe (see
``Estimate.accel_y_bias_mps2``).

Per quantity: RMS, max |error| and mean error over all rows after settling; RMS over the rows
the estimate flags valid, and the fraction valid. Biases and the GNSS delay also get the final
value and its (relative) error. Sideslip additionally reports how often |error| <= 2 sigma.

Honest validity (:func:`validity_metrics`, per quantity with a std column): a valid flag is a
promise, so these look at the WHOLE drive, settling included: coverage (fraction of valid rows
with |error| <= 1/2/3 reported sigma), the count of valid rows beyond 3 sigma, the worst error
while valid, the time to the first valid row (from the drive's start and from the first good GNSS
fix above 5 m/s, i.e. the first row where the truth's ``gnss_good`` column marks a good fix
received while the car moves faster than 5 m/s; without that column, the first row above 5 m/s
plus the GNSS delay), and the valid fraction overall and on the rows above 5 m/s from 3 s after
that fix (the convergence the targets allow).
"""
from __future__ import annotations

import argparse
import csv
import json
import math
import sys
from pathlib import Path

import numpy as np

from .plots import wrap

TRUTH_REQUIRED = ("t", "sideslip_rad", "heading_rad", "vx_mps", "vy_mps", "yaw_rate_bias_radps",
                  "accel_x_bias_mps2", "accel_y_bias_mps2", "gnss_delay_s")
ESTIMATE_REQUIRED = ("t", "sideslip_rad", "sideslip_std_rad", "heading_rad", "heading_std_rad", "vx_mps",
                     "vy_mps", "yaw_rate_bias_radps", "accel_x_bias_mps2", "accel_y_bias_mps2",
                     "gnss_delay_s", "sideslip_valid", "heading_valid")

#: quantity -> (truth column, estimate column, validity column or None, display unit, display factor)
SIGNALS = {
    "sideslip": ("sideslip_rad", "sideslip_rad", "sideslip_valid", "deg", 180 / math.pi),
    "heading": ("heading_rad", "heading_rad", "heading_valid", "deg", 180 / math.pi),
    "vx": ("vx_mps", "vx_mps", "velocity_valid", "m/s", 1.0),
    "vy": ("vy_mps", "vy_mps", "velocity_valid", "m/s", 1.0),
}
#: road and body attitude (issue 11): scored like SIGNALS where both files have the columns
ROAD_SIGNALS = {
    "bank": ("bank_rad", "bank_rad", "bank_valid", "deg", 180 / math.pi),
    "grade": ("grade_rad", "grade_rad", "grade_valid", "deg", 180 / math.pi),
    "roll": ("roll_rad", "roll_rad", "roll_valid", "deg", 180 / math.pi),
}
#: quantity -> the estimate's reported 1-sigma column (validity metrics need it)
STD_COLUMNS = {"sideslip": "sideslip_std_rad", "heading": "heading_std_rad", "vx": "vx_std_mps",
               "vy": "vy_std_mps", "bank": "bank_std_rad", "grade": "grade_std_rad", "roll": "roll_std_rad"}
VALID_SPEED_MPS = 5.0  # rows above this speed are where sideslip and heading must be valid
CONVERGE_S = 3.0  # time after the first good fix above VALID_SPEED_MPS the targets allow
#: bias-like quantities: (truth column(s) in order of preference, estimate column, unit, factor)
BIASES = {
    "yaw_rate_bias": (("yaw_rate_bias_radps",), "yaw_rate_bias_radps", "deg/s", 180 / math.pi),
    "accel_x_bias": (("accel_x_bias_eff_mps2", "accel_x_bias_mps2"), "accel_x_bias_mps2", "m/s^2", 1.0),
    "accel_y_bias": (("accel_y_bias_eff_mps2", "accel_y_bias_mps2"), "accel_y_bias_mps2", "m/s^2", 1.0),
    "gnss_delay": (("gnss_delay_s",), "gnss_delay_s", "s", 1.0),
    "wheel_scale": (("wheel_scale",), "wheel_scale", "", 1.0),
    "steering_offset": (("steering_offset_rad",), "steering_offset_rad", "deg", 180 / math.pi),
    "cornering_stiffness_front": (("cornering_stiffness_front_n_per_rad",),
                                  "cornering_stiffness_front_n_per_rad", "kN/rad", 1e-3),
    "cornering_stiffness_rear": (("cornering_stiffness_rear_n_per_rad",),
                                 "cornering_stiffness_rear_n_per_rad", "kN/rad", 1e-3),
}


class EvaluationError(ValueError):
    """An unusable input file, described in one line."""


_BOOL = {"true": 1.0, "false": 0.0, "1": 1.0, "0": 0.0, "1.0": 1.0, "0.0": 0.0}


def read_csv(path: str | Path, required: tuple[str, ...], what: str) -> dict[str, np.ndarray]:
    """Columns of a header-first CSV as float arrays (booleans True/False -> 1/0)."""
    p = Path(path)
    try:
        f = open(p, newline="", encoding="utf-8")
    except OSError as e:
        raise EvaluationError(f"cannot read {what} {p}: {e.strerror or e}") from None
    with f:
        try:
            reader = csv.reader(f)
            header = next(reader, None)
            if header is None:
                raise EvaluationError(f"{what} {p} is empty")
            header = [h.strip() for h in header]
            missing = [c for c in required if c not in header]
            if missing:
                raise EvaluationError(f"{what} {p}: missing column(s) {', '.join(missing)}")
            rows = list(reader)
        except UnicodeDecodeError:
            raise EvaluationError(f"{what} {p} is not UTF-8 text") from None
        except csv.Error as e:
            raise EvaluationError(f"{what} {p}: not a CSV file: {e}") from None
    rows = [r for r in rows if r and any(c.strip() for c in r)]
    if not rows:
        raise EvaluationError(f"{what} {p} has a header but no data rows")
    short = next((i for i, r in enumerate(rows) if len(r) < len(header)), None)
    if short is not None:
        raise EvaluationError(f"{what} {p}:{short + 2}: {len(rows[short])} fields, the header has {len(header)}")
    cols: dict[str, np.ndarray] = {}
    # one transpose, then Python's float() per cell: numpy's own parse of a list of str was 0.67 of
    # 1.5 s on a 7500-row estimate (float() takes the padding a strip would remove)
    for name, column in zip(header, zip(*rows)):
        try:
            cols[name] = np.fromiter(map(float, column), dtype=float, count=len(column))
            continue
        except ValueError:
            pass
        cells = [c.strip() for c in column]
        out = np.empty(len(rows))
        for i, cell in enumerate(cells):
            try:
                out[i] = float(cell)
            except ValueError:
                b = _BOOL.get(cell.lower())
                if b is not None:
                    out[i] = b
                elif name in required:
                    raise EvaluationError(f"{what} {p}:{i + 2}: column {name}: {cell!r} is not a number") from None
                else:
                    out[i] = math.nan
        cols[name] = out
    t = cols["t"]
    if not np.all(np.isfinite(t)):
        raise EvaluationError(f"{what} {p}: column t has non-finite values")
    if np.any(np.diff(t) < 0):
        raise EvaluationError(f"{what} {p}: column t is not in time order")
    return cols


def same_time_rows(truth: dict, est: dict) -> tuple[np.ndarray, np.ndarray]:
    """Row indices (truth, estimate) where both files have a row at the same t: the offline tools'
    row-by-row join (a replay of a simulated drive writes its estimate on the truth's grid), where
    :func:`evaluate` interpolates the truth instead."""
    _, ti, ei = np.intersect1d(truth["t"], est["t"], assume_unique=False, return_indices=True)
    return ti, ei


def _stats(err: np.ndarray) -> dict:
    err = err[np.isfinite(err)]
    if len(err) == 0:
        return {"rms": math.nan, "max_abs": math.nan, "mean": math.nan}
    return {"rms": float(np.sqrt(np.mean(err ** 2))), "max_abs": float(np.max(np.abs(err))),
            "mean": float(np.mean(err))}


def validity_metrics(t: np.ndarray, err: np.ndarray, std: np.ndarray, valid: np.ndarray,
                     speed: np.ndarray, t_start: float, t_fix: float) -> dict:
    """Honesty of one quantity's valid flag and std (see the module doc); arrays share rows.

    ``t_fix``: time of the first good GNSS fix above 5 m/s (NaN: none). Times to valid are NaN
    when the flag never comes; coverage is NaN without valid rows.
    """
    valid = valid.astype(bool)
    a = np.abs(err[valid])
    s = std[valid]
    n = int(valid.sum())
    out: dict = {"valid_rows": n}
    for k in (1, 2, 3):
        out[f"coverage_{k}sigma"] = float(np.mean(a <= k * s)) if n else math.nan
    out["valid_beyond_3sigma"] = int(np.sum(~(a <= 3 * s)))
    out["worst_error_valid"] = float(np.max(a)) if n else math.nan
    first = t[valid][0] if n else math.nan
    out["time_to_valid_s"] = float(first - t_start)
    out["time_to_valid_after_fix_s"] = math.nan
    if math.isfinite(t_fix):
        i = int(np.searchsorted(t, t_fix))
        if i > 0 and valid[i - 1]:
            out["time_to_valid_after_fix_s"] = 0.0  # already valid when the fix came
        elif valid[i:].any():
            out["time_to_valid_after_fix_s"] = float(t[i:][valid[i:]][0] - t_fix)
    out["valid_fraction"] = float(valid.mean()) if len(valid) else math.nan
    fast = speed > VALID_SPEED_MPS
    if math.isfinite(t_fix):
        fast &= t >= t_fix + CONVERGE_S
    out["valid_fraction_above_5mps"] = float(valid[fast].mean()) if fast.any() else math.nan
    return out


def first_good_fix(truth: dict) -> float:
    """Time the first good GNSS fix above 5 m/s reached the receiver's host (NaN: never)."""
    tt = truth["t"]
    speed = truth["speed_mps"] if "speed_mps" in truth else np.hypot(truth["vx_mps"], truth["vy_mps"])
    if "gnss_good" in truth:
        ok = (truth["gnss_good"] > 0.5) & (speed > VALID_SPEED_MPS)
        return float(tt[ok][0]) if ok.any() else math.nan
    ok = speed > VALID_SPEED_MPS
    return float(tt[ok][0] + truth["gnss_delay_s"][ok][0]) if ok.any() else math.nan


def evaluate(truth_csv: str | Path, estimate_csv: str | Path, settle_s: float = 10.0) -> dict:
    """Error statistics of an estimate CSV against a truth CSV (see module doc); SI units."""
    truth = read_csv(truth_csv, TRUTH_REQUIRED, "truth CSV")
    est = read_csv(estimate_csv, ESTIMATE_REQUIRED, "estimate CSV")
    return _evaluate(truth, est, settle_s)


def _evaluate(truth: dict, est: dict, settle_s: float) -> dict:
    tt, te = truth["t"], est["t"]
    lo, hi = max(tt[0], te[0] + settle_s), tt[-1]
    sel = (te >= lo) & (te <= hi)
    if not np.any(sel):
        raise EvaluationError(f"no estimate rows inside the truth time span {tt[0]:.3f}..{tt[-1]:.3f} s"
                              f" after settling ({settle_s:g} s); estimate spans {te[0]:.3f}..{te[-1]:.3f} s")
    t = te[sel]
    span = (te >= tt[0]) & (te <= hi)  # the whole drive, for the validity metrics
    t_all = te[span]
    t_fix = first_good_fix(truth)
    speed = np.interp(t_all, tt, truth["speed_mps"] if "speed_mps" in truth
                      else np.hypot(truth["vx_mps"], truth["vy_mps"]))
    out: dict = {"rows": int(sel.sum()), "t_start": float(t[0]), "t_end": float(t[-1]), "settle_s": settle_s,
                 "drive_start": float(t_all[0]), "first_good_fix_above_5mps": t_fix}
    road = {n: v for n, v in ROAD_SIGNALS.items() if v[0] in truth and v[1] in est}
    for name, (tc, ec, vc, _, _) in {**SIGNALS, **road}.items():
        if name in ("heading", "sideslip"):  # angles: +-180 deg apart is 0 (heading north, reversing)
            ref = np.interp(t_all, tt, np.unwrap(truth[tc]))
            err_all = wrap(est[ec][span] - ref)
        else:
            ref = np.interp(t_all, tt, truth[tc])
            err_all = est[ec][span] - ref
        err = err_all[sel[span]]
        s = _stats(err)
        fast = speed[sel[span]] > VALID_SPEED_MPS
        s["rms_above_5mps"] = _stats(err[fast])["rms"] if fast.any() else math.nan
        sc = STD_COLUMNS.get(name)
        if vc in est and sc in est:
            s["validity"] = validity_metrics(t_all, err_all, est[sc][span], est[vc][span] > 0.5, speed,
                                             float(t_all[0]), t_fix)
        if vc in est:
            valid = est[vc][sel] > 0.5
            s["fraction_valid"] = float(valid.mean())
            s["rms_valid"] = _stats(err[valid])["rms"] if valid.any() else math.nan
            s["max_abs_valid"] = _stats(err[valid])["max_abs"] if valid.any() else math.nan
        std_col = ec.replace("_rad", "_std_rad") if name in ("sideslip", "heading") else None
        if std_col and std_col in est:
            std = est[std_col][sel]
            s["within_2sigma"] = float(np.mean(np.abs(err) <= 2 * std))
        out[name] = s
        out[name]["_err"] = err
    for name, (tcs, ec, _, _) in BIASES.items():
        tc = next((c for c in tcs if c in truth), None)
        if tc is None or ec not in est:
            continue
        ref = np.interp(t, tt, truth[tc])
        err = est[ec][sel] - ref
        s = _stats(err)
        final_truth = float(ref[-1])
        final = float(est[ec][sel][-1])
        s.update(final=final, truth=final_truth, final_error=final - final_truth,
                 relative_error=abs(final - final_truth) / abs(final_truth) if final_truth else math.nan)
        s["_err"] = err
        out[name] = s
    out["_t"] = t
    return out


def public(result: dict) -> dict:
    """``result`` without the per-row error arrays, NaN as None: strict JSON for other programs."""
    def clean(v):
        if isinstance(v, dict):
            return public(v)
        return None if isinstance(v, float) and not math.isfinite(v) else v

    return {k: clean(v) for k, v in result.items() if not k.startswith("_")}


def format_table(result: dict) -> str:
    lines = [f"{result['rows']} estimate rows, {result['t_start']:.3f}..{result['t_end']:.3f} s"
             f" (first {result['settle_s']:g} s excluded)",
             f"{'quantity':<26}{'unit':>7}{'rms':>10}{'max':>10}{'mean':>10}{'rms@valid':>11}{'valid':>7}"
             f"{'in 2sig':>8}"]
    shown = {**SIGNALS, **{n: v for n, v in ROAD_SIGNALS.items() if n in result}}
    for name, (_, _, _, unit, k) in shown.items():
        s = result[name]
        rv = s.get("rms_valid", math.nan)
        fv = s.get("fraction_valid", math.nan)
        w2 = s.get("within_2sigma")
        rv_s = f"{rv * k:.3f}" if rv == rv else "-"
        fv_s = f"{fv * 100:.0f}%" if fv == fv else "-"
        lines.append(f"{name:<26}{unit:>7}{s['rms'] * k:>10.3f}{s['max_abs'] * k:>10.3f}{s['mean'] * k:>10.3f}"
                     f"{rv_s:>11}{fv_s:>7}" + (f"{w2 * 100:>7.0f}%" if w2 is not None else ""))
    lines.append(f"validity over the whole drive (first good GNSS fix above {VALID_SPEED_MPS:g} m/s at "
                 + (f"{result['first_good_fix_above_5mps'] - result['drive_start']:.2f} s)"
                    if math.isfinite(result["first_good_fix_above_5mps"]) else "none)"))
    lines.append(f"{'quantity':<12}{'in 1sig':>8}{'in 2sig':>8}{'in 3sig':>8}{'>3sig':>7}{'worst@valid':>12}"
                 f"{'t valid':>8}{'after fix':>10}{'valid':>7}{'>5m/s':>7}")
    pct = lambda v: f"{v * 100:.1f}%" if v == v else "-"  # noqa: E731
    num = lambda v, k=1.0: f"{v * k:.3g}" if v == v else "-"  # noqa: E731
    for name, (_, _, _, unit, k) in shown.items():
        v = result[name].get("validity")
        if v is None:
            continue
        lines.append(f"{name:<12}{pct(v['coverage_1sigma']):>8}{pct(v['coverage_2sigma']):>8}"
                     f"{pct(v['coverage_3sigma']):>8}{v['valid_beyond_3sigma']:>7}"
                     f"{num(v['worst_error_valid'], k) + ' ' + unit:>12}{num(v['time_to_valid_s']):>8}"
                     f"{num(v['time_to_valid_after_fix_s']):>10}{pct(v['valid_fraction']):>7}"
                     f"{pct(v['valid_fraction_above_5mps']):>7}")
    lines.append(f"{'bias / parameter':<26}{'unit':>7}{'final':>10}{'truth':>10}{'error':>10}{'rel err':>11}"
                 f"{'rms':>8}")
    for name, (_, _, unit, k) in BIASES.items():
        s = result.get(name)
        if s is None:
            continue
        rel = s["relative_error"]
        lines.append(f"{name:<26}{unit:>7}{s['final'] * k:>10.4g}{s['truth'] * k:>10.4g}"
                     f"{s['final_error'] * k:>10.3g}{(f'{rel * 100:.1f}%' if rel == rel else '-'):>11}"
                     f"{s['rms'] * k:>8.3g}")
    return "\n".join(lines)


def plot(truth_csv: str | Path, estimate_csv: str | Path, out_dir: str | Path) -> list[Path]:
    """PNG plots of estimate vs truth over time; returns the files written."""
    from .plots import write_plots

    return write_plots(read_csv(estimate_csv, ESTIMATE_REQUIRED, "estimate CSV"), out_dir,
                       truth=read_csv(truth_csv, TRUTH_REQUIRED, "truth CSV"))


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--truth", help="truth.csv from 'ecu-daemon simulate'")
    parser.add_argument("--estimate", help="estimate CSV from 'ecu-daemon replay'")
    parser.add_argument("--suite", action="store_true",
                        help="simulate, replay and score the scenario suite; one table, exit 1 if a target fails")
    parser.add_argument("--only", metavar="PATTERN",
                        help="--suite: only scenarios whose name or family matches (globs, comma-separated)")
    parser.add_argument("--jobs", type=int, default=0, help="--suite: parallel scenarios (default: CPU count)")
    parser.add_argument("--out", metavar="DIR", help="--suite: folder for every scenario's files (default out/suite)")
    parser.add_argument("--plots", metavar="DIR", help="write PNG plots into DIR")
    parser.add_argument("--settle-s", type=float, default=10.0,
                        help="seconds at the start of the estimate left out of the statistics (default 10)")
    parser.add_argument("--json", action="store_true", help="print the statistics as JSON instead of a table")


def main(args: argparse.Namespace) -> int:
    from .errors import UserError

    if args.suite:
        from .suite import main as suite_main

        if args.truth or args.estimate or args.plots:
            raise UserError("--suite makes its own drives: give it without --truth, --estimate, --plots")
        if args.jobs < 0:
            raise UserError(f"--jobs must be >= 1, got {args.jobs}")
        return suite_main(args)
    if not (args.truth and args.estimate):
        raise UserError("give --truth and --estimate (or --suite)")
    if not (args.settle_s >= 0 and math.isfinite(args.settle_s)):
        raise UserError(f"--settle-s must be >= 0, got {args.settle_s}")
    try:
        result = evaluate(args.truth, args.estimate, settle_s=args.settle_s)
        files = plot(args.truth, args.estimate, args.plots) if args.plots else []
    except EvaluationError as e:
        raise UserError(str(e)) from None
    except OSError as e:
        raise UserError(f"cannot write plots to {args.plots}: {e.strerror or e}") from None
    if args.json:
        json.dump(public(result), sys.stdout, indent=2, allow_nan=False)
        sys.stdout.write("\n")
    else:
        print(format_table(result))
        for f in files:
            print(f"wrote {f}")
    return 0
