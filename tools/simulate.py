#!/usr/bin/env python3
"""Simulate a drive from a source checkout: same as ``ecu-daemon simulate`` (see ``--help``)."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from ecu_daemon.cli import main  # noqa: E402

if __name__ == "__main__":
    raise SystemExit(main(["simulate", *sys.argv[1:]]))
