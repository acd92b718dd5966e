"""``ecu-daemon demo``: the real daemon, live, on a simulated drive -- no CAN hardware needed.

The built-in ``demo`` scenario is simulated first (physics, sensors, CAN frames through our input
DBC, UBX NAV-PVT messages). Then the unmodified daemon code path runs on a python-can ``virtual``
bus and a pseudo-terminal as its GNSS port, while a :class:`Feeder` thread plays the frames onto
the bus and writes the GNSS bytes into the pty master, in real time (or ``--speed`` times
faster: the daemon then runs on a :class:`~ecu_daemon.io.tick.ScaledClock`). A terminal view
(plain ANSI redraw at 5 Hz; periodic lines when stdout is not a terminal or with ``--no-tui``)
shows estimates against the simulator's truth and the daemon's health; at the end an accuracy
summary (RMS sideslip / heading error over the steps flagged valid).
"""
from __future__ import annotations

import argparse
import asyncio
import collections
import io
import math
import os
import shutil
import sys
import threading
import time
import tty

import can
import numpy as np

from . import config as config_mod
from .daemon import Daemon, bus_overrides
from .diagnostics import BUS_STATE_NAMES
from .estimator import estimate as est_mod
from .io.logging_setup import setup_logging
from .io.player import Event, GnssPort, Player
from .io.tick import ScaledClock

DEG = 180.0 / math.pi
_STATUS_NAMES = [(getattr(est_mod, n), n[len("STATUS_"):].lower()) for n in dir(est_mod) if n.startswith("STATUS_")]


class Feeder(threading.Thread):
    """Plays a :class:`~ecu_daemon.sim.SimResult` onto a virtual bus and a pty master in real time,
    through the package's one player (:class:`~ecu_daemon.io.player.Player`).

    Simulated receive time ``s`` is sent at daemon-clock time ``c0 + (s - sim.t0)`` and, on the
    virtual bus, stamped with that time (:meth:`stamp`): the feeder stands in for the bus and the
    kernel, which stamp a frame when it arrives, and the drive says when that is. Stamping when
    this thread got round to sending (what the virtual bus does by itself) folded the feeder's
    lateness into the data: on a loaded machine p99 7-14 ms, up to 48 ms, on every input. A frame
    the feeder sends late now reaches the daemon late with its own time, like a frame a late
    reader finds in the socket (a late sample). At ``speed == 1`` the stamp is wall-clock time
    (``time.time()``, like a kernel's), so the daemon's realtime->monotonic mapping is exercised;
    otherwise the daemon's (scaled) clock. The daemon's own output frames come back on this bus and are drained while
    waiting (``outputs`` collects them with their arrival time when ``keep_outputs`` is set).
    ``frame_filter(t, kind, id, data) -> data | None`` changes or drops an event as it is due
    (kind 0 CAN, 1 GNSS, 2 the second receiver's GNSS).
    ``gnss2_fd``: the second receiver's pty master, for a scenario with two (``sim.gnss2_messages``).
    """

    def __init__(self, sim, channel: str, gnss_fd: int, *, clock=time.monotonic, speed: float = 1.0,
                 lead_s: float = 0.05, keep_outputs: bool = False, frame_filter=None,
                 bus_config: dict | None = None, gnss2_fd: int | None = None) -> None:
        super().__init__(name="demo-feeder", daemon=True)
        self.sim = sim
        self.channel = channel
        self.clock = clock
        self.speed = speed
        self.lead_s = lead_s
        self.keep_outputs = keep_outputs
        self.frame_filter = frame_filter  # f(t_sim, kind, id, data) -> data | None (fault injection)
        self.c0 = math.nan
        self.outputs: list = []  # (daemon-clock arrival time, can.Message)
        self.played = threading.Event()  # every frame and GNSS byte is out
        self.finished = threading.Event()  # ... and the thread is done
        self._stop_evt = threading.Event()
        stamp = None
        self._wall_offset = 0.0  # time.time() - clock() (speed 1), set when the feeder starts
        if bus_config is None or bus_config.get("interface") == "virtual":
            self._bus = can.Bus(interface="virtual", channel=channel, preserve_timestamps=True)
            stamp = self.stamp
        else:  # a bus other processes see (e.g. udp_multicast): they stamp receive times themselves
            self._bus = can.Bus(**bus_config)
        gnss = {"gnss": GnssPort(fd=gnss_fd)}
        if gnss2_fd is not None:
            gnss["gnss2"] = GnssPort(fd=gnss2_fd)
        self._player = Player((), buses={None: self._bus}, gnss=gnss, clock=clock,
                              rate=speed, stamp=stamp, idle=self._drain)

    @property
    def frames_sent(self) -> int:
        return self._player.stats.can_sent

    @property
    def gnss_bytes(self) -> int:
        return self._player.stats.gnss_bytes

    @property
    def gnss_dropped(self) -> int:
        return self._player.stats.gnss_dropped

    def stamp(self, deadline: float) -> float:
        """A frame's receive timestamp: its deadline (daemon clock), as wall-clock time at speed 1."""
        return deadline + self._wall_offset

    def sim_time(self, t_daemon: float) -> float:
        return t_daemon - self.c0 + self.sim.t0

    def stop(self) -> None:
        self._stop_evt.set()
        self._player.stop()
        if self.is_alive():
            self.join(5.0)

    def _drain(self) -> None:
        bus = self._bus
        while True:
            m = bus.recv(0)
            if m is None:
                return
            if self.keep_outputs:
                self.outputs.append((self.clock(), m))

    def _events(self):
        """(seconds after c0, Event), the fault filter applied as each comes due."""
        sim = self.sim
        events = [(t, 0, fid, data) for t, fid, data in sim.can_frames]
        events += [(t, 1, None, payload) for t, payload in sim.gnss_messages]
        events += [(t, 2, None, payload) for t, payload in sim.gnss2_messages]
        events.sort(key=lambda e: (e[0], e[1]))
        ext = sim.extended_ids
        s0 = sim.t0
        for t, kind, fid, data in events:
            if self.frame_filter is not None:
                data = self.frame_filter(t, kind, fid, data)
                if data is None:
                    continue
            if kind == 0:
                yield t - s0, Event(t, self.channel, can.Message(arbitration_id=fid, data=data,
                                                                 is_extended_id=fid in ext, check=False))
            else:
                yield t - s0, Event(t, "gnss" if kind == 1 else "gnss2", None, data)

    def run(self) -> None:
        player = self._player
        if self.speed == 1.0:  # one offset for the whole drive: a kernel's stamps do not jitter with us
            self._wall_offset = time.time() - self.clock()
        self.c0 = player.start_at = self.clock() + self.lead_s
        player.events = self._events()
        try:
            player.run()
            self.played.set()
            # keep draining briefly so late outputs are collected
            end = time.monotonic() + (0.2 if self.keep_outputs else 0.0)
            while time.monotonic() < end and not self._stop_evt.is_set():
                self._drain()
                self._stop_evt.wait(0.01)
        finally:
            self._drain()
            self._bus.shutdown()
            self.finished.set()


def open_gnss_pty() -> tuple[int, str]:
    """A pseudo-terminal pair in raw mode: (non-blocking master fd, slave path for the daemon)."""
    master, slave = os.openpty()
    tty.setraw(slave)
    path = os.ttyname(slave)
    os.close(slave)
    os.set_blocking(master, False)
    return master, path


class TruthTracker:
    """Estimates vs simulator truth: the numbers for the view and the closing summary."""

    def __init__(self, sim, to_sim_time) -> None:
        tt = sim.truth_table()
        self.t = tt["t"]
        self.tt = tt
        self.heading_unwrapped = np.unwrap(tt["heading_rad"])
        self.to_sim_time = to_sim_time
        self.n = 0
        self.beta_sq = 0.0
        self.beta_n = 0
        self.beta_max = 0.0
        self.psi_sq = 0.0
        self.psi_n = 0
        self.vx_sq = 0.0
        self.vx_n = 0
        self.last = None  # (estimate, truth dict at its time)

    def truth_at(self, s: float) -> dict:
        t = self.t
        out = {k: float(np.interp(s, t, self.tt[k])) for k in (
            "sideslip_rad", "vx_mps", "vy_mps", "yaw_rate_bias_radps", "accel_x_bias_eff_mps2",
            "accel_y_bias_eff_mps2", "gnss_delay_s", "wheel_scale", "speed_mps")}
        out["heading_rad"] = float(np.interp(s, t, self.heading_unwrapped)) % (2 * math.pi)
        return out

    def add(self, ests) -> None:
        for e in ests:
            s = self.to_sim_time(e.t)
            if not (self.t[0] <= s <= self.t[-1]):
                continue
            self.n += 1
            tr = None
            if e.sideslip_valid:
                tr = self.truth_at(s)
                err = e.sideslip_rad - tr["sideslip_rad"]
                self.beta_sq += err * err
                self.beta_n += 1
                self.beta_max = max(self.beta_max, abs(err))
            if e.heading_valid:
                tr = tr or self.truth_at(s)
                err = (e.heading_rad - tr["heading_rad"] + math.pi) % (2 * math.pi) - math.pi
                self.psi_sq += err * err
                self.psi_n += 1
            if e.velocity_valid:
                tr = tr or self.truth_at(s)
                err = e.vx_mps - tr["vx_mps"]
                self.vx_sq += err * err
                self.vx_n += 1
        if ests:
            e = ests[-1]
            s = self.to_sim_time(e.t)
            if self.t[0] <= s <= self.t[-1]:
                self.last = (e, self.truth_at(s))

    @staticmethod
    def _rms(sq, n):
        return math.sqrt(sq / n) if n else math.nan

    def rms_sideslip_deg(self) -> float:
        return self._rms(self.beta_sq, self.beta_n) * DEG

    def rms_heading_deg(self) -> float:
        return self._rms(self.psi_sq, self.psi_n) * DEG

    def rms_vx(self) -> float:
        return self._rms(self.vx_sq, self.vx_n)


class LogTail(io.TextIOBase):
    """Where log lines go while the full-screen view is up: the view shows the last few."""

    def __init__(self, n: int = 4) -> None:
        self.lines: collections.deque = collections.deque(maxlen=n)
        self.all: list[str] = []

    def write(self, s: str) -> int:
        for line in s.splitlines():
            if line.strip():
                self.lines.append(line)
                self.all.append(line)
        return len(s)


def _fmt(v: float, spec: str) -> str:
    return format(v, spec) if isinstance(v, (int, float)) and math.isfinite(v) else "-".rjust(len(format(0.0, spec)))


def _compass_deg(rad: float) -> float:
    """Heading in [0, 360) as printed to 0.1 deg: 359.96 deg reads 0.0, not 360.0."""
    return round(math.degrees(rad) % 360.0, 1) % 360.0


def _valid_or_dash(v: float, valid: bool, spec: str) -> str:
    """The value when the estimator flags it valid, a dash otherwise: the plain line shows what
    the bus promises, as the output frame's validity bit does."""
    return format(v, spec) if valid else "-".rjust(len(format(0.0, spec)))


class DemoSession:
    def __init__(self, cfg, sim, *, speed: float = 1.0, tui: bool = True, record_dir=None,
                 out=None, bus_config: dict | None = None) -> None:
        self.sim = sim
        self.speed = speed
        self.out = out if out is not None else sys.stdout
        self.tui = tui
        self.master, port = open_gnss_pty()
        # a second receiver (front-rear): its own pty, as the daemon opens one port per receiver
        self.master2 = None
        if len(cfg.gnss.receiver) >= 2:
            self.master2, port2 = open_gnss_pty()
            cfg.gnss.receiver[0].port, cfg.gnss.receiver[1].port = port, port2
        bus_config = dict(bus_config or {"interface": "virtual", "channel": f"ecu-daemon-demo-{os.getpid()}"})
        self.channel = str(bus_config["channel"])
        cfg.can.interface = bus_config["interface"]
        cfg.can.channel = self.channel
        cfg.gnss.port = port
        cfg.daemon.state_file = ""  # the demo must not touch a real installation's learned state
        self.cfg = cfg
        self.clock = time.monotonic if speed == 1.0 else ScaledClock(speed)
        self.feeder = Feeder(sim, self.channel, self.master, clock=self.clock, speed=speed, bus_config=bus_config,
                             gnss2_fd=self.master2)
        self.truth = TruthTracker(sim, self.feeder.sim_time)
        self.daemon = Daemon(cfg, bus_config=bus_config,
                             clock=self.clock, speed=speed, estimate_sink=self.truth.add, record_dir=record_dir)
        self.log_tail = LogTail() if tui else None
        self._last_line = -math.inf

    def run(self) -> int:
        setup_logging(self.cfg.daemon.log_level, stream=self.log_tail if self.tui else None)
        if self.tui:
            self.out.write("\x1b[?25l\x1b[2J")
        try:
            asyncio.run(self._main())
        finally:
            self.feeder.stop()
            os.close(self.master)
            if self.master2 is not None:
                os.close(self.master2)
            if self.tui:
                self.out.write("\x1b[?25h")
                self.out.flush()
                setup_logging(self.cfg.daemon.log_level)
        self.out.write(self.summary() + "\n")
        self.out.flush()
        return 0

    async def _main(self) -> None:
        d = self.daemon
        task = asyncio.create_task(d.run())
        while not d.ready.is_set() and not task.done():
            await asyncio.sleep(0.01)
        if task.done():
            await task  # raises the setup error
            return
        self.feeder.start()
        stop_at = None
        while not task.done():
            if (self.feeder.played.is_set() or self.feeder.finished.is_set()) and stop_at is None:
                stop_at = time.monotonic() + 0.03 / self.speed  # the last frames reach the estimator
            if stop_at is not None and time.monotonic() >= stop_at:
                d.request_stop()
            self._show()
            await asyncio.wait([task], timeout=0.03 if stop_at else 0.2)
        await task
        self._show(final=True)

    # ----------------------------------------------------------------------------- view
    def _lines(self) -> list[str]:
        d, sim = self.daemon, self.sim
        f = self.feeder
        now_s = f.sim_time(self.clock()) - sim.t0 if math.isfinite(f.c0) else 0.0
        dur = sim.t_end - sim.t0
        lines = [f"ecu-daemon demo: simulated drive '{sim.scenario.name}' on {self.cfg.can.interface}:{self.channel},"
                 f" GNSS on {', '.join(rx.port for rx in self.cfg.gnss.receivers())}",
                 f"t = {min(max(now_s, 0.0), dur):5.1f} / {dur:.1f} s   speed x{self.speed:g}   "
                 f"frames {f.frames_sent}  GNSS bytes {f.gnss_bytes}", ""]
        last = self.truth.last
        lines.append(f"{'':24}{'estimate':>10} {'+-1 sigma':>10} {'truth':>10} {'error':>9}  valid")
        if last is None:
            lines.append("  (waiting for the first estimate)")
        else:
            e, tr = last
            herr = (e.heading_rad - tr["heading_rad"] + math.pi) % (2 * math.pi) - math.pi
            rows = [
                ("sideslip [deg]", e.sideslip_rad * DEG, e.sideslip_std_rad * DEG, tr["sideslip_rad"] * DEG,
                 (e.sideslip_rad - tr["sideslip_rad"]) * DEG, e.sideslip_valid),
                ("heading [deg]", e.heading_rad * DEG, e.heading_std_rad * DEG, tr["heading_rad"] * DEG,
                 herr * DEG, e.heading_valid),
                ("vx [m/s]", e.vx_mps, e.vx_std_mps, tr["vx_mps"], e.vx_mps - tr["vx_mps"], e.velocity_valid),
                ("vy [m/s]", e.vy_mps, e.vy_std_mps, tr["vy_mps"], e.vy_mps - tr["vy_mps"], e.velocity_valid),
                ("yaw-rate bias [deg/s]", e.yaw_rate_bias_radps * DEG, e.yaw_rate_bias_std_radps * DEG,
                 tr["yaw_rate_bias_radps"] * DEG, (e.yaw_rate_bias_radps - tr["yaw_rate_bias_radps"]) * DEG,
                 e.biases_valid),
                ("ax bias [m/s2]", e.accel_x_bias_mps2, e.accel_x_bias_std_mps2, tr["accel_x_bias_eff_mps2"],
                 e.accel_x_bias_mps2 - tr["accel_x_bias_eff_mps2"], e.biases_valid),
                ("ay bias [m/s2]", e.accel_y_bias_mps2, e.accel_y_bias_std_mps2, tr["accel_y_bias_eff_mps2"],
                 e.accel_y_bias_mps2 - tr["accel_y_bias_eff_mps2"], e.biases_valid),
                ("GNSS latency [s]", e.gnss_delay_s, math.nan, tr["gnss_delay_s"],
                 e.gnss_delay_s - tr["gnss_delay_s"], True),
                ("wheel scale", e.wheel_scale, math.nan, tr["wheel_scale"], e.wheel_scale - tr["wheel_scale"], True),
            ]
            for name, v, sd, t, err, ok in rows:
                lines.append(f"  {name:22}{_fmt(v, '10.3f')} {_fmt(sd, '10.3f')} {_fmt(t, '10.3f')}"
                             f" {_fmt(err, '+9.3f')}  {'yes' if ok else 'no'}")
            flags = [name for bit, name in sorted(_STATUS_NAMES) if e.status & bit]
            lines.append(f"  status: {' '.join(flags) or '-'}   GNSS fused {e.gnss_fused}"
                         f" rejected {e.gnss_rejected} late {e.gnss_late}")
        lines.append("")
        tr = self.truth
        lines.append(f"  running RMS error (valid steps): sideslip {_fmt(tr.rms_sideslip_deg(), '.3f')} deg,"
                     f" heading {_fmt(tr.rms_heading_deg(), '.3f')} deg, vx {_fmt(tr.rms_vx(), '.3f')} m/s")
        diag = d.diag
        ts = d.tick_stats.snapshot()
        h = d.canio.health if d.canio else None
        fresh = sum(1 for x in diag.inputs.values() if x.age_ms < 1000)
        lines.append("")
        lines.append(f"health: inputs {fresh}/{len(diag.inputs)} fresh, GNSS fix {diag.gnss_fix_type}"
                     f" sv {diag.gnss_num_sv} age {_fmt(diag.gnss_receive_age_ms, '.0f')} ms,"
                     f" port {'open' if diag.gnss_serial_connected else 'closed'}")
        bus_state = BUS_STATE_NAMES.get(diag.can_bus_state, "?")
        lines.append(f"        CAN {bus_state}, error frames {diag.can_error_frames},"
                     f" sent {h.tx_sent if h else 0}, tx failures {diag.can_tx_failures}")
        lines.append(f"        tick lateness p50 {ts.late_p50_s * 1e6:.0f} us, p99 {ts.late_p99_s * 1e6:.0f} us,"
                     f" max {ts.late_max_s * 1e6:.0f} us, overruns {ts.overruns}, late samples {d.late_samples},"
                     f" CPU {diag.cpu_load_pct:.0f} %")
        if self.log_tail is not None and self.log_tail.lines:
            lines.append("")
            lines.append("log:")
            lines += ["  " + ln for ln in self.log_tail.lines]
        return lines

    def _show(self, final: bool = False) -> None:
        if self.tui:
            width = shutil.get_terminal_size((120, 40)).columns
            body = "".join(ln[:width] + "\x1b[K\n" for ln in self._lines())
            self.out.write("\x1b[H" + body + "\x1b[J")
            self.out.flush()
            return
        now = time.monotonic()
        if not final and now - self._last_line < 5.0:
            return
        self._last_line = now
        last = self.truth.last
        f = self.feeder
        t = f.sim_time(self.clock()) - self.sim.t0 if math.isfinite(f.c0) else 0.0
        if last is None:
            self.out.write(f"t={t:5.1f} s  waiting for the first estimate\n")
        else:
            e, tr = last
            self.out.write(f"t={t:5.1f} s  sideslip {_valid_or_dash(e.sideslip_rad * DEG, e.sideslip_valid, '+6.2f')} deg"
                           f" (truth {tr['sideslip_rad'] * DEG:+6.2f})"
                           f"  heading {_valid_or_dash(_compass_deg(e.heading_rad), e.heading_valid, '6.1f')} deg"
                           f" (truth {_compass_deg(tr['heading_rad']):6.1f})"
                           f"  vx {e.vx_mps:5.2f} m/s  RMS sideslip {_fmt(self.truth.rms_sideslip_deg(), '.3f')} deg"
                           f"  tick p99 {self.daemon.tick_stats.snapshot().late_p99_s * 1e6:.0f} us\n")
        self.out.flush()

    def summary(self) -> str:
        tr, d = self.truth, self.daemon
        ts = d.tick_stats.snapshot()
        lines = ["", f"demo summary ({tr.n} estimates compared with the simulator's truth):",
                 f"  sideslip RMS error {_fmt(tr.rms_sideslip_deg(), '.3f')} deg (max {tr.beta_max * DEG:.3f} deg)"
                 f" over {tr.beta_n} valid steps ({100.0 * tr.beta_n / max(tr.n, 1):.0f} %)",
                 f"  heading  RMS error {_fmt(tr.rms_heading_deg(), '.3f')} deg over {tr.psi_n} valid steps"
                 f" ({100.0 * tr.psi_n / max(tr.n, 1):.0f} %)",
                 f"  vx       RMS error {_fmt(tr.rms_vx(), '.3f')} m/s"]
        if tr.last is not None:
            e, t = tr.last
            lines.append(f"  final: yaw-rate bias {e.yaw_rate_bias_radps * DEG:+.3f} deg/s (truth"
                         f" {t['yaw_rate_bias_radps'] * DEG:+.3f}), GNSS latency {e.gnss_delay_s:.3f} s"
                         f" (truth {t['gnss_delay_s']:.3f})")
        est = d.estimator
        if est is not None and len(est.receivers) > 1:
            lines.append("  GNSS receivers: " + "; ".join(
                f"#{i + 1} fused {f.fused}, latency {lat.delay_s:.3f} s" for i, (f, lat)
                in enumerate(zip(est.receivers, est.latencies))))
        lines.append(f"  tick lateness p50 {ts.late_p50_s * 1e6:.0f} us, p99 {ts.late_p99_s * 1e6:.0f} us,"
                     f" max {ts.late_max_total_s * 1e6:.0f} us; {ts.overruns} overruns; {d.late_samples}"
                     f" late samples; {d.frames_sent} frames sent")
        return "\n".join(lines)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--duration", type=float, metavar="S", help="play only the first S seconds of the drive")
    parser.add_argument("--speed", type=float, default=1.0, metavar="X",
                        help="play X times faster than real time (default 1)")
    parser.add_argument("--no-tui", action="store_true", help="periodic lines instead of the live view")
    parser.add_argument("--config", "-C", help="base configuration (DBC, mapping); the vehicle comes from the scenario")
    parser.add_argument("--record", metavar="DIR", help="record what the daemon received, as `run --record` does")
    parser.add_argument("--gnss", choices=("velocity", "dual-antenna", "front-rear"), default="velocity",
                        help="the simulated receiver: velocity only (default), a dual-antenna moving-base pair"
                        " that adds the heading (UBX NAV-RELPOSNED, 1.2 m baseline across the car), or two"
                        " velocity receivers front and rear (2.5 m apart, own latency each, one pty each)")
    from can.cli import add_bus_arguments

    add_bus_arguments(parser, group_title="CAN bus (default: an in-process virtual bus; to watch the demo with"
                      " `ecu-daemon monitor` from another terminal or over ssh: -i udp_multicast -c 239.74.163.2)")


def main(args: argparse.Namespace) -> int:
    from .errors import UserError
    from .sim import SCENARIOS, simulate, vehicle_config
    from .sim.scenario import GNSS_SETUPS

    if not (args.speed > 0 and math.isfinite(args.speed)) or args.speed > 20:
        raise UserError("--speed must be a number between 0 and 20")
    bus_config = None
    if getattr(args, "interface", None) not in (None, "virtual"):
        if args.speed != 1.0:
            raise UserError(f"--speed must be 1 on a shared bus ({args.interface} stamps frames with real time)")
        bus_config = {k: v for k, v in bus_overrides(args).items() if v is not None}
        bus_config.setdefault("channel", "239.74.163.2" if args.interface == "udp_multicast" else "vcan0")
    scenario = SCENARIOS["demo"].with_(**GNSS_SETUPS[getattr(args, "gnss", None) or "velocity"])
    if args.duration is not None:
        if not args.duration > 1.0:
            raise UserError("--duration must be more than 1 second")
        scenario = scenario.with_(duration_s=min(args.duration, scenario.duration()))
    base = config_mod.load(args.config) if args.config else None
    cfg = vehicle_config(scenario, base)
    tui = not args.no_tui and sys.stdout.isatty()
    print(f"simulating the '{scenario.name}' drive ({scenario.duration():.0f} s) ...", file=sys.stderr, flush=True)
    sim = simulate(scenario, cfg)
    return DemoSession(cfg, sim, speed=args.speed, tui=tui, record_dir=args.record, bus_config=bus_config).run()
