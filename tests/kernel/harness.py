"""Host side of the kernel tests: boot UML jobs, then read what the guest captured.

The guest writes into a host directory (hostfs shares the host's files); everything checked here
is read back from those files: the candump capture, ``cantools decode`` output, the daemon's log,
the sd_notify messages, ``results.json``.
"""
from __future__ import annotations

import json
import os
import shutil
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

from ecu_daemon.config import find_data_file

REPO = Path(__file__).resolve().parents[2]
TOOLS = REPO / "tools"
if str(TOOLS) not in sys.path:
    sys.path.insert(0, str(TOOLS))

import player  # noqa: E402
from uml import boot as uml_boot  # noqa: E402

INPUT_DBC = REPO / "ecu_daemon" / "dbc" / "ecu_daemon_inputs.dbc"
OUTPUT_DBC = REPO / "ecu_daemon" / "dbc" / "ecu_daemon_outputs.dbc"


def python_for_guest() -> str:
    """The interpreter the guest runs: this very one, by the path it was started with.

    The guest sees the host's files, so it runs the same interpreter with the same packages. Not
    ``realpath``: a venv's ``bin/python`` is a symlink to the base interpreter, and only when
    started through the link does Python find the ``pyvenv.cfg`` beside it and so the venv's
    ``site-packages`` (the base interpreter of a fresh machine has none of our packages).
    """
    return os.path.abspath(sys.executable)


# --------------------------------------------------------------------------- running a guest job

@dataclass
class GuestRun:
    out: Path
    results: dict
    boot: uml_boot.BootResult

    def explain(self) -> str:
        parts = [f"results: {json.dumps(self.results)[:1500]}"]
        for name in ("guest-run.log", "daemon.log", "player.log", "canplayer.log"):
            p = self.out / name
            if p.exists():
                parts.append(f"--- {name} (tail)\n" + "\n".join(p.read_text(errors="replace").splitlines()[-25:]))
        parts.append("--- console (tail)\n" + self.boot.console_tail(25))
        return "\n".join(parts)


def run_replay_job(out: Path, *, drive_dir: Path, config: Path, faults: list | None = None,
                   drive_log: Path | None = None, timeout: float = 240.0, daemon_cmd: list | None = None,
                   extra_daemon_env: dict | None = None, capture_filter: str = "0:0") -> GuestRun:
    """Boot the hostfs guest and run ``tools/uml/guest_replay.py`` on a simulated drive."""
    out.mkdir(parents=True, exist_ok=True)
    drive_log = drive_log or drive_dir / "drive.log"
    first = next(player.read_candump(drive_log))
    last_t = first.t
    for ev in player.read_candump(drive_log):
        last_t = ev.t
    py = python_for_guest()
    job = {
        "out": str(out), "repo": str(REPO), "python": py, "channel": "vcan0",
        "drive_log": str(drive_log), "gnss_log": str(drive_dir / "drive_gnss.log"),
        "log_iface": first.source, "epoch": first.t,
        "daemon_cmd": daemon_cmd or [py, "-m", "ecu_daemon", "run", "--config", str(config)],
        "daemon_env": {"WATCHDOG_USEC": "2000000", **(extra_daemon_env or {})},
        # ECU_KERNEL_DAEMON_REPO: run the daemon from another checkout (a fix under test)
        "daemon_cwd": os.environ.get("ECU_KERNEL_DAEMON_REPO", str(REPO)),
        "output_dbc": str(OUTPUT_DBC), "faults": faults or [], "capture_filter": capture_filter,
        "play_timeout": (last_t - first.t) * 2 + 60, "ready_timeout": 120,
    }
    (out / "job.json").write_text(json.dumps(job, indent=1))
    env = {"ECU_UML_OUT": str(out), "ECU_UML_PYTHON": py, "ECU_UML_RUN": str(TOOLS / "uml" / "guest_replay.py"),
           "ECU_UML_JOB": str(out / "job.json")}
    res = uml_boot.boot(str(TOOLS / "uml" / "guest_init.sh"), console=out / "console.log", mem="1024M",
                        timeout=timeout, env=env)
    results = {}
    if (out / "results.json").exists():
        results = json.loads((out / "results.json").read_text())
    run = GuestRun(out, results, res)
    if res.timed_out:
        pytest.fail(f"UML guest hung: killed after {timeout:.0f} s\n{run.explain()}")
    if not results:
        pytest.fail(f"the guest wrote no results (UML exit {res.returncode})\n{run.explain()}")
    return run


#: Input staleness timeout in the guest. Under UML the whole guest shares one ptrace-slow CPU and
#: the daemon can be descheduled for 100+ ms; the default (10 cycles = 100 ms) would then flag
#: inputs stale on a clean drive; 0.5 s still did once on a loaded host. 1 s keeps "stale" meaning
#: "the sensor stopped" (the fault test stops one for 3 s).
GUEST_INPUT_TIMEOUT_S = 1.0


def guest_config(sim_config: Path, dest: Path, gnss_port: str, channel: str = "vcan0",
                 state_file: str = "none") -> Path:
    """The simulator's config with the bus switched to SocketCAN and the GNSS port to our pty."""
    import tomllib

    import tomli_w

    cfg = tomllib.loads(sim_config.read_text())
    cfg.setdefault("can", {}).update(interface="socketcan", channel=channel)
    cfg["can"].pop("bus_kwargs", None)
    for key in ("dbc", "output_dbc"):  # absolute: resolved as the daemon would from the simulator's config
        if key in cfg["can"]:
            cfg["can"][key] = str(find_data_file(cfg["can"][key], sim_config.parent).resolve())
    cfg.setdefault("gnss", {})["port"] = gnss_port
    # Under UML a GNSS message's receive time is when the slow guest got round to the pty (tens of
    # ms of jitter), so the online latency identification would legitimately settle elsewhere live
    # than offline, and the live-vs-replay comparison would measure UML's scheduler. Use the
    # configured latency here; its identification is tested on the host (test_estimator_accuracy,
    # test_real_data).
    cfg["gnss"]["estimate_delay"] = False
    cfg.setdefault("daemon", {})["state_file"] = state_file
    for table in cfg.get("inputs", {}).values():
        table["timeout_s"] = GUEST_INPUT_TIMEOUT_S
    dest.write_text(tomli_w.dumps(cfg))
    return dest


# --------------------------------------------------------------------------- reading the capture

@dataclass
class Capture:
    frames: list  # (t, can.Message) in capture order

    @classmethod
    def read(cls, path: Path) -> "Capture":
        return cls([(ev.t, ev.message) for ev in player.read_candump(path)])

    def of(self, frame_id: int) -> list:
        return [(t, m) for t, m in self.frames
                if m.arbitration_id == frame_id and not m.is_error_frame and not m.is_extended_id]

    def error_frames(self) -> list:
        return [(t, m) for t, m in self.frames if m.is_error_frame]


def e2e_data_id(msg) -> int:
    attr = (msg.dbc.attributes or {}).get("E2EDataId") if msg.dbc is not None else None
    return int(attr.value) & 0xFF if attr is not None else msg.frame_id & 0xFF


def integrity(cap: Capture, msg) -> dict:
    """Counter continuity and E2E profile-2 CRCs of one output message, checked with cantools' own CRC."""
    from cantools.autosar.end_to_end import compute_profile2_crc

    frames = cap.of(msg.frame_id)
    counters = [m.data[1] & 0x0F for _, m in frames]
    jumps = sum(1 for a, b in zip(counters, counters[1:]) if b != (a + 1) % 16)
    did = e2e_data_id(msg)
    bad_crc = sum(1 for _, m in frames if compute_profile2_crc(bytes(m.data), did) != m.data[0])
    bad_dlc = sum(1 for _, m in frames if m.dlc != msg.length)
    return {"count": len(frames), "counter_jumps": jumps, "bad_crc": bad_crc, "bad_dlc": bad_dlc}


def periods_ms(cap: Capture, frame_id: int):
    import numpy as np

    t = np.array([t for t, _ in cap.of(frame_id)])
    return np.diff(t) * 1e3


def decode(cap: Capture, msg) -> tuple:
    """(times, {signal: array}) of one output message, decoded with the DBC (no choices)."""
    import numpy as np

    ts, rows = [], []
    for t, m in cap.of(msg.frame_id):
        ts.append(t)
        rows.append(msg.decode(bytes(m.data), decode_choices=False, scaling=True))
    keys = rows[0].keys() if rows else []
    return np.array(ts), {k: np.array([r.get(k, np.nan) for r in rows], dtype=float) for k in keys}


def log_time_offset(cap: Capture, drive_log: Path, input_ids: set[int]) -> float:
    """Capture time minus log time, from the replayed input frames (seen in order in both)."""
    import numpy as np

    log_t = [ev.t for ev in player.read_candump(drive_log) if ev.message.arbitration_id in input_ids]
    cap_t = [t for t, m in cap.frames if not m.is_error_frame and m.arbitration_id in input_ids]
    n = min(len(log_t), len(cap_t))
    return float(np.median(np.array(cap_t[:n]) - np.array(log_t[:n])))


def copy_artifacts(src: Path, name: str) -> None:
    """Keep a run's files for CI inspection when ECU_KERNEL_ARTIFACTS is set."""
    dest = os.environ.get("ECU_KERNEL_ARTIFACTS")
    if dest:
        shutil.copytree(src, Path(dest) / name, dirs_exist_ok=True,
                        ignore=shutil.ignore_patterns(".uml", "gnss0"))
