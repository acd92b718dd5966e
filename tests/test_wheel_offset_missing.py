"""A wheel-speed offset missing from the config is not learned as a wheel radius and published
valid while wrong (issue 7, wofs27).

Before (integ27 7d93778; tools/probe_wrong_config.py ``wheel_offset_missing``: our DBC's wheel
speeds carry offset -10.016 m/s, a mapping that forgets it reads v + 10.016): on the flying start
flying_30_r150l_h100 WheelScaleSeed saw the wheels read 1.32x GNSS at a steady 30 m/s and
re-seeded the wheel scale to 0.755; when the speed fell to 24 m/s the offset showed (0.755 x 34 =
25.7 vs 24): vx valid beyond 3 sigma on 1802 of 5699 rows, worst 1.46 m/s. At one speed a scale
and an offset are the same thing; a scale is one ratio at every speed, an offset is not
(input_consistency.WheelScaleSeed: the re-seed is a hypothesis until fixes across speeds confirm it).
"""
from __future__ import annotations

import pytest

from ecu_daemon.estimator.input_consistency import KWS_OFFSET_MPS, WheelScaleSeed
from ecu_daemon.sim.suite import SUITE

from config_replay import replay_edited, simulated_drive, wrong_valid_rows

WHEELS = ("wheel_speed_fl", "wheel_speed_fr", "wheel_speed_rl", "wheel_speed_rr")
DBC_OFFSET = 10.016  # m/s: our DBC's wheel-speed offset is -10.016; a mapping without it reads v + 10.016


def _feed(seed: WheelScaleSeed, wheels, t0: float, v: float, seconds: float) -> float:
    """Steady 5 Hz fixes at GNSS speed ``v`` with raw wheel speed ``wheels(v)``; the time after."""
    t = t0
    while t < t0 + seconds:
        if seed.observe(t, wheels(v), v, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1e-6, (0.95, 1.05)):
            assert not seed.offset_found
        t += 0.2
    return t


@pytest.mark.parametrize("what", ["scale", "offset"])
def test_a_scale_is_one_ratio_at_every_speed_an_offset_is_not(what):
    """Wheels 1.25x (a scale 0.8) and wheels + 10 m/s look the same at 40 m/s: both re-seed the
    scale to 0.8. At 32 m/s (20 % slower) the scale holds, the offset shows as one of 10 m/s."""
    wheels = (lambda v: v / 0.8) if what == "scale" else (lambda v: v + 10.0)
    seed = WheelScaleSeed()
    t = _feed(seed, wheels, 0.0, 40.0, 15.0)
    assert seed.seeded and seed.scale == pytest.approx(0.8, abs=1e-9)
    assert seed.v_seed == pytest.approx(40.0)
    # before any fix at another speed: what an offset would do at 32 m/s, 8 x (1 - 0.8); exactly
    # the error a pure offset leaves there (0.8 x 42 - 32), so 3 sigma covers it
    assert seed.offset_bound(32.0) == pytest.approx(0.8 * 42.0 - 32.0)
    assert seed.offset_bound(40.0) == pytest.approx(0.0)
    _feed(seed, wheels, t, 32.0, 10.0)
    if what == "scale":
        assert seed.ratio_checked and not seed.offset_found
        assert abs(seed.offset) < KWS_OFFSET_MPS
        assert seed.offset_bound(32.0) == 0.0  # confirmed: the seed's std alone
    else:
        assert seed.offset_found and not seed.ratio_checked
        assert seed.offset == pytest.approx(10.0, abs=0.05)
        assert seed.offset_slope == pytest.approx(1.0, abs=0.01)
        assert "[inputs.wheel_speed_fl/fr/rl/rr] offset" in seed.offset_message()
        assert "+10.00 m/s" in seed.offset_message()


def test_no_verdict_without_a_re_seed_or_speeds_apart():
    """Wheels within the state's bounds are never re-seeded, so never judged; a re-seed seen at one
    speed only stays a hypothesis (its bound published), neither confirmed nor refuted."""
    seed = WheelScaleSeed()
    _feed(seed, lambda v: v * 1.01, 0.0, 30.0, 20.0)
    assert not seed.seeded and seed.offset_bound(20.0) == 0.0
    seed = WheelScaleSeed()
    _feed(seed, lambda v: v + 10.0, 0.0, 40.0, 15.0)
    _feed(seed, lambda v: v + 10.0, 15.0, 38.0, 10.0)  # 5 % apart: a scale and an offset still agree
    assert seed.seeded and not seed.offset_found and not seed.ratio_checked
    assert seed.offset_bound(30.0) > 0.0


@pytest.fixture(scope="module")
def flying(tmp_path_factory):
    case = next(c for c in SUITE if c.name == "flying_30_r150l_h100")
    return simulated_drive(tmp_path_factory, "offset_flying", case.scenario)


def test_a_missing_wheel_speed_offset_is_never_valid_while_wrong(flying):
    """The flying start at 30 m/s, slowing to 24 and back, with the DBC offset missing on every
    wheel: no vx or sideslip row valid beyond 3 sigma, and one warning naming the offset key."""
    def offset(data):
        for n in WHEELS:
            data["inputs"][n].update(offset=DBC_OFFSET)
    lines: list[str] = []
    e, t = replay_edited(flying, offset, "offset_missing", log_level="warning", stderr=lines)
    bad_v, bad_b, share = wrong_valid_rows(e, t)
    assert (bad_v, bad_b) == (0, 0)
    found = [ln for ln in lines if "[inputs.wheel_speed_fl/fr/rl/rr] offset" in ln]
    assert len(found) == 1, lines
    o = float(found[0].split("an offset of ")[1].split(" m/s")[0])
    assert o == pytest.approx(DBC_OFFSET, abs=1.0)
