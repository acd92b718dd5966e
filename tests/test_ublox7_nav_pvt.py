"""u-blox 7 receivers (NEO-7M and its clones, UBX protocol 14) send NAV-PVT with an 84-byte payload:
the fields of the 92-byte u-blox 8+ message up to pDOP, then reserved bytes (no flags3, headVeh,
magDec, magAcc). Before: every one was "malformed" ("NAV-PVT payload is 84 bytes, expected 92"),
nothing was fused, and the replay ended with exit 3 blaming "248 NAV-VELNED without a NAV-STATUS"
of a receiver that sent no NAV-VELNED at all."""
from __future__ import annotations

import math
import struct

from ecu_daemon.cli import main as cli_main
from ecu_daemon.gnss import encode
from ecu_daemon.gnss.logfile import read_gnss_log
from ecu_daemon.gnss.stream import GnssStreamParser
from ecu_daemon.gnss.ubx import UbxDecoder, nav_pvt_sample, ubx_checksum

from test_gnss_captures import key


def _resized(frame: bytes, n: int, fill: int = 0) -> bytes:
    """A NAV-PVT frame cut (or padded with ``fill``) to an n-byte payload, checksum redone."""
    payload = frame[6:-2][:n].ljust(n, bytes([fill]))
    body = frame[2:4] + struct.pack("<H", n) + payload
    return b"\xb5\x62" + body + ubx_checksum(body)


def _pvt(**kw) -> bytes:
    return encode.nav_pvt(**encode.utc_fields(1717228800.2), lat_deg=48.1, lon_deg=11.5, vel_n_mps=12.3,
                          vel_e_mps=-4.5, vel_d_mps=0.2, speed_acc_mps=0.25, **kw)


def _samples(data: bytes):
    p = GnssStreamParser("auto")
    return p.feed(1.0, data) + p.finish(), p


def test_an_84_byte_nav_pvt_gives_the_sample_of_its_92_byte_original():
    full = _pvt()
    (s92,), _ = _samples(full)
    (s7,), p = _samples(_resized(full, 84))
    assert key(s7) == key(s92) and p.stats["malformed"] == 0
    assert (s7.vel_n_mps, s7.vel_e_mps, s7.speed_acc_mps, s7.fix_ok) == (12.3, -4.5, 0.25, True)


def test_u_blox_7_reserved_bytes_do_not_void_the_position_fast_path_and_pyubx2_alike():
    """Bytes 78-83 are reserved in protocol 14: a set bit there is not u-blox 8's invalidLlh."""
    frame = _resized(_pvt(), 84)
    frame = _resized(frame[:84] + b"\xff" * 6 + frame[90:], 84)  # reserved bytes all ones
    fast = nav_pvt_sample(2.0, frame)
    assert key(fast) == key(UbxDecoder.nav_pvt_reference(2.0, frame))
    assert math.isclose(fast.lat_deg, 48.1) and math.isclose(fast.lon_deg, 11.5)
    flagged = _pvt(invalid_llh=True)  # on u-blox 8+ the flag still voids it
    assert math.isnan(nav_pvt_sample(2.0, flagged).lat_deg)


def test_a_nav_pvt_of_another_length_is_named_as_undecodable_not_as_a_missing_nav_status():
    samples, p = _samples(b"".join(_resized(_pvt(), 80) for _ in range(3)))
    assert samples == [] and p.stats["malformed"] == 3
    why = p.why_unusable()
    assert why.startswith("none of its 3 velocity messages could be decoded (3 malformed; the last: NAV-PVT"
                          " payload is 80 bytes, expected 92 (or 84, u-blox 7))"), why
    assert "NAV-VELNED" not in why


def test_a_drive_logged_by_a_u_blox_7_replays_with_its_gnss_fused(tmp_path, capsys):
    d = tmp_path / "drive"
    assert cli_main(["simulate", "--scenario", "straight_dry", "--duration", "20", "--out", str(d)]) == 0
    with open(tmp_path / "ublox7.log", "w") as f:
        for t, port, frame in read_gnss_log(d / "drive_gnss.log"):
            f.write(f"({t:.6f}) {port} {_resized(frame, 84).hex().upper()}\n")
    capsys.readouterr()
    rc = cli_main(["replay", "--config", str(d / "config.toml"), "--can", str(d / "drive.log"),
                   "--gnss", str(tmp_path / "ublox7.log"), "--out-csv", str(tmp_path / "est.csv")])
    err = capsys.readouterr().err
    assert rc == 0, err.strip().splitlines()[-1]
    import csv

    with open(tmp_path / "est.csv") as f:
        rows = list(csv.DictReader(f))
    assert int(rows[-1]["gnss_fused"]) >= 90 and int(rows[-1]["gnss_rejected"]) == 0
