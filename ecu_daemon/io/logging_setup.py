"""stderr logging that journald reads well, with one line per problem and a rate limit.

One set-up for every command (``cli.main`` calls :func:`setup_logging` before dispatching):

* Under systemd (``$JOURNAL_STREAM`` set) lines carry a ``<N>`` syslog priority prefix, which
  journald turns into the entry's priority, and no timestamp (journald adds its own).
* On a terminal: ``HH:MM:SS.mmm LEVEL message``.
* Python warnings (``warnings.warn`` in a library) and the records of the libraries we use
  (python-can, cantools...) go through the same handler, so no bare line reaches stderr.

ONE rate limiter, :class:`RateLimitedLog`: the first line of a kind goes out, then at most one per
``interval_s`` per key, carrying the count of what was suppressed. Code that knows its kinds
(the decoder per input and error kind, the GNSS parser per error kind, on stream time) calls it
directly; :class:`RateLimitFilter` applies it to every record of the handler, keyed by logger and
message with its numbers blanked, so a CAN bus spewing bad frames at 1 kHz costs a handful of lines.
"""
from __future__ import annotations

import logging
import os
import sys
import re
import time
import warnings

_DIGITS = re.compile(r"0x[0-9A-Fa-f]+|[0-9]+(?:\.[0-9]+)?")
_PRIORITY = {logging.DEBUG: 7, logging.INFO: 6, logging.WARNING: 4, logging.ERROR: 3, logging.CRITICAL: 2}


class JournalFormatter(logging.Formatter):
    def format(self, record: logging.LogRecord) -> str:
        prio = _PRIORITY.get(record.levelno, 6)
        return f"<{prio}>{super().format(record)}"


class RateLimitedLog:
    """One log line per key at its first occurrence, then at most one per ``interval_s`` with a count.

    ``now``: the time of the event on the caller's clock (stream time for a parser that is also
    run offline); without it, ``clock()``. Time going backwards (a replay restarted) lets a line out.
    """

    def __init__(self, logger: logging.Logger | None, interval_s: float = 10.0, clock=time.monotonic):
        self.logger = logger
        self.interval_s = interval_s
        self.clock = clock
        self._state: dict = {}  # key -> [time of last line, occurrences suppressed since]

    def admit(self, key, now: float | None = None) -> int | None:
        """None: suppress (counted); else the number suppressed since the last admitted one."""
        now = self.clock() if now is None else now
        st = self._state.get(key)
        if st is None:
            if len(self._state) > 4096:  # bounded memory if keys are not templated
                self._state.clear()
            self._state[key] = [now, 0]
            return 0
        if not 0.0 <= now - st[0] < self.interval_s:
            more = st[1]
            st[0], st[1] = now, 0
            return more
        st[1] += 1
        return None

    def report(self, key, level: int, message: str, now: float | None = None) -> bool:
        """Log ``message`` now or count it; returns True if a line was written."""
        more = self.admit(key, now)
        if more is None:
            return False
        if more:
            self.logger.log(level, "%s (+%d more in the last %.0f s)", message, more, self.interval_s)
        else:
            self.logger.log(level, "%s", message)
        return True


class RateLimitFilter(logging.Filter):
    """:class:`RateLimitedLog` applied to every record of a handler (INFO and above)."""

    def __init__(self, interval_s: float = 10.0, clock=time.monotonic) -> None:
        super().__init__()
        self._limit = RateLimitedLog(None, interval_s, clock)

    def filter(self, record: logging.LogRecord) -> bool:
        if getattr(record, "unlimited", False) or record.levelno < logging.INFO:
            return True
        # key: the message with its numbers blanked, so "bad frame 0x1A" and "bad frame 0x1B" are
        # one kind while different texts logged through a bare "%s" template stay apart
        more = self._limit.admit((record.name, _DIGITS.sub("#", record.getMessage())[:120]))
        if more is None:
            return False
        if more:
            record.msg = f"{record.getMessage()} (+{more} similar suppressed)"
            record.args = None
        return True


class _StderrHandler(logging.StreamHandler):
    """Writes to whatever ``sys.stderr`` is at the time of the record (pytest's capture, a redirect)."""

    def __init__(self) -> None:
        super().__init__(sys.stderr)

    @property
    def stream(self):
        return sys.stderr

    @stream.setter
    def stream(self, value) -> None:
        pass


#: loggers of the libraries we use, routed through our handler (their own records and warnings)
_FOREIGN = ("py.warnings", "can", "cantools", "pyubx2", "serial", "matplotlib")


_SHOWWARNING = warnings.showwarning


def _warning_line(message, category, filename, lineno, file=None, line=None) -> None:
    """``warnings.warn`` as ONE log line (the stdlib's own format spans two, with the source)."""
    logging.getLogger("py.warnings").warning("%s: %s (%s:%s)", category.__name__, message, filename, lineno)


def setup_logging(level: str = "info", stream=None, interval_s: float = 10.0) -> logging.Logger:
    """Configure the ``ecu_daemon`` logger tree and the libraries' loggers (idempotent); returns
    the ``ecu_daemon`` logger. ``stream``: default the current ``sys.stderr`` at each record."""
    handler = _StderrHandler() if stream is None else logging.StreamHandler(stream)
    handler._ecu_daemon = True  # type: ignore[attr-defined]
    if os.environ.get("JOURNAL_STREAM"):
        handler.setFormatter(JournalFormatter("%(message)s"))
    else:
        handler.setFormatter(logging.Formatter("%(asctime)s.%(msecs)03d %(levelname)s %(message)s",
                                               datefmt="%H:%M:%S"))
    handler.addFilter(RateLimitFilter(interval_s))
    warnings.showwarning = _warning_line
    for name in ("ecu_daemon",) + _FOREIGN:
        lg = logging.getLogger(name)
        _remove_ours(lg)
        lg.addHandler(handler)
        lg.propagate = False
        if name != "ecu_daemon" and lg.level == logging.NOTSET:
            lg.setLevel(logging.WARNING)  # libraries: their warnings, not their chatter
            lg._ecu_daemon_level = True  # type: ignore[attr-defined]
    root = logging.getLogger("ecu_daemon")
    root.setLevel(level.upper())
    return root


def _remove_ours(lg: logging.Logger) -> None:
    for h in list(lg.handlers):
        if getattr(h, "_ecu_daemon", False):
            lg.removeHandler(h)


def reset_logging() -> None:
    """Undo :func:`setup_logging` (tests, embedding): records propagate to the root logger again."""
    warnings.showwarning = _SHOWWARNING
    for name in ("ecu_daemon",) + _FOREIGN:
        lg = logging.getLogger(name)
        _remove_ours(lg)
        if getattr(lg, "_ecu_daemon_level", False) or name == "ecu_daemon":
            lg.setLevel(logging.NOTSET)
            lg.__dict__.pop("_ecu_daemon_level", None)
        lg.propagate = True
