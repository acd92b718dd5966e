"""Where a drive's published sideslip std comes from, row by row, and which term keeps it invalid.

Why: a sideslip that is right but invalid (issue 7 item 3: the low-speed circles, 0.1 deg off and
valid on 58-68 % of the rows) is only fixable where a term of its std is counted twice or too
wide; before changing one, see which term holds the std above the validity limit and when.

The published std (``core.Estimator._estimate``) is the filter's own sideslip std (its vx / vy
covariance: the GNSS velocity fixes with the latency std as noise across the track, the gyro
scale and IMU lever arm as linear vy growth, the single-track pseudo-measurement), replaced by the
single-track model's bound (``_model_bound``: the model's parameter / tyre-law error, its
saturation term and floor, plus a third of the filter's distance from the model) where that is
smaller, the bound exists (a steady corner with fresh GNSS for ``MODEL_STEADY_S``) and the
filter's own std is above the limit. The latency-consider term (``latency_sensitivity.py``)
and the lever-arm checks widen only the heading and vx stds, never the sideslip's: their values
are printed so that a table shows they were off.

This replays a drive folder (``config.toml``, ``drive.log``, ``drive_gnss.log``; ``truth.csv``
for the speed and the validity rows the suite counts; e.g. one scenario of
``ecu-daemon evaluate --suite --out DIR``) through the same estimator with a read-only hook on
``_estimate``, then sorts the rows the suite's ``valid above 5 m/s`` counts into: valid; invalid
while the bound is not offered (transient, GNSS stale); invalid with the bound the smaller
(model-limited, with the bound's parts); invalid with the filter the smaller (filter-limited).
``--set MODULE.NAME=VALUE`` and ``--latency-std-scale F`` replay what-ifs (a term switched off
or narrowed) to size each term; they are measurements, not settings to adopt.

    python3 tools/sideslip_budget.py /tmp/suite/lowspeed_r10 [--table] [--set core.YAW_SCALE_STD=0]
"""
from __future__ import annotations

import argparse
import math
import os
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
# the hook replaces a method of Estimator: a compiled class is immutable, so the estimator runs its
# .py (the same rules and bits, compiled_python.py; only slower)
os.environ["ECU_DAEMON_PURE_PYTHON"] = "1"
from ecu_daemon import config as config_mod  # noqa: E402
from ecu_daemon.estimator import core, yaw_scale_check  # noqa: E402
from ecu_daemon.estimator.fusion import gnss_velocity, single_track  # noqa: E402
from ecu_daemon.estimator.kinematic import VX, VY  # noqa: E402
from ecu_daemon.evaluate import CONVERGE_S, VALID_SPEED_MPS, first_good_fix, read_csv  # noqa: E402
from ecu_daemon.replay import run_replay  # noqa: E402

#: per-row record columns
COLUMNS = ("t", "sideslip", "vx", "r", "filter_std", "bound_vy", "bound_k1", "bound_k3", "bound_floor", "bound_dev",
           "published_std", "valid", "latency_std", "lever_flagged", "augmented")
CLASSES = ("valid", "no bound (transient / GNSS stale)", "model-limited (bound < filter)",
           "filter-limited (filter <= bound)", "other")
MODULES = {"core": core, "single_track": single_track, "gnss_velocity": gnss_velocity, "yaw_scale_check": yaw_scale_check}


def _bound_parts(est, t: float, vx: float, vy: float, r: float, iso: int) -> tuple:
    """The model bound's vy std and its parts (k1: the parameter and law error, k3: the rest of
    the parameter term with its cross term, floor: saturation and unmodelled dynamics, dev: a third
    of |vy - vy_model|); NaNs where no bound is offered. Above 0.6 g the k1 column is the
    variance below it and the k3 column holds the rest of the parameter term."""
    b = est._model_bound(t, vx, vy, r, iso)
    if not math.isfinite(b):
        return (math.inf,) + (math.nan,) * 4
    st = est.single_track
    vy_m, s_m = st.model_error(vx, r, est.model_ay, est.rdot)
    phi = st.regressor_rear(vx, est.model_ay, est.rdot)
    n2 = (est.model_ay / single_track.G) ** 2
    _, var_all = st.rear.predict(phi, n2, True)
    _, var_k1 = st.rear.predict(phi, 0.0, True)  # the same k1 variance (below 0.6 g), no k3 term
    floor2 = max(s_m * s_m - var_all, 0.0)
    return (b, math.sqrt(max(var_k1, 0.0)), math.sqrt(max(var_all - var_k1, 0.0)), math.sqrt(floor2),
            abs(vy - vy_m) / 3.0)


def record(folder: Path, latency_std_scale: float = 1.0) -> dict:
    """Replay ``folder`` and return the per-row budget (arrays named by :data:`COLUMNS`)."""
    rows: list[tuple] = []
    orig_estimate = core.Estimator._estimate
    orig_fuse = gnss_velocity.GnssVelocityFusion.fuse

    def estimate(self, t, x, pd, p_vxvy, r, status, imu_ok, wheels_ok, iso):
        e = orig_estimate(self, t, x, pd, p_vxvy, r, status, imu_ok, wheels_ok, iso)
        vx, vy = x[VX], x[VY]
        sp2 = vx * vx + vy * vy
        if sp2 > 0.25:
            var_b = (vx * vx * pd[VY] - 2.0 * vx * vy * float(p_vxvy) + vy * vy * pd[VX]) / (sp2 * sp2)
            parts = _bound_parts(self, t, vx, vy, r, iso)
        else:
            var_b, parts = math.pi ** 2, (math.inf,) + (math.nan,) * 4
        rows.append((t, e.sideslip_rad, vx, r, math.sqrt(max(var_b, 0.0)), *parts, e.sideslip_std_rad, float(e.sideslip_valid),
                     self._latency_std(), float(self.lever_flagged), float(self.augmented)))
        return e

    def fuse(self, hist, s, g, gate=True, delay_std_s=0.0, consider=None):
        return orig_fuse(self, hist, s, g, gate, delay_std_s * latency_std_scale, consider)

    core.Estimator._estimate = estimate
    if latency_std_scale != 1.0:
        gnss_velocity.GnssVelocityFusion.fuse = fuse
    try:
        cfg = config_mod.load(folder / "config.toml")
        gnss = folder / "drive_gnss.log"
        run_replay(cfg, str(folder / "drive.log"), [str(gnss)] if gnss.exists() else None)
    finally:
        core.Estimator._estimate = orig_estimate
        gnss_velocity.GnssVelocityFusion.fuse = orig_fuse
    a = np.array(rows, dtype=float).reshape(-1, len(COLUMNS))
    return {c: a[:, i] for i, c in enumerate(COLUMNS)}


def counted_rows(rec: dict, truth: dict | None) -> np.ndarray:
    """The rows the suite's sideslip ``valid above 5 m/s`` counts (``evaluate.validity_metrics``):
    inside the truth's span, above 5 m/s, from CONVERGE_S after the first good fix; without a
    truth, every row above 5 m/s by the estimate's own vx."""
    t = rec["t"]
    if truth is None:
        return rec["vx"] > VALID_SPEED_MPS
    tt = truth["t"]
    speed = np.interp(t, tt, truth["speed_mps"] if "speed_mps" in truth else np.hypot(truth["vx_mps"], truth["vy_mps"]))
    m = (t >= tt[0]) & (t <= tt[-1]) & (speed > VALID_SPEED_MPS)
    t_fix = first_good_fix(truth)
    if math.isfinite(t_fix):
        m &= t >= t_fix + CONVERGE_S
    return m


def classify(rec: dict) -> dict[str, np.ndarray]:
    """Each row's class (:data:`CLASSES`) as boolean masks that partition the rows."""
    limit = core.SIDESLIP_STD_VALID
    valid = rec["valid"] > 0.5
    vx = np.maximum(np.abs(rec["vx"]), 1e-3)
    bound_beta = rec["bound_vy"] / vx  # the bound as a sideslip std (vy << vx)
    high = rec["published_std"] >= limit
    has_bound = np.isfinite(rec["bound_vy"])
    out = {CLASSES[0]: valid,
           CLASSES[1]: ~valid & high & ~has_bound,
           CLASSES[2]: ~valid & high & has_bound & (bound_beta < rec["filter_std"]),
           CLASSES[3]: ~valid & high & has_bound & (bound_beta >= rec["filter_std"])}
    out[CLASSES[4]] = ~(out[CLASSES[0]] | out[CLASSES[1]] | out[CLASSES[2]] | out[CLASSES[3]])
    return out


def summary(rec: dict, mask: np.ndarray) -> list[str]:
    """One line per class: its share of the counted rows, the median lateral acceleration, the
    published std over the limit, the filter's and the bound's sideslip std, the latency std;
    for the model-limited rows also the bound's parts against the vy std the limit allows."""
    limit = core.SIDESLIP_STD_VALID
    n = int(mask.sum())
    lines = [f"{n} rows counted (above {VALID_SPEED_MPS:g} m/s), validity limit {math.degrees(limit):.3f} deg"]
    if n == 0:
        return lines
    vx = np.maximum(np.abs(rec["vx"]), 1e-3)
    ay_g = np.abs(rec["r"] * rec["vx"]) / single_track.G
    for name, c in classify(rec).items():
        c = c & mask
        k = int(c.sum())
        if k == 0:
            lines.append(f"  {name:36s} 0.000")
            continue
        bb = rec["bound_vy"][c] / vx[c]
        bb = bb[np.isfinite(bb)]
        lines.append(f"  {name:36s} {k / n:.3f}  ay {np.median(ay_g[c]):.2f} g  published/limit "
                     f"{np.median(rec['published_std'][c]) / limit:.2f}  filter {math.degrees(np.median(rec['filter_std'][c])):.2f}"
                     f" deg  bound {math.degrees(np.median(bb)) if len(bb) else math.nan:.2f} deg  latency std "
                     f"{np.median(rec['latency_std'][c]):.3f} s  lever flagged {rec['lever_flagged'][c].mean():.2f}"
                     f"  augmented {rec['augmented'][c].mean():.2f}")
        if name == CLASSES[2]:
            lines.append("    bound parts, vy std (m/s, medians): k1 %.3f  k3 %.3f  floor %.3f  |vy - model|/3 %.3f"
                         " -> bound %.3f; the limit allows %.3f" % (tuple(
                             float(np.median(rec[f][c])) for f in ("bound_k1", "bound_k3", "bound_floor", "bound_dev",
                                                                   "bound_vy"))
                             + (float(np.median(limit * vx[c])),)))
    return lines


def accuracy(rec: dict, truth: dict, mask: np.ndarray) -> str:
    """What a what-if must not lose: the sideslip error over the counted rows and the promise of the
    valid ones (within 3 sigma, worst)."""
    err = rec["sideslip"] - np.interp(rec["t"], truth["t"], np.unwrap(truth["sideslip_rad"]))
    err = (err + math.pi) % (2.0 * math.pi) - math.pi
    v = mask & (rec["valid"] > 0.5)
    cov = float(np.mean(np.abs(err[v]) <= 3.0 * rec["published_std"][v])) if v.any() else math.nan
    worst = math.degrees(float(np.max(np.abs(err[v])))) if v.any() else math.nan
    rms = math.degrees(float(np.sqrt(np.mean(err[mask] ** 2)))) if mask.any() else math.nan
    return f"  sideslip rms {rms:.3f} deg; valid rows within 3 sigma {cov:.4f}, worst {worst:.3f} deg"


def table(rec: dict, every_s: float = 1.0) -> list[str]:
    """The budget once per ``every_s`` (rows above 3 m/s)."""
    lines = ["      t     vx      r  filter  bound_vy     k1     k3  floor    dev  published  valid  lat_std"]
    t = rec["t"]
    nxt = -math.inf
    for i in range(len(t)):
        if t[i] < nxt or rec["vx"][i] < 3.0:
            continue
        nxt = t[i] + every_s
        lines.append(f"{t[i]:7.1f} {rec['vx'][i]:6.2f} {rec['r'][i]:6.3f} {math.degrees(rec['filter_std'][i]):7.3f} "
                     f"{rec['bound_vy'][i]:9.3f} {rec['bound_k1'][i]:6.3f} {rec['bound_k3'][i]:6.3f} "
                     f"{rec['bound_floor'][i]:6.3f} {rec['bound_dev'][i]:6.3f} {math.degrees(rec['published_std'][i]):10.3f}"
                     f" {int(rec['valid'][i]):6d} {rec['latency_std'][i]:8.3f}")
    return lines


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("folder", type=Path, help="drive folder: config.toml, drive.log, drive_gnss.log[, truth.csv]")
    ap.add_argument("--table", action="store_true", help="also print the budget once a second")
    ap.add_argument("--set", action="append", default=[], metavar="MODULE.NAME=VALUE",
                    help="what-if: set a module constant (modules: %s)" % ", ".join(MODULES))
    ap.add_argument("--latency-std-scale", type=float, default=1.0,
                    help="what-if: scale the latency std the GNSS velocity fusion uses")
    args = ap.parse_args(argv)
    for kv in args.set:
        key, _, value = kv.partition("=")
        mod, _, name = key.partition(".")
        if mod not in MODULES or not hasattr(MODULES[mod], name) or not value:
            ap.error(f"--set {kv}: expected MODULE.NAME=VALUE with MODULE in {', '.join(MODULES)} and an existing NAME")
        setattr(MODULES[mod], name, type(getattr(MODULES[mod], name))(float(value)))
    rec = record(args.folder, args.latency_std_scale)
    truth_path = args.folder / "truth.csv"
    truth = read_csv(truth_path, ("t",), "truth CSV") if truth_path.exists() else None
    mask = counted_rows(rec, truth)
    print(f"{args.folder.name} {' '.join(args.set)}"
          + (f" latency std x{args.latency_std_scale:g}" if args.latency_std_scale != 1.0 else ""))
    print("\n".join(summary(rec, mask)))
    if truth is not None and "sideslip_rad" in truth:
        print(accuracy(rec, truth, mask))
    if args.table:
        print("\n".join(table(rec)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
