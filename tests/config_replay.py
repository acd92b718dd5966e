"""A simulated drive folder (drive.log, drive_gnss.log, truth.csv) replayed through the real command
line with another configuration: the wrong-configuration tests' one way in."""
from __future__ import annotations

import subprocess
import sys
import tomllib
from pathlib import Path
from typing import Callable

import numpy as np
import tomli_w

from ecu_daemon.sim import simulate, vehicle_config
from ecu_daemon.sim.scenario import Scenario
from ecu_daemon.sim.writer import write_all


def simulated_drive(tmp_path_factory, name: str, scenario: Scenario) -> Path:
    """A fresh folder holding ``scenario`` simulated with its own (right) configuration."""
    d = tmp_path_factory.mktemp(name)
    write_all(d, simulate(scenario, vehicle_config(scenario)))
    return d


def replay_with(drive: Path, config: Path, log_level: str = "error",
                stderr: list[str] | None = None, state: Path | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(estimate rows, truth rows) as named arrays; the estimate CSV is written beside ``config``.
    ``stderr``: a list the replay's log lines (at ``log_level``) are appended to; ``state``: the
    learned-state file (``replay --state``)."""
    out = config.with_suffix(".csv")
    r = subprocess.run([sys.executable, "-m", "ecu_daemon", "replay", "--config", str(config),
                        "--can", str(drive / "drive.log"), "--gnss", str(drive / "drive_gnss.log"),
                        "--out-csv", str(out), "--no-progress", "--log-level", log_level]
                       + (["--state", str(state)] if state is not None else []),
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    if stderr is not None:
        stderr.extend(r.stderr.splitlines())
    return (np.genfromtxt(out, delimiter=",", names=True),
            np.genfromtxt(drive / "truth.csv", delimiter=",", names=True))


def replay_edited(drive: Path, edit: Callable[[dict], None], name: str, **kw) -> tuple[np.ndarray, np.ndarray]:
    """:func:`replay_with` on the drive's own config.toml changed by ``edit`` (saved as ``name``.toml)."""
    data = tomllib.loads((drive / "config.toml").read_text())
    edit(data)
    cfg = drive / f"{name}.toml"
    cfg.write_text(tomli_w.dumps(data))
    return replay_with(drive, cfg, **kw)


def replay_edited_here(drive: Path, edit: Callable[[dict], None], name: str) -> tuple[np.ndarray, np.ndarray]:
    """:func:`replay_edited` in this process (``run_replay``, no command line), so that an estimator flag
    the test sets (monkeypatch) holds."""
    from ecu_daemon import config as config_mod
    from ecu_daemon.replay import run_replay
    data = tomllib.loads((drive / "config.toml").read_text())
    edit(data)
    cfg = drive / f"{name}.toml"
    cfg.write_text(tomli_w.dumps(data))
    out = cfg.with_suffix(".csv")
    run_replay(config_mod.load(str(cfg)), str(drive / "drive.log"), str(drive / "drive_gnss.log"), out_csv=str(out))
    return (np.genfromtxt(out, delimiter=",", names=True),
            np.genfromtxt(drive / "truth.csv", delimiter=",", names=True))


def yaw_rate_scaled(k: float) -> Callable[[dict], None]:
    """A config edit: the gyro's mapping scaled by ``k`` (-1: a flipped sign, 1/57: degrees read as rad)."""
    def edit(data: dict) -> None:
        y = data["inputs"]["yaw_rate"]
        y["scale"] = y.get("scale", 1.0) * k
    return edit


def wrong_valid_rows(e: np.ndarray, t: np.ndarray) -> tuple[int, int, float]:
    """(vx rows valid beyond 3 std, sideslip rows valid beyond 3 std, vx valid share) of an
    estimate against its truth: the wrong-configuration tests' verdict on a promise."""
    vx = np.interp(e["t"], t["t"], t["vx_mps"])
    beta = np.interp(e["t"], t["t"], t["sideslip_rad"])
    v = e["velocity_valid"].astype(bool)
    b = e["sideslip_valid"].astype(bool)
    bad_v = v & (np.abs(e["vx_mps"] - vx) > 3.0 * e["vx_std_mps"])
    bad_b = b & (np.abs(e["sideslip_rad"] - beta) > 3.0 * e["sideslip_std_rad"])
    return int(bad_v.sum()), int(bad_b.sum()), float(v.mean())
