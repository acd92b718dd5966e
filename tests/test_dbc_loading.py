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


# ------------------------------------------------------------------------------------ the parse cache

def _describe(db) -> list:
    """Everything the decoder, encoder and simulator read of a database, comparable."""
    return [(m.name, m.frame_id, m.is_extended_frame, m.length, m.cycle_time, m.comment,
             [(s.name, s.start, s.length, s.byte_order, s.is_signed, s.is_float, s.scale, s.offset,
               s.minimum, s.maximum, s.unit, s.choices and {int(k): str(v) for k, v in s.choices.items()},
               s.receivers, s.comment) for s in m.signals],
             dict(m.dbc.attributes) and sorted((k, a.value) for k, a in m.dbc.attributes.items()))
            for m in db.messages]


@pytest.mark.parametrize("dbc", [CIVIC, ROOT / "ecu_daemon" / "dbc" / "ecu_daemon_outputs.dbc",
                                 ROOT / "ecu_daemon" / "dbc" / "ecu_daemon_inputs.dbc"])
def test_a_cached_dbc_is_a_fresh_copy_of_what_parsing_gives(dbc, monkeypatch):
    from ecu_daemon import dbc_loading

    monkeypatch.setattr(dbc_loading, "_CACHE", type(dbc_loading._CACHE)())
    parses = []
    real = cantools.database.load_string
    monkeypatch.setattr(cantools.database, "load_string", lambda *a, **k: (parses.append(1), real(*a, **k))[1])
    first = load_dbc(dbc)
    n = len(parses)
    second, third = load_dbc(dbc), load_dbc(dbc)
    assert len(parses) == n  # not parsed again
    assert _describe(first) == _describe(second) == _describe(third) and len(first.messages) >= 5
    assert second is not third and second.messages[0] is not third.messages[0]
    m = second.messages[0]
    data = bytes(range(m.length))
    assert second.decode_message(m.frame_id, data) == first.decode_message(m.frame_id, data)
    second.messages[0].signals[0].scale = 12345.0  # a caller changing its copy changes no one else's
    assert load_dbc(dbc).messages[0].signals[0].scale == first.messages[0].signals[0].scale


def test_a_changed_dbc_or_import_is_parsed_again(tmp_path):
    (tmp_path / "_a.dbc").write_text('BO_ 101 A: 1 XXX\n SG_ Y : 0|8@1+ (1,0) [0|255] "" XXX\n')
    car = tmp_path / "car.dbc"
    car.write_text('CM_ "IMPORT _a.dbc";\nVERSION ""\n\nBO_ 102 C: 1 XXX\n SG_ Z : 0|8@1+ (1,0) [0|255] "" XXX\n')
    assert load_dbc(car).get_message_by_name("C").signals[0].scale == 1
    car.write_text(car.read_text().replace("(1,0)", "(2,0)"))
    assert load_dbc(car).get_message_by_name("C").signals[0].scale == 2
    (tmp_path / "_a.dbc").write_text('BO_ 101 A: 1 XXX\n SG_ Y : 0|8@1+ (0.5,0) [0|255] "" XXX\n')
    assert load_dbc(car).get_message_by_name("A").signals[0].scale == 0.5


def test_a_cached_dbc_says_its_lines_again(caplog):
    with caplog.at_level(logging.INFO, logger="ecu_daemon.dbc_loading"):
        load_dbc(CIVIC, "[can] dbc")
        first = [r.getMessage() for r in caplog.records]
        caplog.clear()
        load_dbc(CIVIC, "[x] other")
        again = [r.getMessage() for r in caplog.records]
    assert len(first) >= 2 and again == [m.replace("[can] dbc", "[x] other") for m in first]


def test_an_invalid_dbc_is_refused_every_time(tmp_path):
    (tmp_path / "bad.dbc").write_text('BO_ oops\n')
    for _ in range(2):
        with pytest.raises(ConfigError, match="is not a valid DBC"):
            load_dbc(tmp_path / "bad.dbc")
