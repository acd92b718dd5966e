"""Where the drive jobs run: in this process, on a local process pool, or on a Dask cluster.

Dask gets each drive as one task (``client.map``) and does the scheduling, retries and moving of
results itself; the input files must be readable at the same paths on every worker (a shared file
system), as the result store must be writable. Every backend returns the same records in the
order of the drives, so the tables do not depend on the backend.

Drives are handed out longest first (:func:`longest_first`, by the size of their input files,
which the replay's cost follows): the last drives to start are then the short ones, so the workers
finish together instead of one replaying a long drive while the others idle.
"""
from __future__ import annotations

import os
import uuid
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, as_completed

from .job import run_drive, warm
from .manifest import Drive

RETRIES = 2  # a worker lost mid-drive (OOM, preemption): Dask reruns the task on another one


def run_all(drives: list[Drive], store_dir: str, jobs: int | None = None, scheduler: str | None = None,
            on_done: Callable[[dict], None] | None = None) -> list[dict]:
    """One record per drive, in the order of ``drives``. ``jobs``: local processes (default: all
    cores; 1 runs in this process); ``scheduler``: a Dask scheduler address (overrides ``jobs``)."""
    done = on_done or (lambda rec: None)
    if scheduler:
        recs = _dask(drives, store_dir, scheduler, done)
    elif (jobs or os.cpu_count() or 1) <= 1:
        recs = []
        for d in drives:
            recs.append(run_drive(d, store_dir))
            done(recs[-1])
    else:
        recs = _pool(drives, store_dir, jobs or os.cpu_count() or 1, done)
    return recs


def longest_first(drives: list[Drive]) -> list[int]:
    """Indices of the drives, the largest inputs first (ties, unreadable files: in order)."""
    def size(d: Drive) -> int:
        total = 0
        for f in (d.can, *d.gnss):
            try:
                total += os.path.getsize(f)
            except OSError:
                pass
        return total

    sizes = [size(d) for d in drives]
    return sorted(range(len(drives)), key=lambda i: (-sizes[i], i))


def pool_executor(workers: int) -> ProcessPoolExecutor:
    """Worker processes that start with the replay imported (:func:`~ecu_daemon.fleet.job.warm`):
    forked ones inherit this process's imports, spawned ones import in their initializer."""
    warm()
    return ProcessPoolExecutor(max_workers=workers, initializer=warm)


def _pool(drives, store_dir, jobs, done) -> list[dict]:
    out: list = [None] * len(drives)
    with pool_executor(min(jobs, len(drives))) as pool:
        futures = {pool.submit(run_drive, drives[i], store_dir): i for i in longest_first(drives)}
        for fut in as_completed(futures):
            i = futures[fut]
            out[i] = _result(fut.result, drives[i])
            done(out[i])
    return out


def _dask(drives, store_dir, address, done) -> list[dict]:
    from ..errors import UserError

    try:
        from distributed import Client
        from distributed import as_completed as dask_completed
    except ImportError as e:
        raise UserError(f"--scheduler needs Dask (pip install 'ecu-daemon[fleet]'): {e}") from None
    run = uuid.uuid4().hex[:8]
    order = longest_first(drives)
    keys = [f"fleet-{run}-{i}" for i in order]
    out: list = [None] * len(drives)
    try:
        client = Client(address)
    except (OSError, TimeoutError, ValueError) as e:
        raise UserError(f"cannot reach the Dask scheduler at {address}: {e}") from None
    with client:
        futures = client.map(run_drive, [drives[i] for i in order], [store_dir] * len(drives), key=keys,
                             retries=RETRIES, pure=False)
        index = {f.key: i for f, i in zip(futures, order)}
        for fut in dask_completed(futures):
            i = index[fut.key]
            out[i] = _result(fut.result, drives[i])
            done(out[i])
    return out


def _result(get, drive: Drive) -> dict:
    """The job's record; a job that died outright (worker lost after the retries) becomes an error row."""
    try:
        return get()
    except Exception as e:  # noqa: BLE001
        return {"vehicle": drive.vehicle, "drive": drive.drive, "status": "error",
                "error": f"job failed: {e.__class__.__name__}: {e}", "cached": False, "wall_s": 0.0}
