"""The pipeline alone: the tick record makes a replay hand every input over at the tick the live
run did (late inputs, overrun catch-ups, host health), and the time rule is what a foreign log gets.

A "live" run is played here without threads: ticks on the step grid, the inputs of a stalled
event loop delivered a few steps late, one overrun; everything goes through the real
:class:`~ecu_daemon.io.recorder.Recorder` into files that ``run_replay`` reads back. Twice: one
GNSS receiver, and two (front and rear, the front one a dual-antenna pair sending the heading too),
whose second capture is a log of its own (``gnss2.log``, ``late gnss2 SEQ K`` in the tick record).
"""
from __future__ import annotations

import math

import can
import pytest

from ecu_daemon.canlog import read_can_log
from ecu_daemon.diagnostics import BUS_PASSIVE, HostStatus
from ecu_daemon.estimate_csv import format_row
from ecu_daemon.estimator.latency import LR_REJECT
from ecu_daemon.io.recorder import Recorder
from ecu_daemon.pipeline import Pipeline, TickRecord, stale_validity_mask
from ecu_daemon.replay import run_replay
from ecu_daemon.step_grid import last_step_at, step_of

DT = 0.006
STALLS = ((150, 3), (260, 2), (371, 4))  # (step, steps): the loop delivers that step's inputs late
OVERRUN = (300, 303)  # ticks not run: their steps run in tick 304, unsent


@pytest.fixture(scope="module", params=["one-receiver", "two-receivers"])
def live(tmp_path_factory, request):
    from ecu_daemon.sim import SCENARIOS, simulate, vehicle_config
    from ecu_daemon.sim.scenario import GNSS_SETUPS

    two = request.param == "two-receivers"
    tmp = tmp_path_factory.mktemp("pipeline")
    scenario = SCENARIOS["demo"].with_(duration_s=3.0)
    if two:
        scenario = scenario.with_(**GNSS_SETUPS["dual-antenna"], **GNSS_SETUPS["front-rear"])
    cfg = vehicle_config(scenario)
    sim = simulate(scenario, cfg)
    events = sorted([(t, 0, fid, data) for t, fid, data in sim.can_frames]
                    + [(t, 1, None, payload) for t, payload in sim.gnss_messages]
                    + [(t, 2, None, payload) for t, payload in sim.gnss2_messages], key=lambda e: (e[0], e[1]))
    events = [(float("%.6f" % t), kind, fid, data) for t, kind, fid, data in events]
    k0 = step_of(events[0][0], DT)
    stalls = [(k0 + s, n) for s, n in STALLS]
    if two:  # the loop also stalls over a message of each receiver (GNSS after 1 s: clear of the overrun)
        for kind in (1, 2):
            t = next(e[0] for e in events if e[1] == kind and e[0] > events[0][0] + 1.0)
            stalls.append((step_of(t, DT) - 1, 3))
    overrun = range(k0 + OVERRUN[0], k0 + OVERRUN[1] + 1)

    def arrival(t):
        k = step_of(t, DT)
        for s, n in stalls:
            if s <= k < s + n:
                return s + n
        return k

    rec = Recorder(tmp / "rec", can_channel="vcan0", gnss_port="ttyACM0", extra_gnss_ports=["ttyACM1"] if two else [])
    pl = Pipeline(cfg, gnss_connected=True)
    pl.on_late = lambda source, seq, k: rec.on_tick_record(TickRecord.line("late", source, seq, k))
    pl.on_host = lambda k, h: rec.on_tick_record(TickRecord.line("host", k, *h))
    host = HostStatus(True, 0, 0, 0, 120.5, 800.25, 1500.0, 0, 3.5)
    pl.push_host(host)
    sent, steps = [], []
    i, can_seq, gnss_seq = 0, 0, [0, 0]
    k_end = last_step_at(events[-1][0], DT)
    rec.on_tick_record(TickRecord.line("start", k0))
    last = None
    for k in range(k0, k_end + 1):
        while i < len(events) and arrival(events[i][0]) <= k:
            t, kind, fid, data = events[i]
            i += 1
            if kind == 0:
                rec.on_can(t, can.Message(arbitration_id=fid, data=data, is_extended_id=False))
                pl.push_can(t, fid, data, False, False, can_seq)
                can_seq += 1
            else:
                rx = kind - 1
                rec.on_gnss(t, data, rx)
                pl.push_gnss(t, data, f"ttyACM{rx}", gnss_seq[rx], rx)
                gnss_seq[rx] += 1
        if k in overrun:
            continue
        if last is not None and k > last + 1:
            rec.on_tick_record(TickRecord.line("skip", last + 1, k - 1))
        last = k
        if k == k0 + 200:
            pl.push_host(host._replace(can_bus_state=BUS_PASSIVE, can_error_frames=7, cpu_load_pct=math.pi))
        out = pl.tick(k)
        steps += out
        for m in out[-1].frames:
            rec.on_output(m.timestamp, m)
            sent.append(m)
        rec.on_estimates([st.estimate for st in out])
    rec.on_tick_record(TickRecord.line("end", last))
    rec.close()
    gnss = [str(tmp / "rec" / "gnss.log")] + ([str(tmp / "rec" / "gnss2.log")] if two else [])
    return dict(tmp=tmp, cfg=cfg, pl=pl, sent=sent, steps=steps, rec=tmp / "rec", gnss=gnss, two=two)


def frames(path):
    return [(round(t * 1e6), fid, bytes(data)) for t, fid, _, _, data in read_can_log(path)]


def test_the_live_run_had_late_inputs_and_an_overrun(live):
    record = TickRecord.read(live["rec"] / "ticks.log")
    assert live["pl"].late_items == len(record.late) > 10
    assert record.skipped == [(record.start + OVERRUN[0], record.start + OVERRUN[1])]
    assert len(record.host) == 2
    assert len(live["steps"]) == record.end - record.start + 1  # every step ran, some unsent
    if live["two"]:  # each receiver's late chunks named by their line in its own capture
        assert {"gnss", "gnss2"} <= {source for source, _ in record.late}
        est = live["pl"].estimator
        assert all(f.fused > 0 for f in est.receivers) and est.heading.fused > 0


def test_replay_following_the_tick_record_writes_the_live_frames_and_estimates(live, tmp_path):
    out_can, out_csv = tmp_path / "out.log", tmp_path / "out.csv"
    run_replay(live["cfg"], str(live["rec"] / "can.log"), live["gnss"], str(out_csv),
               str(out_can), ticks_path=str(live["rec"] / "ticks.log"))
    want = [(round(m.timestamp * 1e6), m.arbitration_id, bytes(m.data)) for m in live["sent"]]
    assert frames(out_can) == want == frames(live["rec"] / "outputs.log")
    rows = out_csv.read_text().splitlines()[1:]
    assert rows == [format_row(s.estimate).rstrip("\n") for s in live["steps"]]
    assert rows == (live["rec"] / "estimates.csv").read_text().splitlines()[1:]


def test_the_time_rule_alone_does_not_reproduce_the_live_run(live, tmp_path):
    """Without the tick record the late inputs are applied at their own step: different estimates
    (which is why the recording keeps it)."""
    out_csv = tmp_path / "out.csv"
    run_replay(live["cfg"], str(live["rec"] / "can.log"), live["gnss"], str(out_csv))
    live_rows = {r.split(",")[0]: r for r in (live["rec"] / "estimates.csv").read_text().splitlines()[1:]}
    rows = {r.split(",")[0]: r for r in out_csv.read_text().splitlines()[1:]}
    common = set(live_rows) & set(rows)
    assert len(common) > 0.9 * len(rows)
    assert any(live_rows[t] != rows[t] for t in common)


def test_a_tick_record_round_trips_and_lists_the_ticks(tmp_path):
    p = tmp_path / "ticks.log"
    h = HostStatus(False, 3, 2, 1, 0.1, 1e-300, math.inf, 4, math.nan)
    p.write_text("start 10\n" + TickRecord.line("late", "can", 5, 12) + TickRecord.line("skip", 13, 14)
                 + TickRecord.line("host", 11, *h) + "end 17\n")
    r = TickRecord.read(p)
    assert (r.start, r.end, r.late, r.skipped) == (10, 17, {("can", 5): 12}, [(13, 14)])
    assert r.host[11][:8] == h[:8] and math.isnan(r.host[11].cpu_load_pct)
    assert list(r.ticks()) == [10, 11, 12, 15, 16, 17]
    p.write_text("late can 5\n")
    with pytest.raises(ValueError, match="not a tick record"):
        TickRecord.read(p)


def test_stale_inputs_clear_the_flags_that_depend_on_them():
    assert stale_validity_mask([]) == {}
    assert stale_validity_mask(["yaw_rate"]) == {"sideslip_valid": False, "heading_valid": False,
                                                 "velocity_valid": False, "biases_valid": False}
    assert stale_validity_mask(["wheel_speed_fl"]) == {"velocity_valid": False, "sideslip_valid": False}


def test_a_step_before_the_first_input_publishes_finite_invalid_values(live):
    cfg = live["cfg"]
    pl = Pipeline(cfg)
    (st,) = pl.tick(1000)
    e = st.estimate
    assert not (e.sideslip_valid or e.heading_valid or e.velocity_valid or e.biases_valid)
    assert all(math.isfinite(v) for v in e[:21])
    assert {m.arbitration_id for m in st.frames}  # the frames due at this step go out


def test_steps_of_a_whole_log_is_step_of_of_each_time():
    """The batch replay takes each frame's step from ``steps_of``; it must be the step rule itself,
    including times on a step boundary and a microsecond either side of one."""
    import numpy as np

    from ecu_daemon.step_grid import steps_of

    rng = np.random.default_rng(7)
    k = rng.integers(0, 2_000_000, 20_000)
    t = np.round(np.concatenate([k * DT, k * DT + 1e-6, k * DT - 1e-6, rng.uniform(0, 3e5, 20_000)]), 6)
    assert steps_of(t, DT).tolist() == [step_of(x, DT) for x in t.tolist()]


def _tick_through(cfg, events, arrival):
    """Tick a pipeline over ``events`` ((t, kind, id, data), kind 0 CAN / 1 GNSS), each pushed at
    ``arrival(i, t)`` (its step); returns the pipeline, the late reports and, per tick, the GNSS
    samples fused so far with the step of validity of the newest."""
    pl = Pipeline(cfg, encode=False, gnss_connected=True)
    late = []
    pl.on_late = lambda source, seq, k: late.append((source, seq, k))
    per_tick = []
    i = 0
    order = sorted(range(len(events)), key=lambda j: (arrival(j, events[j][0]), j))
    k0 = step_of(events[0][0], DT)
    seqs = {}
    for k in range(k0, last_step_at(events[-1][0], DT) + 3):
        while i < len(order) and arrival(order[i], events[order[i]][0]) <= k:
            t, kind, fid, data = events[order[i]]
            seq = order[i]  # the event's line in its log
            if kind == 0:
                pl.push_can(t, fid, data, False, False, seq)
            else:
                pl.push_gnss(t, data, "ttyACM0", seq)
            seqs[order[i]] = k
            i += 1
        pl.tick(k)
        est = pl.estimator
        per_tick.append((k, est.receivers[0].fused, est.fix_steps.get(0)))
    return pl, late, per_tick


def _demo_events(duration_s):
    """The demo drive's first seconds as (time, 0 CAN / 1 GNSS, id, payload) in arrival order."""
    from ecu_daemon.sim import SCENARIOS, simulate, vehicle_config

    scenario = SCENARIOS["demo"].with_(duration_s=duration_s)
    cfg = vehicle_config(scenario)
    sim = simulate(scenario, cfg)
    events = sorted([(float("%.6f" % t), 0, fid, data) for t, fid, data in sim.can_frames]
                    + [(float("%.6f" % t), 1, None, p) for t, p in sim.gnss_messages], key=lambda e: (e[0], e[1]))
    return cfg, events


@pytest.fixture(scope="module")
def drive():
    return _demo_events(8.0)


def test_a_late_gnss_sample_is_fused_at_its_time_of_validity(drive):
    """A GNSS message that reaches the tick thread two steps after its step ran is not dropped:
    it is fused, through the history, at the same step of validity as when it came in time."""
    cfg, events = drive
    gnss = [j for j, e in enumerate(events) if e[1] == 1]
    on_time, _, ticks_a = _tick_through(cfg, events, lambda j, t: step_of(t, DT))
    # the last messages, after the estimator initialised and fused some: each one 2 steps late
    late_ones = set(gnss[-8:])
    late_run, late, ticks_b = _tick_through(
        cfg, events, lambda j, t: step_of(t, DT) + (2 if j in late_ones else 0))
    assert sorted(seq for _, seq, _ in late) == sorted(late_ones)
    assert all(source == "gnss" for source, _, _ in late)
    assert all(k == step_of(events[seq][0], DT) + 2 for _, seq, k in late)  # applied at the tick it arrived
    fused_a = on_time.estimator.receivers[0].fused
    assert fused_a > len(late_ones)  # (the late ones are among the fused ones)
    assert late_run.estimator.receivers[0].fused == fused_a
    # the step of validity each message was fused at, in order: the same, late or not
    steps_a = [s for _, _, s in ticks_a if s is not None]
    steps_b = [s for _, _, s in ticks_b if s is not None]
    assert list(dict.fromkeys(steps_b)) == list(dict.fromkeys(steps_a))


def test_a_late_can_frame_is_applied_at_the_next_step_not_dropped(drive):
    """A CAN input that reaches the tick thread after its step ran is taken at the next step run
    (reported to ``on_late``, which the recording keeps) with its own receive time."""
    cfg, events = drive
    j = next(i for i, e in enumerate(events) if e[1] == 0 and e[0] > events[0][0] + 5.0)
    t = events[j][0]
    pl, late, _ = _tick_through(cfg, events[:j + 1], lambda i, ti: step_of(ti, DT) + (1 if i == j else 0))
    assert late == [("can", j, step_of(t, DT) + 1)]
    assert pl.late_items == 1 and pl.earliest_late_t == t
    assert t in pl.estimator.held_t  # its value is held with its own time


@pytest.fixture(scope="module")
def long_drive():
    """The demo's first 40 s, configured with a 0.3 s latency prior for its true 0.4 s: the data must
    move it (the demo's own prior is the truth, which latency.TIMING_INFORMATION now keeps exactly:
    before it, noise moved it to 0.3926 s; from 0.3 it goes to 0.387 s, std 0.016 s)."""
    import dataclasses

    cfg, events = _demo_events(40.0)
    return dataclasses.replace(cfg, gnss=dataclasses.replace(cfg.gnss, delay_s=0.3)), events


def test_a_late_gnss_sample_does_not_lengthen_the_identified_latency(long_drive):
    """Every GNSS message applied 3 steps after it was received: the latency identification measures
    from the receive step, so it learns what it learns on time (before, it took the 18 ms as latency)."""
    cfg, events = long_drive
    on_time, _, _ = _tick_through(cfg, events, lambda j, t: step_of(t, DT))
    late_run, late, _ = _tick_through(
        cfg, events, lambda j, t: step_of(t, DT) + (3 if events[j][1] == 1 else 0))
    assert late  # the messages did arrive late
    a, b = on_time.estimator.latencies[0], late_run.estimator.latencies[0]
    assert a.delay_s != cfg.gnss.delay_s  # the drive taught the identification something
    # the std is the width of the set of grid candidates the data cannot reject: a difference in
    # the last bits (the delay's 1e-5 s here) may move its edge by one candidate, a step of
    # dt / (2 sqrt(LR_REJECT)) = 0.75 ms (0.65 ms once the prior is combined in); a late sample
    # read as latency would be 18 ms
    quantum = 0.5 * DT / math.sqrt(LR_REJECT)
    assert abs(a.delay_s - b.delay_s) < 1e-4, (a.delay_s, b.delay_s)
    assert abs(a.std_s - b.std_s) <= quantum, (a.std_s, b.std_s)
