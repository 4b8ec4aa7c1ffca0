"""Tolerance ladders: every adaptive integrator of every engine (Engine.adaptive) run at a sweep of requested
tolerances, per point the error achieved and the cost.

For a case × engine × formulation × adaptive integrator (an AdaptiveFamily), a ladder is one run per tolerance of
TOLERANCES (1e-3 ... 1e-13, a decade apart; the default run's DEFAULT_TOLERANCES: two decades apart), each prepared
with Engine.prepare(..., tolerance=tol) (the contract of harness.engines.base: rtol = atol = tol) and run on the
grid of the sweep's adaptive rows (RunKey.grid, harness.run.spec). Each point is one untimed accuracy run (errors
against the truth on the same sample times, as the dt ladders define them: state_err = max(attitude_err, omega_err,
casimir_drift)) and separate timed runs, taken in rounds over all the points after every accuracy run
(harness.analysis.dt_ladders.time_points' protocol), costed as µs of stepping per simulated second, right-hand-side
evaluations and steps per simulated second. The truth row itself (heyoka's taylor on the quaternion at its default,
truth-grade tolerance) is not a ladder point: every point names its tolerance, and heyoka's taylor joins at the
loose ones like any other adaptive method.

A ladder walks from loose to tight and stops early, saying so in the last point's message, once a point's accuracy
run took longer than POINT_BUDGET_S (the tighter points would each take longer still). The fits (tolerance
proportionality, error below the tolerance) are harness.analysis.fitting.tolerance_fit.

The ladders run on the sweep's process pool (harness.run.sweep.worker_pool), one task per family.
"""
from __future__ import annotations

import math
from concurrent.futures import as_completed
from typing import Callable

from .. import budget
from ..engines import get_engine
from ..engines.base import FLOAT64
from ..scenes.cases import Case
from ..scenes.rigid_body import state_err
from ..trajectory import Status
from ..run import timing
from ..run.measure import measure as run_measure, prepare as prepare_run, rate
from ..run.processes import raise_unless_data
from ..run.workers import WatchedPool
from .dt_ladders import TIMING_BUDGET_S, TIMING_REPEATS, Family, case_truth_on

TOLERANCE_COLUMNS = ("case", "engine", "formulation", "integrator", "precision", "tolerance", "t_end", "steps", "rhs_evals",
                     "status", "message", "attitude_err", "attitude_err_end", "omega_err", "casimir_drift",
                     "energy_drift", "state_err", "err_over_tol", "wall_s", "us_per_sim_s", "us_per_sim_s_spread",
                     "rhs_per_sim_s", "steps_per_sim_s")
TOLERANCES = tuple(10.0 ** -k for k in range(3, 14))  # --dt-ladder: every decade
# The default run's ladders: every other decade, which halves their cost (~0.5 min on two cores, most of it Radau's
# and BDF's tight points) and still spans the range.
DEFAULT_TOLERANCES = TOLERANCES[::2]
# A point whose accuracy run took longer than this (s) ends its ladder: each tighter tolerance costs more. Measured on
# the 2-core dev machine (default ladder cases, t_end 20): the scipy methods' points take 0.005-3 s, BDF's and
# Radau's at 1e-12 the longest.
POINT_BUDGET_S = 5.0


AdaptiveFamily = Family  # runs of one adaptive integrator that differ only in the requested tolerance


def families(cases: list[Case], engines: list[str], integrators: list[str] | None,
             formulations: tuple[str, ...] | None = None) -> list[AdaptiveFamily]:
    """Every adaptive integrator (Engine.adaptive) of the engines, on each formulation and case the engine models;
    integrators: the names chosen (None: all of them, whatever the sweep's default). formulations: only these (an
    engine with formulations but none of these: its first), None: all."""
    out = []
    for name in engines:
        engine = get_engine(name)
        chosen = [i for i in engine.integrators() if engine.adaptive(i) and (integrators is None or i in integrators)]
        own = tuple(engine.formulations()) or ("",)
        if formulations is not None:
            own = tuple(f for f in own if f in formulations) or own[:1]
        for case in cases:
            if engine.unsupported(case):
                continue
            for integrator in chosen:
                for formulation in own:
                    if engine.unsupported_run(case, formulation, integrator):
                        continue
                    for precision in engine.precisions(integrator):
                        out.append(AdaptiveFamily(case, name, formulation, integrator, precision))
    return out


# ------------------------------------------------------------------------------------------------ one point

def measure(family: AdaptiveFamily, tolerance: float, truth=None) -> dict:
    """One ladder point's accuracy run (measure.measure, untimed): errors against the truth (the case's truth on the
    family's grid, dt_ladders.case_truth_on; computed here when None), drifts, steps and evaluations. Never raises;
    the run's wall time goes to `_accuracy_s` (for the ladder's budget, not a timing)."""
    run = family.run(tolerance=float(tolerance))
    row = {"tolerance": float(tolerance)}
    try:
        if truth is None:
            with budget.within("truth", budget.configured().truth_s):
                truth = case_truth_on(run)
    except budget.BudgetExceeded as exc:  # the ladder stops here (run_ladder: the point took longer than its budget)
        return {**_failed_point(family, tolerance, str(exc)), "_accuracy_s": math.inf}
    except Exception as exc:
        raise_unless_data(exc)
        return {**_failed_point(family, tolerance, f"truth failed: {type(exc).__name__}: {exc}"), "_accuracy_s": 0.0}
    measured = run_measure(run, truth, full=False)
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
        return [_failed_point(family, tolerances[0], f"truth failed: {exc}")]
    except Exception as exc:
        raise_unless_data(exc)
        return [_failed_point(family, tolerances[0], f"truth failed: {type(exc).__name__}: {exc}")]
    points = []
    for tolerance in sorted(tolerances, reverse=True):
        row = measure(family, tolerance, truth)
        points.append(row)
        if row["_accuracy_s"] > budget_s and tolerance != min(tolerances):
            stop = f"ladder stopped after this point: its run took {row['_accuracy_s']:.3g} s (> {budget_s:g} s)"
            row["message"] = "; ".join(x for x in (row.get("message", ""), stop) if x)
            break
    return points


def _failed_point(family: AdaptiveFamily, tolerance: float, message: str) -> dict:
    return {**family.columns, "tolerance": float(tolerance), "status": Status.FAILED.value,
            "message": message.splitlines()[0]}


def time_points(points: list[dict], families_by_key: dict[tuple, AdaptiveFamily]) -> None:
    """The timing phase, as the dt ladders' (harness.run.timing.time_points)."""
    def prepare(row: dict):
        family = families_by_key[(row["case"], row["engine"], row["formulation"], row["integrator"],
                                  row["precision"])]
        return prepare_run(family.run(tolerance=row["tolerance"]))

    timing.time_points(points, prepare, TIMING_REPEATS, TIMING_BUDGET_S)


def _ladder_cost(family: AdaptiveFamily) -> float:
    """Rank of a family's cost, to start the costliest first: the engine's cost of a step (Engine.pass_us)."""
    return get_engine(family.engine).pass_us


def run_ladders(chosen: list[AdaptiveFamily], pool: WatchedPool | None = None,
                progress: Callable[[str], None] | None = None,
                tolerances: tuple[float, ...] = TOLERANCES, budget_s: float = POINT_BUDGET_S) -> list[dict]:
    """Every family's ladder, its accuracy runs in this process (pool None) or on the sweep's pool, then its points
    timed here (time_points). Returns the points (TOLERANCE_COLUMNS) in the order of `chosen`, each family's loose
    to tight. budget_s: run_ladder's point budget."""
    results: dict[int, list[dict]] = {}
    order = sorted(range(len(chosen)), key=lambda i: _ladder_cost(chosen[i]), reverse=True)
    if pool is None:
        for index in order:
            results[index] = run_ladder(chosen[index], tolerances, budget_s)
            if progress:
                progress(chosen[index].label)
    else:
        futures = {pool.submit(run_ladder, chosen[index], tolerances, budget_s): index for index in order}
        for future in as_completed(futures):
            index = futures[future]
            try:
                results[index] = future.result()
            except Exception as exc:  # a worker that died: one failed point says why
                raise_unless_data(exc)
                results[index] = [_failed_point(chosen[index], max(tolerances),
                                                f"worker failed: {type(exc).__name__}: {exc}")]
            if progress:
                progress(chosen[index].label)
    points = [point for index in range(len(chosen)) for point in results[index]]
    time_points(points, {f.key: f for f in chosen})
    return [{k: v for k, v in point.items() if not k.startswith("_")} for point in points]


def tolerance_frame(points: list[dict]):
    """The points as tolerance.csv's table (TOLERANCE_COLUMNS, NaN where a column does not apply)."""
    import pandas as pd

    df = pd.DataFrame(points, columns=list(TOLERANCE_COLUMNS))
    return df.fillna({"formulation": "", "message": "", "precision": FLOAT64}).astype({"tolerance": float})


__all__ = ["AdaptiveFamily", "DEFAULT_TOLERANCES", "POINT_BUDGET_S", "TOLERANCES", "TOLERANCE_COLUMNS", "families",
           "measure", "run_ladder", "run_ladders", "time_points", "tolerance_frame"]
