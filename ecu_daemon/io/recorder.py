"""``--record DIR``: what the live daemon received, in the formats ``ecu-daemon replay`` reads.

Files (all stamped on the daemon's monotonic clock, the same one the estimator used):

* ``can.log``  -- every received input frame, candump ``-L`` format, timestamps already converted
  to the monotonic clock and rounded to 1 us exactly as the estimator saw them;
* ``gnss.log`` -- every chunk of bytes read from the GNSS port, in the GNSS capture format,
  stamped with its receive time; ``gnss2.log``, ... for the further receivers of a
  ``[[gnss.receiver]]`` list;
* ``estimates.csv`` -- the published estimates (validity as sent), one row per step, in the
  format of ``replay --out-csv``;
* ``outputs.log`` -- the frames the daemon sent, candump ``-L``, stamped with the tick time;
* ``ticks.log`` -- the tick record (:class:`~ecu_daemon.pipeline.TickRecord`): what the time
  rule does not say about when each input reached the estimator.

``ecu-daemon replay --can DIR/can.log --gnss DIR/gnss.log [--gnss DIR/gnss2.log ...]`` follows
``ticks.log`` and writes the frames of ``outputs.log`` and the rows of ``estimates.csv`` again,
byte for byte. All writes happen in the event-loop thread; :meth:`flush` runs periodically and
on SIGTERM, so a stopped daemon leaves complete files.
"""
from __future__ import annotations

import logging
from pathlib import Path

import can

from ..canlog import CandumpWriter, CanLogError
from ..gnss.logfile import GnssLogWriter
from ..errors import UserError
from ..estimate_csv import csv_header, format_rows

log = logging.getLogger("ecu_daemon.record")


class Recorder:
    def __init__(self, directory: str | Path, *, can_channel: str = "can0", gnss_port: str = "ttyACM0",
                 extra_gnss_ports: list[str] = ()) -> None:
        self.dir = Path(directory)
        try:
            self.dir.mkdir(parents=True, exist_ok=True)
            self.can = CandumpWriter(self.dir / "can.log", channel=can_channel)
            self.outputs = CandumpWriter(self.dir / "outputs.log", channel=can_channel)
            self.gnss = GnssLogWriter(self.dir / "gnss.log", gnss_port)
            self.gnss_extra = [GnssLogWriter(self.dir / f"gnss{i + 2}.log", port)
                               for i, port in enumerate(extra_gnss_ports)]
            self._csv = open(self.dir / "estimates.csv", "w", encoding="ascii", newline="\n")
            self._ticks = open(self.dir / "ticks.log", "w", encoding="ascii", newline="\n")
        except (OSError, CanLogError) as e:
            raise UserError(f"cannot record into {self.dir}: {getattr(e, 'strerror', None) or e}") from None
        self._csv.write(csv_header())
        self.frames = 0
        self.gnss_messages = 0
        self.estimates = 0
        self.write_errors = 0
        self._closed = False

    def _guard(self, fn, *args) -> None:
        if self._closed:
            return
        try:
            fn(*args)
        except (OSError, ValueError) as e:  # disk full etc.: keep the daemon running, say so
            self.write_errors += 1
            log.error("recording into %s failed: %s", self.dir, e)

    def on_can(self, t: float, msg: can.Message) -> None:
        """A received frame (data or error frame) stamped with its monotonic receive time."""
        self.frames += 1
        self._guard(self.can.write_frame, t, msg.arbitration_id, bytes(msg.data), msg.is_extended_id,
                    msg.is_error_frame)

    def on_tick_record(self, line: str) -> None:
        self._guard(self._ticks.write, line)

    def on_gnss(self, t: float, payload: bytes, receiver: int = 0) -> None:
        self.gnss_messages += 1
        self._guard((self.gnss_extra[receiver - 1] if receiver else self.gnss).write, t, payload)

    def on_output(self, t: float, msg: can.Message) -> None:
        self._guard(self.outputs.write_frame, t, msg.arbitration_id, bytes(msg.data), False, False)

    def on_estimates(self, ests: list) -> None:
        """A tick's published estimates (one, or the steps of a catch-up), formatted together."""
        self.estimates += len(ests)
        self._guard(self._csv.write, format_rows(ests))

    def flush(self) -> None:
        for f in (self.can, self.outputs, self.gnss, *self.gnss_extra, self._csv, self._ticks):
            self._guard(f.flush)

    def close(self) -> None:
        if self._closed:
            return
        self.flush()
        for f in (self.can, self.outputs, self.gnss, *self.gnss_extra, self._csv, self._ticks):
            self._guard(f.close)
        self._closed = True

