"""The UBX fast paths against pyubx2, their reference: the Fletcher checksum and the NAV-PVT
``struct`` decoder, on every capture of ../shared/data/gnss-captures and tests/data/gnss, on a
simulated drive's capture and on random and extreme payloads."""
from __future__ import annotations

import struct
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ecu_daemon.gnss import stream, ubx
from ecu_daemon.gnss.logfile import raw_capture_bytes, read_gnss_log
from ecu_daemon.gnss.stream import GnssStreamParser
from ecu_daemon.gnss.ubx import UbxDecoder, nav_pvt_sample, ubx_checksum, ubx_checksum_reference
from ecu_daemon.sim import SCENARIOS, simulate, vehicle_config
from ecu_daemon.sim.writer import write_all

from test_gnss_captures import key

ROOT = Path(__file__).resolve().parents[1]
CAPTURE_DIRS = (ROOT.parent / "shared" / "data" / "gnss-captures", ROOT / "tests" / "data" / "gnss")
CAPTURES = sorted(p for d in CAPTURE_DIRS for p in d.rglob("*") if p.is_file() and p.suffix in (".log", ".ubx"))


def _frame(cls: int, mid: int, payload: bytes) -> bytes:
    body = bytes((cls, mid)) + struct.pack("<H", len(payload)) + payload
    return b"\xb5\x62" + body + ubx_checksum_reference(body)


def _nav_pvt(payload: bytes) -> bytes:
    return _frame(0x01, 0x07, payload)


def _same(frame: bytes, t: float = 12.5) -> None:
    assert key(nav_pvt_sample(t, frame)) == key(UbxDecoder.nav_pvt_reference(t, frame))


@pytest.fixture(scope="module")
def sim_capture(tmp_path_factory):
    sc = SCENARIOS["demo"].with_(duration_s=20.0)
    d = tmp_path_factory.mktemp("ubx_fast")
    write_all(d, simulate(sc, vehicle_config(sc)))
    return d / "drive_gnss.log"


class _Recording(UbxDecoder):
    def __init__(self, frames: list) -> None:
        super().__init__()
        self.frames = frames

    def decode(self, t, frame):
        self.frames.append(frame)
        return super().decode(t, frame)


def _frames_of(data: bytes) -> list[bytes]:
    """Every checksum-valid UBX frame the stream parser accepts (its own framing)."""
    frames: list[bytes] = []
    p = GnssStreamParser("auto")
    p._ubx = _Recording(frames)
    p.feed(0.0, data)
    p.finish()
    return frames


def _parse(data_or_items, monkeypatch=None, reference=False):
    """Samples and counters of one stream, with the fast paths or with pyubx2's."""
    if reference:
        monkeypatch.setattr(stream, "ubx_checksum", ubx_checksum_reference)
        monkeypatch.setattr(ubx, "nav_pvt_sample", UbxDecoder.nav_pvt_reference)
    try:
        p = GnssStreamParser("auto")
        items = [(0.0, data_or_items)] if isinstance(data_or_items, bytes) else data_or_items
        out = [s for t, b in items for s in p.feed(t, b)] + p.finish()
        return [key(s) for s in out], dict(p.stats)
    finally:
        if reference:
            monkeypatch.undo()


def test_every_capture_gives_the_same_samples_and_counters_as_pyubx2(monkeypatch):
    # the vendored extracts always; the shared captures (84 more) where ../shared is checked out
    assert len(CAPTURES) >= (50 if CAPTURE_DIRS[0].is_dir() else 20)
    nav_pvt = 0
    for path in CAPTURES:
        data = raw_capture_bytes(path)
        for frame in _frames_of(data):
            assert ubx_checksum(frame[2:-2]) == ubx_checksum_reference(frame[2:-2]) == frame[-2:]
            if frame[2:4] == b"\x01\x07" and len(frame) == 100:
                nav_pvt += 1
                _same(frame)
        assert _parse(data) == _parse(data, monkeypatch, reference=True), path
    # the captures hold real NAV-PVT traffic, not just a handful
    assert nav_pvt > (300 if CAPTURE_DIRS[0].is_dir() else 150)


def test_a_simulated_drive_gives_the_same_samples_as_pyubx2(sim_capture, monkeypatch):
    items = [(t, b) for t, _, b in read_gnss_log(sim_capture)]
    fast = _parse(items)
    assert len(fast[0]) > 90 and fast[1]["ubx_frames"] > 90
    assert fast == _parse(items, monkeypatch, reference=True)


@settings(max_examples=300, deadline=None)
@given(st.binary(min_size=92, max_size=92), st.floats(0, 1e6))
def test_nav_pvt_on_random_payloads_equals_pyubx2(payload, t):
    _same(_nav_pvt(payload), t)


@pytest.mark.parametrize("payload", [
    bytes(92), b"\xff" * 92, b"\x80" * 92, b"\x7f" * 92,
    # valid date and time flags with an impossible date (month 13) and a negative nano
    bytes(4) + struct.pack("<HBBBBBB", 2024, 13, 1, 0, 0, 0, 0x03) + bytes(4) + struct.pack("<i", -5) + bytes(72),
    # invalidLlh set: no position
    bytes(78) + struct.pack("<H", 1) + bytes(12),
])
def test_nav_pvt_extremes_equal_pyubx2(payload):
    _same(_nav_pvt(payload))


@given(st.binary(max_size=300))
def test_checksum_equals_pyubx2(body):
    assert ubx_checksum(body) == ubx_checksum_reference(body)
    assert ubx_checksum(bytearray(body)) == ubx_checksum(memoryview(body)) == ubx_checksum_reference(body)


@pytest.mark.parametrize("length", [0, 91, 93, 100])
def test_nav_pvt_of_another_length_stays_malformed_and_never_reaches_the_fast_decoder(length, monkeypatch):
    called = []
    monkeypatch.setattr(ubx, "nav_pvt_sample", lambda *a: called.append(a))
    p = GnssStreamParser("auto")
    assert p.feed(1.0, _nav_pvt(bytes(length))) + p.finish() == []
    assert p.stats["malformed"] == 1 and called == []
