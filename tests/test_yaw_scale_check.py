"""The yaw-rate scale fit (estimator/yaw_scale_check.py) on synthetic course / gyro series."""
import math

import numpy as np
import pytest

from ecu_daemon.estimator.yaw_scale_check import BANK_TILT_SCALE, RESTORE_FLOOR, SCALE_PRIOR, YawScaleCheck

DT = 0.006
STEPS = 17  # ~0.1 s between fixes


def _drive(scale: float, r_of_t, duration: float, bias: float = 0.0, course_noise: float = 0.0, seed: int = 1,
           chk: YawScaleCheck | None = None):
    """A car at 10 m/s with zero sideslip turning at r_of_t(t); the gyro reads (1 + scale) r + bias and
    the filter's bias correction is exact up to ``bias`` (the residual the fit must not read as scale)."""
    rng = np.random.default_rng(seed)
    chk = YawScaleCheck(0.0) if chk is None else chk
    psi = 0.3
    k = 0
    t = 0.0
    while t < duration:
        rs = []
        for _ in range(STEPS):
            k += 1
            t = k * DT
            r_true = r_of_t(t)
            psi -= r_true * DT
            rs.append((1.0 + scale) * r_true + bias)
        course = psi + course_noise * rng.standard_normal()
        chk.observe(t, k, DT, float(np.sum(rs)), course, 0.05, 10.0, 10.0, 0.0, rs[-1], 0.0, 0.02,
                    math.radians(0.01))
    return chk


def _circle_with_speed_changes(t):
    return 0.2 + 0.15 * math.sin(2.0 * math.pi * t / 40.0)


@pytest.mark.parametrize("scale", [-0.03, -0.01, 0.0, 0.01, 0.03])
def test_scale_is_learned_within_its_std_on_a_circle(scale):
    chk = _drive(scale, _circle_with_speed_changes, 90.0, course_noise=math.radians(0.3))
    assert chk.scale_sd < 0.2 * SCALE_PRIOR  # the circle observes it well
    # the fit's scale is the heading's error per radian the gyro integrates: s / (1 + s)
    assert abs(chk.scale - scale / (1.0 + scale)) < 3.0 * chk.scale_sd
    # the published std covers the actual scale error
    assert chk.scale_std() >= abs(scale / (1.0 + scale))


def test_straight_driving_keeps_the_prior():
    chk = _drive(0.03, lambda t: 0.0, 60.0)
    assert chk.scale_std() == pytest.approx(SCALE_PRIOR, rel=1e-3)


def test_a_residual_bias_within_the_filter_std_is_not_read_as_a_scale():
    # 0.01 deg/s residual bias on a steady circle at 0.3 rad/s: would be 0.06 % of scale, inside the std
    chk = _drive(0.0, lambda t: 0.3, 120.0, bias=math.radians(0.01))
    assert abs(chk.scale) < 3.0 * chk.scale_sd
    assert chk.scale_sd < SCALE_PRIOR


def test_floor_is_the_bank_tilt():
    chk = _drive(0.0, _circle_with_speed_changes, 90.0)
    assert chk.scale_std() == pytest.approx(BANK_TILT_SCALE)
    assert 0.0017 < BANK_TILT_SCALE < 0.0019


def test_many_laps_with_a_large_scale_error_do_not_wrap():
    # 3 % over ~30 laps: the gyro's heading is > pi off the course
    chk = _drive(0.03, lambda t: 0.6, 330.0)
    assert abs(chk.scale - 0.03 / 1.03) < 3.0 * chk.scale_sd


# --- the applied scale (core: r = r_m (1 - applied), the fit fed the raw gyro back) ---------------

def _drive_applied(scale: float, r_of_t, duration: float, feed_raw: bool = True, seed: int = 2):
    """As ``_drive``, with the core's loop around the fit: the gyro is corrected by the scale the fit
    resolved (``applied()``) at every step, the corrected rates are stored, and the fit is fed them
    divided by the (1 - applied) of their step (``feed_raw``) or as stored (the feedback loop)."""
    rng = np.random.default_rng(seed)
    chk = YawScaleCheck(0.0)
    psi, k, t = 0.3, 0, 0.0
    trace = []
    while t < duration:
        stored, ring = [], []
        for _ in range(STEPS):
            k += 1
            t = k * DT
            r_true = r_of_t(t)
            psi -= r_true * DT
            a = chk.applied()
            stored.append((1.0 + scale) * r_true * (1.0 - a))
            ring.append(a)
        rs = np.array(stored) / (1.0 - np.array(ring)) if feed_raw else np.array(stored)
        chk.observe(t, k, DT, float(np.sum(rs)), psi + math.radians(0.3) * rng.standard_normal(), 0.05, 10.0, 10.0, 0.0,
                    stored[-1], 0.0, 0.02, math.radians(0.01))
        trace.append((t, chk.scale, chk.scale_sd, chk.applied()))
    return chk, trace


@pytest.mark.parametrize("scale", [-0.03, 0.01, 0.03])
def test_the_applied_scale_does_not_run_away_on_a_long_circle(scale):
    # 10 minutes on a circle (twice the fit's memory): the fit reads the raw gyro, so what it applies
    # tracks the sensor's s / (1 + s) and the residual stays within the published term
    chk, trace = _drive_applied(scale, _circle_with_speed_changes, 600.0)
    truth = scale / (1.0 + scale)
    assert chk.applied() == chk.scale
    for t, s, sd, a in trace:
        if t > 60.0:
            assert abs(s - truth) < 3.0 * sd, (t, s, sd)
            assert a == s  # resolved for good: applied, not toggled
    assert abs(truth - chk.applied()) <= chk.scale_std(chk.applied())
    assert chk.scale_std(chk.applied()) < 0.5 * chk.scale_std(0.0)  # the residual, not the whole scale


def test_feeding_the_corrected_gyro_back_would_learn_only_the_residual():
    # what the raw read-back prevents: fed the corrected rates, the fit sees a fraction of the scale
    # at each moment and the applied scale ends far from the sensor's (the loop the core avoids)
    truth = 0.03 / 1.03
    raw, _ = _drive_applied(0.03, _circle_with_speed_changes, 120.0)
    loop, _ = _drive_applied(0.03, _circle_with_speed_changes, 120.0, feed_raw=False)
    assert abs(raw.applied() - truth) < 3.0 * raw.scale_sd
    assert abs(loop.applied() - truth) > 3.0 * raw.scale_sd


def test_straight_driving_leaves_the_gyro_untouched():
    chk, trace = _drive_applied(0.03, lambda t: 0.0, 120.0)
    assert all(a == 0.0 for _, _, _, a in trace)
    assert chk.scale_std(chk.applied()) == pytest.approx(SCALE_PRIOR, rel=1e-3)


def test_a_restored_scale_is_applied_from_the_start_and_kept_on_straights():
    chk = YawScaleCheck(0.0, prior=(0.0095, 0.0008))
    # the restored information (std at RESTORE_FLOOR) combined with the 0.5 % prior
    assert chk.scale_sd == pytest.approx(1.0 / math.sqrt(1.0 / RESTORE_FLOOR ** 2 + 1.0 / SCALE_PRIOR ** 2))
    assert chk.scale == pytest.approx(0.0095 * (chk.scale_sd / RESTORE_FLOOR) ** 2)
    assert chk.applied() == chk.scale > 0.008
    # ten seconds of straight driving: the restored scale holds (fading only over WINDOW_S)
    rs = np.full(STEPS, 0.0)
    for i in range(1, 100):
        chk.observe(i * STEPS * DT, i * STEPS, DT, float(np.sum(rs)) if i > 1 else None, 0.3, 0.05, 10.0, 10.0, 0.0, 0.0, 0.0,
                    0.02, math.radians(0.01))
    assert chk.scale > 0.0075
    assert chk.applied() == chk.scale


def test_a_restored_scale_is_relearned_when_the_gyro_changed():
    # a restored +1 % on a gyro that now reads -1 % (sensor replaced): the circle overrides the prior
    chk = _drive(-0.01, _circle_with_speed_changes, 90.0, chk=YawScaleCheck(0.0, prior=(0.0099, 0.0008)))
    assert abs(chk.scale - (-0.01 / 0.99)) < 3.0 * chk.scale_sd
    assert chk.r_info == 0.0  # the restored scale was dropped: this drive disagreed with it
    assert max(chk.scale_sd, BANK_TILT_SCALE) >= abs(-0.01 / 0.99 - chk.applied())  # the term covers the rest


def test_the_learned_state_file_carries_the_scale(tmp_path):
    # saved and loaded as the daemon does (estimator key check, JSON file): the restored estimator
    # applies the scale from its first step and saves it again even before a new fix
    from ecu_daemon.config import Config
    from ecu_daemon.estimator.core import LEARNED_VERSION, Estimator
    from ecu_daemon.io.state_store import load_state, save_state

    save_state(tmp_path / "state.json", {"version": LEARNED_VERSION, "yaw_rate_scale": 0.0095,
                                         "yaw_rate_scale_std": 0.0008})
    restored = Estimator._check_learned(load_state(tmp_path / "state.json"))
    assert restored["yaw_rate_scale"] == 0.0095 and restored["yaw_rate_scale_std"] == 0.0008
    est = Estimator(Config(), restored)
    chk = est.yaw_scale_checks[0]
    assert est.yaw_scale_applied == chk.scale > 0.008
    assert est.yaw_scale_std == pytest.approx(chk.scale + chk.scale_sd)  # the whole scale (core: yaw_scale_std)
    assert est._yaw_scale_learned() == {"yaw_rate_scale": chk.scale, "yaw_rate_scale_std": chk.scale_sd}
    # without a file: the gyro as it reads, the prior term, nothing learned to save
    fresh = Estimator(Config(), None)
    assert fresh.yaw_scale_applied == 0.0 and fresh.yaw_scale_std == pytest.approx(SCALE_PRIOR)
    assert fresh._yaw_scale_learned() == {}
    # an implausible file value (10 % and beyond) is not restored
    assert "yaw_rate_scale" not in Estimator._check_learned({"version": LEARNED_VERSION, "yaw_rate_scale": 0.2})


@pytest.mark.parametrize("name", ["gyro_scale_+1pct", "gyro_scale_-1pct", "gyro_scale_+3pct", "gyro_scale_-3pct"])
def test_a_real_gyro_scale_error_is_not_wrong_while_valid(tmp_path, name):
    # end to end (simulate -> files -> replay -> evaluate): the 40 m circle to 0.65 g with the yaw
    # rate x1.01 / x0.99; before the scale was applied (and published on the heading): sideslip
    # within 3 sigma 93 %, up to 3.2 deg off while valid, heading 30-38 %, up to 4.5 deg.
    # +-3 %: heading within 3 sigma 88.8 / 85.4 % on main 2c600ae (1.4-3.1 deg off with a std of
    # 0.4-0.9 deg between 22 and 31 s: the 0.5 % prior shrank the scale to 0.45 +- 0.46 % at 25 s);
    # now the heading std counts the scale over both priors times the rotation since the heading was
    # last constrained, and the wide prior's fit resolves the scale at ~26 s
    from ecu_daemon.sim.suite import SUITE
    from ecu_daemon.suite import run_case

    row = run_case({c.name: c for c in SUITE}[name], tmp_path)
    assert not any(f.startswith("error") for f in row["failed"]), row["failed"]
    assert row["sideslip_coverage_3sigma"] >= 0.99 and row["heading_coverage_3sigma"] >= 0.99
    assert row["sideslip_worst_valid_deg"] < 2.0 and row["heading_worst_valid_deg"] < 5.0
    # not bought by never promising it; +3 %: 0.491 with core.MODEL_TYRE_FORCE (0.5 bar before it, stop 51:
    # the model's tyre force costs the 40 m circle's availability while the scale is unresolved, gyro51)
    assert row["sideslip_valid_above_5mps"] > (0.45 if name == "gyro_scale_+3pct" else 0.5)


# -3 %: 0.631 before core.BRAKE_GRIP, 0.574 with it (integ37, measured with the flag off and on; where
# on the circle it widens the rear law is not diagnosed yet): invalid while right, the price of
# brake_grip's fixes on random drives 239, 301, 637, 504, 507
# With core.MODEL_TYRE_FORCE on (stop 51): +1 % RMS 0.321 -> 0.455 deg and valid 0.943 -> 0.712, -3 % valid
# 0.629 -> 0.500; coverage 1.0 and worst valid 1.34 deg in both: invalid while right on this circle until the
# scale is resolved, the price of the never-seen drives the tyre force fixed (4085, 4147, 4309)
@pytest.mark.parametrize("name,rms_deg,valid", [("gyro_scale_+1pct", 0.5, 0.65), ("gyro_scale_-3pct", 1.2, 0.45)])
def test_the_heading_a_scale_turned_before_it_was_resolved_is_taken_out(tmp_path, name, rms_deg, valid):
    # end to end, the suite's 40 m circle: before the fit resolves the scale (37 / 31 s) the gyro has
    # turned heading and vy together by s x its integral, the direction course cannot see on a
    # circle, and the single-track model alone took tens of seconds to pull it back (on main
    # 531388f: sideslip RMS 0.71 / 1.60 deg, heading 1.6 / 3.6 deg off at the fit's resolution, still
    # 1.1 / 2.6 deg off 25 s later; sideslip valid above 5 m/s 71 / 37 %, held invalid by the whole
    # scale on vy's std). Moved by what it carries of the scale (S x applied, scale_sensitivity.py)
    # when the scale is applied (integ18: realigned to the fit's heading), after which only the
    # residual scale is published.
    from ecu_daemon.sim.suite import SUITE
    from ecu_daemon.suite import run_case

    row = run_case({c.name: c for c in SUITE}[name], tmp_path)
    assert not any(f.startswith("error") for f in row["failed"]), row["failed"]
    assert row["sideslip_rms_deg"] < rms_deg
    assert row["sideslip_coverage_3sigma"] >= 0.99 and row["sideslip_worst_valid_deg"] < 2.0
    assert row["sideslip_valid_above_5mps"] > valid


@pytest.mark.parametrize("scale", [-0.05, -0.03, 0.03, 0.05])
def test_a_scale_beyond_the_calibrated_prior_is_resolved_early_in_a_long_corner(scale):
    # 10 s straight, then a steady circle at 0.25 rad/s: 10 s into it (2.5 rad turned) the data say
    # the scale to ~0.3 %, but the 0.5 % prior alone shrank a 3 % scale to 1.0 +- 0.3 % (main
    # 2c600ae), 6 sigma off, and the core's heading was realigned to that. The data's own scale
    # selects the sensor-tolerance prior (a Bayes factor) and its fit is the scale.
    chk = _drive(scale, lambda t: 0.0 if t < 10.0 else 0.25, 20.0, course_noise=math.radians(0.3))
    true = scale / (1.0 + scale)
    assert abs(chk.scale - true) < 3.0 * chk.scale_sd
    assert chk.applied() and chk.p_wide > 0.9


@pytest.mark.parametrize("scale", [-0.03, 0.02, 0.03, 0.05])
def test_the_heading_scale_covers_a_large_scale_before_it_is_resolved(scale):
    # 3 s into the circle (0.75 rad): the narrow fit still says ~0.25 +- 0.48 %; what the core
    # multiplies the rotation by for the heading std must cover the scale at 3 sigma by 5 s in
    chk = _drive(scale, lambda t: 0.0 if t < 10.0 else 0.25, 15.0, course_noise=math.radians(0.3))
    assert 3.0 * chk.heading_scale() >= abs(scale / (1.0 + scale))
    assert chk.heading_scale() >= chk.scale_std()


@pytest.mark.parametrize("seed", range(6))
def test_an_exact_gyro_never_selects_the_wide_prior(seed):
    # course noise up to 1 deg, steady and varying circles: the wide prior is never selected, and
    # the heading's scale returns to the narrow fit's once the data agree with it
    for r_of_t in (lambda t: 0.0 if t < 10.0 else 0.25, _circle_with_speed_changes):
        for noise in (0.3, 1.0):
            chk = YawScaleCheck(0.0)
            seen = []
            orig = chk._select
            chk._select = lambda s_w, v_w: (orig(s_w, v_w), seen.append(chk.p_wide))
            _drive(0.0, r_of_t, 60.0, course_noise=math.radians(noise), seed=seed, chk=chk)
            assert max(seen) < 0.5
            assert not chk.applied()
            assert chk.heading_scale() < 1.5 * chk.scale_std()


def _drive_step(scale_after: float, t_step: float, r_of_t, duration: float, course_noise: float = 0.0,
                seed: int = 3):
    """As ``_drive`` (no bias), the gyro reading exact until t_step and (1 + scale_after) r from then
    on (a temperature jump, a swapped sensor); returns the check and its scale_std() over time."""
    rng = np.random.default_rng(seed)
    chk = YawScaleCheck(0.0)
    psi = 0.3
    k = 0
    t = 0.0
    trace = []
    while t < duration:
        rs = []
        for _ in range(STEPS):
            k += 1
            t = k * DT
            r_true = r_of_t(t)
            psi -= r_true * DT
            rs.append((1.0 + (scale_after if t >= t_step else 0.0)) * r_true)
        course = psi + course_noise * rng.standard_normal()
        chk.observe(t, k, DT, float(np.sum(rs)), course, 0.05, 10.0, 10.0, 0.0, rs[-1], 0.0, 0.02,
                    math.radians(0.01))
        trace.append((t, chk.scale, chk.scale_std()))
    return chk, trace


@pytest.mark.parametrize("scale_after", [-0.03, 0.02, 0.01])
def test_a_scale_step_mid_drive_is_detected_and_relearned(scale_after):
    # 60 s of an exact gyro (the fit is sure of 0 % within ~0.1 %), then a step. The 300 s window
    # alone holds the old scale: on integ 546e586 the published scale 60 s after a -3 % / +2 % step
    # was still 0.96 / 0.81 % (final fit -0.89 / +1.57 %). The detector forgets it and the refit
    # learns the new one; the fit reads ~10 % low (the bias column takes a part of s r), hence 0.85.
    chk, trace = _drive_step(scale_after, 60.0, _circle_with_speed_changes, 150.0,
                             course_noise=math.radians(0.3))
    true = scale_after / (1.0 + scale_after)
    assert chk.changes >= 1
    assert min(sd for t, _, sd in trace if t > 120.0) >= 0.85 * abs(true)
    assert abs(chk.scale - true) < 0.15 * abs(true)


@pytest.mark.parametrize("scale", [0.0, 0.01, -0.03])
def test_a_constant_scale_does_not_trigger_the_change_detector(scale):
    # 5 minutes of a circle with speed changes and course noise: a constant scale (learned or not)
    # is no change
    chk = _drive(scale, _circle_with_speed_changes, 300.0, course_noise=math.radians(0.3))
    assert chk.changes == 0


_STEP_OPEN = ("issue 7 open: a step early in the drive (fit not yet sure of the old scale) is learned by the fit "
              "itself, but the heading it turned wrong before that is not published; the detector does not fire "
              "in time")


@pytest.mark.parametrize("name,at_s,factor", [
    # since gyro17 (the heading std from the scale over both priors) its heading is covered (100 %,
    # worst valid 2.1 deg), but its sideslip is marginal: within 3 sigma 98.93 % and worst valid
    # 1.97 deg against the 99 % / 2.0 deg asserted, the same bits compiled and pure Python on the
    # developer's machine (xfail) and above 99 % in CI (XPASS); with the road bank walk merged
    # (integ18) 99.77 % within 3 sigma but worst valid 1.967 deg: not strict until that margin is real
    pytest.param("gyro_step_+2pct_at35", 35.0, 1.02,
                 marks=pytest.mark.xfail(strict=False, reason="marginal: sideslip 98.9 % within 3 sigma")),
    pytest.param("gyro_step_-3pct_at45", 45.0, 0.97, marks=pytest.mark.xfail(strict=True, reason=_STEP_OPEN)),
])
def test_a_gyro_scale_step_mid_drive_is_not_wrong_while_valid(tmp_path, name, at_s, factor):
    # end to end: the suite's 40 m circle (circle_dry) with an exact gyro that steps to x1.02 at 35 s
    # / x0.97 at 45 s. On integ 546e586 (the 300 s fit holding the old scale, nothing detecting the
    # step): sideslip within 3 sigma 87.9 / 83.2 %, heading 91.4 / 81.3 %, worst valid 2.95 / 5.31 deg
    # sideslip and 4.02 / 6.20 deg heading.
    from ecu_daemon.sim.sensors import Fault
    from ecu_daemon.sim.suite import SuiteCase, _base
    from ecu_daemon.suite import run_case

    case = SuiteCase(name, "gyro_scale", _base(name, "circle_dry",
                                               sensor_faults=(Fault("yaw_rate", "scaled", at_s, 1e4, factor),)))
    row = run_case(case, tmp_path)
    assert not any(f.startswith("error") for f in row["failed"]), row["failed"]
    assert row["sideslip_coverage_3sigma"] >= 0.99 and row["heading_coverage_3sigma"] >= 0.99
    assert row["sideslip_worst_valid_deg"] < 2.0 and row["heading_worst_valid_deg"] < 5.0


def _fit_state(chk: YawScaleCheck):
    return (chk.scale, chk.scale_sd, chk.p_wide, *chk.wide)


@pytest.mark.parametrize("scale, prior", [(0.03, None), (-0.02, (0.01, 0.002)), (0.0, (0.04, 0.002))])
def test_the_scale_fit_runs_the_compiled_fit_kernels_and_agrees_with_the_reference(scale, prior, monkeypatch):
    """Both solves of a fix (narrow and wide prior) go through the lever-arm checks' ``fit_update``
    (compiled by ``backend.select``: Gauss-Jordan, not LAPACK's bits), which agrees with the
    numpy reference within 1e-9 over a drive with speed changes, course noise, a restored scale
    (kept, or dropped as disagreeing) and the wide prior's selection."""
    from ecu_daemon.estimator import backend, lever_arm_check
    if backend.compiled is None:
        pytest.skip("no compiled kernels")
    runs = {}
    for use_compiled in (False, True):
        with backend.selected(use_compiled):
            calls = []
            solve = lever_arm_check.fit_update
            monkeypatch.setattr(lever_arm_check, "fit_update", lambda *a: calls.append(1) or solve(*a))
            chk = _drive(scale, _circle_with_speed_changes, 120.0, course_noise=0.002, seed=3,
                         chk=YawScaleCheck(0.0, prior))
            monkeypatch.undo()
            runs[use_compiled] = (chk, len(calls))
    (ref, n_ref), (comp, n_comp) = runs[False], runs[True]
    assert n_ref == n_comp >= 2 * comp.n > 500  # two solves a fitted fix
    assert (comp.n, comp.gated, comp.changes, comp.restored) == (ref.n, ref.gated, ref.changes, ref.restored)
    assert np.allclose(_fit_state(comp), _fit_state(ref), rtol=1e-9, atol=0.0)
    # the nuisance columns are poorly conditioned (cond ~1e10: the latency error's takes relative
    # differences of a few 1e-9): compared in units of their stds
    sd = np.sqrt(np.diag(ref.cov))
    assert np.all(np.abs(comp.theta - ref.theta) <= 1e-9 * sd)
    assert np.all(np.abs(comp.cov - ref.cov) <= 1e-9 * np.outer(sd, sd))


# --- a delay still being identified while the car circles (random drives 277, 417) -----------------

def _circle_while_the_delay_moves(pass_delay: bool, trace: list | None = None, true_delay: float = 0.6, d0: float = 0.32,
                                  d1: float = 0.57, duration: float = 40.0, radius: float = 9.8):
    """A car on a 9.8 m circle speeding up from 5 to 6 m/s (r 0.51 -> 0.61 rad/s), exact gyro, no
    sideslip. Its GNSS (8 Hz) is 0.6 s late; each fix is placed at its reception less the delay the
    identification holds then, which moves from a prior 0.28 s short to 0.03 s short over the first
    12 s of the circle (random drive 417: 0.32 -> 0.57 s while circling at 0.56 rad/s). The check is
    told the latency std the estimator claims for the current delay (0.035 s) and, where
    ``pass_delay``, the delay each fix was placed with."""
    chk = YawScaleCheck(0.0)
    n = int(duration / DT)
    t = np.arange(n) * DT
    v = 5.0 + t / duration
    r = np.where(t > 4.0, v / radius, 0.0)  # a straight, then the circle
    psi = 0.3 - np.cumsum(r) * DT  # clockwise heading
    k_last = -1
    trace = [] if trace is None else trace
    every = int(round(0.125 / DT))
    lag = int(round(true_delay / DT))
    for k_rx in range(lag + every, n, every):
        d = d0 + (d1 - d0) * min(max((k_rx * DT - 5.0) / 6.0, 0.0), 1.0)
        s = int(round(k_rx - d / DT))  # the step the fix is placed at
        j = k_rx - lag  # the fix's true instant
        course = psi[j]
        r_sum = float(np.sum(r[k_last + 1:s + 1])) if k_last >= 0 else None
        chk.observe(s * DT, s, DT, r_sum, course, 0.03, v[s], v[s], 0.0, r[s], 0.0, 0.035,
                    math.radians(0.01), 0.0, d if pass_delay else None)
        k_last = s
        trace.append((s * DT, chk.scale, chk.scale_sd, chk.applied()))
    return chk


def test_a_delay_moving_during_a_circle_is_not_read_as_a_scale():
    """The fixes' latency error is that of the delay each was placed with; rebased on the current
    delay (lever_arm_check.rebase_latency) they share one, and the fit never applies a scale to an
    exact gyro."""
    trace = []
    chk = _circle_while_the_delay_moves(True, trace)
    assert all(applied == 0.0 for _, _, _, applied in trace)
    assert max(abs(scale) for _, scale, _, _ in trace) < 0.01  # the old fit: 3.5 %
    assert chk.scale_sd < 0.2 * SCALE_PRIOR and abs(chk.scale) < 3.0 * chk.scale_sd
    assert chk.changes == 0  # nor a scale change
    # the control: the same courses taken as placed with one delay read its change (r x 0.25 s, 8 deg
    # over the circle's first 3 rad) as a scale of -2.7 to -3.5 %, applied (review35's behaviour:
    # -2.8 % applied on random drive 417, the heading moved 5.5 deg)
    trace = []
    _circle_while_the_delay_moves(False, trace)
    assert min(applied for _, _, _, applied in trace) < -0.02
