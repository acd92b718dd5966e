"""OutputEncoder: Estimate + Diagnostics -> E2E-protected frames of the output DBC, on a real python-can bus."""
from __future__ import annotations

import math
from pathlib import Path

import can
import cantools
import pytest

from ecu_daemon import config
from ecu_daemon.config import ConfigError
from ecu_daemon.diagnostics import BUS_OFF, Diagnostics
from ecu_daemon.estimator.estimate import (ESTIMATE_FIELDS, STATUS_GNSS_FRESH, STATUS_HEADING_ALIGNED, STATUS_INPUT_STALE,
                                           Estimate)
from ecu_daemon.outputs import OutputEncoder, OutputFrameError, decode_output_frame

ROOT = Path(__file__).resolve().parents[1]
OUT_DBC = ROOT / "ecu_daemon" / "dbc" / "ecu_daemon_outputs.dbc"

BASE = dict(t=3.0, sideslip_rad=-0.0123, sideslip_std_rad=0.0021, heading_rad=4.5, heading_std_rad=0.015,
            vx_mps=23.4, vy_mps=-0.29, vx_std_mps=0.04, vy_std_mps=0.12, yaw_rate_radps=-0.2345,
            yaw_rate_bias_radps=-0.0072, yaw_rate_bias_std_radps=0.0004, accel_x_bias_mps2=0.12,
            accel_x_bias_std_mps2=0.03, accel_y_bias_mps2=-0.08, accel_y_bias_std_mps2=0.04,
            gnss_delay_s=0.2021, wheel_scale=0.9912, steering_offset_rad=0.0123,
            cornering_stiffness_front_n_per_rad=98765.0, cornering_stiffness_rear_n_per_rad=123456.0,
            sideslip_valid=True, heading_valid=True, velocity_valid=True, biases_valid=True,
            status=STATUS_GNSS_FRESH | STATUS_HEADING_ALIGNED, gnss_fused=70001, gnss_rejected=3, gnss_late=1)

#: DBC signal -> Estimate field, for the round-trip check
FIELDS = {"SIDESLIP": "sideslip_rad", "SIDESLIP_STD": "sideslip_std_rad", "YAW_RATE": "yaw_rate_radps",
          "VX": "vx_mps", "VY": "vy_mps", "VX_STD": "vx_std_mps", "VY_STD": "vy_std_mps",
          "HEADING": "heading_rad", "HEADING_STD": "heading_std_rad", "YAW_RATE_BIAS": "yaw_rate_bias_radps",
          "ACCEL_X_BIAS": "accel_x_bias_mps2", "ACCEL_Y_BIAS": "accel_y_bias_mps2",
          "YAW_RATE_BIAS_STD": "yaw_rate_bias_std_radps", "ACCEL_X_BIAS_STD": "accel_x_bias_std_mps2",
          "ACCEL_Y_BIAS_STD": "accel_y_bias_std_mps2", "GNSS_DELAY": "gnss_delay_s", "WHEEL_SCALE": "wheel_scale",
          "STEERING_OFFSET": "steering_offset_rad",
          "CORNERING_STIFFNESS_FRONT": "cornering_stiffness_front_n_per_rad",
          "CORNERING_STIFFNESS_REAR": "cornering_stiffness_rear_n_per_rad"}


def est(**kw) -> Estimate:
    return Estimate(**{**BASE, **kw})


@pytest.fixture
def enc():
    return OutputEncoder(config.Config())


def collect(enc, steps, e=None, diag=None):
    """Decode every frame of ``steps`` steps: {message name: [values, ...]} (checks CRC and counter)."""
    db = enc.db
    seen, last_counter = {}, {}
    for k in steps:
        for msg in enc.frames(k, e or est(), diag):
            name = db.get_message_by_frame_id(msg.arbitration_id).name
            vals = decode_output_frame(db, msg, last_counter.get(name))
            last_counter[name] = vals["COUNTER"]
            seen.setdefault(name, []).append(vals)
    return seen


def test_schedule_follows_the_dbc_cycle_times_without_bursts(enc):
    db = cantools.database.load_file(OUT_DBC)
    per_step = []
    counts = {}
    for k in range(120):
        frames = enc.frames(k, est(), Diagnostics())
        per_step.append(len(frames))
        for m in frames:
            counts[m.arbitration_id] = counts.get(m.arbitration_id, 0) + 1
            assert m.timestamp == 3.0 and not m.is_extended_id and m.dlc == 8
    for m in db.messages:
        assert counts[m.frame_id] == 120 // (m.cycle_time // 6), m.name
    # 3 fast frames + EST_DIAG every other step + seven 60 ms frames over 10 steps: at most two slower
    # frames in one step, and the greedy stagger spreads them (no step carries more)
    assert max(per_step) <= 5
    assert sum(n == 5 for n in per_step) == 120 // 10 * 2
    for name, fid, period, phase in enc.schedule:
        assert period == db.get_message_by_name(name).cycle_time // 6 and 0 <= phase < period


def test_round_trip_values_validity_status_and_counters(enc):
    seen = collect(enc, range(40))
    flat = {}
    for frames in seen.values():
        for k, v in frames[0].items():
            flat.setdefault(k, v)
    db = cantools.database.load_file(OUT_DBC)
    for sig, field in FIELDS.items():
        lsb = db.get_message_by_name(next(n for n, f in seen.items() if sig in f[0])).get_signal_by_name(sig).scale
        assert flat[sig] == pytest.approx(BASE[field], abs=lsb / 2 + 1e-12), sig
    for v in ("SIDESLIP_VALID", "YAW_RATE_VALID", "VELOCITY_VALID", "HEADING_VALID", "BIASES_VALID",
              "CALIBRATION_VALID", "CORNERING_VALID"):
        assert flat[v] == 1, v
    assert flat["STATUS_GNSS_FRESH"] == 1 and flat["STATUS_HEADING_ALIGNED"] == 1 and flat["STATUS_RESET"] == 0
    assert flat["GNSS_FUSED"] == 70001 % 65536 and flat["GNSS_REJECTED"] == 3 and flat["GNSS_LATE"] == 1
    # counters run 0..15 and wrap, per message
    assert [f["COUNTER"] for f in seen["EST_SIDESLIP"]] == [k & 15 for k in range(40)]
    assert [f["COUNTER"] for f in seen["EST_BIASES"]] == [0, 1, 2, 3]


def test_saturation_clears_only_its_own_frame_validity(enc, caplog):
    seen = collect(enc, range(10), est(sideslip_rad=0.5, vy_std_mps=7.0, yaw_rate_bias_radps=-1.0))
    s = seen["EST_SIDESLIP"][0]
    assert s["SIDESLIP"] == pytest.approx(0.32767) and s["SIDESLIP_VALID"] == 0 and s["YAW_RATE_VALID"] == 1
    v = seen["EST_VELOCITY"][0]
    assert v["VY_STD"] == pytest.approx(1.275) and v["VELOCITY_VALID"] == 0 and v["VX"] == pytest.approx(23.4)
    assert seen["EST_BIASES"][0]["YAW_RATE_BIAS"] == pytest.approx(-0.32768)
    assert seen["EST_BIASES"][0]["BIASES_VALID"] == 0 and seen["EST_BIAS_STD"][0]["BIASES_VALID"] == 1
    assert seen["EST_HEADING"][0]["HEADING_VALID"] == 1
    assert enc.saturated == {"SIDESLIP": 10, "VY_STD": 10, "YAW_RATE_BIAS": 1}
    lines = [r.getMessage() for r in caplog.records if "SIDESLIP" in r.getMessage()]
    assert len(lines) == 1 and "SIDESLIP_VALID cleared" in lines[0]  # rate-limited: one line, not 10


def test_nan_and_inf_are_sent_as_zero_with_validity_cleared(enc):
    seen = collect(enc, range(10), est(vx_mps=math.nan, heading_std_rad=math.inf, wheel_scale=math.nan,
                                       gnss_fused=0))
    v = seen["EST_VELOCITY"][0]
    assert v["VX"] == 0 and v["VELOCITY_VALID"] == 0 and v["VY"] == pytest.approx(-0.29)
    h = seen["EST_HEADING"][0]
    assert h["HEADING_STD"] == 0 and h["HEADING_VALID"] == 0
    c = seen["EST_CALIBRATION"][0]
    assert c["WHEEL_SCALE"] == pytest.approx(1.0 - 32768e-5)  # 0 is out of range: the limit nearest to it
    assert c["CALIBRATION_VALID"] == 0
    assert enc.non_finite["VX"] == 10


def _invalid_estimate(**kw) -> Estimate:
    """What the estimator emits before its filter initialises: NaN states, every flag false."""
    nan = math.nan
    fields = ("sideslip_rad", "sideslip_std_rad", "heading_rad", "heading_std_rad", "vx_mps", "vy_mps",
              "vx_std_mps", "vy_std_mps", "yaw_rate_radps", "yaw_rate_bias_radps", "yaw_rate_bias_std_radps",
              "accel_x_bias_mps2", "accel_x_bias_std_mps2", "accel_y_bias_mps2", "accel_y_bias_std_mps2",
              "wheel_scale")
    return est(**{**dict.fromkeys(fields, nan), "sideslip_valid": False, "heading_valid": False,
                  "velocity_valid": False, "biases_valid": False, "status": STATUS_INPUT_STALE, **kw})


def test_non_finite_or_saturated_values_already_flagged_invalid_are_not_logged(enc, caplog):
    e = _invalid_estimate()
    seen = collect(enc, range(200), e)
    s, v, c = seen["EST_SIDESLIP"][0], seen["EST_VELOCITY"][0], seen["EST_CALIBRATION"][0]
    # encoded as before: 0 (or the in-range value nearest 0) with the validity bit cleared
    assert (s["SIDESLIP"], s["SIDESLIP_VALID"], s["YAW_RATE"], s["YAW_RATE_VALID"]) == (0, 0, 0, 0)
    assert (v["VX"], v["VELOCITY_VALID"]) == (0, 0) and seen["EST_HEADING"][0]["HEADING_VALID"] == 0
    assert c["WHEEL_SCALE"] == pytest.approx(1.0 - 32768e-5) and c["CALIBRATION_VALID"] == 0
    # ... but it is the normal "unknown", not a problem: no line, no count
    assert [r.getMessage() for r in caplog.records if r.name == "ecu_daemon.outputs"] == []
    assert enc.non_finite == {} and enc.saturated == {}
    # the start-up sideslip std of pi (no speed yet) saturates SIDESLIP_STD while SIDESLIP_VALID is false
    collect(enc, range(10), est(sideslip_std_rad=math.pi, sideslip_valid=False))
    assert enc.saturated == {} and not caplog.records
    # the same values in a field that claims to be valid are still reported
    collect(enc, range(10), est(vx_mps=math.nan, sideslip_std_rad=math.pi))
    lines = [r.getMessage() for r in caplog.records if r.name == "ecu_daemon.outputs"]
    assert len(lines) == 2 and enc.non_finite == {"VX": 10} and enc.saturated == {"SIDESLIP_STD": 10}
    assert any("VX = nan not finite" in x and "VELOCITY_VALID cleared" in x for x in lines)
    # a frame without an estimator flag (YAW_RATE_VALID) counts as claimed valid while the filter runs
    collect(enc, range(10), est(yaw_rate_radps=math.inf))
    assert enc.non_finite["YAW_RATE"] == 10


def test_estimator_flags_and_heading_wrap(enc):
    seen = collect(enc, range(2), est(sideslip_valid=False, heading_rad=2 * math.pi + 0.1,
                                      status=STATUS_INPUT_STALE))
    assert seen["EST_SIDESLIP"][0]["SIDESLIP_VALID"] == 0
    h = seen["EST_HEADING"][0]
    assert h["HEADING"] == pytest.approx(0.1, abs=1e-4) and h["HEADING_VALID"] == 1
    assert h["STATUS_INPUT_STALE"] == 1 and h["STATUS_GNSS_FRESH"] == 0
    h = collect(enc, range(1), est(heading_rad=-0.1))["EST_HEADING"][0]
    assert h["HEADING"] == pytest.approx(2 * math.pi - 0.1, abs=1e-4)


def test_diagnostics_pages_cover_everything(enc):
    d = Diagnostics(gnss_fix_type=3, gnss_num_sv=17, gnss_speed_acc_mps=math.nan, gnss_receive_age_ms=45.0,
                    gnss_latency_ms=201.3, gnss_checksum_errors=300, gnss_parse_errors=2,
                    gnss_serial_connected=True, can_bus_state=BUS_OFF, can_error_frames=12, can_tx_failures=70000,
                    tick_late_p50_us=120.0, tick_late_p99_us=99999.0, tick_late_max_us=2.5e6, tick_overruns=4,
                    cpu_load_pct=12.3, gnss_heading_state=3, gnss_heading_carr_soln=1,
                    gnss_heading_acc_rad=0.0052, gnss_heading_baseline_m=1.3125, gnss_heading_fused=70001,
                    gnss_heading_rejected=12)
    d.inputs["yaw_rate"].age_ms = 7.4
    d.inputs["yaw_rate"].rate_hz = 99.87
    d.inputs["yaw_rate"].counter_errors = 257
    d.inputs["accel_y"].checksum_errors = 5
    d.sources["yaw_rate"].isolated = True
    d.sources["yaw_rate"].events = 3
    d.sources["gnss"].events = 258
    period = next(p for n, _, p, _ in enc.schedule if n == "EST_DIAG")
    pages = {}
    for f in collect(enc, range(period * 25 * 2), diag=d)["EST_DIAG"]:
        pages.setdefault(f["DIAG_PAGE"], f)
    assert len(pages) == 25
    assert pages[5]["YAW_RATE_AGE"] == 7 and pages[5]["YAW_RATE_RATE"] == pytest.approx(99.87)
    assert pages[0]["WS_FL_AGE"] == 65535  # never received
    assert pages[21]["YAW_RATE_COUNTER_ERRORS"] == 1 and pages[23]["ACCEL_Y_CHECKSUM_ERRORS"] == 5  # modulo 256
    g = pages[32]
    assert (g["GNSS_FIX_TYPE"], g["GNSS_NUM_SV"], g["GNSS_SERIAL_CONNECTED"]) == (3, 17, 1)
    assert g["GNSS_SPEED_ACC"] == pytest.approx(65.535) and g["GNSS_CHECKSUM_ERRORS"] == 300 % 256  # unknown
    assert pages[33]["GNSS_RX_AGE"] == 45 and pages[33]["GNSS_LATENCY"] == pytest.approx(201.3)
    assert (pages[34]["ISO_YAW_RATE_ACTIVE"], pages[34]["ISO_WHEELS_ACTIVE"]) == (1, 0)
    assert pages[35]["ISO_YAW_RATE_EVENTS"] == 3 and pages[35]["ISO_GNSS_EVENTS"] == 258 % 256
    h = pages[36]  # dual-antenna heading: a float fix whose baseline does not match the mounted one
    assert (h["GNSS_HEADING_STATE"], h["GNSS_HEADING_CARR_SOLN"]) == (3, 1)
    assert h["GNSS_HEADING_ACC"] == pytest.approx(0.0052) and h["GNSS_HEADING_BASELINE"] == pytest.approx(1.3125, abs=1e-3)
    assert (pages[37]["GNSS_HEADING_FUSED"], pages[37]["GNSS_HEADING_REJECTED"]) == (70001 % 65536, 12)
    assert pages[48]["CAN_BUS_STATE"] == 3 and pages[48]["CAN_TX_FAILURES"] == 70000 % 65536
    assert pages[49]["TICK_LATE_P99"] == 65535 and pages[49]["CPU_LOAD"] == pytest.approx(12.5)
    assert pages[50]["TICK_LATE_MAX"] == 2_500_000 and pages[50]["TICK_OVERRUNS"] == 4
    # cantools shows the choice names a person reads on the bench
    db = cantools.database.load_file(OUT_DBC)
    msg = next(m for m in enc.frames(0, est(), d) if m.arbitration_id == 0x320)
    assert db.decode_message(0x320, msg.data)["WS_FL_AGE"] == "NEVER"


def test_no_diagnostics_no_diag_frame(enc):
    ids = {m.arbitration_id for k in range(20) for m in enc.frames(k, est(), None)}
    assert 0x320 not in ids and 0x300 in ids


def test_decode_output_frame_rejects_bad_frames(enc):
    db = enc.db
    good = enc.frames(0, est(), None)[0]
    assert decode_output_frame(db, good)["SIDESLIP"] == pytest.approx(-0.0123)
    bad = bytearray(good.data)
    bad[4] ^= 1
    with pytest.raises(OutputFrameError, match="CRC"):
        decode_output_frame(db, can.Message(arbitration_id=0x300, is_extended_id=False, data=bad))
    with pytest.raises(OutputFrameError, match="COUNTER 0 after 3"):
        decode_output_frame(db, good, prev_counter=3)
    with pytest.raises(OutputFrameError, match="not an output message"):
        decode_output_frame(db, can.Message(arbitration_id=0x123, is_extended_id=False, data=good.data))
    with pytest.raises(OutputFrameError, match="expected 8"):
        decode_output_frame(db, can.Message(arbitration_id=0x300, is_extended_id=False, data=good.data[:7]))


def test_frames_survive_a_real_python_can_bus(enc):
    with can.Bus(interface="virtual", channel="test-outputs", preserve_timestamps=True) as tx, \
            can.Bus(interface="virtual", channel="test-outputs", preserve_timestamps=True) as rx:
        sent = [m for k in range(12) for m in enc.frames(k, est(t=k * 0.006), Diagnostics())]
        for m in sent:
            tx.send(m)
        got = [rx.recv(timeout=2.0) for _ in sent]
    assert all(g is not None for g in got)
    last = {}
    for s, g in zip(sent, got):
        assert (g.arbitration_id, bytes(g.data), g.timestamp) == (s.arbitration_id, bytes(s.data), s.timestamp)
        vals = decode_output_frame(enc.db, g, last.get(g.arbitration_id))
        last[g.arbitration_id] = vals["COUNTER"]


def test_cycle_time_not_a_multiple_of_the_step_is_a_config_error():
    cfg = config.from_dict({"estimator": {"dt_s": 0.005}})
    with pytest.raises(ConfigError, match="cycle time 6 ms is not a multiple of the estimator step 5 ms"):
        OutputEncoder(cfg)


def test_output_dbc_signal_without_a_source_is_a_config_error(tmp_path):
    text = OUT_DBC.read_text(encoding="ascii").replace(
        ' SG_ YAW_RATE : 48|16@1- (0.0001,0) [-3.2768|3.2767] "rad/s" Vector__XXX\n',
        ' SG_ YAW_RATE : 48|16@1- (0.0001,0) [-3.2768|3.2767] "rad/s" Vector__XXX\n'
        ' SG_ SPARE_THING : 14|2@1+ (1,0) [0|3] "" Vector__XXX\n', 1)
    (tmp_path / "out.dbc").write_text(text, encoding="ascii")
    with pytest.raises(ConfigError, match="SPARE_THING has no source"):
        OutputEncoder(config.from_dict({"can": {"output_dbc": str(tmp_path / "out.dbc")}}))
    with pytest.raises(ConfigError, match="cannot read"):
        OutputEncoder(config.from_dict({"can": {"output_dbc": str(tmp_path / "missing.dbc")}}))


def test_diagnostics_summary_is_one_line_naming_problems():
    d = Diagnostics(can_bus_state=BUS_OFF, gnss_serial_connected=False)
    d.inputs["yaw_rate"].age_ms = 12.0
    d.inputs["yaw_rate"].checksum_errors = 2
    line = d.summary()
    assert "\n" not in line and "bus-off" in line and "port closed" in line and "input errors 2" in line
    assert "1/8 fresh" in line and "wheel_speed_fl" in line and "yaw_rate," not in line


def _random_values(rng, signals) -> dict:
    """Random raw values over each signal's whole bit range, as the scaled values the encoder feeds."""
    values = {}
    for sig in signals:
        n = sig.length
        lo, hi = (-(1 << (n - 1)), (1 << (n - 1)) - 1) if sig.is_signed else (0, (1 << n) - 1)
        raw = rng.choice((lo, hi, 0, rng.randint(lo, hi)))
        v = raw * sig.scale + sig.offset
        values[sig.name] = v + rng.uniform(-0.49, 0.49) * sig.scale if isinstance(v, float) else v
    return values


def _packers():
    """The packers to check: the Python reference, and the compiled one when it is built (CI's
    ``pip install`` builds it: its absence there fails the CI's own import check, not this)."""
    from ecu_daemon import outputs

    out = [pytest.param(outputs._pack_reference, id="reference")]
    if outputs._pack_compiled is not None:
        out.append(pytest.param(outputs._pack_compiled, id="compiled"))
    return out


@pytest.mark.parametrize("_pack", _packers())
def test_precompiled_layout_packs_exactly_what_cantools_encodes(enc, _pack):
    """The per-frame fast path (outputs._pack) against ``Message.encode`` on every output message:
    random raw values over each signal's whole bit range, as the scaled values the encoder feeds."""
    import random

    from ecu_daemon.outputs import _layout

    rng = random.Random(5)
    checked = 0
    for msg in enc.db.messages:
        layout = _layout(msg)
        if msg.is_multiplexed():
            continue  # EST_DIAG: per page, below
        assert layout is not None, msg.name  # our DBC is all Intel integers
        for _ in range(300):
            values = _random_values(rng, msg.signals)
            assert _pack(layout, values, msg.length) == msg.encode(values, True, False, False), msg.name
            checked += 1
    assert checked >= 300 * 5


@pytest.mark.parametrize("_pack", _packers())
def test_each_page_of_est_diag_packs_exactly_what_cantools_encodes(enc, _pack):
    """The multiplexed EST_DIAG: a page's layout (selector + the page's signals) gives the bytes
    ``Message.encode`` gives for that page, on random values of every page."""
    import random

    from ecu_daemon.outputs import _page_layout

    rng = random.Random(6)
    msg = enc.db.get_message_by_name("EST_DIAG")
    pages = sorted(next(n for n in msg.signal_tree if isinstance(n, dict))["DIAG_PAGE"])
    assert len(pages) >= 2
    for page in pages:
        layout = _page_layout(msg, page)
        sigs = [s for s in msg.signals if s.multiplexer_ids is None or page in s.multiplexer_ids]
        for _ in range(200):
            values = _random_values(rng, sigs)
            values["DIAG_PAGE"] = page
            assert _pack(layout, values, msg.length) == msg.encode(values, True, False, False), page


def test_the_compiled_packer_is_built():
    """pip install builds it (setup.py); a silent fallback would hide a broken build, and with it
    the compiled cases of the packing tests above (they are parametrized over what is built)."""
    from ecu_daemon import outputs

    assert outputs._pack_compiled is not None


def test_compiled_packer_hands_what_it_cannot_hold_to_the_reference():
    """Over 52 bits a double no longer holds every raw value (such a message keeps cantools'
    encode: no layout), over 8 bytes a uint64 no longer holds the payload: the compiled packer
    declines (NotImplemented) and the reference packs."""
    from ecu_daemon import outputs

    assert outputs._pack_compiled is not None, "pip install builds ecu_daemon/_frames.c (setup.py)"
    db = cantools.database.load_string(
        'VERSION ""\nBO_ 256 M: 8 ECU\n SG_ A : 0|60@1+ (1,0) [0|0] "" ECU\n', database_format="dbc")
    assert outputs._layout(db.messages[0]) is None
    wide = (("A", 0, 1, 0, (1 << 60) - 1, 0, (1 << 60) - 1),)
    assert outputs._pack_compiled(wide, {"A": 5}, 8) is NotImplemented
    long = (("A", 0, 1, 0, 0xFF, 0, 0xFF),)
    assert outputs._pack_compiled(long, {"A": 7}, 12) is NotImplemented
    assert outputs._pack(long, {"A": 7}, 12) == bytearray([7] + [0] * 11)
    narrow = (("A", 0.0, 0.5, 4, 0xF, -8, 7),)
    assert outputs._pack_compiled(narrow, {"A": 1.25}, 1) == outputs._pack_reference(narrow, {"A": 1.25}, 1)
    assert outputs._pack_compiled(narrow, {"A": 9.0}, 1) is None  # raw 18 > 7: out of range, as the reference


def test_compiled_e2e_crc_is_the_reference_crc():
    """``_frames.e2e_p2`` (the CRC of the frames the Python path packs, EST_DIAG's pages) against
    integrity.e2e_p2_crc on random payloads of every length and data id; an id outside a byte is
    left to the reference (NotImplemented), and ``outputs._crc`` gives the reference's answer."""
    import random

    from ecu_daemon import outputs
    from ecu_daemon.integrity import CRC8H2F_TABLE, e2e_p2_crc

    assert outputs._e2e_p2_compiled is not None, "pip install builds ecu_daemon/_frames.c (setup.py)"
    rng = random.Random(10)
    for _ in range(2000):
        payload = bytearray(rng.randrange(256) for _ in range(rng.randrange(0, 9)))
        did = rng.randrange(256)
        assert outputs._e2e_p2_compiled(payload, did, CRC8H2F_TABLE) == e2e_p2_crc(payload, did)
        assert outputs._crc(payload, did) == e2e_p2_crc(payload, did)
    assert outputs._e2e_p2_compiled(bytearray(8), 256, CRC8H2F_TABLE) is NotImplemented
    assert outputs._e2e_p2_compiled(bytearray(8), -1, CRC8H2F_TABLE) is NotImplemented
    assert outputs._crc(bytearray(8), -1) == e2e_p2_crc(bytearray(8), -1)


def test_a_big_endian_message_keeps_cantools_encode(tmp_path):
    from ecu_daemon.outputs import _layout

    db = cantools.database.load_string(
        'VERSION ""\nBO_ 256 M: 8 ECU\n SG_ A : 7|16@0+ (1,0) [0|65535] "" ECU\n', database_format="dbc")
    assert _layout(db.messages[0]) is None


def _random_estimate(rng, enc) -> Estimate:
    """An estimate whose every output field is in range, at a limit, beyond it or not finite, with
    random validity flags and status: every branch of the per-field range check."""
    from ecu_daemon.outputs import _ESTIMATE_SOURCES

    limits = {}
    for p in enc._plans:
        for f in p.fields:
            if isinstance(f.source, int):
                limits[ESTIMATE_FIELDS[f.source]] = (f.lo, f.hi)
    kw = {}
    for name, (lo, hi) in limits.items():
        if name in ("gnss_fused", "gnss_rejected", "gnss_late"):
            kw[name] = rng.choice((0, 15, 16, 65535, 65536, 2 ** 40, rng.randint(0, 10 ** 6)))
            continue
        kw[name] = rng.choice((lo, hi, rng.uniform(lo, hi), rng.uniform(lo, hi), rng.uniform(lo, hi),
                               lo - 1.0, hi * 1.5 + 1.0, math.nan, math.inf, -math.inf, -7.5, 13.0))
    for flag in ("sideslip_valid", "heading_valid", "velocity_valid", "biases_valid"):
        kw[flag] = rng.random() < 0.6
    kw["status"] = rng.randrange(1 << 12)
    assert set(_ESTIMATE_SOURCES.values()) and kw
    return est(**kw)


def test_compiled_frame_encoder_gives_the_reference_frames_and_log_counts():
    """``_frames.encode`` (the whole estimate frame in C) against the Python path it replaces, on
    random estimates with saturated, non-finite and wrapped values, claimed valid or not: the same
    bytes in every frame, the same counters, and the same counts of values logged as claimed valid
    (the C path hands those frames to Python, which logs them)."""
    import random

    from ecu_daemon import outputs

    if outputs._encode_compiled is None:
        pytest.skip("the compiled frame encoder is not built (pip install builds it)")
    fast, ref = OutputEncoder(config.Config()), OutputEncoder(config.Config())
    assert all(p.compiled is not None for p in fast._plans if not p.pages)
    for p in ref._plans:
        p.compiled = None
    rng = random.Random(11)
    took_c = 0
    calls = []
    real = outputs._encode_compiled

    def counting(plan, e, counter):
        out = real(plan, e, counter)
        calls.append(out is not NotImplemented)
        return out

    outputs._encode_compiled = counting
    try:
        for k in range(3000):
            e = _random_estimate(rng, fast) if k % 3 else est(t=k * 0.006, heading_rad=rng.uniform(-20, 20))
            a = [(m.arbitration_id, bytes(m.data)) for m in fast.frames(k, e)]
            b = [(m.arbitration_id, bytes(m.data)) for m in ref.frames(k, e)]
            assert a == b, (k, e)
    finally:
        outputs._encode_compiled = real
    took_c = sum(calls)
    assert fast.saturated == ref.saturated and fast.non_finite == ref.non_finite
    assert ref.saturated and ref.non_finite  # the log paths were exercised
    assert 0.3 * len(calls) < took_c < len(calls)  # both paths ran
