"""A heading set by GNSS courses at a slide's onset inherits the sideslip's error (issue 7, hdg44: not fixed).

Why (random drive 2271, generator v1: a steady circle on mu 0.22, 2.9 deg of bank, all-wheel drive, 2 Hz
GNSS, spinning out from t 1243 s): one antenna's course is heading less sideslip, so each fused GNSS
velocity splits its residual between the two by their variances. From 1239.6 s, as the car began to
slide, the gyro disagreed with its witnesses and ``Estimator._widen_unverified`` grew P's heading std by
2-3 deg/s (0.44 -> 2.3-2.9 deg by 1243 s: heading invalid, rightly). It grows vy's std by the same angle,
but vy's did not stay grown (0.17 m/s at 1242 s, 0.7 deg of sideslip: inferred, the every-step vy updates
took it back), so from 1243.2 s four fixes (1243.2-1244.7 s) brought the heading's P std down to 0.35 deg
against a sideslip published valid at a 0.42-0.64 deg std and 1.8-5.3 deg off (the true sideslip growing
from 1.8 to 6 deg, the filter's staying at 0.0-0.7 deg): the courses set the heading with the sideslip's
error in it (heading error -1.1 -> -3.1 deg). It then stayed 2-4.3 deg off at a 0.53-0.69 deg std, valid,
until 1247.97 s: 709 valid rows beyond 3 sigma on main d1a0953 (worst 4.31 deg; 715 on this 50 s cut).
The heading's covariance is right about the filter's sideslip; the sideslip's std is not right about the
slide (257 valid sideslip rows beyond 3 sigma on this drive).

Tried (hdg44, /work/wt/_reports/hdg44.md): publishing the heading the fixes moved while the sideslip was
doubted (its std beyond the valid bound) cut these rows only 709 -> 699: the heading was set while the
sideslip was still trusted. The lever is the sideslip's std at the slide's onset (or a heading widening
that the courses cannot take back through a vy the model holds), so this stays a strict xfail until then.
"""
from __future__ import annotations

import pytest
from tools_import import load_tool

SEED = 2271
DURATION_S = 50.0  # to 1250 s: the slide's onset and the 4.3 deg heading, not the spin that follows


@pytest.mark.xfail(strict=True, reason="heading set by courses with a sideslip valid beyond 3 sigma at the "
                                       "slide's onset (issue 7, hdg44: the sideslip's std, not yet fixed)")
def test_heading_set_by_courses_in_a_slide_is_not_promised_beyond_its_std(tmp_path):
    rd = load_tool("random_drives")
    sc = rd.draw(SEED)
    assert not sc.sensors.faults and not sc.gnss.faults and not sc.gnss.dual_antenna
    d = rd.run_drive(SEED, str(tmp_path), DURATION_S)
    assert d["error"] is None, d["error"]
    he = d["figures"]["heading"]
    assert he["valid_rows"] > 3000  # the heading is promised on this drive before the slide
    assert he["beyond_3sigma"] == 0, f"{he['beyond_3sigma']} valid heading rows beyond 3 sigma"
