"""Running the per-log records on Dask (docs/results/fleet.md, "Engine").

One task per log (`client.submit` of `task`); results stream back through
`as_completed` and each record is written to the store as it arrives, by
this process only (a record is never written twice, and a worker that dies
loses only the task it was running: the scheduler gives it to another
worker, up to ALLOWED_FAILURES deaths, then the log is reported as
refused).  By default a LocalCluster of processes with one thread each and
a memory limit per worker (Dask's nanny restarts a worker that exceeds
it); --scheduler runs the same tasks on an existing cluster.

`run_direct` calls the same task in this process, one log after another:
the baseline the engine's overhead is measured against, and the reference
the distributed results are compared with bit for bit."""
from __future__ import annotations

import contextlib
import logging
import os
import resource
import signal
import sys
import threading
import time

from ..safeio import HdError
from . import record

CONNECT_TIMEOUT_S = 10
ALLOWED_FAILURES = 2


class EngineError(HdError):
    """The engine cannot run (an unreachable scheduler): exit 1."""
    code = 1


def task(path: str, options: dict, part=None):
    """(values or None, refusal message or None, stats) for one log or one
    part of it (record.analyze_log's byte_range / window_ns / joint); a bad
    log is a refusal, never an exception (the run goes on)."""
    from threadpoolctl import threadpool_limits
    from ..analysis.cfilter import FilterError
    from ..safeio import UsageError
    t0 = time.perf_counter()
    values, problem = None, None
    try:
        # One BLAS thread wherever the task runs: a threaded dot product sums
        # in another order, and the record must not depend on the worker.
        with threadpool_limits(limits=1):
            values = record.analyze_log(path, **(part or {}),
                                        **{k: v for k, v in options.items() if k != "chunk_bytes"})
    except (UsageError, FilterError) as exc:
        problem = " | ".join(str(exc).splitlines()) or type(exc).__name__
        # the record names the log by its relative path: no absolute path in it
        problem = problem[len(path) + 2:] if problem.startswith(f"{path}: ") else problem
    except (ValueError, FloatingPointError, MemoryError, OSError) as exc:
        problem = f"cannot analyse: {type(exc).__name__}: {exc}"
    stats = {"elapsed_s": time.perf_counter() - t0, "pid": os.getpid(),
             "max_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0}
    return values, problem, stats


def _silence():
    for name in ("distributed", "tornado", "asyncio", "bokeh"):
        logging.getLogger(name).setLevel(logging.CRITICAL)


def connect(scheduler=None, workers=2, memory_per_worker="2GiB"):
    """A dask.distributed Client: on an existing cluster, or a LocalCluster
    of `workers` processes with one thread each.  EngineError (one line)
    when the scheduler cannot be reached within CONNECT_TIMEOUT_S."""
    import dask
    from distributed import Client, LocalCluster
    _silence()
    # Dask's nanny starts workers with MALLOC_TRIM_THRESHOLD_=65536, which
    # also fixes glibc's mmap threshold: every large numpy array of a replay
    # becomes a fresh mmap and the task ran 1.8x slower than in the client
    # (measured, docs/results/fleet.md).  Our workers keep glibc's default; the
    # nanny's memory limit still bounds them.
    environ = {k: v for k, v in dask.config.get("distributed.nanny.pre-spawn-environ").items()
               if k != "MALLOC_TRIM_THRESHOLD_"}
    dask.config.set({"distributed.scheduler.allowed-failures": ALLOWED_FAILURES,
                     "distributed.logging.distributed": "critical",
                     "distributed.nanny.pre-spawn-environ": environ})
    if scheduler:
        try:
            return Client(scheduler, timeout=CONNECT_TIMEOUT_S, set_as_default=False)
        except (OSError, TimeoutError, ValueError) as exc:
            msg = " ".join(str(exc).split())[:200] or type(exc).__name__
            raise EngineError(f"--scheduler {scheduler}: cannot connect: {msg}") from None
    cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                           memory_limit=memory_per_worker, dashboard_address=None,
                           silence_logs=logging.CRITICAL)
    return Client(cluster, set_as_default=False)


@contextlib.contextmanager
def deferred_sigint():
    """SIGINT held back while a cluster starts or stops (a KeyboardInterrupt
    inside distributed's start-up was swallowed and the run went on, or
    came out at exit as a death by signal); delivered, as
    KeyboardInterrupt, when the block ends."""
    main = threading.current_thread() is threading.main_thread()
    if main:
        signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        if main:
            signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})


def close(client):
    cluster = getattr(client, "cluster", None)
    client.close()
    if cluster is not None:
        cluster.close()


def _bar(total, quiet):
    from tqdm import tqdm
    return tqdm(total=total, unit="log", disable=True if quiet else None, file=sys.stderr,
                dynamic_ncols=True)


def run(client, jobs, options, on_result, quiet=False):
    """jobs: [(key, path, part or None)] (task's part).  Calls on_result(key, values, problem, stats) as
    each task finishes, in completion order."""
    from distributed import as_completed
    from distributed.client import FutureCancelledError
    futures = {client.submit(task, path, options, part, key=f"hdfleet-{key}", pure=False): key
               for key, path, part in jobs}
    with _bar(len(futures), quiet) as bar:
        for fut in as_completed(list(futures), loop=client.loop):
            key = futures[fut]
            try:
                values, problem, stats = fut.result()
            except (FutureCancelledError, OSError) as exc:
                values, problem, stats = None, f"engine: {type(exc).__name__}: {exc}", {}
            except Exception as exc:  # noqa: BLE001 - KilledWorker and friends: the log's fault
                name = type(exc).__name__
                what = ("its worker died " + str(ALLOWED_FAILURES + 1) + " times (memory?)"
                        if name == "KilledWorker" else f"{name}: {exc}")
                values, problem, stats = None, f"engine: {what}", {}
            on_result(key, values, problem, stats)
            fut.release()
            bar.update(1)


def run_direct(jobs, options, on_result, quiet=False):
    """The same tasks in this process, in order (no engine)."""
    with _bar(len(jobs), quiet) as bar:
        for key, path, part in jobs:
            on_result(key, *task(path, options, part))
            bar.update(1)
