"""Replay of the CAN logs people bring: ASC/BLF on their own clock, several buses in one log,
output in the format the file name asks for, and the EST_DIAG frames the daemon also sends.

Every log here is written by the library that owns its format (python-can's ASC/BLF writers)
from a simulated drive's candump, and must replay to the candump original's estimates.
"""
from __future__ import annotations

import re

import can
import pytest

from ecu_daemon import cli, config as config_mod
from ecu_daemon.canlog import read_can_log
from ecu_daemon.diagnostics import BUS_NOT_AVAILABLE
from ecu_daemon.outputs import OutputEncoder, decode_output_frame
from ecu_daemon.sim import SCENARIOS, simulate, vehicle_config
from ecu_daemon.sim.writer import write_all

DIAG_ID = 0x320


@pytest.fixture(scope="module")
def drive(tmp_path_factory):
    d = tmp_path_factory.mktemp("drive")
    sc = SCENARIOS["slalom_dry"].with_(duration_s=20.0)
    write_all(d, simulate(sc, vehicle_config(sc)))
    return d


@pytest.fixture(scope="module")
def original(drive, tmp_path_factory):
    """The candump original's CSV and CAN output."""
    out = tmp_path_factory.mktemp("original")
    assert replay(drive, drive / "drive.log", out) == 0
    return out


def replay(drive, can_log, out, *extra, config=None, name="o"):
    return cli.main(["replay", "--config", str(config or drive / "config.toml"), "--can", str(can_log),
                     "--gnss", str(drive / "drive_gnss.log"), "--out-csv", str(out / f"{name}.csv"),
                     "--out-can", str(out / f"{name}.log"), "--no-progress", *extra])


def convert(src, writer, **kwargs):
    """Write every message of a candump log with one of python-can's writers."""
    w = writer(**kwargs)
    for m in read_can_log(src, messages=True):
        w.on_message_received(m)
    w.stop()


def last_error_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert err and "Traceback" not in "\n".join(err)
    return err[-1]


def test_asc_written_by_python_can_replays_to_the_candump_estimates(drive, original, tmp_path):
    # ASC dates the start in whole milliseconds; python-can's writer counts the times from the first
    # frame itself, so a log must start on a whole millisecond to survive the trip: here a frame no
    # input maps, at 1200.003 s (python-can writes that start as "00:20:00.3")
    log = tmp_path / "drive.log"
    log.write_text("(1200.003000) can0 7DF#0201050000000000\n" + (drive / "drive.log").read_text())
    asc = tmp_path / "drive.asc"
    convert(log, can.ASCWriter, file=str(asc))
    assert "00:20:00.3 1970" in asc.read_text()
    assert next(iter(read_can_log(asc)))[0] == 1200.003
    # python-can's own reader takes ".3" for 300 ms
    assert next(iter(can.ASCReader(str(asc), relative_timestamp=False))).timestamp == pytest.approx(1200.3)
    assert replay(drive, asc, tmp_path) == 0
    assert (tmp_path / "o.csv").read_bytes() == (original / "o.csv").read_bytes()
    assert [f[1:] for f in read_can_log(asc)] == [f[1:] for f in read_can_log(log)]
    assert all(abs(a[0] - b[0]) < 1e-9 for a, b in zip(read_can_log(asc), read_can_log(log)))


def test_blf_without_start_date_is_refused_then_lines_up_with_the_offset(drive, original, tmp_path, capsys):
    blf = tmp_path / "drive.blf"
    convert(drive / "drive.log", can.BLFWriter, file=str(blf))
    r = read_can_log(blf)
    first = next(r)[0]
    r.close()
    # the simulated clock starts at 1200 s: before 1990, so python-can's BLF writer stores no start date
    assert not r.absolute_time and first < 1.0
    assert replay(drive, blf, tmp_path) == 2
    line = last_error_line(capsys)
    assert "no start date" in line and "--can-time-offset" in line
    t0 = next(iter(read_can_log(drive / "drive.log")))[0]
    assert replay(drive, blf, tmp_path, "--can-time-offset", f"{int(t0 * 1000) / 1000:.3f}") == 0
    assert (tmp_path / "o.csv").read_bytes() == (original / "o.csv").read_bytes()


def test_can_log_on_another_clock_than_the_gnss_capture_is_refused(drive, original, tmp_path, capsys):
    shifted = tmp_path / "shifted.log"
    with open(shifted, "w") as f:
        for line in (drive / "drive.log").read_text().splitlines():
            t, rest = line.split(" ", 1)
            f.write(f"({float(t[1:-1]) + 3600.0:.6f}) {rest}\n")
    assert replay(drive, shifted, tmp_path) == 2
    line = last_error_line(capsys)
    assert re.search(r"\(-3599\.\d s apart\)", line) and "--can-time-offset" in line
    assert replay(drive, shifted, tmp_path, "--can-time-offset", "-3600") == 0
    assert (tmp_path / "o.csv").read_bytes() == (original / "o.csv").read_bytes()


@pytest.fixture(scope="module")
def two_buses(drive, tmp_path_factory):
    """The drive on can0, and on can1 the same frames with every data byte inverted (another bus)."""
    p = tmp_path_factory.mktemp("two") / "two.log"
    with open(p, "w") as f:
        for line in (drive / "drive.log").read_text().splitlines():
            f.write(line + "\n")
            head, _, data = line.rpartition("#")
            other = bytes(b ^ 0xFF for b in bytes.fromhex(data)).hex().upper()
            f.write(head.replace(" can0 ", " can1 ") + "#" + other + "\n")
    return p


def test_two_bus_log_without_a_choice_is_refused_listing_the_channels(drive, two_buses, tmp_path, capsys):
    assert replay(drive, two_buses, tmp_path) == 2
    line = last_error_line(capsys)
    n = len((drive / "drive.log").read_text().splitlines())
    assert f"can0 ({n} frames), can1 ({n} frames)" in line and "--can-channel" in line


def test_a_log_without_interface_names_is_refused_in_one_short_line_naming_the_first_line(drive, tmp_path,
                                                                                          capsys):
    """``(t) 0B4#...`` (no interface; canplayer refuses it too). Before: the channel scan took each
    frame for a channel, and the replay was refused with ONE line of 338 KB listing "10229 CAN
    channels: 0B0#00083EBC47F7D01E (1 frames), ..." (the 45 s slalom's 15000 frames)."""
    p = tmp_path / "noiface.log"
    p.write_text("".join(line.replace(" can0 ", " ", 1) + "\n"
                         for line in (drive / "drive.log").read_text().splitlines()))
    assert replay(drive, p, tmp_path) == 2
    line = last_error_line(capsys)
    assert line.startswith(f"ecu-daemon replay: error: {p}:1: no interface name before the frame"), line
    assert len(line) < 300


def test_a_log_of_many_channels_lists_the_busiest_and_counts_the_rest(drive, tmp_path, capsys):
    lines = (drive / "drive.log").read_text().splitlines()
    p = tmp_path / "many.log"
    p.write_text("".join(line.replace(" can0 ", f" can{k % 20} ", 1) + "\n" for k, line in enumerate(lines)))
    assert replay(drive, p, tmp_path) == 2
    line = last_error_line(capsys)
    assert "holds frames of 20 CAN channels: " in line and line.count(" frames)") == 8
    assert "and 12 more; choose one with --can-channel NAME" in line


@pytest.mark.parametrize("choice", ["can0", "vcan0=can0"])
def test_chosen_channel_replays_as_if_alone(drive, original, two_buses, tmp_path, choice):
    assert replay(drive, two_buses, tmp_path, "--can-channel", choice) == 0
    assert (tmp_path / "o.csv").read_bytes() == (original / "o.csv").read_bytes()


def test_configured_channel_is_used_when_the_log_has_several(drive, original, two_buses, tmp_path):
    cfg = tmp_path / "config.toml"
    cfg.write_text((drive / "config.toml").read_text().replace("[can]\n", '[can]\nchannel = "can0"\n', 1)
                   .replace('channel = "ecu-daemon"\n', ""))
    assert config_mod.load(cfg).can.channel == "can0"
    assert replay(drive, two_buses, tmp_path, config=cfg) == 0
    assert (tmp_path / "o.csv").read_bytes() == (original / "o.csv").read_bytes()


def test_unknown_channel_is_one_line(drive, two_buses, tmp_path, capsys):
    assert replay(drive, two_buses, tmp_path, "--can-channel", "can7") == 2
    line = last_error_line(capsys)
    assert "no frames on channel 'can7'" in line and "can1 (" in line


@pytest.mark.parametrize("suffix", [".blf", ".asc"])
def test_out_can_writes_the_format_of_the_extension(drive, original, tmp_path, suffix, capsys):
    out = tmp_path / f"o{suffix}"
    assert cli.main(["replay", "--config", str(drive / "config.toml"), "--can", str(drive / "drive.log"),
                     "--gnss", str(drive / "drive_gnss.log"), "--out-can", str(out), "--no-progress"]) == 0
    # the simulated clock (1200 s) has no BLF start date: said once, not silently lost (the CLI logs
    # through its own stderr handler)
    err = capsys.readouterr().err.splitlines()
    said = [line for line in err if "have no BLF start date" in line]
    assert len(said) == (suffix == ".blf")
    assert all(f" WARNING {out}: times before 1990" in line for line in said)  # the file asked for, not its .partial
    reader = can.ASCReader(str(out), relative_timestamp=False) if suffix == ".asc" else can.BLFReader(str(out))
    theirs = [(m.arbitration_id, bytes(m.data), m.timestamp) for m in reader]
    ours = [(fid, data, t) for t, fid, ext, err, data in read_can_log(original / "o.log")]
    assert [x[:2] for x in theirs] == [x[:2] for x in ours] and len(ours) > 1000
    if suffix == ".asc":  # absolute times, the start date in three-digit milliseconds
        assert all(abs(a[2] - b[2]) < 2e-6 for a, b in zip(theirs, ours))
    # and our reader reads it back to the candump output's times exactly (BLF: 1200 s is before 1990)
    if suffix == ".asc":
        assert [(t, fid, data) for t, fid, ext, err, data in read_can_log(out)] == [
            (t, fid, data) for fid, data, t in ours]


def test_replay_sends_est_diag_pages_with_live_only_fields_not_available(drive, original):
    cfg = config_mod.load(drive / "config.toml")
    db = OutputEncoder(cfg).db
    prev: dict = {}
    pages: dict = {}
    for t, fid, ext, err, data in read_can_log(original / "o.log"):
        values = decode_output_frame(db, can.Message(timestamp=t, arbitration_id=fid, is_extended_id=ext, data=data),
                                     prev.get(fid))
        prev[fid] = values["COUNTER"]
        if fid == DIAG_ID:
            pages[values["DIAG_PAGE"]] = (t, values)
    expected = {m.name: m for m in db.messages}
    assert {m.frame_id for m in expected.values()} == set(prev)  # every frame of the output DBC
    assert set(pages) == {0, 1, 2, 3, 4, 5, 6, 7, 16, 17, 18, 19, 20, 21, 22, 23, 32, 33, 34, 35, 36, 37, 48, 49, 50}
    assert pages[48][1]["CAN_BUS_STATE"] == BUS_NOT_AVAILABLE
    assert pages[49][1]["TICK_LATE_P50"] == 65535 and pages[49][1]["TICK_LATE_P99"] == 65535
    assert pages[49][1]["CPU_LOAD"] == 127.5 and pages[50][1]["TICK_LATE_MAX"] == 16777215
    # what the log does say: inputs received at their rate, GNSS fixes
    assert pages[0][1]["WS_FL_AGE"] < 100 and pages[0][1]["WS_FL_RATE"] > 10
    assert pages[32][1]["GNSS_FIX_TYPE"] >= 2 and pages[32][1]["GNSS_SERIAL_CONNECTED"] == 1
    assert pages[33][1]["GNSS_RX_AGE"] < 1000
    assert pages[36][1]["GNSS_HEADING_STATE"] == 0  # a velocity-only receiver: no heading ever received


def test_time_offset_must_be_finite(drive, tmp_path, capsys):
    assert replay(drive, drive / "drive.log", tmp_path, "--can-time-offset", "nan") == 2
    assert "--can-time-offset must be a finite number" in last_error_line(capsys)


def test_channel_appearing_after_the_scan_is_kept_out_and_reported(drive, original, two_buses, tmp_path,
                                                                    monkeypatch, capsys):
    """ASC/BLF logs are scanned for channels over their beginning only; a later channel is not mixed in."""
    from ecu_daemon import replay_input

    asc = tmp_path / "two.asc"
    convert(two_buses, can.ASCWriter, file=str(asc))
    monkeypatch.setattr(replay_input, "SCAN_FRAMES", 1)  # the scan sees channel 0 only
    assert replay(drive, asc, tmp_path) == 0
    n = len((drive / "drive.log").read_text().splitlines())
    err = capsys.readouterr().err.splitlines()  # the CLI logs through its own stderr handler
    assert [line.split(" WARNING ", 1)[1] for line in err if "not replayed" in line] == [
        f"{asc}: replayed channel 0 only; 1 ({n} frames) not replayed (choose with --can-channel)"]
    assert not [line for line in err if "CRC" in line]  # can1's inverted frames stayed out


@pytest.mark.parametrize("log,channel,want", [
    ("rec/can.log", "vcan0", "vcan0"),  # a daemon recording: its outputs.log names the daemon's bus
    ("rec/can.log", "ecu-daemon-demo-12", "ecu-daemon-demo-12"),
    ("drive.log", None, "can0"),  # no frames: nothing to name
    ("drive.asc", "0", "can0"),  # python-can formats number their channels: not a candump name
    ("drive.blf", "1", "can0"),
    ("drive.log.gz", "can1", "can0"),
])
def test_out_can_names_the_replayed_candump_channel(log, channel, want):
    from ecu_daemon.replay_input import output_channel

    assert output_channel(log, channel) == want
