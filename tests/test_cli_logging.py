"""One logging set-up for every command: ``--log-level`` is taken wherever a user puts it after a
command or one of its actions (``fleet run --log-level warning`` was refused as an unknown
argument, and its value taken for the positional input)."""
from __future__ import annotations

import argparse
import subprocess
import sys

import pytest

from ecu_daemon import cli


def _command_paths(parser: argparse.ArgumentParser, prefix: tuple[str, ...] = ()):
    """(path, parser) of every command and nested action, e.g. ("fleet", "run")."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, p in action.choices.items():
                yield prefix + (name,), p
                yield from _command_paths(p, prefix + (name,))


def test_every_command_and_action_takes_log_level():
    parser, _ = cli.build_parser()
    paths = dict(_command_paths(parser))
    assert {("fleet", "run"), ("fleet", "calibrate"), ("fleet", "simulate"), ("replay",), ("run",)} <= set(paths)
    for path, p in paths.items():
        assert "--log-level" in p._option_string_actions, " ".join(path)


@pytest.mark.parametrize("argv, level", [
    (["fleet", "run", "--log-level", "debug", "IN", "--out", "OUT"], "debug"),
    (["fleet", "--log-level", "error", "run", "IN", "--out", "OUT"], "error"),  # before the action: kept
    (["fleet", "run", "IN", "--out", "OUT"], None),
    (["replay", "--log-level", "warning", "--config", "c", "--can", "l"], "warning"),
])
def test_the_level_reaches_the_set_up_wherever_it_is_given(argv, level):
    parser, _ = cli.build_parser()
    args = parser.parse_args(argv)
    assert args.log_level == level
    if argv[0] == "fleet":
        assert args.input == "IN"  # the level's value is not taken for the positional input


def test_fleet_action_with_log_level_fails_on_its_input_not_on_the_option(tmp_path):
    missing = tmp_path / "no-such-fleet"
    r = subprocess.run([sys.executable, "-m", "ecu_daemon", "fleet", "run", "--log-level", "warning", str(missing),
                        "--out", str(tmp_path / "out")], capture_output=True, text=True)
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert r.stderr.strip().splitlines() == [f"ecu-daemon fleet: error: fleet input {missing}: no such folder or manifest"]
