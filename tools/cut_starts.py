"""Starts in motion on real data: each real drive replayed from N cut points, cold and restarted.

The held-out judge replays real drives that start in motion: a log cut mid-drive (the daemon
starts with nothing learned) or a daemon restarted while driving (it restores the learned-state
file its earlier run saved). This tool makes both from the real drives of ``../shared/data``
(the same logs ``tools/real_data.py`` builds: Revs as Toyota CAN + delayed 5 Hz UBX, the RAV4's
recorded candump + its u-blox fixes) and reports per cut point:

* the context at the cut (speed, yaw rate, lateral acceleration, sideslip);
* ``cold``: the logs from the cut on, nothing learned;
* ``warm``: the logs before the cut replayed first, its learned state saved and loaded through
  the daemon's state file (:mod:`ecu_daemon.io.state_store`), then the logs from the cut on;
* per run: worst sideslip / heading error while valid, share of valid rows within 3 reported
  sigma, time to valid after the first GNSS fix received after the cut (above 5 m/s), and the
  RMS from that fix (the heading: from its first course) to ``--window`` seconds after the cut
  against the RMS of the uncut run's estimate over the same rows (what the cut costs);
* ``full``: the uncut run over the same span (how the estimator does there when it has run
  all along).

The RAV4 has no sideslip or heading truth: on its straight highway the sideslip is ~0 and the
heading is the u-blox course at each fix's own epoch (README of the data, section 2), so its
heading error is scored at the fix epochs and its "sideslip error" is the estimate itself.

    python3 tools/cut_starts.py revs --out /tmp/cuts_revs [--every 20] [--at 137 301] [--jobs 2]
    python3 tools/cut_starts.py rav4 --out /tmp/cuts_rav4 [--every 10]

Why: a flying start on real motion (jittery real sensors, tyre saturation, a latency the filter
has not yet identified) may break a promise the simulated flying starts keep.
"""
from __future__ import annotations

import argparse
import json
import math
import multiprocessing
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "tools"))
import real_data  # noqa: E402
from ecu_daemon import config as config_mod  # noqa: E402
from ecu_daemon.evaluate import read_csv, wrap  # noqa: E402
from ecu_daemon.io.state_store import load_state, save_state  # noqa: E402
from ecu_daemon.replay import run_replay  # noqa: E402

DEG = 180.0 / math.pi
#: the speed above which the first GNSS fix counts (evaluate.VALID_SPEED_MPS, the judge's)
FIX_SPEED_MPS = 5.0
#: what each cut run replays after the cut: the window scored plus the restart's settling
AFTER_S = 60.0
EST_COLUMNS = ("t", "sideslip_rad", "sideslip_std_rad", "sideslip_valid", "heading_rad", "heading_std_rad",
               "heading_valid")


# ------------------------------------------------------------------------------------ logs

def _line_time(line: str) -> float:
    """Time of a candump / GNSS capture line: '(seconds.micros) ...' (NaN for anything else)."""
    if line.startswith("("):
        end = line.find(")")
        try:
            return float(line[1:end])
        except ValueError:
            return math.nan
    return math.nan


def cut_log(src: Path, dst: Path, t_from: float, t_to: float) -> int:
    """Lines of a log stamped in [t_from, t_to) into ``dst``; returns how many."""
    n = 0
    with open(src, encoding="ascii") as f, open(dst, "w", encoding="ascii") as g:
        for line in f:
            t = _line_time(line)
            if t_from <= t < t_to:
                g.write(line)
                n += 1
    return n


def first_rx_time(gnss_log: Path) -> float:
    with open(gnss_log, encoding="ascii") as f:
        for line in f:
            t = _line_time(line)
            if math.isfinite(t):
                return t
    return math.nan


# ------------------------------------------------------------------------------------ truth

class Truth:
    """Sideslip and heading truth of a drive as functions of time (NaN where there is none)."""

    def __init__(self, t, speed, beta=None, heading=None, yaw_rate=None, ay=None, fix_t=None, fix_course=None):
        self.t, self.speed, self.beta, self.heading = t, speed, beta, heading
        self.yaw_rate, self.ay, self.fix_t, self.fix_course = yaw_rate, ay, fix_t, fix_course

    def at(self, name: str, t: float) -> float:
        v = getattr(self, name)
        return float(np.interp(t, self.t, v)) if v is not None else math.nan


def revs_truth(out: Path) -> Truth:
    tr = read_csv(out / "truth.csv", ("t", "sideslip_rad", "heading_rad", "speed_mps", "yaw_rate_radps",
                                      "ay_mps2"), "truth CSV")
    return Truth(tr["t"], tr["speed_mps"], tr["sideslip_rad"], np.unwrap(tr["heading_rad"]),
                 tr["yaw_rate_radps"], tr["ay_mps2"])


def rav4_truth() -> Truth:
    g = real_data.load_rav4_gnss()
    # the course at the fix's own epoch; the speed there too (the highway's beta ~ 0)
    return Truth(g["fix_time_boot_s"], g["speed_mps"], fix_t=g["fix_time_boot_s"],
                 fix_course=np.unwrap(np.radians(g["bearing_deg"])))


# ------------------------------------------------------------------------------------ scoring

def _errors(est: dict, truth: Truth) -> dict:
    """Per estimate row (sideslip) or per fix epoch (RAV4 heading): error, std, valid."""
    t = est["t"]
    out = {}
    if truth.beta is not None:
        ref = np.interp(t, truth.t, truth.beta)
    else:
        ref = np.zeros_like(t)  # RAV4: straight highway, sideslip ~ 0
    out["sideslip"] = (t, wrap(est["sideslip_rad"] - ref), est["sideslip_std_rad"], est["sideslip_valid"] > 0.5)
    if truth.heading is not None:
        ref = np.interp(t, truth.t, truth.heading)
        out["heading"] = (t, wrap(est["heading_rad"] - ref), est["heading_std_rad"], est["heading_valid"] > 0.5)
    else:  # the course at each fix epoch inside the estimate
        ft = truth.fix_t[(truth.fix_t >= t[0]) & (truth.fix_t <= t[-1])]
        i = np.clip(np.searchsorted(t, ft), 0, len(t) - 1)
        h = np.interp(ft, t, np.unwrap(est["heading_rad"]))
        course = np.interp(ft, truth.fix_t, truth.fix_course)
        out["heading"] = (ft, wrap(h - course), est["heading_std_rad"][i], est["heading_valid"][i] > 0.5)
    return out


def score(est: dict, truth: Truth, t_fix: float, window_s: float, full: dict | None) -> dict:
    """Worst valid error, 3-sigma coverage, time to valid after ``t_fix``, RMS over the window."""
    res = {}
    errs = _errors(est, truth)
    ferrs = _errors(full, truth) if full is not None else None
    for name, (t, e, s, v) in errs.items():
        a = np.abs(e)
        r = {"valid_rows": int(v.sum()),
             "worst_valid_deg": float(a[v].max() * DEG) if v.any() else math.nan,
             "cov3": float(np.mean(a[v] <= 3 * s[v])) if v.any() else math.nan,
             "beyond_3sigma": int(np.sum(a[v] > 3 * s[v]))}
        after = t >= t_fix
        r["ttv_s"] = float(t[after & v][0] - t_fix) if (after & v).any() else math.nan
        # from the first fix on, and only where the quantity is known at all (before the first
        # course the heading is published with a std of pi: its value means nothing)
        t_end = t[0] + window_s
        known = s < math.pi / 2
        t_known = t[known & (t >= t_fix)][0] if (known & (t >= t_fix)).any() else math.inf
        w = (t >= t_known) & (t < t_end)
        r["rms_window_deg"] = float(np.sqrt(np.mean(e[w] ** 2)) * DEG) if w.any() else math.nan
        r["valid_window"] = float(np.mean(v[w])) if w.any() else math.nan
        if ferrs is not None:
            ft, fe = ferrs[name][0], ferrs[name][1]
            fw = (ft >= t_known) & (ft < t_end)
            r["rms_window_full_deg"] = float(np.sqrt(np.mean(fe[fw] ** 2)) * DEG) if fw.any() else math.nan
        res[name] = r
    return res


# ------------------------------------------------------------------------------------ runs

def _replay(cfg_path: Path, can: Path, gnss: Path, est: Path, learned: dict | None = None) -> dict:
    cfg = config_mod.load(cfg_path)
    return run_replay(cfg, str(can), str(gnss), str(est), learned=learned)


def run_cut(job: tuple) -> dict:
    """One cut point: the cold and the warm (restarted) run; returns its report row."""
    drive, out, offset, t_cut, t_end, window_s, warm = job
    d = out / f"cut_{offset:07.2f}"
    d.mkdir(parents=True, exist_ok=True)
    src = out / "full"
    truth = revs_truth(src) if drive == "revs" else rav4_truth()
    can_src, gnss_src = src / "drive.log", src / "drive_gnss.log"
    can, gnss = d / "drive.log", d / "drive_gnss.log"
    cut_log(can_src, can, t_cut, t_end)
    cut_log(gnss_src, gnss, t_cut, t_end)
    full = read_csv(src / "estimate.csv", EST_COLUMNS, "estimate CSV")
    full = {k: v[(full["t"] >= t_cut) & (full["t"] < t_end)] for k, v in full.items()}
    t_fix = first_fix_above(gnss, truth)
    row = {"offset_s": offset, "t_cut": t_cut, "t_fix": t_fix,
           "speed_mps": truth.at("speed", t_cut), "yaw_rate_degps": truth.at("yaw_rate", t_cut) * DEG,
           "ay_mps2": truth.at("ay", t_cut), "beta_deg": truth.at("beta", t_cut) * DEG}
    # the uncut run over the same span: what the estimator does there when it has run all along
    row["full"] = score(full, truth, t_fix, window_s, None)
    runs = {"cold": None}
    if warm:
        can_a, gnss_a = d / "before.log", d / "before_gnss.log"
        cut_log(can_src, can_a, -math.inf, t_cut)
        cut_log(gnss_src, gnss_a, -math.inf, t_cut)
        summary = _replay(src / "config.toml", can_a, gnss_a, d / "estimate_before.csv")
        save_state(d / "state.json", summary["learned"])
        runs["warm"] = load_state(d / "state.json")
        can_a.unlink()
        gnss_a.unlink()
    for kind, learned in runs.items():
        est_path = d / f"estimate_{kind}.csv"
        _replay(src / "config.toml", can, gnss, est_path, learned)
        est = read_csv(est_path, EST_COLUMNS, "estimate CSV")
        row[kind] = score(est, truth, t_fix, window_s, full)
    return row


def first_fix_above(gnss_log: Path, truth: Truth) -> float:
    """Receive time of the first fix of a cut capture while the car moves above FIX_SPEED_MPS."""
    t = first_rx_time(gnss_log)
    if not math.isfinite(t):
        return math.nan
    with open(gnss_log, encoding="ascii") as f:
        for line in f:
            t = _line_time(line)
            if math.isfinite(t) and truth.at("speed", t) > FIX_SPEED_MPS:
                return t
    return math.nan


def build_full(drive: str, out: Path) -> tuple[float, float]:
    """The uncut drive's logs, config and estimate in ``out/full``; returns its (start, end) time."""
    src = out / "full"
    src.mkdir(parents=True, exist_ok=True)
    if drive == "revs":
        paths = real_data.build_revs(src)
        can, gnss = paths["can"], paths["gnss"]
    else:
        can = src / "drive.log"
        can.write_bytes((real_data.RAV4_DIR / "rav4_bus0_candump.log").read_bytes())
        gnss = src / "drive_gnss.log"
        real_data.write_rav4_gnss(gnss, "ubx")
        real_data._write_config(real_data.rav4_config(), src)
    _replay(src / "config.toml", can, gnss, src / "estimate.csv")
    with open(can, encoding="ascii") as f:
        first = _line_time(f.readline())
    est = read_csv(src / "estimate.csv", ("t",), "estimate CSV")
    return first, float(est["t"][-1])


# ------------------------------------------------------------------------------------ report

def _f(v: float, nd: int = 2) -> str:
    return "-" if v is None or not math.isfinite(v) else f"{v:.{nd}f}"


def format_rows(rows: list[dict]) -> str:
    head = (f"{'cut s':>7}{'v':>6}{'r d/s':>7}{'ay':>6}{'beta':>6} | {'run':<5}{'b worst':>8}{'b 3sig':>8}"
            f"{'b ttv':>7}{'b rms30':>8}{'full':>6}{'h worst':>8}{'h 3sig':>8}{'h ttv':>7}{'h rms30':>8}{'full':>6}")
    lines = [head, "-" * len(head)]
    for r in rows:
        ctx = (f"{r['offset_s']:>7.1f}{_f(r['speed_mps'], 1):>6}{_f(r['yaw_rate_degps'], 1):>7}"
               f"{_f(r['ay_mps2'], 1):>6}{_f(r['beta_deg'], 1):>6}")
        for i, kind in enumerate(k for k in ("cold", "warm", "full") if k in r):
            b, h = r[kind]["sideslip"], r[kind]["heading"]
            cells = (f" | {kind:<5}{_f(b['worst_valid_deg']):>8}{_f(b['cov3'] * 100, 1):>8}{_f(b['ttv_s'], 1):>7}"
                     f"{_f(b['rms_window_deg'], 3):>8}{_f(b.get('rms_window_full_deg', math.nan), 3):>6}"
                     f"{_f(h['worst_valid_deg']):>8}{_f(h['cov3'] * 100, 1):>8}{_f(h['ttv_s'], 1):>7}"
                     f"{_f(h['rms_window_deg'], 3):>8}{_f(h.get('rms_window_full_deg', math.nan), 3):>6}")
            lines.append((ctx if i == 0 else " " * len(ctx)) + cells)
    return "\n".join(lines)


def summary_lines(rows: list[dict]) -> list[str]:
    out = []
    for kind in ("cold", "warm", "full"):
        rs = [r[kind] for r in rows if kind in r]
        if not rs:
            continue
        for q, limit, ttv_target in (("sideslip", 2.0, 3.0), ("heading", 5.0, 3.0)):
            worst = max((x[q]["worst_valid_deg"] for x in rs if math.isfinite(x[q]["worst_valid_deg"])), default=math.nan)
            cov = min((x[q]["cov3"] for x in rs if math.isfinite(x[q]["cov3"])), default=math.nan)
            ttv = np.array([x[q]["ttv_s"] for x in rs])
            slow = int(np.sum(~(ttv <= ttv_target)))
            out.append(f"{kind} {q}: worst valid {_f(worst)} deg (promise {limit:g}), min 3-sigma coverage"
                       f" {_f(cov * 100, 2)} %, ttv median {_f(float(np.nanmedian(ttv)) if np.isfinite(ttv).any() else math.nan, 1)} s,"
                       f" {slow} of {len(rs)} starts not valid within {ttv_target:g} s")
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("drive", choices=("revs", "rav4"))
    p.add_argument("--out", required=True, type=Path)
    p.add_argument("--every", type=float, help="a cut every N s (default: 20 on Revs, 10 on the RAV4)")
    p.add_argument("--at", type=float, nargs="*", default=[], help="more cut points (s from the drive's start)")
    p.add_argument("--only-at", action="store_true", help="only the --at cut points")
    p.add_argument("--window", type=float, default=30.0, help="RMS window after the cut (s)")
    p.add_argument("--after", type=float, default=AFTER_S, help="s replayed after each cut")
    p.add_argument("--no-warm", action="store_true", help="cold starts only (no restart from a learned state)")
    p.add_argument("--jobs", type=int, default=1)
    args = p.parse_args(argv)
    if not real_data.SHARED.is_dir():
        print(f"real data not found at {real_data.SHARED}", file=sys.stderr)
        return 2
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    t0, t1 = build_full(args.drive, out)
    every = args.every or (20.0 if args.drive == "revs" else 10.0)
    offsets = [] if args.only_at else list(np.arange(every, t1 - t0 - args.window, every))
    offsets = sorted(set(round(float(o), 2) for o in offsets + list(args.at)))
    jobs = [(args.drive, out, o, t0 + o, t0 + o + args.after, args.window, not args.no_warm) for o in offsets]
    if args.jobs > 1:
        with multiprocessing.Pool(args.jobs) as pool:
            rows = pool.map(run_cut, jobs)
    else:
        rows = [run_cut(j) for j in jobs]
    (out / "cuts.json").write_text(json.dumps(rows, indent=1) + "\n")
    print(f"{args.drive}: {len(rows)} cut starts, {args.after:g} s replayed after each; angles in deg,"
          f" ttv after the first fix received after the cut; rms30 over the first {args.window:g} s vs the"
          f" uncut run ('full') in the same window")
    print(format_rows(rows))
    for line in summary_lines(rows):
        print(line)
    return 0


if __name__ == "__main__":
    sys.exit(main())
