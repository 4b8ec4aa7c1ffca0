"""Step-size advice, the runs (advice.csv; issue 21 item 2): per run family and accuracy target, the model's setting
checked by runs (analysis.step_advice.search), each run one ladder point (pipeline.dt_ladders.measure, or
pipeline.tolerance_ladders.measure for an adaptive method: the one measure path of the ladders), the advised runs then
timed on the workers, a core each (the ladders' timing phase). Which families are advised, on which known points, and the
rows' shape are analysis.step_advice's (advice_tasks, families_to_advise, advice_row; re-exported here). Used by
`stereodyn run` (pipeline.work_precision) and `stereodyn advise`.
"""
from __future__ import annotations

import math
from concurrent.futures import as_completed
from typing import Callable

import pandas as pd

from . import dt_ladders, tolerance_ladders
from ..analysis.ladders import MIN_STEPS
from ..analysis.step_advice import (ADVICE_COLUMNS, TOLERANCE_HI, TOLERANCE_LO, advice_row,  # noqa: F401 (this API)
                                    advice_tasks, advised_error, error_model, families_to_advise, family_key, rounded,
                                    search)
from ..run.pool import family_affinity
from ..run.processes import raise_unless_data
from ..run.spec import Family
from ..run.workers import WatchedPool


def advise_family(family: Family, adaptive: bool, known: list[dict], order: float, targets: tuple[float, ...],
                  max_steps: int) -> tuple[list[dict], list[dict]]:
    """The advice rows of one family for the targets (loose to tight), and the advised runs still to time (ladder
    rows: dt_ladders.LADDER_COLUMNS or tolerance_ladders.TOLERANCE_COLUMNS). known: the family's points already
    measured (sweep rows and ladder points: the setting column, steps, status, state_err, attitude_err and, where
    timed, us_per_sim_s). order: convergence.csv's fitted order, or the tolerance ladder's slope. Never raises: a
    point that breaks is data."""
    case = family.case
    what = "tolerance" if adaptive else "dt"
    frame = pd.DataFrame(known, columns=sorted({k for row in known for k in row} | {what, "steps", "status",
                                                                                     "state_err", "attitude_err"}))
    model = error_model(frame, order, what)
    if adaptive:
        lo, hi, cap = TOLERANCE_LO, TOLERANCE_HI, "the tolerance ladders' tightest"
        try:
            truth = tolerance_ladders.family_truth(family)
        except Exception as exc:  # the family's rows say why (our own bug says it louder: harness.errors)
            raise_unless_data(exc)
            return [advice_row(family, target, what, note=f"truth failed: {type(exc).__name__}: {exc}".splitlines()[0])
                    for target in targets], []
        measure = lambda s: tolerance_ladders.measure(family, s, truth)  # noqa: E731
    else:
        lo, hi, cap = case.t_end / max_steps, case.t_end / MIN_STEPS, f"t_end / {max_steps}"
        measure = lambda s: dt_ladders.measure(family, s, timed=False)  # noqa: E731
    points: dict[float, dict] = {float(row[what]): row for row in known if math.isfinite(row.get(what, math.nan))}
    errors = {s: advised_error(row) for s, row in points.items()}

    def error_at(setting: float) -> float:
        points[setting] = {k: v for k, v in measure(setting).items() if not k.startswith("_")}
        return advised_error(points[setting])

    rows, untimed = [], {}
    for target in sorted(targets, reverse=True):
        estimate = model.setting_for(target) if model is not None else math.nan
        advice = search(error_at, target, estimate, lo, hi, errors, what, cap)
        row = advice_row(family, target, what, setting=advice.setting, error=advice.error, fails_at=advice.fails_at,
                   error_fails=advice.error_fails, estimate=estimate, order=order, runs=advice.runs, note=advice.note)
        ran = points.get(advice.setting)
        row["us_per_sim_s"] = ran.get("us_per_sim_s", math.nan) if ran is not None else math.nan
        if ran is not None and not math.isfinite(row["us_per_sim_s"]):  # timed later, in the parent (run_advice)
            untimed[advice.setting] = {k: v for k, v in ran.items() if not k.startswith("_")} | {
                "case": case.name, "engine": family.engine, "formulation": family.formulation,
                "integrator": family.integrator, "precision": family.precision, what: advice.setting}
        rows.append(row)
    return rows, list(untimed.values())


def run_advice(tasks: list[tuple[Family, bool, list[dict], float]], targets: tuple[float, ...], max_steps: int,
               pool: WatchedPool | None = None,
               progress: Callable[[str], None] | None = None) -> pd.DataFrame:
    """advice.csv's table for tasks (family, adaptive, known points, order): the searches in this process (pool
    None) or on the sweep's pool, one task per family, then the advised runs not yet timed timed on the pool's
    workers, a core each (here without a pool), in rounds (the ladders' timing phase)."""
    results: dict[int, tuple[list[dict], list[dict]]] = {}
    if pool is None:
        for index, (family, adaptive, known, order) in enumerate(tasks):
            results[index] = advise_family(family, adaptive, known, order, targets, max_steps)
            if progress:
                progress(family.label)
    else:
        futures = {pool.submit(advise_family, family, adaptive, known, order, targets, max_steps): index
                   for index, (family, adaptive, known, order) in enumerate(tasks)}
        for future in as_completed(futures):
            index = futures[future]
            family = tasks[index][0]
            try:
                results[index] = future.result()
            except Exception as exc:  # a worker that died: the family's rows say why
                raise_unless_data(exc)
                what = "tolerance" if tasks[index][1] else "dt"
                results[index] = ([advice_row(family, t, what, note=f"worker failed: {type(exc).__name__}: {exc}"
                                        .splitlines()[0]) for t in sorted(targets, reverse=True)], [])
            if progress:
                progress(family.label)
    rows = [row for index in range(len(tasks)) for row in results[index][0]]
    _time_advised(rows, {index: results[index][1] for index in results}, tasks, pool)
    return pd.DataFrame(rows, columns=list(ADVICE_COLUMNS)).fillna({"formulation": "", "note": ""})


def _time_advised(rows: list[dict], untimed: dict[int, list[dict]], tasks, pool: WatchedPool | None = None) -> None:
    """Time the advised runs that have no timing yet (each once, whatever the targets sharing it), on the pool's
    workers, each on a core of its own (None: here), and fill their rows' us_per_sim_s, in place."""
    fixed = {family.key: family for family, adaptive, _, _ in tasks if not adaptive}
    adaptive = {family.key: family for family, is_adaptive, _, _ in tasks if is_adaptive}
    points = [point for index in sorted(untimed) for point in untimed[index]]
    dt_points = [p for p in points if family_key(p) in fixed]
    tol_points = [p for p in points if family_key(p) in adaptive]
    if dt_points:
        dt_ladders.time_points(dt_points, fixed, pool=pool)
    if tol_points:
        dt_ladders.time_points(tol_points, adaptive, "tolerance", pool)
    cost = {}
    for p in dt_points:
        cost[(*family_key(p), "dt", p["dt"])] = p.get("us_per_sim_s")
    for p in tol_points:
        cost[(*family_key(p), "tolerance", p["tolerance"])] = p.get("us_per_sim_s")
    for row in rows:
        what = "tolerance" if math.isfinite(row["tolerance"]) else "dt"
        found = cost.get((*family_key(row), what, row[what]))
        if found is not None and math.isfinite(found):
            row["us_per_sim_s"] = found


__all__ = ["advise_family", "run_advice", "rounded"]


def advise(case, families: list[tuple[Family, bool]], targets: tuple[float, ...], max_steps: int,
           progress: Callable[[str], None] | None = None,
           pool: WatchedPool | None = None) -> tuple[pd.DataFrame, dict[tuple, str]]:
    """What `stereodyn advise` runs: per family, the case's own dt list and a short ladder (dt doubled or halved until
    three points are asymptotic, pipeline.dt_ladders.run_short_ladder) for the order, or for an adaptive method the
    default tolerance ladder (1e-3, 1e-5 … 1e-13) for its slope (ladder_for_advice); then the checked search per
    target and the advised runs timed. All on the pool's workers (None: here), so that an engine plug-in that exits,
    kills its process or leaves children behind fails its family's answer, not the command (issue 46, F1). Returns
    advice.csv's rows and, per family key without an order, why."""
    tasks, why = [], {}
    for family, adaptive in families if progress else ():
        progress(f"{family.label}: {'tolerance ladder' if adaptive else 'dt list and short ladder'}")
    if pool is None:
        found = {index: ladder_for_advice(family, adaptive, max_steps)
                 for index, (family, adaptive) in enumerate(families)}
    else:
        futures = {pool.submit(ladder_for_advice, family, adaptive, max_steps,
                               affinity=family_affinity(family, max_steps)): index
                   for index, (family, adaptive) in enumerate(families)}
        found = {}
        for future in as_completed(futures):
            try:
                found[futures[future]] = future.result()
            except Exception as exc:  # its worker died (os._exit, a signal): the family's answer says so
                raise_unless_data(exc)
                found[futures[future]] = ([], math.nan, f"worker failed: {type(exc).__name__}: {exc}".splitlines()[0])
    for index, (family, adaptive) in enumerate(families):
        known, order, note = found[index]
        if not math.isfinite(order):
            failed = next((p["message"] for p in known if p.get("status") == "failed" and p.get("message")), None)
            why[family.key] = (note or "no fitted order") + (f"; the first failure: {failed}" if failed else "")
            continue
        tasks.append((family, adaptive, known, order))
    if progress and tasks:
        progress("checking the advice")
    return run_advice(tasks, targets, max_steps, pool), why


def ladder_for_advice(family: Family, adaptive: bool, max_steps: int) -> tuple[list[dict], float, str]:
    """(known points, fitted order or slope, its note) of one family for advise: the tolerance ladder's slope of an
    adaptive method, else the order of the case's dt list and a short ladder. A pool task (a function of the module:
    a worker unpickles it)."""
    from ..analysis import fitting

    if adaptive:
        known = [{k: v for k, v in p.items() if not k.startswith("_")}
                 for p in tolerance_ladders.run_ladder(family, tolerance_ladders.DEFAULT_TOLERANCES)]
        fit = fitting.tolerance_fit(pd.DataFrame(known, columns=list(tolerance_ladders.TOLERANCE_COLUMNS)))
        return known, fit["slope"], fit["note"]
    known = [dt_ladders.measure(family, dt, timed=False) for dt in sorted(family.case.dt, reverse=True)]
    new, row = dt_ladders.run_short_ladder(family, known, max_steps)
    return known + new, row["order"], row["note"]
