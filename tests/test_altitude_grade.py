"""Grade from an NMEA receiver's altitude (issue 11): GGA altitude parsing with its own epoch time
(synthetic and real gpsd captures), and ``estimator/altitude_grade.py`` through the road filter on
climbs whose height error follows the simulator's receiver model (Monte Carlo honesty)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from ecu_daemon.estimator.altitude_grade import MAX_GAP_S, AltitudeGrade
from ecu_daemon.estimator.road import ANGLE_STD_VALID, ANGLE_WALK, G, RoadAttitude
from ecu_daemon.gnss import GnssStreamParser, encode
from ecu_daemon.gnss.logfile import raw_capture_bytes
from ecu_daemon.samples import GnssSample
from ecu_daemon.sim.sensors import GnssParams
from test_gnss_captures import GPSD, parse_all

UTC0 = 1717228800.0
DEG = math.pi / 180.0
DT = 0.006


def _epoch(utc: float, alt, quality: int = 1, speed: float = 10.0) -> str:
    return "".join(s + "\r\n" for s in (
        encode.nmea_rmc(utc=utc, lat_deg=48.1, lon_deg=11.5, speed_mps=speed, course_deg=90.0),
        encode.nmea_gga(utc=utc, lat_deg=48.1, lon_deg=11.5, num_sv=10, alt_m=alt, quality=quality)))


# ----------------------------------------------------------------------------------- parsing
def test_gga_altitude_is_parsed_with_its_own_epoch_time():
    p = GnssStreamParser("nmea")
    text = _epoch(UTC0, 500.3) + _epoch(UTC0 + 0.2, 500.7) + _epoch(UTC0 + 0.4, None) + _epoch(UTC0 + 0.6, 501.0, 0)
    out = p.feed(1.0, text.encode()) + p.finish()
    assert [round(s.fix_time_utc_s - UTC0, 3) for s in out] == [0.0, 0.2, 0.4, 0.6]
    assert math.isnan(out[0].alt_m)  # the epoch's GGA comes after its RMC: nothing yet
    # each later sample carries the previous epoch's height, dated by that epoch
    assert out[1].alt_m == pytest.approx(500.3) and out[1].alt_time_utc_s == pytest.approx(UTC0)
    assert out[2].alt_m == pytest.approx(500.7) and out[2].alt_time_utc_s == pytest.approx(UTC0 + 0.2)
    assert math.isnan(out[3].alt_m)  # an empty altitude field
    p2 = GnssStreamParser("nmea")
    after_no_fix = p2.feed(1.0, (_epoch(UTC0, 480.0, 0) + _epoch(UTC0 + 0.2, 480.0)).encode())
    assert math.isnan(after_no_fix[1].alt_m)  # quality 0: the receiver has no position
    p3 = GnssStreamParser("nmea")
    simulated = p3.feed(1.0, (_epoch(UTC0, 695.7, 8) + _epoch(UTC0 + 0.2, 695.7, 8)).encode())
    assert math.isnan(simulated[1].alt_m)  # quality 8: a receiver in simulator mode (Garmin demo logs)


def test_a_bad_altitude_field_drops_only_the_altitude():
    good = encode.nmea_gga(utc=UTC0, lat_deg=48.1, lon_deg=11.5, num_sv=10, alt_m=500.0)
    fields = good[:good.index("*")].split(",")
    fields[9] = "5x0.0"
    body = ",".join(fields)[1:]
    ck = 0
    for ch in body.encode():
        ck ^= ch
    bad = f"${body}*{ck:02X}"
    rmc = encode.nmea_rmc(utc=UTC0 + 0.2, lat_deg=48.1, lon_deg=11.5, speed_mps=10.0, course_deg=90.0)
    samples, parser = parse_all(f"{bad}\r\n{rmc}\r\n".encode(), protocol="nmea")
    assert len(samples) == 1 and samples[0].fix_ok and samples[0].num_sv == 10  # the rest of the GGA is used
    assert math.isnan(samples[0].alt_m)


@pytest.mark.parametrize("name", ["haicom-305N", "ublox-zed-f9p-nmea", "st-teseo-liv4f", "nmea-fuzzy-cases"])
def test_real_captures_give_each_gga_altitude_at_its_epoch(name):
    """Answer key: the GGA sentences' own altitude field, read as text. Every sample's altitude is
    the one its GGA printed, dated by that GGA's time of day."""
    data = raw_capture_bytes(GPSD / f"{name}.log")
    samples, _ = parse_all(data)
    printed = {}
    for line in data.decode("ascii", "replace").splitlines():
        f = line.strip().lstrip("$").split(",")
        if len(f) > 9 and f[0][2:5] == "GGA" and f[9] and f[6] in ("1", "2", "3", "4", "5"):
            hh, mm, ss = int(f[1][0:2]), int(f[1][2:4]), float(f[1][4:])
            printed.setdefault(round((hh * 3600 + mm * 60 + ss) * 1000), float(f[9]))
    with_alt = [s for s in samples if math.isfinite(s.alt_m)]
    assert with_alt, "no sample carries an altitude"
    for s in with_alt:
        tod_ms = round((s.alt_time_utc_s % 86400.0) * 1000)
        assert s.alt_m == pytest.approx(printed[tod_ms], abs=1e-9)
        assert 0.0 <= s.fix_time_utc_s - s.alt_time_utc_s <= 1.5


# ----------------------------------------------------------------------------------- the estimator
def _climb(road: RoadAttitude, grade: float, seconds: float, rng, speed: float = 20.0, rate: float = 5.0,
           params: GnssParams = GnssParams(), jump_at: float | None = None, offset: float = 0.1) -> None:
    """Fixes of a car climbing ``grade``: GGA heights (0.1 m steps) with the simulator's
    Gauss-Markov height error, and the main filter's ``b_ax`` (sensor ``offset`` + gravity, std
    0.01 m/s^2) at every step, which alone cannot split grade from offset."""
    period = 1.0 / rate
    steps = round(period / DT)
    b_ax = offset + G * math.sin(grade)
    a = math.exp(-period / params.pos_tau_s)
    err = rng.standard_normal() * params.alt_noise_m
    prev = None
    for i in range(int(seconds * rate)):
        t = i * period
        err = a * err + rng.standard_normal() * params.alt_noise_m * math.sqrt(1 - a * a)
        h = 500.0 + speed * t * math.tan(grade) + err + (2.0 if jump_at is not None and t >= jump_at else 0.0)
        g = GnssSample(t=t, vel_n_mps=speed, vel_e_mps=0.0, speed_acc_mps=math.nan, fix_type=3, fix_ok=True,
                       fix_time_utc_s=UTC0 + t,
                       alt_m=prev[0] if prev else math.nan, alt_time_utc_s=prev[1] if prev else math.nan)
        for k in range(i * steps, (i + 1) * steps):
            road.step(k, b_ax, 1e-4, 0.0, 1e-4, 0.0)
        road.fuse_altitude(g, speed, True)
        prev = (round(h, 1), UTC0 + t)


def test_altitude_grade_is_honest_over_many_drives():
    """200 climbs of 60 s at 20 m/s: the grade from altitude alone is within 3 sigma in >= 99 % of
    drives, its std is a promise (< 0.5 deg) and not a vast overstatement of the error."""
    rng = np.random.default_rng(7)
    errs, stds = [], []
    for _ in range(200):
        grade = rng.uniform(-0.12, 0.12)
        road = RoadAttitude(DT, 0.1, {})
        _climb(road, grade, 60.0, rng, offset=rng.normal(0.0, 0.1))
        errs.append(road.grade.x[0] - grade)
        stds.append(road.grade.std)
    errs, stds = np.array(errs), np.array(stds)
    assert np.mean(np.abs(errs) <= 3 * stds) >= 0.99
    assert np.all(stds < ANGLE_STD_VALID)
    # not a vast overstatement (the std allows for a grade that wanders; these roads are straight)
    assert np.sqrt(np.mean(errs ** 2)) / np.sqrt(np.mean(stds ** 2)) > 0.3


def test_a_height_jump_is_gated_not_taken_as_a_grade():
    rng = np.random.default_rng(3)
    road = RoadAttitude(DT, 0.1, {})
    _climb(road, 0.05, 60.0, rng, params=GnssParams(alt_noise_m=0.05), jump_at=30.0)
    assert road.altitude_rejected >= 1
    assert road.grade.x[0] == pytest.approx(math.atan(0.05), abs=3 * road.grade.std)


def test_a_gap_in_the_fixes_or_a_reverse_starts_a_new_segment():
    alt = AltitudeGrade(ANGLE_WALK)
    for i in range(6):
        alt.speed(UTC0 + 0.2 * i, 20.0, True)
    assert alt.measure(500.0, UTC0) is None  # the anchor
    assert alt.measure(502.0, UTC0 + 1.0) is not None  # 20 m on: a grade of 2 m in 20 m
    alt.speed(UTC0 + 1.0 + MAX_GAP_S + 0.2, 20.0, True)  # no fix for longer than a receiver's period
    assert alt.measure(502.5, UTC0 + 1.0) is None  # the distance to it is no longer known
    alt = AltitudeGrade(ANGLE_WALK)
    for i in range(6):
        alt.speed(UTC0 + 0.2 * i, 20.0, i < 3)  # reversing from the fourth fix
    assert alt.measure(500.0, UTC0 + 0.6) is None and alt.measure(501.0, UTC0 + 1.0) is None
