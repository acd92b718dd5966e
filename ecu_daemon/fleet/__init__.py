"""``ecu-daemon fleet``: replay, score and calibrate many recorded drives (issue 12).

One drive is one job (:mod:`.job`): the project's deterministic replay on its CAN log and GNSS
capture, scored against truth when there is one, its learned parameters read with their
uncertainty. Jobs run on a local process pool or a Dask cluster (:mod:`.backends`); each result is
stored atomically under the hash of its inputs and the project version (:mod:`.store`), so a rerun
only does what is missing. :mod:`.tables` and :mod:`.report` turn the results into per-drive and
per-vehicle tables and a Markdown report; :mod:`.calibrate` combines a vehicle's drives into one
config override; :mod:`.simfleet` writes a simulated fleet with known, different parameters.
"""
