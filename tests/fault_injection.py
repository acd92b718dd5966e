"""Sensor faults injected into a simulated drive by post-processing its frames (test helper).

The simulator writes clean frames; a fault is applied afterwards, as it would appear on the bus:
each CAN frame in the window is decoded with cantools, the input's physical value replaced, and the
frame re-encoded with its own COUNTER and a fresh E2E CRC (so the decoder accepts it, as it would a
sensor that is wrong but alive). GNSS UBX NAV-PVT frames get their velocity fields patched and the
UBX checksum recomputed. The simulator itself stays untouched.
"""
from __future__ import annotations

import dataclasses
import math
import struct
from typing import Callable

from ecu_daemon.gnss.ubx import ubx_checksum
from ecu_daemon.integrity import data_id_for, e2e_p2_apply
from ecu_daemon.signals import load_dbc
from ecu_daemon.sim.run import SimResult

#: NAV-PVT payload offsets (u-blox interface description): velN, velE (I4 mm/s), gSpeed (I4 mm/s),
#: headMot (I4 1e-5 deg)
_VEL_N, _VEL_E, _G_SPEED, _HEAD_MOT = 48, 52, 60, 64
_UBX_HEADER = 6


def fault_can(result: SimResult, inputs: tuple[str, ...], t0: float, t1: float,
              value: Callable[[float, float], float]) -> SimResult:
    """``result`` with ``value(t, v_true) -> v`` applied to the named inputs for t0 <= t < t1."""
    cfg = result.config
    db = load_dbc(cfg.dbc_path())
    targets: dict[int, list[tuple[str, float, float]]] = {}
    for name in inputs:
        m = cfg.inputs[name]
        msg = db.get_message_by_name(m.message) if isinstance(m.message, str) else \
            db.get_message_by_frame_id(m.message)
        (sig,) = m.signal_names()
        targets.setdefault(msg.frame_id, []).append((sig, m.scale, m.offset))
    frames = []
    for t, fid, data in result.can_frames:
        if fid in targets and t0 <= t < t1:
            msg = db.get_message_by_frame_id(fid)
            values = msg.decode(data, decode_choices=False, scaling=True)
            for sig, scale, offset in targets[fid]:
                si = values[sig] * scale + offset
                values[sig] = (value(t, si) - offset) / scale
            out = bytearray(msg.encode(values, strict=False, padding=False))
            e2e_p2_apply(out, data_id_for(msg))
            data = bytes(out)
        frames.append((t, fid, data))
    return dataclasses.replace(result, can_frames=frames)


def fault_gnss(result: SimResult, t0: float, t1: float,
               velocity: Callable[[float, float], tuple[float, float]]) -> SimResult:
    """``result`` with ``velocity(vn, ve) -> (vn, ve)`` applied to NAV-PVT received in [t0, t1)."""
    msgs = []
    for t, payload in result.gnss_messages:
        if t0 <= t < t1 and payload[2:4] == b"\x01\x07":
            frame = bytearray(payload)
            p = _UBX_HEADER
            vn, ve = (x / 1000.0 for x in struct.unpack_from("<ii", frame, p + _VEL_N))
            vn, ve = velocity(vn, ve)
            struct.pack_into("<ii", frame, p + _VEL_N, round(vn * 1000), round(ve * 1000))
            struct.pack_into("<i", frame, p + _G_SPEED, round(math.hypot(vn, ve) * 1000))
            head = math.degrees(math.atan2(ve, vn)) % 360.0
            struct.pack_into("<i", frame, p + _HEAD_MOT, round(head * 1e5))
            frame[-2:] = ubx_checksum(frame[2:-2])
            payload = bytes(frame)
        msgs.append((t, payload))
    return dataclasses.replace(result, gnss_messages=msgs)
