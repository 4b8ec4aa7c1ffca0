"""Sweeps on an existing Dask cluster (`--scheduler tcp://HOST:PORT`; the optional extra `stereodyn[dask]`).

The parent keeps the roles it has with local processes: it computes the truth, submits one task per run (the truth
of each case is scattered to the workers once), and stores every row the moment it comes back, so the result store,
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


def run_on_cluster(address: str, specs: Sequence, truths: dict, execute: Callable, finished: Callable,
                   worker_failed: Callable) -> None:
    """Run execute(spec, truths[spec.case.name]) for every spec on the cluster at `address`, longest first (the
    order given); call finished(spec, row) in the parent as each completes, or finished(spec, worker_failed(spec,
    exc)) when its task was lost (a worker died)."""
    from distributed import as_completed

    with _connect(address) as client:
        scattered = {name: client.scatter(truth, broadcast=True, hash=False) for name, truth in truths.items()}
        futures = {client.submit(execute, spec, scattered[spec.case.name], pure=False, priority=len(specs) - rank):
                   spec for rank, spec in enumerate(specs)}
        try:
            for future in as_completed(futures, loop=client.loop):
                spec = futures[future]
                try:
                    row = future.result()
                except Exception as exc:  # the task was lost: its worker died, or the cluster went away
                    raise_if_internal(exc)  # ... but a bug of ours raised in the task is no row
                    row = worker_failed(spec, exc)
                finished(spec, row)
        except BaseException:
            client.cancel(list(futures))
            raise
