"""Assemble the daemon's :class:`~ecu_daemon.diagnostics.Diagnostics` from its parts.

The parts keep their own counters (decoder per input, GNSS parser stats, serial port, bus
health, tick statistics); this module only reads them: the host's part in the event-loop thread
a few times a second (:func:`host_status`), the rest in the pipeline on the step grid
(:func:`build_diagnostics`), so that a replay of a recording builds the same EST_DIAG frames.
"""
from __future__ import annotations

import math
import os
import time

from ..diagnostics import BUS_ACTIVE, BUS_NOT_AVAILABLE, BUS_OFF, BUS_PASSIVE, Diagnostics, HostStatus
from ..estimator import source_status
from ..estimator.fault_detection import SOURCE_BITS
from ..estimator.fusion.gnss_heading import STATE_STALE
from ..estimator.fusion.magnetometer import STATE_STALE as MAG_STALE
from ..samples import GnssSample
from . import can_bus
from .tick import TickSnapshot

_BUS_MAP = {can_bus.BUS_ACTIVE: BUS_ACTIVE, can_bus.BUS_WARNING: BUS_ACTIVE,
            can_bus.BUS_PASSIVE: BUS_PASSIVE, can_bus.BUS_OFF: BUS_OFF}


class CpuMeter:
    """CPU use of this process in percent of one core, over the interval since the last call."""

    def __init__(self) -> None:
        self._wall = time.monotonic()
        self._cpu = time.process_time()
        self.pct = 0.0

    def update(self) -> float:
        wall, cpu = time.monotonic(), time.process_time()
        if wall - self._wall > 0.2:
            self.pct = 100.0 * (cpu - self._cpu) / (wall - self._wall)
            self._wall, self._cpu = wall, cpu
        return self.pct


def thread_cpu_s(native_id: int | None) -> float:
    """CPU seconds used by one thread of this process (Linux /proc), NaN if unknown."""
    if native_id is None:
        return math.nan
    try:
        with open(f"/proc/self/task/{native_id}/stat", "rb") as f:
            fields = f.read().rsplit(b")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    except (OSError, IndexError, ValueError):
        return math.nan


def build_diagnostics(t: float, *, decoder, gnss_stats: dict | None, gnss_last: GnssSample | None,
                      gnss_delay_s: float, host: HostStatus | None, gnss_connected: bool = False,
                      error_frames: int = 0, status: int = 0, isolation_events: dict | None = None,
                      gnss_heading=None, gnss_timeout_s: float = math.inf, mag=None,
                      mag_timeout_s: float = 0.25, road=None, roll_rate_t: float = -math.inf,
                      roll_rate_timeout_s: float = 0.25, baseline_configured: bool = False) -> Diagnostics:
    """The snapshot at step time ``t``. ``host``: the live host's part (:func:`host_status`);
    offline (replay of a foreign log) there is none: "not available" bus state, tick and CPU,
    ``gnss_connected`` as given and the log's own ``error_frames``. ``status``: the latest
    Estimate.status (its isolation bits); ``isolation_events``: the estimator's per-source
    isolation counts (``FaultDetector.events``); ``gnss_heading``: the estimator's
    ``GnssHeadingFusion`` (its last sample and what became of it), silent for longer than
    ``gnss_timeout_s`` reads as stale; ``mag``: the estimator's ``MagnetometerFusion`` (None: no
    magnetometer mapped), silent for longer than ``mag_timeout_s`` reads as stale; ``road``: the
    estimator's ``RoadAttitude`` (baseline elevations, roll gyro), ``roll_rate_t`` the time of the
    last roll-rate sample, ``baseline_configured`` a receiver has a baseline in the config; with
    them the per-source status codes of ``estimator/source_status.py``."""
    d = Diagnostics(inputs=decoder.input_diagnostics(t))  # not the default's inputs, replaced at once
    for name, src in d.sources.items():
        src.isolated = bool(status & SOURCE_BITS[name])
        src.events = (isolation_events or {}).get(name, 0)
    if gnss_last is not None:
        d.gnss_fix_type = gnss_last.fix_type if gnss_last.fix_ok else 0
        d.gnss_num_sv = gnss_last.num_sv
        d.gnss_speed_acc_mps = gnss_last.speed_acc_mps
        d.gnss_receive_age_ms = max(0.0, (t - gnss_last.t) * 1000.0)
    d.gnss_latency_ms = gnss_delay_s * 1000.0
    if gnss_stats:
        d.gnss_checksum_errors = gnss_stats.get("checksum_errors", 0)
        d.gnss_parse_errors = (gnss_stats.get("malformed", 0) + gnss_stats.get("truncated", 0)
                               + gnss_stats.get("garbage_bytes", 0))
    if gnss_heading is not None and gnss_heading.last is not None:
        g = gnss_heading.last
        d.gnss_heading_state = STATE_STALE if t - g.t > gnss_timeout_s else gnss_heading.state
        d.gnss_heading_carr_soln = g.carr_soln if 0 <= g.carr_soln <= 2 else 3
        d.gnss_heading_acc_rad = g.heading_acc_rad
        d.gnss_heading_baseline_m = g.baseline_m
        d.gnss_heading_fused = gnss_heading.fused
        d.gnss_heading_rejected = gnss_heading.rejected
    if mag is not None and math.isfinite(mag.last_t):
        d.mag_state = MAG_STALE if t - mag.last_t > mag_timeout_s else mag.state
        d.mag_field_norm_t = mag.norm
        d.mag_inclination_rad = mag.dip
        d.mag_offset_rad = mag.offset
        d.mag_offset_std_rad = math.sqrt(mag.offset_var)
        d.mag_rejected = mag.rejected
    if gnss_heading is not None:
        d.src_baseline = source_status.baseline_status(gnss_heading, baseline_configured, t, gnss_timeout_s)
    d.src_mag = source_status.mag_status(mag, t, mag_timeout_s)
    if road is not None:
        d.src_roll_gyro = source_status.roll_gyro_status(road, road.roll_gyro_params is not None, roll_rate_t, t,
                                                         roll_rate_timeout_s)
        d.src_baseline_elevation_rejected = road.elevation_rejected
        gy = road.gyro
        if gy is not None:
            d.src_roll_gyro_rejected = gy.rejected
            d.roll_gyro_bias_radps = float(gy.x[1])
            d.roll_gyro_bias_std_radps = math.sqrt(max(float(gy.P[1, 1]), 0.0))
    if host is None:
        d.gnss_serial_connected = gnss_connected
        d.can_bus_state = BUS_NOT_AVAILABLE
        d.can_error_frames = error_frames
        d.tick_late_p50_us = d.tick_late_p99_us = d.tick_late_max_us = math.nan
        d.cpu_load_pct = math.nan
    else:
        for name, v in zip(HostStatus._fields, host):
            setattr(d, name, v)
    return d


def host_status(*, bus: can_bus.BusHealth, tick: TickSnapshot, cpu_pct: float,
                gnss_connected: bool) -> HostStatus:
    """The live host's part of the diagnostics (see :class:`~ecu_daemon.diagnostics.HostStatus`)."""
    return HostStatus(bool(gnss_connected), _BUS_MAP.get(bus.state, BUS_ACTIVE), bus.error_frames,
                      bus.tx_failures, tick.late_p50_s * 1e6, tick.late_p99_s * 1e6, tick.late_max_s * 1e6,
                      tick.overruns, float(cpu_pct))


def gap_line(est) -> str:
    """The one line that says the estimator skipped a gap in its input (see ``Estimator._skip_gap``)."""
    t0, t1 = est.last_gap
    return (f"input gap: nothing from {t0:.3f} s to {t1:.3f} s ({t1 - t0:.6g} s, longer than the"
            f" {est.gap_s:g} s input timeouts): skipped, every input stale, estimator re-initialised"
            f" ({est.gaps} gap{'s' if est.gaps > 1 else ''} so far)")
