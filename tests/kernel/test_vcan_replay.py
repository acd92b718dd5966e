"""The daemon on a real Linux SocketCAN stack: canplayer -> vcan0 -> ecu-daemon -> vcan0 -> candump.

One UML boot (module fixture) replays a 30 s simulated drive with ``canplayer`` while
``tools/player.py`` feeds the GNSS capture into a pseudo-terminal; ``candump -L`` records the bus and
``cantools decode`` reads it with our output DBC. The tests below read those files on the host.

Timing note: under UML every system call is a ptrace round trip (30-70 us on a virtualised CI host,
measured in the guest), and on a loaded host the whole guest is descheduled for a second or more:
the daemon then runs late, skips output slots and flags inputs stale, as it should. So the
assertions here hold whatever the load: the schedule is never *faster* than the DBC cycle time, the
tick goes on, no frame is lost or corrupted, no decode error is counted. Periods, tick lateness,
stale episodes and live-vs-offline differences are reported; their tight versions are host tests
(tests/test_daemon_replay.py: slot-exact output schedule, live == replay step for step).
"""
from __future__ import annotations

import math
import subprocess
import sys

import cantools
import numpy as np
import pytest

import harness
from conftest import FACTS, TIMINGS

INPUT_IDS = {0x0B0, 0x0B2, 0x0B4}


@pytest.fixture(scope="module")
def run(uml, sim_drive, tmp_path_factory):
    out = tmp_path_factory.mktemp("vcan-replay")
    cfg = harness.guest_config(sim_drive / "config.toml", out / "daemon.toml", str(out / "gnss0"))
    r = harness.run_replay_job(out, drive_dir=sim_drive, config=cfg)
    harness.copy_artifacts(out, "vcan-replay")
    TIMINGS.append(("vcan replay guest (boot + 30 s drive + teardown)", r.boot.seconds))
    assert r.results.get("error") is None, r.explain()
    return r


@pytest.fixture(scope="module")
def out_db():
    return cantools.database.load_file(str(harness.OUTPUT_DBC))


@pytest.fixture(scope="module")
def capture(run):
    return harness.Capture.read(run.out / "bus.log")


def test_daemon_lifecycle_on_socketcan(run):
    res = run.results
    assert res["daemon_ready"], run.explain()
    assert res["canplayer_rc"] == 0, run.explain()
    assert res["daemon_alive_at_end"], run.explain()
    stop = res["daemon_stop"]
    assert stop["returncode"] == 0 and not stop["killed"], f"SIGTERM shutdown: {stop}\n{run.explain()}"
    assert res["stopping_sent"], "no STOPPING=1 on SIGTERM"
    # WATCHDOG_USEC=2 s was offered: pings must come at least every second (half the interval)
    assert res["watchdog_pings"] >= res["playback_s"] / 1.0, res
    log = (run.out / "daemon.log").read_text()
    assert "Traceback" not in log, log[-3000:]
    FACTS.append(f"vcan replay: daemon READY after {res['daemon_ready_s']} s, stopped {stop['seconds']} s after "
                 f"SIGTERM, CPU {res['daemon_cpu_s']} s for {res['playback_s']} s of drive")


def test_every_input_frame_reached_the_bus(run, sim_drive, capture):
    log_frames = sum(1 for ev in harness.player.read_candump(sim_drive / "drive.log")
                     if ev.message.arbitration_id in INPUT_IDS)
    seen = sum(1 for _, m in capture.frames if m.arbitration_id in INPUT_IDS and not m.is_error_frame)
    assert seen == log_frames > 0


def test_outputs_at_their_cycle_times(run, capture, out_db):
    lines = []
    for msg in out_db.messages:
        p = harness.periods_ms(capture, msg.frame_id)
        assert len(p) > 0, f"{msg.name} never sent"
        p50, p99, mx = np.percentile(p, 50), np.percentile(p, 99), p.max()
        slots = run.results["playback_s"] * 1e3 / msg.cycle_time
        lines.append(f"{msg.name} {msg.cycle_time} ms: n={len(p) + 1} of {slots:.0f} slots, p50 {p50:.2f} "
                     f"p99 {p99:.1f} max {mx:.1f}")
        # never more often than its cycle (a late tick skips a slot, never adds one) ...
        assert len(p) + 1 <= 1.02 * slots + 20 and p50 >= 0.85 * msg.cycle_time, lines[-1]
        # ... and the tick goes on through whatever the host does to the guest
        assert len(p) + 1 >= 0.1 * slots, lines[-1]
    FACTS.append("vcan replay output periods (ms): " + "; ".join(lines))


def test_counters_and_crcs(capture, out_db, run):
    report = {}
    for msg in out_db.messages:
        r = harness.integrity(capture, msg)
        report[msg.name] = r
        assert r["bad_crc"] == 0 and r["bad_dlc"] == 0, (msg.name, r)
    # A counter never repeats between frames sent close together (a stale frame resent); a jump
    # means frames the daemon skipped (tick overruns): counted and reported. After a silence of 16+
    # cycles the 4-bit counter may legitimately come round to the same value.
    jumps = sum(r["counter_jumps"] for r in report.values())
    repeats = 0
    for msg in out_db.messages:
        fr = capture.of(msg.frame_id)
        repeats += sum(1 for (ta, a), (tb, b) in zip(fr, fr[1:])
                       if (a.data[1] & 0x0F) == (b.data[1] & 0x0F) and (tb - ta) * 1e3 < 8 * msg.cycle_time)
    assert repeats == 0
    FACTS.append(f"vcan replay: {sum(r['count'] for r in report.values())} output frames, all CRCs good, "
                 f"{jumps} counter jumps (skipped ticks)")


def test_cantools_decode_reads_every_output(run, out_db):
    assert run.results["cantools_rc"] == 0, run.results.get("cantools_stderr")
    text = (run.out / "decoded.txt").read_text()
    for msg in out_db.messages:
        assert f"{msg.name}(" in text, f"{msg.name} not decoded"
    unknown = [ln for ln in text.splitlines() if "Unknown frame id" in ln]
    assert all(int(ln.split("#")[0].split()[-1], 16) in INPUT_IDS for ln in unknown), unknown[:3]


def _diag_values(capture, out_db, t_from: float, t_to: float = math.inf) -> dict:
    """Every value each diagnostics signal took between two capture times, in order (the
    multiplexed pages each carry some of the signals)."""
    diag = out_db.get_message_by_name("EST_DIAG")
    values: dict[str, list] = {}
    for t, m in capture.of(diag.frame_id):
        if t_from <= t <= t_to:
            for k, v in diag.decode(bytes(m.data), decode_choices=False).items():
                values.setdefault(k, []).append(v)
    return values


def test_diagnostics_clean(run, capture, out_db):
    t0 = run.results["playback_start_realtime"] + 3.0  # inputs and GNSS flowing by then
    after = _diag_values(capture, out_db, t0)
    first, last = {k: v[0] for k, v in after.items()}, {k: v[-1] for k, v in after.items()}
    assert last, "no diagnostics frames after playback started"
    grew = {k: (first[k], last[k]) for k in last if k.endswith("_ERRORS") and last[k] != first[k]}
    assert not grew, f"error counters grew during a clean drive: {grew}"
    # a guest descheduled past the input timeout rightly flags inputs stale for a moment: reported
    stale = {k: last[k] - first[k] for k in last if k.endswith("_STALE_COUNT") and last[k] != first[k]}
    FACTS.append(f"vcan replay: stale episodes during the drive (guest descheduled > "
                 f"{harness.GUEST_INPUT_TIMEOUT_S} s): {stale or 'none'}")
    assert last.get("CAN_ERROR_FRAMES", 0) == 0 and last.get("CAN_TX_FAILURES", 0) == 0, last
    assert last.get("GNSS_SERIAL_CONNECTED") == 1, last
    assert last.get("GNSS_FIX_TYPE") == 3, last
    assert last.get("CAN_BUS_STATE") == 0, last
    # every input received fresh through the second half of the drive, not merely "no errors counted".
    # A starved guest runs late (CI once: 39 % of output slots, inputs stale 11 times), so one page
    # may show an input older than the timeout; an input that stopped decoding is old on every page.
    end = run.results["playback_start_realtime"] + run.results["playback_s"]
    values = _diag_values(capture, out_db, t0 + (end - t0) / 2, end)
    age_keys = sorted(k for k in last if k.endswith("_AGE") and k != "GNSS_RX_AGE")
    freshest = {k: min(values.get(k, [math.inf])) for k in age_keys}
    assert len(freshest) == 8 and all(v < 1000 * harness.GUEST_INPUT_TIMEOUT_S for v in freshest.values()), freshest
    rate_keys = sorted(k for k in last if k.endswith("_RATE") and k != "YAW_RATE")
    best_rate = {k: max(values.get(k, [0])) for k in rate_keys}
    assert best_rate and all(v > 50 for v in best_rate.values()), best_rate
    diag = out_db.get_message_by_name("EST_DIAG")
    shown = ("TICK_LATE_P50", "TICK_LATE_P99", "TICK_LATE_MAX", "TICK_OVERRUNS", "CPU_LOAD")
    FACTS.append("vcan replay diagnostics (in UML): " + ", ".join(
        f"{k} {last.get(k)} {diag.get_signal_by_name(k).unit or ''}".strip() for k in shown))


def test_estimates_match_offline_replay(run, sim_drive, capture, out_db, tmp_path):
    """The live estimates on vcan follow ``ecu-daemon replay`` of the same drive.

    Asserted, whatever the host's load: vx with the same sign, unit and scale, well correlated.
    How closely each estimate follows (RMS, median |difference|, against the bounds a quiet host
    meets) is reported: a starved guest runs late. Step-for-step equality is the host's
    tests/test_daemon_replay.py.
    """
    offline = tmp_path / "offline.csv"
    cfg = harness.guest_config(sim_drive / "config.toml", tmp_path / "offline.toml", "none")  # same settings
    r = subprocess.run([sys.executable, "-m", "ecu_daemon", "replay", "--config", str(cfg),
                        "--can", str(sim_drive / "drive.log"), "--gnss", str(sim_drive / "drive_gnss.log"),
                        "--out-csv", str(offline), "--no-progress"],
                       cwd=harness.REPO, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0 and offline.exists(), f"ecu-daemon replay failed: {r.stderr[-2000:]}"
    import csv

    rows = list(csv.DictReader(offline.open()))
    t_off = np.array([float(x["t"]) for x in rows])
    offset = harness.log_time_offset(capture, sim_drive / "drive.log", INPUT_IDS)
    # That offset comes from input frames which canplayer itself plays late under UML by a varying
    # amount; vx changes by up to ~4 m/s^2 in this drive, so 30 ms of clock misalignment alone is
    # 0.12 m/s. Refine the clock offset (not the estimates) on vx within +-0.1 s.
    t_vx, s_vx = harness.decode(capture, out_db.get_message_by_name("EST_VELOCITY"))
    vx_off = np.array([float(x["vx_mps"]) for x in rows])
    ok = (s_vx["VELOCITY_VALID"] == 1) & (t_vx - offset > t_off[0] + 10.0) & (t_vx - offset < t_off[-1] - 0.2)
    lags = np.arange(-0.1, 0.1001, 0.002)
    cost = [np.mean((s_vx["VX"][ok] - np.interp(t_vx[ok] - offset - lag, t_off, vx_off)) ** 2) for lag in lags]
    offset += float(lags[int(np.argmin(cost))])
    checks = {"EST_SIDESLIP": [("SIDESLIP", "sideslip_rad", math.radians(0.5))],
              # vx: under UML hundreds of samples reach the tick after their step (0.03-0.12 m/s
              # RMS seen run to run on a quiet host, up to 1.3 when the loaded host stalled the guest
              # for over a second); the exact live == replay check is on the host,
              # tests/test_daemon_replay.py
              "EST_VELOCITY": [("VX", "vx_mps", 0.2), ("VY", "vy_mps", 0.1)],
              "EST_HEADING": [("HEADING", "heading_rad", math.radians(1.0))]}
    summary = []
    for name, pairs in checks.items():
        msg = out_db.get_message_by_name(name)
        t_live, sig = harness.decode(capture, msg)
        t_log = t_live - offset
        valid_key = [k for k in sig if k.endswith("_VALID")][0]
        keep = (sig[valid_key] == 1) & (t_log > t_off[0] + 10.0) & (t_log < t_off[-1])
        assert keep.sum() > 100, f"{name}: too few valid frames to compare"
        for live_key, col, tol in pairs:
            ref = np.interp(t_log[keep], t_off, np.array([float(x[col]) for x in rows]))
            d = sig[live_key][keep] - ref
            if "HEADING" in live_key:
                d = (d + math.pi) % (2 * math.pi) - math.pi
            rms, med = float(np.sqrt(np.mean(d ** 2))), float(np.median(np.abs(d)))
            if "HEADING" in live_key:  # unwrapped, so that 359 deg vs 1 deg is no outlier
                ref = np.interp(t_log[keep], t_off, np.unwrap([float(x[col]) for x in rows]))
            live_v = ref + d
            slope, _ = np.polyfit(ref, live_v, 1)
            corr = float(np.corrcoef(ref, live_v)[0, 1])
            summary.append(f"{live_key} RMS {rms:.4g} median {med:.4g} slope {slope:.3f} r {corr:.3f}")
            if med >= tol:  # a guest the loaded host held back: estimates late, not wrong (reported)
                FACTS.append(f"vcan replay: {live_key} live vs offline median |difference| {med:.4g} above "
                             f"{tol:.4g}: guest CPU_LOAD / stale episodes above say how starved it was")
            # what load cannot do: flip a sign, change a unit or a scale, decorrelate the quantity.
            # Judged on vx, which spans 10+ m/s over the drive (r 0.998 seen with the host loaded
            # 2.5x over): sideslip, vy and heading move little next to the errors of a guest that
            # runs tens of ms late (r 0.15-0.6 seen; reported)
            if live_key == "VX":
                assert 0.5 < slope < 2.0 and corr > 0.5, f"{live_key}: slope {slope:.3f}, r {corr:.3f} vs offline"
    FACTS.append(f"vcan replay vs offline replay (log-time offset {offset:.3f} s): " + ", ".join(summary))
