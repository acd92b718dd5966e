"""Vehicle simulator: ground truth plus realistic CAN and GNSS sensor streams.

Layers, each a small module: ``tyre`` (Magic Formula), ``vehicle`` (two-track model, 1 kHz),
``manoeuvres`` (test drives and the driver), ``sensors`` (biases, noise, timing, GNSS receiver),
``can_encoder`` (SI -> frames through any DBC + mapping), ``scenario`` (the named drives),
``run`` (:func:`simulate`), ``writer`` (files for ``ecu-daemon replay``), ``cli``.

Python API::

    from ecu_daemon.sim import SCENARIOS, simulate
    result = simulate(SCENARIOS["dlc_dry"])       # SimResult
    result.can_frames      # [(t_rx, arbitration_id, data), ...] time-ordered
    result.gnss_messages   # [(t_rx, payload_bytes), ...]
    result.truth_table()   # truth.csv columns as numpy arrays
"""
from .run import SimResult, simulate, vehicle_config  # noqa: F401
from .scenario import SCENARIOS, Scenario, T0  # noqa: F401
