"""Child processes of the tests' worker pools: which started, and whether they ended (tests/test_scheduling.py,
tests/test_workprecision_pool.py)."""
import multiprocessing
import os
import time


def started_since(before: set) -> set:
    """Child processes started since `before` (earlier tests' pools may still be exiting)."""
    return set(multiprocessing.active_children()) - before


def ended(processes: set, within_s: float = 60.0) -> bool:
    """Whether every process ended within a generous bound (not a timing check). The pool's own thread may reap a
    worker before Process.join sees it (its exitcode then stays None), so a process also counts as ended once its pid
    is gone."""
    deadline = time.monotonic() + within_s
    for process in processes:
        while True:
            process.join(timeout=0.1)
            if process.exitcode is not None or not exists(process.pid):
                break
            if time.monotonic() > deadline:
                return False
    return True


def exists(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True
