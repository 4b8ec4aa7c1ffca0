"""The truths of a sweep's cases, each computed once in the parent by the case's scene on every grid its runs use."""
from __future__ import annotations

from typing import Callable

from .. import budget
from ..grid import TimeGrid, time_grid
from ..scenes import scene_of
from ..trajectory import Status
from .processes import raise_unless_data
from .spec import RunKey


def case_grids(case) -> list[TimeGrid]:
    """Every grid a sweep's runs of the case sample: one per dt of its list, and the adaptive runs' (RunKey.grid)."""
    return [time_grid(case.t_end, dt, case.samples) for dt in case.dt] + [RunKey(case, "", "").grid]


def case_truth(case, certify: bool, budget_s: float | None = None):
    """The case's truth on all its grids (its scene's Scene.truth; None for a scene without one), within the truth
    budget (budget_s, default this process's: harness.budget)."""
    with budget.within("truth", budget.configured().truth_s if budget_s is None else budget_s):
        return scene_of(case).truth(case, case_grids(case), certify)


def sweep_truths(cases: list, needed: Callable[[object], bool], certify: bool, phase: Callable[[str], None],
                 failed: Callable[[object, dict], None], budgets: budget.Budgets | None = None) -> dict:
    """case name -> truth of every case with runs still to do (needed(case)). A truth that cannot be computed fails
    its case's runs, as data: failed(case, the failure's columns); one stopped by its budget says so (`_budget`),
    so that --resume redoes it once the budget is raised."""
    budgets = budgets or budget.configured()
    truths = {}
    for case in cases:
        if not needed(case):
            continue
        if scene_of(case).needs_truth:
            phase(f"truth {case.name}")
        try:
            truths[case.name] = case_truth(case, certify, budgets.truth_s)
        except budget.BudgetExceeded as exc:
            failed(case, {**budget.failed_row(exc), "message": f"truth failed: {exc}"})
        except Exception as exc:
            raise_unless_data(exc)
            failed(case, {"status": Status.FAILED.value,
                          "message": f"truth failed: {type(exc).__name__}: {exc}".splitlines()[0]})
    return truths
