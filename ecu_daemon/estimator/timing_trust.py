"""How far a GNSS speed's time of validity may be off, as the along-track weight of a fix sees it.

A fix fused at ``t_rx - delay`` whose receiver's true latency is ``d`` longer reports the speed
of ``d`` earlier: ``v - a d`` (``a``: the acceleration along the track). ``gnss_velocity.py`` adds
that to the fix's noise as ``a^2 std^2`` (weighted as one bias per manoeuvre, ``TIMING_FIXES``),
with ``std`` the latency's 1-sigma. Once the data have identified the latency (``latency.py``'s
std well below its prior) that is evidence. Before, it is only the configuration's claim: the
default prior std (``PRIOR_STD_S``, 0.15 s) whatever ``delay_s`` says. A user who configures
0.1 s for a 0.8 s receiver makes the fixes of the first acceleration (2.2 m/s^2 on dlc) read
1.5 m/s low where the filter allows 0.33 m/s over the whole manoeuvre, and they teach the
wheel-scale state ``k_w`` that the wheels read 5 % high. It ran to its bound, and vx was
published 1.4 m/s off as valid, with the std P gives a scale that GNSS "confirmed", until the
latency was identified (dlc_lat08: 134 rows beyond 3 sigma, 12-20 s); with a fixed delay
(``estimate_delay = false``) the same launch did it before the delay's monitor refuted it.

So until the latency is identified, the along-track timing std is what a receiver's latency
can be off before any evidence: the RMS distance from the delay in use to a latency anywhere in
the receiver's range ``[0, max_delay_s]`` (uniform), never less than ``latency.py``'s own std.
For 0.1 s in a 1.1 s range that is 0.55 s, so the 0.7 s error is 1.3 sigma, not 4.7. It acts
through ``a``: a fix at a steady speed (``a`` ~ 0), the one that measures a tyre's scale, keeps
its full weight; the fixes of an acceleration weigh little until the timing is known, and the
wheels keep vx meanwhile. Across the track an estimated latency keeps ``latency.py``'s std
(heading and sideslip have their own consider / sensitivity terms).

A fixed delay (``estimate_delay = false``) is a claim too, and the data never confirm it: its
monitor (``latency.py`` with ``fixed``) only refutes it, and it needs the acceleration whose
fixes do the harm to do so. Trusted until refuted, a 0.1 s delay for a 0.4 s receiver let the
first acceleration of dlc_dry take the wheel scale 2 % off (333 vx rows valid beyond 3 sigma)
before the refutation came. So its along-track timing term keeps the receiver's range for the
whole drive: k_w learns from the steady fixes. A delay nobody monitors (neither estimated nor
monitored) is used with its own std, as before.

While the monitor refutes a fixed delay, and for the rest of the drive once it has named it
wrong (its warning: a refutation that lasted; a configuration does not change while the daemon
runs), the delay may be off by more than the std it widened to (``latency.py`` caps that at
``PRIOR_STD_S``: 0.15 s for a 0.7 s error). Then the receiver's range is the timing std across
the track and in the published heading std too (:func:`timing_std`): with the along-track change
alone, the courses of a lane change, 0.7 s old and fused as 0.15 s-uncertain, published the
sideslip 1-2 deg off at a std of 0.3 (dlc_lat08: 14 rows beyond 3 sigma, slalom_lat08: 19; 6
left on dlc_lat08 with the warning alone, before it came).
"""
from __future__ import annotations

import math

from .latency import PRIOR_STD_S, LatencyEstimator

#: an estimated latency counts as identified once its std is below this (half the default prior)
IDENTIFIED_STD_S = 0.5 * PRIOR_STD_S

# Two predicates on one latency, on purpose: they answer different questions for different terms.
# ``identified`` is the along-track timing term's: may a speed fix be weighted with latency.py's
# std, i.e. do the data vouch for the delay (std at most half the prior; a fixed delay never: its
# monitor only refutes). Until then the std is the receiver's range (module docstring), because a
# fix's along-track error is what teaches the wheel scale. ``at_prior`` is the timing window's
# (core.Estimator._timing_window: a course's heading slope, the across-track sensitivity): is an
# estimated latency's std still exactly the prior's (nothing learned yet), so that the fix's true
# instant may be anywhere in the receiver's range rather than within 3 of latency.py's sigmas.
# Between the two (an estimated latency whose std has fallen below the prior, not yet to half of
# it) the along-track term keeps the wide std while the window is already +- 3 sigma; a fixed
# delay's window is +- 3 sigma of its std (widened by its monitor when refuted, and timing_std).
# Merging them would move both terms for those latencies: a behaviour change to measure on the
# suite, not a clean-up.


def identified(lat: LatencyEstimator) -> bool:
    """Whether the data (not only the configuration) vouch for ``lat``'s delay (the along-track
    timing term's question, above)."""
    if not lat.enabled:  # neither estimated nor monitored: there will never be evidence
        return True
    if lat.fixed:
        return False
    return lat.std_s <= IDENTIFIED_STD_S


def at_prior(lat: LatencyEstimator) -> bool:
    """Whether ``lat`` is estimated and its std is still the prior's, ``PRIOR_STD_S`` (latency.py
    never lets it exceed that): the data have not narrowed the delay at all yet, and a fix may be
    from anywhere in the receiver's range (the timing window's question, above). A configured
    prior below ``PRIOR_STD_S`` is never "at the prior" here: the user vouched for a tighter one."""
    return lat.enabled and not lat.fixed and lat.std_s >= PRIOR_STD_S


def unconfirmed_std(delay_s: float, max_delay_s: float) -> float:
    """RMS distance (s) from ``delay_s`` to a latency uniform over ``[0, max_delay_s]``."""
    half = 0.5 * max_delay_s
    return math.sqrt((delay_s - half) ** 2 + max_delay_s * max_delay_s / 12.0)


def along_track_std(lat: LatencyEstimator) -> float:
    """The latency std (s) a speed fix's along-track timing term uses (module docstring)."""
    if identified(lat):
        return lat.std_s
    return max(lat.std_s, unconfirmed_std(lat.delay_s, lat.max_steps * lat.dt))


def timing_std(lat: LatencyEstimator) -> float:
    """The latency std (s) of every timing term of a fix (across the track, the published heading's
    share): ``latency.py``'s, or the receiver's range while its monitor refutes a fixed delay and
    once it has named it wrong."""
    if lat.fixed and lat.enabled and (lat.refuted_logged or lat.refuted_run > 0):
        return max(lat.std_s, unconfirmed_std(lat.delay_s, lat.max_steps * lat.dt))
    return lat.std_s
