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
