"""Estimate (+ Diagnostics) -> the CAN frames of the output DBC, with counters, CRCs and validity.

The DBC (``dbc/ecu_daemon_outputs.dbc``) decides layout and timing; this module only knows which
:class:`Estimate` / :class:`Diagnostics` field feeds which DBC signal (``_ESTIMATE_SOURCES``,
``_diag_source``), so a new output signal is one DBC line plus one table entry. Everything else is
bound once at start-up: cycle times become step periods, every signal gets its saturation limits
(the DBC range, within what the bits can carry), and messages of the same period are staggered
over the steps so that no step sends a burst (CAN interfaces queue only ~10 frames by default).

Per frame: values outside a signal's range are saturated and non-finite ones sent as 0; either
clears the frame's validity bit. Only a value the estimate claims to be valid is a problem worth a
(rate-limited) log line: NaN in a field whose estimator flag is already false is a way of saying
"unknown" (the pipeline's estimate before the first input is finite and all-invalid). Then
``Message.encode(strict=False)`` (the range check already happened here), a 4-bit COUNTER per
message and the E2E profile-2 CRC in byte 0.
"""
from __future__ import annotations

import logging
import math
import operator
from pathlib import Path

import can

from .config import Config, ConfigError
from .dbc_loading import load_dbc
from .diagnostics import Diagnostics
from .estimator import estimate as estimate_module
from .estimator import source_status
from .estimator.estimate import ESTIMATE_FIELDS, Estimate
from .integrity import CRC8H2F_TABLE, data_id_for, e2e_p2_crc, next_counter
from .io.logging_setup import RateLimitedLog

try:
    from ._frames import pack as _pack_compiled  # setup.py builds it; optional
    from ._frames import compile_plan as _compile_plan, encode as _encode_compiled
except ImportError:
    _pack_compiled = _compile_plan = _encode_compiled = None
try:  # apart: a build older than this function keeps the rest of _frames
    from ._frames import e2e_p2 as _e2e_p2_compiled
except ImportError:
    _e2e_p2_compiled = None

log = logging.getLogger(__name__)

TWO_PI = 2.0 * math.pi

# how a value is brought into a signal's range
_SAT = 0  # clamp to [lo, hi]; clamping or a non-finite value (-> 0, or the limit nearest 0) clears validity
_ANGLE = 1  # wrap into [0, 2*pi); non-finite -> 0 and invalid
_WRAP = 2  # integer counter, modulo 2**length
_UNKNOWN_HI = 3  # clamp; non-finite -> hi (the DBC's NEVER / UNKNOWN value); no validity bit
_CLAMP = 4  # clamp; non-finite -> 0; no validity bit

#: output DBC signal -> (Estimate field, validity signal of the same frame, mode)
_ESTIMATE_SOURCES = {
    "SIDESLIP": ("sideslip_rad", "SIDESLIP_VALID", _SAT),
    "SIDESLIP_STD": ("sideslip_std_rad", "SIDESLIP_VALID", _SAT),
    "YAW_RATE": ("yaw_rate_radps", "YAW_RATE_VALID", _SAT),
    "VX": ("vx_mps", "VELOCITY_VALID", _SAT),
    "VY": ("vy_mps", "VELOCITY_VALID", _SAT),
    "VX_STD": ("vx_std_mps", "VELOCITY_VALID", _SAT),
    "VY_STD": ("vy_std_mps", "VELOCITY_VALID", _SAT),
    "HEADING": ("heading_rad", "HEADING_VALID", _ANGLE),
    "HEADING_STD": ("heading_std_rad", "HEADING_VALID", _SAT),
    "YAW_RATE_BIAS": ("yaw_rate_bias_radps", "BIASES_VALID", _SAT),
    "ACCEL_X_BIAS": ("accel_x_bias_mps2", "BIASES_VALID", _SAT),
    "ACCEL_Y_BIAS": ("accel_y_bias_mps2", "BIASES_VALID", _SAT),
    "YAW_RATE_BIAS_STD": ("yaw_rate_bias_std_radps", "BIASES_VALID", _SAT),
    "ACCEL_X_BIAS_STD": ("accel_x_bias_std_mps2", "BIASES_VALID", _SAT),
    "ACCEL_Y_BIAS_STD": ("accel_y_bias_std_mps2", "BIASES_VALID", _SAT),
    "GNSS_DELAY": ("gnss_delay_s", "CALIBRATION_VALID", _SAT),
    "WHEEL_SCALE": ("wheel_scale", "CALIBRATION_VALID", _SAT),
    "STEERING_OFFSET": ("steering_offset_rad", "CALIBRATION_VALID", _SAT),
    "CORNERING_STIFFNESS_FRONT": ("cornering_stiffness_front_n_per_rad", "CORNERING_VALID", _SAT),
    "CORNERING_STIFFNESS_REAR": ("cornering_stiffness_rear_n_per_rad", "CORNERING_VALID", _SAT),
    "BANK": ("bank_rad", "BANK_VALID", _SAT),
    "GRADE": ("grade_rad", "GRADE_VALID", _SAT),
    "ROLL": ("roll_rad", "ROLL_VALID", _SAT),
    "BANK_STD": ("bank_std_rad", "BANK_VALID", _SAT),
    "GRADE_STD": ("grade_std_rad", "GRADE_VALID", _SAT),
    "ROLL_STD": ("roll_std_rad", "ROLL_VALID", _SAT),
    "GNSS_FUSED": ("gnss_fused", None, _WRAP),
    "GNSS_REJECTED": ("gnss_rejected", None, _WRAP),
    "GNSS_LATE": ("gnss_late", None, _WRAP),
}
#: validity signal -> the Estimate flag it starts from (None: valid unless a value was clamped; such a
#: frame's values count as claimed valid while any of the four flags is set, i.e. the filter runs)
_VALID_FLAGS = {
    "SIDESLIP_VALID": "sideslip_valid",
    "HEADING_VALID": "heading_valid",
    "VELOCITY_VALID": "velocity_valid",
    "BIASES_VALID": "biases_valid",
    "BANK_VALID": "bank_valid",
    "GRADE_VALID": "grade_valid",
    "ROLL_VALID": "roll_valid",
    "YAW_RATE_VALID": None,
    "CALIBRATION_VALID": None,
    "CORNERING_VALID": None,
}
_INTEGRITY = ("CHECKSUM", "COUNTER")
_DIAG_MUX = "DIAG_PAGE"
#: EST_DIAG signal prefix -> input name
_DIAG_INPUT_PREFIX = {"WS_FL": "wheel_speed_fl", "WS_FR": "wheel_speed_fr", "WS_RL": "wheel_speed_rl",
                      "WS_RR": "wheel_speed_rr", "STEER": "steering_wheel_angle", "YAW_RATE": "yaw_rate",
                      "ACCEL_X": "accel_x", "ACCEL_Y": "accel_y"}
_DIAG_INPUT_SUFFIX = {"AGE": ("age_ms", _UNKNOWN_HI), "RATE": ("rate_hz", _CLAMP),
                      "STALE_COUNT": ("stale_count", _WRAP), "DLC_ERRORS": ("dlc_errors", _WRAP),
                      "DECODE_ERRORS": ("decode_errors", _WRAP), "RANGE_ERRORS": ("range_errors", _WRAP),
                      "COUNTER_ERRORS": ("counter_errors", _WRAP), "CHECKSUM_ERRORS": ("checksum_errors", _WRAP)}
#: EST_DIAG signal prefix -> fault-isolation source (Diagnostics.sources)
_DIAG_SOURCE_PREFIX = {"ISO_WHEELS": "wheels", "ISO_YAW_RATE": "yaw_rate", "ISO_ACCEL_X": "accel_x",
                       "ISO_ACCEL_Y": "accel_y", "ISO_GNSS": "gnss", "ISO_WHEEL_SPEED": "wheel_speed"}
_DIAG_SOURCE_SUFFIX = {"ACTIVE": ("isolated", _CLAMP), "EVENTS": ("events", _WRAP)}
_DIAG_FIELDS = {
    "GNSS_FIX_TYPE": ("gnss_fix_type", _CLAMP), "GNSS_SERIAL_CONNECTED": ("gnss_serial_connected", _CLAMP),
    "GNSS_NUM_SV": ("gnss_num_sv", _CLAMP), "GNSS_SPEED_ACC": ("gnss_speed_acc_mps", _UNKNOWN_HI),
    "GNSS_CHECKSUM_ERRORS": ("gnss_checksum_errors", _WRAP), "GNSS_RX_AGE": ("gnss_receive_age_ms", _UNKNOWN_HI),
    "GNSS_LATENCY": ("gnss_latency_ms", _UNKNOWN_HI), "GNSS_PARSE_ERRORS": ("gnss_parse_errors", _WRAP),
    "CAN_BUS_STATE": ("can_bus_state", _CLAMP), "CAN_ERROR_FRAMES": ("can_error_frames", _WRAP),
    "CAN_TX_FAILURES": ("can_tx_failures", _WRAP), "TICK_LATE_P50": ("tick_late_p50_us", _UNKNOWN_HI),
    "TICK_LATE_P99": ("tick_late_p99_us", _UNKNOWN_HI), "TICK_LATE_MAX": ("tick_late_max_us", _UNKNOWN_HI),
    "TICK_OVERRUNS": ("tick_overruns", _WRAP), "CPU_LOAD": ("cpu_load_pct", _UNKNOWN_HI),
    "GNSS_HEADING_STATE": ("gnss_heading_state", _CLAMP),
    "GNSS_HEADING_CARR_SOLN": ("gnss_heading_carr_soln", _CLAMP),
    "GNSS_HEADING_ACC": ("gnss_heading_acc_rad", _UNKNOWN_HI),
    "GNSS_HEADING_BASELINE": ("gnss_heading_baseline_m", _UNKNOWN_HI),
    "GNSS_HEADING_FUSED": ("gnss_heading_fused", _WRAP),
    "GNSS_HEADING_REJECTED": ("gnss_heading_rejected", _WRAP),
    "MAG_STATE": ("mag_state", _CLAMP), "MAG_FIELD_NORM": ("mag_field_norm_t", _UNKNOWN_HI),
    "MAG_INCLINATION": ("mag_inclination_rad", _CLAMP), "MAG_OFFSET": ("mag_offset_rad", _CLAMP),
    "MAG_OFFSET_STD": ("mag_offset_std_rad", _UNKNOWN_HI), "MAG_REJECTED": ("mag_rejected", _WRAP),
    "SRC_BASELINE": ("src_baseline", _CLAMP), "SRC_ROLL_GYRO": ("src_roll_gyro", _CLAMP),
    "SRC_MAG": ("src_mag", _CLAMP),
    "SRC_BASELINE_ELEVATION_REJECTED": ("src_baseline_elevation_rejected", _WRAP),
    "SRC_ROLL_GYRO_REJECTED": ("src_roll_gyro_rejected", _WRAP),
    "ROLL_GYRO_BIAS": ("roll_gyro_bias_radps", _CLAMP), "ROLL_GYRO_BIAS_STD": ("roll_gyro_bias_std_radps", _UNKNOWN_HI),
}
#: EST_DIAG pages of an optional source, sent only when the config maps it (a car without one sends
#: the same pages, in the same rotation, as before the source existed)
_OPTIONAL_PAGE_PREFIX = {"MAG_": ("mag_x", "mag_y", "mag_z"), "ROLL_GYRO_": ("roll_rate",)}
#: the EST_DIAG page of every optional aiding source's status: sent when the config names any
_AIDING_PAGE_PREFIX = "SRC_"


class OutputFrameError(ValueError):
    """An output frame that does not check out (unknown id, length, CRC, counter)."""


def _limits(sig) -> tuple[float, float]:
    """Physical range a signal can carry: the DBC [min|max] within the raw bit range."""
    n = sig.length
    rmin, rmax = (-(1 << (n - 1)), (1 << (n - 1)) - 1) if sig.is_signed else (0, (1 << n) - 1)
    a, b = rmin * sig.scale + sig.offset, rmax * sig.scale + sig.offset
    lo, hi = min(a, b), max(a, b)
    if sig.minimum is not None:
        lo = max(lo, float(sig.minimum))
    if sig.maximum is not None:
        hi = min(hi, float(sig.maximum))
    return lo, hi


def _diag_source(name: str):
    """EST_DIAG signal -> (getter(Diagnostics), mode), or None if unknown."""
    if name in _DIAG_FIELDS:
        attr, mode = _DIAG_FIELDS[name]
        return operator.attrgetter(attr), mode
    for prefix, input_name in _DIAG_INPUT_PREFIX.items():
        if name.startswith(prefix + "_") and name[len(prefix) + 1:] in _DIAG_INPUT_SUFFIX:
            attr, mode = _DIAG_INPUT_SUFFIX[name[len(prefix) + 1:]]
            return (lambda d, n=input_name, a=attr: getattr(d.inputs[n], a)), mode
    for prefix, source in _DIAG_SOURCE_PREFIX.items():
        if name.startswith(prefix + "_") and name[len(prefix) + 1:] in _DIAG_SOURCE_SUFFIX:
            attr, mode = _DIAG_SOURCE_SUFFIX[name[len(prefix) + 1:]]
            return (lambda d, n=source, a=attr: getattr(d.sources[n], a)), mode
    return None


class _Field:
    __slots__ = ("signal", "source", "lo", "hi", "zero", "mode", "valid", "modulus")

    def __init__(self, signal, source, mode, valid=None):
        self.signal = signal.name
        self.source = source  # Estimate index, or getter(Diagnostics)
        self.lo, self.hi = _limits(signal)
        self.zero = min(max(0.0, self.lo), self.hi)  # stand-in for a non-finite value
        self.mode = mode
        self.valid = valid
        self.modulus = 1 << signal.length


def _layout(message, signals=None):
    """The message's bit layout precompiled for :func:`_pack`: per signal (name, offset, scale,
    shift, mask, raw range); None if a signal is big-endian, float or wider than 52 bits (a
    double no longer holds every raw value; those frames keep ``Message.encode``). ``signals``: a
    subset (one page of a multiplexed message)."""
    out = []
    for sig in message.signals if signals is None else signals:
        if sig.byte_order != "little_endian" or sig.is_float or sig.length > 52:
            return None
        n = sig.length
        lo, hi = (-(1 << (n - 1)), (1 << (n - 1)) - 1) if sig.is_signed else (0, (1 << n) - 1)
        out.append((sig.name, sig.offset, sig.scale, sig.start, (1 << n) - 1, lo, hi))
    return tuple(out)


def _page_layout(message, page: int):
    """:func:`_layout` of one page of a message multiplexed by one selector: the selector, the
    signals of no page and the page's own (what ``Message.encode`` packs for that page)."""
    sigs = [s for s in message.signals if s.multiplexer_ids is None or page in s.multiplexer_ids]
    return _layout(message, sigs)


def _crc(payload: bytearray, data_id: int) -> int:
    """:func:`~ecu_daemon.integrity.e2e_p2_crc`, compiled (``_frames.c``) where built: the EST_DIAG
    pages take this path every other step, where the Python table loop was ~1 us a frame."""
    if _e2e_p2_compiled is not None:
        crc = _e2e_p2_compiled(payload, data_id, CRC8H2F_TABLE)
        if crc is not NotImplemented:
            return crc
    return e2e_p2_crc(payload, data_id)


def _pack(layout, values: dict, length: int) -> bytearray | None:
    """:func:`_pack_reference`, compiled (``_frames.c``) where built and the layout fits it."""
    if _pack_compiled is not None:
        out = _pack_compiled(layout, values, length)
        if out is not NotImplemented:
            return out
    return _pack_reference(layout, values, length)


def _pack_reference(layout, values: dict, length: int) -> bytearray | None:
    """The payload ``Message.encode(values, scaling=True, padding=False, strict=False)`` gives,
    without its per-call generality (tests/test_outputs.py checks them equal); None if a raw value
    does not fit its bits.

    ``round((v - offset) / scale)`` is cantools' scaled-to-raw conversion of every integer signal
    (its identity and integer-scale variants give the same integer for values under 2**53, which
    is why :func:`_layout` takes no wider signal), inlined: the method call per signal was most of
    the cost.
    """
    acc = 0
    for name, offset, scale, shift, mask, lo, hi in layout:
        raw = round((values[name] - offset) / scale)
        if raw < lo or raw > hi:
            return None
        acc |= (raw & mask) << shift
    return bytearray(acc.to_bytes(length, "little"))


class _MessagePlan:
    __slots__ = ("name", "message", "encode", "layout", "length", "frame_id", "data_id", "period", "phase",
                 "counter", "values", "fields", "valid", "status", "pages", "ok", "compiled")

    def __init__(self, message, period: int):
        self.name = message.name
        self.message = message
        self.encode = message.encode
        self.layout = None if message.is_multiplexed() else _layout(message)
        self.length = message.length
        self.frame_id = message.frame_id
        self.data_id = data_id_for(message)
        self.period = period
        self.phase = 0
        self.counter = 0
        self.values: dict = {}
        self.fields: list[_Field] = []
        self.valid: list[tuple[str, int | None]] = []  # (validity signal, Estimate index of its flag)
        self.status: list[tuple[str, int]] = []  # (status-bit signal, mask)
        self.pages: list[tuple[int, dict, list[_Field], list | None]] = []  # multiplexed: (page, values,
        # fields, layout)
        self.ok: dict[str, bool] = {}  # every validity signal -> True: the start of each frame's check
        self.compiled = None  # _frames.encode's plan of an estimate frame (None: Python only)


class OutputEncoder:
    """Builds the output frames due at each estimator step.

    ``schedule``: ``(message name, frame id, period in steps, phase)`` per message; a message is
    due at step k when ``k % period == phase``. ``saturated`` / ``non_finite``: counts per signal
    of values the estimate claimed to be valid (the ones that are logged).
    """

    def __init__(self, cfg: Config, *, log_interval_s: float = 10.0):
        self.dbc_path: Path = cfg.output_dbc_path()
        self.db = load_dbc(self.dbc_path, "[can] output_dbc", allow_non_strict=False)
        self.dt_s = float(cfg.estimator.dt_s)
        self._mapped = set(cfg.inputs)
        self._aiding = source_status.configured(cfg)
        self._log = RateLimitedLog(log, log_interval_s)
        self.saturated: dict[str, int] = {}
        self.non_finite: dict[str, int] = {}
        self._plans = [self._plan(m) for m in self.db.messages]
        self._stagger()
        self.schedule = [(p.name, p.frame_id, p.period, p.phase) for p in self._plans]
        # the plans due at each step of one hyperperiod (the schedule repeats), so a step looks
        # only at its own messages; none when the hyperperiod is too long to tabulate
        hyper = math.lcm(*(p.period for p in self._plans)) if self._plans else 1
        self._due = ([[p for p in self._plans if k % p.period == p.phase] for k in range(hyper)]
                     if hyper <= 10000 else None)
        self.frame_ids = sorted(p.frame_id for p in self._plans)

    # ----------------------------------------------------------------------------- set-up
    def _plan(self, msg) -> _MessagePlan:
        where = f"[can] output_dbc {self.dbc_path}: message {msg.name}"
        if msg.is_extended_frame or msg.frame_id > 0x7FF:
            raise ConfigError(f"{where} must use an 11-bit frame id")
        if not msg.cycle_time:
            raise ConfigError(f"{where} has no GenMsgCycleTime")
        period = msg.cycle_time / (self.dt_s * 1000.0)
        if period < 1 or abs(period - round(period)) > 1e-6:
            raise ConfigError(f"{where}: cycle time {msg.cycle_time} ms is not a multiple of the"
                              f" estimator step {self.dt_s * 1000.0:g} ms")
        names = {s.name for s in msg.signals}
        missing = [s for s in _INTEGRITY if s not in names]
        if missing or msg.get_signal_by_name("CHECKSUM").start != 0 or msg.length < 2:
            raise ConfigError(f"{where} needs CHECKSUM in byte 0 and a COUNTER (E2E profile 2)")
        p = _MessagePlan(msg, int(round(period)))
        if msg.is_multiplexed():
            self._plan_pages(p, msg, where)
        else:
            self._plan_estimate(p, msg, where)
        return p

    def _plan_estimate(self, p: _MessagePlan, msg, where: str) -> None:
        for sig in msg.signals:
            name = sig.name
            p.values[name] = 0
            if name in _INTEGRITY:
                continue
            if name in _VALID_FLAGS:
                flag = _VALID_FLAGS[name]
                p.valid.append((name, None if flag is None else ESTIMATE_FIELDS.index(flag)))
                p.ok[name] = True
            elif name.startswith("STATUS_") and isinstance(getattr(estimate_module, name, None), int):
                p.status.append((name, getattr(estimate_module, name)))
            elif name in _ESTIMATE_SOURCES:
                field, valid, mode = _ESTIMATE_SOURCES[name]
                if valid is not None and valid not in {s.name for s in msg.signals}:
                    raise ConfigError(f"{where}: signal {name} needs its validity bit {valid} in the same message")
                p.fields.append(_Field(sig, ESTIMATE_FIELDS.index(field), mode, valid))
            else:
                raise ConfigError(f"{where}: signal {name} has no source in ecu_daemon/outputs.py")
        p.compiled = _compiled_plan(p)

    def _plan_pages(self, p: _MessagePlan, msg, where: str) -> None:
        tree = [n for n in msg.signal_tree if isinstance(n, dict)]
        if len(tree) != 1 or _DIAG_MUX not in tree[0]:
            raise ConfigError(f"{where}: a multiplexed output message must be multiplexed by {_DIAG_MUX}")
        for page, signal_names in sorted(tree[0][_DIAG_MUX].items()):
            if any(all(isinstance(n, str) and n.startswith(prefix) for n in signal_names)
                   and not self._mapped.issuperset(inputs)
                   for prefix, inputs in _OPTIONAL_PAGE_PREFIX.items()):
                continue
            if not self._aiding and all(isinstance(n, str) and n.startswith(_AIDING_PAGE_PREFIX) for n in signal_names):
                continue
            values = {"CHECKSUM": 0, "COUNTER": 0, _DIAG_MUX: page}
            fields = []
            for name in signal_names:
                if not isinstance(name, str):
                    raise ConfigError(f"{where}: nested multiplexing is not supported")
                src = _diag_source(name)
                if src is None:
                    raise ConfigError(f"{where}: signal {name} has no source in ecu_daemon/outputs.py")
                values[name] = 0
                fields.append(_Field(msg.get_signal_by_name(name), src[0], src[1]))
            p.pages.append((page, values, fields, _page_layout(msg, page)))

    def _stagger(self) -> None:
        """Give each slower message the phase with the fewest frames already due (greedy)."""
        periods = [p.period for p in self._plans]
        hyper = math.lcm(*periods) if periods else 1
        if hyper > 100000:
            return
        load = [0] * hyper
        for p in sorted(self._plans, key=lambda p: p.period):  # faster first: they have no choice
            best = min(range(p.period), key=lambda ph: (max(load[ph::p.period]), ph))
            p.phase = best
            for k in range(best, hyper, p.period):
                load[k] += 1

    # ----------------------------------------------------------------------------- per step
    def frames(self, step_index: int, est: Estimate, diag: Diagnostics | None = None) -> list[can.Message]:
        """The frames due at estimator step ``step_index`` (``est.t`` is their timestamp)."""
        t = est.t
        return [can.Message(timestamp=t, arbitration_id=fid, is_extended_id=False, data=payload, check=False)
                for fid, payload in self.payloads(step_index, est, diag)]

    def payloads(self, step_index: int, est: Estimate, diag: Diagnostics | None = None) -> list[tuple[int, bytearray]]:
        """:meth:`frames` as ``(frame id, payload)`` pairs (11-bit ids): what a log writer needs,
        without a ``can.Message`` per frame (the replay's output path)."""
        out = []
        due = self._due
        for p in self._plans if due is None else due[step_index % len(due)]:
            if due is None and step_index % p.period != p.phase:
                continue
            compiled = p.compiled  # (only estimate frames have one: the common case first)
            if compiled is not None:
                payload = _encode_compiled(compiled, est, p.counter)
                if payload is not NotImplemented:  # else a value to check, log or leave to cantools
                    p.counter = (p.counter + 1) & 0xF
                    out.append((p.frame_id, payload))
                    continue
            if p.pages:
                if diag is None:
                    continue
                page, values, fields, layout = p.pages[(step_index // p.period) % len(p.pages)]
                self._fill(p.name, values, fields, diag, None, None)
            else:
                values = p.values
                layout = p.layout
                ok = p.ok.copy()
                self._fill(p.name, values, p.fields, est, ok, p.valid)
                for vsig, flag in p.valid:
                    values[vsig] = 1 if ok[vsig] and (flag is None or est[flag]) else 0
                if p.status:
                    status = est.status
                    for ssig, mask in p.status:
                        values[ssig] = 1 if status & mask else 0
            values["COUNTER"] = p.counter
            p.counter = (p.counter + 1) & 0xF
            payload = None if layout is None else _pack(layout, values, p.length)
            if payload is None:
                payload = bytearray(p.encode(values, True, False, False))
            payload[0] = _crc(payload, p.data_id)
            out.append((p.frame_id, payload))
        return out

    def _fill(self, msg_name: str, values: dict, fields: list[_Field], src, ok: dict | None,
              valid: list | None) -> None:
        """Bring every field of ``src`` into range; ``ok`` (Estimate frames only) collects validity.

        ``valid``: the frame's (validity signal, Estimate flag index); a value saturated or not
        finite where the estimate claims validity (:func:`_claimed`) is reported; where it does
        not, the value is encoded the same way but silently (the validity bit is already 0).
        """
        isfinite = math.isfinite
        for f in fields:
            s = f.source
            v = src[s] if ok is not None else s(src)  # Estimate: tuple index; Diagnostics: getter
            mode = f.mode
            if mode == _WRAP:
                values[f.signal] = int(v) % f.modulus if isfinite(v) else 0
                continue
            if not isfinite(v):
                if mode == _UNKNOWN_HI:
                    values[f.signal] = f.hi
                    continue
                values[f.signal] = f.zero
                if ok is not None:
                    ok[f.valid] = False
                    if _claimed(src, valid, f.valid):
                        self._count("non_finite", msg_name, f, v)
                continue
            if mode == _ANGLE:
                v = v % TWO_PI
                if v >= f.hi:
                    v = 0.0
            elif v < f.lo or v > f.hi:
                clamped = f.lo if v < f.lo else f.hi
                if ok is not None and mode == _SAT:
                    ok[f.valid] = False
                    if _claimed(src, valid, f.valid):
                        self._count("saturated", msg_name, f, v)
                v = clamped
            values[f.signal] = v

    def _count(self, kind: str, msg_name: str, f: _Field, v: float) -> None:
        table = self.non_finite if kind == "non_finite" else self.saturated
        table[f.signal] = table.get(f.signal, 0) + 1
        what = f"not finite, sent as {f.zero:g}" if kind == "non_finite" else f"saturated to [{f.lo:g}, {f.hi:g}]"
        self._log.report((f.signal, kind), logging.WARNING,
                         f"output {msg_name}.{f.signal} = {float(v):.6g} {what}; {f.valid} cleared")


def _compiled_plan(p: _MessagePlan):
    """The estimate frame's whole per-step encoding (:meth:`OutputEncoder.frames` for frames whose
    values all fit) as a plan for ``_frames.encode``; None without the extension or for a layout
    it does not take. Per layout signal: where its value comes from and how it is packed."""
    if _compile_plan is None or p.layout is None:
        return None
    valid = dict(p.valid)
    status = dict(p.status)
    fields = {f.signal: f for f in p.fields}
    slot = {e[0]: i for i, e in enumerate(p.layout)}
    i_status = ESTIMATE_FIELDS.index("status")
    entries = []
    for name, offset, scale, shift, mask, rlo, rhi in p.layout:
        kind, mode, src, lo, hi, modulus, smask, zero, vslot, vflag = 0, 0, 0, 0.0, 0.0, 1, 0, 0.0, -1, -1
        if name == "COUNTER":
            kind = 1
        elif name in valid:
            kind, src = 3, -1 if valid[name] is None else valid[name]
        elif name in status:
            kind, src, smask = 4, i_status, status[name]
        elif name in fields:
            f = fields[name]
            if f.mode not in (_SAT, _ANGLE, _WRAP) or (f.mode != _WRAP and f.valid not in slot):
                return None
            kind, mode, src, lo, hi, modulus, zero = 2, f.mode, f.source, f.lo, f.hi, f.modulus, f.zero
            if f.mode != _WRAP:
                vslot = slot[f.valid]
                vflag = -1 if valid[f.valid] is None else valid[f.valid]
        elif name != "CHECKSUM":
            return None
        entries.append((kind, mode, src, float(lo), float(hi), modulus, smask, float(zero), vslot, vflag,
                        float(offset), float(scale), shift, mask, float(rlo), float(rhi)))
    return _compile_plan(tuple(entries), p.length, p.data_id, CRC8H2F_TABLE)


def _claimed(est: Estimate, valid: list, vsig: str) -> bool:
    """Whether ``est`` claims the values behind validity signal ``vsig`` valid: its flag, or for a
    signal without one, any of the four flags (the filter runs). Asked only for a bad value."""
    flag = next(f for v, f in valid if v == vsig)
    if flag is None:
        return bool(est.sideslip_valid or est.heading_valid or est.velocity_valid or est.biases_valid)
    return bool(est[flag])


def decode_output_frame(db, msg: can.Message, prev_counter: int | None = None) -> dict:
    """Decode one output frame and check it (for tests and tools).

    Raises :class:`OutputFrameError` for an unknown or extended id, a wrong length, a CRC that
    does not match, or (when ``prev_counter`` is given) a COUNTER that does not follow it.
    Returns the decoded signals (numbers, no choice strings).
    """
    if msg.is_extended_id:
        raise OutputFrameError(f"0x{msg.arbitration_id:X}: output frames use 11-bit ids")
    try:
        m = db.get_message_by_frame_id(msg.arbitration_id)
    except KeyError:
        raise OutputFrameError(f"0x{msg.arbitration_id:03X} is not an output message") from None
    data = bytes(msg.data)
    if len(data) != m.length:
        raise OutputFrameError(f"{m.name}: {len(data)} data bytes, expected {m.length}")
    crc = e2e_p2_crc(data, data_id_for(m))
    if data[0] != crc:
        raise OutputFrameError(f"{m.name}: CRC 0x{data[0]:02X}, expected 0x{crc:02X}")
    values = m.decode(data, decode_choices=False)
    if prev_counter is not None and values["COUNTER"] != next_counter(prev_counter):
        raise OutputFrameError(f"{m.name}: COUNTER {values['COUNTER']} after {prev_counter}")
    return values


__all__ = ["OutputEncoder", "OutputFrameError", "decode_output_frame"]
