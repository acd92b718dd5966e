"""A GNSS delay fixed by the user (``[gnss] estimate_delay = false``) that the data refute
(issue 7, wrong configurations): the delay stays as configured, but its std widens so that what
the filter publishes stays within its promise.

Measured on the demo drive (true latency 0.4 s): fixed at 0.3 or 0.5 s, the sideslip was 2.6-2.9
deg off while flagged valid, within 3 published sigma on 78-81 % of the valid rows, because a
fixed delay was taken as good to 0.01 s and its timing error went into the sideslip."""
from __future__ import annotations

import math

import numpy as np
import pytest

from ecu_daemon.estimator.latency import FIXED_STD_S, LatencyEstimator

from config_replay import replay_edited


def _replay_fixed(d, delay_s):
    """(estimate rows, truth rows, the replay's log lines at warning level)."""
    def edit(c):
        c["gnss"]["delay_s"] = delay_s
        c["gnss"]["estimate_delay"] = False
    log: list[str] = []
    e, t = replay_edited(d, edit, f"fixed_{delay_s}", log_level="warning", stderr=log)
    return e, t, log


def _warned(log):
    return [ln for ln in log if "estimate_delay = false" in ln]


@pytest.mark.parametrize("delay_s", [0.3, 0.5])
def test_a_wrong_fixed_delay_keeps_the_sideslip_promise(demo_drive, delay_s):
    e, t, log = _replay_fixed(demo_drive, delay_s)
    assert np.all(e["gnss_delay_s"] == delay_s)  # the user's delay is used as it is
    beta = np.interp(e["t"], t["t"], t["sideslip_rad"])
    err = np.abs(e["sideslip_rad"] - beta)
    valid = e["sideslip_valid"].astype(bool)
    assert valid.sum() > 1000
    assert (err[valid] <= 3.0 * e["sideslip_std_rad"][valid]).mean() >= 0.99
    assert math.degrees(err[valid].max()) < 2.0
    assert len(_warned(log)) == 1 and not any("Traceback" in ln for ln in log), log


def test_the_right_fixed_delay_is_not_widened(demo_drive):
    e, t, log = _replay_fixed(demo_drive, 0.4)
    assert not _warned(log)
    beta = np.interp(e["t"], t["t"], t["sideslip_rad"])
    valid = e["sideslip_valid"].astype(bool)
    assert valid.mean() > 0.8
    assert math.degrees(np.sqrt(np.mean((e["sideslip_rad"] - beta)[valid] ** 2))) < 0.2


def test_a_fixed_delay_never_moves_and_starts_at_the_fixed_std():
    lat = LatencyEstimator(0.006, 0.3, 0.8, fixed=True)
    assert lat.std_s == FIXED_STD_S
    rng = np.random.default_rng(0)
    # a speed that changes, seen 0.4 s late: the candidates' regressor is the speed at each delay
    t = np.arange(0, 60, 0.006)
    v = 15 + 3 * np.sin(0.4 * t)
    for k in range(2000, len(t), 33):  # 5 Hz fixes
        m = np.arange(lat.max_steps + 1)
        x = v[k - 1 - m]
        lat.observe_series(x, v[k - round(0.4 / 0.006)] + 0.02 * rng.standard_normal())
    assert lat.delay_s == 0.3
    assert lat.std_s >= 0.1 / 3  # the 0.1 s the data put it off is inside 3 sigma
