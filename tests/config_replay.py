"""A simulated drive folder (drive.log, drive_gnss.log, truth.csv) replayed through the real command
line with another configuration: the wrong-configuration tests' one way in."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np


def replay_with(drive: Path, config: Path) -> tuple[np.ndarray, np.ndarray]:
    """(estimate rows, truth rows) as named arrays; the estimate CSV is written beside ``config``."""
    out = config.with_suffix(".csv")
    r = subprocess.run([sys.executable, "-m", "ecu_daemon", "replay", "--config", str(config),
                        "--can", str(drive / "drive.log"), "--gnss", str(drive / "drive_gnss.log"),
                        "--out-csv", str(out), "--no-progress", "--log-level", "error"],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    return (np.genfromtxt(out, delimiter=",", names=True),
            np.genfromtxt(drive / "truth.csv", delimiter=",", names=True))
