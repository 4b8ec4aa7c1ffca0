"""Tasks for a pool's worker that misbehave as a plug-in's code may (tests/test_plugin_faults.py): importable by
name in a spawned worker."""
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from stereodyn.harness import budget


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


# A daemon's start: sh starts `sleep 300` in a session of its own (setsid) and exits, which leaves it to a subreaper or
# init; that one started `sleep 301` in a session of its own too: a child of the orphan, in no group either leads.
# Each lets go of the pipe where it execs its sleep, after its setsid.
_DAEMON = ("setsid sh -c 'setsid sh -c \"exec sleep 301 </dev/null >/dev/null 2>&1\" & echo child $!; "
           "exec sleep 300 </dev/null >/dev/null 2>&1' & echo orphan $!")


def starts_orphans(path: str | None = None) -> list[int]:
    """[the orphan, its child] of _DAEMON, once its sh exited (also written to path, for a task that does not return);
    the pipe's end (EOF) is once both have let go of it."""
    out = subprocess.run(["sh", "-c", _DAEMON], stdin=subprocess.DEVNULL, capture_output=True, text=True,
                         check=True).stdout
    said = dict(line.split() for line in out.splitlines())
    pids = [int(said["orphan"]), int(said["child"])]
    if path is not None:
        Path(path).write_text(" ".join(map(str, pids)))
    return pids


def orphans_then_exits(path: str) -> None:
    """Leave orphans, then end the worker abruptly (no end_group: its orphans are init's at once)."""
    starts_orphans(path)
    os._exit(5)


def orphans_then_hangs(path: str, seconds: float) -> None:
    """Leave orphans, then sleep past a budget of `seconds` (the parent ends the worker)."""
    starts_orphans(path)
    with budget.within("run", seconds):
        time.sleep(1000)
