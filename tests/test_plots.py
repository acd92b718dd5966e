"""``replay --plots``: a drive without truth drawn as PNGs (the same plotting code as ``evaluate``)."""
from __future__ import annotations

import pytest

from ecu_daemon import cli, config as config_mod
from ecu_daemon.replay import run_replay
from ecu_daemon.samples import REQUIRED_INPUTS
from ecu_daemon.sim import SCENARIOS, simulate, vehicle_config
from ecu_daemon.sim.writer import write_all

mpl_image = pytest.importorskip("matplotlib.image", reason="matplotlib (the 'plot' extra) not installed")


@pytest.fixture(scope="module")
def drive(tmp_path_factory):
    d = tmp_path_factory.mktemp("plotdrive")
    sc = SCENARIOS["slalom_dry"].with_(duration_s=12.0)
    write_all(d, simulate(sc, vehicle_config(sc)))
    return d


def test_replay_plots_a_drive_without_truth(drive, tmp_path, capsys):
    plots = tmp_path / "plots"
    rc = cli.main(["replay", "--config", str(drive / "config.toml"), "--can", str(drive / "drive.log"),
                   "--gnss", str(drive / "drive_gnss.log"), "--plots", str(plots), "--no-progress"])
    assert rc == 0
    names = {"sideslip.png", "heading.png", "velocities.png", "biases.png", "validity.png", "inputs.png"}
    assert {p.name for p in plots.glob("*.png")} == names
    for name in names:
        img = mpl_image.imread(plots / name)
        assert img.shape[0] > 500 and img.shape[1] > 1000  # a real figure, not an empty file
        assert img[..., :3].std() > 0.05  # something drawn on it
    assert (plots / "out.csv").read_text().startswith("t,sideslip_rad")  # the CSV the plots show
    assert f"wrote {plots / 'inputs.png'}" in capsys.readouterr().err


def test_replay_collects_every_decoded_input_and_the_gnss_speed_for_the_plots(drive):
    inputs: dict = {}
    cfg = config_mod.load(str(drive / "config.toml"))
    summary = run_replay(cfg, str(drive / "drive.log"), str(drive / "drive_gnss.log"), inputs=inputs)
    assert set(inputs) == set(REQUIRED_INPUTS) | {"gnss_speed"}  # every mapped input (no magnetometer here)
    t, v = inputs["gnss_speed"]
    assert len(t) == len(v) == summary["gnss_samples"] and max(v) > 5.0  # a moving car, m/s
    t, v = inputs["wheel_speed_fl"]
    assert t == sorted(t) and abs(max(v) - max(inputs["gnss_speed"][1])) < 2.0  # SI, like the GNSS


def test_unwritable_plot_directory_is_a_one_line_error(drive, tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("")
    rc = cli.main(["replay", "--config", str(drive / "config.toml"), "--can", str(drive / "drive.log"),
                   "--plots", str(blocker / "plots"), "--no-progress"])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and "cannot write plots" in err
