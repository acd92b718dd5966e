"""Sign-magnitude inputs (VW MQB: magnitude + sign bit) with the real opendbc extract, both ways.

Frames are built with cantools from the real DBC (not with our encoder) for the decoder test, so
the decoder is checked against an independent reference; the simulator's encoder is checked by a
round trip and by refusing what the DBC cannot carry.
"""
from __future__ import annotations

import math
from pathlib import Path

import cantools
import pytest

from ecu_daemon import config as config_mod
from ecu_daemon.cli import main as cli_main
from ecu_daemon.config import ConfigError
from ecu_daemon.samples import INPUT_NAMES
from ecu_daemon.signals import SignalDecoder
from ecu_daemon.sim.can_encoder import FrameEncoder, UnencodableValue

ROOT = Path(__file__).resolve().parents[1]
VW_EXAMPLE = ROOT / "examples" / "vw_mqb.toml"
VW_EXTRACT = ROOT / "examples" / "vw_mqb_chassis.dbc"
SHARED_VW = ROOT.parent / "shared" / "data" / "opendbc" / "dbc" / "vw_mqb.dbc"


@pytest.fixture(scope="module")
def vw():
    return config_mod.load(VW_EXAMPLE)


def _decode(dec, frame_id, data):
    return {INPUT_NAMES[s.index]: s.value for s in dec.decode(1.0, frame_id, data)}


def test_magnitude_and_sign_bit_decode_to_signed_si(vw):
    db = cantools.database.load_file(str(VW_EXTRACT), strict=False)
    esp02, lwi = db.get_message_by_name("ESP_02"), db.get_message_by_name("LWI_01")
    dec = SignalDecoder(vw)
    base = {s.name: 0 for s in esp02.signals}
    base.update(ESP_Querbeschleunigung=0.0, ESP_Laengsbeschl=0.0)
    for sign, expect in ((0, 1.0), (1, -1.0)):
        frame = esp02.encode({**base, "ESP_Gierrate": 12.34, "ESP_VZ_Gierrate": sign, "COUNTER": sign})
        got = _decode(dec, esp02.frame_id, frame)
        assert got["yaw_rate"] == pytest.approx(expect * math.radians(12.34), abs=1e-9)
    lbase = {s.name: 0 for s in lwi.signals}
    got = _decode(dec, lwi.frame_id, lwi.encode({**lbase, "LWI_Lenkradwinkel": 123.4, "LWI_VZ_Lenkradwinkel": 1}))
    assert got["steering_wheel_angle"] == pytest.approx(-math.radians(123.4), abs=1e-9)


def test_without_the_sign_signal_a_negative_value_would_be_lost(vw):
    """What the issue saw: the magnitude alone reads a right turn as a left one."""
    db = cantools.database.load_file(str(VW_EXTRACT), strict=False)
    esp02 = db.get_message_by_name("ESP_02")
    frame = esp02.encode({**{s.name: 0 for s in esp02.signals}, "ESP_Querbeschleunigung": 0.0,
                          "ESP_Laengsbeschl": 0.0, "ESP_Gierrate": 5.0, "ESP_VZ_Gierrate": 1})
    unsigned = config_mod.load(VW_EXAMPLE)
    unsigned.inputs["yaw_rate"].sign_signal = ""
    assert _decode(SignalDecoder(unsigned), esp02.frame_id, frame)["yaw_rate"] > 0
    assert _decode(SignalDecoder(vw), esp02.frame_id, frame)["yaw_rate"] < 0


def test_encoder_round_trips_negative_values_through_the_sign_bit(vw):
    enc, dec = FrameEncoder(vw), SignalDecoder(vw)
    values = {"wheel_speed_fl": 20.0, "wheel_speed_fr": 20.1, "wheel_speed_rl": 19.9, "wheel_speed_rr": 20.0,
              "steering_wheel_angle": -1.2, "yaw_rate": -0.35, "accel_x": -1.5, "accel_y": -4.0}
    got = {}
    for plan in enc.plans:
        data = enc.encode(plan, {name: values[name] for name, *_ in plan.inputs})
        got.update(_decode(dec, plan.frame_id, data))
    assert got["yaw_rate"] == pytest.approx(-0.35, abs=math.radians(0.01))
    assert got["steering_wheel_angle"] == pytest.approx(-1.2, abs=math.radians(0.1))
    assert got["accel_y"] == pytest.approx(-4.0, abs=0.1)
    assert got["wheel_speed_fl"] == pytest.approx(20.0, abs=0.01)


def test_encoder_refuses_what_the_dbc_cannot_hold_instead_of_clipping(vw):
    enc = FrameEncoder(vw)
    wheels = next(p for p in enc.plans if p.message.name == "ESP_19")
    with pytest.raises(UnencodableValue, match=r"\[inputs.wheel_speed_fl\] -2 \(SI\).*ESP_VL_Radgeschw_02 \[0, 491.49\]"):
        enc.encode(wheels, {"wheel_speed_fl": -2.0, "wheel_speed_fr": 1.0, "wheel_speed_rl": 1.0, "wheel_speed_rr": 1.0})
    imu = next(p for p in enc.plans if p.message.name == "ESP_02")
    with pytest.raises(UnencodableValue, match="ESP_Querbeschleunigung"):  # 2 g: the signal holds +-1.27 g
        enc.encode(imu, {"yaw_rate": 0.1, "accel_x": 0.0, "accel_y": 2 * 9.81})
    # a signed value still fits within half a step of the range end
    enc.encode(imu, {"yaw_rate": math.radians(163.82), "accel_x": 0.0, "accel_y": 0.0})


def test_simulate_cli_reports_an_unencodable_drive_in_one_line(tmp_path, capsys):
    """A drive whose lateral acceleration the (re-scaled) signal cannot carry: refused, not clipped."""
    rc = cli_main(["simulate", "-s", "dlc_dry", "--config", str(VW_EXAMPLE), "--duration", "2",
                   "-o", str(tmp_path / "ok")])
    assert rc == 0
    capsys.readouterr()
    cfg_path = tmp_path / "signed_ay.toml"
    text = VW_EXAMPLE.read_text().replace('dbc = "vw_mqb_chassis.dbc"', f'dbc = "{VW_EXTRACT}"')
    cfg_path.write_text(text.replace('scale = 9.80665  # g -> m/s^2', 'scale = 0.5'))  # 1.27 -> 0.635 m/s^2
    rc = cli_main(["simulate", "-s", "circle_bank", "--config", str(cfg_path), "--duration", "25",
                   "-o", str(tmp_path / "bad")])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and "[inputs.accel_y]" in err and "cannot be encoded" in err


def test_unknown_sign_signal_is_a_config_error(vw):
    bad = config_mod.load(VW_EXAMPLE)
    bad.inputs["yaw_rate"].sign_signal = "ESP_VZ_Gierate"
    with pytest.raises(ConfigError, match="sign_signal 'ESP_VZ_Gierate'.*did you mean 'ESP_VZ_Gierrate'"):
        SignalDecoder(bad)


@pytest.mark.skipif(not SHARED_VW.exists(), reason="../shared/data/opendbc not present")
def test_extract_is_unmodified_from_the_opendbc_file():
    full = cantools.database.load_file(str(SHARED_VW), strict=False)
    ext = cantools.database.load_file(str(VW_EXTRACT), strict=False)
    for m in ext.messages:
        ref = full.get_message_by_frame_id(m.frame_id)
        assert [(s.name, s.start, s.length, s.scale, s.offset, s.is_signed) for s in m.signals] == \
               [(s.name, s.start, s.length, s.scale, s.offset, s.is_signed) for s in ref.signals]
