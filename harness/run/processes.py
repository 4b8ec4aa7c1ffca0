"""Worker processes that never outlive the command: a pool worker exits within PARENT_POLL_S of its parent's death.

A SIGKILLed parent cannot end its pool; spawned workers then wait on their task queue forever (two idle ~185 MB
workers and the multiprocessing resource tracker were seen alive 4 minutes after a SIGKILL), and the tracker lives as
long as they do. Each worker therefore watches its parent from a daemon thread and exits when it is gone.
"""
from __future__ import annotations

import os
import threading
import time

PARENT_POLL_S = 0.5   # a killed sweep's workers are gone ~0.5 s later, well inside the 5 s the issue allows


def _watch(parent: int) -> None:
    while True:
        time.sleep(PARENT_POLL_S)
        if os.getppid() != parent:  # re-parented (to init or a subreaper): the parent is dead
            os._exit(1)


def exit_with_parent() -> None:
    """Start the watch in this (worker) process; a pool initializer, or called first by one."""
    threading.Thread(target=_watch, args=(os.getppid(),), name="exit-with-parent", daemon=True).start()
