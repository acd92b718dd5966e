"""A receiver that reports speed without course: speed is fused, heading is not (issue 9).

NMEA receivers blank the course field when slow or when their firmware says so; the parser then
publishes ``course_known=False`` with the speed, and the estimator must use it as a magnitude
measurement only (never as a zero vector, never to align the heading).
"""
from __future__ import annotations

import csv

import pytest

from ecu_daemon import cli
from ecu_daemon.estimator import estimate as est_mod
from ecu_daemon.gnss.logfile import read_gnss_log
from ecu_daemon.sim import SCENARIOS, simulate, vehicle_config
from ecu_daemon.sim.writer import write_all


def _blank_course(line: bytes) -> bytes:
    """An RMC/VTG sentence with its course field emptied and the checksum recomputed."""
    body = line.strip()[1:line.strip().rfind(b"*")].decode()
    f = body.split(",")
    if f[0][2:] == "RMC":
        f[8] = ""
    elif f[0][2:] == "VTG":
        f[1] = ""
    body = ",".join(f)
    ck = 0
    for c in body.encode():
        ck ^= c
    return f"${body}*{ck:02X}\r\n".encode()


@pytest.fixture(scope="module")
def replayed(tmp_path_factory):
    d = tmp_path_factory.mktemp("nocourse")
    sc = SCENARIOS["slalom_dry"].with_(duration_s=20.0, gnss_protocol="nmea")
    write_all(d, simulate(sc, vehicle_config(sc)))
    lines = []
    for t, port, payload in read_gnss_log(d / "drive_gnss.log"):
        lines.append(f"({t:.6f}) {port} {_blank_course(payload).decode().strip()}\n")
    (d / "nocourse_gnss.log").write_text("".join(lines))
    rc = cli.main(["replay", "--config", str(d / "config.toml"), "--can", str(d / "drive.log"),
                   "--gnss", str(d / "nocourse_gnss.log"), "--out-csv", str(d / "out.csv"), "--no-progress"])
    assert rc == 0
    with open(d / "out.csv") as f:
        return list(csv.DictReader(f)), sum("RMC" in line for line in lines)


def test_speed_without_course_is_fused_but_never_aligns_the_heading(replayed):
    replayed, epochs = replayed
    assert epochs > 50 and int(replayed[-1]["gnss_fused"]) >= 0.9 * epochs  # the speed is used
    assert not any(int(r["heading_valid"]) for r in replayed)
    assert not any(int(r["status"]) & est_mod.STATUS_HEADING_ALIGNED for r in replayed)
    assert all(int(r["velocity_valid"]) for r in replayed[len(replayed) // 2:])
