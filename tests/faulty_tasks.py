"""Tasks for a pool's worker that misbehave as a plug-in's code may (tests/test_plugin_faults.py): importable by
name in a spawned worker."""
import os
import signal
import subprocess
import sys
import time


def ends_with(kind: str):
    """Raise what is not an Exception, as a plug-in's run() may."""
    raise {"exit": SystemExit(0), "interrupt": KeyboardInterrupt(), "generator": GeneratorExit()}[kind]


def exits(code: int) -> None:
    os._exit(code)


def kills_itself() -> None:
    os.kill(os.getpid(), signal.SIGKILL)


def forks() -> int:
    """A child by os.fork that outlives the task (it sleeps); its pid."""
    pid = os.fork()
    if pid == 0:
        time.sleep(300)
        os._exit(0)
    return pid


def starts() -> int:
    """A child by subprocess that outlives the task; its pid."""
    return subprocess.Popen([sys.executable, "-c", "import time; time.sleep(300)"]).pid


def starts_apart() -> int:
    """A child in a process group of its own (Popen(process_group=0): setpgid in the child, no at-fork hook, so no
    parent-death signal either) that outlives the task; its pid."""
    return subprocess.Popen([sys.executable, "-c", "import time; time.sleep(300)"], process_group=0).pid


def pid() -> int:
    return os.getpid()
