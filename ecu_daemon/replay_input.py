"""Which frames of a CAN log a replay reads, and on which clock.

Two mistakes a log makes easy and that end in a replay that runs but means nothing:

* **two buses in one log** (candump ``-L`` of ``any``, an ASC of two channels): the same frame id
  from two buses mixes two streams (counter errors, a second car's wheel speeds). The replay
  keeps one channel, chosen as ``canplayer`` does (``--can-channel can1`` or ``can0=can1``:
  the log's ``can1`` plays as our ``can0``); with none chosen, a log of one channel is used as
  it is, a log of several uses the configured ``[can] channel`` if it is one of them and is
  refused otherwise, with the channels listed.
* **a CAN log and a GNSS capture on different clocks** (an ASC/BLF without a start date counts
  from 0; an ASC's local-time date against a Unix-time capture): nothing lines up, GNSS is
  never fused, and the replay still "works". A log without a start date, or one whose start is
  more than :data:`MAX_START_GAP_S` away from the capture's, is refused with the fix
  (``--can-time-offset SECONDS``, added to every CAN time; 0 accepts the times as they are).
"""
from __future__ import annotations

import logging
import math
from pathlib import Path

from .canlog import PYTHON_CAN_SUFFIXES, CanLogError, log_channels, read_can_log
from .errors import UserError
from .gnss.logfile import GnssLogError, read_gnss_log

log = logging.getLogger(__name__)

#: CAN log and GNSS capture starting further apart than this are taken to be on different clocks
MAX_START_GAP_S = 300.0
#: frames of an ASC/BLF/... log scanned for its channels
SCAN_FRAMES = 100_000


def parse_channel_option(text: str) -> str:
    """The log channel named by ``--can-channel``: ``NAME``, or canplayer's ``IF=NAME``."""
    name = text.rpartition("=")[2].strip()
    if not name:
        raise UserError(f"--can-channel {text!r}: expected a log channel name (NAME or IF=NAME)")
    return name


#: channels named in one message at most (the busiest); the rest are counted
MAX_LISTED = 8


def _listing(channels: dict[str, int]) -> str:
    busiest = sorted(sorted(channels.items()), key=lambda kv: -kv[1])[:MAX_LISTED]
    more = len(channels) - len(busiest)
    return (", ".join(f"{name or '(none)'} ({n} frames)" for name, n in sorted(busiest))
            + (f" and {more} more" if more > 0 else ""))


def choose_channel(can_path: str, option: str | None, configured: str) -> str | None:
    """The log channel a replay keeps (``None``: the log has no frames).

    A candump text log is scanned whole (~1 us per frame); other formats, read through python-can
    (9-17 us per frame), only over their first :data:`SCAN_FRAMES` frames: buses interleave, and a
    channel that only appears later is still kept out (the reader keeps the chosen channel) and
    reported.
    """
    try:
        channels = log_channels(can_path, SCAN_FRAMES)
    except CanLogError as e:
        raise UserError(str(e)) from None
    if option is not None:
        name = parse_channel_option(option)
        if name not in channels and sum(channels.values()) < SCAN_FRAMES:  # (a longer scan may have missed it)
            raise UserError(f"{can_path} has no frames on channel {name!r}; it has: {_listing(channels)}")
        return name
    if len(channels) <= 1:
        return next(iter(channels), None)
    if configured in channels:
        log.info("%s holds %d CAN channels; replaying [can] channel %s (choose another with --can-channel)",
                 can_path, len(channels), configured)
        return configured
    raise UserError(f"{can_path} holds frames of {len(channels)} CAN channels: {_listing(channels)};"
                    " choose one with --can-channel NAME (or canplayer's IF=NAME), or set [can] channel")


def output_channel(can_path: str, channel: str | None) -> str:
    """The channel the replay's ``--out-can`` candump lines name: the replayed candump log's own
    (the daemon sends its outputs on the bus it reads), ``can0`` for a log of another format or
    without frames.

    Why: a daemon recording's ``outputs.log`` names the daemon's bus (``vcan0``, the demo's
    ``ecu-daemon-demo-PID``); the replay of the recording wrote the same frames, byte for byte,
    but named them ``can0``, so ``cmp outputs.log out.log`` failed on every line (live49: four
    demo runs, frames and estimates identical, the files not)."""
    suffixes = {s.lower() for s in Path(can_path).suffixes[-2:]}
    candump = not (suffixes & {*PYTHON_CAN_SUFFIXES, ".gz"})
    if candump and channel and not any(c.isspace() for c in channel):
        return channel
    return "can0"


def report_other_channels(can_path: str, channel: str | None, seen: dict[str, int]) -> None:
    """One warning for frames of channels that only appeared after the scan and were not replayed."""
    others = {k: v for k, v in seen.items() if k != channel}
    if channel is not None and others:
        log.warning("%s: replayed channel %s only; %s not replayed (choose with --can-channel)", can_path,
                    channel, _listing(others))


def check_time_base(can_path: str, gnss_path: str | None, channel: str | None, time_offset: float | None) -> None:
    """Refuse a CAN log that cannot be lined up with the GNSS capture (see module doc)."""
    if time_offset is not None and not math.isfinite(time_offset):
        raise UserError(f"--can-time-offset must be a finite number of seconds, got {time_offset}")
    if gnss_path is None or time_offset is not None:
        return
    try:
        with read_can_log(can_path, channel=channel) as r:
            first = next(r, None)
            absolute = r.absolute_time
        gnss = read_gnss_log(gnss_path)
        g = next(gnss, None)
        gnss.close()
    except (CanLogError, GnssLogError) as e:
        raise UserError(str(e)) from None
    if first is None or g is None:
        return  # nothing to line up; reading reports what is missing
    gnss_t = g[0]
    if not absolute:
        raise UserError(f"{can_path} has no start date (its times count from 0), so it cannot be lined up with"
                        f" the GNSS capture (which starts at {gnss_t:.6f} s): give --can-time-offset SECONDS,"
                        " the time of the log's 0 on the capture's clock")
    gap = gnss_t - first[0]
    if abs(gap) > MAX_START_GAP_S:
        raise UserError(f"{can_path} starts at {first[0]:.6f} s and the GNSS capture at {gnss_t:.6f} s"
                        f" ({gap:+.1f} s apart): not on the same clock? line them up with --can-time-offset"
                        " SECONDS (added to every CAN time; 0 takes the times as they are)")
