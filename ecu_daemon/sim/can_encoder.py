"""SI input values -> CAN frames, for any DBC plus ``[inputs.*]`` mapping of a :class:`Config`.

The exact inverse of :mod:`ecu_daemon.signals`: the decoder computes
``SI = scale * sum(physical values of the mapped signals) + offset``, so here
``physical = (SI - offset) / scale``. For a split signal (``signals = [a, b]``, e.g. Toyota's
STEER_ANGLE + STEER_FRACTION) ``a`` gets the value rounded to its own resolution and ``b`` the
remainder (``a`` is moved by one step if the remainder would not fit ``b``). Signals the mapping
does not use carry their DBC initial value (GenSigStartValue) or 0. Rolling counters count up by
one per frame; checksums, every scheme with the config's data id, use the same code the decoder
checks them with (:class:`ecu_daemon.checksums.FrameChecksum`). Quantisation happens here, by the DBC's resolution, as on a car.
A sign-magnitude mapping (``sign_signal``) gets |value| in its signal(s) and 1 in the sign signal
when negative. A value the DBC cannot hold (a negative yaw rate in an unsigned signal without a
sign bit, a speed beyond the signal's range) raises :class:`UnencodableValue`: clipping it would
hand the estimator a different drive than the truth describes.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from ..config import Config, ConfigError
from ..checksums import FrameChecksum
from ..integrity import data_id_for
from ..dbc_loading import load_dbc


class UnencodableValue(ValueError):
    """A value outside what the DBC signal can carry (message names input, value and range)."""


class SignalInfo:
    """What encoding needs of one DBC signal, precomputed (raw and physical limits)."""

    __slots__ = ("name", "scale", "offset", "is_float", "raw_lo", "raw_hi", "phys_lo", "phys_hi")

    def __init__(self, sig):
        self.name = sig.name
        self.scale = float(sig.scale)
        self.offset = float(sig.offset)
        self.is_float = bool(sig.is_float)
        if sig.is_signed:
            self.raw_lo, self.raw_hi = -(1 << (sig.length - 1)), (1 << (sig.length - 1)) - 1
        else:
            self.raw_lo, self.raw_hi = 0, (1 << sig.length) - 1
        a, b = sorted((self.raw_lo * self.scale + self.offset, self.raw_hi * self.scale + self.offset))
        mn, mx = sig.minimum, sig.maximum
        # the DBC's [min|max] narrows the range only when it is plausible, i.e. inside what the
        # bits can hold (opendbc writes [0|65535] on 10-bit offset signals, [0|0] for "unspecified")
        tol = 1e-9 * max(1.0, abs(a), abs(b))
        if mn is not None and mx is not None and mn < mx and mn >= a - tol and mx <= b + tol:
            a, b = float(mn), float(mx)
        self.phys_lo, self.phys_hi = a, b

    def to_raw(self, phys: float):
        if self.is_float:
            return float(phys)
        raw = int(round((phys - self.offset) / self.scale))
        return self.raw_lo if raw < self.raw_lo else (self.raw_hi if raw > self.raw_hi else raw)

    def to_phys(self, raw) -> float:
        return raw if self.is_float else raw * self.scale + self.offset

    def clip(self, phys: float) -> float:
        return self.phys_lo if phys < self.phys_lo else (self.phys_hi if phys > self.phys_hi else phys)

    def checked(self, phys: float) -> float:
        """``phys`` if the signal can hold it (to within half a step), else :class:`UnencodableValue`."""
        tol = 0.0 if self.is_float else 0.5 * abs(self.scale)
        if not (self.phys_lo - tol <= phys <= self.phys_hi + tol):
            raise UnencodableValue(f"{phys:.6g} does not fit signal {self.name} [{self.phys_lo:g}, {self.phys_hi:g}]")
        return self.clip(phys)


def split_value(sigs: list[SignalInfo], phys: float) -> dict:
    """Raw values of signals whose physical values sum to ``phys`` (the first takes the coarse part)."""
    if len(sigs) == 1:
        s = sigs[0]
        return {s.name: s.to_raw(s.checked(phys))}
    out = {}
    rest = phys
    for k, sig in enumerate(sigs):
        if k == len(sigs) - 1:
            out[sig.name] = sig.to_raw(sig.checked(rest))
            break
        raw = sig.to_raw(rest)
        if not sig.is_float:
            nxt = sigs[k + 1]
            step = 1 if sig.scale > 0 else -1
            for _ in range(2):  # move by one step so the remainder fits the next signal
                rem = rest - sig.to_phys(raw)
                if rem > nxt.phys_hi and sig.raw_lo <= raw + step <= sig.raw_hi:
                    raw += step
                elif rem < nxt.phys_lo and sig.raw_lo <= raw - step <= sig.raw_hi:
                    raw -= step
                else:
                    break
        out[sig.name] = raw
        rest -= sig.to_phys(raw)
    return out


@dataclass
class MessagePlan:
    """One DBC message that carries at least one mapped input."""

    message: object  # cantools Message
    inputs: list = field(default_factory=list)  # (input name, InputMapping, [Signal, ...])
    counters: dict = field(default_factory=dict)  # counter signal name -> [next raw value, mask]
    checksum: FrameChecksum | None = None  # the message's scheme, as the decoder binds it
    template: dict = field(default_factory=dict)  # raw values of every signal

    @property
    def frame_id(self) -> int:
        return self.message.frame_id

    @property
    def is_extended(self) -> bool:
        return self.message.is_extended_frame

    def cycle_s(self, default_hz: float | None) -> float:
        if default_hz:
            return 1.0 / default_hz
        ct = self.message.cycle_time
        return ct / 1000.0 if ct else 0.01


class FrameEncoder:
    """Builds frames for the messages that carry ``cfg.inputs``; stateful (counters)."""

    def __init__(self, cfg: Config):
        self.cfg = cfg
        self.dbc_path = cfg.dbc_path()
        self.db = load_dbc(self.dbc_path)
        plans: dict[tuple, MessagePlan] = {}
        for name, m in cfg.inputs.items():
            msg = self._find_message(name, m.message)
            if msg.is_multiplexed():
                raise ConfigError(f"[inputs.{name}] {msg.name} is multiplexed; the simulator cannot encode it")
            key = (msg.frame_id, msg.is_extended_frame)
            plan = plans.get(key)
            if plan is None:
                plan = plans[key] = MessagePlan(msg)
                for sig in msg.signals:
                    info = SignalInfo(sig)
                    plan.template[sig.name] = (sig.raw_initial if sig.raw_initial is not None
                                               else info.to_raw(info.clip(0.0)))
            sigs = [SignalInfo(self._signal(name, msg, s)) for s in m.signal_names()]
            sign = SignalInfo(self._signal(name, msg, m.sign_signal)) if m.sign_signal else None
            plan.inputs.append((name, m, sigs, sign))
            if m.counter:
                length = self._signal(name, msg, m.counter).length
                plan.counters.setdefault(m.counter, [0, (1 << length) - 1])
            if m.checksum != "none" and plan.checksum is None:
                # the decoder's binding (signals.SignalDecoder._bind_checksum): the config's data id
                # (one, or VW's 16 indexed by the counter), else the DBC's; it refuses disagreeing inputs
                ids = ((data_id_for(msg),) if m.data_id is None
                       else tuple(m.data_id) if isinstance(m.data_id, list) else (m.data_id,))
                plan.checksum = FrameChecksum(m.checksum, msg.frame_id, msg.is_extended_frame, ids)
        self.plans = list(plans.values())

    def _find_message(self, name: str, ref):
        if isinstance(ref, str):
            try:
                return self.db.get_message_by_name(ref)
            except KeyError:
                try:
                    ref = int(ref, 0)
                except ValueError:
                    raise ConfigError(f"[inputs.{name}] message '{ref}' is not in {self.dbc_path}") from None
        found = sorted((m for m in self.db.messages if m.frame_id == ref), key=lambda m: m.is_extended_frame)
        if not found:
            raise ConfigError(f"[inputs.{name}] no message with frame id 0x{ref:X} in {self.dbc_path}")
        return found[0]

    @staticmethod
    def _signal(name: str, msg, sig_name: str):
        try:
            return msg.get_signal_by_name(sig_name)
        except KeyError:
            raise ConfigError(f"[inputs.{name}] signal '{sig_name}' is not in message {msg.name}") from None

    def encode(self, plan: MessagePlan, values: dict) -> bytes:
        """One frame of ``plan`` carrying ``values`` (input name -> SI value); advances counters."""
        raw = dict(plan.template)
        for name, m, sigs, sign in plan.inputs:
            phys = (values[name] - m.offset) / m.scale
            if sign is not None:
                raw[sign.name] = 1 if phys < 0 else 0
                phys = abs(phys)
            try:
                raw.update(split_value(sigs, phys))
            except UnencodableValue as e:
                raise UnencodableValue(f"[inputs.{name}] {values[name]:.6g} (SI) cannot be encoded in"
                                       f" {plan.message.name} of {self.dbc_path.name}: {e}") from None
        for cname, state in plan.counters.items():
            raw[cname] = state[0]
            state[0] = (state[0] + 1) & state[1]
        data = bytearray(plan.message.encode(raw, scaling=False, padding=False, strict=False))
        if plan.checksum is not None:
            plan.checksum.apply(data)
        return bytes(data)
