"""Live == replay: the daemon on a ``virtual`` bus fed in real time by a simulated drive (GNSS
written into a pseudo-terminal) sends the output frames that ``ecu-daemon replay`` of its own
recording writes, byte for byte, every frame (EST_DIAG included) of the whole run, and records
the estimates that replay computes, every row.

Both run the same :class:`~ecu_daemon.pipeline.Pipeline`. Live, step k runs ``grace`` after its
time and an input that reaches the tick thread after that is applied at the next step run; a
loaded machine also makes ticks overrun (the missed steps run in the next tick, unsent). The
recording's tick record (``ticks.log``) keeps both, and the host health each tick saw, so the
replay follows the live run exactly; the test runs with the daemon's default 1 ms grace so that
late inputs and overruns do happen on a busy machine (their counts are printed).

Twice: one velocity receiver, and two receivers (front and rear, each on its own pty, the front
one a dual-antenna moving-base pair that also sends the heading), recorded as ``gnss.log`` and
``gnss2.log`` and replayed with two ``--gnss``.
"""
from __future__ import annotations

import asyncio
import math
import os
import threading
import time

import pytest

from ecu_daemon import config as config_mod
from ecu_daemon.cli import main as cli_main
from ecu_daemon.canlog import read_can_log
from ecu_daemon.daemon import Daemon
from ecu_daemon.demo import Feeder, open_gnss_pty
from ecu_daemon.outputs import decode_output_frame
from ecu_daemon.signals import load_dbc

DURATION_S = 10.0
GRACE_S = float(os.environ.get('ECU_TEST_GRACE_S', '0.001'))


def wait_until(cond, timeout=30.0, what="condition"):
    """Poll ``cond`` until true; fail the test after ``timeout`` s (an upper bound, not a window)."""
    end = time.monotonic() + timeout
    while not cond():
        assert time.monotonic() < end, f"timed out after {timeout} s waiting for {what}"
        time.sleep(0.005)


@pytest.fixture(scope="module", params=["one-receiver", "two-receivers"])
def live_run(tmp_path_factory, request):
    from ecu_daemon.sim import SCENARIOS, simulate, vehicle_config
    from ecu_daemon.sim.scenario import GNSS_SETUPS

    two = request.param == "two-receivers"
    tmp = tmp_path_factory.mktemp("live")
    scenario = SCENARIOS["demo"].with_(duration_s=DURATION_S)
    if two:
        scenario = scenario.with_(**GNSS_SETUPS["dual-antenna"], **GNSS_SETUPS["front-rear"])
    cfg = vehicle_config(scenario)
    sim = simulate(scenario, cfg)
    master, port = open_gnss_pty()
    master2 = None
    channel = f"live-replay-{os.getpid()}-{request.param}"
    cfg.can.interface, cfg.can.channel = "virtual", channel
    cfg.gnss.port = port
    if two:
        master2, port2 = open_gnss_pty()
        cfg.gnss.receiver[0].port, cfg.gnss.receiver[1].port = port, port2
    cfg.daemon.state_file = ""
    daemon = Daemon(cfg, bus_config={"interface": "virtual", "channel": channel}, record_dir=tmp / "rec",
                    input_grace_s=GRACE_S)
    feeder = Feeder(sim, channel, master, keep_outputs=True, gnss2_fd=master2)
    errors = []

    def run():
        try:
            asyncio.run(daemon.run())
        except BaseException as e:
            errors.append(e)

    th = threading.Thread(target=run, daemon=True)
    th.start()
    wait_until(lambda: daemon.ready.is_set() or errors, what="daemon ready")
    assert daemon.ready.is_set(), errors
    feeder.start()
    assert feeder.played.wait(DURATION_S + 30), "feeder did not finish"
    # every frame and GNSS byte received, then enough ticks for the last of them to be stepped
    wait_until(lambda: daemon.canio.rx_frames + daemon.canio.rx_ignored >= feeder.frames_sent
               and sum(s.bytes_read for s in daemon.serials) >= feeder.gnss_bytes,
               what="the daemon to receive everything")
    steps = daemon.steps
    wait_until(lambda: daemon.steps > steps + math.ceil(GRACE_S / 0.006) + 2, what="the last inputs stepped")
    daemon.request_stop()
    th.join(20)
    feeder.stop()
    os.close(master)
    if master2 is not None:
        os.close(master2)
    assert not errors and not th.is_alive()
    cfg_path = tmp / "ecu.toml"
    cfg_path.write_text(config_mod.to_toml(cfg))
    return dict(tmp=tmp, cfg=cfg, cfg_path=cfg_path, daemon=daemon, feeder=feeder, sim=sim, two=two)


def frames(path):
    return [(round(t * 1e6), fid, bytes(data)) for t, fid, _, _, data in read_can_log(path)]


def test_replay_of_the_recording_sends_the_live_frames_byte_for_byte(live_run):
    tmp, d = live_run["tmp"], live_run["daemon"]
    rec = tmp / "rec"
    out_can, out_csv = tmp / "replay.log", tmp / "replay.csv"
    gnss = ["--gnss", str(rec / "gnss.log")] + (["--gnss", str(rec / "gnss2.log")] if live_run["two"] else [])
    rc = cli_main(["replay", "--config", str(live_run["cfg_path"]), "--can", str(rec / "can.log"), *gnss,
                   "--out-can", str(out_can), "--out-csv", str(out_csv)])
    assert rc == 0
    if live_run["two"]:  # both receivers and the heading were used live, not only recorded
        est = d.estimator
        assert all(f.fused > 0 for f in est.receivers) and est.heading.fused > 0, \
            ([f.fused for f in est.receivers], est.heading.fused)
        assert d.diag.gnss_heading_state != 0 and d.diag.gnss_heading_baseline_m > 1.0
    live, rep = frames(rec / "outputs.log"), frames(out_can)
    assert d.canio.health.tx_failures == 0  # (a failed send is a frame missing from outputs.log)
    assert len(live) > 0.9 * DURATION_S / 0.006  # several frames per step, most steps sent
    assert {fid for _, fid, _ in live} == {m.frame_id for m in load_dbc(live_run["cfg"].output_dbc_path()).messages}
    first_diff = next((i for i, (a, b) in enumerate(zip(live, rep)) if a != b), None)
    assert first_diff is None, (first_diff, live[first_diff], rep[first_diff])
    assert len(live) == len(rep)
    # the file itself, byte for byte: the replay names the frames with the recording's bus (the
    # daemon's channel), not can0, so `cmp outputs.log replay.log` holds
    assert out_can.read_bytes() == (rec / "outputs.log").read_bytes()
    live_rows = (rec / "estimates.csv").read_text().splitlines()
    rep_rows = out_csv.read_text().splitlines()
    assert live_rows == rep_rows
    ticks = d.tick_stats.snapshot()
    record = (rec / "ticks.log").read_text().splitlines()
    print(f"live vs replay: {len(live)} frames identical over {len(live_rows) - 1} steps"
          f" ({(len(live_rows) - 1) * 0.006:.1f} s), {d.late_samples} inputs applied late,"
          f" {ticks.skipped} steps skipped by overruns, {len(record)} tick records")


def test_output_frames_are_sent_at_their_cycle_times(live_run):
    cfg, d, feeder = live_run["cfg"], live_run["daemon"], live_run["feeder"]
    db = load_dbc(cfg.output_dbc_path(), allow_non_strict=False)
    period_steps = {m.frame_id: round(m.cycle_time / 6) for m in db.messages}
    # what the daemon sent, stamped with the step time (outputs.log)
    stamps = {}
    for line in (live_run["tmp"] / "rec" / "outputs.log").read_text().splitlines():
        ts, _, frame = line.split()
        stamps.setdefault(int(frame.split("#")[0], 16), []).append(round(float(ts[1:-1]) / 0.006))
    assert set(stamps) == set(period_steps)
    ticks = d.tick_stats.snapshot()
    for fid, steps in stamps.items():
        gaps = [b - a for a, b in zip(steps, steps[1:])]
        assert all(g % period_steps[fid] == 0 for g in gaps)  # a late tick skips a slot, never shifts it
        # a slot is left empty only by an overrun, whose catch-up sends just the newest step's frames:
        # every missing frame is a step the tick thread counted as skipped (how many depends on load)
        missing = sum(g // period_steps[fid] - 1 for g in gaps)
        assert missing <= ticks.skipped, (hex(fid), missing, ticks)
        print(f"{hex(fid)}: {len(gaps) - missing} of {len(gaps)} periods on time ({ticks.skipped} steps skipped)")
    # what arrived on the bus: every frame, valid CRC, counters running on
    got = [m for _, m in feeder.outputs if m.arbitration_id in period_steps]
    assert len(got) == d.frames_sent
    last_counter = {}
    for m in got:
        v = decode_output_frame(db, m)  # raises on a bad CRC or length
        prev = last_counter.get(m.arbitration_id)
        if prev is not None:
            assert v["COUNTER"] == (prev + 1) % 16  # one step per frame sent, even after an overrun
        last_counter[m.arbitration_id] = v["COUNTER"]
