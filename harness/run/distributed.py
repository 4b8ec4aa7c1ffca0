"""Sweeps on an existing Dask cluster (`--scheduler tcp://HOST:PORT`; the optional extra `stereodyn[dask]`).

The parent keeps the roles it has with local processes: it plans, submits the tasks and gathers: each case's truth is
a task on a worker, each run a task that depends on its own case's truth, and the timing of the runs that decide an
answer tasks too (cluster_timer: pool.time_on_a_free_core); it stores every row the moment it comes back, so the result store,
`--resume` and results.csv behave exactly as in a local sweep. Workers need the same stereodyn and libraries: a worker
with other library versions than this process is refused, since results are keyed by this process's versions.
"""
from __future__ import annotations

from typing import Callable, Sequence

from ..errors import raise_if_internal

CONNECT_TIMEOUT_S = 10


class ClusterError(RuntimeError):
    """The cluster cannot be used (dask missing, scheduler unreachable, mismatched workers): bad input, exit 2."""


def check_cluster(address: str) -> None:
    """That the cluster at `address` can run this sweep (ClusterError otherwise), before the command computes any
    truth: an unreachable scheduler was found only after the truths (seconds to minutes)."""
    _connect(address).close()


def _connect(address: str):
    """A client of the cluster at `address` with at least one worker, whose workers have this process's library
    versions; ClusterError otherwise."""
    try:
        from distributed import Client
    except ImportError as exc:
        raise ClusterError(f"--scheduler needs dask.distributed ({exc}); install it with "
                           "pip install 'stereodyn[dask]'") from None
    from ..environment import library_versions

    try:
        client = Client(address, timeout=CONNECT_TIMEOUT_S, set_as_default=False)
    except (OSError, TimeoutError, ValueError) as exc:
        raise ClusterError(f"--scheduler: cannot connect to {address}: {exc}") from None
    try:
        try:
            client.wait_for_workers(1, timeout=CONNECT_TIMEOUT_S)
        except TimeoutError:
            raise ClusterError(f"--scheduler: the cluster at {address} has no workers") from None
        mine = library_versions()
        try:
            theirs = client.run(library_versions)
        except Exception as exc:  # e.g. ModuleNotFoundError: stereodyn is not installed on the workers
            raise ClusterError(f"--scheduler: the workers cannot run stereodyn: {type(exc).__name__}: {exc}") from None
        for worker, versions in theirs.items():
            if versions != mine:
                differ = ", ".join(f"{k} {versions.get(k)} (here {v})" for k, v in mine.items() if versions.get(k) != v)
                raise ClusterError(f"--scheduler: worker {worker} has other library versions: {differ}")
    except BaseException:
        client.close()
        raise
    return client


def run_on_cluster(address: str, specs: Sequence, execute: Callable, truth: Callable, finished: Callable,
                   worker_failed: Callable) -> None:
    """Run execute(spec, truth(spec.case)) for every spec on the cluster at `address`, longest first (the order
    given): each case's truth a task of its own, on a worker, that its runs depend on (Dask starts a run once its own
    case's truth is done and moves the truth to its worker), so no truth waits for another. finished(spec, row) in
    the parent as each completes; finished(spec, worker_failed(spec, exc)) when its task was lost (a worker died); the
    runs of a case whose truth failed get truth.truth_failure's row."""
    from distributed import as_completed

    from .spec import base_row
    from .truth import truth_failure

    with _connect(address) as client:
        cases = {id(spec.case): spec.case for spec in specs}
        truths = {key: client.submit(truth, case, pure=False, priority=len(specs) + 1) for key, case in cases.items()}
        futures = {client.submit(execute, spec, truths[id(spec.case)], pure=False, priority=len(specs) - rank):
                   spec for rank, spec in enumerate(specs)}
        try:
            for future in as_completed(futures, loop=client.loop):
                spec = futures[future]
                own = truths[id(spec.case)]
                try:
                    row = future.result()
                except Exception as exc:
                    if own.status == "error":  # its truth failed: the case's runs say why
                        failure = own.exception()
                        raise_if_internal(failure)
                        row = {**base_row(spec, None), **truth_failure(failure)}
                    else:  # the task was lost: its worker died, or the cluster went away
                        raise_if_internal(exc)  # ... but a bug of ours raised in the task is no row
                        row = worker_failed(spec, exc)
                finished(spec, row)
        except BaseException:
            client.cancel(list(futures) + list(truths.values()))
            raise


def cluster_timer(address: str) -> tuple[Callable, int]:
    """(spread, ways): timing.time_runs' `elsewhere` on the cluster at `address`, and how many timings it takes at
    once (its worker threads). Each chunk a task (pool.time_on_a_free_core: on a core of its machine that no other
    timing holds, waiting for one, so that one timing runs per core and per worker thread at a time); a chunk whose
    task was lost keeps its runs' single times (None each); our bug raises."""
    with _connect(address) as client:
        ways = max(1, sum(client.nthreads().values()))

    def spread(chunks: list) -> list:
        from distributed import as_completed

        from .pool import time_on_a_free_core

        results = [[None] * len(chunk.runs) for chunk in chunks]
        with _connect(address) as client:
            futures = {client.submit(time_on_a_free_core, chunk, pure=False, priority=len(chunks) - k): k
                       for k, chunk in enumerate(chunks)}
            try:
                for future in as_completed(futures, loop=client.loop):
                    try:
                        results[futures[future]] = future.result()
                    except Exception as exc:  # lost with its worker: the runs keep their single times
                        raise_if_internal(exc)
            except BaseException:
                client.cancel(list(futures))
                raise
        return results
    return spread, ways
