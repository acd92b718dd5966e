"""Fuzz targets and hypothesis strategies shared by ``tests/test_fuzz.py`` (a short run) and
``tools/bench_fuzz.py`` (>= 1e5 inputs each, with counts and rates).

Each ``check_*`` takes one generated input, asserts what must hold for it and returns the outcome
as a short string (what the bench counts): the property is that bad input ends as the module's
own one-line error, never as another exception.
"""
from __future__ import annotations

import gzip
import math
import os
import tempfile
from pathlib import Path

from hypothesis import strategies as st

from ecu_daemon import config as config_mod
from ecu_daemon.canlog import CanLogError, read_can_log
from ecu_daemon.config import RANGES, RECEIVER_KEYS, RECEIVER_ROLES, ConfigError
from ecu_daemon.estimator import Estimator
from ecu_daemon.integrity import e2e_p2_apply
from ecu_daemon.samples import INPUT_INDEX, INPUT_NAMES, GnssSample, InputSample
from ecu_daemon.signals import _EXTENDED_KEY, SignalDecoder

ROOT = Path(__file__).resolve().parents[1]
FD_LENGTHS = (0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64)
_NASTY = (0, -1, 1, 1e-320, 5e-324, 1e20, 1e308, -1e308, math.inf, -math.inf, math.nan)


# ----------------------------------------------------------------------------------- config
def _number(lo: float, hi: float, integer: bool):
    """Mostly allowed values (their extremes included), else anything: what passes must work."""
    inside = st.integers(int(lo), int(hi)) if integer else st.floats(lo, hi)
    near = (st.integers(int(lo) - 2, int(hi) + 2) if integer
            else st.floats(lo - abs(lo) - 1.0, hi * 2.0 + 1.0, allow_nan=False))
    return st.one_of(*[inside] * 40, near, st.sampled_from(_NASTY), st.floats(), st.integers(-2**70, 2**70))


def _section(section: str):
    keys = {k: _number(lo, hi, isinstance(getattr(getattr(config_mod.Config(), section), k), int)
                       and not isinstance(getattr(getattr(config_mod.Config(), section), k), bool))
            for (sec, k), (lo, hi, _) in RANGES.items() if sec == section}
    if section == "gnss":
        keys["lever_arm_m"] = st.lists(st.one_of(st.floats(-30, 30), st.sampled_from(_NASTY)), min_size=0, max_size=3)
    return st.fixed_dictionaries({}, optional=keys)


def _inputs():
    scale, offset, timeout = (RANGES[("inputs", k)] for k in ("scale", "offset", "timeout_s"))
    one = st.fixed_dictionaries({}, optional={
        "scale": _number(scale[0], scale[1], False), "offset": _number(offset[0], offset[1], False),
        "timeout_s": _number(timeout[0], timeout[1], False),
        "min": st.one_of(st.floats(-1e3, 0), st.sampled_from(_NASTY)),
        "max": st.one_of(st.floats(0, 1e3), st.sampled_from(_NASTY))})
    return st.dictionaries(st.sampled_from(INPUT_NAMES), one, max_size=3)


def _receiver():
    """One ``[[gnss.receiver]]`` table: the per-receiver keys of [gnss], a role, a port."""
    keys = {k: _number(*RANGES[("gnss", k)][:2], k == "baudrate")
            for k in RECEIVER_KEYS if ("gnss", k) in RANGES}
    keys["lever_arm_m"] = st.lists(st.one_of(st.floats(-30, 30), st.sampled_from(_NASTY)), min_size=2, max_size=2)
    keys["role"] = st.sampled_from(RECEIVER_ROLES + ("other",))
    return st.fixed_dictionaries({"port": st.sampled_from(("/dev/ttyACM0", "/dev/ttyACM1", "/dev/ttyUSB0"))},
                                 optional=keys)


@st.composite
def _docs(draw):
    doc = draw(st.fixed_dictionaries({}, optional={
        "gnss": _section("gnss"), "vehicle": _section("vehicle"), "estimator": _section("estimator"),
        "daemon": _section("daemon"), "can": _section("can"), "inputs": _inputs()}))
    if draw(st.integers(0, 3)) == 0:  # several receivers: the per-receiver keys go in their tables
        gnss = {k: v for k, v in doc.get("gnss", {}).items() if k not in RECEIVER_KEYS or draw(st.booleans())}
        doc["gnss"] = {**gnss, "receiver": draw(st.lists(_receiver(), min_size=1, max_size=3))}
    return doc


config_docs = _docs()


def _merge_inputs(doc: dict) -> dict:
    """A partial [inputs.NAME] table replaces the default mapping: give it the default message/signal."""
    doc = dict(doc)
    if "inputs" in doc:
        cfg = config_mod.Config()
        cfg.inputs.update(config_mod.magnetometer_inputs())  # the optional inputs' defaults too
        cfg.inputs.update(config_mod.roll_rate_input())
        defaults = config_mod.to_dict(cfg)["inputs"]
        doc["inputs"] = {n: {**defaults[n], **t} for n, t in doc["inputs"].items()}
    return doc


def check_config(doc: dict) -> str:
    """A document either fails validation with one line naming the key, or builds an estimator that
    steps through inputs without an exception."""
    try:
        cfg = config_mod.from_dict(_merge_inputs(doc))
    except ConfigError as e:
        text = str(e)
        assert "\n" not in text and text.startswith("["), text
        return "refused"
    est = Estimator(cfg)
    for j in range(40):
        t = 100.0 + 0.01 * j
        for i in range(len(INPUT_NAMES)):
            est.push_input(InputSample(t, i, 20.0 if i < 4 else 0.1))
        if j % 10 == 0:
            est.push_gnss(GnssSample(t=t, vel_n_mps=20.0, vel_e_mps=0.0, speed_acc_mps=0.1, fix_type=3,
                                     fix_ok=True, num_sv=10))
        for e in est.advance_to(t - 1e-9):
            assert math.isfinite(e.t)
    return "accepted"


# ----------------------------------------------------------------------------------- decoder
_DECODERS: dict = {}


def decoders() -> dict:
    """Decoders of our own DBC (E2E, counters) and of the real Toyota example (opendbc DBC)."""
    if not _DECODERS:
        _DECODERS["own"] = SignalDecoder(config_mod.load(None))
        _DECODERS["toyota"] = SignalDecoder(config_mod.load(ROOT / "examples" / "toyota_rav4.toml"))
        value_counter = config_mod.load(None)  # a counter mapped onto a signed, scaled value signal
        for name in ("yaw_rate", "accel_x", "accel_y"):  # (one message: one checksum scheme)
            value_counter.inputs[name].counter, value_counter.inputs[name].checksum = "", "none"
        value_counter.inputs["yaw_rate"].counter = "ACCEL_X"
        _DECODERS["value_counter"] = SignalDecoder(value_counter)
        for d in _DECODERS.values():
            d._log.interval_s = math.inf  # one line per kind, not one per example
    return _DECODERS


@st.composite
def can_frames(draw):
    dec = decoders()[draw(st.sampled_from(("own", "toyota", "value_counter")))]
    ids = sorted(dec.frame_ids)
    fid, ext = draw(st.one_of(st.sampled_from(ids), st.tuples(st.integers(0, 0x1FFFFFFF), st.booleans())))
    plan = dec._plans.get(fid | _EXTENDED_KEY if ext else fid)
    # the DLC the DBC gives (what gets past the length check) or any classic / FD length
    n = draw(st.sampled_from(FD_LENGTHS) if plan is None else st.one_of(st.just(plan.length), st.sampled_from(FD_LENGTHS)))
    data = bytearray(draw(st.binary(min_size=n, max_size=n)))
    if n >= 2 and draw(st.booleans()):  # make the E2E CRC right so the decode goes past it
        e2e_p2_apply(data, fid & 0xFF)
    t = draw(st.one_of(st.floats(0, 1e10), st.sampled_from(_NASTY)))
    return dec, t, fid, ext, bytes(data)


def check_frame(frame) -> str:
    """decode never raises; every sample it returns is finite and inside its input's range."""
    dec, t, fid, ext, data = frame
    plan = dec._plans.get(fid | _EXTENDED_KEY if ext else fid)
    # decode() turns any exception into a counted, logged drop (the daemon's safety net); below it,
    # nothing but the library's own decode errors may be caught, so the fuzz calls the layer beneath
    out = dec.decode(t, fid, data, ext) if plan is None else dec._decode(plan, t, data)
    for s in out:
        assert type(s) is InputSample and math.isfinite(s.value) and 0 <= s.index < len(INPUT_INDEX)
    return f"{len(out)} samples" if out else "nothing"


# ----------------------------------------------------------------------------------- compressed logs
_SAMPLE_LOG = "".join(f"({1000 + 0.01 * i:.6f}) can0 0B4#{(i * 0x1F1F1F1F) & 0xFFFFFFFFFFFFFFFF:016X}\n"
                      for i in range(200)).encode()
SAMPLE_GZ = gzip.compress(_SAMPLE_LOG, mtime=0)


@st.composite
def gz_inputs(draw):
    """A valid .log.gz cut short, with bytes flipped, or random bytes."""
    kind = draw(st.sampled_from(("cut", "flip", "random")))
    if kind == "random":
        return draw(st.binary(max_size=300))
    b = bytearray(SAMPLE_GZ)
    if kind == "cut":
        return bytes(b[:draw(st.integers(0, len(b)))])
    for _ in range(draw(st.integers(1, 4))):
        i = draw(st.integers(0, len(b) - 1))
        b[i] ^= draw(st.integers(1, 255))
    return bytes(b)


_SCRATCH: list = []  # one temporary directory for all examples (removed at exit)


def check_gz(data: bytes) -> str:
    """Reading a damaged .log.gz ends in CanLogError or frames, nothing else."""
    if not _SCRATCH:
        shm = Path("/dev/shm")  # a memory file system where there is one: opening files on /tmp costs ~1 ms here
        _SCRATCH.append(tempfile.TemporaryDirectory(dir=shm if shm.is_dir() and os.access(shm, os.W_OK) else None))
    p = Path(_SCRATCH[0].name) / "x.log.gz"
    p.write_bytes(data)
    try:
        n = sum(1 for _ in read_can_log(p))
    except CanLogError as e:
        assert "\n" not in str(e) and "x.log.gz" in str(e)
        return "refused"
    return "read" if n else "empty"


# ----------------------------------------------------------------------------------- volume
# The same input families drawn with a seeded ``random.Random``: hypothesis' engine manages ~100
# inputs/s here, too slow for 1e5 per target; these feed the same check_* functions in the bench.
def _rand_number(rng, lo: float, hi: float, integer: bool):
    r = rng.random()
    if r < 0.85:
        return rng.randint(int(lo), int(hi)) if integer else rng.uniform(lo, hi)
    if r < 0.9:
        return rng.randint(int(lo) - 2, int(hi) + 2) if integer else rng.uniform(lo - abs(lo) - 1.0, hi * 2.0 + 1.0)
    if r < 0.97:
        return rng.choice(_NASTY)
    return rng.randint(-2**70, 2**70) if rng.random() < 0.5 else rng.uniform(-1e308, 1e308)


def random_config_doc(rng) -> dict:
    doc: dict = {}
    for (section, key), (lo, hi, _) in RANGES.items():
        if section == "inputs" or rng.random() < 0.5:
            continue
        default = getattr(getattr(config_mod.Config(), section), key)
        doc.setdefault(section, {})[key] = _rand_number(rng, lo, hi, isinstance(default, int))
    if rng.random() < 0.3:
        doc.setdefault("gnss", {})["lever_arm_m"] = [rng.choice((rng.uniform(-30, 30), rng.choice(_NASTY)))
                                                     for _ in range(rng.choice((2, 2, 2, 0, 1, 3)))]
    if rng.random() < 0.25:  # several receivers: the per-receiver keys go in their tables
        gnss = {k: v for k, v in doc.get("gnss", {}).items() if k not in RECEIVER_KEYS or rng.random() < 0.1}
        receivers = []
        for _ in range(rng.randint(1, 3)):
            rx: dict = {"port": rng.choice(("/dev/ttyACM0", "/dev/ttyACM1", "/dev/ttyUSB0")),
                        "role": rng.choice(RECEIVER_ROLES + RECEIVER_ROLES + ("other",))}
            for key in RECEIVER_KEYS:
                if ("gnss", key) in RANGES and rng.random() < 0.5:
                    lo, hi, _ = RANGES[("gnss", key)]
                    rx[key] = _rand_number(rng, lo, hi, key == "baudrate")
            if rng.random() < 0.5:
                rx["lever_arm_m"] = [rng.choice((rng.uniform(-30, 30), rng.choice(_NASTY))) for _ in range(2)]
            receivers.append(rx)
        doc["gnss"] = {**gnss, "receiver": receivers}
    if rng.random() < 0.5:
        inputs = {}
        for name in rng.sample(INPUT_NAMES, rng.randint(1, 3)):
            t = {}
            for key in ("scale", "offset", "timeout_s"):
                if rng.random() < 0.5:
                    lo, hi, _ = RANGES[("inputs", key)]
                    t[key] = _rand_number(rng, lo, hi, False)
            if rng.random() < 0.3:
                t["min"] = rng.choice((rng.uniform(-1e3, 0), rng.choice(_NASTY)))
            if rng.random() < 0.3:
                t["max"] = rng.choice((rng.uniform(0, 1e3), rng.choice(_NASTY)))
            inputs[name] = t
        doc["inputs"] = inputs
    return doc


def random_frame(rng):
    dec = decoders()[rng.choice(("own", "toyota", "value_counter"))]
    if rng.random() < 0.8:
        fid, ext = rng.choice(dec.frame_ids)
    else:
        fid, ext = rng.randrange(0x20000000), rng.random() < 0.5
    plan = dec._plans.get(fid | _EXTENDED_KEY if ext else fid)
    n = plan.length if plan is not None and rng.random() < 0.5 else rng.choice(FD_LENGTHS)
    data = bytearray(rng.randbytes(n))
    if n >= 2 and rng.random() < 0.5:
        e2e_p2_apply(data, fid & 0xFF)
    t = rng.uniform(0, 1e10) if rng.random() < 0.95 else rng.choice(_NASTY)
    return dec, t, fid, ext, bytes(data)


def random_gz(rng) -> bytes:
    kind = rng.choice(("cut", "flip", "random"))
    if kind == "random":
        return rng.randbytes(rng.randint(0, 300))
    b = bytearray(SAMPLE_GZ)
    if kind == "cut":
        return bytes(b[:rng.randint(0, len(b))])
    for _ in range(rng.randint(1, 4)):
        b[rng.randrange(len(b))] ^= rng.randint(1, 255)
    return bytes(b)
