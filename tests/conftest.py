"""Suite-wide fixtures."""
import pytest


@pytest.fixture(autouse=True)
def _isolated_logging():
    """A test that configures the daemon's logging (its own stderr handler, propagate off) must
    not leave it behind: later tests read log records through pytest's caplog on the root logger."""
    yield
    from ecu_daemon.io.logging_setup import reset_logging

    reset_logging()


@pytest.fixture(scope="session")
def demo_drive(tmp_path_factory):
    """The simulated demo drive with its right configuration, for the wrong-configuration tests that
    replay it with an edited copy (each under its own name, beside it)."""
    from config_replay import simulated_drive
    from ecu_daemon.sim.scenario import Scenario
    return simulated_drive(tmp_path_factory, "demo_drive", Scenario("demo", "demo"))

