"""Rolling counters and checksums of CAN frames (AUTOSAR E2E profile 2, Toyota).

E2E profile 2 is the scheme of our own DBCs: CHECKSUM in byte 0 = CRC8H2F (AUTOSAR CRC-8, poly
0x2F, init 0xFF, final xor 0xFF) over bytes 1..n-1 followed by one data-id byte; a 4-bit COUNTER
in the low nibble of byte 1. ``cantools.autosar.end_to_end.compute_profile2_crc`` is the
reference implementation, but it costs ~19 us per frame (it builds a crccheck object per call),
more than the whole decode budget. So the 256-entry table is *derived from the same crccheck class
cantools uses* at import, checked against cantools once, and applied with a plain table loop
(~0.8 us per 8-byte frame).
"""
from __future__ import annotations

import crccheck.crc
from cantools.autosar.end_to_end import compute_profile2_crc

#: Attribute (BO_) of our DBCs that carries a message's E2E data id.
E2E_DATA_ID_ATTRIBUTE = "E2EDataId"


def _crc8h2f_table() -> bytes:
    """T[x] = one byte x pushed through the CRC-8/AUTOSAR register from 0 (no init, no final xor).

    Public API only: the final xor is what ``calc`` returns for no data from a zero register.
    """
    cls = crccheck.crc.Crc8Autosar
    xor_out = cls.calc(b"", initvalue=0)
    return bytes(cls.calc(bytes([i]), initvalue=0) ^ xor_out for i in range(256))


_T = _crc8h2f_table()
CRC8H2F_TABLE = _T  # for the compiled output encoder (_frames.c)


def e2e_p2_crc(payload: bytes | bytearray, data_id: int) -> int:
    """CRC8H2F of ``payload[1:] + data_id`` (byte 0 is where the CRC goes and is not covered)."""
    t = _T
    r = 0xFF
    for b in payload[1:]:
        r = t[r ^ b]
    return t[r ^ data_id] ^ 0xFF


def e2e_p2_check(payload: bytes | bytearray, data_id: int) -> bool:
    """True if byte 0 holds the profile-2 CRC of the rest (payloads under 2 bytes never pass)."""
    return len(payload) >= 2 and payload[0] == e2e_p2_crc(payload, data_id)


def e2e_p2_apply(payload: bytearray, data_id: int) -> bytearray:
    """Write the profile-2 CRC into byte 0 (in place) and return the payload."""
    payload[0] = e2e_p2_crc(payload, data_id)
    return payload


def data_id_for(message) -> int:
    """E2E data id of a cantools Message: its ``E2EDataId`` attribute, else the frame id's low byte."""
    dbc = getattr(message, "dbc", None)
    attrs = getattr(dbc, "attributes", None) or {}
    attr = attrs.get(E2E_DATA_ID_ATTRIBUTE)
    if attr is not None and attr.value is not None:
        return int(attr.value) & 0xFF
    return message.frame_id & 0xFF


def toyota_checksum(frame_id: int, payload: bytes | bytearray) -> int:
    """Toyota's checksum (opendbc ``toyota_checksum``): length + address bytes + data bytes but the last."""
    s = len(payload)
    addr = frame_id
    while addr:
        s += addr & 0xFF
        addr >>= 8
    s += sum(payload[:-1])
    return s & 0xFF


def toyota_check(frame_id: int, payload: bytes | bytearray) -> bool:
    """True if the last byte holds :func:`toyota_checksum` (empty payloads never pass)."""
    return len(payload) >= 1 and payload[-1] == toyota_checksum(frame_id, payload)


def next_counter(value: int, bits: int = 4) -> int:
    """The counter value that should follow ``value``."""
    return (value + 1) & ((1 << bits) - 1)


class CounterCheck:
    """Continuity of a rolling counter: each value must be the previous + 1 (modulo 2**bits).

    The first value after construction or :meth:`reset` is accepted. After a failure the check
    re-synchronises on the received value, so one lost frame costs one error, not a burst.
    """

    __slots__ = ("mask", "prev")

    def __init__(self, bits: int = 4):
        self.mask = (1 << bits) - 1
        self.prev: int | None = None

    def check(self, value: int) -> bool:
        prev = self.prev
        self.prev = value
        return prev is None or value == ((prev + 1) & self.mask)

    def reset(self) -> None:
        self.prev = None


def _self_test() -> None:
    for payload, did in ((b"\x00\x01\x02\x03\x04\x05\x06\x07", 0xB0), (b"\xff\x00", 0x00),
                         (b"\x12\x34\x56\x78\x9a\xbc\xde\xf0", 0x55)):
        if e2e_p2_crc(payload, did) != compute_profile2_crc(payload, did):
            raise RuntimeError("CRC8H2F table disagrees with cantools.autosar; crccheck changed?")


_self_test()
