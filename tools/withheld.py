"""Why the sideslip is withheld above 5 m/s, and how often it was right while withheld.

Why (issue 7): "invalid while right" is the second worst defect, and on main's 240 never-seen
random drives 1681-1920 the sideslip is valid on only 83.7 % of the rows above 5 m/s. Before any
rule is loosened, count which rule withholds each such row and whether the estimate was in fact
right there (|error| < 3 x the std it published and < 0.5 deg): the rule that withholds the most
right rows is the one to look at.

Two modes:

* ``csv ROOT...``: from the drive folders alone (estimate.csv, truth.csv; the output of
  ``tools/random_drives.py --out ROOT`` or ``ecu-daemon evaluate --suite --out ROOT``): the rows the
  suite counts (as ``evaluate.validity_metrics``: above 5 m/s, from ``CONVERGE_S`` after the first
  good fix) split into "std" (published std at or above ``SIDESLIP_STD_VALID``), "velocity"
  (velocity not valid: every sideslip rests on it) and "other rule"; the std's rows again (lines
  "std | ...", a subset, not added to the total) by the status word: a gyro or ay isolated, GNSS
  not fresh, neither. Main b26daff on 1681-1920: 1,802,466 counted rows, 304,759 withheld, 207,211
  of them right; the std withheld 181,303 right rows, 34,949 of them with an IMU signal isolated
  on fault-free banked drives (1710, 1729, 1796, 1892, 1748, 1757: the ay test's flat-road tolerance).
* ``probe SEED... --out DIR``: replays random drives in plain Python with each term of
  ``Estimator._estimate``'s sideslip decision recorded per step, and names the first term that
  fails (in the order the code tests them), so "other rule" is split too; a std row also says why
  the single-track model's vy bound (``MODEL_BOUND``) did not narrow it: off with an IMU signal
  isolated, off in or within ``MODEL_STEADY_S`` after a transient (and which condition), or on but
  wide (28 drives of 1681-1920: those three ~equal; the 2 s wait itself only ~2 % of counted rows).

    python3 tools/withheld.py csv /work/wt/_reports/rd41_integb
    ECU_DAEMON_PURE_PYTHON=1 python3 tools/withheld.py probe 1681 1700 --out /tmp/withheld
"""
from __future__ import annotations

import argparse
import collections
import json
import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))
from ecu_daemon.estimator import core  # noqa: E402
from ecu_daemon.estimator.estimate import (STATUS_ACCEL_Y_ISOLATED, STATUS_GNSS_FRESH,  # noqa: E402
                                           STATUS_YAW_RATE_ISOLATED)
from invalid_rows import counted_rows as suite_counted_rows  # noqa: E402

DEG = 180.0 / math.pi
RIGHT_DEG = 0.5  # "right": also within this, whatever the std


def counted_rows(folder: Path):
    """estimate columns, the rows the suite counts (invalid_rows.py's rule) and which were right."""
    e, tr, counted = suite_counted_rows(folder)
    t = e["t"]
    truth = np.interp(t, tr["t"], np.unwrap(tr["sideslip_rad"]))
    err = np.abs((e["sideslip_rad"] - truth + math.pi) % (2.0 * math.pi) - math.pi)
    right = (err < 3.0 * e["sideslip_std_rad"]) & (err * DEG < RIGHT_DEG)
    return e, counted, right, err


def csv_reasons(folder: Path) -> dict:
    """Per reason: [withheld rows, of them right]; plus the counted and valid totals."""
    e, counted, right, _ = counted_rows(folder)
    inv = counted & (e["sideslip_valid"] < 0.5)
    by_std = inv & (e["sideslip_std_rad"] >= core.SIDESLIP_STD_VALID)
    by_vel = inv & ~by_std & (e["velocity_valid"] < 0.5)
    other = inv & ~by_std & ~by_vel
    status = e["status"].astype(np.int64)
    iso = (status & (STATUS_YAW_RATE_ISOLATED | STATUS_ACCEL_Y_ISOLATED)) != 0
    stale = (status & STATUS_GNSS_FRESH) == 0
    out = {"counted": int(counted.sum()), "invalid": int(inv.sum())}
    for k, m in (("std", by_std), ("velocity", by_vel), ("other rule", other)):
        out[k] = [int(m.sum()), int((m & right).sum())]
    # the std's rows by what the status word says of them (the model's bound is off with an IMU
    # signal isolated; without fresh GNSS the filter's vy is the model's own)
    for k, m in (("std | gyro or ay isolated", by_std & iso), ("std | GNSS not fresh", by_std & ~iso & stale),
                 ("std | neither", by_std & ~iso & ~stale)):
        out[k] = [int(m.sum()), int((m & right).sum())]
    return out


# --- the probe: each term of the sideslip decision, per step (plain Python only) ---------------

TERMS = ("imu_ok", "spinning", "wheels_or_gnss_vx", "isolation", "gnss_conflict", "lon_scale_failing",
         "wheel_scale_wrong", "offset_found", "axis_swapped", "gyro_motion", "imu_trusted", "slow",
         "std", "lat_scale_failing", "wheel_scale_unconfirmed", "gyro_scale_unconfirmed")


def _terms(est, t, imu_ok, wheels_ok, iso, e) -> tuple:
    """The failing terms of ``_estimate``'s ss_valid, recomputed from the estimator after the call
    (every one side-effect free), in the code's order."""
    C = core
    wheels_trusted = wheels_ok and not iso & C.WHEELS and est.wheel_reject_t == math.inf
    fdi = est.fdi
    if iso & C.YAW_RATE:
        imu_trusted = not iso & C.ACCEL_Y and wheels_trusted and fdi.witnesses_agree
    elif iso & C.ACCEL_Y:
        imu_trusted = wheels_trusted and fdi.wheels_vouch_gyro
    else:
        imu_trusted = not fdi.yaw_suspect
    gnss_fresh = t - est.last_gnss_fused_t <= C.GNSS_FRESH_S
    beta_std = e.sideslip_std_rad
    sp2 = e.vx_mps ** 2 + e.vy_mps ** 2
    gnss_vx = gnss_fresh
    if C.GNSS_VX_NEEDS_SIDESLIP and gnss_fresh and not wheels_trusted:
        gnss_vx = (imu_trusted and beta_std < C.SIDESLIP_STD_VALID) or sp2 <= C.VX_STD_VALID ** 2
    gg = est.gyro_gate
    gyro_ss_ok = gg.sideslip_ok_forgetting() if C.SLOW_TURN_FORGOTTEN else gg.sideslip_ok()
    fails = {
        "imu_ok": not imu_ok,
        "spinning": est.spin.active,
        "wheels_or_gnss_vx": not (wheels_trusted or gnss_vx),
        "isolation": (iso & (C.WHEELS | C.ACCEL_X)) == C.WHEELS | C.ACCEL_X,
        "gnss_conflict": est._gnss_conflict(t),
        "lon_scale_failing": est.lon_scale.failing,
        "wheel_scale_wrong": est.wheel_scale_check.wrong,
        "offset_found": est.wheel_scale_seed.offset_found,
        "axis_swapped": est.axis_swap.swapped,
        "gyro_motion": not gg.motion_ok(),
        "imu_trusted": not imu_trusted,
        "slow": not e.vx_mps > C.MIN_SPEED_SIDESLIP,
        "std": not beta_std < C.SIDESLIP_STD_VALID,
        "lat_scale_failing": est.lat_scale.failing,
        "wheel_scale_unconfirmed": not est.wheel_scale_check.confirmed,
        "gyro_scale_unconfirmed": not (iso & C.YAW_RATE != 0 or gyro_ss_ok),
    }
    return tuple(k for k in TERMS if fails[k])


def _unsteady_trigger(est, t, imu_ok, iso) -> str:
    """The first of the conditions that restart the model bound's steady wait (core._step)."""
    C, fdi = core, est.fdi
    if not imu_ok or iso & (C.YAW_RATE | C.ACCEL_Y):
        return "imu/isolation"
    if abs(est.rdot) > C.MODEL_STEADY_RDOT:
        return "rdot"
    if fdi.lat_excess > 0.0:
        return "lat_excess"
    if fdi.lat_unexplained > est.lat_drift_tol:
        return "lat_unexplained"
    if fdi.yaw_disagreement > 0.0:
        return "yaw_disagreement"
    if t - est.last_gnss_fused_t > C.GNSS_FRESH_S:
        return "outage, law does not hold / law_var"
    return "law_var (tyre law excess)"


def _std_split(est, t, x, pd, p_vxvy, r, iso, trigger) -> str:
    """Why the sideslip std is at or above SIDESLIP_STD_VALID: the model's bound off (stale, or
    within MODEL_STEADY_S of a transient, and which) or on but too wide."""
    C = core
    if t - est.model_t > (C.MODEL_EVERY + 0.5) * est.dt:
        return "bound off: model not fused"
    age = t - est.model_unsteady_t
    if age < C.MODEL_STEADY_S:
        if est.model_unsteady_t == t:
            return "bound off: unsteady now (%s)" % trigger
        return "bound off: steady wait %.1f-%.1f s (%s)" % (math.floor(age * 2) / 2, math.floor(age * 2) / 2 + 0.5,
                                                           trigger)
    return "bound on, too wide"


def probe_drive(seed: int, out: str, max_duration_s: float | None = None) -> dict:
    """Replay random drive ``seed`` with the decision's terms recorded; per first failing term:
    [withheld counted rows, of them right], the drives' rows, and the terms of each row."""
    import random_drives as rd
    orig = core.Estimator._estimate
    log: dict[float, tuple] = {}

    trig = ["start"]

    def _estimate(self, t, x, pd, p_vxvy, r, status, imu_ok, wheels_ok, iso):
        if self.model_unsteady_t == t:  # what made the model's bound wait this step (MODEL_STEADY_S)
            trig[0] = _unsteady_trigger(self, t, imu_ok, iso)
        e = orig(self, t, x, pd, p_vxvy, r, status, imu_ok, wheels_ok, iso)
        terms = () if e.sideslip_valid else _terms(self, t, imu_ok, wheels_ok, iso, e)
        if terms and terms[0] == "std":
            terms = ("std: " + _std_split(self, t, x, pd, p_vxvy, r, iso, trig[0]),) + terms[1:]
        log[round(t, 6)] = terms
        return e

    try:
        core.Estimator._estimate = _estimate
    except TypeError:  # a compiled extension type: its methods cannot be replaced on the class
        raise SystemExit("the probe needs plain Python: ECU_DAEMON_PURE_PYTHON=1") from None
    try:
        d = rd.run_drive(seed, out, max_duration_s)
    finally:
        core.Estimator._estimate = orig
    folder = Path(out) / d["name"]
    res = {"seed": seed, "reasons": {}, "error": d["error"]}
    if d["error"]:
        return res
    e, counted, right, _ = counted_rows(folder)
    inv = counted & (e["sideslip_valid"] < 0.5)
    reasons = collections.defaultdict(lambda: [0, 0])
    for i in np.flatnonzero(inv):
        terms = log.get(round(float(e["t"][i]), 6))
        key = "not stepped (no estimate call)" if terms is None else (
            terms[0] if terms else "pipeline mask (stale input)")
        reasons[key][0] += 1
        reasons[key][1] += int(right[i])
    res["reasons"] = dict(reasons)
    res["counted"] = int(counted.sum())
    return res


def _rank(per_drive: dict, top: int) -> list[str]:
    tot = collections.defaultdict(lambda: [0, 0])
    drives = collections.defaultdict(list)
    counted = sum(v.get("counted", 0) for v in per_drive.values())
    for name, v in per_drive.items():
        for k, (n, r) in v["reasons"].items():
            tot[k][0] += n
            tot[k][1] += r
            drives[k].append((r, name))
    lines = [f"{len(per_drive)} drives, {counted} counted sideslip rows (> 5 m/s after convergence)"]
    for k, (n, r) in sorted(tot.items(), key=lambda kv: -kv[1][1]):
        best = ", ".join(f"{nm} {rr}" for rr, nm in sorted(drives[k], reverse=True)[:top] if rr)
        lines.append(f"{k:32s} withheld {n:8d} ({n / max(counted, 1):6.1%})  right {r:8d} "
                     f"({r / max(counted, 1):6.1%})   top: {best}")
    return lines


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="mode", required=True)
    c = sub.add_parser("csv")
    c.add_argument("roots", nargs="+")
    c.add_argument("--top", type=int, default=8)
    p = sub.add_parser("probe")
    p.add_argument("seeds", nargs="+", type=int)
    p.add_argument("--out", required=True)
    p.add_argument("--top", type=int, default=8)
    p.add_argument("--max-duration", type=float, default=None, help="cut each drive to this many seconds")
    a = ap.parse_args(argv[1:])
    per = {}
    if a.mode == "csv":
        for root in a.roots:
            for f in sorted(Path(root).iterdir()):
                if (f / "estimate.csv").exists() and (f / "truth.csv").exists():
                    v = csv_reasons(f)
                    per[f.name] = {"counted": v.pop("counted"), "reasons": {k: x for k, x in v.items()
                                                                              if k != "invalid"}}
    else:
        for s in a.seeds:
            r = probe_drive(s, a.out, a.max_duration)
            per[f"s{s}"] = r
            print(s, json.dumps(r["reasons"]), flush=True)
        Path(a.out, "withheld.json").write_text(json.dumps(per, indent=1))
    print("\n".join(_rank(per, a.top)))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
