"""Processes the tests start: the worker pools' children, which started and whether they ended
(tests/test_scheduling.py, tests/test_workprecision_pool.py); a command's session or process group, from /proc
(tests/test_boundaries.py, tests/test_faults.py)."""
import multiprocessing
import os
import time
from pathlib import Path


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


def alive_in(*, session: int | None = None, group: int | None = None) -> list[int]:
    """The live (not zombie) processes of a session or of a process group, read from /proc/PID/stat (Linux)."""
    field, value = (3, session) if session is not None else (2, group)  # after the name: state, ppid, pgrp, session
    alive = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[field]) == value and fields[0] != "Z":
                alive.append(int(entry.name))
    return alive


_PAID: set = set()


def pay(key: str, startup_s: float, run_s: float) -> tuple[int, str, bool]:
    """A fake engine's run on a pool worker (tests/test_engine_affinity.py): its start-up (startup_s) the first time
    this process sees the key, then the run (run_s). (pid, key, whether it paid the start-up)."""
    first = key not in _PAID
    if first:
        time.sleep(startup_s)
        _PAID.add(key)
    time.sleep(run_s)
    return os.getpid(), key, first


class _WritesAtTeardown:
    def __init__(self, path: str):
        self.path = path

    def __del__(self):
        Path(self.path).write_text("freed")


_HELD = []


def watch_exit(folder: str) -> int:
    """A task for a pool's worker (tests/test_scheduling.py): folder/exit-handler is written if its exit handlers run,
    folder/teardown if the interpreter frees what its modules hold. Returns the worker's pid."""
    import atexit

    atexit.register(lambda: Path(folder, "exit-handler").write_text("ran"))
    _HELD.append(_WritesAtTeardown(str(Path(folder, "teardown"))))
    return os.getpid()
