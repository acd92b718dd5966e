"""``[[gnss.receiver]]``: several receivers in one config; the single-receiver ``[gnss]`` unchanged."""
from __future__ import annotations

import tomllib

import pytest

from ecu_daemon import config as config_mod
from ecu_daemon.config import ConfigError, GnssReceiver

TWO = """
[gnss]
min_fix_type = 3
[[gnss.receiver]]
port = "/dev/ttyACM0"
lever_arm_m = [1.5, 0.0]
delay_s = 0.35
[[gnss.receiver]]
port = "/dev/ttyUSB1"
protocol = "nmea"
role = "heading"
delay_s = 0.1
heading_offset_deg = 90
baseline_m = 1.2
"""


def _load(text: str):
    return config_mod.from_dict(tomllib.loads(text))


def test_a_single_receiver_config_is_one_velocity_receiver():
    cfg = _load('[gnss]\nport = "/dev/ttyS3"\nlever_arm_m = [0.5, -0.2]\ndelay_s = 0.3\nbaseline_m = 1.1\n')
    assert cfg.gnss.receivers() == [GnssReceiver("/dev/ttyS3", 115200, "auto", "velocity", 0.3, [0.5, -0.2], 0.0, 1.1)]
    assert "receiver" not in config_mod.to_dict(cfg)["gnss"]  # show-config prints what it always printed


def test_a_receiver_list_keeps_each_receivers_settings_and_mirrors_the_first_velocity_one():
    cfg = _load(TWO)
    a, b = cfg.gnss.receivers()
    assert (a.port, a.lever_arm_m, a.delay_s, a.role) == ("/dev/ttyACM0", [1.5, 0.0], 0.35, "velocity")
    assert (b.port, b.protocol, b.role, b.heading_offset_deg, b.baseline_m) == ("/dev/ttyUSB1", "nmea", "heading", 90.0, 1.2)
    # code written for one receiver reads the first velocity receiver
    assert (cfg.gnss.port, cfg.gnss.lever_arm_m, cfg.gnss.delay_s) == ("/dev/ttyACM0", [1.5, 0.0], 0.35)
    assert cfg.gnss.min_fix_type == 3 and cfg.gnss.max_delay_s >= 0.65


def test_show_config_round_trips_a_receiver_list():
    cfg = _load(TWO)
    text = config_mod.to_toml(cfg)
    assert text.count("[[gnss.receiver]]") == 2
    again = config_mod.from_dict(tomllib.loads(text))
    assert again.gnss.receivers() == cfg.gnss.receivers()


@pytest.mark.parametrize("text, message", [
    ('[gnss]\nport = "/dev/a"\n[[gnss.receiver]]\nport = "/dev/b"\n', "these go in each receiver"),
    ('[[gnss.receiver]]\nport = "/dev/a"\n[[gnss.receiver]]\nport = "/dev/a"\n', "ports must differ"),
    ('[[gnss.receiver]]\nport = "/dev/a"\nrole = "heading"\n', "role = \"velocity\""),
    ('[[gnss.receiver]]\nport = "/dev/a"\nrole = "course"\n', "role must be velocity or heading"),
    ('[[gnss.receiver]]\nport = "/dev/a"\nlever_arm_m = [30.0, 0.0]\n', "#1 lever_arm_m"),
    ('[[gnss.receiver]]\nport = "/dev/a"\ndelay_s = 9.0\n', "#1 delay_s = 9.0 is out of range"),
    ('[[gnss.receiver]]\nport = "/dev/a"\nbaud = 9600\n', "did you mean 'baudrate'"),
    ('[gnss]\nreceiver = 3\n', "list of [[gnss.receiver]] tables"),
])
def test_bad_receiver_lists_are_refused_in_one_line(text, message):
    with pytest.raises(ConfigError, match=None) as e:
        _load(text)
    assert message in str(e.value) and "\n" not in str(e.value)
