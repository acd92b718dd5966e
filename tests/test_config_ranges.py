"""Every number in the config has a range; a value outside it is one line naming key, value, range."""
from __future__ import annotations

import dataclasses
import math
import subprocess
import sys

import pytest

from ecu_daemon import config as config_mod
from ecu_daemon.config import RANGES, ConfigError


def test_every_number_in_the_config_has_a_range():
    cfg = config_mod.Config()
    for section in ("can", "gnss", "vehicle", "estimator", "daemon"):
        for f in dataclasses.fields(getattr(cfg, section)):
            v = getattr(getattr(cfg, section), f.name)
            if isinstance(v, (int, float)) and not isinstance(v, bool):
                assert (section, f.name) in RANGES, f"[{section}] {f.name} has no range"
    for f in dataclasses.fields(config_mod.InputMapping):
        if f.type in ("float", "int") and f.name not in ("min", "max"):  # min/max: any order-able pair
            assert ("inputs", f.name) in RANGES, f"[inputs.*] {f.name} has no range"


@pytest.mark.parametrize("doc, key, shown", [
    ({"vehicle": {"mass_kg": 1e308}}, "[vehicle] mass_kg", "1e+308"),
    ({"estimator": {"dt_s": 1e-320}}, "[estimator] dt_s", "1e-320"),
    ({"estimator": {"dt_s": 0.0001}}, "[estimator] dt_s", "0.0001"),  # the replay would crawl
    ({"gnss": {"max_delay_s": 1e20}}, "[gnss] max_delay_s", "1e+20"),  # a 99 GiB ring buffer
    ({"estimator": {"accel_noise_mps2": math.inf}}, "[estimator] accel_noise_mps2", "inf"),
    ({"estimator": {"yaw_rate_bias_walk": 1e308}}, "[estimator] yaw_rate_bias_walk", "1e+308"),
    ({"estimator": {"wheel_speed_noise_mps": math.nan}}, "[estimator] wheel_speed_noise_mps", "nan"),
    ({"gnss": {"lever_arm_m": [math.inf, 0.0]}}, "[gnss] lever_arm_m", "inf"),
    ({"gnss": {"baudrate": 0}}, "[gnss] baudrate", "0"),
    ({"inputs": {"yaw_rate": {"message": "IMU", "signal": "YAW_RATE", "scale": math.inf}}},
     "[inputs.yaw_rate] scale", "inf"),
    ({"inputs": {"yaw_rate": {"message": "IMU", "signal": "YAW_RATE", "offset": -math.inf}}},
     "[inputs.yaw_rate] offset", "-inf"),
    ({"inputs": {"yaw_rate": {"message": "IMU", "signal": "YAW_RATE", "scale": 1e-300}}},
     "[inputs.yaw_rate] scale", "1e-300"),
    ({"inputs": {"yaw_rate": {"message": "IMU", "signal": "YAW_RATE", "min": math.nan}}},
     "[inputs.yaw_rate] min", "nan"),
    ({"vehicle": {"steering_ratio": 0.0}}, "[vehicle] steering_ratio", "0.0"),
    ({"daemon": {"realtime_priority": 1000}}, "[daemon] realtime_priority", "1000"),
])
def test_a_number_out_of_range_is_one_line_naming_key_value_and_range(doc, key, shown):
    with pytest.raises(ConfigError) as e:
        config_mod.from_dict(doc)
    text = str(e.value)
    assert "\n" not in text and text.startswith(key) and shown in text, text
    assert "allowed" in text or "below max" in text, text


def test_extremes_of_every_range_are_accepted_and_build_an_estimator():
    from ecu_daemon.estimator import Estimator

    for pick in (0, 1):
        doc: dict = {}
        for (section, key), (lo, hi, _) in RANGES.items():
            if section != "inputs" and not (section, key) == ("vehicle", "steering_ratio"):
                doc.setdefault(section, {})[key] = (lo, hi)[pick]
        Estimator(config_mod.from_dict(doc))


def test_cli_refuses_an_out_of_range_config_with_one_line(tmp_path):
    p = tmp_path / "c.toml"
    p.write_text("[estimator]\ndt_s = 1e-9\n")
    r = subprocess.run([sys.executable, "-m", "ecu_daemon", "show-config", "--config", str(p)],
                       capture_output=True, text=True)
    assert r.returncode == 2 and "Traceback" not in r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "[estimator] dt_s = 1e-09 is out of range: allowed 0.001 to 0.1 s" in lines[0]
