"""Fault injection (issue 22): interrupts at several moments, start-up included; killed parents and the processes they
leave; the gate racing a sweep; hostile files for every reader. The fast parts run by default, the real commands
interrupted at wall-clock moments with `-m slow`.

Every outcome asserted is the one the contract names (DESIGN §5, docs/limits.md): exit 130 and one line for an
interrupt, exit 2 and one line for bad input or a busy or unfinished folder, no process alive after its parent died.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from stereodyn.harness import cli
from stereodyn.harness.run import processes
from stereodyn.harness import engines as engine_registry

INTERRUPTED = "stereodyn: interrupted"


def _alive(pid: int) -> bool:
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return False
    return fields[0] != "Z"


def _wait_gone(pids, within_s: float = 60.0) -> list[int]:
    """The pids still alive after within_s (a generous bound for a loaded machine, not a timing check)."""
    deadline = time.monotonic() + within_s
    while (alive := [p for p in pids if _alive(p)]) and time.monotonic() < deadline:
        time.sleep(0.1)
    return alive


# --- 1. interrupts: never a green run, never an engine "unavailable" because of one

class _Entry:
    """An engine entry point whose module's init was interrupted, as pybind11 reports it: ImportError("initialization
    failed") raised from the KeyboardInterrupt."""

    value = "fake_sdk:Engine"

    def __init__(self, cause: BaseException | None):
        self.cause = cause

    def load(self):
        try:
            if self.cause is not None:
                raise self.cause
            raise ImportError("No module named 'fake_sdk'")
        except BaseException as exc:
            raise ImportError("initialization failed") from exc


def test_an_engine_whose_import_was_interrupted_is_not_unavailable():
    with pytest.raises(KeyboardInterrupt):
        engine_registry._load("fake", _Entry(KeyboardInterrupt()))
    missing = engine_registry._load("fake", _Entry(None))  # a missing SDK is still data: the engine's rows skipped
    assert isinstance(missing, engine_registry.UnavailableEngine) and "fake engine unavailable" in missing.reason


def test_an_interrupt_an_sdk_swallows_still_ends_the_command_with_130(monkeypatch, capsys):
    """Ctrl-C inside code that catches it (an SDK's callback, a broad except) and goes on: the command still ends
    with 130 and one line, whatever the command returned."""
    from stereodyn.harness.scenes import cases

    suite = cases.load_suite

    def swallowing(*args, **kwargs):
        try:
            processes.on_interrupt(signal.SIGINT, None)
        except BaseException:
            pass
        return suite(*args, **kwargs)

    monkeypatch.setattr(cases, "load_suite", swallowing)
    assert cli.main(["cases"]) == 130
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(INTERRUPTED), err
    monkeypatch.setattr(cases, "load_suite", suite)
    assert cli.main(["cases"]) == 0  # the next command in this process starts afresh


def test_a_run_broken_by_an_interrupt_is_no_row(monkeypatch):
    """A run whose failure the interrupt caused is not recorded as `failed` (it would be stored and reused)."""
    from stereodyn.harness.run import sweep

    monkeypatch.setattr(processes, "_interrupts", [0.0])
    with pytest.raises(KeyboardInterrupt):
        processes.raise_if_interrupted(RuntimeError("an SDK's wrapping of the interrupt"))
    monkeypatch.setattr(processes, "_interrupts", [])
    processes.raise_if_interrupted(RuntimeError("a real failure"))  # no interrupt: data, nothing raised
    assert sweep.raise_if_interrupted is processes.raise_if_interrupted


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_workers_die_with_a_parent_killed_before_they_finished_starting(tmp_path):
    """The parent is SIGKILLed right after it started its pool, while the workers still import (the moment the
    0.2.0 watch, started in the pool initializer from os.getppid(), missed: it then watched init forever)."""
    script = tmp_path / "parent.py"
    script.write_text(textwrap.dedent("""
        import os, signal, sys
        from stereodyn.harness.run.sweep import worker_pool
        pool_context = worker_pool(2, ())
        pool = pool_context.__enter__()
        print(" ".join(str(pid) for pid in pool._processes), flush=True)
        os.kill(os.getpid(), signal.SIGKILL)
    """))
    child = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=120)
    assert child.returncode == -signal.SIGKILL, child.stderr
    workers = [int(pid) for pid in child.stdout.split()]
    assert len(workers) == 2
    try:
        assert _wait_gone(workers) == []
    finally:
        for pid in workers:
            if _alive(pid):
                os.kill(pid, signal.SIGKILL)
    assert "leaked semaphore" not in child.stderr and "Traceback" not in child.stderr, child.stderr


def test_a_worker_ignores_ctrl_c_from_its_first_moment():
    """Ctrl-C to the workers while they start (still importing): none prints or dies of it, every one ignores it."""
    from stereodyn.harness.run.sweep import worker_pool

    with worker_pool(2, ()) as pool:
        workers = list(pool._processes)
        for pid in workers:
            os.kill(pid, signal.SIGINT)
        handlers = {pool.submit(signal.getsignal, signal.SIGINT).result(timeout=120) for _ in range(4)}
        assert handlers == {signal.SIG_IGN}
        assert all(_alive(pid) for pid in workers)
