"""The shipped systemd template unit and the README section it points to, checked on the host.

The kernel tests boot the unit under a real systemd; these say, without UML, what a packager reads:
the devices allowed by class, no memory-lock limit the daemon has no use for, an ``ExecStart=``
that the CLI accepts where ``pip install`` puts the script, and the README's "Running under
systemd" covering install, enable, journal, watchdog and state directory.
"""
from __future__ import annotations

import re
import shlex
from pathlib import Path

from ecu_daemon.cli import build_parser

ROOT = Path(__file__).resolve().parents[1]
UNIT = ROOT / "systemd" / "ecu-daemon@.service"
SECTION = "## Running under systemd"


def directives(text: str) -> dict[str, list[str]]:
    """``Key=value`` lines of a unit file (continuations joined, comments dropped), every value kept."""
    out: dict[str, list[str]] = {}
    for line in re.sub(r"\\\n\s*", " ", text).splitlines():
        line = line.strip()
        if line and not line.startswith(("#", ";", "[")) and "=" in line:
            key, value = line.split("=", 1)
            out.setdefault(key.strip(), []).append(value.strip())
    return out


def readme_section() -> str:
    text = (ROOT / "README.md").read_text()
    assert SECTION in text
    return text.split(SECTION, 1)[1].split("\n## ", 1)[0]


def test_devices_are_allowed_by_class_not_by_path():
    allowed = directives(UNIT.read_text())["DeviceAllow"]
    assert sorted(allowed) == ["char-ttyACM rw", "char-ttyUSB rw"], allowed
    assert directives(UNIT.read_text())["DevicePolicy"] == ["closed"]


def test_no_memory_lock_limit_unless_the_daemon_locks_its_memory():
    calls_mlockall = any("mlockall" in p.read_text() for p in (ROOT / "ecu_daemon").rglob("*.py"))
    assert ("LimitMEMLOCK" in directives(UNIT.read_text())) == calls_mlockall


def test_exec_start_is_where_pip_puts_the_script_and_the_cli_accepts_it():
    d = directives(UNIT.read_text())
    (exec_start,) = d["ExecStart"]
    argv = shlex.split(exec_start.replace("%i", "can0").replace("${STATE_DIRECTORY}", "/var/lib/ecu-daemon/can0"))
    assert argv[0] == "/usr/local/bin/ecu-daemon"  # pip install as root, outside a venv
    args = build_parser()[0].parse_args(argv[1:])
    assert (args.command, args.interface, args.channel) == ("run", "socketcan", "can0")
    assert args.state_file == "/var/lib/ecu-daemon/can0/state.json"
    assert d["StateDirectory"] == ["ecu-daemon/%i"] and d["Type"] == ["notify"]
    # the script's place and how to link a venv's script there are documented where the unit points
    assert '"Running under systemd"' in UNIT.read_text()
    section = readme_section()
    assert "/usr/local/bin/ecu-daemon" in section and "ExecStart=" in section


def test_the_readme_section_covers_install_enable_journal_watchdog_and_state():
    section = readme_section()
    for topic in ("**Install.**", "**Enable.**", "**Journal.**", "**Watchdog.**", "**State directory.**"):
        assert topic in section, topic
    unit = directives(UNIT.read_text())
    assert f"WatchdogSec={unit['WatchdogSec'][0]}" in section
    assert "systemctl enable --now" in section and "journalctl -u ecu-daemon@can0" in section
    assert "StateDirectory=ecu-daemon/%i" in section
