"""Wall-time budgets: every run, its preparation and every truth end in bounded time.

A budget is a deadline on time.monotonic(), held in a context variable while a run, a preparation or a truth is computed
(`within`). The loops stereodyn drives check it: the harness's integrators every CHECK_EVERY steps, scipy's methods
every step, MuJoCo between rollout chunks and in its Python step loops, Pinocchio's ladder loop, Drake between samples
or through its simulator's monitor, heyoka through its step callback (reference.* take the deadline as an argument,
since `reference/` never imports the harness). Past the deadline they raise BudgetExceeded (reference.*: OutOfTime),
which the sweep turns into a `failed` row whose message names the budget and the flag that raises it (`failed_row`); the
store keeps which budget it was, so `--resume` redoes the run only when that budget was raised (`still_holds`).
Outside `within` there is no deadline, and a check costs one context-variable read.

The checks are cooperative; what makes them a guarantee is the pool (harness/run/workers.py): a worker tells its parent
each deadline it enters (`watch`), and the parent ends a worker still running a budget's grace after its deadline
(`grace`), whatever it is doing (a plug-in's loop that never checks, a sleep, one long compiled call).

A plug-in engine whose own loop runs long calls `check()` (or compares `deadline()`) in it; model building and
compilation (`Engine.prepare`) have their own budget (`prepared`), checked when prepare returns.
"""
from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass

from ..reference.deadline import OutOfTime

# Defaults (docs/limits.md, "Time"). The suite's longest accuracy run (an extreme case's 1e6 steps of a Python-stepped
# integrator) takes ~15 s on the 2-core dev machine; its longest truth ~10 s with its real128 certification; model
# building ~0.2 s (heyoka's compact-mode JIT), an XLA/Warp compilation tens of seconds.
RUN_BUDGET_S = 60.0      # the accuracy run of one row: its simulation, metrics and the checks' perturbed reruns
PREPARE_BUDGET_S = 120.0  # Engine.prepare: model building and compilation
TRUTH_BUDGET_S = 120.0    # one case's truth: the double-precision propagation and its real128 certification
# What --run-budget, --prepare-budget and --truth-budget accept, s: a millisecond to about eleven days.
MIN_BUDGET_S, MAX_BUDGET_S = 1e-3, 1e6
# How often the harness's own step loops look at the clock (steps); ~0.1 µs a look against >= 1 µs a step.
CHECK_EVERY = 256

FLAGS = {"run": "--run-budget", "prepare": "--prepare-budget", "truth": "--truth-budget"}
# How long past its deadline a pool worker still runs before its parent ends it (grace): a loop that checks stops within
# milliseconds of the deadline (a look every CHECK_EVERY steps, MuJoCo's 10 000-step chunks; ~8x that on a loaded
# machine), so only a run that does not check meets the grace. Ending one too early would cost a new worker (~3 s of
# imports), not a different sweep row: a run ended by the parent fails with its budget's message, as one that stopped
# itself. The 10 % keeps long budgets (a 600 s compilation) from being ended for a second's lateness.
GRACE_MIN_S, GRACE_FRACTION = 2.0, 0.1


@dataclass(frozen=True)
class Budgets:
    """The wall-time budgets of a sweep, s: run_s per row's accuracy run, prepare_s per Engine.prepare, truth_s per
    case's truth (stereodyn run --run-budget, --prepare-budget, --truth-budget)."""

    run_s: float = RUN_BUDGET_S
    prepare_s: float = PREPARE_BUDGET_S
    truth_s: float = TRUTH_BUDGET_S

    def seconds(self, what: str) -> float:
        return {"run": self.run_s, "prepare": self.prepare_s, "truth": self.truth_s}[what]


class BudgetExceeded(OutOfTime):
    """A run, preparation or truth went past its wall-time budget. what: "run", "prepare" or "truth". A reference.*
    propagation stopped at the deadline (OutOfTime) leaves `within` as this."""

    def __init__(self, what: str, seconds: float):
        self.what, self.seconds = what, float(seconds)
        super().__init__(message(what, seconds))


def message(what: str, seconds: float) -> str:
    """The row's message: which budget, how large, and the flag that raises it."""
    return f"{what} budget exceeded: stopped after {seconds:g} s of wall time ({FLAGS[what]} raises it)"


def grace(seconds: float) -> float:
    """How long past a budget of `seconds` a pool worker may still run before its parent ends it, s: 10 % of the
    budget, at least 2 s."""
    return max(GRACE_MIN_S, GRACE_FRACTION * seconds)


_ACTIVE: ContextVar[tuple[float, str, float] | None] = ContextVar("stereodyn_budget", default=None)
# Who hears of each change of this process's deadline (a pool worker's parent: watch), or None.
_WATCHER: list[Callable[[tuple[float, str, float] | None], None] | None] = [None]


def watch(report: Callable[[tuple[float, str, float] | None], None] | None) -> None:
    """Call report((seconds left, what, budget seconds)) whenever a deadline starts to hold, report(None) when none
    holds any more (a pool worker's initializer: harness/run/workers.py); None stops reporting."""
    _WATCHER[0] = report


def _tell(active: tuple[float, str, float] | None) -> None:
    report = _WATCHER[0]
    if report is not None:
        report(None if active is None else (active[0] - time.monotonic(), active[1], active[2]))


@contextmanager
def within(what: str, seconds: float) -> Iterator[None]:
    """Hold a deadline `seconds` from now for the block (nested: the earlier deadline wins)."""
    deadline = time.monotonic() + seconds
    outer = _ACTIVE.get()
    active = (deadline, what, seconds) if outer is None or deadline < outer[0] else outer
    token = _ACTIVE.set(active)
    if active is not outer:
        _tell(active)
    try:
        yield
    except OutOfTime as exc:
        if isinstance(exc, BudgetExceeded):
            raise
        raise BudgetExceeded(active[1], active[2]) from None
    finally:
        _ACTIVE.reset(token)
        if active is not outer:
            _tell(outer)


def deadline() -> float | None:
    """The current deadline (time.monotonic() seconds), or None outside `within`."""
    active = _ACTIVE.get()
    return None if active is None else active[0]


def check() -> None:
    """Raise BudgetExceeded when the current deadline has passed."""
    active = _ACTIVE.get()
    if active is not None and time.monotonic() > active[0]:
        raise BudgetExceeded(active[1], active[2])


def pieces(start: int, stop: int) -> Iterable[range]:
    """range(start, stop) in pieces of CHECK_EVERY, the budget checked before each: a Python step loop's way to stop
    in time (`for piece in pieces(done, target): for k in piece: ...`)."""
    active = _ACTIVE.get()
    if stop - start <= CHECK_EVERY:
        # the usual span between two samples: one piece, no generator (a fixed-step run with a sample every step
        # calls this once a step; the generator cost ~0.4 µs a call, 1.5% of a profiled reference sweep)
        if active is not None and time.monotonic() > active[0]:
            raise BudgetExceeded(active[1], active[2])
        return (range(start, stop),)
    return _pieces(start, stop, active)


def _pieces(start: int, stop: int, active: tuple[float, str, float] | None) -> Iterator[range]:
    for first in range(start, stop, CHECK_EVERY):
        if active is not None and time.monotonic() > active[0]:
            raise BudgetExceeded(active[1], active[2])
        yield range(first, min(first + CHECK_EVERY, stop))


_CONFIGURED = [Budgets()]  # this process's budgets: `stereodyn run`'s flags, a pool worker's from its parent


def configure(budgets: Budgets) -> None:
    """Set this process's budgets (the command line; a pool worker's initializer)."""
    _CONFIGURED[0] = budgets


def configured() -> Budgets:
    return _CONFIGURED[0]


def prepared(make, seconds: float | None = None):
    """make() (an Engine.prepare) under the prepare budget; BudgetExceeded when it took longer, even where it could
    not be stopped inside (a compilation in C++)."""
    seconds = configured().prepare_s if seconds is None else seconds
    start = time.monotonic()
    with within("prepare", seconds):
        made = make()
    if time.monotonic() - start > seconds:
        raise BudgetExceeded("prepare", seconds)
    return made


def failed_row(exc: BudgetExceeded) -> dict:
    """The columns of a row stopped by its budget, and the private `_budget` the store keeps ({"what", "seconds"})."""
    return {"status": "failed", "message": str(exc), "_budget": {"what": exc.what, "seconds": exc.seconds}}


def still_holds(stopped: object, budgets: Budgets) -> bool:
    """Whether a stored run stopped by a budget (its record's "budget": {"what", "seconds"}) would stop again: the
    budget it exceeded was not raised since. A record without one (None) holds."""
    if stopped is None:
        return True
    try:
        return budgets.seconds(stopped["what"]) <= float(stopped["seconds"])
    except (TypeError, KeyError, ValueError):
        return False  # not what this version writes: redo the run


def exceeded() -> BudgetExceeded:
    """The exception for the current budget (a loop that found its deadline passed, or reference.* out of time)."""
    active = _ACTIVE.get()
    return BudgetExceeded("run", RUN_BUDGET_S) if active is None else BudgetExceeded(active[1], active[2])
