"""``ecu-daemon simulate --config car.toml`` with a car whose IMU has a roll-rate gyro or a magnetometer
mapped ([inputs.roll_rate], [inputs.mag_x/y/z]) on a scenario that has none. Before: a KeyError
traceback from the sensor model ("unknown input 'roll_rate'"), exit 1, nothing written."""
from __future__ import annotations

import pytest

from ecu_daemon import config as config_mod
from ecu_daemon.cli import main as cli_main
from ecu_daemon.replay import run_replay

ROLL = '[inputs.roll_rate]\nmessage = "IMU_ROLL"\nsignal = "ROLL_RATE"\n'
MAG = "".join(f'[inputs.mag_{a}]\nmessage = "MAGNETOMETER"\nsignal = "MAG_{a.upper()}"\nscale = 1e-6\n'
              f"min = -1e-3\nmax = 1e-3\n" for a in "xyz")


@pytest.mark.parametrize("mapping, inputs", [(ROLL, ("roll_rate",)), (MAG, ("mag_x", "mag_y", "mag_z")),
                                             (ROLL + MAG, ("roll_rate", "mag_x"))])
def test_a_config_mapping_an_optional_sensor_simulates_it_and_the_replay_reads_it(tmp_path, capsys, mapping,
                                                                                  inputs):
    cfg = tmp_path / "car.toml"
    cfg.write_text(mapping)
    out = tmp_path / "drive"
    rc = cli_main(["simulate", "--scenario", "dlc_dry", "--duration", "8", "--config", str(cfg), "--out", str(out)])
    err = capsys.readouterr().err
    assert rc == 0, err.strip().splitlines()[-1]
    said = [line for line in err.splitlines() if "the simulated car gets" in line]
    assert len(said) == 1 and all(n in said[0] for n in inputs)
    summary = run_replay(config_mod.load(out / "config.toml"), str(out / "drive.log"),
                         str(out / "drive_gnss.log"), str(tmp_path / "est.csv"), None, progress=False)
    for name in inputs:
        row = summary["inputs"][name]
        assert row["frames"] > 300 and row["samples"] == row["frames"], (name, row)


def test_a_scenario_that_has_the_sensor_keeps_its_own(tmp_path):
    """The suite's magnetometer scenarios carry disturbance events: a mapped magnetometer does not
    replace them with the plain default."""
    from ecu_daemon.sim.run import with_mapped_sensors
    from ecu_daemon.sim.scenario import get
    from ecu_daemon.sim.sensors import MagEvent, MagParams

    mag = MagParams(events=(MagEvent(1.0, 2.0, (1e-6, 0.0, 0.0), 1.0, 1.0),))
    sc = get("dlc_dry").with_(sensor_magnetometer=mag, sensor_roll_rate=True)
    cfg = tmp_path / "car.toml"
    cfg.write_text(ROLL + MAG)
    assert with_mapped_sensors(sc, config_mod.load(cfg)) is sc
