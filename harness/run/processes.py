"""Worker processes that never outlive the command, and never take its Ctrl-C.

A SIGKILLed parent cannot end its pool; spawned workers then wait on their task queue forever (two idle ~185 MB
workers and the multiprocessing resource tracker were seen alive 60 s after a SIGKILL), and the tracker lives as long
as they do. A worker is tied to its parent from its first moment, whatever the start method:
- the parent names itself in the environment (PARENT_ENV) before it starts one, so a worker knows whose child it is
  even when that parent died before the worker ran a line (os.getppid() is then already init's: a watch started from
  it would wait forever, as the pool initializer's did);
- a spawned worker ties itself to the parent when stereodyn is first imported in it (stereodyn/__init__.py calls
  worker_started), before the seconds of numpy and SDK imports that precede the pool initializer; a forked one in the
  initializer (exit_with_parent);
- the tie is the kernel's parent-death signal (Linux prctl PR_SET_PDEATHSIG: SIGKILL the moment the parent dies, even
  inside a long C call that holds the GIL) and a thread that polls the parent every PARENT_POLL_S (elsewhere, and as a
  second line).
A worker leads a process group of its own (own_process_group), so that what a plug-in starts in it dies with it:
the parent kills what the worker answers for where it ends a worker (harness/run/workers.py: past a budget, on Ctrl-C,
once one died), a worker that exits kills it first (end_group), and a process a plug-in forks there (os.fork,
multiprocessing's fork) gets the parent-death signal on the worker, so that it dies with the worker even when the
worker is SIGKILLed with the command. What a worker answers for (_group_members) is every descendant, whatever group or
session it moved to (Popen(process_group=0), setsid), and every member of a group one of them leads: a worker is the
child subreaper of what it starts (Linux PR_SET_CHILD_SUBREAPER), so an orphan (`sh -c 'setsid cmd &'`, a double
fork) is the worker's child, not init's, while the worker lives. A worker that died abruptly (os._exit, a crash, the
memory killer) has left its orphans to init; the parent still finds those that carry the worker's mark in their
environment (WORKER_ENV, inherited by what it execs: /proc/PID/environ) when it removes that worker. Out of reach
still: an orphan of such a worker that was started with an environment of its own (Popen(env=...) without the mark)
or forked outside Python (no at-fork hook, and a fork's environ is the worker's start-up one, unmarked), and every
orphan when the command itself is SIGKILLed (its workers die by the parent-death signal, nobody scans). An orphan that
ends by itself is a zombie of its worker until the worker exits (init reaped it before): the worker cannot tell it
from a child whose exit status a plug-in's code will ask for.
Ctrl-C reaches the whole process group; the parent handles it (stops the sweep, ends its workers). A worker ignores it
from its start: the parent blocks SIGINT while it starts workers (the mask survives fork and exec; the kernel holds a
blocked signal, so the parent's own Ctrl-C meanwhile is delivered when the block ends, never dropped) and the worker
ignores it before it unblocks it, so no worker prints a traceback or a second "interrupted" line.
"""
from __future__ import annotations

import atexit
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

from ...reference.plugins import code_raised
from ..errors import raise_if_internal

PARENT_POLL_S = 0.5   # the thread's poll: a killed sweep's workers are gone ~0.5 s later at the latest
PARENT_ENV = "STEREODYN_POOL_PARENT"  # the pid of the process that starts workers (set by starting_workers)
# The multiprocessing resource tracker, when its clients were killed, warns about the semaphores they left (it cleans
# them up itself): noise for a user who pressed Ctrl-C or whose run was killed. It inherits the environment.
_TRACKER_WARNING = "ignore:resource_tracker:UserWarning"
WORKER_ENV = "STEREODYN_POOL_WORKER"  # a worker's mark (own_process_group), inherited by what it starts
_PR_SET_PDEATHSIG = 1  # linux/prctl.h
_PR_SET_CHILD_SUBREAPER = 36
_KILL_ROUNDS = 3  # end_group_of's scans at most: what a killed process forked meanwhile is the next scan's


def _prctl(option: int, value: int) -> bool:
    if not sys.platform.startswith("linux"):
        return False
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        return libc.prctl(option, value, 0, 0, 0) == 0
    except (OSError, AttributeError):
        return False


def parent_death_signal(signum: int = signal.SIGKILL) -> bool:
    """Ask the kernel to send this process signum (SIGKILL) when its parent dies (Linux); False where that is not
    available."""
    return _prctl(_PR_SET_PDEATHSIG, signum)


def _watch_pid(parent: int) -> None:
    while True:
        time.sleep(PARENT_POLL_S)
        if os.getppid() != parent:  # re-parented (to init or a subreaper): the parent is dead
            end_group()
            os._exit(1)


def _watch_sentinel(sentinel: int) -> None:
    from multiprocessing.connection import wait

    wait([sentinel])  # readable (EOF) once the parent is gone: its end of the pipe closed with it
    end_group()
    os._exit(1)


def own_process_group(marker: str | None = None) -> None:
    """A pool worker's first act: lead a process group of its own (the parent kills it whole: kill_group), be the
    subreaper of what it starts (an orphan is its child, not init's: _group_members finds it), give every process it
    forks from Python the parent-death signal on it (a plug-in's os.fork), and put its marker in the environment of
    what it starts (WORKER_ENV: the parent finds those once the worker died abruptly)."""
    if marker is not None:
        os.environ[WORKER_ENV] = marker
    _prctl(_PR_SET_CHILD_SUBREAPER, 1)
    if not hasattr(os, "setpgid"):
        return
    try:
        os.setpgid(0, 0)
    except OSError:  # already a group leader (a session leader cannot move): its group is still its own
        pass
    os.register_at_fork(after_in_child=parent_death_signal)


def answer_for_orphans() -> None:
    """The command's first act (started as the command, never imported as a library: harness/cli/__init__.py): be
    the subreaper of what it starts, and at its exit end what is left of it. A daemon a plug-in started at import in
    the command's own process (a double fork, setsid) was init's and outlived the command, where one started in a
    worker dies with the worker (issue 46's eleventh attack, F10). Linux only (elsewhere nothing is done)."""
    if _prctl(_PR_SET_CHILD_SUBREAPER, 1):
        atexit.register(end_descendants)


def end_descendants(grace_s: float = 2.0) -> None:
    """At the command's exit: the pool's workers, which exit on their own once idle, get grace_s to do so; then every
    descendant still alive (an orphan it adopted as their subreaper, what a plug-in started and left) is killed."""
    import multiprocessing

    deadline = time.monotonic() + grace_s
    for child in multiprocessing.active_children():
        child.join(max(0.0, deadline - time.monotonic()))
    _kill_all(lambda: _descendants(os.getpid()))
    _reap(time.monotonic() + REAP_S)


REAP_S = 1.0  # a SIGKILLed process is gone in milliseconds; one in uninterruptible sleep is not waited for longer


def _reap(deadline: float) -> None:
    """Wait for every child (the adopted orphans it killed included) until none is left or the deadline: unreaped,
    they were zombies that init inherits and reaps when it will (seen seconds later in a container), which a check
    for survivors counts as alive (issue 46's twelfth attack)."""
    while True:
        try:
            pid, _ = os.waitpid(-1, os.WNOHANG)
        except ChildProcessError:
            return  # no child left
        if pid == 0:  # children left, none ended yet
            if time.monotonic() >= deadline:
                return
            time.sleep(0.005)


def _kill_all(scan: Callable[[], list[int]]) -> None:
    """SIGKILL every process scan() finds, scanned again after each kill (what one forked between the scan and its
    kill is found by the next), at most _KILL_ROUNDS times, never a pid twice."""
    killed: set[int] = set()
    for _ in range(_KILL_ROUNDS):
        left = [pid for pid in scan() if pid not in killed]
        if not left:
            return
        for pid in left:
            try:
                os.kill(pid, signal.SIGKILL)
            except OSError:
                pass
        killed.update(left)


def _descendants(root: int) -> list[int]:
    """The live descendants of root (by parent links only, from one scan of /proc; none where there is no /proc)."""
    children: dict[int, list[int]] = {}
    alive = set()
    try:
        entries = [entry.name for entry in Path("/proc").iterdir() if entry.name.isdigit()]
    except OSError:
        return []
    for name in entries:
        try:
            with open(f"/proc/{name}/stat", "rb") as stat:
                state, ppid = stat.read().rsplit(b")", 1)[1].split()[:2]
        except (OSError, ValueError):
            continue
        children.setdefault(int(ppid), []).append(int(name))
        if state != b"Z":
            alive.add(int(name))
    found, todo = set(), [root]
    while todo:
        for child in children.get(todo.pop(), []):
            if child not in found:
                found.add(child)
                todo.append(child)
    return sorted(found & alive)


def _marked(pid: str, mark: bytes) -> bool:
    try:
        with open(f"/proc/{pid}/environ", "rb") as environ:
            return mark in environ.read().split(b"\0")
    except OSError:  # gone, or another user's
        return False


def _group_members(leader: int, marker: str | None = None) -> list[int]:
    """The live processes a worker (leader) answers for, from one scan of /proc (Linux; elsewhere none are known):
    its descendants, whatever group or session they moved to (the orphans among them are its children: it is their
    subreaper), the members of its group and of any group one of them leads, and theirs in turn; with a marker also
    the processes whose environment carries it (WORKER_ENV) and theirs. Never the calling process."""
    try:
        entries = [entry.name for entry in Path("/proc").iterdir() if entry.name.isdigit()]
    except OSError:
        return []
    mark = f"{WORKER_ENV}={marker}".encode() if marker is not None else None
    alive, found = set(), {leader}
    children: dict[int, list[int]] = {}
    members: dict[int, list[int]] = {}
    for name in entries:
        try:
            with open(f"/proc/{name}/stat", "rb") as stat:
                state, ppid, group = stat.read().rsplit(b")", 1)[1].split()[:3]  # after the name
        except (OSError, ValueError):
            continue
        pid = int(name)
        children.setdefault(int(ppid), []).append(pid)
        members.setdefault(int(group), []).append(pid)
        if state != b"Z":  # a zombie is walked through (a group it led lives on), not killed
            alive.add(pid)
        if mark is not None and _marked(name, mark):
            found.add(pid)
    todo = list(found)
    while todo:  # the closure over "child of" and "member of a group led by"
        pid = todo.pop()
        for other in children.get(pid, []) + members.get(pid, []):
            if other not in found:
                found.add(other)
                todo.append(other)
    found.discard(os.getpid())
    return sorted(found & alive)


def end_group() -> None:
    """Before a worker exits: kill the other processes of its group (what a plug-in started and left), where it leads
    one (own_process_group); a process in someone else's group (a worker the tests made by hand) kills nothing."""
    me = os.getpid()
    if hasattr(os, "getpgrp") and os.getpgrp() == me:
        end_group_of(me)


def end_group_of(leader: int, marker: str | None = None) -> None:
    """Kill the processes leader answers for (_group_members) but the leader (the pool's thread at shutdown, before it
    ends: a worker that thread started dies by its parent-death signal when it ends, before it can end its group).
    Scanned again after a kill: what a process forked between the scan and its kill is an orphan of the worker now."""
    _kill_all(lambda: [pid for pid in _group_members(leader, marker) if pid != leader])


def kill_group(leader: int, marker: str | None = None) -> None:
    """The parent's end of a worker: SIGKILL what it answers for (end_group_of; marker: the worker's WORKER_ENV, for
    one that died), then its process group (the worker, as long as it is not reaped, keeps the group's id from being
    reused); nothing where it has none."""
    end_group_of(leader, marker)
    if hasattr(os, "killpg"):
        try:
            os.killpg(leader, signal.SIGKILL)
        except OSError:  # no such group (it never made it, or every member is gone)
            pass


def _watch(target, argument) -> None:
    threading.Thread(target=target, args=(argument,), name=f"exit-with-parent-{target.__name__}", daemon=True).start()


def exit_with_parent() -> None:
    """The pool initializer's tie, whatever the start method: the parent-death signal on the process's parent, and a
    thread that waits on multiprocessing's parent sentinel (the pipe from the process that made the pool: for the
    forkserver method not the parent, which dies with it). Exits now when that process is gone already."""
    import multiprocessing

    parent_death_signal()
    parent = multiprocessing.parent_process()
    if parent is None:  # not a multiprocessing child (called by hand): watch the parent's pid
        _watch(_watch_pid, os.getppid())
    else:
        _watch(_watch_sentinel, parent.sentinel)


def is_worker() -> bool:
    """Whether this process is a worker that starting_workers started by spawn or forkserver (not a fork: a forked
    worker runs no import, its pool initializer ties it)."""
    return bool(os.environ.get(PARENT_ENV)) and "--multiprocessing-fork" in getattr(sys, "orig_argv", ())


def worker_started() -> None:
    """The first thing a spawned worker does (stereodyn/__init__.py): ignore Ctrl-C, tie itself to its parent, and
    name itself the parent of any process it starts."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})  # ignored now: a pending one is dropped
    parent = int(os.environ[PARENT_ENV])
    parent_death_signal()
    if os.getppid() != parent:  # it died before the signal was armed (the signal covers every moment after)
        os._exit(1)
    _watch(_watch_pid, parent)
    os.environ[PARENT_ENV] = str(os.getpid())


@contextmanager
def starting_workers() -> Iterator[None]:
    """Around the code that starts worker processes: they know their parent (PARENT_ENV), start with Ctrl-C blocked,
    and their resource tracker does not warn about what a killed process left. In this process a Ctrl-C meanwhile
    is held and delivered at the end of the block (none is lost)."""
    os.environ[PARENT_ENV] = str(os.getpid())
    warnings = os.environ.get("PYTHONWARNINGS", "")
    if _TRACKER_WARNING not in warnings.split(","):
        os.environ["PYTHONWARNINGS"] = ",".join(w for w in (warnings, _TRACKER_WARNING) if w)
    # The resource tracker first: starting it unblocks SIGINT in the calling thread (multiprocessing's own
    # ensure_running), which would leave the workers started after it deaf to nothing.
    from multiprocessing import resource_tracker

    resource_tracker.ensure_running()
    blocked = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, blocked)


# ------------------------------------------------------------------------------------------------------- Ctrl-C
_interrupts: list[int] = []  # the signals (SIGINT, SIGTERM) this process took, in order (on_interrupt)


def interrupted_while_loading(signum, frame) -> None:
    """SIGINT, SIGTERM or SIGHUP while the command's modules load (harness/cli/__init__.py puts it): one line, exit
    130 (128 + the signal's number for the others), as after loading (on_interrupt, harness.cli)."""
    sys.stderr.write("stereodyn: interrupted\n" if signum == signal.SIGINT else
                     f"stereodyn: terminated ({signal.Signals(signum).name})\n")
    os._exit(128 + signum)


def on_interrupt(signum, frame) -> None:
    """The command's SIGINT and SIGTERM handler: remember the signal, then raise KeyboardInterrupt as Python's own
    does for SIGINT, so that a SIGTERM ends the workers and what they started as Ctrl-C does (its default ended the
    command alone: a plug-in's detached child outlived it; issue 46's fifth attack). An SDK that swallows or rewraps
    the KeyboardInterrupt (pybind11 turns one during a module's init into ImportError: "initialization failed")
    cannot make the command end as if nothing happened: it ends with 130, or 143 for SIGTERM (harness.cli)."""
    _interrupts.append(signum)
    raise KeyboardInterrupt


def terminated() -> int | None:
    """The last signal this process took where it was not SIGINT (SIGTERM, SIGHUP: on_interrupt), else None: the
    command ends with 128 + its number, not 130."""
    return _interrupts[-1] if _interrupts and _interrupts[-1] != signal.SIGINT else None


def forget_interrupts() -> None:
    """A new command starts (harness.cli.main, also called in-process by tests)."""
    _interrupts.clear()


def interrupted() -> bool:
    """Whether this process took a Ctrl-C or a SIGTERM (on_interrupt)."""
    return bool(_interrupts)


on_interrupt.took_ctrl_c = interrupted  # reference.plugins.code_raised asks the handler (reference/ imports no harness/)


def raise_if_interrupted(exc: BaseException) -> None:
    """In an `except Exception` that records a failure as data: a failure the interrupt caused is no data."""
    if interrupted():
        raise KeyboardInterrupt from exc


def plugin_fault(exc: BaseException) -> bool:
    """Whether exc, not an Exception, is a plug-in's way out that its run's failure must hold (SystemExit,
    GeneratorExit, a KeyboardInterrupt its code raised: reference.plugins.code_raised), rather than Ctrl-C or our bug."""
    if isinstance(exc, KeyboardInterrupt):
        return code_raised(exc)
    return isinstance(exc, (SystemExit, GeneratorExit))


def raise_unless_data(exc: BaseException) -> None:
    """In an `except Exception` that records a failure as data: neither a failure the interrupt caused nor a bug in
    stereodyn's own code (harness.errors) is data."""
    raise_if_interrupted(exc)
    raise_if_internal(exc)
