"""CAN side of the shell on python-can's real ``virtual`` bus: time base, filters, error frames, bus-off."""
from __future__ import annotations

import asyncio
import itertools
import time

import can
import pytest
from can.interfaces.virtual import VirtualBus

from ecu_daemon.config import CanSettings, ConfigError
from ecu_daemon.io import can_bus
from ecu_daemon.io.can_bus import BusHealth, CanIO, ClockMapper, resolve_bus_config

_chan = itertools.count()


def channel():
    return f"test-can-{next(_chan)}"


async def wait_for(cond, timeout=5.0, what="condition"):
    end = time.monotonic() + timeout
    while not cond():
        if time.monotonic() > end:
            raise AssertionError(f"timed out waiting for {what}")
        await asyncio.sleep(0.002)


# ----------------------------------------------------------------------------------- ClockMapper
def test_clock_mapper_uses_the_minimum_latency_offset_and_stays_causal():
    m = ClockMapper()
    offset = 1000.0  # message clock = monotonic + 1000 s (like CLOCK_REALTIME vs CLOCK_MONOTONIC)
    latencies = [0.0030, 0.0002, 0.0050, 0.0004, 0.0100]
    out = []
    for i, lat in enumerate(latencies):
        ts = offset + 10.0 + i * 0.01  # when the frame hit the wire, message clock
        now = ts - offset + lat  # when Python got to it
        t = m.map(ts, now)
        assert t <= now + 5e-7  # never in the future
        out.append(t)
    # from the second frame on, offset = clock offset + the 0.2 ms minimum latency: frames keep
    # their kernel spacing whatever Python's own delay was
    assert out[1] == pytest.approx(10.0102, abs=1e-6)
    assert out[4] == pytest.approx(10.0402, abs=1e-6)  # a 10 ms late frame keeps its kernel time
    assert all(round(t * 1e6) == pytest.approx(t * 1e6, abs=1e-6) for t in out)  # 1 us grid


def test_clock_mapper_follows_clock_steps():
    m = ClockMapper(block_s=0.5, blocks=4, step_s=0.05)
    now = 100.0
    for _ in range(200):  # 1 s of frames, message clock = monotonic + 50
        now += 0.005
        m.map(now + 50.0, now + 1e-4)
    assert m.offset_s == pytest.approx(-50.0, abs=1e-3)
    # the message clock jumps 2 s forward (NTP step): adopted at once
    now += 0.005
    t = m.map(now + 52.0, now + 1e-4)
    assert m.offset_s == pytest.approx(-52.0, abs=1e-3) and t == pytest.approx(now, abs=1e-3)
    # ... and 5 s back: detected when a whole block sits far above the estimate
    for _ in range(400):
        now += 0.005
        t = m.map(now + 47.0, now + 1e-4)
    assert m.steps >= 1
    assert m.offset_s == pytest.approx(-47.0, abs=1e-3) and t == pytest.approx(now, abs=1e-3)


def test_clock_mapper_output_never_goes_backwards_and_handles_missing_timestamps():
    m = ClockMapper()
    a = m.map(5000.0, 10.0)
    b = m.map(4999.0, 10.001)  # a frame with an older timestamp than the previous one
    assert b >= a
    c = m.map(0.0, 10.5)  # interface without timestamps: stamped at reception
    assert c == pytest.approx(10.5) and m.untimestamped == 1


# ----------------------------------------------------------------------------------- BusHealth
def err_frame(cls, data=b"\0" * 8):
    return can.Message(is_error_frame=True, arbitration_id=cls, data=data, is_extended_id=False)


def test_bus_health_decodes_error_classes():
    h = BusHealth()
    h.on_error_frame(err_frame(can_bus.CAN_ERR_CRTL | can_bus.CAN_ERR_CNT,
                               bytes([0, can_bus.CAN_ERR_CRTL_TX_WARNING, 0, 0, 0, 0, 97, 12])), 1.0)
    assert h.state == can_bus.BUS_WARNING and (h.tx_error_counter, h.rx_error_counter) == (97, 12)
    passive = bytes([0, can_bus.CAN_ERR_CRTL_TX_PASSIVE, 0, 0, 0, 0, 0, 0])
    h.on_error_frame(err_frame(can_bus.CAN_ERR_CRTL, passive), 1.1)
    assert h.state == can_bus.BUS_PASSIVE
    h.on_error_frame(err_frame(can_bus.CAN_ERR_BUSOFF), 1.2)
    assert h.bus_off and h.bus_off_count == 1 and not h.may_send(1.3)
    h.on_error_frame(err_frame(can_bus.CAN_ERR_RESTARTED), 1.4)
    assert not h.bus_off and h.restarts == 1 and h.may_send(1.4)
    assert h.error_frames == 4 and h.tx_suppressed == 1


def test_bus_off_without_restart_retries_with_growing_interval():
    h = BusHealth()
    h.on_error_frame(err_frame(can_bus.CAN_ERR_BUSOFF), 10.0)
    assert not h.may_send(10.4) and h.may_send(10.0 + BusHealth.RETRY_MIN_S)
    h.on_error_frame(err_frame(can_bus.CAN_ERR_BUSOFF), 11.0)  # still off: wait twice as long
    assert not h.may_send(11.0 + BusHealth.RETRY_MIN_S) and h.may_send(11.0 + 2 * BusHealth.RETRY_MIN_S)
    assert h.bus_off_count == 1  # one episode


def test_consecutive_send_failures_pause_transmission():
    h = BusHealth()
    for _ in range(BusHealth.TX_FAIL_LIMIT):
        assert h.may_send(1.0)
        h.on_send_failed(1.0, can.CanOperationError("Transmit buffer full"))
    assert not h.may_send(1.0 + BusHealth.TX_PAUSE_MIN_S / 2)
    assert h.may_send(1.0 + BusHealth.TX_PAUSE_MIN_S)
    h.on_send_ok()
    assert h.tx_failures == BusHealth.TX_FAIL_LIMIT and h.tx_sent == 1


# ----------------------------------------------------------------------------------- CanIO on a virtual bus
def test_canio_filters_maps_time_and_backs_off_on_bus_off():
    ch = channel()
    got = []

    async def main():
        bus = can.Bus(interface="virtual", channel=ch)
        peer = can.Bus(interface="virtual", channel=ch)
        io = CanIO(bus, [(0x0B0, False), (0x18FF0010, True)], on_frame=lambda t, m: got.append((t, m)))
        assert not io.kernel_filters  # virtual filters in Python: done here, error frames must pass
        io.start()
        try:
            t0 = time.monotonic()
            peer.send(can.Message(arbitration_id=0x0B0, data=b"\x01" * 8, is_extended_id=False))
            peer.send(can.Message(arbitration_id=0x0B1, data=b"\x02" * 8, is_extended_id=False))  # not ours
            peer.send(can.Message(arbitration_id=0x0B0, data=b"\x03" * 8, is_extended_id=True))  # wrong kind
            peer.send(can.Message(arbitration_id=0x18FF0010, data=b"\x04" * 8, is_extended_id=True))
            await wait_for(lambda: len(got) == 2 and io.rx_ignored == 2, what="filtered frames")
            assert [bytes(m.data)[:1] for _, m in got] == [b"\x01", b"\x04"]
            assert all(t0 <= t <= time.monotonic() for t, _ in got)  # on the monotonic clock
            assert io.send(can.Message(arbitration_id=0x300, data=b"\0" * 8, is_extended_id=False))
            assert peer.recv(1.0).arbitration_id == 0x300
            # bus-off reported by the controller: transmission stops
            peer.send(can.Message(is_error_frame=True, arbitration_id=can_bus.CAN_ERR_BUSOFF, data=b"\0" * 8))
            await wait_for(lambda: io.health.bus_off, what="bus-off")
            assert not io.send(can.Message(arbitration_id=0x300, data=b"\xee" * 8, is_extended_id=False))
            assert io.health.tx_suppressed == 1
            # a frame from another node proves the controller is back on the bus
            peer.send(can.Message(arbitration_id=0x0B0, data=b"\x05" * 8, is_extended_id=False))
            await wait_for(lambda: not io.health.bus_off, what="recovery")
            assert io.send(can.Message(arbitration_id=0x300, data=b"\0" * 8, is_extended_id=False))
            # the next frame on the bus is the one sent after recovery: the suppressed one never went out
            assert bytes(peer.recv(5.0).data) == b"\0" * 8
            assert io.health.restarts == 1 and io.health.error_frames == 1
        finally:
            io.shutdown()
            peer.shutdown()

    asyncio.run(main())


def test_send_failures_are_counted_not_fatal():
    ch = channel()
    bus = can.Bus(interface="virtual", channel=ch)
    peer = can.Bus(interface="virtual", channel=ch, rx_queue_size=1)  # a receiver that never reads
    # a frozen clock: the six sends fall inside the pause however slowly this machine runs them
    io = CanIO(bus, [], on_frame=lambda t, m: None, clock=lambda: 100.0)
    try:
        msg = can.Message(arbitration_id=0x300, data=b"\0" * 8, is_extended_id=False)
        results = [io.send(msg) for _ in range(6)]
        assert results[0] is True and results[1] is False  # queue full -> CanOperationError
        assert io.health.tx_failures == BusHealth.TX_FAIL_LIMIT  # then paused, not hammering
        assert io.health.tx_suppressed == 6 - 1 - BusHealth.TX_FAIL_LIMIT
    finally:
        io.shutdown()
        peer.shutdown()


# ----------------------------------------------------------------------------------- bus configuration
def test_bus_config_precedence(monkeypatch, tmp_path):
    monkeypatch.setenv("CAN_INTERFACE", "virtual")
    monkeypatch.setenv("CAN_CHANNEL", "from-env")
    monkeypatch.setenv("CAN_BITRATE", "250000")
    monkeypatch.setattr(can, "rc", {})
    s = CanSettings()
    # nothing in the TOML: python-can's own configuration wins over our defaults
    cfg = resolve_bus_config(s)
    assert (cfg["interface"], cfg["channel"], cfg["bitrate"]) == ("virtual", "from-env", 250000)
    # written in the TOML: beats the environment
    s.channel = "from-toml"
    cfg = resolve_bus_config(s, explicit_keys={"channel"})
    assert cfg["channel"] == "from-toml" and cfg["bitrate"] == 250000
    # command-line flags beat both
    cfg = resolve_bus_config(s, explicit_keys={"channel"}, overrides={"channel": "from-cli", "bitrate": 1000000})
    assert (cfg["channel"], cfg["bitrate"]) == ("from-cli", 1000000)
    # bus_kwargs pass through
    s.bus_kwargs = {"receive_own_messages": True}
    assert resolve_bus_config(s)["receive_own_messages"] is True


def test_unknown_interface_is_a_config_error(monkeypatch):
    monkeypatch.delenv("CAN_INTERFACE", raising=False)
    s = CanSettings(interface="nosuchbus")
    with pytest.raises(ConfigError, match="nosuchbus"):
        resolve_bus_config(s, explicit_keys={"interface"})


def test_kernel_filters_are_used_where_the_interface_has_them():
    from can.interfaces.socketcan import SocketcanBus
    from can.interfaces.virtual import VirtualBus

    assert can_bus._has_own_filtering(SocketcanBus)  # CAN_RAW_FILTER in the kernel
    assert not can_bus._has_own_filtering(VirtualBus)  # Python filtering: done by CanIO itself


def test_frames_created_on_this_host_are_inputs_too():
    """socketcan flags frames from any local socket (canplayer onto vcan0) with is_rx=False."""
    ch = channel()
    got = []
    bus = can.Bus(interface="virtual", channel=ch)
    io = CanIO(bus, [(0x0B0, False)], on_frame=lambda t, m: got.append(m))
    try:
        io._on_message(can.Message(arbitration_id=0x0B0, data=bytes(8), is_extended_id=False, is_rx=False,
                                   timestamp=time.time()))
        io._on_message(can.Message(arbitration_id=0x300, data=bytes(8), is_extended_id=False, is_rx=False,
                                   timestamp=time.time()))  # our own output echoed: not an input id
        assert [m.arbitration_id for m in got] == [0x0B0] and io.rx_ignored == 1
    finally:
        io.shutdown()


def test_a_batch_keeps_each_frames_own_time():
    """Frames read together (one wake-up of the reader, a backlog) keep the sender's spacing,
    even while the clock window is young, and none is stamped after it was read."""
    ch = channel()
    got = []
    bus = can.Bus(interface="virtual", channel=ch)
    peer = can.Bus(interface="virtual", channel=ch)
    io = CanIO(bus, [(0x0B0, False)], on_frame=lambda t, m: got.append((t, m)))
    try:
        peer.send(can.Message(arbitration_id=0x0B0, data=b"\x01" * 8, is_extended_id=False))
        time.sleep(0.05)  # the spacing itself is read back from the frames' own timestamps
        peer.send(can.Message(arbitration_id=0x0B1, data=b"\x02" * 8, is_extended_id=False))  # not ours
        peer.send(can.Message(arbitration_id=0x0B0, data=b"\x03" * 8, is_extended_id=False))
        assert io.drain() == 3 and io.rx_batches == 1 and io.rx_ignored == 1
        (t1, m1), (t2, m2) = got
        assert t2 <= time.monotonic()
        assert abs((t2 - t1) - (m2.timestamp - m1.timestamp)) < 2e-6  # the sender's spacing, to the us
        assert m2.timestamp - m1.timestamp >= 0.05
        assert io.drain() == 0
    finally:
        io.shutdown()
        peer.shutdown()


class _FilteringBus(VirtualBus):
    """A virtual bus that filters where socketcan does, below ``recv`` (``_apply_filters``, the
    frames it drops never reach Python); ``refuse`` makes it fall back like socketcan does when
    the kernel refuses the filter list (``_is_filtered`` False, python-can's software filter)."""

    refuse = False

    def _apply_filters(self, filters):
        self.applied = filters
        self._is_filtered = bool(filters) and not self.refuse

    def _recv_internal(self, timeout):
        while True:
            msg, _ = super()._recv_internal(timeout)
            if msg is None or not self._is_filtered or msg.is_error_frame or self._matches_filters(msg):
                return msg, self._is_filtered
            timeout = 0  # dropped below recv, as CAN_RAW_FILTER does


def test_unconsumed_ids_are_filtered_on_the_bus_where_it_can():
    """On an interface that filters (socketcan: CAN_RAW_FILTER), the frames the decoder does not
    consume never reach the reader: CanIO hands the bus exactly the decoder's ids."""
    ch = channel()
    got = []
    bus = _FilteringBus(channel=ch)
    peer = can.Bus(interface="virtual", channel=ch)
    io = CanIO(bus, [(0x0B0, False), (0x18FF0010, True)], on_frame=lambda t, m: got.append(m))
    try:
        assert io.kernel_filters
        assert sorted((f["can_id"], f["can_mask"], f["extended"]) for f in bus.applied) == [
            (0x0B0, 0x7FF, False), (0x18FF0010, 0x1FFFFFFF, True)]
        for fid, ext in ((0x0B1, False), (0x0B0, False), (0x0B0, True), (0x18FF0010, True), (0x120, False)):
            peer.send(can.Message(arbitration_id=fid, data=bytes(8), is_extended_id=ext))
        peer.send(can.Message(is_error_frame=True, arbitration_id=can_bus.CAN_ERR_CRTL, data=bytes(8)))
        assert io.drain() == 3  # two of ours and the error frame: the others stayed below recv
        assert [(m.arbitration_id, m.is_extended_id) for m in got] == [(0x0B0, False), (0x18FF0010, True)]
        assert io.rx_ignored == 0 and io.health.error_frames == 1
    finally:
        io.shutdown()
        peer.shutdown()


def test_a_refused_bus_filter_falls_back_to_filtering_here_with_error_frames_and_whole_batches():
    """socketcan falls back to python-can's software filter when the kernel refuses the list; that
    one drops error frames and ends a recv(0) batch at the first frame it drops. CanIO takes it
    off and filters itself."""
    ch = channel()
    got = []
    bus = _FilteringBus(channel=ch)
    bus.refuse = True
    peer = can.Bus(interface="virtual", channel=ch)
    io = CanIO(bus, [(0x0B0, False)], on_frame=lambda t, m: got.append(m))
    try:
        assert not io.kernel_filters and bus.applied is None
        peer.send(can.Message(arbitration_id=0x120, data=bytes(8), is_extended_id=False))  # not ours
        peer.send(can.Message(arbitration_id=0x0B0, data=bytes(8), is_extended_id=False))
        peer.send(can.Message(is_error_frame=True, arbitration_id=can_bus.CAN_ERR_CRTL, data=bytes(8)))
        assert io.drain() == 3 and io.rx_batches == 1  # one batch: the foreign frame did not end it
        assert [m.arbitration_id for m in got] == [0x0B0]
        assert io.rx_ignored == 1 and io.health.error_frames == 1
    finally:
        io.shutdown()
        peer.shutdown()
