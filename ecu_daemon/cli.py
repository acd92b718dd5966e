"""Command line: run | replay | demo | show-config | evaluate | simulate | monitor.

Each subcommand's module contributes its own options (``add_arguments``) and entry point
(``main(args) -> int``) and is imported lazily, so ``show-config`` does not pay for numpy or
python-can. Every command logs through the same set-up (``io/logging_setup.py``, ``--log-level``).
Every expected failure (bad config, unreadable file) ends as one line on stderr and a non-zero
exit status, never a traceback: 2 for a bad option, file or config, 3 for a replay that ran to
the end but never had a usable sample of a required input.
"""
from __future__ import annotations

import argparse
import importlib
import os
import sys

from . import __version__
from .errors import UserError

#: subcommand -> (module, help)
SUBCOMMANDS = {
    "run": ("ecu_daemon.daemon", "run the live daemon on a CAN bus and a GNSS serial port"),
    "replay": ("ecu_daemon.replay", "run the estimator offline on a CAN log (+ GNSS capture)"),
    "demo": ("ecu_daemon.demo", "live daemon on a built-in simulated drive (virtual bus + pseudo-terminal)"),
    "show-config": ("ecu_daemon.cli", "print the effective configuration as TOML"),
    "evaluate": ("ecu_daemon.evaluate", "score a replay CSV against simulator truth, with plots"),
    "simulate": ("ecu_daemon.sim.cli", "simulate a drive: CAN log, GNSS capture, truth CSV"),
    "monitor": ("ecu_daemon.monitor", "live terminal view of a running daemon, decoded from its CAN outputs"),
    "fleet": ("ecu_daemon.fleet.cli", "replay, score and calibrate a fleet's drives (local pool or Dask)"),
}


def add_arguments(parser: argparse.ArgumentParser) -> None:  # show-config
    parser.add_argument("--config", "-C", help="TOML configuration file (default: built-in defaults)")


def main_show_config(args: argparse.Namespace) -> int:
    from . import config

    cfg = config.load(args.config)
    sys.stdout.write(config.to_toml(cfg))
    return 0


def build_parser() -> tuple[argparse.ArgumentParser, dict]:
    parser = argparse.ArgumentParser(prog="ecu-daemon", description=__doc__.splitlines()[0])
    parser.add_argument("--version", action="version", version=f"ecu-daemon {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    entries = {}
    for name, (modname, help_) in SUBCOMMANDS.items():
        p = sub.add_parser(name, help=help_, description=help_)
        if name == "show-config":
            add_arguments(p)
            entries[name] = main_show_config
            continue
        try:
            mod = importlib.import_module(modname)
        except ImportError as e:  # a module still missing must not break the other commands
            entries[name] = _unavailable(name, e)
            continue
        mod.add_arguments(p)
        entries[name] = mod.main
    for p in sub.choices.values():  # one logging set-up for every command (``run`` has its own option)
        _add_log_level(p, None)
    return parser, entries


def _add_log_level(p: argparse.ArgumentParser, default) -> None:
    """``--log-level`` on a command and on each of its actions (``fleet run --log-level ...``).

    An action's option defaults to SUPPRESS so that ``fleet --log-level warning run`` keeps the
    level given before the action."""
    try:
        p.add_argument("--log-level", choices=("debug", "info", "warning", "error"), default=default,
                       help="log level of the lines on stderr (default: info)")
    except argparse.ArgumentError:
        pass  # ``run`` has its own (it overrides [daemon] log_level)
    for action in p._actions:
        if isinstance(action, argparse._SubParsersAction):
            for nested in action.choices.values():
                _add_log_level(nested, argparse.SUPPRESS)


def _unavailable(name, err):
    def fail(args):
        raise UserError(f"'{name}' is not available: {err}")

    return fail


def main(argv: list[str] | None = None) -> int:
    from .config import ConfigError

    parser, entries = build_parser()
    args = parser.parse_args(argv)
    if not args.command:
        parser.print_help()
        return 2
    from .io.logging_setup import setup_logging

    setup_logging(getattr(args, "log_level", None) or "info")
    try:
        return int(entries[args.command](args) or 0)
    except (ConfigError, UserError) as e:
        prio = "<3>" if os.environ.get("JOURNAL_STREAM") else ""  # journald: an error entry
        print(f"{prio}ecu-daemon {args.command}: error: {e}", file=sys.stderr)
        return getattr(e, "exit_code", 2)
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:
        return 0


if __name__ == "__main__":
    raise SystemExit(main())
