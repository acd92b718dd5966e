"""The checksums the makes put in their CAN frames, bound per message and checked per frame.

Schemes (``[inputs.NAME] checksum``), as opendbc checks them:

* ``e2e_p2``: AUTOSAR E2E profile 2 (CRC8H2F in byte 0 over bytes 1.. and a data id; our DBCs,
  VW MQB). The data id is one byte, or one per value of the counter in the low nibble of byte 1
  (VW MQB: ``data_id = [16 values]``); from the config, else the DBC's ``E2EDataId`` attribute,
  else the frame id's low byte.
* ``toyota``: byte sum of length, id bytes and data, in the last byte.
* ``honda`` (and Acura): 4-bit sum of the id's and data's nibbles, in the low nibble of the last
  byte; ``8 - sum``, plus 3 for a 29-bit id.
* ``subaru``: byte sum of the id bytes and bytes 1.., in byte 0.
* ``hyundai_canfd`` (Hyundai/Kia/Genesis CAN FD): CRC-16/XMODEM over bytes 2.. and the id's two low
  bytes, xored with a constant per frame length, little-endian in bytes 0-1.

CRCs run on 256-entry tables derived at import from crccheck's classes (the library's own
parameters) and checked against the library once: per frame the libraries take 7x (crccheck,
CRC-16 over 32 bytes) to 15x (cantools' E2E CRC, 8 bytes) longer (``tools/bench_checksums.py``).
"""
from __future__ import annotations

import functools

import crccheck.crc

from .config import CHECKSUM_SCHEMES
from .integrity import e2e_p2_check, e2e_p2_crc, toyota_check, toyota_checksum


def honda_checksum(frame_id: int, payload: bytes | bytearray, extended: bool) -> int:
    """opendbc's ``honda_checksum``: the checksum nibble itself (low nibble of the last byte) excluded."""
    s = 0
    a = frame_id
    while a:
        s += a & 0xF
        a >>= 4
    for b in payload[:-1]:
        s += (b & 0xF) + (b >> 4)
    if payload:
        s += payload[-1] >> 4
    s = 8 - s
    if extended:
        s += 3
    return s & 0xF


def subaru_checksum(frame_id: int, payload: bytes | bytearray) -> int:
    """opendbc's ``subaru_checksum``: id bytes + bytes 1.. (byte 0 holds the checksum)."""
    s = 0
    a = frame_id
    while a:
        s += a & 0xFF
        a >>= 8
    return (s + sum(payload[1:])) & 0xFF


def _crc16_xmodem_table() -> tuple[int, ...]:
    """T[x] = one byte x pushed through the CRC-16/XMODEM register from 0 (it has no final xor)."""
    return tuple(crccheck.crc.Crc16Xmodem.calc(bytes([i]), initvalue=0) for i in range(256))


_T16 = _crc16_xmodem_table()
#: final xor of Hyundai's CAN FD CRC per frame length (other lengths: none)
_HYUNDAI_XOR = {8: 0x5F29, 16: 0x041D, 24: 0x819D, 32: 0x9F5B}


def crc16_xmodem(data: bytes | bytearray, crc: int = 0) -> int:
    """CRC-16/XMODEM of ``data``, continuing from the register value ``crc``."""
    t = _T16
    for b in data:
        crc = ((crc << 8) & 0xFFFF) ^ t[(crc >> 8) ^ b]
    return crc


def hyundai_canfd_checksum(frame_id: int, payload: bytes | bytearray) -> int:
    """CRC-16/XMODEM over bytes 2.. then the id's low and second byte, xored per length."""
    crc = crc16_xmodem(payload[2:])
    crc = crc16_xmodem(bytes((frame_id & 0xFF, (frame_id >> 8) & 0xFF)), crc)
    return crc ^ _HYUNDAI_XOR.get(len(payload), 0)


def _self_test() -> None:
    for data in (b"123456789", bytes(range(32)), b"\xff\x00"):
        if crc16_xmodem(data) != crccheck.crc.Crc16Xmodem.calc(data):
            raise RuntimeError("CRC-16/XMODEM table disagrees with crccheck; crccheck changed?")


_self_test()


class FrameChecksum:
    """One message's checksum scheme, bound to its frame id (and E2E data ids).

    ``data_ids``: for ``e2e_p2``, one data id, or 16 indexed by the counter in byte 1's low nibble.
    """

    __slots__ = ("scheme", "frame_id", "extended", "data_ids", "min_length", "check")

    MIN_LENGTH = {"e2e_p2": 2, "toyota": 1, "honda": 1, "subaru": 2, "hyundai_canfd": 3}
    assert set(MIN_LENGTH) == set(CHECKSUM_SCHEMES) - {"none"}

    def __init__(self, scheme: str, frame_id: int, extended: bool = False, data_ids: tuple[int, ...] = (0,)):
        if scheme not in self.MIN_LENGTH:
            raise ValueError(f"unknown checksum scheme {scheme!r}")
        if len(data_ids) not in (1, 16):
            raise ValueError("E2E data ids: one, or one per counter value (16)")
        self.scheme = scheme
        self.frame_id = frame_id
        self.extended = extended
        self.data_ids = tuple(data_ids)
        self.min_length = self.MIN_LENGTH[scheme]
        # the fast path: a check bound to this message, one call per frame (the common two without a
        # Python-level method in between)
        if scheme == "e2e_p2" and len(self.data_ids) == 1:
            self.check = functools.partial(e2e_p2_check, data_id=self.data_ids[0])
        elif scheme == "toyota":
            self.check = functools.partial(toyota_check, frame_id)
        else:
            self.check = getattr(self, "_check_" + scheme)

    def data_id(self, payload) -> int:
        ids = self.data_ids
        return ids[0] if len(ids) == 1 else ids[payload[1] & 0x0F]

    def expected(self, payload: bytes | bytearray) -> int:
        """The checksum this payload should carry."""
        s = self.scheme
        if s == "e2e_p2":
            return e2e_p2_crc(payload, self.data_id(payload))
        if s == "toyota":
            return toyota_checksum(self.frame_id, payload)
        if s == "honda":
            return honda_checksum(self.frame_id, payload, self.extended)
        if s == "subaru":
            return subaru_checksum(self.frame_id, payload)
        return hyundai_canfd_checksum(self.frame_id, payload)

    def stored(self, payload: bytes | bytearray) -> int:
        """The checksum the payload carries."""
        s = self.scheme
        if s in ("e2e_p2", "subaru"):
            return payload[0]
        if s == "toyota":
            return payload[-1]
        if s == "honda":
            return payload[-1] & 0x0F
        return payload[0] | payload[1] << 8

    def describe(self, payload: bytes | bytearray) -> str:
        """``<scheme> checksum 0x.., expected 0x..`` for a log line."""
        what = "E2E CRC" if self.scheme == "e2e_p2" else f"{self.scheme} checksum"
        if len(payload) < self.min_length:
            return f"{what}: {len(payload)} bytes is too short to carry one"
        w = 4 if self.scheme == "hyundai_canfd" else 2
        return f"{what} 0x{self.stored(payload):0{w}X}, expected 0x{self.expected(payload):0{w}X}"

    def _check_e2e_p2(self, payload) -> bool:
        if len(payload) < 2:
            return False
        ids = self.data_ids
        return payload[0] == e2e_p2_crc(payload, ids[0] if len(ids) == 1 else ids[payload[1] & 0x0F])

    def _check_honda(self, payload) -> bool:
        return len(payload) >= 1 and payload[-1] & 0x0F == honda_checksum(self.frame_id, payload, self.extended)

    def _check_subaru(self, payload) -> bool:
        return len(payload) >= 2 and payload[0] == subaru_checksum(self.frame_id, payload)

    def _check_hyundai_canfd(self, payload) -> bool:
        return len(payload) >= 3 and payload[0] | payload[1] << 8 == hyundai_canfd_checksum(self.frame_id, payload)
