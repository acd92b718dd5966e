"""The offline replay contract: CLI, file formats, determinism, one-line errors."""
from __future__ import annotations

import subprocess
import sys
import tomllib

import can
import pytest

from ecu_daemon import cli, config as config_mod
from ecu_daemon.canlog import read_can_log
from ecu_daemon.estimator import ESTIMATE_FIELDS
from ecu_daemon.outputs import OutputEncoder, decode_output_frame
from ecu_daemon.sim import SCENARIOS, simulate, vehicle_config
from ecu_daemon.sim.writer import write_all

CONTRACT_COLUMNS = ("t", "sideslip_rad", "sideslip_std_rad", "heading_rad", "heading_std_rad", "vx_mps",
                    "vy_mps", "yaw_rate_bias_radps", "accel_x_bias_mps2", "accel_y_bias_mps2",
                    "gnss_delay_s", "sideslip_valid", "heading_valid")


@pytest.fixture(scope="module")
def drive(tmp_path_factory):
    d = tmp_path_factory.mktemp("drive")
    sc = SCENARIOS["slalom_dry"].with_(duration_s=30.0)
    write_all(d, simulate(sc, vehicle_config(sc)))
    return d


def _replay(drive, out, *extra):
    args = ["replay", "--config", str(drive / "config.toml"), "--can", str(drive / "drive.log"),
            "--gnss", str(drive / "drive_gnss.log"), "--out-csv", str(out / "o.csv"),
            "--out-can", str(out / "o.log"), "--no-progress", *extra]
    return cli.main(args)


def test_two_replays_are_byte_identical(drive, tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    a.mkdir()
    b.mkdir()
    assert _replay(drive, a) == 0
    assert _replay(drive, b) == 0
    assert (a / "o.csv").read_bytes() == (b / "o.csv").read_bytes()
    assert (a / "o.log").read_bytes() == (b / "o.log").read_bytes()
    assert (a / "o.csv").stat().st_size > 100_000


def test_csv_columns_and_time_base(drive, tmp_path):
    assert _replay(drive, tmp_path) == 0
    lines = (tmp_path / "o.csv").read_text().splitlines()
    header = lines[0].split(",")
    assert tuple(header) == ESTIMATE_FIELDS
    assert all(c in header for c in CONTRACT_COLUMNS)
    t = [float(line.split(",", 1)[0]) for line in lines[1:]]
    steps = [round(x / 0.006) for x in t]
    assert steps == list(range(steps[0], steps[0] + len(steps)))  # every 6 ms step, once, in order
    first_can = next(iter(read_can_log(drive / "drive.log")))[0]
    assert abs(t[0] - first_can) < 0.006  # the input log's own time base


def test_output_can_log_decodes_with_counters_and_crcs(drive, tmp_path):
    assert _replay(drive, tmp_path) == 0
    cfg = config_mod.load(drive / "config.toml")
    db = OutputEncoder(cfg).db
    prev: dict = {}
    n = 0
    for t, fid, ext, err, data in read_can_log(tmp_path / "o.log"):
        msg = can.Message(timestamp=t, arbitration_id=fid, is_extended_id=ext, data=data)
        decode_output_frame(db, msg, prev.get(fid))  # raises on a bad CRC or counter
        prev[fid] = data[1] & 0x0F
        n += 1
    assert n > 1000 and {0x300, 0x301, 0x302} <= set(prev)


def test_malformed_can_log_is_one_line_and_exit_2(drive, tmp_path):
    bad = tmp_path / "bad.log"
    lines = (drive / "drive.log").read_text().splitlines()[:50]
    lines[20] = "(1000.5) can0 0B0#ZZ"
    bad.write_text("\n".join(lines) + "\n")
    r = subprocess.run([sys.executable, "-m", "ecu_daemon", "replay", "--config", str(drive / "config.toml"),
                        "--can", str(bad), "--out-csv", str(tmp_path / "x.csv")],
                       capture_output=True, text=True)
    assert r.returncode == 2
    err = r.stderr.strip().splitlines()
    assert len(err) == 1 and "bad.log:21" in err[0] and "Traceback" not in r.stderr


@pytest.mark.parametrize("what", ["missing_can", "missing_gnss", "bad_gnss", "bad_config"])
def test_bad_inputs_are_one_line_errors(drive, tmp_path, what):
    cfg, can_log, gnss = drive / "config.toml", drive / "drive.log", drive / "drive_gnss.log"
    if what == "missing_can":
        can_log = tmp_path / "nope.log"
    elif what == "missing_gnss":
        gnss = tmp_path / "nope_gnss.log"
    elif what == "bad_gnss":
        gnss = tmp_path / "g.log"
        gnss.write_text("(1000.000000) ttyACM0 B5620\n")
    else:
        cfg = tmp_path / "c.toml"
        cfg.write_text((drive / "config.toml").read_text().replace("mass_kg", "mas_kg"))
    r = subprocess.run([sys.executable, "-m", "ecu_daemon", "replay", "--config", str(cfg), "--can", str(can_log),
                        "--gnss", str(gnss), "--out-csv", str(tmp_path / "x.csv")], capture_output=True, text=True)
    assert r.returncode == 2, r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and "Traceback" not in r.stderr
    if what == "bad_config":
        assert "mas_kg" in r.stderr and "mass_kg" in r.stderr  # names the key and suggests the fix


def test_show_config_round_trips(tmp_path, capsys):
    assert cli.main(["show-config"]) == 0
    text = capsys.readouterr().out
    p = tmp_path / "c.toml"
    p.write_text(text)
    assert config_mod.to_dict(config_mod.load(p)) == tomllib.loads(text)


def test_state_file_carries_the_learned_state_into_the_next_replay(drive, tmp_path):
    """A restart mid-drive is two replays: the second starts from what the first learned."""
    import csv
    import json

    state = tmp_path / "state.json"
    first, second = tmp_path / "first", tmp_path / "second"
    first.mkdir()
    second.mkdir()
    assert _replay(drive, first, "--state", str(state)) == 0
    learned = json.loads(state.read_text())["learned"]
    assert learned["yaw_rate_bias_radps"] == pytest.approx(0.00873, abs=0.001)  # the sim's 0.5 deg/s
    assert _replay(drive, second, "--state", str(state)) == 0
    with open(second / "o.csv") as f:
        rows = list(csv.DictReader(f))
    with open(first / "o.csv") as f:
        fresh = list(csv.DictReader(f))
    started = next(r for r in rows if float(r["yaw_rate_bias_std_radps"]) > 0)
    fresh_start = next(r for r in fresh if float(r["yaw_rate_bias_std_radps"]) > 0)
    assert float(started["yaw_rate_bias_radps"]) == pytest.approx(learned["yaw_rate_bias_radps"], abs=1e-4)
    assert float(started["yaw_rate_bias_std_radps"]) < float(fresh_start["yaw_rate_bias_std_radps"])


def test_unreadable_state_file_is_one_line(drive, tmp_path, capsys):
    bad = tmp_path / "state.json"
    bad.write_text("{not json")
    assert _replay(drive, tmp_path, "--state", str(bad)) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "corrupt" in err
