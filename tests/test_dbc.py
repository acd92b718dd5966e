"""Our two DBC files: strict-loadable, the layout the daemon and the brief rely on, readable by cantools."""
from __future__ import annotations

import dataclasses
import math
import shutil
import subprocess
import sys
from pathlib import Path

import cantools
import pytest

from ecu_daemon import config
from ecu_daemon.canlog import CandumpWriter
from ecu_daemon.diagnostics import Diagnostics, InputDiagnostics, SourceDiagnostics
from ecu_daemon.estimator import estimate as estimate_module
from ecu_daemon.estimator.estimate import ESTIMATE_FIELDS, Estimate
from ecu_daemon.integrity import data_id_for
from ecu_daemon.outputs import (OutputEncoder, _DIAG_FIELDS, _DIAG_INPUT_PREFIX, _DIAG_INPUT_SUFFIX,
                                _DIAG_SOURCE_PREFIX, _DIAG_SOURCE_SUFFIX, _ESTIMATE_SOURCES)

ROOT = Path(__file__).resolve().parents[1]
INPUTS_DBC = ROOT / "ecu_daemon" / "dbc" / "ecu_daemon_inputs.dbc"
OUTPUTS_DBC = ROOT / "ecu_daemon" / "dbc" / "ecu_daemon_outputs.dbc"


@pytest.fixture(scope="module")
def inputs_db():
    return cantools.database.load_file(INPUTS_DBC, strict=True)


@pytest.fixture(scope="module")
def outputs_db():
    return cantools.database.load_file(OUTPUTS_DBC, strict=True)


def raw_range(sig):
    n = sig.length
    lo, hi = (-(1 << (n - 1)), (1 << (n - 1)) - 1) if sig.is_signed else (0, (1 << n) - 1)
    return lo * sig.scale + sig.offset, hi * sig.scale + sig.offset


@pytest.mark.parametrize("path", [INPUTS_DBC, OUTPUTS_DBC])
def test_dbc_is_ascii_and_carries_cycle_times_nodes_and_integrity_fields(path):
    path.read_bytes().decode("ascii")  # cantools reads cp1252 by default: keep it ASCII
    db = cantools.database.load_file(path, strict=True)
    ids = [m.frame_id for m in db.messages]
    assert len(ids) == len(set(ids))
    node_names = {n.name for n in db.nodes}
    for m in db.messages:
        assert not m.is_extended_frame and m.frame_id <= 0x7FF
        assert m.length == 8
        assert isinstance(m.cycle_time, int) and m.cycle_time > 0
        assert m.senders and set(m.senders) <= node_names
        chk, cnt = m.get_signal_by_name("CHECKSUM"), m.get_signal_by_name("COUNTER")
        assert (chk.start, chk.length, chk.byte_order, chk.is_signed) == (0, 8, "little_endian", False)
        assert (cnt.start, cnt.length, cnt.byte_order, cnt.is_signed) == (8, 4, "little_endian", False)
        assert data_id_for(m) == m.frame_id & 0xFF == m.dbc.attributes["E2EDataId"].value
    comment = _db_comment(path)  # the E2E scheme is documented in the file itself
    assert "compute_profile2_crc(payload, frame_id & 0xFF)" in comment and "E2EDataId" in comment


def _db_comment(path: Path) -> str:
    text = path.read_text(encoding="ascii")
    start = text.index('CM_ "')
    return text[start:text.index('";', start)]


def test_input_dbc_layout_matches_the_default_mapping(inputs_db):
    ws = inputs_db.get_message_by_name("WHEEL_SPEEDS")
    st = inputs_db.get_message_by_name("STEERING")
    imu = inputs_db.get_message_by_name("IMU")
    assert (ws.frame_id, st.frame_id, imu.frame_id) == (0x0B0, 0x0B2, 0x0B4)
    assert {m.name: m.cycle_time for m in inputs_db.messages} == {"WHEEL_SPEEDS": 10, "STEERING": 10, "IMU": 10,
                                                                  "MAGNETOMETER": 20,  # optional, 50 Hz
                                                                  "IMU_ROLL": 10}  # optional
    roll = inputs_db.get_message_by_name("IMU_ROLL").get_signal_by_name("ROLL_RATE")
    assert roll.is_signed and roll.unit == "rad/s" and roll.scale <= 1e-4 and raw_range(roll)[1] >= 3.0
    for name, m in config.roll_rate_input().items():  # the optional mapping fits its signal too
        lo, hi = raw_range(inputs_db.get_message_by_name(m.message).get_signal_by_name(m.signal))
        assert lo <= m.min and m.max <= hi, name
    assert (ws.senders, st.senders, imu.senders) == (["ABS"], ["SAS"], ["IMU"])
    for corner in ("FL", "FR", "RL", "RR"):
        s = ws.get_signal_by_name(f"WHEEL_SPEED_{corner}")
        lo, hi = raw_range(s)
        assert s.unit == "m/s" and lo <= -10.0 and hi >= 250.0
        assert s.scale <= 0.032  # best 13 bits allow: 4 wheels + CHECKSUM + COUNTER in 8 bytes
        assert s.raw_initial is not None and abs(s.raw_initial * s.scale + s.offset) < 1e-9  # starts at 0 m/s
    angle = st.get_signal_by_name("STEERING_WHEEL_ANGLE")
    assert angle.is_signed and angle.unit == "rad" and angle.scale <= 0.0005 and raw_range(angle)[1] >= 15.0
    assert st.get_signal_by_name("STEERING_WHEEL_RATE").unit == "rad/s"
    yaw = imu.get_signal_by_name("YAW_RATE")
    assert yaw.is_signed and yaw.unit == "rad/s" and yaw.scale <= 1e-4 and raw_range(yaw)[1] >= 3.0
    for name in ("ACCEL_X", "ACCEL_Y"):
        a = imu.get_signal_by_name(name)
        assert a.is_signed and a.unit == "m/s^2" and a.scale <= 1e-3 and raw_range(a)[1] >= 30.0
    # every default [inputs.*] mapping names a real message and signal, inside the signal's range
    for name, m in config.Config().inputs.items():
        msg = inputs_db.get_message_by_name(m.message)
        sig = msg.get_signal_by_name(m.signal)
        lo, hi = raw_range(sig)
        assert lo <= m.min and m.max <= hi, name
        assert msg.get_signal_by_name(m.counter).length == 4


def test_output_dbc_timing_ids_and_resolution(outputs_db):
    for m in outputs_db.messages:
        assert 0x300 <= m.frame_id < 0x400
        assert m.cycle_time % 6 == 0, m.name
        assert m.senders == ["ECU_DAEMON"]
    sideslip = outputs_db.get_message_by_name("EST_SIDESLIP")
    assert sideslip.cycle_time == 6
    beta = sideslip.get_signal_by_name("SIDESLIP")
    assert beta.is_signed and beta.length == 16 and beta.scale <= math.radians(0.001)
    heading = outputs_db.get_message_by_name("EST_HEADING").get_signal_by_name("HEADING")
    assert heading.scale <= 1e-4 and raw_range(heading)[1] >= 2 * math.pi
    diag = outputs_db.get_message_by_name("EST_DIAG")
    assert diag.is_multiplexed() and diag.cycle_time % 6 == 0


def test_every_estimate_and_diagnostics_field_has_an_output_signal(outputs_db):
    signals = {s.name for m in outputs_db.messages for s in m.signals}
    fed = {field for field, _, _ in _ESTIMATE_SOURCES.values()}
    flags = {f for f in ESTIMATE_FIELDS if f.endswith("_valid")}
    missing = set(ESTIMATE_FIELDS) - fed - flags - {"t", "status"}
    assert not missing
    assert all(name in signals for name in _ESTIMATE_SOURCES)
    status_bits = [n for n in dir(estimate_module) if n.startswith("STATUS_")]
    assert status_bits and all(n in signals for n in status_bits)
    diag_fields = {f.name for f in dataclasses.fields(Diagnostics)} - {"inputs", "sources"}
    assert diag_fields == {attr for attr, _ in _DIAG_FIELDS.values()}
    assert {f.name for f in dataclasses.fields(InputDiagnostics)} == {a for a, _ in _DIAG_INPUT_SUFFIX.values()}
    for prefix in _DIAG_INPUT_PREFIX:
        for suffix in _DIAG_INPUT_SUFFIX:
            assert f"{prefix}_{suffix}" in signals
    assert {f.name for f in dataclasses.fields(SourceDiagnostics)} == {a for a, _ in _DIAG_SOURCE_SUFFIX.values()}
    assert set(_DIAG_SOURCE_PREFIX.values()) == set(Diagnostics().sources)
    for prefix in _DIAG_SOURCE_PREFIX:
        for suffix in _DIAG_SOURCE_SUFFIX:
            assert f"{prefix}_{suffix}" in signals


def test_cantools_decode_cli_reads_every_output_signal_from_a_candump(tmp_path):
    """What a person does on the bench: candump -L | cantools decode dbc/ecu_daemon_outputs.dbc."""
    cfg = config.Config()
    cfg.inputs.update(config.magnetometer_inputs())  # its EST_DIAG pages are sent only with one mapped
    cfg.inputs.update(config.roll_rate_input())  # and so is the roll gyro's
    enc = OutputEncoder(cfg)
    est = Estimate(t=12.5, sideslip_rad=0.01, sideslip_std_rad=0.002, heading_rad=1.0, heading_std_rad=0.02,
                   vx_mps=20.0, vy_mps=0.2, vx_std_mps=0.05, vy_std_mps=0.1, yaw_rate_radps=0.1,
                   yaw_rate_bias_radps=-0.007, yaw_rate_bias_std_radps=0.001, accel_x_bias_mps2=0.1,
                   accel_x_bias_std_mps2=0.05, accel_y_bias_mps2=-0.1, accel_y_bias_std_mps2=0.05,
                   gnss_delay_s=0.2, wheel_scale=0.99, steering_offset_rad=0.01,
                   cornering_stiffness_front_n_per_rad=1e5, cornering_stiffness_rear_n_per_rad=1.2e5,
                   sideslip_valid=True, heading_valid=True, velocity_valid=True, biases_valid=True,
                   status=estimate_module.STATUS_HEADING_ALIGNED, gnss_fused=7, gnss_rejected=1, gnss_late=0)
    log = tmp_path / "out.log"
    with CandumpWriter(log) as w:
        period = max(p for _, _, p, _ in enc.schedule)
        for k in range(max(period, 2 * 29)):  # every message, and all 29 EST_DIAG pages
            for msg in enc.frames(k, est, Diagnostics()):
                w.write(msg)
    r = subprocess.run([sys.executable, "-m", "cantools", "decode", str(OUTPUTS_DBC)],
                       stdin=log.open(), capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    db = cantools.database.load_file(OUTPUTS_DBC)
    for m in db.messages:
        for s in m.signals:
            assert f"    {s.name}: " in r.stdout, s.name
    assert "SIDESLIP: 0.01 rad" in r.stdout and "Unknown frame" not in r.stdout and "Error" not in r.stdout
    # value tables: the validity and status bits are printed by name
    for name in ("SIDESLIP_VALID: VALID", "HEADING_VALID: VALID", "BIASES_VALID: VALID", "STATUS_HEADING_ALIGNED: ALIGNED",
                 "STATUS_STANDSTILL: MOVING", "STATUS_GNSS_REJECTED: GNSS_ACCEPTED", "GNSS_FIX_TYPE: NO_FIX",
                 "STATUS_GNSS_HEADING: NO_GNSS_HEADING", "GNSS_HEADING_STATE: NONE"):
        assert f"    {name}" in r.stdout, name


def _diag_pages(cfg) -> set:
    enc = OutputEncoder(cfg)
    db = cantools.database.load_file(OUTPUTS_DBC)
    est = Estimate(*([0.0] * 21), *([False] * 4), 0, 0, 0, 0)
    pages = set()
    for k in range(max(p for _, _, p, _ in enc.schedule) * 40):
        for msg in enc.frames(k, est, Diagnostics()):
            if db.get_message_by_frame_id(msg.arbitration_id).name == "EST_DIAG":
                pages.add(msg.data[2])
    return pages


def test_aiding_source_pages_are_sent_only_for_the_sources_the_config_names():
    """A car without a baseline, roll gyro or magnetometer sends the EST_DIAG pages it always
    sent; a dual-antenna receiver adds AIDING_SOURCES (page 40), a roll gyro also ROLL_GYRO (41)."""
    plain = _diag_pages(config.Config())
    assert 40 not in plain and 41 not in plain and {0, 32, 36, 48} <= plain
    dual = config.Config()
    dual.gnss.baseline_m = 1.2
    assert _diag_pages(dual) == plain | {40}
    gyro = config.Config()
    gyro.inputs.update(config.roll_rate_input())
    assert _diag_pages(gyro) == plain | {40, 41}


def test_every_validity_and_status_bit_has_a_value_table(outputs_db):
    """So that `cantools decode` (and any DBC tool) shows names, not bare 0/1."""
    bits = [(m.name, s) for m in outputs_db.messages for s in m.signals
            if s.name.endswith("_VALID") or s.name.startswith("STATUS_")]
    assert len(bits) == 30  # 24 + bank, grade and roll validity in EST_ROAD and EST_ROAD_STD
    for msg, s in bits:
        assert s.choices is not None and set(s.choices) == {0, 1}, f"{msg}.{s.name}"
    decoded = outputs_db.decode_message("EST_HEADING", outputs_db.encode_message(
        "EST_HEADING", {"CHECKSUM": 0, "COUNTER": 0, "HEADING_VALID": 0, "HEADING": 1.0, "HEADING_STD": 0.1,
                        **{s.name: 1 for _, s in bits if s.name.startswith("STATUS_")}}))
    assert decoded["HEADING_VALID"] == "INVALID" and decoded["STATUS_RESET"] == "RESET"


@pytest.mark.skipif(shutil.which("gcc") is None, reason="no C compiler")
@pytest.mark.parametrize("path", [INPUTS_DBC, OUTPUTS_DBC])
def test_generated_c_code_compiles_cleanly(tmp_path, path):
    """A well-formed DBC also serves a future embedded port: cantools' C generator + gcc -Wall -Werror."""
    from cantools.database.can.c_source import generate

    name = path.stem
    header, source, _, _ = generate(cantools.database.load_file(path, strict=True), name, f"{name}.h",
                                    f"{name}.c", f"{name}_fuzzer.c")
    (tmp_path / f"{name}.h").write_text(header)
    (tmp_path / f"{name}.c").write_text(source)
    r = subprocess.run(["gcc", "-c", "-std=c99", "-Wall", "-Wextra", "-Werror", f"{name}.c"], cwd=tmp_path,
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr


@pytest.mark.parametrize("scenario", ["reversing", "demo"])
def test_every_output_signal_of_a_replay_is_inside_its_dbc_range(tmp_path, scenario):
    """What `cantools decode` / `cantools monitor` users see on the bus: every frame of a replayed drive
    (reversing: negative speeds; demo: a mixed drive with a GNSS outage) is a known message, and every
    signal decodes inside the [min|max] our output DBC gives it (a value outside would mean a clipped or
    wrapped raw value)."""
    from ecu_daemon.replay import run_replay
    from ecu_daemon.sim import SCENARIOS, simulate, vehicle_config
    from ecu_daemon.sim.scenario import Scenario
    from ecu_daemon.sim.writer import write_all

    sc = Scenario("reversing", "reversing") if scenario == "reversing" else SCENARIOS["demo"].with_(duration_s=40.0)
    write_all(tmp_path, simulate(sc, vehicle_config(sc)))
    cfg = config.load(tmp_path / "config.toml")
    run_replay(cfg, str(tmp_path / "drive.log"), str(tmp_path / "drive_gnss.log"), None, str(tmp_path / "out.log"),
               progress=False)
    db = cantools.database.load_file(OUTPUTS_DBC, strict=True)
    n, names = 0, set()
    for line in (tmp_path / "out.log").read_text().splitlines():
        frame_id, data = line.split()[2].split("#")
        msg = db.get_message_by_frame_id(int(frame_id, 16))
        names.add(msg.name)
        for name, v in msg.decode(bytes.fromhex(data), decode_choices=False).items():
            sig = msg.get_signal_by_name(name)
            assert sig.minimum - 1e-9 <= v <= sig.maximum + 1e-9, (msg.name, name, v, sig.minimum, sig.maximum)
        n += 1
    assert n > 5000 and names == {m.name for m in db.messages}  # every message was sent
