"""The truths of a sweep's cases, each computed once in the parent by the case's scene on every grid its runs use."""
from __future__ import annotations

from typing import Callable

from ..grid import TimeGrid, time_grid
from ..scenes import scene_of
from .processes import raise_if_interrupted
from .spec import RunKey


def case_grids(case) -> list[TimeGrid]:
    """Every grid a sweep's runs of the case sample: one per dt of its list, and the adaptive runs' (RunKey.grid)."""
    return [time_grid(case.t_end, dt, case.samples) for dt in case.dt] + [RunKey(case, "", "").grid]


def case_truth(case, certify: bool):
    """The case's truth on all its grids (its scene's Scene.truth; None for a scene without one)."""
    return scene_of(case).truth(case, case_grids(case), certify)


def sweep_truths(cases: list, needed: Callable[[object], bool], certify: bool, phase: Callable[[str], None],
                 failed: Callable[[object, str], None]) -> dict:
    """case name -> truth of every case with runs still to do (needed(case)). A truth that cannot be computed fails
    its case's runs, as data: failed(case, reason)."""
    truths = {}
    for case in cases:
        if not needed(case):
            continue
        if scene_of(case).needs_truth:
            phase(f"truth {case.name}")
        try:
            truths[case.name] = case_truth(case, certify)
        except Exception as exc:
            raise_if_interrupted(exc)
            failed(case, f"truth failed: {type(exc).__name__}: {exc}".splitlines()[0])
    return truths
