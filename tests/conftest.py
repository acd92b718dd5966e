"""Suite-wide fixtures."""
import pytest


@pytest.fixture(autouse=True)
def _isolated_logging():
    """A test that configures the daemon's logging (its own stderr handler, propagate off) must
    not leave it behind: later tests read log records through pytest's caplog on the root logger."""
    yield
    from ecu_daemon.io.logging_setup import reset_logging

    reset_logging()
