"""Per-drive cornering stiffness (estimator/fusion/stiffness_regression.py) on simulated drives.

Each drive is the real simulator's (Magic Formula tyres, load transfer, roll, noisy biased sensors,
delayed GNSS) with the tyres' stiffness scaled away from the nominal car, replayed with the nominal
config, as a fleet's drives are: what ``fleet calibrate`` combines must be near the truth and its
std must say how near.
"""
from __future__ import annotations

import math

import pytest

from ecu_daemon.fleet.job import learned_parameters
from ecu_daemon.fleet.simfleet import MANOEUVRES, NOMINAL_LATENCY_S, drive_scenario
from ecu_daemon.replay import run_replay
from ecu_daemon.sim import writer
from ecu_daemon.sim.run import simulate, vehicle_config
from ecu_daemon.sim.scenario import get

TRUTH = {"gnss_latency_s": 0.2, "wheel_scale": 1.01, "cf_factor": 0.85, "cr_factor": 1.2,
         "steering_offset_rad": math.radians(2.0), "yaw_rate_bias_radps": math.radians(0.4)}
KEYS = ("cornering_stiffness_front_n_per_rad", "cornering_stiffness_rear_n_per_rad")
REAR = KEYS[1]


def _learned(tmp_path, manoeuvre: str) -> tuple[dict, dict]:
    """(learned parameters, true stiffness) of one drive of that manoeuvre."""
    sc = drive_scenario(TRUTH, MANOEUVRES.index(manoeuvre), 0, seed=3, duration_s=None)
    result = simulate(sc, vehicle_config(sc))
    writer.write_can_log(tmp_path / writer.CAN_LOG, result)
    writer.write_gnss_log(tmp_path / writer.GNSS_LOG, result)
    cfg = vehicle_config(get("demo").with_(gnss_latency_s=NOMINAL_LATENCY_S))  # the nominal car
    summary = run_replay(cfg, str(tmp_path / writer.CAN_LOG), str(tmp_path / writer.GNSS_LOG))
    out = learned_parameters(summary["learned"], summary["learned_std"], cfg)
    return out, dict(zip(KEYS, sc.vehicle.axle_cornering_stiffness()))


@pytest.mark.parametrize("manoeuvre", ["slalom_dry", "dlc_dry"])
def test_transients_learn_the_rear_stiffness_away_from_the_prior_within_its_std(tmp_path, manoeuvre):
    # rear 20 % stiffer than the config: the filter-vy learner stayed at ~1.0x the prior
    out, truth = _learned(tmp_path, manoeuvre)
    assert abs(out[REAR] / truth[REAR] - 1.0) <= 0.10
    # learned: the std is at most half the prior's 50 %, and covers the error
    assert math.isfinite(out[f"{REAR}_std"]) and 0.0 < out[f"{REAR}_std"] <= 0.25 * out[REAR]
    assert abs(out[REAR] - truth[REAR]) <= 3.0 * out[f"{REAR}_std"]


def test_a_steady_circle_leaves_the_rear_stiffness_uncertain(tmp_path):
    # constant lateral force: the slip and a constant heading error look the same; only the speed
    # ramp separates them, so the std must stay large (calibrate then leans on other drives)
    out, truth = _learned(tmp_path, "circle_dry")
    assert out[f"{REAR}_std"] >= 0.1 * out[REAR]
    assert abs(out[REAR] - truth[REAR]) <= 3.0 * out[f"{REAR}_std"]


def test_the_latency_slope_says_how_far_a_latency_error_moves_both_axles(tmp_path):
    # the same double lane change replayed with the latency fixed 0.02 s short and long: the
    # estimate moves by about what its own slope (d kappa / d tau) predicts (measured: front 1.15x,
    # rear 0.7x; a slalom 1.4x / 0.4-0.7x: fleet/calibrate.py counts the slope 50 % uncertain),
    # and by more than its std at an exact latency: what lets the fleet move every drive to the
    # vehicle's combined latency
    sc = drive_scenario(TRUTH, MANOEUVRES.index("dlc_dry"), 0, seed=3, duration_s=None)
    result = simulate(sc, vehicle_config(sc))
    writer.write_can_log(tmp_path / writer.CAN_LOG, result)
    writer.write_gnss_log(tmp_path / writer.GNSS_LOG, result)
    runs = []
    for tau in (TRUTH["gnss_latency_s"] - 0.02, TRUTH["gnss_latency_s"] + 0.02):
        cfg = vehicle_config(get("demo").with_(gnss_latency_s=tau))
        cfg.gnss.estimate_delay = False
        cfg.gnss.delay_monitor = False  # held at tau exactly: the experiment's control, not a user's guess
        s = run_replay(cfg, str(tmp_path / writer.CAN_LOG), str(tmp_path / writer.GNSS_LOG))
        assert s["learned_std"]["kappa_drive_latency_s"] == pytest.approx(tau)
        runs.append(s)
    for k in ("kappa_f_drive", "kappa_r_drive"):
        moved = runs[1]["learned"][k] - runs[0]["learned"][k]
        slope = 0.5 * (runs[0]["learned_std"][f"{k}_per_latency_s"] + runs[1]["learned_std"][f"{k}_per_latency_s"])
        assert abs(moved) > runs[0]["learned_std"][f"{k}_given_latency"]
        assert moved == pytest.approx(slope * 0.04, rel=0.5)
        assert runs[0]["learned_std"][f"{k}_given_latency"] < runs[0]["learned_std"][k]


@pytest.mark.parametrize("manoeuvre", ["slalom_dry", "dlc_dry"])
def test_the_live_model_takes_the_stiffness_and_uncertainty_the_drive_taught(tmp_path, manoeuvre):
    # the single-track pseudo-measurement's own compliance (learned state kappa_r / kappa_r_std):
    # it used to stay within a few % of the config's, 20 % off here, with ~35 % std, so the
    # sideslip it anchors stayed as uncertain as on an unlearned car for the whole drive
    sc = drive_scenario(TRUTH, MANOEUVRES.index(manoeuvre), 0, seed=3, duration_s=None)
    result = simulate(sc, vehicle_config(sc))
    writer.write_can_log(tmp_path / writer.CAN_LOG, result)
    writer.write_gnss_log(tmp_path / writer.GNSS_LOG, result)
    cfg = vehicle_config(get("demo").with_(gnss_latency_s=NOMINAL_LATENCY_S))
    learned = run_replay(cfg, str(tmp_path / writer.CAN_LOG), str(tmp_path / writer.GNSS_LOG))["learned"]
    kappa_true = cfg.vehicle.mass_kg / sc.vehicle.axle_cornering_stiffness()[1]
    prior = cfg.vehicle.mass_kg / cfg.vehicle.cornering_stiffness_rear_n_per_rad
    assert abs(prior / kappa_true - 1.0) > 0.15  # the config is off
    assert abs(learned["kappa_r"] / kappa_true - 1.0) <= 0.10
    assert learned["kappa_r_std"] <= 0.2 * learned["kappa_r"]
    assert abs(learned["kappa_r"] - kappa_true) <= 3.0 * learned["kappa_r_std"]


def _ramped_circle(scale_error: float, consider: bool, seed: int = 1) -> tuple[float, float, float]:
    """One axle's filter on a circle (R 120 m) driven 10 -> 30 m/s in 40 s, fed as ``observe``
    feeds it, with a gyro that reads ``scale_error`` too much: (k1, its std, the true k1)."""
    import numpy as np

    from ecu_daemon.estimator.fusion import stiffness_regression as sr
    rng = np.random.default_rng(seed)
    mass, c_r, lf, lr = 1500.0, 75000.0, 1.2, 1.4
    k_true, tau, dt, steps = mass / c_r, 0.1, 0.005, 20
    ax = sr.AxleFilter(1.3 * k_true, 0.0)
    ax.start_heading(0.0, math.radians(0.5) ** 2, 0.0, 1e-4 ** 2)
    psi_true = 0.0
    for i in range(400):
        vx = 10.0 + 0.05 * i
        r = vx / 120.0
        ay = vx * r
        psi_true -= r * steps * dt
        ax.propagate(r * (1.0 + scale_error) * steps, steps, dt, 5e-4 ** 2 * steps * dt, 2e-5 ** 2 * steps * dt)
        ax.latency(tau, 0.01)
        if consider:
            ax.scale_std(0.005)
        phi = -vx * lf * ay / (lf + lr)
        z = k_true * phi + vx * (ax.psi - psi_true) + 0.05 * rng.normal() - ay * tau
        model_var = (0.1 * ax.x[0] * phi) ** 2
        ax.update(z, np.array([phi, phi * (ay / 9.81) ** 2, vx, 0.0, -ay, 0.0]), 0.05 ** 2 + model_var, model_var)
    return float(ax.x[0]), ax.k1_std(), k_true


@pytest.mark.parametrize("scale_error", [0.004, -0.004])
def test_a_gyro_scale_error_on_a_ramped_circle_is_inside_the_claimed_std(scale_error):
    # The heading ramp a scale error turns in (s x angle turned, ~ vx^2..vx^3 on a circle driven
    # faster) grows like the slip (phi ~ vx^3): no residual shows it. As a white random walk only, the
    # estimate sat 4-5 claimed sigma off (never-seen drive 2946: the live model took it, sideslip
    # 1.6 deg off); considered (CONSIDER_GYRO_SCALE) its std says how far it can be.
    k, std, k_true = _ramped_circle(scale_error, consider=False)
    assert abs(k - k_true) > 3.0 * std  # the mechanism: overconfident without it
    k, std, k_true = _ramped_circle(scale_error, consider=True)
    assert abs(k - k_true) <= 2.0 * std
    assert std >= 0.2 * k_true  # a circle alone does not teach the stiffness to the live model's gate


def _straight_then_corner(corner: bool, seed: int = 2) -> tuple[float, float, float, float]:
    """One rear-axle filter fed as ``observe`` feeds it: 30 fixes on a straight (phi 0: nothing
    about k1) whose GNSS noise is a quarter of what the noise model says (NIS ~ 0.06, as never-seen
    drive 3974's straight gave), then, if ``corner``, 200 fixes of a 0.4 g corner at 20 m/s that
    do teach k1. (k1, its std, the true k1, the prior's std)."""
    import numpy as np

    from ecu_daemon.estimator.fusion import stiffness_regression as sr
    rng = np.random.default_rng(seed)
    k_true, tau, dt, steps, sigma = 0.015, 0.2, 0.005, 40, 0.05
    ax = sr.AxleFilter(1.4 * k_true, 0.0)
    prior_std = 0.5 * 1.4 * k_true
    ax.start_heading(0.0, math.radians(0.5) ** 2, 0.0, 1e-4 ** 2)
    psi_true = 0.0
    for i in range(230 if corner else 30):
        vx, ay = (8.0, 0.0) if i < 30 else (20.0, 0.4 * 9.81)
        r = ay / vx
        psi_true -= r * steps * dt
        ax.propagate(r * steps, steps, dt, 5e-4 ** 2 * steps * dt, 2e-5 ** 2 * steps * dt)
        ax.latency(tau, 0.01)
        phi = -vx * 1.2 * ay / 2.6
        z = k_true * phi + vx * (ax.psi - psi_true) + 0.25 * sigma * rng.normal() - ay * tau
        ax.update(z, np.array([phi, phi * (ay / 9.81) ** 2, vx, 0.0, -ay, 0.0]), sigma ** 2)
    return float(ax.x[0]), ax.k1_std(), k_true, prior_std


def test_fixes_that_say_nothing_of_k1_leave_its_prior_however_small_their_residuals(monkeypatch):
    # Issue 7 (circle49, never-seen 3974): a straight's small residuals scaled k1's untouched prior
    # down to 0.36 of its std, below the live model's take gate (single_track.TAKE_MAX_REL_VAR: half
    # its prior's std), which then went into a circle at 17 % for a k1 43 % off. The residuals' level
    # scales the samples' information, not the prior (SCALE_DATA_ONLY).
    from ecu_daemon.estimator.fusion import stiffness_regression as sr
    monkeypatch.setattr(sr, "SCALE_DATA_ONLY", False)
    _, std, _, prior_std = _straight_then_corner(False)
    assert std < 0.5 * prior_std  # the mechanism: taught by a straight
    monkeypatch.setattr(sr, "SCALE_DATA_ONLY", True)
    k, std, _, prior_std = _straight_then_corner(False)
    assert std >= 0.95 * prior_std
    # a corner teaches it, and the residuals' level still scales what it taught
    k, std, k_true, prior_std = _straight_then_corner(True)
    assert std < 0.25 * prior_std and abs(k - k_true) <= 3.0 * std
    monkeypatch.setattr(sr, "SCALE_DATA_ONLY", False)
    _, std_off, _, _ = _straight_then_corner(True)
    assert std == pytest.approx(std_off, rel=0.3)
