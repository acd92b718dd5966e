"""Resynchronising on garbage made of frame headers: the range checks behind it, and the frames
that follow the garbage are still found, and the work is linear (the rate is measured in tools/bench_gnss.py)."""
from __future__ import annotations

from hypothesis import given, settings, strategies as st

from ecu_daemon.gnss import GnssStreamParser
from ecu_daemon.gnss import encode as enc
from ecu_daemon.gnss.stream import _RangeChecks, crc24q
from ecu_daemon.gnss.ubx import ubx_checksum

T0 = 1700000000.0


@settings(max_examples=200, deadline=None)
@given(st.binary(min_size=1, max_size=3000), st.data())
def test_range_checks_equal_the_direct_checksums(data, draw):
    buf = bytearray(data)
    rc = _RangeChecks(buf, len(buf))
    a = draw.draw(st.integers(0, len(buf)))
    b = draw.draw(st.integers(a, min(len(buf), a + 1029)))
    assert rc.fletcher(a, b) == ubx_checksum(buf[a:b])
    assert rc.crc24q(a, b) == crc24q(buf[a:b])


def test_frames_behind_header_garbage_are_found_after_long_claimed_frames():
    pvt = enc.nav_pvt(**enc.utc_fields(T0), lat_deg=48.1, lon_deg=11.5, vel_n_mps=10.0, vel_e_mps=1.0)
    junk = b"\xb5\x62\x01\x07\xff\x1f" * 3000 + b"\xd3\x03\xff" * 2000
    stream = junk + pvt + junk[:7000] + pvt
    p = GnssStreamParser("ubx")
    got = []
    for i in range(0, len(stream), 256):
        got += p.feed(i * 1e-5, stream[i:i + 256])
    got += p.finish()
    assert len(got) == 2 and p.stats["ubx_frames"] == 2
    assert p.stats["garbage_bytes"] == len(junk) + 7000


def test_resynchronising_on_header_garbage_is_linear_in_its_length(monkeypatch):
    """Counted, not timed: the bytes the checksums go over (direct checks and the prefix tables).
    Checking every candidate over the 8 kB its header claims cost ~1400 bytes of checksum per byte
    of garbage (11 kB/s, a 115200-baud line's whole rate); the prefix tables make it a constant."""
    from ecu_daemon.gnss import stream

    work = [0]
    ubx_ck, crc, checks = stream.ubx_checksum, stream.crc24q, stream._RangeChecks

    class CountedChecks(checks):
        def __init__(self, buf, n):
            work[0] += n
            super().__init__(buf, n)

    monkeypatch.setattr(stream, "ubx_checksum", lambda d: (work.__setitem__(0, work[0] + len(d)), ubx_ck(d))[1])
    monkeypatch.setattr(stream, "crc24q", lambda d: (work.__setitem__(0, work[0] + len(d)), crc(d))[1])
    monkeypatch.setattr(stream, "_RangeChecks", CountedChecks)
    for unit in (b"\xb5\x62\x01\x07\xff\x1f", b"\xd3\x03\xff"):  # UBX claiming 8191 B, RTCM3 1023 B
        per_byte = []
        for size in (60_000, 240_000):
            work[0] = 0
            data = (unit * (size // len(unit) + 1))[:size]
            p = GnssStreamParser("auto")
            for i in range(0, size, 256):  # as a serial port delivers it
                assert p.feed(i * 1e-5, data[i:i + 256]) == []
            p.finish()
            assert p.stats["garbage_bytes"] == size
            per_byte.append(work[0] / size)
        assert max(per_byte) < 64 and per_byte[1] < 1.5 * per_byte[0], (unit.hex(), per_byte)
