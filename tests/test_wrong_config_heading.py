"""Wrong GNSS configurations on a low-speed circle that break the heading promise (issue 7, wrong
configurations; measured by cfg10, not fixed yet): strict xfails, so whoever fixes one sees XPASS.

On lowspeed_r15 (5-10 m/s on a 15 m circle) a single antenna's course differs from the CG's by
``atan(r x_antenna / v)``: an antenna lever arm configured 1.5 m too far forward turns the course
by r * 1.5 / v = 5.9 deg, which the filter puts into the heading (the steady circle cannot tell
heading from a lever arm). A latency prior of 0.8 s for a 0.1 s receiver aligns the heading from a
course 0.7 s older than assumed at the turn-in: 6.6 deg off with a 1.3 deg std."""
from __future__ import annotations

import math
import tomllib

import numpy as np
import pytest
import tomli_w

from ecu_daemon.sim import simulate, vehicle_config
from ecu_daemon.sim.scenario import Scenario
from ecu_daemon.sim.writer import write_all

from config_replay import replay_with

LOW = Scenario("lowspeed_r15", "low_speed", params=(("radius_m", 15.0), ("v_max", 10.0)))  # 75 s


def _heading_rows(d, edit, name):
    data = tomllib.loads((d / "config.toml").read_text())
    edit(data)
    cfg = d / f"{name}.toml"
    cfg.write_text(tomli_w.dumps(data))
    e, t = replay_with(d, cfg)
    psi = np.interp(e["t"], t["t"], np.unwrap(t["heading_rad"]))
    err = np.degrees(np.abs((e["heading_rad"] - psi + math.pi) % (2 * math.pi) - math.pi))
    return e["heading_valid"].astype(bool), err


def _drive(tmp_path_factory, name, sc):
    d = tmp_path_factory.mktemp(name)
    write_all(d, simulate(sc, vehicle_config(sc)))
    return d


@pytest.mark.xfail(strict=True, reason="antenna lever arm 1.5 m off: heading 5.9 deg off while valid "
                                       "(3341 rows on the 75 s drive); nothing checks the lever arm")
def test_gnss_lever_arm_configured_too_far_forward_is_not_promised(tmp_path_factory):
    d = _drive(tmp_path_factory, "lever", LOW)

    def edit(c):
        c["gnss"]["lever_arm_m"] = [c["gnss"]["lever_arm_m"][0] + 1.5, c["gnss"]["lever_arm_m"][1]]
    valid, err = _heading_rows(d, edit, "lever")
    assert not (valid & (err > 5.0)).any(), err[valid].max()


@pytest.mark.xfail(strict=True, reason="latency prior 0.8 s for a 0.1 s receiver: the turn-in's course "
                                       "alignment 6.6-8.7 deg off while valid (286 rows); the prior std "
                                       "0.15 s does not cover a user's 0.7 s error")
def test_latency_prior_far_too_long_is_not_promised(tmp_path_factory):
    d = _drive(tmp_path_factory, "latency", LOW.with_(name="lat01", gnss_latency_s=0.1, duration_s=25.0))

    def edit(c):
        c["gnss"]["delay_s"] = 0.8
        c["gnss"]["max_delay_s"] = max(c["gnss"]["max_delay_s"], 0.8)
    valid, err = _heading_rows(d, edit, "latency")
    assert not (valid & (err > 5.0)).any(), err[valid].max()
