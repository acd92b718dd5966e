"""Resynchronising on garbage made of frame headers: the range checks behind it, and the frames
that follow the garbage are still found (the rate is measured in tools/bench_gnss.py)."""
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
