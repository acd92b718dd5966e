"""GNSS serial port on a real pseudo-terminal: reading, receive timestamps, unplug and replug."""
from __future__ import annotations

import asyncio
import io
import logging
import os
import time
import tty

import pytest

from ecu_daemon.io.logging_setup import RateLimitFilter, reset_logging, setup_logging
from ecu_daemon.io.serial_port import GnssSerial


async def wait_for(cond, timeout=5.0, what="condition"):
    end = time.monotonic() + timeout
    while not cond():
        if time.monotonic() > end:
            raise AssertionError(f"timed out waiting for {what}")
        await asyncio.sleep(0.005)


class FakeReceiver:
    """A pty standing in for a USB GNSS receiver, reachable through a stable symlink."""

    def __init__(self, link):
        self.link = link
        self.master = -1
        self.plug()

    def plug(self):
        m, s = os.openpty()
        tty.setraw(s)
        if os.path.lexists(self.link):
            os.unlink(self.link)
        os.symlink(os.ttyname(s), self.link)
        os.close(s)
        self.master = m

    def unplug(self):
        os.close(self.master)
        os.unlink(self.link)
        self.master = -1

    def write(self, data):
        os.write(self.master, data)


@pytest.fixture
def log():
    buf = io.StringIO()
    setup_logging("info", stream=buf)
    yield buf
    reset_logging()


def test_unplug_and_replug_reconnects_and_says_so_once(tmp_path, log):
    got = []

    async def main():
        rx = FakeReceiver(str(tmp_path / "ttyGNSS"))
        port = GnssSerial(rx.link, 115200, on_data=lambda t, b: got.append((t, b)))
        port.start(asyncio.get_running_loop())
        assert port.connected
        t0 = time.monotonic()
        rx.write(b"$GPRMC,first*00\r\n")
        await wait_for(lambda: got, what="first bytes")
        assert t0 <= got[0][0] <= time.monotonic()  # stamped on the monotonic clock at read
        rx.unplug()
        await wait_for(lambda: not port.connected, what="loss detected")
        failures = port.open_failures
        # stay unplugged through several reconnect attempts (each one must stay quiet in the log)
        await wait_for(lambda: port.open_failures >= failures + 2, what="two failed reconnect attempts")
        assert not port.connected
        rx.plug()
        await wait_for(lambda: port.connected, timeout=10, what="reconnect")
        rx.write(b"$GPRMC,second*00\r\n")
        await wait_for(lambda: len(got) >= 2 and b"second" in b"".join(b for _, b in got),
                       what="bytes after replug")
        port.close()
        return port

    port = asyncio.run(main())
    data = b"".join(b for _, b in got)
    assert data == b"$GPRMC,first*00\r\n$GPRMC,second*00\r\n"  # nothing lost, nothing doubled
    ts = [t for t, _ in got]
    assert ts == sorted(ts)
    assert port.losses == 1 and port.reconnects == 1
    lines = [ln for ln in log.getvalue().splitlines() if "GNSS port" in ln]
    assert len(lines) == 2, lines
    assert "lost" in lines[0] and "reconnected" in lines[1]


def test_port_missing_at_start_is_retried(tmp_path, log):
    got = []

    async def main():
        link = str(tmp_path / "ttyLATE")
        port = GnssSerial(link, 9600, on_data=lambda t, b: got.append(b))
        port.start(asyncio.get_running_loop())
        assert not port.connected
        await wait_for(lambda: port.open_failures >= 2, what="a retry that failed too")  # said once only
        rx = FakeReceiver(link)
        await wait_for(lambda: port.connected, timeout=10, what="late port")
        rx.write(b"\xb5\x62hello")
        await wait_for(lambda: got, what="bytes")
        port.close()
        rx.unplug()
        return port

    port = asyncio.run(main())
    assert got == [b"\xb5\x62hello"]
    assert port.losses == 0
    text = log.getvalue()
    assert text.count("not available") == 1 and text.count("available after") == 1


def test_rate_limited_logging_counts_suppressed_lines():
    """One line per kind per interval; the next line let through says how many were held back."""
    now = [100.0]
    buf = io.StringIO()
    handler = logging.StreamHandler(buf)
    handler.addFilter(RateLimitFilter(interval_s=10.0, clock=lambda: now[0]))
    lg = logging.getLogger("ecu_daemon.test.ratelimit")
    lg.addHandler(handler)
    try:
        for i in range(50):
            lg.warning("bad frame 0x%X", i)
        lg.warning("another kind of problem")
        now[0] += 9.9  # still inside the interval: held back and counted
        lg.warning("bad frame 0x%X", 50)
        assert buf.getvalue().splitlines() == ["bad frame 0x0", "another kind of problem"]
        now[0] += 0.1  # the interval is over: this line goes out and says what was suppressed
        lg.warning("bad frame 0x%X", 51)
        lg.warning("bad frame 0x%X", 52)
        assert buf.getvalue().splitlines()[2:] == ["bad frame 0x33 (+50 similar suppressed)"]
    finally:
        lg.removeHandler(handler)


def _gnss_rx_threads():
    import threading
    return [th for th in threading.enumerate() if th.name.startswith("ecu-gnss-rx")]


def test_stamp_is_the_arrival_not_when_the_loop_gets_round_to_it(tmp_path):
    """Bytes written while the event loop is blocked are stamped when they arrive, before the
    block ends: the port is read in its own thread. (Read from ``loop.add_reader``, the stamp was
    when the loop got round to the port: after the block.) The block ends as soon as the port has
    read the bytes, or after 5 s: only the order of the times is asserted."""
    got = []
    marks = {}

    async def main():
        rx = FakeReceiver(str(tmp_path / "ttyBLOCK"))
        # stamps not rounded to 1 us: the order is asserted to the clock's own resolution
        port = GnssSerial(rx.link, 115200, on_data=lambda t, b: got.append((t, b)), quantum_s=1e-9)
        port.start(asyncio.get_running_loop())
        done = asyncio.Event()

        def write_then_block():
            marks["write"] = time.monotonic()
            rx.write(b"$GPRMC,during-block*00\r\n")
            end = marks["write"] + 5.0
            while port.bytes_read == 0 and time.monotonic() < end:
                pass  # the loop is busy (a long callback, a GC pause, a recording flush)
            marks["unblock"] = time.monotonic()
            assert not got  # handed on in the loop only, after this callback
            done.set()

        asyncio.get_running_loop().call_soon(write_then_block)
        await done.wait()
        await wait_for(lambda: got, what="the chunk")
        port.close()
        rx.unplug()

    asyncio.run(main())
    assert b"".join(b for _, b in got) == b"$GPRMC,during-block*00\r\n"
    assert marks["write"] <= got[0][0] < marks["unblock"]
    assert not _gnss_rx_threads()  # close() left no reader behind


def test_drain_delivers_every_byte_in_order_and_stops_the_reader(tmp_path):
    """Chunks written while the loop never gets round to them (shutdown right after) all reach
    on_data by drain(), in order, with non-decreasing stamps; no reader thread is left."""
    got = []
    msgs = [f"$GPGGA,{i:04d}*00\r\n".encode() for i in range(200)]

    async def main():
        rx = FakeReceiver(str(tmp_path / "ttyDRAIN"))
        port = GnssSerial(rx.link, 115200, on_data=lambda t, b: got.append((t, b)))
        port.start(asyncio.get_running_loop())
        assert _gnss_rx_threads()
        for m in msgs:
            rx.write(m)
        port.drain()  # no await in between: the loop never delivered a chunk itself
        port.close()
        assert not _gnss_rx_threads()
        rx.unplug()

    asyncio.run(main())
    assert b"".join(b for _, b in got) == b"".join(msgs)
    ts = [t for t, _ in got]
    assert ts == sorted(ts)
