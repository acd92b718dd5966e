"""A wheel speed beyond the chassis DBC's range is sent saturated and dropped, not refused (issue 7).

Random drives 3170, 3313, 3382, 3420 (generator v1) spin out on low friction and roll on tail
first faster than WHEEL_SPEED_xx reaches (-10.016 m/s): the simulator refused them
(UnencodableValue), so the drives where a spin puts the promise most at risk were never scored.
A real wheel-speed channel saturates at its range; the frame carries the range end and the
decoder's plausibility range (wheel speeds [-5, 120] m/s) drops it as invalid: the estimator is
told "no speed", never a wrong one. A range end the decoder would take as a measurement is still
refused (test_sign_magnitude: the VW wheel speed, a re-scaled lateral acceleration).
"""
from __future__ import annotations

import pytest

from ecu_daemon.config import Config, InputMapping
from ecu_daemon.samples import INPUT_NAMES
from ecu_daemon.signals import SignalDecoder
from ecu_daemon.sim.can_encoder import FrameEncoder, UnencodableValue

WHEELS = ("wheel_speed_fl", "wheel_speed_fr", "wheel_speed_rl", "wheel_speed_rr")


def _wheel_plan(enc: FrameEncoder):
    return next(p for p in enc.plans if p.message.name == "WHEEL_SPEEDS")


def test_a_wheel_faster_backwards_than_the_dbc_reaches_is_sent_as_the_range_end_and_dropped():
    cfg = Config()
    enc, dec = FrameEncoder(cfg), SignalDecoder(cfg)
    plan = _wheel_plan(enc)
    data = enc.encode(plan, dict(zip(WHEELS, (-9.0, -9.5, -20.0, -10.1))))
    raw = plan.message.decode(data, scaling=False)
    assert raw["WHEEL_SPEED_RL"] == 0 and raw["WHEEL_SPEED_RR"] == 0  # the range end: -10.016 m/s
    got = {INPUT_NAMES[s.index]: s.value for s in dec.decode(1.0, plan.frame_id, data)}
    # -9.0 and -9.5 fit the signal but not the plausibility range either: dropped as before
    assert got == {}
    assert all(dec.health[w].errors["range"] == 1 for w in WHEELS)
    # within the range nothing changes: the same bits as before
    ok = enc.encode(plan, dict(zip(WHEELS, (20.0, 20.1, -4.0, 19.9))))
    got = {INPUT_NAMES[s.index]: s.value for s in dec.decode(1.01, plan.frame_id, ok)}
    assert got["wheel_speed_rl"] == pytest.approx(-4.0, abs=0.016)
    assert got["wheel_speed_fr"] == pytest.approx(20.1, abs=0.016)


def test_a_range_end_the_decoder_would_take_as_a_speed_is_still_refused():
    """With no plausibility range the saturated -10.016 would reach the estimator as a measurement
    of a car rolling at -20 m/s: the simulator refuses that drive, as before."""
    cfg = Config()
    m = cfg.inputs["wheel_speed_rr"]
    cfg.inputs["wheel_speed_rr"] = InputMapping(message=m.message, signal=m.signal, counter=m.counter,
                                                checksum=m.checksum)  # min/max: -inf/inf
    enc = FrameEncoder(cfg)
    with pytest.raises(UnencodableValue, match=r"wheel_speed_rr\] -20"):
        enc.encode(_wheel_plan(enc), dict(zip(WHEELS, (1.0, 1.0, 1.0, -20.0))))
