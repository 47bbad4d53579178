"""Many independent runs on Dask, each a row: what `gyro-fmu sweep` and
`gyro-fmu selfcal-lot` share.

`run_tasks(fn, args)` submits fn(*a) for every a in args to a LocalCluster of
single-threaded worker processes (one per core) or to an existing scheduler, and
collects one row (a dict) per task in task order. A task that raises, or whose
worker dies, becomes the row `lost_row(i, exc)`: it is never lost and never stops the
study. Ctrl-C keeps every finished row (`interrupted` says how many); the workers of
a local cluster never take the signal, so there are no worker tracebacks.
"""

from __future__ import annotations

import logging
import os
import signal
import threading
import time
from collections.abc import Callable, Sequence

from ..errors import GyroFmuError
from ..extras import require
from .progress import progress_bar

_log = logging.getLogger(__name__)


def run_tasks(
    fn: Callable[..., dict],
    args: Sequence[tuple],
    lost_row: Callable[[int, BaseException], dict],
    scheduler: str | None = None,
    n_workers: int | None = None,
    progress: bool = True,
    on_row: Callable[[dict], None] | None = None,
    is_failed: Callable[[dict], bool] = lambda row: row.get("status") != "ok",
) -> tuple[list[dict], float, int, str | None]:
    """(rows in task order, wall time s, workers, interrupted message or None)."""
    require("distributed", "lots")
    from dask.distributed import Client, as_completed

    cluster = None
    if scheduler is None:
        n_workers = n_workers or os.cpu_count() or 1
        if progress:  # Dask takes seconds to start its workers: say so first
            _log.info("starting a local Dask cluster of %d worker processes ...", n_workers)
        cluster = local_cluster(n_workers)
        client = Client(cluster)
    else:
        try:
            client = Client(scheduler, timeout="30s")
        except (ValueError, OSError, TimeoutError) as exc:  # a malformed or dead address
            raise SchedulerError(f"cannot reach the Dask scheduler {scheduler!r} ({exc}): "
                                 "give its address as tcp://HOST:PORT ([::1] for IPv6), "
                                 "or leave --scheduler out for a local cluster") from None
    try:
        n_workers = len(client.scheduler_info().get("workers", {})) or (n_workers or 1)
        start = time.perf_counter()
        futures = {client.submit(fn, *a, pure=False): i for i, a in enumerate(args)}
        rows: dict[int, dict] = {}
        interrupted = None
        failed = 0
        try:
            with progress_bar(len(futures) if progress else 0, "runs", "run", 1) as bar:
                for fut in as_completed(futures):
                    i = futures[fut]
                    try:
                        row = fut.result()
                    except Exception as exc:  # worker died, task lost: still a row
                        row = lost_row(i, exc)
                    rows[i] = row
                    if on_row:
                        on_row(row)
                    failed += bool(is_failed(row))
                    if bar:
                        bar(len(rows), len(futures), failed)
        except KeyboardInterrupt:  # keep every finished row; the caller writes them
            interrupted = f"interrupted after {len(rows)} of {len(futures)} runs"
            if cluster is None:  # someone else's cluster: stop our tasks there
                client.cancel(list(futures))  # (a local one is closed below)
        wall = time.perf_counter() - start
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    return [rows[i] for i in sorted(rows)], wall, n_workers, interrupted


def dask_setup(worker: object) -> None:
    """Dask preload hook of the local cluster's workers (`preload=[this module]`): ignore
    SIGINT for good. The blocked mask they start with (`local_cluster`) does not survive
    a worker that its nanny restarts, and asyncio's handler would then end it with a
    KeyboardInterrupt traceback of its own when a terminal's Ctrl-C reaches the group."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)


class SchedulerError(GyroFmuError, OSError):
    """The scheduler address given cannot be used (the CLI prints it in one line)."""


def local_cluster(n_workers: int):
    """A LocalCluster of single-threaded worker processes that never see SIGINT.

    A terminal's Ctrl-C reaches the whole process group: workers that took it would die
    with tracebacks of their own. SIGINT is blocked while they start, so they inherit
    the blocked signal (a signal mask survives fork and exec), and so do the cluster's
    threads; a Ctrl-C during start-up stays pending here and is raised as
    KeyboardInterrupt once the mask is lifted (run_tasks keeps every finished row)."""
    from dask.distributed import LocalCluster

    previous = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        # silence_logs: the workers' own log lines stay out of the user's terminal (a
        # successful `sweep -n 4` printed a heartbeat traceback as the cluster closed); a
        # task's error still comes back through its future, with its traceback
        return LocalCluster(n_workers=n_workers, threads_per_worker=1, processes=True,
                            dashboard_address=None, preload=[__name__],
                            silence_logs=logging.CRITICAL)
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)
