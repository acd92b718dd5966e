"""One status code per optional aiding source (issue 11), for the EST_DIAG ``AIDING_SOURCES`` page.

The dual-antenna baseline, the roll-rate gyro and the magnetometer each keep their own detailed
state (``gnss_heading.STATE_*``, ``magnetometer.STATE_*``, the roll gyro's counts); a tester on
the bus first wants the same four answers for each: is it used, did the estimator refuse its
last sample, has it gone silent, or does the estimator no longer trust it at all. The code says
which, in the order a reader should care (the worst that applies):

* ``ISOLATED``: the estimator has stopped believing it and the outputs it feeds say so: the
  baseline's heading or the magnetometer rejected by their gates twice in a row or more (the
  published heading is invalid then, see ``Estimator._estimate``); a roll gyro whose learned roll
  gradient no car has (a wrong mapping: the roll is not promised);
* ``TIMED_OUT``: nothing received for longer than its timeout;
* ``REJECTED``: its last sample was refused (receiver flags, accuracy, baseline length, a
  magnetic disturbance, its innovation gate; the roll gyro: disagreed with the suspension model);
* ``USED``: its last sample was fused;
* ``WAITING``: configured, nothing received yet (or the magnetometer still learning its field);
* ``NOT_CONFIGURED``.
"""
from __future__ import annotations

import math

from ..samples import MAG_INPUTS
from .fusion import gnss_heading as hd
from .fusion import magnetometer as mg

NOT_CONFIGURED = 0
WAITING = 1
USED = 2
REJECTED = 3
TIMED_OUT = 4
ISOLATED = 5
NAMES = {NOT_CONFIGURED: "NOT_CONFIGURED", WAITING: "WAITING", USED: "USED", REJECTED: "REJECTED",
         TIMED_OUT: "TIMED_OUT", ISOLATED: "ISOLATED"}
ISOLATING_REJECTS = 2  # gate rejections in a row that make the published heading invalid


def configured(cfg) -> bool:
    """The config names an aiding source this page reports on: a receiver with a dual-antenna
    baseline (its length, its elevation fused, or the heading role), a roll-rate gyro, a
    magnetometer (a car without any sends the EST_DIAG pages it sent before they existed)."""
    return "roll_rate" in cfg.inputs or any(n in cfg.inputs for n in MAG_INPUTS) or baseline_configured(cfg)


def baseline_configured(cfg) -> bool:
    """A receiver is configured with a dual-antenna baseline (a receiver that sends headings
    without one is reported too, from its first heading on)."""
    return any(rx.baseline_m > 0.0 or rx.fuse_baseline_elevation or rx.role == "heading"
               for rx in cfg.gnss.receivers())


def baseline_status(heading, configured: bool, t: float, timeout_s: float) -> int:
    """The dual-antenna baseline (``GnssHeadingFusion``): its headings (NAV-RELPOSNED, HDT, THS).
    Its elevation counts apart (``RoadAttitude.elevation_*``): a float solution still gives a heading."""
    g = heading.last
    if g is None:
        return WAITING if configured else NOT_CONFIGURED
    if heading.consecutive_rejects >= ISOLATING_REJECTS:
        return ISOLATED
    if t - g.t > timeout_s:
        return TIMED_OUT
    return USED if heading.state == hd.STATE_FUSED else REJECTED


def roll_gyro_status(road, configured: bool, last_t: float, t: float, timeout_s: float) -> int:
    """The roll-rate gyro (``road.RollGyro``); ``last_t``: the time of its last good sample."""
    if not configured:
        return NOT_CONFIGURED
    gy = road.gyro
    if gy is None or not math.isfinite(last_t):
        return WAITING
    if not gy.plausible() or road.roll_check.wrong:  # a mapping a car cannot have / its roll against the force
        return ISOLATED
    if t - last_t > timeout_s:
        return TIMED_OUT
    return REJECTED if gy.last_rejected else USED


def mag_status(mag, t: float, timeout_s: float) -> int:
    """The magnetometer (``MagnetometerFusion``; None: not mapped)."""
    if mag is None:
        return NOT_CONFIGURED
    if not math.isfinite(mag.last_t) or mag.state in (mg.STATE_NONE, mg.STATE_LEARNING):
        return TIMED_OUT if math.isfinite(mag.last_t) and t - mag.last_t > timeout_s else WAITING
    if mag.consecutive_rejects >= ISOLATING_REJECTS:
        return ISOLATED
    if t - mag.last_t > timeout_s:
        return TIMED_OUT
    return USED if mag.state == mg.STATE_FUSED else REJECTED
