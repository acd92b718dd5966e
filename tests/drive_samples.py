"""A simulated drive's decoded samples in the estimator's input order (tests that feed an
Estimator directly, without the pipeline): CAN through the signal decoder, GNSS through the stream
parser, sorted by time with CAN before GNSS at equal times."""
from __future__ import annotations

from ecu_daemon.gnss.stream import GnssStreamParser
from ecu_daemon.signals import SignalDecoder


def decoded_events(cfg, sim) -> list[tuple]:
    """``(t, kind, sample)`` with kind 0 for an input sample, 1 for a GNSS sample."""
    decoder = SignalDecoder(cfg)
    events = []
    for t, fid, data in sim.can_frames:
        events.extend((t, 0, s) for s in decoder.decode(t, fid, data, fid in sim.extended_ids))
    parser = GnssStreamParser(cfg.gnss.protocol)
    for t, payload in sim.gnss_messages:
        events.extend((s.t, 1, s) for s in parser.feed(t, payload))
    events.extend((s.t, 1, s) for s in parser.finish())
    events.sort(key=lambda e: (e[0], e[1]))
    return events


def scenario_estimates(scenario: str, seconds: float) -> list[str]:
    """A hand-made scenario's first ``seconds`` through a real Estimator, as the replay hands them
    over (``advance_to`` per sample): every estimate's repr (its bits), for the tests that compare
    an implementation with its reference on a whole drive."""
    from ecu_daemon.estimator import Estimator
    from ecu_daemon.sim import SCENARIOS, simulate, vehicle_config

    sc = SCENARIOS[scenario]
    cfg = vehicle_config(sc)
    est = Estimator(cfg)
    out, t0 = [], None
    for t, kind, s in decoded_events(cfg, simulate(sc, cfg)):
        t0 = t if t0 is None else t0
        if t - t0 > seconds:
            break
        (est.push_gnss if kind else est.push_input)(s)
        out.extend(repr(tuple(e)) for e in est.advance_to(t - 1e-6))
    return out
