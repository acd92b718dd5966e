"""Online latency of a heading-only receiver (issue 11): its heading changes regressed on the
integrated yaw rate, on a simulated drive through the real replay path."""
from __future__ import annotations

import pytest

from ecu_daemon import config as config_mod
from ecu_daemon.replay import run_replay
from ecu_daemon.sim import SCENARIOS, simulate, vehicle_config
from ecu_daemon.sim import writer


@pytest.mark.parametrize("kind", ["slalom_dry", "dlc_dry"])
def test_heading_only_receiver_identifies_its_own_latency(tmp_path, kind):
    """A moving-base pair that sends only its heading, 0.15 s late, configured with 0.3 s: the
    identification ends within 0.03 s of the truth (it kept the configured 0.3 s before)."""
    sc = SCENARIOS[kind].with_(gnss2_dual_antenna=True, gnss2_latency_s=0.15, gnss2_baseline_m=1.2,
                               gnss2_baseline_offset_deg=90.0, gnss2_lever_arm_m=(0.0, 0.0))
    cfg = vehicle_config(sc)
    result = simulate(sc, cfg)
    paths = writer.write_all(tmp_path, result, cfg)
    rcfg = config_mod.load(paths["config"])
    rx = rcfg.gnss.receiver[1]
    rx.role, rx.delay_s = "heading", 0.3
    summary = run_replay(rcfg, str(paths["can"]), [str(paths["gnss"]), str(paths["gnss2"])], str(tmp_path / "est.csv"))
    learned = summary["learned"]
    assert learned["gnss_delay_s_1"] == pytest.approx(0.15, abs=0.03), learned
    assert learned["gnss_delay_s"] == pytest.approx(sc.gnss.latency_s, abs=0.05)  # the velocity receiver's own
