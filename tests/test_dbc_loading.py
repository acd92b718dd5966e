"""DBC loading: opendbc's IMPORT lines resolved (or refused naming the file), opendbc's dialect,
and the same log line from every command that loads a DBC."""
from __future__ import annotations

import logging
import re
import shutil
from pathlib import Path

import cantools
import pytest

from ecu_daemon import cli
from ecu_daemon.config import ConfigError
from ecu_daemon.dbc_loading import load_dbc

HONDA = Path(__file__).parent / "data" / "opendbc" / "generator" / "honda"
CIVIC = HONDA / "honda_civic_hatchback_ex_2017_can.dbc"
ROOT = Path(__file__).resolve().parents[1]
RAV4_LOG = Path(__file__).parent / "data" / "comma2k19" / "rav4_bus0_candump_5s.log"


def messages_defined(path: Path) -> set[str]:
    return set(re.findall(r"^BO_ \d+ (\w+):", path.read_text(encoding="cp1252"), re.M))


def test_imports_are_resolved_relative_to_the_dbc_folder(tmp_path, monkeypatch):
    imported = re.findall(r'IMPORT (\S+)"', CIVIC.read_text())
    assert len(imported) == 7
    # cantools alone reads the IMPORT lines as comments: a database without a single message
    assert cantools.database.load_file(str(CIVIC), strict=False).messages == []
    monkeypatch.chdir(tmp_path)  # relative to the DBC, not to the working directory
    db = load_dbc(CIVIC)
    want = set().union(*(messages_defined(HONDA / f) for f in imported))
    assert {m.name for m in db.messages} == want and len(want) > 40
    for name in ("WHEEL_SPEEDS", "KINEMATICS", "VEHICLE_DYNAMICS", "STEERING_SENSORS", "LKAS_HUD"):
        db.get_message_by_name(name)
    # opendbc's 29-bit ids written as plain numbers come out as extended frames
    assert db.get_message_by_name("LKAS_HUD_A").is_extended_frame


def test_missing_import_is_refused_naming_both_files(tmp_path):
    shutil.copy(CIVIC, tmp_path / CIVIC.name)
    for f in HONDA.glob("_*.dbc"):
        if f.name != "_lkas_hud_5byte.dbc":
            shutil.copy(f, tmp_path / f.name)
    with pytest.raises(ConfigError, match=r"honda_civic_hatchback_ex_2017_can.dbc imports _lkas_hud_5byte.dbc,"
                                          r" which cannot be read"):
        load_dbc(tmp_path / CIVIC.name)


def test_nested_and_repeated_imports_load_once(tmp_path):
    (tmp_path / "_a.dbc").write_text('CM_ "IMPORT _b.dbc";\nBO_ 100 A: 1 XXX\n SG_ X : 0|8@1+ (1,0) [0|255] "" XXX\n')
    (tmp_path / "_b.dbc").write_text('BO_ 101 B: 1 XXX\n SG_ Y : 0|8@1+ (1,0) [0|255] "" XXX\n')
    (tmp_path / "car.dbc").write_text('CM_ "IMPORT _a.dbc";\nCM_ "IMPORT _b.dbc";\nVERSION ""\n\n'
                                      'BO_ 102 C: 1 XXX\n SG_ Z : 0|8@1+ (1,0) [0|255] "" XXX\n')
    assert sorted(m.name for m in load_dbc(tmp_path / "car.dbc").messages) == ["A", "B", "C"]


def test_a_syntax_error_is_reported_in_the_file_and_line_where_it_is(tmp_path):
    (tmp_path / "_ok.dbc").write_text('BO_ 100 A: 1 XXX\n SG_ X : 0|8@1+ (1,0) [0|255] "" XXX\n')
    (tmp_path / "_bad.dbc").write_text('BO_ 101 B: 1 XXX\n SG_ Y : 0|8@1+ (1,0) [0|255] "" XXX\n\nBO_ oops\n')
    (tmp_path / "car.dbc").write_text('CM_ "IMPORT _ok.dbc";\nCM_ "IMPORT _bad.dbc";\n')
    with pytest.raises(ConfigError, match=r"car.dbc is not a valid DBC: .*line 4, column \d+ of _bad.dbc"):
        load_dbc(tmp_path / "car.dbc")


def test_every_command_loads_through_the_same_function_and_says_the_same(tmp_path, caplog, capsys):
    """replay logs the non-strict fallback as run does (it did not: run only)."""
    assert cli.main(["replay", "--config", str(ROOT / "examples" / "toyota_rav4.toml"), "--can", str(RAV4_LOG),
                     "--out-csv", str(tmp_path / "o.csv"), "--no-progress"]) == 0
    # the CLI logs through its own stderr handler: "HH:MM:SS.mmm LEVEL message"
    lines = [line.split(" ", 2)[2] for line in capsys.readouterr().err.splitlines() if "strict=False" in line]
    assert len(lines) == 1 and lines[0].startswith("[can] dbc: ") and "_toyota_2017.dbc fails cantools'" in lines[0]
    from ecu_daemon.io.logging_setup import reset_logging

    reset_logging()  # records reach caplog again
    caplog.clear()
    from ecu_daemon import config as config_mod
    from ecu_daemon.signals import SignalDecoder

    with caplog.at_level(logging.INFO, logger="ecu_daemon.dbc_loading"):
        SignalDecoder(config_mod.load(ROOT / "examples" / "toyota_rav4.toml"))  # what `run` builds
    assert [r.getMessage() for r in caplog.records if "strict=False" in r.getMessage()] == lines
