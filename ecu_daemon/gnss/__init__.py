"""GNSS input: receiver byte stream (UBX NAV-PVT/NAV-SOL/HNR-PVT/NAV-VELNED, NMEA RMC/VTG/GGA/GNS/ZDA/GST) -> GnssSample;
NAV-RELPOSNED, NMEA HDT/THS (dual-antenna heading) -> GnssHeadingSample.

* ``stream.GnssStreamParser`` -- framing, checksums, auto-detection, counters (the entry point).
* ``ubx`` / ``nmea`` -- message content -> SI samples (unit conversions happen there, once).
* ``logfile`` -- the GNSS capture log format (read, write, replay to samples).
* ``encode`` -- realistic receiver output for the simulator and tests.
"""
from .logfile import GnssLogError, GnssLogWriter, read_gnss_log, samples_from_log  # noqa: F401
from .stream import STAT_KEYS, GnssStreamParser  # noqa: F401
