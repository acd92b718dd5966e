"""Estimator.advance_to over a gap in its input: skipped, not stepped through; re-initialised after."""
from __future__ import annotations

import logging
import math

from ecu_daemon import config
from ecu_daemon.estimator import Estimator
from ecu_daemon.estimator.estimate import STATUS_RESET
from ecu_daemon.samples import INPUT_INDEX, InputSample

DT = 0.006


def feed(est, t0: float, t1: float, speed: float = 15.0) -> list:
    """Push 100 Hz inputs of a car driving straight from t0 to t1 and step through them."""
    out = []
    n = round((t1 - t0) / 0.01)
    for j in range(n):
        t = t0 + 0.01 * j
        for name in INPUT_INDEX:
            v = speed if name.startswith("wheel") else 0.0
            est.push_input(InputSample(t, INPUT_INDEX[name], v))
        out += est.advance_to(t - 1e-9)
    return out


def launch(est, t0: float, t1: float, speed: float = 15.0, accel: float = 2.0, rest: float = 2.0) -> list:
    """Push 100 Hz inputs of a car at rest for ``rest`` s, then accelerating at ``accel`` up to
    ``speed`` and driving on straight until t1: a launch, on which the accelerometer confirms the
    wheels' scale without GNSS (wheel_launch_check.py)."""
    out = []
    for j in range(round((t1 - t0) / 0.01)):
        t = t0 + 0.01 * j
        moving = max(t - t0 - rest, 0.0)
        v = min(accel * moving, speed)
        a = accel if 0.0 < moving and v < speed else 0.0
        for name in INPUT_INDEX:
            est.push_input(InputSample(t, INPUT_INDEX[name], v if name.startswith("wheel") else
                                       a if name == "accel_x" else 0.0))
        out += est.advance_to(t - 1e-9)
    return out


def test_a_gap_is_skipped_marked_stale_and_the_filter_reinitialised():
    est = Estimator(config.load(None))
    launch(est, 90.0, 100.0)  # (no GNSS) the wheels' scale is confirmed on the launch from rest
    assert est.wheel_scale_check.confirmed and est.wheel_launch.confirmed
    before = feed(est, 100.0, 103.0)
    assert before[-1].velocity_valid and est.gaps == 0
    after = feed(est, 100.0 + 1e7, 100.0 + 1e7 + 3.0)  # a 1e7 s jump: 1.7e9 steps if stepped through
    assert est.gaps == 1
    tail = [e for e in after if e.t < 1e6]  # the step of the samples already queued before the gap
    after = after[len(tail):]
    assert len(tail) <= 1
    t0, t1 = est.last_gap
    assert t0 == (tail or before)[-1].t and math.isclose(t1, 100.0 + 1e7)
    assert after[0].t >= 100.0 + 1e7 - DT  # resumes at the next sample, nothing in between
    assert len(after) < 3.0 / DT + 2
    assert after[0].status & STATUS_RESET  # re-initialised on the first step after the gap
    assert est.resets == 1
    assert after[-1].velocity_valid  # and the filter comes back on the new data (the wheels stay checked)


def test_a_short_outage_is_stepped_through_and_not_a_gap():
    est = Estimator(config.load(None))
    a = feed(est, 100.0, 101.0)
    b = feed(est, 101.5, 102.0)  # 0.5 s without input: < the input timeouts, every step is built
    assert est.gaps == 0
    steps = [round(e.t / DT) for e in a + b]
    assert steps == list(range(steps[0], steps[0] + len(steps)))


def test_a_clock_jump_with_nothing_queued_runs_one_step_not_millions():
    """The live daemon's tick after a clock jump asks for a step far ahead with an empty queue."""
    est = Estimator(config.load(None))
    last = feed(est, 100.0, 101.0)[-1]
    k = round(last.t / DT)
    out = est.advance_to((k + 10_000_000) * DT)
    assert est.gaps == 1 and len(out) <= 2 and round(out[-1].t / DT) == k + 10_000_000
    assert not out[-1].velocity_valid


def test_the_live_daemon_skips_a_clock_jump_and_says_so_once(caplog):
    """The tick thread's view: samples in, ticks on k; then the clock jumps 1e6 steps ahead."""
    from ecu_daemon.daemon import Daemon
    from ecu_daemon.pipeline import Pipeline

    cfg = config.load(None)
    cfg.can.send_outputs = False
    d = Daemon(cfg)
    d.pipeline = Pipeline(cfg, encode=False)
    k0 = 20000
    for j in range(200):
        k = k0 + j
        for name in INPUT_INDEX:
            d.pipeline.push_sample(InputSample(k * DT - 0.002, INPUT_INDEX[name], 15.0 if name.startswith("wheel") else 0.0))
        d._on_tick(k, k * DT)
    assert d.latest is None and d.steps == 200 and d.estimator.gaps == 0
    d._on_tick(k + 1_000_000, (k + 1_000_000) * DT)  # the clock jumped by 6000 s
    assert d.steps <= 202 and d.estimator.gaps == 1
    with caplog.at_level(logging.WARNING, logger="ecu_daemon"):
        d._say_gaps()
        d._say_gaps()
    # (the decoder says the inputs are stale too: these samples did not come through it)
    lines = [r.getMessage() for r in caplog.records if r.name == "ecu_daemon.daemon"]
    assert len(lines) == 1 and "input gap" in lines[0] and "6000" in lines[0] and "re-initialised" in lines[0]
