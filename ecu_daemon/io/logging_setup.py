"""stderr logging that journald reads well, with one line per problem and a rate limit.

* Under systemd (``$JOURNAL_STREAM`` set) lines carry a ``<N>`` syslog priority prefix, which
  journald turns into the entry's priority, and no timestamp (journald adds its own).
* On a terminal: ``HH:MM:SS.mmm LEVEL message``.
* :class:`RateLimitFilter` lets the first line of a kind through and then at most one per
  ``interval_s`` per (logger, message with numbers blanked); the next line that gets through says how many
  were suppressed. A CAN bus spewing bad frames at 1 kHz thus costs a handful of log lines.
"""
from __future__ import annotations

import logging
import os
import sys
import re
import time

_DIGITS = re.compile(r"0x[0-9A-Fa-f]+|[0-9]+(?:\.[0-9]+)?")
_PRIORITY = {logging.DEBUG: 7, logging.INFO: 6, logging.WARNING: 4, logging.ERROR: 3, logging.CRITICAL: 2}


class JournalFormatter(logging.Formatter):
    def format(self, record: logging.LogRecord) -> str:
        prio = _PRIORITY.get(record.levelno, 6)
        return f"<{prio}>{super().format(record)}"


class RateLimitFilter(logging.Filter):
    """At most one record per ``interval_s`` for each (logger, message kind), counting the rest."""

    def __init__(self, interval_s: float = 10.0, clock=time.monotonic) -> None:
        super().__init__()
        self.interval_s = interval_s
        self._clock = clock
        self._last: dict[tuple, float] = {}
        self._suppressed: dict[tuple, int] = {}

    def filter(self, record: logging.LogRecord) -> bool:
        if getattr(record, "unlimited", False) or record.levelno < logging.INFO:
            return True
        # key: the message with its numbers blanked, so "bad frame 0x1A" and "bad frame 0x1B" are
        # one kind while different texts logged through a bare "%s" template stay apart
        key = (record.name, _DIGITS.sub("#", record.getMessage())[:120])
        now = self._clock()
        last = self._last.get(key)
        if last is not None and now - last < self.interval_s:
            self._suppressed[key] = self._suppressed.get(key, 0) + 1
            return False
        self._last[key] = now
        n = self._suppressed.pop(key, 0)
        if n:
            record.msg = f"{record.msg} ({n} similar suppressed)"
        if len(self._last) > 4096:  # bounded memory if messages are not templated
            self._last.clear()
        return True


def setup_logging(level: str = "info", stream=None, interval_s: float = 10.0) -> logging.Logger:
    """Configure the ``ecu_daemon`` logger tree (idempotent) and return its root."""
    stream = sys.stderr if stream is None else stream
    root = logging.getLogger("ecu_daemon")
    for h in list(root.handlers):
        if getattr(h, "_ecu_daemon", False):
            root.removeHandler(h)
    handler = logging.StreamHandler(stream)
    handler._ecu_daemon = True  # type: ignore[attr-defined]
    if os.environ.get("JOURNAL_STREAM"):
        handler.setFormatter(JournalFormatter("%(message)s"))
    else:
        handler.setFormatter(logging.Formatter("%(asctime)s.%(msecs)03d %(levelname)s %(message)s",
                                               datefmt="%H:%M:%S"))
    handler.addFilter(RateLimitFilter(interval_s))
    root.addHandler(handler)
    root.setLevel(level.upper())
    root.propagate = False
    return root


def reset_logging() -> None:
    """Undo :func:`setup_logging` (tests, embedding): records propagate to the root logger again."""
    root = logging.getLogger("ecu_daemon")
    for h in list(root.handlers):
        if getattr(h, "_ecu_daemon", False):
            root.removeHandler(h)
    root.setLevel(logging.NOTSET)
    root.propagate = True
