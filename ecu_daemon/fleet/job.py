"""One drive: replay it, score it, read what the estimator learned; one flat record.

The only place the fleet calls the replay (:func:`_replay`). A drive whose files cannot be read,
whose config is bad or whose required inputs never decoded becomes a record with ``status`` =
``error`` and the reason, so one bad drive never stops the fleet. Records of finished drives (ok or
a deterministic input error) are stored under :func:`content_key`; a later run returns them as they
are (``cached``) without replaying.
"""
from __future__ import annotations

import contextlib
import hashlib
import logging
import math
import tempfile
import time
from pathlib import Path

import numpy as np

from .. import __version__
from .. import config as config_mod
from ..errors import UserError
from ..evaluate import ESTIMATE_REQUIRED, TRUTH_REQUIRED, EvaluationError, _evaluate, read_csv
from .manifest import Drive
from .store import ResultStore

#: learned parameter -> (unit, its key in the config or None when it is learned state only)
PARAMS = {
    "gnss_delay_s": ("s", ("gnss", "delay_s")),
    "wheel_scale": ("", None),
    "cornering_stiffness_front_n_per_rad": ("N/rad", ("vehicle", "cornering_stiffness_front_n_per_rad")),
    "cornering_stiffness_rear_n_per_rad": ("N/rad", ("vehicle", "cornering_stiffness_rear_n_per_rad")),
    "steering_offset_rad": ("rad", None),
    "yaw_rate_bias_radps": ("rad/s", None),
}
#: per cornering stiffness, what moves it to another latency (see :func:`learned_parameters`)
STIFFNESS_EXTRA = ("std_given_latency", "per_latency_s")
#: parameters the estimator learns without an uncertainty: their std column is NaN (none since the
#: steering offset has its own, estimator/steering_offset.py)
NO_STD: tuple = ()
VALIDITY = ("sideslip_valid", "heading_valid", "velocity_valid", "biases_valid")
#: quantity scored against truth -> record column prefix
SCORED = {"sideslip": "sideslip", "heading": "heading", "vx": "vx"}
SETTLE_S = 10.0  # as the scenario suite: the first seconds of a drive are convergence, not error
INPUT_ERRORS = (UserError, config_mod.ConfigError, EvaluationError)


def content_key(drive: Drive) -> str:
    """Hash of everything that decides the result: project version, the effective config (and
    its DBC files), the CAN log, the GNSS capture(s) and the truth."""
    h = hashlib.sha256(f"ecu-daemon {__version__}\n".encode())
    cfg = config_mod.load(drive.config)
    h.update(config_mod.to_toml(cfg).encode())
    files = [cfg.dbc_path(), cfg.output_dbc_path(), drive.can, *drive.gnss] + ([drive.truth] if drive.truth else [])
    for f in files:
        h.update(f"\n{Path(f).name}\n".encode())
        with open(f, "rb") as fh:
            for chunk in iter(lambda: fh.read(1 << 20), b""):
                h.update(chunk)
    if drive.start_latency_s is not None:
        h.update(f"\nstart latency {drive.start_latency_s!r}\n".encode())
    return h.hexdigest()[:40]


def run_drive(drive: Drive, store_dir: str) -> dict:
    """The drive's record: stored, or computed now (and stored unless the failure was unexpected)."""
    store = ResultStore(store_dir)
    base = {"vehicle": drive.vehicle, "drive": drive.drive}
    try:
        key = content_key(drive)
    except (OSError, *INPUT_ERRORS) as e:
        return {**base, "status": "error", "error": _one_line(e), "cached": False, "wall_s": 0.0}
    done = store.load(key)
    if done is not None:
        return {**done, **base, "cached": True}
    started, cpu = time.perf_counter(), time.process_time()
    keep = True
    try:
        with _replay_log_quiet():
            rec = {**base, "status": "ok", "error": "", **replay_and_score(drive)}
    except INPUT_ERRORS as e:
        rec = {**base, "status": "error", "error": _one_line(e)}
    except Exception as e:  # noqa: BLE001 - a bug on one drive is that drive's row, not the fleet's end
        rec = {**base, "status": "error", "error": _one_line(e)}
        keep = False
    # wall and CPU time of the job: on a shared machine the wall time also counts the others' load
    rec.update(key=key, version=__version__, wall_s=time.perf_counter() - started, cpu_s=time.process_time() - cpu)
    if keep:
        store.save(key, rec)
    return {**rec, "cached": False}


def _one_line(e: BaseException) -> str:
    """The error as one line, the same wherever it ran: without the replay's note of where it kept
    the partial estimate (a temporary folder of this job, removed with it)."""
    text = str(e).splitlines()[0] if str(e) else ""
    text = text.split("; output so far kept in ")[0]
    return f"{e.__class__.__name__}: {text}" if not isinstance(e, UserError) else text


@contextlib.contextmanager
def _replay_log_quiet():
    """Without the replay's per-drive input table (INFO): thousands of drives, warnings only."""
    rlog = logging.getLogger("ecu_daemon.replay")
    level = rlog.level
    if rlog.getEffectiveLevel() == logging.INFO:
        rlog.setLevel(logging.WARNING)
    try:
        yield
    finally:
        rlog.setLevel(level)


def warm() -> None:
    """Import what a drive's replay needs (the estimator, decoders, C kernels): ~0.5-2 s per
    process. The local pool calls it in the parent before its workers fork (they start with it
    loaded: one import per run, not one per worker) and as their initializer (where they spawn)."""
    from ..estimator import core  # noqa: F401
    from .. import replay  # noqa: F401


def _replay(cfg, drive: Drive, est_csv: str) -> dict:
    from ..estimator.core import LEARNED_VERSION
    from ..replay import run_replay

    learned = None
    if drive.start_latency_s is not None:  # no std: the estimator's own prior width, as from the config
        learned = {"version": LEARNED_VERSION, "gnss_delay_s": drive.start_latency_s}
    return run_replay(cfg, drive.can, list(drive.gnss), est_csv, config_path=drive.config,  # one per receiver
                      learned=learned)


def replay_and_score(drive: Drive) -> dict:
    """Summary counts, validity fractions, learned parameters with 1-sigma, and (with truth) the
    errors and the true parameters; SI, NaN where a figure does not exist."""
    cfg = config_mod.load(drive.config)
    with tempfile.TemporaryDirectory(prefix="ecu-fleet-") as tmp:
        est_csv = str(Path(tmp) / "estimate.csv")
        t0 = time.perf_counter()
        summary = _replay(cfg, drive, est_csv)
        replay_s = time.perf_counter() - t0
        est = read_numeric_csv(est_csv, ESTIMATE_REQUIRED + VALIDITY[2:], "estimate CSV")
    gnss = summary["inputs"].get("gnss", {})
    out = {"duration_s": float(summary["duration_s"]), "frames": int(summary["frames"]),
           "gnss_samples": int(summary["gnss_samples"]), "gnss_fused": int(gnss.get("fused", 0)),
           "gnss_rejected": int(gnss.get("rejected", 0)), "gaps": int(summary["gaps"]),
           "late_inputs": int(summary["late_inputs"]), "steps": int(summary["steps"]),
           "replay_s": replay_s}  # wall time in the replay itself (a timing, kept out of the tables)
    for v in VALIDITY:
        out[f"{v}_fraction"] = float(np.mean(est[v] > 0.5)) if len(est[v]) else math.nan
    out["start_latency_s"] = math.nan if drive.start_latency_s is None else float(drive.start_latency_s)
    out.update(learned_parameters(summary["learned"], summary.get("learned_std", {}), cfg, drive.start_latency_s))
    if drive.truth:
        out.update(truth_scores(read_numeric_csv(drive.truth, TRUTH_REQUIRED, "truth CSV"), est))
    return out


def read_numeric_csv(path: str, required: tuple[str, ...], what: str) -> dict[str, np.ndarray]:
    """``evaluate.read_csv``'s columns, parsed by pyarrow's C++ reader when the file is plain
    numbers with the required columns and time in order (the estimate CSV and a simulator's truth
    always are): the Python parser took ~15 % of a drive's job. Anything else (booleans as words,
    a bad cell, a missing column) goes to ``read_csv`` itself, for its values and its one-line
    errors."""
    import pyarrow as pa
    import pyarrow.csv as pacsv

    try:
        table = pacsv.read_csv(path, read_options=pacsv.ReadOptions(use_threads=False))
        cols = {}
        for name in table.column_names:
            c = table[name]
            if not (pa.types.is_floating(c.type) or pa.types.is_integer(c.type)) or c.null_count:
                raise ValueError(name)
            cols[name.strip()] = c.to_numpy().astype(float)
        t = cols["t"]
        ok = all(c in cols for c in required) and len(t) > 0 and np.all(np.isfinite(t)) and not np.any(np.diff(t) < 0)
    except (pa.ArrowException, OSError, ValueError, KeyError):
        ok = False
    return cols if ok else read_csv(path, required, what)


def learned_parameters(learned: dict, std: dict, cfg: config_mod.Config, start_latency_s: float | None = None) -> dict:
    """The :data:`PARAMS` and their ``_std`` from the estimator's learned state; the cornering
    stiffness from a compliance kappa = m / C (std by first-order propagation), both axles from the
    drive's own regression on GNSS velocity (``kappa_*_drive``, ``estimator/fusion/
    stiffness_regression.py``). Its estimate leans on the drive's GNSS latency (a sample placed
    d_tau late reads ay d_tau of lateral velocity, as large as the slip itself at ~0.15 s), so the
    record also carries, per axle, :data:`STIFFNESS_EXTRA`: the stiffness's slope per second of
    latency, its std were the latency exact, and the latency it is for; the calibration moves every
    drive to the vehicle's combined latency with them. A value still bit-identical to the
    config's prior was never learned on this drive: its std is NaN, so the calibration does not
    count the same prior once per drive (the latency's prior: ``start_latency_s`` when the drive
    started from one, else the config's)."""
    out = {}
    for name in ("gnss_delay_s", "wheel_scale", "steering_offset_rad", "yaw_rate_bias_radps"):
        out[name] = float(learned.get(name, math.nan))
        out[f"{name}_std"] = float(std.get(name, math.nan))
    if out["gnss_delay_s"] == (cfg.gnss.delay_s if start_latency_s is None else start_latency_s):
        out["gnss_delay_s_std"] = math.nan
    m = cfg.vehicle.mass_kg
    out["stiffness_latency_s"] = float(std.get("kappa_drive_latency_s", math.nan))
    for axle, k in (("front", "kappa_f_drive"), ("rear", "kappa_r_drive")):
        c = f"cornering_stiffness_{axle}_n_per_rad"
        kappa = float(learned.get(k, math.nan))
        learnt = kappa != m / getattr(cfg.vehicle, c)
        out[c] = m / kappa
        d = m / kappa ** 2  # |dC / dkappa|
        out[f"{c}_std"] = d * float(std.get(k, math.nan)) if learnt else math.nan
        out[f"{c}_std_given_latency"] = d * float(std.get(f"{k}_given_latency", math.nan)) if learnt else math.nan
        out[f"{c}_per_latency_s"] = -d * float(std.get(f"{k}_per_latency_s", math.nan))
    return out


def truth_scores(truth: dict, est: dict) -> dict:
    """RMS errors and 3-sigma coverage of the valid rows (``evaluate``'s figures), and ``true_*``
    for every learned parameter the truth file carries."""
    try:
        r = _evaluate(truth, est, SETTLE_S)
    except EvaluationError:
        r = {}
    out = {}
    for q, col in SCORED.items():
        s = r.get(q, {})
        out[f"{col}_rms"] = float(s.get("rms", math.nan))
        out[f"{col}_coverage_3sigma"] = float(s.get("validity", {}).get("coverage_3sigma", math.nan))
    for name in PARAMS:
        out[f"true_{name}"] = float(truth[name][-1]) if name in truth else math.nan
    return out
