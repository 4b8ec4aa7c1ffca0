"""Tasks for the watched pool's workers in tests/test_hung_engines.py: a helper module, importable in a spawned worker
(the test modules themselves are not: pytest imports them with --import-mode=importlib)."""
import ctypes
import time

from stereodyn.harness import budget


def sleeps(what: str, seconds: float) -> None:
    with budget.within(what, seconds):
        time.sleep(1000)


def spins(what: str, seconds: float) -> None:
    with budget.within(what, seconds):
        while True:  # never looks at the clock
            pass


def sleeps_in_c(what: str, seconds: float) -> None:
    with budget.within(what, seconds):
        ctypes.CDLL(None).sleep(1000)  # one call that never returns to Python: no signal handler could stop it


def within_then_outside(seconds: float) -> str:
    """A budget left in time, then longer than budget + grace outside any budget."""
    with budget.within("run", seconds):
        pass
    time.sleep(seconds + budget.grace(seconds) + 0.5)
    return "done"

