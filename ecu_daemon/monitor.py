"""``ecu-daemon monitor``: a live terminal view of a running daemon, from its CAN outputs only.

It opens any python-can bus with the same ``-i/-c/-b`` flags as ``run``, decodes every frame of
the output DBC (CRC and counter checked, as a receiving ECU would) and draws, a few times a
second: sideslip, heading, velocities and biases with their std and validity, the status bits,
GNSS state, the health of every input and the tick lateness (from the EST_DIAG pages), with
sparklines of the last ``--history`` seconds. It is a terminal program (rich), so it works over
ssh. To watch the demo from another terminal, put both on a shared bus::

    ecu-daemon demo -i udp_multicast -c 239.74.163.2
    ecu-daemon monitor -i udp_multicast -c 239.74.163.2

``MonitorState`` (frames in, values and histories out) is kept apart from the drawing.
"""
from __future__ import annotations

import argparse
import collections
import math
import time

import can

from .integrity import next_counter
from .outputs import OutputFrameError, decode_output_frame

DEG = 180 / math.pi
SPARK = "▁▂▃▄▅▆▇█"
#: rows of the estimate table: label, message, signal, std (message, signal) or None, validity signal, factor
ROWS = (
    ("sideslip [deg]", "EST_SIDESLIP", "SIDESLIP", ("EST_SIDESLIP", "SIDESLIP_STD"), "SIDESLIP_VALID", DEG),
    ("yaw rate [deg/s]", "EST_SIDESLIP", "YAW_RATE", None, "YAW_RATE_VALID", DEG),
    ("heading [deg]", "EST_HEADING", "HEADING", ("EST_HEADING", "HEADING_STD"), "HEADING_VALID", DEG),
    ("vx [m/s]", "EST_VELOCITY", "VX", ("EST_VELOCITY", "VX_STD"), "VELOCITY_VALID", 1.0),
    ("vy [m/s]", "EST_VELOCITY", "VY", ("EST_VELOCITY", "VY_STD"), "VELOCITY_VALID", 1.0),
    ("yaw-rate bias [deg/s]", "EST_BIASES", "YAW_RATE_BIAS", ("EST_BIAS_STD", "YAW_RATE_BIAS_STD"),
     "BIASES_VALID", DEG),
    ("ax bias [m/s2]", "EST_BIASES", "ACCEL_X_BIAS", ("EST_BIAS_STD", "ACCEL_X_BIAS_STD"), "BIASES_VALID", 1.0),
    ("ay bias [m/s2]", "EST_BIASES", "ACCEL_Y_BIAS", ("EST_BIAS_STD", "ACCEL_Y_BIAS_STD"), "BIASES_VALID", 1.0),
    ("GNSS latency [s]", "EST_CALIBRATION", "GNSS_DELAY", None, "CALIBRATION_VALID", 1.0),
    ("wheel scale", "EST_CALIBRATION", "WHEEL_SCALE", None, "CALIBRATION_VALID", 1.0),
    ("bank [deg]", "EST_ROAD", "BANK", ("EST_ROAD_STD", "BANK_STD"), "BANK_VALID", DEG),
    ("grade [deg]", "EST_ROAD", "GRADE", ("EST_ROAD_STD", "GRADE_STD"), "GRADE_VALID", DEG),
    ("roll [deg]", "EST_ROAD", "ROLL", ("EST_ROAD_STD", "ROLL_STD"), "ROLL_VALID", DEG),
)
#: EST_DIAG input prefixes, in the order the daemon's inputs are listed
INPUTS = ("WS_FL", "WS_FR", "WS_RL", "WS_RR", "STEER", "YAW_RATE", "ACCEL_X", "ACCEL_Y")


def sparkline(values, width: int) -> str:
    """The last ``width`` finite values as block characters scaled to their own range."""
    vals = [v for v in list(values)[-width:] if math.isfinite(v)]
    if not vals:
        return ""
    lo, hi = min(vals), max(vals)
    span = hi - lo
    return "".join(SPARK[0 if span <= 0 else min(len(SPARK) - 1, int((v - lo) / span * len(SPARK)))]
                   for v in vals)


class MonitorState:
    """Latest decoded values of the output messages, their histories and the frame counts."""

    def __init__(self, db, history_s: float = 30.0, spark_hz: float = 4.0) -> None:
        self.db = db
        self.values: dict[str, dict] = {}  # message name -> last decoded signals (numbers)
        self.seen: dict[str, float] = {}  # message name -> receive time of the last frame
        self.diag: dict[str, float] = {}  # every EST_DIAG page signal, merged
        self.frames = 0
        self.other_frames = 0  # not in the output DBC (inputs on the same bus, ...)
        self.bad_frames = 0  # wrong length or CRC
        self.counter_jumps = 0
        self.last_error = ""
        self._counters: dict[int, int] = {}
        self._spark_dt = 1.0 / spark_hz
        self._n = max(8, round(history_s * spark_hz))
        self.history: dict[str, collections.deque] = {label: collections.deque(maxlen=self._n) for label, *_ in ROWS}
        self._next_sample = -math.inf

    def add(self, msg: can.Message) -> None:
        """One received frame (receive time ``msg.timestamp``)."""
        try:
            m = self.db.get_message_by_frame_id(msg.arbitration_id)
        except KeyError:
            self.other_frames += 1
            return
        if msg.is_extended_id or msg.is_error_frame or msg.is_remote_frame:
            self.other_frames += 1
            return
        try:
            vals = decode_output_frame(self.db, msg)
        except OutputFrameError as e:
            self.bad_frames += 1
            self.last_error = str(e)
            return
        self.frames += 1
        prev = self._counters.get(msg.arbitration_id)
        if prev is not None and vals["COUNTER"] != next_counter(prev):
            self.counter_jumps += 1
        self._counters[msg.arbitration_id] = vals["COUNTER"]
        self.values[m.name] = vals
        self.seen[m.name] = msg.timestamp
        if m.name == "EST_DIAG":
            self.diag.update(vals)
        if msg.timestamp >= self._next_sample:
            self._next_sample = msg.timestamp + self._spark_dt
            for label, name, sig, _std, _valid, k in ROWS:
                v = self.values.get(name, {}).get(sig)
                self.history[label].append(v * k if v is not None else math.nan)

    def get(self, name: str, sig: str) -> float:
        return self.values.get(name, {}).get(sig, math.nan)

    def choice(self, name: str, sig: str, spec: str = "g") -> str:
        """A signal's last value by its value-table name (the DBC's VAL_: VALID, NEVER, FIX_3D...)
        when it has one, else the number formatted with ``spec``."""
        v = self.get(name, sig) if name != "EST_DIAG" else self.diag.get(sig, math.nan)
        if not math.isfinite(v):
            return "-"
        s = self.db.get_message_by_name(name).get_signal_by_name(sig)
        raw = s.conversion.numeric_scaled_to_raw(v)
        return str((s.choices or {}).get(raw, format(v, spec)))


def _num(v: float, spec: str = ".3f") -> str:
    return format(v, spec) if isinstance(v, (int, float)) and math.isfinite(v) else "-"


def render(state: MonitorState, source: str, now: float, spark_width: int = 40):
    """The whole screen as one rich renderable."""
    from rich.console import Group
    from rich.table import Table
    from rich.text import Text

    age = now - max(state.seen.values()) if state.seen else math.inf
    head = Text(f"ecu-daemon monitor on {source}   output frames {state.frames}"
                f"  bad {state.bad_frames}  counter jumps {state.counter_jumps}"
                f"  other frames {state.other_frames}   last frame {_num(age * 1e3, '.0f')} ms ago")
    if not state.seen:
        head.append("\n(waiting for output frames of the daemon)", style="yellow")

    est = Table(title="estimates", title_justify="left", expand=False)
    for col, justify in (("", "left"), ("value", "right"), ("±1σ", "right"), ("valid", "left"),
                         ("history", "left")):
        est.add_column(col, justify=justify, no_wrap=True)
    for label, name, sig, std, valid, k in ROWS:
        sd = state.get(*std) * k if std else math.nan
        ok = state.choice(name, valid)
        est.add_row(Text(label), _num(state.get(name, sig) * k), _num(sd), Text(ok, style="green" if ok == "VALID" else "red"),
                    sparkline(state.history[label], spark_width))
    heading = state.db.get_message_by_name("EST_HEADING")
    flags = [s.name[7:] for s in heading.signals
             if s.name.startswith("STATUS_") and state.get("EST_HEADING", s.name) == 1]
    status = Text("status: " + (" ".join(flags) if flags else "-"))

    d = state.diag
    gnss = Text(f"GNSS: fix {state.choice('EST_DIAG', 'GNSS_FIX_TYPE')}  sv {_num(d.get('GNSS_NUM_SV', math.nan), '.0f')}"
                f"  speed acc {state.choice('EST_DIAG', 'GNSS_SPEED_ACC', '.3f')} m/s"
                f"  rx age {state.choice('EST_DIAG', 'GNSS_RX_AGE', '.0f')} ms"
                f"  latency {state.choice('EST_DIAG', 'GNSS_LATENCY', '.1f')} ms"
                f"  port {state.choice('EST_DIAG', 'GNSS_SERIAL_CONNECTED')}"
                f"  fused {_num(state.get('EST_GNSS_COUNTS', 'GNSS_FUSED'), '.0f')}"
                f" rejected {_num(state.get('EST_GNSS_COUNTS', 'GNSS_REJECTED'), '.0f')}"
                f" late {_num(state.get('EST_GNSS_COUNTS', 'GNSS_LATE'), '.0f')}"
                f"  parse errors {_num(d.get('GNSS_PARSE_ERRORS', math.nan), '.0f')}")

    parts = [head, est, status, gnss]
    if d.get("GNSS_HEADING_STATE", 0):  # a dual-antenna heading was received at some point
        parts.append(Text(f"GNSS heading: {state.choice('EST_DIAG', 'GNSS_HEADING_STATE')}"
                          f"  carrier {state.choice('EST_DIAG', 'GNSS_HEADING_CARR_SOLN')}"
                          f"  acc {_num(math.degrees(d.get('GNSS_HEADING_ACC', math.nan)), '.2f')} deg"
                          f"  baseline {state.choice('EST_DIAG', 'GNSS_HEADING_BASELINE', '.3f')} m"
                          f"  fused {_num(d.get('GNSS_HEADING_FUSED', math.nan), '.0f')}"
                          f" rejected {_num(d.get('GNSS_HEADING_REJECTED', math.nan), '.0f')}"))

    inputs = Table(title="inputs", title_justify="left")
    for col in ("input", "age ms", "rate Hz", "stale", "dlc", "decode", "range", "counter", "checksum"):
        inputs.add_column(col, justify="left" if col == "input" else "right", no_wrap=True)
    for p in INPUTS:
        row = [p, state.choice("EST_DIAG", f"{p}_AGE", ".0f"), _num(d.get(f"{p}_RATE", math.nan), ".1f")]
        row += [_num(d.get(f"{p}_{s}", math.nan), ".0f") for s in
                ("STALE_COUNT", "DLC_ERRORS", "DECODE_ERRORS", "RANGE_ERRORS", "COUNTER_ERRORS", "CHECKSUM_ERRORS")]
        inputs.add_row(*row)

    tick = Text(f"tick lateness p50 {_num(d.get('TICK_LATE_P50', math.nan), '.0f')} us"
                f"  p99 {_num(d.get('TICK_LATE_P99', math.nan), '.0f')} us"
                f"  max {_num(d.get('TICK_LATE_MAX', math.nan), '.0f')} us"
                f"  overruns {_num(d.get('TICK_OVERRUNS', math.nan), '.0f')}"
                f"  CPU {_num(d.get('CPU_LOAD', math.nan), '.1f')} %"
                f"   CAN {state.choice('EST_DIAG', 'CAN_BUS_STATE')}"
                f"  error frames {_num(d.get('CAN_ERROR_FRAMES', math.nan), '.0f')}"
                f"  tx failures {_num(d.get('CAN_TX_FAILURES', math.nan), '.0f')}")
    parts += [inputs, tick]
    if state.last_error:
        parts.append(Text(f"last bad frame: {state.last_error}", style="red"))
    return Group(*parts)


# --------------------------------------------------------------------------------- command line
def add_arguments(parser: argparse.ArgumentParser) -> None:
    from can.cli import add_bus_arguments

    parser.add_argument("--config", "-C", help="TOML configuration: its [can] bus and output_dbc (default: built-in)")
    add_bus_arguments(parser, group_title="CAN bus (overrides [can] and python-can's own configuration)")
    parser.add_argument("--history", type=float, default=30.0, metavar="S",
                        help="seconds of history in the sparklines (default 30)")
    parser.add_argument("--duration", type=float, metavar="S", help="stop after S seconds (default: Ctrl-C)")


def main(args: argparse.Namespace) -> int:
    from rich.console import Console
    from rich.live import Live

    from . import config as config_mod
    from .errors import UserError
    from .daemon import bus_overrides, explicit_can_keys
    from .io.can_bus import resolve_bus_config
    from .signals import load_dbc

    if not (args.history > 0 and math.isfinite(args.history)):
        raise UserError("--history must be a positive number of seconds")
    cfg = config_mod.load(args.config)
    db = load_dbc(cfg.output_dbc_path(), "[can] output_dbc", allow_non_strict=False)
    bus_config = resolve_bus_config(cfg.can, explicit_can_keys(args.config), bus_overrides(args))
    source = f"{bus_config.get('interface')}:{bus_config.get('channel')}"
    try:
        bus = can.Bus(**bus_config)
    except (can.CanError, OSError, ValueError, ImportError) as e:
        raise UserError(f"cannot open CAN bus {source}: {e}") from None
    state = MonitorState(db, history_s=args.history)
    console = Console()
    end = time.monotonic() + args.duration if args.duration else math.inf
    try:
        if console.is_terminal:
            with Live(render(state, source, time.time()), console=console, screen=True, auto_refresh=False) as live:
                _loop(bus, state, end, 0.25, lambda: live.update(render(state, source, time.time()), refresh=True))
        else:  # a pipe or a log file: a plain snapshot every 2 s
            _loop(bus, state, end, 2.0, lambda: console.print(render(state, source, time.time())))
    except KeyboardInterrupt:
        pass
    finally:
        bus.shutdown()
    return 0


def _loop(bus, state: MonitorState, end: float, every_s: float, show) -> None:
    next_show = time.monotonic()
    while time.monotonic() < end:
        msg = bus.recv(timeout=0.05)
        while msg is not None:
            state.add(msg)
            msg = bus.recv(timeout=0)
        if time.monotonic() >= next_show:
            show()
            next_show = time.monotonic() + every_s
    show()
