"""``ecu-daemon evaluate --suite``: simulate, replay and score the scenario suite in one table.

Every case goes through the same code as the commands a user runs: ``simulate`` writes the
drive's files, :func:`ecu_daemon.replay.run_replay` (``ecu-daemon replay``) estimates from them
with the ``config.toml`` written beside them, :func:`ecu_daemon.evaluate.evaluate` scores, and
the plain single-track observer (:mod:`ecu_daemon.baseline`) runs on the same CAN log. A restart
case is two replays, the second starting from the state file the first one saved (as the
daemon's ``[daemon] state_file``), and is scored from the restart on.

Targets (issue 7), each a short code in the table when it fails:

* ``cov-b`` / ``cov-h`` / ``cov-v``: valid sideslip / heading / vx rows within 3 reported sigma >= 99 %
  (a valid flag is a promise, ``velocity_valid`` too);
* ``worst-b`` / ``worst-h``: worst error while valid <= 2 deg (sideslip) / 5 deg (heading);
* ``avail-b``: sideslip valid on >= 90 % of the rows above 5 m/s once converged;
* ``ttv-b`` / ``ttv-h``: valid within 3 s of the first good GNSS fix above 5 m/s;
* ``lat``: final GNSS latency estimate within 0.03 s of the truth;
* ``rms-b`` (low-speed cases only): sideslip RMS <= 0.30 deg and <= 0.6 x the single-track observer.

Issue 11 (more aiding sources), per family:

* ``dual_antenna`` (moving-base pair, 1.2 m baseline): ``rms-h`` heading RMS <= 0.15 deg over every
  row after settling, standstill included; ``rms-b5`` sideslip RMS above 5 m/s <= 0.1 deg.
* ``two_receivers`` (front and rear, 2.5 m apart, 5 Hz, 0.4 / 0.33 s latency): turning cases
  ``rms2-b`` sideslip RMS <= 0.15 deg, ``rms2-h`` heading RMS <= 0.2 deg; the straight case
  ``vs1-b`` / ``vs1-h`` no worse than the same drive with the first receiver only (within 5 % +
  0.005 deg: the two runs share every other noise); every case ``lat2`` the second receiver's own
  latency identified within 0.03 s.
* ``magnetometer`` (a magnetometer on CAN with magnetic disturbances, GNSS outages): ``rms-m``
  heading RMS <= 1 deg from 5 s after the heading first became valid; ``jump-m`` no disturbance
  moves the heading error by more than 2 deg (from its start to 5 s after its end). The same
  drive is also replayed without the magnetometer mapped (``no mag`` columns of the row) to show
  what it holds.
* every case: ``cov-r`` valid bank / grade / roll rows within 3 reported sigma >= 99 %; ``road``
  cases on a graded / banked road: ``rms-g`` / ``rms-k`` grade / bank RMS <= 0.5 deg.
"""
from __future__ import annotations

import dataclasses
import fnmatch
import json
import logging
import math
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from . import config as config_mod
from .baseline import single_track_sideslip
from .evaluate import TRUTH_REQUIRED, ESTIMATE_REQUIRED, _evaluate, public, read_csv
from .plots import wrap
from .sim.suite import SUITE, SuiteCase

DEG = 180.0 / math.pi
SETTLE_S = 10.0
TARGETS = {
    "coverage_3sigma": 0.99,
    "worst_sideslip_deg": 2.0,
    "worst_heading_deg": 5.0,
    "sideslip_valid_above_5mps": 0.90,
    "time_to_valid_after_fix_s": 3.0,
    "latency_error_s": 0.03,
    "low_speed_sideslip_rms_deg": 0.30,
    "low_speed_ratio_to_baseline": 0.6,
    "dual_antenna_heading_rms_deg": 0.15,
    "dual_antenna_sideslip_rms_above_5mps_deg": 0.1,
    "two_receivers_sideslip_rms_deg": 0.15,
    "two_receivers_heading_rms_deg": 0.2,
    "magnetometer_heading_rms_deg": 1.0,
    "magnetometer_jump_deg": 2.0,
    "road_angle_rms_deg": 0.5,
}


def encoding_config(encoding: str) -> config_mod.Config:
    """The DBC + ``[inputs.*]`` mapping a case's car uses ("" = ours)."""
    if not encoding:
        return config_mod.Config()
    if encoding == "vw_mqb":
        return config_mod.load(config_mod.find_data_file("examples/vw_mqb.toml"))
    raise ValueError(f"unknown suite encoding {encoding!r}")


def select(pattern: str | None, cases: list[SuiteCase] = SUITE) -> list[SuiteCase]:
    """Cases whose name or family matches any comma-separated glob (a bare word matches as a substring)."""
    if not pattern:
        return list(cases)
    pats = [p if any(c in p for c in "*?[") else f"*{p}*" for p in pattern.split(",") if p]
    return [c for c in cases if any(fnmatch.fnmatchcase(c.name, p) or fnmatch.fnmatchcase(c.family, p)
                                    for p in pats)]


def _split(result, t_cut: float):
    """Two SimResults: frames and GNSS messages received before ``t_cut``, and from it on."""
    a = dataclasses.replace(result, can_frames=[f for f in result.can_frames if f[0] < t_cut],
                            gnss_messages=[m for m in result.gnss_messages if m[0] < t_cut])
    b = dataclasses.replace(result, can_frames=[f for f in result.can_frames if f[0] >= t_cut],
                            gnss_messages=[m for m in result.gnss_messages if m[0] >= t_cut])
    return a, b


def _baseline_rms(cfg, can_path: Path, truth: dict, t_from: float) -> float:
    rows = np.array(list(single_track_sideslip(cfg, str(can_path))), dtype=float).reshape(-1, 2)
    t, beta = rows[:, 0], rows[:, 1]
    sel = (t >= t_from) & (t <= truth["t"][-1]) & np.isfinite(beta)
    if not sel.any():
        return math.nan
    err = wrap(beta[sel] - np.interp(t[sel], truth["t"], truth["sideslip_rad"]))
    return float(np.sqrt(np.mean(err ** 2)))


class _replay_tables_at_debug:
    """A suite replays each case two to four times; each replay's per-input table (nine INFO
    lines) would bury the one line per case the suite prints. The tables stay visible with
    ``--log-level debug``; the replay's warnings and errors are not touched."""

    def __enter__(self):
        self.log = logging.getLogger("ecu_daemon.replay")
        self.level = self.log.level
        if not self.log.isEnabledFor(logging.DEBUG):
            self.log.setLevel(logging.WARNING)

    def __exit__(self, *exc):
        self.log.setLevel(self.level)
        return False


def run_case(case: SuiteCase, out_dir: str | Path) -> dict:
    """:func:`score_case`, or a row that says in one line why the case could not run (the suite goes on)."""
    started = time.perf_counter()
    try:
        with _replay_tables_at_debug():
            return score_case(case, out_dir)
    except Exception as e:  # noqa: BLE001 - one broken case must not hide the other rows
        row = {key: math.nan for _, key, _ in COLUMNS}
        row.update(scenario=case.name, family=case.family, has_fix=False, spun_out=False,
                   wall_s=time.perf_counter() - started,
                   failed=[f"error: {e.__class__.__name__}: {str(e).splitlines()[0] if str(e) else ''}"])
        return row


def score_case(case: SuiteCase, out_dir: str | Path) -> dict:
    """Simulate, replay, evaluate one case; returns its table row (SI, plus the failed targets)."""
    from .io.state_store import load_state, save_state
    from .replay import run_replay
    from .sim import writer
    from .sim.run import simulate, vehicle_config

    started = time.perf_counter()
    d = Path(out_dir) / case.name
    sc = case.scenario
    cfg = vehicle_config(sc, encoding_config(case.encoding))
    result = simulate(sc, cfg)
    paths = writer.write_all(d, result, cfg)
    replay_cfg = config_mod.load(paths["config"])  # what `ecu-daemon replay --config` reads
    truth = read_csv(paths["truth"], TRUTH_REQUIRED, "truth CSV")
    can, gnss = paths["can"], paths["gnss"]
    learned = None
    if case.restart_at_s is not None:
        t_cut = result.t0 + case.restart_at_s
        first, second = _split(result, t_cut)
        can_a, gnss_a = d / "drive_before_restart.log", d / "drive_before_restart_gnss.log"
        can, gnss = d / "drive_after_restart.log", d / "drive_after_restart_gnss.log"
        writer.write_can_log(can_a, first)
        writer.write_gnss_log(gnss_a, first)
        writer.write_can_log(can, second)
        writer.write_gnss_log(gnss, second)
        summary = run_replay(replay_cfg, str(can_a), str(gnss_a), str(d / "estimate_before_restart.csv"))
        save_state(d / "state.json", summary["learned"])
        learned = load_state(d / "state.json")
        truth = {k: v[truth["t"] >= t_cut] for k, v in truth.items()}
    est_csv = d / "estimate.csv"
    captures = [str(gnss)] + ([str(paths["gnss2"])] if "gnss2" in paths and case.restart_at_s is None else [])
    replayed = run_replay(replay_cfg, str(can), captures, str(est_csv), learned=learned)
    est = read_csv(est_csv, ESTIMATE_REQUIRED, "estimate CSV")
    r = _evaluate(truth, est, SETTLE_S)
    base = _baseline_rms(replay_cfg, can, truth, float(est["t"][0]) + SETTLE_S)
    extra = {}
    if sc.gnss2 is not None:
        extra["latency2_error_s"] = replayed["learned"]["gnss_delay_s_1"] - sc.gnss2.latency_s
    if case.compare_single:  # the same drive and noise, the second receiver's capture left out
        one_cfg = config_mod.load(paths["config"])
        one_cfg.gnss.receiver = one_cfg.gnss.receiver[:1]
        run_replay(one_cfg, str(can), [str(gnss)], str(d / "estimate_one_receiver.csv"), learned=learned)
        r1 = _evaluate(truth, read_csv(d / "estimate_one_receiver.csv", ESTIMATE_REQUIRED, "estimate CSV"), SETTLE_S)
        extra.update(single_sideslip_rms_deg=r1["sideslip"]["rms"] * DEG, single_heading_rms_deg=r1["heading"]["rms"] * DEG)
    if sc.sensors.magnetometer is not None:
        extra.update(_magnetometer_figures(sc, truth, est))
        no_cfg = config_mod.load(paths["config"])
        for n in ("mag_x", "mag_y", "mag_z"):
            no_cfg.inputs.pop(n, None)
        run_replay(no_cfg, str(can), captures, str(d / "estimate_no_magnetometer.csv"), learned=learned)
        no = _magnetometer_figures(sc, truth, read_csv(d / "estimate_no_magnetometer.csv", ESTIMATE_REQUIRED,
                                                         "estimate CSV"))
        extra.update({f"no_{k}": v for k, v in no.items()})
    row = summarise(case, r, base, extra)
    row["wall_s"] = time.perf_counter() - started
    row["spun_out"] = result.spun_out
    (d / "evaluation.json").write_text(json.dumps({"row": public(row), "evaluation": public(r)}, indent=1,
                                                  allow_nan=False) + "\n")
    return row


def _magnetometer_figures(sc, truth: dict, est: dict) -> dict:
    """Heading RMS from 5 s after the heading first became valid, and the largest change of the
    heading error over any magnetic disturbance (from its start to 5 s after its end)."""
    t = est["t"]
    err = wrap(est["heading_rad"] - np.interp(t, truth["t"], np.unwrap(truth["heading_rad"])))
    valid = est["heading_valid"] > 0.5
    if not valid.any():
        return {"mag_heading_rms_deg": math.nan, "mag_jump_deg": math.nan}
    sel = t >= t[np.argmax(valid)] + 5.0
    t0 = float(truth["t"][0])
    jump = 0.0
    for ev in sc.sensors.magnetometer.events:
        a = t0 + ev.t_rel
        w = (t >= a) & (t <= a + ev.duration_s + 5.0)
        if w.any():
            e0 = err[np.argmax(w)]
            jump = max(jump, float(np.max(np.abs(wrap(err[w] - e0)))))
    return {"mag_heading_rms_deg": float(np.sqrt(np.mean(err[sel] ** 2))) * DEG, "mag_jump_deg": jump * DEG}


def summarise(case: SuiteCase, r: dict, baseline_rms: float, extra: dict | None = None) -> dict:
    """One table row from an evaluation (see :func:`ecu_daemon.evaluate.evaluate`); ``extra``: the
    two-receiver figures (second latency, the single-receiver comparison), NaN when absent."""
    b, h = r["sideslip"], r["heading"]
    bv, hv, vv = b.get("validity", {}), h.get("validity", {}), r["vx"].get("validity", {})
    g = lambda d, k: d.get(k, math.nan)  # noqa: E731
    row = {
        "scenario": case.name, "family": case.family,
        "sideslip_rms_deg": b["rms"] * DEG, "heading_rms_deg": h["rms"] * DEG,
        "sideslip_rms_above_5mps_deg": b.get("rms_above_5mps", math.nan) * DEG,
        "baseline_sideslip_rms_deg": baseline_rms * DEG,
        "ratio_to_baseline": b["rms"] / baseline_rms if baseline_rms > 0 else math.nan,
        "sideslip_valid_above_5mps": g(bv, "valid_fraction_above_5mps"),
        "heading_valid_above_5mps": g(hv, "valid_fraction_above_5mps"),
        "sideslip_coverage_3sigma": g(bv, "coverage_3sigma"), "heading_coverage_3sigma": g(hv, "coverage_3sigma"),
        "vx_coverage_3sigma": g(vv, "coverage_3sigma"), "vx_worst_valid_mps": g(vv, "worst_error_valid"),
        "sideslip_worst_valid_deg": g(bv, "worst_error_valid") * DEG,
        "heading_worst_valid_deg": g(hv, "worst_error_valid") * DEG,
        "sideslip_time_to_valid_after_fix_s": g(bv, "time_to_valid_after_fix_s"),
        "heading_time_to_valid_after_fix_s": g(hv, "time_to_valid_after_fix_s"),
        "latency_error_s": r["gnss_delay"]["final_error"] if "gnss_delay" in r else math.nan,
        "has_fix": math.isfinite(r["first_good_fix_above_5mps"]),
        "latency2_error_s": math.nan, "single_sideslip_rms_deg": math.nan, "single_heading_rms_deg": math.nan,
        "mag_heading_rms_deg": math.nan, "mag_jump_deg": math.nan,
        "no_mag_heading_rms_deg": math.nan, "no_mag_jump_deg": math.nan,
        **(extra or {}),
        **_road_figures(r),
    }
    row["failed"] = failed_targets(row, case)
    return row


def _road_figures(r: dict) -> dict:
    """Bank / grade / roll RMS (deg) and the worst of their 3-sigma coverages (NaN: never valid)."""
    out = {f"{q}_rms_deg": r[q]["rms"] * DEG if q in r else math.nan for q in ("bank", "grade", "roll")}
    cov = [r[q]["validity"]["coverage_3sigma"] for q in ("bank", "grade", "roll") if "validity" in r.get(q, {})]
    cov = [c for c in cov if math.isfinite(c)]
    out["road_coverage_3sigma"] = min(cov) if cov else math.nan
    return out


def failed_targets(row: dict, case: SuiteCase) -> list[str]:
    """Codes of the targets (module doc) this row misses; a NaN that should be a number fails."""
    T = TARGETS
    fails = []

    def bad(value, limit, above=True):
        return not (value <= limit if above else value >= limit)

    for q, code in (("sideslip", "b"), ("heading", "h")):
        cov = row[f"{q}_coverage_3sigma"]
        if math.isfinite(cov) and cov < T["coverage_3sigma"]:
            fails.append(f"cov-{code}")
        worst = row[f"{q}_worst_valid_deg"]
        if math.isfinite(worst) and worst > T[f"worst_{q}_deg"]:
            fails.append(f"worst-{code}")
    if math.isfinite(row["vx_coverage_3sigma"]) and row["vx_coverage_3sigma"] < T["coverage_3sigma"]:
        fails.append("cov-v")
    if bad(row["sideslip_valid_above_5mps"], T["sideslip_valid_above_5mps"], above=False):
        fails.append("avail-b")
    if row["has_fix"]:
        for q, code in (("sideslip", "b"), ("heading", "h")):
            if bad(row[f"{q}_time_to_valid_after_fix_s"], T["time_to_valid_after_fix_s"]):
                fails.append(f"ttv-{code}")
    if bad(abs(row["latency_error_s"]), T["latency_error_s"]):
        fails.append("lat")
    if case.low_speed and (bad(row["sideslip_rms_deg"], T["low_speed_sideslip_rms_deg"])
                           or bad(row["ratio_to_baseline"], T["low_speed_ratio_to_baseline"])):
        fails.append("rms-b")
    cov_r = row.get("road_coverage_3sigma", math.nan)
    if math.isfinite(cov_r) and cov_r < T["coverage_3sigma"]:
        fails.append("cov-r")
    if case.family == "road":
        if case.scenario.grade_rad and bad(row.get("grade_rms_deg", math.nan), T["road_angle_rms_deg"]):
            fails.append("rms-g")
        if case.scenario.bank_rad and bad(row.get("bank_rms_deg", math.nan), T["road_angle_rms_deg"]):
            fails.append("rms-k")
    if case.family == "dual_antenna":
        if bad(row["heading_rms_deg"], T["dual_antenna_heading_rms_deg"]):
            fails.append("rms-h")
        if bad(row["sideslip_rms_above_5mps_deg"], T["dual_antenna_sideslip_rms_above_5mps_deg"]):
            fails.append("rms-b5")
    if case.family == "two_receivers":
        if case.compare_single:
            for q, code in (("sideslip", "b"), ("heading", "h")):
                if bad(row[f"{q}_rms_deg"], 1.05 * row[f"single_{q}_rms_deg"] + 0.005):
                    fails.append(f"vs1-{code}")
        else:
            if bad(row["sideslip_rms_deg"], T["two_receivers_sideslip_rms_deg"]):
                fails.append("rms2-b")
            if bad(row["heading_rms_deg"], T["two_receivers_heading_rms_deg"]):
                fails.append("rms2-h")
        if bad(abs(row["latency2_error_s"]), T["latency_error_s"]):
            fails.append("lat2")
    if case.family == "magnetometer":
        if bad(row["mag_heading_rms_deg"], T["magnetometer_heading_rms_deg"]):
            fails.append("rms-m")
        if bad(row["mag_jump_deg"], T["magnetometer_jump_deg"]):
            fails.append("jump-m")
    return fails


COLUMNS = (  # header, key, format
    ("scenario", "scenario", "{}"),
    ("b rms", "sideslip_rms_deg", "{:.2f}"),
    ("h rms", "heading_rms_deg", "{:.2f}"),
    ("b rms>5", "sideslip_rms_above_5mps_deg", "{:.2f}"),
    ("base b", "baseline_sideslip_rms_deg", "{:.2f}"),
    ("ratio", "ratio_to_baseline", "{:.2f}"),
    ("b val>5", "sideslip_valid_above_5mps", "{:.0%}"),
    ("h val>5", "heading_valid_above_5mps", "{:.0%}"),
    ("b 3sig", "sideslip_coverage_3sigma", "{:.1%}"),
    ("h 3sig", "heading_coverage_3sigma", "{:.1%}"),
    ("vx 3sig", "vx_coverage_3sigma", "{:.1%}"),
    ("b worst", "sideslip_worst_valid_deg", "{:.2f}"),
    ("h worst", "heading_worst_valid_deg", "{:.1f}"),
    ("b ttv", "sideslip_time_to_valid_after_fix_s", "{:.1f}"),
    ("h ttv", "heading_time_to_valid_after_fix_s", "{:.1f}"),
    ("lat err", "latency_error_s", "{:+.3f}"),
    ("lat2 err", "latency2_error_s", "{:+.3f}"),
    ("mag h", "mag_heading_rms_deg", "{:.2f}"),
    ("mag jump", "mag_jump_deg", "{:.2f}"),
    ("no-mag h", "no_mag_heading_rms_deg", "{:.2f}"),
    ("bank", "bank_rms_deg", "{:.2f}"),
    ("grade", "grade_rms_deg", "{:.2f}"),
    ("roll", "roll_rms_deg", "{:.2f}"),
    ("r 3sig", "road_coverage_3sigma", "{:.1%}"),
)


def format_table(rows: list[dict]) -> str:
    """One table: angles in deg, times in s; '-' where a figure does not exist (never valid...)."""
    cells = [[h for h, _, _ in COLUMNS] + ["result"]]
    for row in rows:
        line = []
        for _, key, fmt in COLUMNS:
            v = row[key]
            line.append("-" if isinstance(v, float) and not math.isfinite(v) else fmt.format(v))
        line.append("pass" if not row["failed"] else "FAIL " + ",".join(row["failed"]))
        cells.append(line)
    widths = [max(len(c[i]) for c in cells) for i in range(len(cells[0]))]
    out = []
    for c in cells:
        out.append("  ".join(x.ljust(w) if i in (0, len(c) - 1) else x.rjust(w)
                             for i, (x, w) in enumerate(zip(c, widths))).rstrip())
    n_pass = sum(1 for r in rows if not r["failed"])
    out.append(f"{n_pass} of {len(rows)} scenarios meet every target (b = sideslip, h = heading; rms after"
               f" the first {SETTLE_S:g} s; val>5 = valid on rows above 5 m/s once converged; 3sig = valid rows"
               " within 3 sigma; worst = worst error while valid; ttv = time to valid after the first good"
               " GNSS fix above 5 m/s; mag h / mag jump = magnetometer cases' heading RMS from 5 s after it is first valid"
               " and largest heading-error change over a disturbance, no-mag h = the same replayed without it;"
               " bank / grade / roll: rms, r 3sig: their worst 3-sigma coverage)")
    return "\n".join(out)


def run_suite(cases: list[SuiteCase], out_dir: str | Path, jobs: int = 1, progress=None) -> list[dict]:
    """Rows in the order of ``cases``; ``progress(row)`` after each finished case."""
    Path(out_dir).mkdir(parents=True, exist_ok=True)
    rows: dict[str, dict] = {}
    if jobs <= 1:
        for c in cases:
            rows[c.name] = run_case(c, out_dir)
            if progress:
                progress(rows[c.name])
    else:
        with ProcessPoolExecutor(max_workers=jobs) as pool:
            futures = {pool.submit(run_case, c, out_dir): c for c in cases}
            for fut in futures:
                row = fut.result()
                rows[row["scenario"]] = row
                if progress:
                    progress(row)
    return [rows[c.name] for c in cases]


def main(args) -> int:
    from .errors import UserError

    cases = select(args.only)
    if not cases:
        raise UserError(f"--only {args.only!r} matches no scenario; names: {', '.join(c.name for c in SUITE)}")
    jobs = args.jobs if args.jobs else (os.cpu_count() or 1)
    out = Path(args.out or "out/suite")
    started = time.perf_counter()

    def tick(row):
        print(f"  {row['scenario']}: {'pass' if not row['failed'] else 'FAIL ' + ','.join(row['failed'])}"
              f" ({row['wall_s']:.1f} s)", file=sys.stderr)

    print(f"running {len(cases)} scenario(s) with {jobs} job(s) into {out}", file=sys.stderr)
    rows = run_suite(cases, out, jobs, tick)
    doc = [public(r) for r in rows]
    (out / "suite.json").write_text(json.dumps(doc, indent=1, allow_nan=False) + "\n")
    if args.json:
        json.dump(doc, sys.stdout, indent=1, allow_nan=False)
        sys.stdout.write("\n")
    else:
        print(format_table(rows))
    print(f"suite: {len(rows)} scenario(s) in {time.perf_counter() - started:.0f} s; rows in {out / 'suite.json'}",
          file=sys.stderr)
    return 0 if all(not r["failed"] for r in rows) else 1
