"""An input mapped with the wrong sign (issue 7, wrong configurations): a user's DBC mapping whose
``scale`` has the wrong sign is the commonest configuration error (comma's RAV4 accelerations are
flipped against ISO 8855). The sources check each other (fault_detection.py); this checks that a
flipped source found again stays out, so what is flagged valid stays within its promise.

Measured on the demo drive before the fix: the flipped lateral accelerometer was isolated 0.1-0.3 s
into each turn and let back in on the straight after it (ay ~ r vx ~ 0 agrees at any sign), so each
next turn-in published sideslip up to 2.7 deg off as valid (98.8 % of the valid rows within 3 sigma)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from ecu_daemon.estimator.estimate import STATUS_ACCEL_Y_ISOLATED

from config_replay import replay_edited


def _replay_flipped(d, name):
    def edit(c):
        c["inputs"][name]["scale"] = -c["inputs"][name]["scale"]
    return replay_edited(d, edit, f"flipped_{name}")


@pytest.mark.parametrize("name", ["accel_y", "yaw_rate", "accel_x"])
def test_a_sign_flipped_input_keeps_the_sideslip_and_heading_promise(demo_drive, name):
    e, t = _replay_flipped(demo_drive, name)
    beta = np.interp(e["t"], t["t"], t["sideslip_rad"])
    psi = np.interp(e["t"], t["t"], np.unwrap(t["heading_rad"]))
    for est, truth, valid, std, limit in (
            (e["sideslip_rad"], beta, e["sideslip_valid"], e["sideslip_std_rad"], 2.0),
            (e["heading_rad"], psi, e["heading_valid"], e["heading_std_rad"], 5.0)):
        err = np.abs((est - truth + math.pi) % (2 * math.pi) - math.pi)
        v = valid.astype(bool)
        if v.any():
            assert (err[v] <= 3.0 * std[v]).mean() >= 0.99, name
            assert math.degrees(err[v].max()) < limit, name


def test_a_sign_flipped_lateral_accelerometer_found_twice_stays_isolated(demo_drive):
    """Before: isolated three times (each turn-in), back in after each (each straight)."""
    e, _ = _replay_flipped(demo_drive, "accel_y")
    iso = (e["status"].astype(np.int64) & STATUS_ACCEL_Y_ISOLATED) != 0
    onsets = np.flatnonzero(iso[1:] & ~iso[:-1]) + 1
    assert len(onsets) == 2 and iso[onsets[1]:].all()
