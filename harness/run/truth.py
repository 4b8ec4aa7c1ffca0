"""The truths of a sweep's cases, each computed once in the parent by the case's scene on every grid its runs use."""
from __future__ import annotations

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


def truth_failure(exc: Exception) -> dict:
    """The columns that fail a case's runs when its truth raised `exc` (here or in a worker): the budget's failure
    (`_budget`, so that --resume redoes it once the budget is raised), else the error's first line; a truth whose
    worker died fails them unstored (`_lost`: --resume tries again, the cause may have passed). Our own bug raises."""
    if isinstance(exc, budget.BudgetExceeded):
        return {**budget.failed_row(exc), "message": f"truth failed: {exc}"}
    raise_unless_data(exc)
    lost = {"_lost": True} if type(exc).__name__ == "WorkerDied" else {}
    return {"status": Status.FAILED.value, **lost,
            "message": f"truth failed: {type(exc).__name__}: {exc}".splitlines()[0]}
