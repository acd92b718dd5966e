"""The wheel-speed source's slip bound: which wheels slip under which longitudinal force."""
from __future__ import annotations

import pytest

from ecu_daemon.estimator.fusion.wheel_speed import SLIP_PER_MPS2, WheelSpeedFusion


@pytest.mark.parametrize("driven", ["front", "rear"])
def test_undriven_pair_slips_under_braking_only(driven):
    w = WheelSpeedFusion(driven, 1.2, 0.02)
    assert w.slip_bound(40.0, -2.0) == pytest.approx(SLIP_PER_MPS2 * 2.0 * 40.0)
    assert w.slip_bound(40.0, 2.0) == 0.0  # traction acts on the other axle
    assert w.slip_bound(-10.0, -1.0) == pytest.approx(SLIP_PER_MPS2 * 10.0)  # reversing: |vx|


def test_all_wheel_drive_slips_under_traction_too():
    w = WheelSpeedFusion("all", 1.2, 0.02)
    assert w.slip_bound(40.0, 2.0) > 0.0
    assert w.slip_bound(40.0, 2.0) == pytest.approx(w.slip_bound(40.0, -2.0))


def test_slip_bound_grows_with_speed():
    w = WheelSpeedFusion("front", 1.2, 0.02)
    assert w.slip_bound(50.0, -2.0) == pytest.approx(5.0 * w.slip_bound(10.0, -2.0))
