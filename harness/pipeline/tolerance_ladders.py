"""Tolerance ladders, the runs (their tables and constants: harness.analysis.ladders, re-exported here): every
adaptive integrator of every engine (Offer.adaptive) run at a sweep of requested tolerances, per point the error
achieved and the cost.

For a case × engine × formulation × adaptive integrator (an AdaptiveFamily), a ladder is one run per tolerance of
TOLERANCES (1e-3 ... 1e-13, a decade apart; the default run's DEFAULT_TOLERANCES: two decades apart), each prepared
with Engine.prepare(..., tolerance=tol) (the contract of harness.engines.base: rtol = atol = tol) and run on the
grid of the sweep's adaptive rows (RunKey.grid, harness.run.spec). Each point is one untimed accuracy run (errors
against the truth on the same sample times, as the dt ladders define them: state_err = max(attitude_err, omega_err,
casimir_drift)) and separate timed runs, taken in rounds over all the points after every accuracy run
(harness.pipeline.points.time_points, the one timing phase of the ladders and the advice), costed as µs of
stepping per simulated second, right-hand-side evaluations and steps per simulated second. The truth row itself
(heyoka's taylor on the quaternion at its default, truth-grade tolerance) is not a ladder point: every point names its
tolerance, and heyoka's taylor joins at the loose ones like any other adaptive method.

A ladder walks from loose to tight and stops early, saying so in the last point's message, once a point's accuracy
run took longer than POINT_BUDGET_S (the tighter points would each take longer still). The fits (tolerance
proportionality, error below the tolerance) are harness.analysis.fitting.tolerance_fit.

The ladders run on the sweep's process pool (harness.run.sweep.worker_pool), one task per family.
"""
from __future__ import annotations

import math
from concurrent.futures import Future, as_completed
from typing import Callable

from .. import budget
from ..analysis.ladders import (DEFAULT_TOLERANCES, POINT_BUDGET_S, TOLERANCE_COLUMNS, TOLERANCES,  # noqa: F401
                                AdaptiveFamily, adaptive_cost, failed_point, tolerance_frame)
from ..scenes.metrics import state_err
from ..trajectory import Status
from ..run.measure import measure as run_measure, rate
from ..run.processes import raise_unless_data
from ..run.workers import WatchedPool
from .points import _timed, case_truth_on, time_points


# ------------------------------------------------------------------------------------------------ one point

def measure(family: AdaptiveFamily, tolerance: float, truth=None, timed: bool = False) -> dict:
    """One ladder point's accuracy run (measure.measure): errors against the truth (the case's truth on the family's
    grid, dt_ladders.case_truth_on; computed here when None), drifts, steps and evaluations, then with timed one timed
    run (timing SINGLE). Never raises; the accuracy run's wall time goes to `_accuracy_s` (for the ladder's budget,
    not a timing)."""
    run = family.run(tolerance=float(tolerance))
    row = {"tolerance": float(tolerance)}
    try:
        if truth is None:
            with budget.within("truth", budget.configured().truth_s):
                truth = case_truth_on(run)
    except budget.BudgetExceeded as exc:  # the ladder stops here (run_ladder: the point took longer than its budget)
        return {**failed_point(family, tolerance, str(exc)), "_accuracy_s": math.inf}
    except Exception as exc:
        raise_unless_data(exc)
        return {**failed_point(family, tolerance, f"truth failed: {type(exc).__name__}: {exc}"), "_accuracy_s": 0.0}
    measured = run_measure(run, truth, full=False, timed=_timed if timed else None)
    row.update({k: v for k, v in measured.items() if k in TOLERANCE_COLUMNS or k == "_accuracy_s"})
    row.pop("dt", None)
    if measured.get("status") != Status.FAILED.value:
        row.update(rhs_evals=measured["_rhs_evals"], rhs_per_sim_s=rate(measured["_rhs_evals"], row["t_end"]),
                   steps_per_sim_s=rate(row["steps"], row["t_end"]), state_err=state_err(measured))
        row["err_over_tol"] = row["state_err"] / float(tolerance)
    else:
        row.pop("steps", None)
    return row


def family_truth(family: AdaptiveFamily):
    """The case's truth on the family's grid (every tolerance of a family runs on one grid), under the truth budget."""
    with budget.within("truth", budget.configured().truth_s):
        return case_truth_on(family.run(tolerance=max(TOLERANCES)))


def run_ladder(family: AdaptiveFamily, tolerances: tuple[float, ...] = TOLERANCES,
               budget_s: float = POINT_BUDGET_S) -> list[dict]:
    """The accuracy runs of one family's ladder, loose to tight, stopping early (module docstring). Never raises."""
    try:
        truth = family_truth(family)
    except budget.BudgetExceeded as exc:
        return [failed_point(family, tolerances[0], f"truth failed: {exc}")]
    except Exception as exc:
        raise_unless_data(exc)
        return [failed_point(family, tolerances[0], f"truth failed: {type(exc).__name__}: {exc}")]
    points = []
    for tolerance in sorted(tolerances, reverse=True):
        row = measure(family, tolerance, truth, timed=True)
        points.append(row)
        if row["_accuracy_s"] > budget_s and tolerance != min(tolerances):
            stop = f"ladder stopped after this point: its run took {row['_accuracy_s']:.3g} s (> {budget_s:g} s)"
            row["message"] = "; ".join(x for x in (row.get("message", ""), stop) if x)
            break
    return points


def start_ladders(chosen: list[AdaptiveFamily], pool: WatchedPool, tolerances: tuple[float, ...] = TOLERANCES,
                  budget_s: float = POINT_BUDGET_S) -> dict[Future, int]:
    """Every family's ladder submitted to the pool, the costliest first: {future: index in chosen}, for
    run_ladders(started=...) to gather. Submitted before the phase's other work (pipeline.work_precision), the
    longest ladder (Drake's runge_kutta3_adaptive on free-asymmetric, ~35 s of one task) starts first instead of
    running alone at the phase's end while the other worker waits."""
    order = sorted(range(len(chosen)), key=lambda i: adaptive_cost(chosen[i]), reverse=True)
    return {pool.submit(run_ladder, chosen[index], tolerances, budget_s): index for index in order}


def run_ladders(chosen: list[AdaptiveFamily], pool: WatchedPool | None = None,
                progress: Callable[[str], None] | None = None,
                tolerances: tuple[float, ...] = TOLERANCES, budget_s: float = POINT_BUDGET_S,
                timed: bool = True, started: dict[Future, int] | None = None) -> list[dict]:
    """Every family's ladder, its accuracy runs in this process (pool None) or on the sweep's pool, each point timed
    once there, then with timed its points timed again on its workers (time_points; timed False leaves that to the caller).
    Returns the points (TOLERANCE_COLUMNS) in the order of `chosen`, each family's loose to tight. budget_s:
    run_ladder's point budget; started: start_ladders' futures of these families, where they are on the pool already."""
    results: dict[int, list[dict]] = {}
    if pool is None:
        for index in sorted(range(len(chosen)), key=lambda i: adaptive_cost(chosen[i]), reverse=True):
            results[index] = run_ladder(chosen[index], tolerances, budget_s)
            if progress:
                progress(chosen[index].label)
    else:
        futures = started if started is not None else start_ladders(chosen, pool, tolerances, budget_s)
        for future in as_completed(futures):
            index = futures[future]
            try:
                results[index] = future.result()
            except Exception as exc:  # a worker that died: one failed point says why
                raise_unless_data(exc)
                results[index] = [failed_point(chosen[index], max(tolerances),
                                                f"worker failed: {type(exc).__name__}: {exc}")]
            if progress:
                progress(chosen[index].label)
    points = [point for index in range(len(chosen)) for point in results[index]]
    if timed:
        time_points(points, {f.key: f for f in chosen}, setting="tolerance", pool=pool)
    return [{k: v for k, v in point.items() if not k.startswith("_")} for point in points]


__all__ = ["AdaptiveFamily", "DEFAULT_TOLERANCES", "POINT_BUDGET_S", "TOLERANCES", "TOLERANCE_COLUMNS", "measure",
           "run_ladder", "run_ladders", "start_ladders", "tolerance_frame"]
