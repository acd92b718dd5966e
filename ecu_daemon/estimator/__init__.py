"""The pure estimator core: timestamped samples in, one Estimate per fixed 6 ms step out.

No clocks, sockets or asyncio here; the same code runs live (``daemon.py``) and offline
(``replay.py``), and replay is deterministic.

Contract (used by both shells):

* ``Estimator(cfg, learned=None)``; ``learned`` is a dict from :meth:`Estimator.learned_state`
  of an earlier run (biases, wheel scale, cornering stiffness, GNSS latency) to start from.
* ``push_input(InputSample)`` / ``push_gnss(GnssSample)``: samples in time order.
* ``advance_to(t) -> list[Estimate]``: runs every step k whose time ``k * dt`` is <= t (steps sit
  on an absolute grid of multiples of dt); each step sees the samples pushed so far with a
  timestamp <= its time. A sample older than the last completed step is applied at the next
  step (and counted in ``late_inputs``).
* ``learned_state() -> dict``: JSON-serialisable learned quantities for persistence.
"""
from .estimate import Estimate, ESTIMATE_FIELDS  # noqa: F401
from .core import Estimator  # noqa: F401
