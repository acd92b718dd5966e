"""The GNSS latency identified on whole simulated drives (simulate -> files -> replay), where the
wheels are a biased clock: issue 7 item 5 asks for the latency within 0.03 s of the truth
whatever the drive.

* ``circle_dry``: a 40 m circle with the speed rising to 0.65 g. The accelerometer's integral
  breaks off mid-corner (the sideslip is not known well enough for its r vy share); with its
  statistics dropped, the wheels (corner-biased) timed the GNSS alone as the circle ended:
  +0.036 s on integ27. The runs' cost profiles are kept (``LatencyEstimator.forget``).
* ``wheel_lag_0.06_grade``: wheel-speed signals through a 0.06 s first-order lag (a delay of
  0.06 s in their clock) on a 10 % grade. Sharp lagged wheels within a broad accelerometer's
  4-sigma set counted as agreeing and pulled the delay to theirs: -0.046 s on integ27. Agreeing
  is mutual now (the wheels must not reject the accelerometer's best either).
"""
from __future__ import annotations

import numpy as np
import pytest

from ecu_daemon import config as config_mod
from ecu_daemon.replay import run_replay
from ecu_daemon.sim import simulate, vehicle_config
from ecu_daemon.sim.suite import SUITE
from ecu_daemon.sim.scenario import SCENARIOS
from ecu_daemon.sim.writer import write_all

TOLERANCE_S = 0.03  # issue 7 item 5


def _scenario(name):
    if name in SCENARIOS:
        return SCENARIOS[name]
    return next(c.scenario for c in SUITE if c.name == name)


@pytest.mark.parametrize("name", ["circle_dry", "wheel_lag_0.06_grade"])
def test_latency_within_issue_7_tolerance_where_the_wheels_are_a_biased_clock(tmp_path, name):
    sc = _scenario(name)
    paths = write_all(tmp_path, simulate(sc, vehicle_config(sc)))
    cfg = config_mod.load(paths["config"])
    run_replay(cfg, str(paths["can"]), str(paths["gnss"]), str(tmp_path / "estimate.csv"))
    est = np.genfromtxt(tmp_path / "estimate.csv", delimiter=",", names=True)
    delay = est["gnss_delay_s"]
    assert np.isfinite(delay[-1])
    assert abs(delay[-1] - sc.gnss.latency_s) <= TOLERANCE_S
    # ... and not only at the end: after the first 30 s of driving it stays there
    t = est["t"] - est["t"][0]
    assert np.max(np.abs(delay[t >= 30.0] - sc.gnss.latency_s)) <= TOLERANCE_S
