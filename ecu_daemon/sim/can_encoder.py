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
hand the estimator a different drive than the truth describes; except when the config's
plausibility range ``[min, max]`` rejects the clipped value: then the frame carries the range end
(a sensor saturates) and the decoder drops it as invalid (:meth:`FrameEncoder._saturated`).
"""
from __future__ import annotations

from dataclasses import dataclass, field

from ..config import Config, ConfigError
from ..checksums import FrameChecksum
from ..integrity import data_id_for
from ..dbc_loading import load_dbc
from ..signals import unsigned_range_hint


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
        # and at least half of it: opendbc's Chrysler DBC writes [0|1] on every value signal (13-bit
        # wheel speeds that hold 0..71 m/s); a sensor range under half of its encoding is no
        # reason to refuse a drive the bits carry
        tol = 1e-9 * max(1.0, abs(a), abs(b))
        if (mn is not None and mx is not None and mn < mx and mn >= a - tol and mx <= b + tol
                and mx - mn >= 0.5 * (b - a)):
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
    pages: list = field(default_factory=list)  # multiplexed: (multiplexer signal, value) per page sent
    page_k: int = 0  # frames sent so far (which page comes next)
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
            page = self._page(name, msg, m.signal_names() + ([m.sign_signal] if m.sign_signal else []))
            if page is not None and page not in plan.pages:
                if plan.pages and plan.pages[0][0] != page[0]:
                    raise ConfigError(f"[inputs.{name}] {msg.name}: signals under two multiplexers"
                                      f" ({plan.pages[0][0]}, {page[0]}); the simulator cannot encode that")
                plan.pages.append(page)
            plan.inputs.append((name, m, sigs, sign, page))
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
            same = [m for m in self.db.messages if m.name == ref]
            if len(same) > 1:  # as the decoder: two DBCs joined by IMPORT lines name two messages alike
                raise ConfigError(f"[inputs.{name}] message '{ref}' names {len(same)} messages in {self.dbc_path}"
                                  f" ({', '.join(f'0x{m.frame_id:X}' for m in same)}): give the frame id instead,"
                                  f" e.g. message = 0x{same[0].frame_id:X}")
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

    @classmethod
    def _page(cls, name: str, msg, sig_names: list[str]) -> tuple[str, int] | None:
        """The (multiplexer signal, value) whose frames carry the input's signals; None when they are
        in every frame. A car sends the pages of a multiplexed message in turn (VW PQ Bremse_2: the
        lateral acceleration in page 0, a timer in page 1); so does the simulator, one page per frame,
        over the pages the mapping needs (the input's rate is the message's divided by their number)."""
        pages = set()
        for sig_name in sig_names:
            sig = cls._signal(name, msg, sig_name)
            if sig.multiplexer_signal is None:
                pages.add(None)
                continue
            if cls._signal(name, msg, sig.multiplexer_signal).multiplexer_signal is not None:
                raise ConfigError(f"[inputs.{name}] signal '{sig_name}' of {msg.name} is under a nested"
                                  " multiplexer; the simulator cannot encode it")
            pages.add((sig.multiplexer_signal, int(sig.multiplexer_ids[0])))
        if len(pages) > 1:
            raise ConfigError(f"[inputs.{name}] signals {', '.join(sig_names)} of {msg.name} are not in one"
                              " multiplexer page: no frame carries all of them")
        return pages.pop()

    @staticmethod
    def _signal(name: str, msg, sig_name: str):
        try:
            return msg.get_signal_by_name(sig_name)
        except KeyError:
            raise ConfigError(f"[inputs.{name}] signal '{sig_name}' is not in message {msg.name}") from None

    @staticmethod
    def _saturated(m, sigs: list[SignalInfo], sign: SignalInfo | None, phys: float, raw: dict):
        """The raw range end a sensor sends for ``phys`` beyond its signal's range, when the
        config's plausibility range ``[m.min, m.max]`` rejects that end; else None (refuse).

        A wheel-speed channel saturates at its range, as an ABS does: after a spin a car rolls on
        tail first faster than the chassis DBC's -10.016 m/s (random drives 3170, 3313, 3382, 3420:
        a wheel below it, vx down to -12.8 m/s on 3170). The receiver's plausibility check (wheel speeds: [-5, 120] m/s)
        drops the range end as an invalid sample, so the estimator is told "no speed", never a
        wrong one, and the drive can be scored. A range end the receiver would take as a
        measurement (a signal too narrow for the config: a wrong scale) is still refused.
        """
        if len(sigs) != 1:
            return None
        s = sigs[0]
        p = s.clip(phys)
        si = (-p if sign is not None and raw[sign.name] else p) * m.scale + m.offset
        if m.min <= si <= m.max:
            return None
        return s.to_raw(p)

    def encode(self, plan: MessagePlan, values: dict) -> bytes:
        """One frame of ``plan`` carrying ``values`` (input name -> SI value); advances counters."""
        raw = dict(plan.template)
        page = None
        if plan.pages:
            page = plan.pages[plan.page_k % len(plan.pages)]
            plan.page_k += 1
            raw[page[0]] = page[1]
        for name, m, sigs, sign, in_page in plan.inputs:
            if in_page is not None and in_page != page:
                continue  # this frame is another page: it does not carry the input
            phys = (values[name] - m.offset) / m.scale
            if sign is not None:
                raw[sign.name] = 1 if phys < 0 else 0
                phys = abs(phys)
            try:
                raw.update(split_value(sigs, phys))
            except UnencodableValue as e:
                sat = self._saturated(m, sigs, sign, phys, raw)
                if sat is not None:
                    raw[sigs[0].name] = sat
                    continue
                hint = next(filter(None, (unsigned_range_hint(plan.message.get_signal_by_name(i.name),
                                                              plan.message.name, self.dbc_path.name)
                                          for i in sigs)), None) if phys < 0 else None
                raise UnencodableValue(f"[inputs.{name}] {values[name]:.6g} (SI) cannot be encoded in"
                                       f" {plan.message.name} of {self.dbc_path.name}: {e}"
                                       + (f" ({hint})" if hint else "")) from None
        for cname, state in plan.counters.items():
            raw[cname] = state[0]
            state[0] = (state[0] + 1) & state[1]
        data = bytearray(plan.message.encode(raw, scaling=False, padding=False, strict=False))
        if plan.checksum is not None:
            plan.checksum.apply(data)
        return bytes(data)
