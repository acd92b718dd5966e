"""The daemon's health snapshot, as carried by the EST_DIAG frame of the output DBC.

The shell fills one :class:`Diagnostics` from the input decoder, the GNSS reader, the CAN bus and
the tick thread; ``outputs.py`` encodes it (one multiplexed page per frame). Plain numbers in
engineering units; ``inf``/``nan`` mean "never" / "unknown" and are encoded as such.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

from .estimator.fault_detection import SOURCE_BITS
from .samples import REQUIRED_INPUTS

# CAN controller state (EST_DIAG.CAN_BUS_STATE); same numbering as io/can_bus.py (ordinal = severity)
BUS_ACTIVE = 0
BUS_WARNING = 1
BUS_PASSIVE = 2
BUS_OFF = 3
BUS_NOT_AVAILABLE = 7  # offline (replay): no bus to have a state
BUS_STATE_NAMES = {BUS_ACTIVE: "active", BUS_WARNING: "warning", BUS_PASSIVE: "passive", BUS_OFF: "bus-off",
                   BUS_NOT_AVAILABLE: "not available"}

#: error kinds counted per input by the decoder (``signals.InputHealth.errors``)
ERROR_KINDS = ("dlc", "decode", "range", "counter", "checksum", "stale")


class HostStatus(NamedTuple):
    """The part of EST_DIAG only the live host knows (bus, tick, CPU, serial port); same names as
    the :class:`Diagnostics` fields it sets. A recording keeps it, so a replay sends the same."""

    gnss_serial_connected: bool
    can_bus_state: int
    can_error_frames: int
    can_tx_failures: int
    tick_late_p50_us: float
    tick_late_p99_us: float
    tick_late_max_us: float
    tick_overruns: int
    cpu_load_pct: float


@dataclass(slots=True)
class InputDiagnostics:
    """Health of one ``[inputs.NAME]`` signal. Error counts are cumulative (wrap on the wire)."""

    age_ms: float = math.inf  # since the last good sample; inf = never received
    rate_hz: float = 0.0  # good samples per second
    dlc_errors: int = 0
    decode_errors: int = 0
    range_errors: int = 0  # out of [min, max] or not finite
    counter_errors: int = 0
    checksum_errors: int = 0
    stale_count: int = 0  # times the input went stale


@dataclass(slots=True)
class SourceDiagnostics:
    """Fault isolation of one source (``estimator/fault_detection.py``: wheels, yaw_rate, ...)."""

    isolated: bool = False  # disagrees with the others now: not fused, dependent outputs invalid
    events: int = 0  # times it was isolated since start (wraps on the wire)


def _all_inputs() -> dict[str, InputDiagnostics]:
    return {name: InputDiagnostics() for name in REQUIRED_INPUTS}


def _all_sources() -> dict[str, SourceDiagnostics]:
    return {name: SourceDiagnostics() for name in SOURCE_BITS}


@dataclass(slots=True)
class Diagnostics:
    """One health snapshot of the whole daemon."""

    inputs: dict[str, InputDiagnostics] = field(default_factory=_all_inputs)  # keyed by input name (the mapped ones)
    sources: dict[str, SourceDiagnostics] = field(default_factory=_all_sources)  # keyed as SOURCE_BITS
    gnss_fix_type: int = 0  # samples.FIX_* numbering
    gnss_num_sv: int = 0
    gnss_speed_acc_mps: float = math.nan  # receiver's 1-sigma speed accuracy; nan = unknown
    gnss_receive_age_ms: float = math.inf  # since the last GNSS sample arrived; inf = never
    gnss_latency_ms: float = math.nan  # estimator's current latency estimate
    gnss_checksum_errors: int = 0
    gnss_parse_errors: int = 0
    gnss_serial_connected: bool = False
    # dual-antenna heading (estimator/fusion/gnss_heading.py STATE_*; nan = unknown / never)
    gnss_heading_state: int = 0
    gnss_heading_carr_soln: int = 3  # 0 none, 1 float, 2 fixed, 3 unknown (NMEA, or no heading yet)
    gnss_heading_acc_rad: float = math.nan  # receiver's 1-sigma
    gnss_heading_baseline_m: float = math.nan  # measured antenna distance
    gnss_heading_fused: int = 0
    gnss_heading_rejected: int = 0
    # magnetometer (estimator/fusion/magnetometer.py STATE_*), only with [inputs.mag_x/y/z]
    mag_state: int = 0
    mag_field_norm_t: float = math.nan  # of the last sample
    mag_inclination_rad: float = math.nan  # of the last sample, tilt-compensated, positive down
    mag_offset_rad: float = math.nan  # learned magnetic minus vehicle heading
    mag_offset_std_rad: float = math.nan
    mag_rejected: int = 0
    # per optional aiding source (estimator/source_status.py codes): used / rejected / timed out / isolated
    src_baseline: int = 0
    src_roll_gyro: int = 0
    src_mag: int = 0
    src_baseline_elevation_rejected: int = 0
    src_roll_gyro_rejected: int = 0
    roll_gyro_bias_radps: float = math.nan  # learned roll-rate gyro bias; nan = not learned yet
    roll_gyro_bias_std_radps: float = math.nan
    can_bus_state: int = BUS_ACTIVE
    can_error_frames: int = 0
    can_tx_failures: int = 0
    tick_late_p50_us: float = 0.0  # NaN = not available (replay)
    tick_late_p99_us: float = 0.0
    tick_late_max_us: float = 0.0
    tick_overruns: int = 0
    cpu_load_pct: float = 0.0  # percent of one core; NaN = not available (replay)

    def summary(self) -> str:
        """One human line (for systemd ``STATUS=`` and logs)."""
        stale = [n for n, d in self.inputs.items() if not d.age_ms < 1000.0]
        errs = sum(d.dlc_errors + d.decode_errors + d.range_errors + d.counter_errors + d.checksum_errors
                   for d in self.inputs.values())
        gnss_age = "never" if math.isinf(self.gnss_receive_age_ms) else f"{self.gnss_receive_age_ms:.0f} ms"
        isolated = [n for n, s in self.sources.items() if s.isolated]
        return (f"inputs {len(self.inputs) - len(stale)}/{len(self.inputs)} fresh"
                + (f" (stale: {', '.join(stale)})" if stale else "")
                + (f", isolated: {', '.join(isolated)}" if isolated else "")
                + f", input errors {errs}; gnss fix {self.gnss_fix_type} sv {self.gnss_num_sv} age {gnss_age}"
                + f"{'' if self.gnss_serial_connected else ' (port closed)'}"
                + f"; can {BUS_STATE_NAMES.get(self.can_bus_state, '?')} err {self.can_error_frames}"
                + f" txfail {self.can_tx_failures}; tick p99 {self.tick_late_p99_us:.0f} us"
                + f" overruns {self.tick_overruns}; cpu {self.cpu_load_pct:.0f}%")
