"""`ecu-daemon replay` as a careless user runs it: outputs over inputs, broken files, bad timestamps,
inputs that never decode. Each ends as one clear line with a documented exit status, and nothing
the user had is lost."""
from __future__ import annotations

import gzip
import os
import random
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest
import tomli_w

from ecu_daemon import cli
from ecu_daemon.sim import SCENARIOS, simulate, vehicle_config
from ecu_daemon.sim.writer import write_all


@pytest.fixture(scope="module")
def drive(tmp_path_factory):
    d = tmp_path_factory.mktemp("drive")
    sc = SCENARIOS["slalom_dry"].with_(duration_s=12.0)
    write_all(d, simulate(sc, vehicle_config(sc)))
    return d


def replay(drive, *args, can=None, gnss=None, config=None, env=None):
    """Run the real command line in a subprocess: (exit status, stderr lines)."""
    argv = [sys.executable, "-m", "ecu_daemon", "replay", "--config", str(config or drive / "config.toml"),
            "--can", str(can or drive / "drive.log"), "--no-progress", *map(str, args)]
    if gnss is not None:
        argv += ["--gnss", str(gnss)]
    r = subprocess.run(argv, capture_output=True, text=True, env={**os.environ, **(env or {})})
    assert "Traceback" not in r.stderr, r.stderr
    return r.returncode, r.stderr.strip().splitlines()


def rows(path: Path) -> int:
    return len(path.read_text().splitlines()) - 1


def stamp(line: str) -> float:
    return float(line[1:line.index(")")])


def restamp(line: str, t: float) -> str:
    return f"({t:.6f})" + line[line.index(")") + 1:]


# ----------------------------------------------------------------------------------- outputs
@pytest.mark.parametrize("which", ["out_can_is_can", "out_csv_is_gnss", "out_csv_is_config",
                                   "outputs_are_one_file", "through_a_symlink"])
def test_an_output_naming_an_input_is_refused_before_anything_is_opened(drive, tmp_path, which):
    can_log, gnss = tmp_path / "in.log", tmp_path / "gnss.log"
    can_log.write_bytes((drive / "drive.log").read_bytes())
    gnss.write_bytes((drive / "drive_gnss.log").read_bytes())
    cfg = tmp_path / "c.toml"
    cfg.write_bytes((drive / "config.toml").read_bytes())
    before = {p: p.read_bytes() for p in (can_log, gnss, cfg)}
    out = {"out_can_is_can": ["--out-can", can_log], "out_csv_is_gnss": ["--out-csv", gnss],
           "out_csv_is_config": ["--out-csv", cfg],
           "outputs_are_one_file": ["--out-csv", tmp_path / "o", "--out-can", tmp_path / "o"]}.get(which)
    if which == "through_a_symlink":
        (tmp_path / "link.log").symlink_to(can_log)
        out = ["--out-can", tmp_path / "link.log"]
    rc, err = replay(drive, *out, can=can_log, gnss=gnss, config=cfg)
    assert rc == 2 and len(err) == 1 and "same file" in err[0] and "refusing" in err[0], err
    assert {p: p.read_bytes() for p in (can_log, gnss, cfg)} == before
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["in.log", "gnss.log", "c.toml"]
                                                                + (["link.log"] if "link" in which else []))


def test_outputs_appear_whole_at_the_end_and_no_temporary_file_is_left(drive, tmp_path):
    rc, _ = replay(drive, "--out-csv", tmp_path / "o.csv", "--out-can", tmp_path / "o.log",
                   gnss=drive / "drive_gnss.log")
    assert rc == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["o.csv", "o.log"]
    assert rows(tmp_path / "o.csv") > 1000 and (tmp_path / "o.log").stat().st_size > 10000
    assert oct((tmp_path / "o.csv").stat().st_mode & 0o777) == oct(0o666 & ~_umask())


def _umask() -> int:
    m = os.umask(0)
    os.umask(m)
    return m


def test_a_truncated_gz_input_is_one_line_and_loses_nothing(drive, tmp_path):
    """The channel scan reads the whole log before any output is opened, so a cut ``.gz`` is found
    before anything is written: the user's old output stays, and no partial file is left."""
    whole = gzip.compress((drive / "drive.log").read_bytes())
    cut = tmp_path / "cut.log.gz"
    cut.write_bytes(whole[: len(whole) * 2 // 3])
    old = tmp_path / "o.csv"
    old.write_text("what the user had\n")
    rc, err = replay(drive, "--out-csv", old, can=cut)
    assert rc == 2 and len(err) == 1, err
    assert "cut.log.gz:" in err[0] and "cut off or corrupt" in err[0]
    assert old.read_text() == "what the user had\n"  # nothing the user had is lost
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cut.log.gz", "o.csv"]


@pytest.mark.parametrize("where", ["missing_dir", "a_directory", "full_disk"])
def test_output_that_cannot_be_written_is_one_line_exit_2(drive, tmp_path, where):
    other = tmp_path / "o.log"
    if where == "missing_dir":
        target, expect = tmp_path / "nope" / "o.csv", "does not exist"
    elif where == "a_directory":
        target, expect = tmp_path, "is a directory"
    else:
        if not Path("/dev/full").exists():
            pytest.skip("no /dev/full on this system")
        target, expect = Path("/dev/full"), "No space left on device"
    rc, err = replay(drive, "--out-csv", target, "--out-can", other)
    assert rc == 2 and len(err) == 1 and expect in err[0], err
    if where == "full_disk":  # the CAN output written until the failure is flushed and kept
        assert "o.partial.log" in err[0]
        kept = (tmp_path / "o.partial.log").read_text().splitlines()
        assert kept and all(line.startswith("(") and line.count(" ") == 2 for line in kept)
    assert not other.exists()


# ----------------------------------------------------------------------------------- time
def _normal_rows(drive, tmp_path) -> int:
    rc, _ = replay(drive, "--out-csv", tmp_path / "ref.csv")
    assert rc == 0
    return rows(tmp_path / "ref.csv")


def test_a_stray_timestamp_far_ahead_is_dropped_not_stepped_to(drive, tmp_path):
    n_ref = _normal_rows(drive, tmp_path)
    lines = (drive / "drive.log").read_text().splitlines()
    i = len(lines) // 2
    lines[i] = restamp(lines[i], stamp(lines[i]) + 3000.0)  # one typo'd digit
    bad = tmp_path / "typo.log"
    bad.write_text("\n".join(lines) + "\n")
    rc, err = replay(drive, "--out-csv", tmp_path / "o.csv", can=bad)
    assert rc == 0
    assert abs(rows(tmp_path / "o.csv") - n_ref) <= 1  # not 500k rows; the good data after it is used
    assert sum("stray timestamp" in line for line in err) == 1


def test_a_jump_in_the_log_is_a_gap_skipped_with_one_line(drive, tmp_path):
    n_ref = _normal_rows(drive, tmp_path)
    lines = (drive / "drive.log").read_text().splitlines()
    i = len(lines) // 2
    lines[i:] = [restamp(x, stamp(x) + 1e7) for x in lines[i:]]
    bad = tmp_path / "jump.log"
    bad.write_text("\n".join(lines) + "\n")
    rc, err = replay(drive, "--out-csv", tmp_path / "o.csv", can=bad)
    assert rc == 0
    assert abs(rows(tmp_path / "o.csv") - n_ref) <= 2
    gap = [line for line in err if "input gap" in line]
    assert len(gap) == 1 and "re-initialised" in gap[0] and "1e+07 s" in gap[0], err


def test_a_gnss_line_far_ahead_at_the_end_does_not_create_rows(drive, tmp_path):
    n_ref = _normal_rows(drive, tmp_path)
    lines = (drive / "drive_gnss.log").read_text().splitlines()
    lines[-1] = restamp(lines[-1], stamp(lines[-1]) + 1e4)
    g = tmp_path / "g.log"
    g.write_text("\n".join(lines) + "\n")
    rc, err = replay(drive, "--out-csv", tmp_path / "o.csv", gnss=g)
    assert rc == 0
    assert rows(tmp_path / "o.csv") <= n_ref + 2


@pytest.mark.parametrize("how", ["reversed", "shuffled"])
def test_a_log_out_of_time_order_is_refused_with_one_line(drive, tmp_path, how):
    lines = (drive / "drive.log").read_text().splitlines()
    if how == "reversed":
        lines.reverse()
    else:
        random.Random(1).shuffle(lines)
    bad = tmp_path / "bad.log"
    bad.write_text("\n".join(lines) + "\n")
    rc, err = replay(drive, "--out-csv", tmp_path / "o.csv", can=bad)
    # (the frames that did go forward before the refusal may have logged their counter errors, and
    # the inputs their going stale: the CSV carries the validity as published, staleness included;
    # at most one line of each per input, the rate limit's)
    assert rc == 2 and "not in time order" in err[-1] and "sort" in err[-1], err
    assert sum("replay: error:" in line for line in err) == 1
    per_input = ("counter error", ": stale:", "receiving again")
    assert all(sum(kind in line for line in err) <= 8 for kind in per_input), err
    assert len([line for line in err if not any(kind in line for kind in per_input)]) <= 2, err
    assert not (tmp_path / "o.csv").exists()


# ----------------------------------------------------------------------------------- inputs
def _config_with(drive, tmp_path, names, key: str, was: str, now: str) -> Path:
    """The drive's config with ``[inputs.NAME] key`` changed from ``was`` (checked) to ``now``."""
    data = tomllib.loads((drive / "config.toml").read_text())
    for name in names:
        assert data["inputs"][name][key] == was
        data["inputs"][name][key] = now
    cfg = tmp_path / "c.toml"
    cfg.write_text(tomli_w.dumps(data))
    return cfg


def test_an_input_that_never_decodes_ends_with_the_table_and_exit_3(drive, tmp_path):
    # the IMU's checksum configured with the wrong scheme
    cfg = _config_with(drive, tmp_path, ("yaw_rate", "accel_x", "accel_y"), "checksum", "e2e_p2", "toyota")
    rc, err = replay(drive, "--out-csv", tmp_path / "o.csv", config=cfg)
    assert rc == 3, err
    table = {cells[0]: cells[1:] for cells in (line.split(" ", 2)[-1].split() for line in err)
             if cells and cells[0] in ("input", "wheel_speed_fl", "yaw_rate", "accel_x", "accel_y", "gnss")}
    assert table["input"] == ["frames", "used", "dlc", "decode", "range", "counter", "checksum"], err
    n = len([ln for ln in (drive / "drive.log").read_text().splitlines() if " 0B4#" in ln])  # IMU frames
    for name in ("yaw_rate", "accel_x", "accel_y"):  # seen, used, dropped by reason: all checksum
        frames, used, dlc, decode, rng, counter, checksum = map(int, table[name])
        assert frames == n > 1000 and used + checksum == frames and used < 0.01 * frames, table[name]
        assert dlc == decode == rng == counter == 0
    assert list(map(int, table["wheel_speed_fl"]))[1:] == [int(table["wheel_speed_fl"][0]), 0, 0, 0, 0, 0]
    final = err[-1]
    assert final.startswith("ecu-daemon replay: error: required input(s) not usable")
    assert "yaw_rate" in final and "accel_x" in final and "accel_y" in final and "checksum" in final
    assert "wheel_speed" not in final
    assert rows(tmp_path / "o.csv") > 1000  # the run went to the end; its output is there to look at


def test_a_counter_mapped_onto_a_value_signal_ends_with_exit_3(drive, tmp_path):
    """The raw wheel speed steps by exactly one now and then, so some frames pass the "counter"
    check: samples from a quarter of the frames, which is not an input."""
    wheels = [n for n in tomllib.loads((drive / "config.toml").read_text())["inputs"] if n.startswith("wheel_speed_")]
    cfg = _config_with(drive, tmp_path, wheels, "counter", "COUNTER", "WHEEL_SPEED_RR")
    rc, err = replay(drive, "--out-csv", tmp_path / "o.csv", config=cfg)
    assert rc == 3, err
    assert any("counter 'WHEEL_SPEED_RR' has scale" in line and "value signal?" in line for line in err), err
    final = err[-1]
    assert final.startswith("ecu-daemon replay: error: required input(s) not usable")
    assert all(n in final for n in wheels) and "counter" in final and "yaw_rate" not in final, final
    assert rows(tmp_path / "o.csv") > 1000


def test_replay_logs_through_the_common_set_up(drive, tmp_path):
    rc, err = replay(drive, "--out-csv", tmp_path / "o.csv", env={"JOURNAL_STREAM": "8:1234"})
    assert rc == 0
    assert err and all(line[:3] in ("<6>", "<4>") for line in err), err  # journald priorities
    assert any("inputs at the end of the replay" in line for line in err)
    rc, err = replay(drive, "--out-csv", tmp_path / "o.csv", "--log-level", "warning")
    assert rc == 0 and err == []
    rc, err = replay(drive, "--out-csv", drive / "drive.log", env={"JOURNAL_STREAM": "8:1234"})
    assert rc == 2 and len(err) == 1 and err[0].startswith("<3>ecu-daemon replay: error:")


def test_cli_error_line_is_the_last_line_in_process(drive, tmp_path, capsys):
    log = tmp_path / "in.log"
    log.write_bytes((drive / "drive.log").read_bytes())
    rc = cli.main(["replay", "--config", str(drive / "config.toml"), "--can", str(log), "--out-can", str(log)])
    assert rc == 2 and log.read_bytes() == (drive / "drive.log").read_bytes()
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("ecu-daemon replay: error:") and "same file" in err[0]


def test_a_gnss_log_that_never_gives_a_sample_is_exit_3(drive, tmp_path):
    g = tmp_path / "g.log"
    lines = (drive / "drive_gnss.log").read_text().splitlines()
    # every frame's checksum broken (UBX in hex, NMEA as text): counted, never a sample
    g.write_text("\n".join(x[:-2] + ("00" if x[-2:] != "00" else "11") for x in lines) + "\n")
    rc, err = replay(drive, gnss=g)
    assert rc == 3, err
    assert "not usable: gnss (0 of" in err[-1] and "checksum" in err[-1]
    assert not any("yaw_rate (" in line for line in err[-1:])


def test_wheel_speeds_in_kmh_mapped_as_mps_end_with_a_warning_naming_the_mapping(drive, tmp_path):
    """A DBC with wheel speeds in km/h (opendbc's Toyota, Honda...) mapped with scale 1: four wheels
    3.6x too fast outvote the one receiver, GNSS is rejected all drive long and vx is wrong.
    The replay still ends (exit 0: a receiver with poor accuracy does the same), but says so in one
    line, naming the likely mapping error; the same drive with the right mapping says nothing."""
    data = tomllib.loads((drive / "config.toml").read_text())
    for name in ("wheel_speed_fl", "wheel_speed_fr", "wheel_speed_rl", "wheel_speed_rr"):
        assert data["inputs"][name]["scale"] == 1.0
        data["inputs"][name].update(scale=3.6, max=500.0)
    cfg = tmp_path / "kmh.toml"
    cfg.write_text(tomli_w.dumps(data))
    rc, err = replay(drive, "--log-level", "warning", config=cfg, gnss=drive / "drive_gnss.log")
    assert rc == 0, err
    (line,) = [ln for ln in err if "gnss:" in ln]
    assert "rejected by the estimator" in line and "[inputs.wheel_speed_*] scale" in line and "3.6x" in line
    # and at the start, from the DBC's own unit (m/s here), one line per wheel naming its signal
    said = [ln for ln in err if "its DBC unit" in ln]
    assert len(said) == 4 and all(f"[inputs.wheel_speed_{c}] signal 'WHEEL_SPEED_{c.upper()}' is in m/s" in ln
                                  for c, ln in zip(("fl", "fr", "rl", "rr"), said)), said
    assert all("scale = 3.6 reads it 3.6x too large in m/s: m/s -> m/s is scale = 1" in ln for ln in said)
    rc, err = replay(drive, "--log-level", "warning", gnss=drive / "drive_gnss.log")
    assert rc == 0 and not any("gnss:" in ln or "DBC unit" in ln for ln in err), err


@pytest.mark.parametrize("capture, protocol, why", [
    ("ublox-lea-5q.log", "auto", "10 of 63 frames used; no usable fix in any of its 10 epochs"
                                 " (the receiver said no fix, or an estimated / simulated one)"),  # RMC status V
    ("ublox-lea-5q.log", "ubx", '0 of 63 frames used; protocol = "ubx" in [gnss], but the receiver sent its'
                                ' velocity as NMEA RMC/VTG (18 ignored); set protocol = "auto" (or "nmea")'),
    ("ublox-8-time.log", "ubx", None),  # a u-blox with a fix (NAV-SOL): no complaint
])
def test_a_gnss_capture_without_a_usable_fix_ends_with_exit_3_and_says_why(drive, tmp_path, capture, protocol, why):
    """A real receiver's session, recorded as the daemon records it, on the drive's clock. Before: the
    no-fix session ran to the end with exit 0, nothing fused and nothing said (10 samples of 63
    sentences, above the 10 % rule); with the simulator's protocol = "ubx" it said "0 of 63 frames used"."""
    from ecu_daemon.gnss import GnssStreamParser
    from ecu_daemon.gnss.logfile import GnssLogWriter, raw_capture_bytes

    log = tmp_path / "gnss.log"
    writer = GnssLogWriter(log)
    messages: list[bytes] = []
    parser = GnssStreamParser(raw_sink=lambda t, data: messages.append(data))
    parser.feed(0.0, raw_capture_bytes(Path(__file__).parent / "data" / "gnss" / "gpsd" / capture))
    parser.finish()
    t0 = stamp((drive / "drive.log").read_text().splitlines()[0])
    for k, data in enumerate(messages[:400]):
        writer.write(t0 + 0.02 * k, data)
    writer.close()
    data = tomllib.loads((drive / "config.toml").read_text())
    data["gnss"]["protocol"] = protocol
    cfg = tmp_path / "c.toml"
    cfg.write_text(tomli_w.dumps(data))
    rc, err = replay(drive, "--out-csv", tmp_path / "o.csv", gnss=log, config=cfg)
    if why is None:
        assert rc == 0 and not any("gnss (" in line for line in err), err
        return
    assert rc == 3, err
    final = err[-1]
    assert final.startswith("ecu-daemon replay: error: required input(s) not usable: gnss (" + why + ")"), final
    assert "wheel_speed" not in final and "yaw_rate" not in final and "DBC" not in final
