"""A ladder point's truth, its single time, and the one timing phase of the dt ladders, the tolerance ladders and the
advice: below both ladders' modules, so that tolerance_ladders reads them without the dt ladders (which re-export
them, their home before issue 29)."""
from __future__ import annotations

import functools

from ..scenes import scene_of
from ..run import timing
from ..run.measure import prepare as prepare_run
from ..run.pool import pool_timer
from ..run.spec import Family
from ..run.workers import WatchedPool

TIMING_REPEATS, TIMING_BUDGET_S = 3, 0.3


def case_truth_on(run) -> object:
    """The truth of a run's case on the run's own grid (its scene's Scene.truth), uncertified."""
    return scene_of(run.case).truth(run.case, [run.grid], False)


def _timed(sim, grid, run) -> dict:
    """A point timed once in its worker, right after its accuracy run (timing.single_time): timing SINGLE."""
    return timing.columns(timing.Timing(timing.single_time(sim, grid, run), 0.0, 1), grid.t_end)


def time_points(points: list[dict], families_by_key: dict[tuple, Family], setting: str = "dt",
                pool: WatchedPool | None = None) -> None:
    """The timing phase of the dt ladders, the tolerance ladders and the advice, its one home (harness.run.timing.
    time_points: best of TIMING_REPEATS, each timing on a core no other timing shares): on the pool's workers
    (pool.time_on_pool; None: here), each point's run prepared again from its family (families_by_key: Family.key ->
    Family) at the point's setting, "dt" or "tolerance"."""
    prepare = functools.partial(prepare_point, families_by_key, setting)
    elsewhere, ways = pool_timer(pool)
    timing.time_points(points, prepare, TIMING_REPEATS, TIMING_BUDGET_S, elsewhere=elsewhere, ways=ways)


def prepare_point(families_by_key: dict[tuple, Family], setting: str, row: dict) -> tuple:
    """(simulation, grid) of a ladder point's run, from its family at the point's setting (a function of the module,
    so that a worker that times the point unpickles it)."""
    family = families_by_key[(row["case"], row["engine"], row["formulation"], row["integrator"], row["precision"])]
    return prepare_run(family.run(**{setting: row[setting]}))
