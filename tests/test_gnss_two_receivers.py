"""Two GNSS receivers (front and rear): each sample tagged with its receiver, replay reading one
capture per receiver, each receiver's latency identified on its own, the heading-only role."""
from __future__ import annotations

import pytest

from ecu_daemon import config as config_mod
from ecu_daemon.cli import UserError
from ecu_daemon.gnss import GnssStreamParser, encode
from ecu_daemon.replay import run_replay
from ecu_daemon.sim import writer
from ecu_daemon.sim.run import simulate, vehicle_config
from ecu_daemon.sim.scenario import SCENARIOS


def test_the_parser_stamps_its_receiver_on_every_sample():
    pvt = encode.nav_pvt(**encode.utc_fields(1.7e9), lat_deg=48.0, lon_deg=11.0, vel_n_mps=3.0, vel_e_mps=4.0)
    rel = encode.nav_relposned(itow_ms=0, heading_deg=10.0, baseline_m=1.0)
    assert [s.source for s in GnssStreamParser(source=1).feed(0.0, pvt + rel)] == [1, 1]
    assert [s.source for s in GnssStreamParser().feed(0.0, pvt + rel)] == [0, 0]


@pytest.fixture(scope="module")
def drive(tmp_path_factory):
    """The dlc drive with receivers 2.5 m apart, latencies 0.4 and 0.33 s, both priors at 0.3 s."""
    sc = SCENARIOS["dlc_dry"].with_(name="two", gnss_lever_arm_m=(1.5, 0.0), gnss_latency_s=0.4,
                                    gnss2_lever_arm_m=(-1.0, 0.0), gnss2_latency_s=0.33, latency_prior_s=0.3)
    cfg = vehicle_config(sc)
    d = tmp_path_factory.mktemp("two")
    paths = writer.write_all(d, simulate(sc, cfg), cfg)
    return config_mod.load(paths["config"]), paths, d


def test_the_written_config_lists_both_receivers(drive):
    cfg, _, _ = drive
    a, b = cfg.gnss.receivers()
    assert (a.lever_arm_m, a.delay_s, b.lever_arm_m, b.delay_s) == ([1.5, 0.0], 0.3, [-1.0, 0.0], 0.3)


def test_replay_identifies_each_receivers_latency_on_its_own(drive):
    cfg, paths, d = drive
    both = run_replay(cfg, str(paths["can"]), [str(paths["gnss"]), str(paths["gnss2"])], str(d / "both.csv"))
    learned = both["learned"]
    assert learned["gnss_delay_s"] == pytest.approx(0.4, abs=0.03)
    assert learned["gnss_delay_s_1"] == pytest.approx(0.33, abs=0.03)
    one = run_replay(cfg, str(paths["can"]), str(paths["gnss"]), str(d / "one.csv"))
    rows_one, rows_both = one["inputs"]["gnss"], both["inputs"]["gnss"]
    assert rows_both["samples"] > 1.9 * rows_one["samples"]  # both captures read, both parsed
    assert rows_both["fused"] > 1.8 * rows_one["fused"]  # and both fused
    assert one["learned"]["gnss_delay_s_1"] == 0.3  # the second receiver: nothing to learn from
    # the per-drive stiffness regression considers one latency: the first receiver's, never the
    # other's (fed both, it jumped by 0.07 s at every other fix and moved its estimate with it)
    assert both["learned_std"]["kappa_drive_latency_s"] == pytest.approx(learned["gnss_delay_s"], abs=1e-9)


def test_a_heading_only_receiver_gives_no_velocity(drive):
    cfg, paths, d = drive
    cfg = config_mod.load(paths["config"])
    cfg.gnss.receiver[1].role = "heading"
    r = run_replay(cfg, str(paths["can"]), [str(paths["gnss"]), str(paths["gnss2"])], str(d / "heading.csv"))
    one = run_replay(cfg, str(paths["can"]), str(paths["gnss"]), str(d / "one_again.csv"))
    assert r["inputs"]["gnss"]["fused"] == one["inputs"]["gnss"]["fused"]


def test_more_captures_than_receivers_is_one_line(drive, tmp_path):
    _, paths, _ = drive
    single = config_mod.Config()
    with pytest.raises(UserError, match="2 GNSS captures given but the config has 1 receiver") as e:
        run_replay(single, str(paths["can"]), [str(paths["gnss"]), str(paths["gnss2"])], str(tmp_path / "x.csv"))
    assert "\n" not in str(e.value)
