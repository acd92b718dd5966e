"""The suite's scenario building blocks: flying starts, reversing, sensor and GNSS faults, config errors."""
from __future__ import annotations

import math

import numpy as np
import pytest

from ecu_daemon.sim import simulate, vehicle_config
from ecu_daemon.sim.scenario import SCENARIOS, T0, Scenario
from ecu_daemon.sim.sensors import Fault, GnssParams, apply_fault, gnss_epochs
from ecu_daemon.sim.suite import SUITE
from ecu_daemon.sim.vehicle import VehicleParams, steady_cornering


def test_fault_kinds_on_known_readings():
    t = T0 + np.arange(10) * 0.1  # 0.0 .. 0.9 s
    v = np.arange(10.0) + 1.0
    rng = np.random.default_rng(0)
    f = lambda kind, value=0.0: apply_fault(Fault("yaw_rate", kind, 0.2, 0.5, value), t, v, T0, rng)  # noqa: E731
    on = slice(2, 7)  # 0.2 <= t < 0.7
    assert list(f("stuck")[on]) == [3.0] * 5 and f("stuck")[7] == 8.0
    assert list(f("stuck", 29.9)[on]) == [29.9] * 5
    assert list(f("zero")[on]) == [0.0] * 5 and f("zero")[1] == 2.0
    assert list(f("offset", 2.0)[on]) == list(v[on] + 2.0)
    assert list(f("scaled", 3.0)[on]) == list(v[on] * 3.0)
    noisy = f("noisy", 1.0)
    assert np.all(noisy[on] != v[on]) and np.array_equal(noisy[:2], v[:2]) and np.array_equal(noisy[7:], v[7:])
    inter = f("intermittent")  # 0 for 0.1 s out of every 0.3 s from the fault's start
    assert list(inter[on]) == [3.0, 4.0, 0.0, 6.0, 7.0]
    with pytest.raises(ValueError, match="unknown sensor fault kind 'bent'"):
        f("bent")


def test_gnss_faults_corrupt_or_drop_solutions_and_mark_them_not_good():
    sc = SCENARIOS["dlc_dry"].with_(duration_s=30.0)
    truth = simulate(sc).truth
    glitch = Fault("gnss", "scaled", 20.0, 5.0, 3.0)
    ok = gnss_epochs(truth, sc.gnss, np.random.default_rng(1))
    bad = gnss_epochs(truth, GnssParams(faults=(glitch,)), np.random.default_rng(1))
    assert len(ok) == len(bad)
    for a, b in zip(ok, bad):
        inside = T0 + 20.0 <= a.t_valid < T0 + 25.0
        assert b.good is not inside
        assert b.vel_n == pytest.approx(a.vel_n * (3.0 if inside else 1.0))
    const = gnss_epochs(truth, GnssParams(faults=(Fault("gnss", "constant", 20.0, 5.0, 140.0),)),
                        np.random.default_rng(1))
    assert {(e.vel_n, e.vel_e) for e in const if not e.good} == {(140.0, 140.0)}
    drop = gnss_epochs(truth, GnssParams(faults=(Fault("gnss", "dropout", 20.0, 5.0),)), np.random.default_rng(1))
    assert len(ok) - len(drop) == 25 and all(e.good for e in drop)


def test_truth_marks_the_good_gnss_rows():
    sc = SCENARIOS["dlc_dry"].with_(duration_s=20.0, gnss_faults=(Fault("gnss", "dropout", 10.0, 5.0),))
    table = simulate(sc).truth_table()
    t, good = table["t"], table["gnss_good"]
    assert good[(t > T0 + 10.5) & (t < T0 + 15.0)].sum() == 0  # receive times lag validity by 0.4 s
    assert good[t < T0 + 10.0].sum() == pytest.approx(48, abs=2)  # 5 Hz from 0.4 s on


@pytest.mark.parametrize("v, radius", [(30.0, 150.0), (10.0, 14.3), (6.0, 9.0)])
def test_flying_start_mid_corner_begins_in_steady_cornering(v, radius):
    sc = Scenario("f", "flying", params=(("v", v), ("radius_m", radius), ("left", True)), duration_s=4.0)
    tr = simulate(sc).truth
    vx, r, vy = tr.col("vx"), tr.col("r"), tr.col("vy")
    assert vx[0] == v and r[0] == pytest.approx(v / radius)
    # the car keeps cornering (the driver's pure pursuit settles on the circle within ~2 s)
    assert np.max(np.abs(r - v / radius)) < 0.45 * v / radius
    assert np.mean(r[-2000:]) == pytest.approx(v / radius, rel=0.1)
    beta = np.arctan2(vy, vx)
    vy0 = steady_cornering(VehicleParams(), v, radius)[0]
    assert math.atan2(vy0, v) == pytest.approx(beta[0])
    assert np.max(np.abs(beta - beta[0])) < math.radians(2.5)
    assert not tr.spin_time


def test_flying_suite_covers_40_degps_and_8_deg_sideslip():
    cases = [c for c in SUITE if c.family == "flying"]
    yaw, beta = [], []
    for c in cases:
        p = dict(c.scenario.params)
        if p["radius_m"]:
            vy, r, _ = steady_cornering(VehicleParams(), p["v"], p["radius_m"])
            yaw.append(math.degrees(r))
            beta.append(math.degrees(math.atan2(vy, p["v"])))
    assert max(yaw) >= 39.0 and max(map(abs, beta)) >= 7.5
    assert {p for c in cases for k, p in c.scenario.params if k == "v"} >= {30.0, 50.0}


def test_reversing_drives_backwards_and_stops():
    tr = simulate(SCENARIOS["straight"].with_(name="rev", manoeuvre="reversing")).truth
    vx, t = tr.col("vx"), tr.t - T0
    assert vx[(t > 33) & (t < 40)] == pytest.approx(-4.0, abs=0.4)
    assert np.all(tr.col("omega_rl")[(t > 33) & (t < 40)] < 0)
    assert vx[-1] == pytest.approx(10.0, abs=0.5) and not tr.spin_time


def test_config_errors_change_the_estimators_config_not_the_car():
    sc = SCENARIOS["slalom_dry"].with_(config_errors=(("mass", 1.3), ("cf", 0.7)))
    ok, wrong = vehicle_config(SCENARIOS["slalom_dry"]), vehicle_config(sc)
    assert wrong.vehicle.mass_kg == pytest.approx(1.3 * ok.vehicle.mass_kg)
    assert wrong.vehicle.cornering_stiffness_front_n_per_rad == pytest.approx(
        0.7 * ok.vehicle.cornering_stiffness_front_n_per_rad, rel=1e-5)
    assert wrong.vehicle.yaw_inertia_kgm2 == ok.vehicle.yaw_inertia_kgm2
    with pytest.raises(ValueError, match="unknown parameter 'mas'"):
        vehicle_config(sc.with_(config_errors=(("mas", 1.3),)))


def test_sensor_fault_reaches_the_can_log():
    sc = SCENARIOS["dlc_dry"].with_(duration_s=25.0, sensor_faults=(Fault("wheels", "zero", 20.0, 2.0),))
    from ecu_daemon.signals import SignalDecoder

    res = simulate(sc)
    dec = SignalDecoder(res.config)
    speeds = [(t, s.value) for t, fid, data in res.can_frames for s in dec.decode(t, fid, data) if s.index == 0]
    during = [v for t, v in speeds if T0 + 20.1 < t < T0 + 21.9]
    before = [v for t, v in speeds if T0 + 18.0 < t < T0 + 19.9]
    assert during and max(map(abs, during)) < 0.02 and min(before) > 15.0
