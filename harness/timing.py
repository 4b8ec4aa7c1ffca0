"""Stepping time, measured apart from accuracy (DESIGN §6.4): best of N timed runs after a warm-up, metrics off."""
from __future__ import annotations

import gc
import time
from typing import Callable

REPEATS = 3          # timed runs at most
BUDGET_S = 2.0       # stop repeating once the timed runs have taken this long (at least one always runs)


def best_time(run: Callable[[], object], repeats: int = REPEATS, budget_s: float = BUDGET_S) -> float:
    """Best wall time (s) of up to `repeats` calls of run(), within `budget_s`; the caller has already warmed it up.

    The garbage collector is off while timing (as timeit does) so a collection does not land in one repeat.
    """
    best, spent = float("inf"), 0.0
    enabled = gc.isenabled()
    gc.disable()
    try:
        for _ in range(max(1, repeats)):
            start = time.perf_counter()
            run()
            elapsed = time.perf_counter() - start
            best, spent = min(best, elapsed), spent + elapsed
            if spent >= budget_s:
                break
    finally:
        if enabled:
            gc.enable()
    return best
