"""A :class:`SimResult` on disk, in exactly the formats ``ecu-daemon replay`` reads.

Files (all on the same clock, which starts at 1200.0 s):

* ``drive.log``: candump ``-L`` lines ``(%.6f) can0 ID#HEX`` (3 hex digits for 11-bit ids, 8 for
  29-bit), time-ordered by receive time.
* ``drive_gnss.log``: the GNSS capture log (:class:`~ecu_daemon.gnss.logfile.GnssLogWriter`);
  ``drive_gnss2.log`` the second receiver's, when the scenario has one.
* ``truth.csv``: one row per 6 ms (every 6th 1 kHz integration step; rows fall on the
  estimator's absolute 6 ms grid); column meanings in :meth:`SimResult.truth_table`.
* ``config.toml``: a config for this car (``ecu-daemon replay --config`` accepts it).
* ``scenario.json``: what was simulated (scenario, parameters, true cornering stiffness, spin).
"""
from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np

from ..canlog import CandumpWriter
from ..config import CanSettings, Config, to_toml
from ..gnss.logfile import GnssLogWriter
from .run import SimResult

CAN_LOG = "drive.log"
GNSS_LOG = "drive_gnss.log"
GNSS2_LOG = "drive_gnss2.log"
GNSS2_PORT = "ttyACM1"
TRUTH_CSV = "truth.csv"
CONFIG_TOML = "config.toml"
SCENARIO_JSON = "scenario.json"
GNSS_PORT = "ttyACM0"
CAN_CHANNEL = "can0"


def write_can_log(path: Path, result: SimResult) -> None:
    ext = result.extended_ids
    with CandumpWriter(path, CAN_CHANNEL) as w:
        for t, fid, data in result.can_frames:
            w.write_frame(t, fid, data, fid in ext)


def write_gnss_log(path: Path, result: SimResult, second: bool = False) -> None:
    """The first receiver's capture, or with ``second`` the second one's."""
    with GnssLogWriter(path, GNSS2_PORT if second else GNSS_PORT) as w:
        for t, payload in (result.gnss2_messages if second else result.gnss_messages):
            w.write(t, payload)


def write_truth_csv(path: Path, result: SimResult) -> None:
    table = result.truth_table()
    names = list(table)
    cols = np.column_stack([table[n] for n in names])
    fmt = ["%.6f"] + ["%.9g"] * (len(names) - 1)
    np.savetxt(path, cols, fmt=fmt, delimiter=",", header=",".join(names), comments="")


def portable_config(cfg: Config) -> Config:
    """``cfg`` with DBC paths that still resolve from another directory (absolute unless ours)."""
    out = dataclasses.replace(cfg, can=dataclasses.replace(cfg.can), base_dir=None)
    defaults = CanSettings()
    if cfg.can.dbc != defaults.dbc or cfg.base_dir is not None:
        out.can.dbc = str(cfg.dbc_path().resolve())
    if cfg.can.output_dbc != defaults.output_dbc or cfg.base_dir is not None:
        out.can.output_dbc = str(cfg.output_dbc_path().resolve())
    return out


def scenario_summary(result: SimResult) -> dict:
    sc = result.scenario
    cf, cr = sc.vehicle.axle_cornering_stiffness()
    tr = result.truth
    ay = np.abs(tr.col("ay"))
    return {
        "scenario": sc.name,
        "description": sc.description,
        "manoeuvre": sc.manoeuvre,
        "mu": sc.mu,
        "mu_change": None if sc.mu_change is None else list(sc.mu_change),
        "bank_rad": sc.bank_rad,
        "grade_rad": sc.grade_rad,
        "seed": sc.seed,
        "t0_s": result.t0,
        "t_end_s": result.t_end,
        "true_cornering_stiffness_n_per_rad": {"front": cf, "rear": cr},
        "understeer_gradient_rad_per_mps2": sc.vehicle.understeer_gradient(),
        "spun_out": result.spun_out,
        "spin_time_s": tr.spin_time,
        "max_abs_sideslip_deg": math.degrees(tr.max_abs_sideslip),
        "max_abs_ay_mps2": float(ay.max()),
        "can_frames": len(result.can_frames),
        "gnss_messages": len(result.gnss_messages),
        "vehicle": dataclasses.asdict(sc.vehicle),
        "sensors": dataclasses.asdict(sc.sensors),
        "gnss": dataclasses.asdict(sc.gnss),
        "dbc": str(result.config.dbc_path()),
    }


def write_all(out_dir: str | Path, result: SimResult, config: Config | None = None) -> dict[str, Path]:
    """Write every file into ``out_dir`` (created); ``config`` defaults to the encoding config."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = {k: out / v for k, v in (("can", CAN_LOG), ("gnss", GNSS_LOG), ("truth", TRUTH_CSV),
                                     ("config", CONFIG_TOML), ("scenario", SCENARIO_JSON))}
    write_can_log(paths["can"], result)
    write_gnss_log(paths["gnss"], result)
    if result.scenario.gnss2 is not None:
        paths["gnss2"] = out / GNSS2_LOG
        write_gnss_log(paths["gnss2"], result, second=True)
    write_truth_csv(paths["truth"], result)
    paths["config"].write_text(to_toml(portable_config(config or result.config)), encoding="utf-8")
    paths["scenario"].write_text(json.dumps(scenario_summary(result), indent=2, default=str) + "\n",
                                 encoding="utf-8")
    return paths
