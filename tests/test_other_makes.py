"""Other makes' DBCs (opendbc, unmodified, in ../shared/data/opendbc/dbc) mapped, simulated through the
DBC and replayed: what a user of a Ford, a VW PQ/MLB or a Hyundai meets first.

Each mapping below is the one a user writes from the DBC alone (units from the signal definitions:
km/h, rad/s of the wheel, deg, deg/s, g). The simulator encodes its CAN log through the same DBC
and mapping, so every layout feature the make uses goes through both directions: Motorola
(big-endian) signals with offsets (Ford), 8-bit counters, wheel speeds as wheel angular speed (the
factor is the wheel radius), magnitude + sign bit and a multiplexed lateral acceleration (VW PQ's
Bremse_2, page 0 of 2), km/h wheel speeds with a counter-checked E2E steering message (VW MLB).
"""
from __future__ import annotations

import math
from pathlib import Path

import cantools
import pytest
import tomli_w

from ecu_daemon import config as config_mod
from ecu_daemon.config import ConfigError
from ecu_daemon.cli import main as cli_main
from ecu_daemon.evaluate import read_csv
from ecu_daemon.replay import REQUIRED_INPUTS, run_replay
from ecu_daemon.samples import INPUT_NAMES
from ecu_daemon.signals import SignalDecoder
from ecu_daemon.sim.can_encoder import FrameEncoder

OPENDBC = Path(__file__).resolve().parents[2] / "shared" / "data" / "opendbc" / "dbc"
pytestmark = pytest.mark.skipif(not OPENDBC.is_dir(), reason=f"{OPENDBC} not present")

KMH, DEG = 1 / 3.6, math.pi / 180
WHEEL_RADIUS_M = 0.32  # rad/s of the wheel -> m/s at the tyre (the simulator's default car)


def _wheels(message: str, names: dict[str, str], scale: float, **extra) -> dict:
    return {f"wheel_speed_{c}": {"message": message, "signal": s, "scale": scale, **extra} for c, s in names.items()}


MAKES = {
    "ford": ("ford_lincoln_base_pt.dbc", {
        **_wheels("WheelSpeed", {"fl": "WhlFl_W_Meas", "fr": "WhlFr_W_Meas", "rl": "WhlRl_W_Meas",
                                 "rr": "WhlRr_W_Meas"}, WHEEL_RADIUS_M),
        "steering_wheel_angle": {"message": "SteeringPinion_Data", "signal": "StePinComp_An_Est", "scale": DEG,
                                 "counter": "StePinAn_No_Cnt"},
        "yaw_rate": {"message": "Yaw_Data_FD1", "signal": "VehYaw_W_Actl", "counter": "VehRollYaw_No_Cnt"},
        "accel_x": {"message": "Accel_Data_FD1", "signal": "VehLong2_A_Actl"},
        "accel_y": {"message": "Accel_Data_FD1", "signal": "VehLat2_A_Actl"},
    }),
    "vw_pq": ("vw_pq.dbc", {
        **_wheels("Bremse_3", {"fl": "Radgeschw__VL_4_1", "fr": "Radgeschw__VR_4_1", "rl": "Radgeschw__HL_4_1",
                               "rr": "Radgeschw__HR_4_1"}, KMH),
        "steering_wheel_angle": {"message": "Lenkwinkel_1", "signal": "LW1_LRW", "sign_signal": "LW1_LRW_Sign",
                                 "scale": DEG},
        "yaw_rate": {"message": "Bremse_5", "signal": "BR5_Giergeschw", "sign_signal": "BR5_Vorzeichen",
                     "scale": DEG},
        "accel_x": {"message": "Bremse_8", "signal": "BR8_Laengsbeschl"},
        "accel_y": {"message": "Bremse_2", "signal": "Querbeschleunigung", "scale": 9.80665},  # multiplexed, g
    }),
    "vw_mlb": ("vw_mlb.dbc", {
        **_wheels("ESP_03", {"fl": "ESP_VL_Radgeschw", "fr": "ESP_VR_Radgeschw", "rl": "ESP_HL_Radgeschw",
                             "rr": "ESP_HR_Radgeschw"}, KMH),
        "steering_wheel_angle": {"message": "LWI_01", "signal": "LWI_Lenkradwinkel",
                                 "sign_signal": "LWI_VZ_Lenkradwinkel", "scale": DEG, "counter": "COUNTER",
                                 "checksum": "e2e_p2"},
        "yaw_rate": {"message": "ESP_02", "signal": "ESP_Gierrate", "sign_signal": "ESP_VZ_Gierrate",
                     "scale": DEG, "counter": "COUNTER"},
        "accel_x": {"message": "ESP_02", "signal": "ESP_Laengsbeschl", "counter": "COUNTER"},
        "accel_y": {"message": "ESP_02", "signal": "ESP_Querbeschleunigung", "scale": 9.80665, "counter": "COUNTER"},
    }),
    # the steering angle's sign fixed in a copy of the DBC (see the test of the unmodified file below)
    "hyundai": ("hyundai_i30_2014.dbc", {
        **_wheels("WHL_SPD", {"fl": "WHL_SPD_FL", "fr": "WHL_SPD_FR", "rl": "WHL_SPD_RL", "rr": "WHL_SPD_RR"}, KMH),
        "steering_wheel_angle": {"message": "SAS1", "signal": "SAS_Angle", "scale": DEG},
        "yaw_rate": {"message": "ESP2", "signal": "YAW_RATE", "scale": DEG},  # deg/s, offset -40.95
        "accel_x": {"message": "ESP2", "signal": "LONG_ACCEL"},
        "accel_y": {"message": "ESP2", "signal": "LAT_ACCEL"},
    }),
}
HYUNDAI_SAS = " SG_ SAS_Angle : 0|16@1+ (0.1,0) [-3276.8|3276.7]"


def write_config(tmp_path: Path, make: str, dbc_path: Path | None = None) -> Path:
    dbc, inputs = MAKES[make]
    if dbc_path is None and make == "hyundai":
        text = (OPENDBC / dbc).read_text(encoding="cp1252")
        assert text.count(HYUNDAI_SAS) == 1
        dbc_path = tmp_path / dbc
        dbc_path.write_text(text.replace(HYUNDAI_SAS, HYUNDAI_SAS.replace("@1+", "@1-")), encoding="cp1252")
    p = tmp_path / f"{make}.toml"
    p.write_text(tomli_w.dumps({"can": {"dbc": str(dbc_path or OPENDBC / dbc), "send_outputs": False},
                                "inputs": inputs}))
    return p


@pytest.mark.parametrize("make", sorted(MAKES))
def test_a_drive_encoded_with_the_makes_dbc_replays_with_every_frame_used(tmp_path, make):
    simulate_and_replay(tmp_path, write_config(tmp_path, make))


def test_chrysler_wheels_and_steering_with_an_imu_from_a_second_dbc_joined_by_import_lines(tmp_path):
    """Chrysler's DBC has no yaw rate or accelerations: a user joins it with the IMU's DBC through
    opendbc's IMPORT lines. Both name a message STEERING (cantools keeps the last one), so the
    steering is mapped by frame id. Before: the simulator refused the drive, "1.01 does not fit signal
    WHEEL_SPEED_FL [0, 1]" -- the placeholder range opendbc's Chrysler DBC gives every value signal."""
    import shutil

    for name in ("chrysler_cusw.dbc",):
        shutil.copy(OPENDBC / name, tmp_path / name)
    shutil.copy(Path(__file__).resolve().parents[1] / "ecu_daemon" / "dbc" / "ecu_daemon_inputs.dbc", tmp_path)
    (tmp_path / "combo.dbc").write_text('CM_ "IMPORT chrysler_cusw.dbc";\nCM_ "IMPORT ecu_daemon_inputs.dbc";\n')
    inputs = {f"wheel_speed_{c}": {"message": f"WHEEL_SPEEDS_{'FRONT' if c[0] == 'f' else 'REAR'}",
                                   "signal": f"WHEEL_SPEED_{c.upper()}", "counter": "COUNTER"}
              for c in ("fl", "fr", "rl", "rr")}  # 13-bit Motorola, [0|1] in the DBC
    inputs["steering_wheel_angle"] = {"message": 494, "signal": "STEER_ANGLE", "scale": DEG,  # offset -720 deg
                                      "counter": "COUNTER"}
    p = tmp_path / "chrysler.toml"
    p.write_text(tomli_w.dumps({"can": {"dbc": "combo.dbc", "send_outputs": False}, "inputs": inputs}))
    simulate_and_replay(tmp_path, p)
    # by name, the mapping would silently read our STEERING (0xB2) instead of Chrysler's (0x1EE)
    inputs["steering_wheel_angle"]["message"] = "STEERING"
    p.write_text(tomli_w.dumps({"can": {"dbc": "combo.dbc", "send_outputs": False}, "inputs": inputs}))
    with pytest.raises(ConfigError, match=r"^\[inputs.steering_wheel_angle\] message 'STEERING' names 2 messages in"
                                          r" .*combo.dbc \(0x1EE, 0xB2\): give the frame id instead, e.g."
                                          r" message = 0x1EE$"):
        SignalDecoder(config_mod.load(p))
    with pytest.raises(ConfigError, match=r"message 'STEERING' names 2 messages in .*\(0x1EE, 0xB2\)"):
        FrameEncoder(config_mod.load(p))  # the simulator too (before: it encoded our STEERING)


def simulate_and_replay(tmp_path: Path, cfg_path: Path) -> None:
    out = tmp_path / "drive"
    assert cli_main(["simulate", "--scenario", "dlc_dry", "--duration", "14", "--config", str(cfg_path),
                     "--out", str(out)]) == 0
    cfg = config_mod.load(out / "config.toml")
    summary = run_replay(cfg, str(out / "drive.log"), str(out / "drive_gnss.log"), str(tmp_path / "est.csv"),
                         None, progress=False)
    rows = summary["inputs"]
    for name in REQUIRED_INPUTS:  # nothing dropped: range, counter, checksum, decode all pass
        assert rows[name]["frames"] > 1000 and rows[name]["samples"] == rows[name]["frames"], (name, rows[name])
    est = read_csv(tmp_path / "est.csv", ("t", "sideslip_rad", "sideslip_valid"), "estimate CSV")
    truth = read_csv(out / "truth.csv", ("t", "sideslip_rad"), "truth CSV")
    valid = est["sideslip_valid"] > 0
    assert valid.sum() > 0.3 * len(valid)
    import numpy as np
    err = np.abs(est["sideslip_rad"] - np.interp(est["t"], truth["t"], truth["sideslip_rad"]))[valid]
    assert err.max() < math.radians(1.0)


def _bremse_2_frames(db, values_g: list[float]) -> list[bytes]:
    """Bremse_2 as a PQ car sends it: page 0 (lateral acceleration) and page 1 (a timer) in turn."""
    msg = db.get_message_by_name("Bremse_2")
    base = {s.name: 0 for s in msg.signals if s.multiplexer_ids is None}
    out = []
    for k, ay in enumerate(values_g):
        out.append(msg.encode({**base, "Querbeschl__TimerTic": 0, "Querbeschleunigung": ay}))
        out.append(msg.encode({**base, "Querbeschl__TimerTic": 1, "Timer": 0.04 * k}))
    return out


def test_a_multiplexed_input_counts_only_the_frames_of_its_page(tmp_path):
    """Before: every Bremse_2 frame counted as an accel_y frame, so half of them looked unusable (and
    with three pages the replay ended with 'accel_y not usable')."""
    cfg = config_mod.load(write_config(tmp_path, "vw_pq"))
    db = cantools.database.load_file(str(OPENDBC / "vw_pq.dbc"), strict=False)
    dec = SignalDecoder(cfg)
    got = []
    for k, frame in enumerate(_bremse_2_frames(db, [0.1, -0.25, 0.5])):
        got += [s.value for s in dec.decode(0.01 * k, 0x5A0, frame) if INPUT_NAMES[s.index] == "accel_y"]
    assert got == pytest.approx([0.1 * 9.80665, -0.25 * 9.80665, 0.5 * 9.80665])
    h = dec.health["accel_y"]
    assert (h.frames, h.samples, sum(h.errors.values())) == (3, 3, 0)


def test_the_simulator_sends_the_page_of_a_multiplexed_input(tmp_path):
    cfg = config_mod.load(write_config(tmp_path, "vw_pq"))
    enc = FrameEncoder(cfg)
    plan = next(p for p in enc.plans if p.message.name == "Bremse_2")
    db = cantools.database.load_file(str(OPENDBC / "vw_pq.dbc"), strict=False)
    frame = enc.encode(plan, {"accel_y": -2.0})
    decoded = db.decode_message("Bremse_2", frame, decode_choices=False)
    assert decoded["Querbeschl__TimerTic"] == 0
    assert decoded["Querbeschleunigung"] * 9.80665 == pytest.approx(-2.0, abs=0.05)  # 0.01 g steps


def test_an_unsigned_signal_with_a_signed_range_is_named_in_one_line(tmp_path, caplog, capsys):
    """opendbc's i30 DBC declares the steering angle unsigned with the range [-3276.8|3276.7]: a right
    turn (two's complement on the car) decodes to 6553.6 deg minus the angle, in cantools too. Before,
    nothing said so: the replay dropped every right turn as out of range, the simulator said only
    'does not fit signal SAS_Angle [0, 6553.5]'."""
    cfg_path = write_config(tmp_path, "hyundai", OPENDBC / "hyundai_i30_2014.dbc")
    with caplog.at_level("WARNING"):
        SignalDecoder(config_mod.load(cfg_path))
    lines = [r.getMessage() for r in caplog.records if "SAS_Angle" in r.getMessage()]
    assert len(lines) == 1 and lines[0].startswith("[inputs.steering_wheel_angle] signal 'SAS_Angle' of SAS1 is unsigned")
    assert "[-3276.8, 3276.7]" in lines[0] and "6553.6 + value" in lines[0] and "(0|16@1-)" in lines[0]
    assert not [r for r in caplog.records if r.levelname == "WARNING" and "SAS_Angle" not in r.getMessage()]
    rc = cli_main(["simulate", "--scenario", "dlc_dry", "--config", str(cfg_path),
                   "--out", str(tmp_path / "d")])
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert rc == 2 and "does not fit signal SAS_Angle" in err and "make it signed in the DBC (0|16@1-)" in err


def test_pages_the_dbc_does_not_define_are_skipped_not_counted_as_decode_errors(tmp_path):
    """A DBC rarely lists every page a car sends (opendbc's are reverse-engineered): cantools cannot
    decode those frames ("expected multiplexer id 0 or 1, but got 2"). They carry none of the
    mapped inputs; before, each one counted as a decode error of the input and was logged."""
    (tmp_path / "mux.dbc").write_text('VERSION ""\n\nNS_ :\n\nBS_:\n\nBU_: ABS\n\n'
                                      'BO_ 1440 Bremse_2: 8 ABS\n'
                                      ' SG_ Page M : 8|2@1+ (1,0) [0|3] "" ABS\n'
                                      ' SG_ Timer m1 : 0|8@1+ (0.04,0) [0|10.2] "usec" ABS\n'
                                      ' SG_ Querbeschleunigung m0 : 0|8@1+ (0.01,-1.27) [-1.27|1.27] "g" ABS\n\n')
    cfg = config_mod.from_dict({"can": {"dbc": str(tmp_path / "mux.dbc")},
                                "inputs": {"accel_y": {"message": "Bremse_2", "signal": "Querbeschleunigung",
                                                       "scale": 9.80665}}})
    cfg.inputs = {"accel_y": cfg.inputs["accel_y"]}  # this DBC carries nothing else
    dec = SignalDecoder(cfg)
    got = []
    for k in range(12):  # pages 0, 1, 2, 3 in turn: 2 and 3 are not in the DBC
        got += [s.value for s in dec.decode(0.01 * k, 0x5A0, bytes([127 + k, k % 4, 0, 0, 0, 0, 0, 0]))]
    assert got == pytest.approx([(127 + k) * 0.01 * 9.80665 - 1.27 * 9.80665 for k in (0, 4, 8)])
    h = dec.health["accel_y"]
    assert (h.frames, h.samples, sum(h.errors.values())) == (3, 3, 0)
    # a frame cantools cannot decode for another reason is still a decode error
    dec.decode(1.0, 0x5A0, bytes(7))
    assert h.errors["dlc"] == 1


@pytest.mark.parametrize("make, warned", [
    ("ford", {"wheel_speed_fl", "wheel_speed_fr", "wheel_speed_rl", "wheel_speed_rr", "steering_wheel_angle"}),
    ("vw_pq", {"wheel_speed_fl", "wheel_speed_fr", "wheel_speed_rl", "wheel_speed_rr", "steering_wheel_angle",
               "yaw_rate", "accel_y"}),
    ("vw_mlb", {"wheel_speed_fl", "wheel_speed_fr", "wheel_speed_rl", "wheel_speed_rr", "steering_wheel_angle",
                "yaw_rate", "accel_y"}),
])
def test_a_scale_left_at_1_for_a_non_si_dbc_unit_is_one_line_per_input(tmp_path, caplog, make, warned):
    """The DBC says km/h, rad/s of a wheel, deg, Grad/sec, g: with scale = 1 the value is read as SI.
    Wheel speeds 3.6x too fast keep the velocity valid and wrong (the worst defect); before, nothing
    said so until the end of a replay (and the live daemon never). The right mapping says nothing."""
    cfg = config_mod.load(write_config(tmp_path, make))
    with caplog.at_level("WARNING"):
        SignalDecoder(cfg)
    assert not [r for r in caplog.records if "DBC unit" in r.getMessage()]
    for m in cfg.inputs.values():
        m.scale = 1.0
    caplog.clear()
    with caplog.at_level("WARNING"):
        SignalDecoder(cfg)
    lines = {r.getMessage().split("]")[0][len("[inputs."):]: r.getMessage() for r in caplog.records
             if "its DBC unit" in r.getMessage()}
    assert set(lines) == warned, lines
    if make == "ford":
        assert lines["wheel_speed_fl"] == (
            "[inputs.wheel_speed_fl] signal 'WhlFl_W_Meas' is in rad/s (its DBC unit), but scale = 1 reads it 3.12x"
            " too large in m/s: rad/s of a wheel -> m/s is its rolling radius: scale = 0.32 for [vehicle]"
            " wheel_radius_m = 0.32")
    else:
        assert "reads it 3.6x too large in m/s" in lines["wheel_speed_fl"]
        assert "reads it 57.3x too large in rad" in lines["steering_wheel_angle"]
        assert "reads it 9.81x too small in m/s^2" in lines["accel_y"]
