"""SignalDecoder: DBC + [inputs.*] mapping -> InputSamples, with every bad-input path, on real data."""
from __future__ import annotations

import csv
import logging
import math
import struct
from pathlib import Path

import numpy as np
import pytest

from ecu_daemon import config
from ecu_daemon.canlog import read_can_log
from ecu_daemon.config import ConfigError
from ecu_daemon.integrity import (CounterCheck, e2e_p2_apply, e2e_p2_check, e2e_p2_crc, toyota_check,
                                  toyota_checksum)
from ecu_daemon.samples import INPUT_INDEX, INPUT_NAMES, REQUIRED_INPUTS
from ecu_daemon.io.logging_setup import RateLimitedLog
from ecu_daemon.signals import DEFAULT_STALE_S, SignalDecoder

ROOT = Path(__file__).resolve().parents[1]
DATA = Path(__file__).parent / "data" / "comma2k19"
SHARED = Path(__file__).resolve().parents[2] / "shared" / "data" / "comma2k19-rav4"
EXAMPLE = ROOT / "examples" / "toyota_rav4.toml"
DEG = math.pi / 180.0


class FakeClock:
    """Controls the log rate limiter's clock (not the decoder's time base, which is the frame's t)."""

    def __init__(self):
        self.now = 0.0

    def __call__(self):
        return self.now


@pytest.fixture
def clock():
    return FakeClock()


@pytest.fixture
def dec(clock):
    return SignalDecoder(config.load(None), clock=clock)


def frame(db, name, counter, **values):
    """A correct frame of our input DBC: cantools encode + counter + E2E profile-2 CRC."""
    msg = db.get_message_by_name(name)
    vals = {s.name: 0 for s in msg.signals}
    vals.update(values, COUNTER=counter)
    payload = bytearray(msg.encode(vals))
    e2e_p2_apply(payload, msg.frame_id & 0xFF)
    return msg.frame_id, bytes(payload)


def by_name(samples):
    return {INPUT_NAMES[s.index]: s.value for s in samples}


# ------------------------------------------------------------------------------ integrity helpers
def test_e2e_and_toyota_checksums_match_their_references():
    from cantools.autosar.end_to_end import compute_profile2_crc

    rng = np.random.default_rng(1)
    for _ in range(300):
        payload = bytes(rng.integers(0, 256, size=int(rng.integers(2, 9)), dtype=np.uint8))
        did = int(rng.integers(0, 256))
        assert e2e_p2_crc(payload, did) == compute_profile2_crc(payload, did)
    # Toyota: worked example from the real RAV4 log, SPEED 0x0B4 (len 8 + 0xB4 + data bytes but last)
    data = bytes.fromhex("000000001D0B7A5E")
    assert toyota_checksum(0xB4, data) == 0x5E and toyota_check(0xB4, data)
    assert not toyota_check(0xB4, data[:-1] + b"\x5F") and not toyota_check(0xB4, b"")
    assert not e2e_p2_check(b"\x00", 0)


def test_counter_check_accepts_first_and_wraps_and_resyncs():
    c = CounterCheck(4)
    assert c.check(14) and c.check(15) and c.check(0)  # first accepted, wrap 15 -> 0
    assert not c.check(2)  # one frame lost
    assert c.check(3)  # re-synchronised on the received value
    assert not c.check(3)  # repeated (stuck) counter
    c.reset()
    assert c.check(9)


# ------------------------------------------------------------------------------ our DBC, default mapping
def test_default_mapping_decodes_our_dbc_in_si(dec):
    db = dec.db
    fid, data = frame(db, "WHEEL_SPEEDS", 0, WHEEL_SPEED_FL=10.0, WHEEL_SPEED_FR=10.5,
                      WHEEL_SPEED_RL=-2.0, WHEEL_SPEED_RR=120.0)
    s = dec.decode(1.25, fid, data)
    assert [x.t for x in s] == [1.25] * 4
    v = by_name(s)
    for name, want in (("wheel_speed_fl", 10.0), ("wheel_speed_fr", 10.5), ("wheel_speed_rl", -2.0),
                       ("wheel_speed_rr", 120.0)):
        assert v[name] == pytest.approx(want, abs=0.016 + 1e-9)  # half an LSB
    fid, data = frame(db, "STEERING", 0, STEERING_WHEEL_ANGLE=-1.2345, STEERING_WHEEL_RATE=0.5)
    assert by_name(dec.decode(1.26, fid, data)) == pytest.approx({"steering_wheel_angle": -1.2345}, abs=2.5e-4)
    fid, data = frame(db, "IMU", 0, YAW_RATE=0.1234, ACCEL_X=-2.5, ACCEL_Y=3.25)
    got = by_name(dec.decode(1.27, fid, data))
    assert got == pytest.approx({"yaw_rate": 0.1234, "accel_x": -2.5, "accel_y": 3.25}, abs=5e-4)
    assert [s.index for s in dec.decode(1.28, *frame(db, "IMU", 1))] == [INPUT_INDEX[n] for n in
                                                                          ("yaw_rate", "accel_x", "accel_y")]
    assert dec.frame_ids == [(0x0B0, False), (0x0B2, False), (0x0B4, False)]
    assert dec.can_filters()[0] == {"can_id": 0x0B0, "can_mask": 0x7FF, "extended": False}
    assert all(h.samples >= 1 and sum(h.errors.values()) == 0 for h in dec.health.values())


def test_unknown_and_extended_ids_are_ignored_without_touching_health(dec):
    fid, data = frame(dec.db, "IMU", 0, YAW_RATE=0.1)
    assert dec.decode(1.0, 0x123, data) == []
    assert dec.decode(1.0, fid, data, is_extended=True) == []  # same number, other frame format
    assert all(h.frames == 0 for h in dec.health.values())


def test_wrong_dlc_drops_all_samples_of_the_frame_and_logs_once(dec, clock, caplog):
    fid, data = frame(dec.db, "IMU", 0, YAW_RATE=0.1)
    with caplog.at_level(logging.WARNING, logger="ecu_daemon.signals"):
        assert dec.decode(1.0, fid, data[:6]) == []
        assert dec.decode(1.01, fid, data + b"\x00") == []
        assert dec.decode(1.02, fid, b"") == []
    for name in ("yaw_rate", "accel_x", "accel_y"):
        h = dec.health[name]
        assert h.errors["dlc"] == 3 and h.samples == 0 and h.frames == 3
        assert "expected 8" in h.last_error
    yaw_lines = [r for r in caplog.records if "input yaw_rate: dlc error" in r.getMessage()]
    assert len(yaw_lines) == 1 and "\n" not in yaw_lines[0].getMessage() and yaw_lines[0].exc_info is None
    # rate limit: after the interval one line with the count of what was suppressed
    clock.now = 10.5
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="ecu_daemon.signals"):
        dec.decode(1.03, fid, data[:2])
    lines = [r.getMessage() for r in caplog.records if "input yaw_rate" in r.getMessage()]
    assert len(lines) == 1 and "+2 more" in lines[0]
    # and the decoder keeps working
    assert len(dec.decode(1.04, fid, frame(dec.db, "IMU", 1, YAW_RATE=0.2)[1])) == 3


def test_bad_crc_drops_the_frame_and_counts_checksum_errors(dec):
    fid, data = frame(dec.db, "STEERING", 0, STEERING_WHEEL_ANGLE=0.3)
    bad = bytearray(data)
    bad[3] ^= 0x10  # one flipped data bit, CRC unchanged
    assert dec.decode(2.0, fid, bytes(bad)) == []
    h = dec.health["steering_wheel_angle"]
    assert h.errors["checksum"] == 1 and "E2E CRC" in h.last_error
    # a frame with the right CRC (and the next counter value) is accepted again
    assert by_name(dec.decode(2.01, *frame(dec.db, "STEERING", 1, STEERING_WHEEL_ANGLE=0.3)))
    # ... a CRC computed with another message's data id is a checksum error too
    msg = dec.db.get_message_by_name("STEERING")
    other = bytearray(msg.encode({"CHECKSUM": 0, "COUNTER": 2, "STEERING_WHEEL_ANGLE": 0.3, "STEERING_WHEEL_RATE": 0}))
    e2e_p2_apply(other, 0xB0)
    assert dec.decode(2.02, fid, bytes(other)) == [] and h.errors["checksum"] == 2


def test_one_bad_crc_frame_between_good_ones_costs_exactly_that_frame(dec):
    db = dec.db
    names = ("wheel_speed_fl", "wheel_speed_fr", "wheel_speed_rl", "wheel_speed_rr")
    assert len(dec.decode(1.00, *frame(db, "WHEEL_SPEEDS", 4, WHEEL_SPEED_FL=10.0))) == 4
    assert len(dec.decode(1.01, *frame(db, "WHEEL_SPEEDS", 5, WHEEL_SPEED_FL=10.0))) == 4
    fid, data = frame(db, "WHEEL_SPEEDS", 6, WHEEL_SPEED_FL=10.0)
    bad = bytearray(data)
    bad[2] ^= 0x04  # one flipped data bit, CRC unchanged
    assert dec.decode(1.02, fid, bytes(bad)) == []
    # the next good frame (counter 7, one after the corrupt frame) and the ones after it are used
    for i, cnt in enumerate((7, 8, 9)):
        assert len(dec.decode(1.03 + 0.01 * i, *frame(db, "WHEEL_SPEEDS", cnt, WHEEL_SPEED_FL=10.0))) == 4
    for name in names:
        h = dec.health[name]
        assert (h.frames, h.samples) == (6, 5), name
        assert h.errors["checksum"] == 1 and h.errors["counter"] == 0, name
    # the counter check still works after the re-synchronisation
    assert dec.decode(1.10, *frame(db, "WHEEL_SPEEDS", 12)) == []
    assert dec.health["wheel_speed_fl"].errors["counter"] == 1


def test_counter_jump_drops_one_frame_then_resyncs(dec):
    db = dec.db
    assert len(dec.decode(1.00, *frame(db, "WHEEL_SPEEDS", 14))) == 4
    assert len(dec.decode(1.01, *frame(db, "WHEEL_SPEEDS", 15))) == 4
    assert len(dec.decode(1.02, *frame(db, "WHEEL_SPEEDS", 0))) == 4  # wraps
    assert dec.decode(1.03, *frame(db, "WHEEL_SPEEDS", 5)) == []  # 4 frames lost
    assert len(dec.decode(1.04, *frame(db, "WHEEL_SPEEDS", 6))) == 4
    assert dec.decode(1.05, *frame(db, "WHEEL_SPEEDS", 6)) == []  # repeated
    h = dec.health["wheel_speed_rr"]
    assert h.errors["counter"] == 2 and "COUNTER 6 after 6, expected 7" in h.last_error
    assert h.samples == 4 and h.frames == 6


def test_counter_and_checksum_are_only_checked_when_the_mapping_asks(clock):
    cfg = config.load(None)
    cfg.inputs["yaw_rate"].counter = ""
    cfg.inputs["yaw_rate"].checksum = "none"
    dec = SignalDecoder(cfg, clock=clock)
    fid, data = frame(dec.db, "IMU", 3, YAW_RATE=0.5)
    assert by_name(dec.decode(1.0, fid, data)).keys() == {"yaw_rate", "accel_x", "accel_y"}
    bad = bytearray(data)
    bad[0] ^= 0xFF
    # yaw_rate does not check the CRC, accel_x/accel_y do
    assert by_name(dec.decode(1.01, fid, bytes(bad))) == pytest.approx({"yaw_rate": 0.5})
    assert dec.health["accel_x"].errors["checksum"] == 1 and dec.health["yaw_rate"].errors["checksum"] == 0
    # a counter jump only hits the inputs that check the counter (the check re-synchronises on the
    # first good frame after a checksum failure, so the jump comes after one)
    assert len(dec.decode(1.015, *frame(dec.db, "IMU", 5, YAW_RATE=0.5))) == 3
    assert by_name(dec.decode(1.02, *frame(dec.db, "IMU", 9, YAW_RATE=0.5))) == pytest.approx({"yaw_rate": 0.5})
    assert dec.health["accel_y"].errors["counter"] == 1 and dec.health["yaw_rate"].errors["counter"] == 0


def test_out_of_range_values_are_dropped_per_input(dec):
    fid, data = frame(dec.db, "WHEEL_SPEEDS", 0, WHEEL_SPEED_FL=10.0, WHEEL_SPEED_FR=200.0,
                      WHEEL_SPEED_RL=-8.0, WHEEL_SPEED_RR=10.0)
    got = by_name(dec.decode(1.0, fid, data))  # default plausibility range: -5 .. 120 m/s
    assert set(got) == {"wheel_speed_fl", "wheel_speed_rr"}
    assert dec.health["wheel_speed_fr"].errors["range"] == 1
    assert "outside [-5, 120]" in dec.health["wheel_speed_rl"].last_error


NAN_DBC = """VERSION ""
NS_ :
BS_:
BU_: SENSOR ECU_DAEMON
BO_ 1056 FLOAT_IMU: 8 SENSOR
 SG_ YAW_RATE_F : 0|32@1- (1,0) [-10|10] "rad/s" ECU_DAEMON
 SG_ ACCEL_X_F : 32|32@1- (1,0) [-50|50] "m/s^2" ECU_DAEMON
SIG_VALTYPE_ 1056 YAW_RATE_F : 1;
SIG_VALTYPE_ 1056 ACCEL_X_F : 1;
"""


def test_nan_and_inf_from_a_float_signal_are_range_errors(tmp_path, clock):
    (tmp_path / "float.dbc").write_text(NAN_DBC)
    inputs = {n: {"message": "FLOAT_IMU", "signal": "YAW_RATE_F"} for n in INPUT_NAMES}
    inputs["accel_x"] = {"message": 1056, "signal": "ACCEL_X_F"}  # by frame id
    cfg = config.from_dict({"can": {"dbc": "float.dbc"}, "inputs": inputs}, base_dir=tmp_path)
    dec = SignalDecoder(cfg, clock=clock)
    ok = by_name(dec.decode(1.0, 1056, struct.pack("<ff", 0.25, -1.5)))
    assert ok["yaw_rate"] == 0.25 and ok["accel_x"] == -1.5
    assert dec.decode(1.01, 1056, struct.pack("<ff", math.nan, math.inf)) == []
    assert dec.health["yaw_rate"].errors["range"] == 1 and "not finite" in dec.health["yaw_rate"].last_error
    assert dec.health["accel_x"].errors["range"] == 1


def test_summed_signals_scale_and_offset(tmp_path, clock):
    cfg = config.from_dict({"can": {"dbc": str(ROOT / "ecu_daemon" / "dbc" / "ecu_daemon_inputs.dbc")},
                            "inputs": {"yaw_rate": {"message": "0x0B4", "signals": ["YAW_RATE", "ACCEL_X"],
                                                    "scale": 2.0, "offset": -1.0}}})
    dec = SignalDecoder(cfg, clock=clock)
    got = by_name(dec.decode(0.5, *frame(dec.db, "IMU", 0, YAW_RATE=0.25, ACCEL_X=1.5)))
    assert got["yaw_rate"] == pytest.approx(2.0 * (0.25 + 1.5) - 1.0, abs=1e-6)


@pytest.mark.parametrize("inputs, expect", [
    ({"yaw_rate": {"message": "IMUU", "signal": "YAW_RATE"}}, "message 'IMUU' is not in .* \\(did you mean 'IMU'\\?\\)"),
    ({"yaw_rate": {"message": "IMU", "signal": "YAWRATE"}}, "signal 'YAWRATE' is not in message IMU \\(did you mean 'YAW_RATE'\\?\\)"),
    ({"yaw_rate": {"message": 0x7AA, "signal": "YAW_RATE"}}, "no message with frame id 0x7AA"),
    ({"yaw_rate": {"message": "IMU", "signal": "YAW_RATE", "counter": "CNT"}}, "counter 'CNT' is not in message IMU"),
    ({"steering_wheel_angle": {"message": "STEERING", "signals": ["STEERING_WHEEL_ANGLE", "STEER_FRAC"]}},
     "\\[inputs.steering_wheel_angle\\] signal 'STEER_FRAC'"),
    # the right signal in the wrong message: the message that carries it is named
    ({"accel_x": {"message": "STEERING", "signal": "ACCEL_X"}},
     "signal 'ACCEL_X' is not in message STEERING \\(it is in IMU: message = \"IMU\"\\); it has:"),
    ({"wheel_speed_fl": {"message": "WHEEL_SPEEDS", "signal": "WHEEL_SPEED_FL", "sign_signal": "YAW_RATE"}},
     "sign_signal 'YAW_RATE' is not in message WHEEL_SPEEDS \\(it is in IMU; the sign_signal must be in the"
     " message of the input's signal\\)"),
])
def test_config_typos_are_one_clear_config_error(inputs, expect):
    cfg = config.from_dict({"inputs": inputs})
    with pytest.raises(ConfigError, match=expect) as e:
        SignalDecoder(cfg)
    assert "\n" not in str(e.value)


def test_missing_or_garbage_dbc_is_a_config_error(tmp_path):
    with pytest.raises(ConfigError, match="cannot read .*nope.dbc"):
        SignalDecoder(config.from_dict({"can": {"dbc": str(tmp_path / "nope.dbc")}}))
    (tmp_path / "junk.dbc").write_text("BO_ this is not a DBC\n\x01\x02")
    with pytest.raises(ConfigError, match="junk.dbc is not a valid DBC"):
        SignalDecoder(config.from_dict({"can": {"dbc": str(tmp_path / "junk.dbc")}}))


def test_stale_inputs_are_flagged_counted_and_recover(dec, clock):
    db = dec.db
    assert dec.check_stale(0.0) == []  # first call: reference time
    for k in range(150):  # 100 Hz IMU for 1.5 s
        dec.decode(k * 0.01 + 0.005, *frame(db, "IMU", k & 15, YAW_RATE=0.1))
    stale = dec.check_stale(1.5)
    assert dec.health["yaw_rate"].rate_hz == pytest.approx(100.0)
    assert dec.timeout_s("yaw_rate") == pytest.approx(0.1)  # 10 cycle times
    assert "yaw_rate" not in stale
    assert set(stale) == {n for n in dec.health if n not in ("yaw_rate", "accel_x", "accel_y")}  # never seen
    assert set(dec.health) == set(REQUIRED_INPUTS)  # the mapped ones (no magnetometer by default)
    assert dec.timeout_s("wheel_speed_fl") == DEFAULT_STALE_S
    assert "yaw_rate" in dec.check_stale(1.7)
    assert "yaw_rate" in dec.check_stale(1.8)
    assert dec.health["yaw_rate"].errors["stale"] == 1  # one transition, not one per check
    dec.decode(1.9, *frame(db, "IMU", 150 & 15, YAW_RATE=0.1))
    assert dec.health["yaw_rate"].rate_hz == pytest.approx(100.0)  # kept while nothing arrives
    assert "yaw_rate" not in dec.check_stale(1.91)
    diag = dec.input_diagnostics(1.95)
    assert diag["yaw_rate"].age_ms == pytest.approx(50.0) and diag["yaw_rate"].stale_count == 1
    assert math.isinf(diag["wheel_speed_fl"].age_ms) and diag["wheel_speed_fl"].stale_count == 1


def test_rate_limited_log_counts_what_it_suppresses(caplog, clock):
    logger = logging.getLogger("test.ratelimit")
    rl = RateLimitedLog(logger, 10.0, clock)
    with caplog.at_level(logging.INFO, logger="test.ratelimit"):
        assert rl.report("k", logging.WARNING, "boom")
        assert not rl.report("k", logging.WARNING, "boom")
        assert rl.report("other", logging.WARNING, "bang")  # keys are independent
        clock.now = 9.9
        assert not rl.report("k", logging.WARNING, "boom")
        clock.now = 10.0
        assert rl.report("k", logging.WARNING, "boom")
    assert [r.getMessage() for r in caplog.records] == ["boom", "bang", "boom (+2 more in the last 10 s)"]


# ------------------------------------------------------------------------------ the real Toyota RAV4
def read_ref(path: Path):
    with path.open() as f:
        return list(csv.DictReader(f))


def decode_log(cfg, path):
    dec = SignalDecoder(cfg)
    out = {n: [] for n in INPUT_NAMES}
    for t, fid, ext, err, data in read_can_log(path):
        if not err:
            for s in dec.decode(t, fid, data, ext):
                out[INPUT_NAMES[s.index]].append((s.t, s.value))
    return dec, {k: np.array(v) for k, v in out.items()}


def check_against_comma(series, ws_ref, steer_ref):
    assert len(series["wheel_speed_fl"]) == len(ws_ref) > 0
    for corner in ("fl", "fr", "rl", "rr"):
        got = series[f"wheel_speed_{corner}"]
        want = np.array([float(r[f"ws_{corner}_mps"]) for r in ws_ref])
        assert np.array_equal(got[:, 0], np.array([float(r["t_boot_s"]) for r in ws_ref]))
        assert np.max(np.abs(got[:, 1] - want)) < 1e-9  # float noise only: same LSB, same order
    got = series["steering_wheel_angle"]
    want = np.radians([float(r["steering_angle_deg"]) for r in steer_ref])
    assert len(got) == len(want)
    assert np.array_equal(got[:, 0], np.array([float(r["t_boot_s"]) for r in steer_ref]))
    assert np.max(np.abs(got[:, 1] - want)) < 1e-9


def smooth(x, n=83):
    return np.convolve(x, np.ones(n) / n, mode="valid")


def test_rav4_extract_matches_comma_reference_and_iso_signs(caplog):
    cfg = config.load(EXAMPLE)  # its DBC: examples/_toyota_2017.dbc, the one vendored copy
    with caplog.at_level(logging.INFO, logger="ecu_daemon.dbc_loading"):
        dec, s = decode_log(cfg, DATA / "rav4_bus0_candump_5s.log")
    assert len([r for r in caplog.records if "strict=False" in r.getMessage()]) == 1
    assert all(sum(h.errors.values()) == 0 for h in dec.health.values())
    check_against_comma(s, read_ref(DATA / "comma_can_ref_wheel_speed_5s.csv"),
                        read_ref(DATA / "comma_can_ref_steering_angle_5s.csv"))
    # sign conventions (ISO 8855) on this window: accelerating, weaving left and right
    t_imu, yaw = s["yaw_rate"][:, 0], s["yaw_rate"][:, 1]
    steer = np.interp(t_imu, *s["steering_wheel_angle"].T)
    speed = np.interp(t_imu, s["wheel_speed_fl"][:, 0],
                      np.mean([s[f"wheel_speed_{c}"][:, 1] for c in ("fl", "fr", "rl", "rr")], axis=0))
    assert np.corrcoef(steer, yaw)[0, 1] > 0.6  # steering left -> turning left
    yaw_unbiased = yaw - yaw.mean()
    assert np.corrcoef(smooth(s["accel_y"][:, 1]), smooth(yaw_unbiased * speed))[0, 1] > 0.8  # ay = r * v
    dvdt = (speed[-1] - speed[0]) / (t_imu[-1] - t_imu[0])
    assert dvdt > 0.5 and s["accel_x"][:, 1].mean() > 0.3  # speeding up -> ax positive forward
    assert s["steering_wheel_angle"][:, 1].min() < math.radians(-4) and s["steering_wheel_angle"][:, 1].max() > math.radians(1)


def test_example_config_points_at_its_own_dbc_copy():
    cfg = config.load(EXAMPLE)
    assert cfg.dbc_path() == (ROOT / "examples" / "_toyota_2017.dbc")
    assert (ROOT / "examples" / "LICENSE-opendbc").exists()
    assert SignalDecoder(cfg).frame_ids == [(0x024, False), (0x025, False), (0x0AA, False)]


def test_toyota_checksum_mapping_on_real_speed_frames(tmp_path):
    cfg = config.load(EXAMPLE)
    cfg.inputs["wheel_speed_fl"] = config.InputMapping(message="SPEED", signal="SPEED", scale=1 / 3.6,
                                                       checksum="toyota")
    dec = SignalDecoder(cfg)
    frames = [(t, fid, data) for t, fid, ext, err, data in read_can_log(DATA / "rav4_bus0_candump_5s.log")
              if fid == 0x0B4]
    assert len(frames) > 150
    assert all(len(dec.decode(t, fid, data)) == 1 for t, fid, data in frames)
    t, fid, data = frames[0]
    bad = data[:-1] + bytes([(data[-1] + 1) & 0xFF])
    assert dec.decode(t, fid, bad) == []
    assert dec.health["wheel_speed_fl"].errors["checksum"] == 1


@pytest.mark.skipif(not SHARED.exists(), reason=f"{SHARED} not present")
def test_rav4_full_minute_matches_comma_reference():
    cfg = config.load(EXAMPLE)
    dec, s = decode_log(cfg, SHARED / "rav4_bus0_candump.log")
    assert all(sum(h.errors.values()) == 0 for h in dec.health.values())
    check_against_comma(s, read_ref(SHARED / "comma_can_ref_wheel_speed.csv"),
                        read_ref(SHARED / "comma_can_ref_steering_angle.csv"))
    t_imu, yaw = s["yaw_rate"][:, 0], s["yaw_rate"][:, 1]
    steer = np.interp(t_imu, *s["steering_wheel_angle"].T)
    assert np.corrcoef(steer, yaw)[0, 1] > 0.6
    assert yaw.mean() == pytest.approx(math.radians(-0.41), abs=math.radians(0.05))  # README: the known bias


def _shipped_dbcs():
    root = Path(__file__).resolve().parents[1]
    return sorted([*root.glob("ecu_daemon/dbc/*.dbc"), *root.glob("examples/*.dbc"),
                   *root.glob("tests/data/opendbc/*.dbc")])


@pytest.mark.parametrize("path", _shipped_dbcs(), ids=lambda p: p.name)
def test_precompiled_layout_decodes_exactly_what_cantools_decodes(path):
    """The per-frame fast path (signals._unpack) against ``Message.decode_simple`` on every message
    of every DBC we ship: random payloads, all zeros, all ones (Intel and Motorola, signed)."""
    import random

    import cantools

    from ecu_daemon.signals import _layout, _unpack

    rng = random.Random(path.name)
    db = cantools.database.load_file(str(path), strict=False)
    checked = big = 0
    for msg in db.messages:
        layout = _layout(msg)
        if layout is None:
            try:
                msg.decode_simple(bytes(msg.length), False)
                assert msg.is_multiplexed() or any(s.is_float for s in msg.signals), msg.name
            except cantools.database.DecodeError:
                pass  # cantools cannot unpack it either (overlapping signals): it keeps cantools' error
            continue
        big += any(not little for _, little, *_ in layout)
        for data in [bytes(msg.length), b"\xff" * msg.length,
                     *(rng.randbytes(msg.length) for _ in range(200))]:
            want = msg.decode_simple(data, False)
            got = _unpack(layout, data)
            assert got == want and [type(v) for v in got.values()] == [type(v) for v in want.values()], msg.name
        checked += 1
    assert checked > 0
    if path.name.startswith("_toyota"):
        assert big > 0  # Motorola signals were among them
