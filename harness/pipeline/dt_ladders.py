"""Work–precision measuring: the runs of the dt ladders and stability limits (their tables, constants and pure rules:
harness.analysis.ladders, re-exported here).

For a case × engine × formulation × integrator, a ladder is LADDER_POINTS log-spaced steps from the largest stable dt
(found by bisection) down to t_end / max_steps, where the 4th-order methods reach their round-off floor. Each point is
one untimed accuracy run (errors against the truth, energy drift) and separate timed runs (harness.run.timing: best of N
after the accuracy run as warm-up, within a budget), costed as µs of stepping per simulated second.

The error whose order is fitted (analysis.fitting) is the global error of the state, state_err = max(attitude_err,
omega_err, casimir_drift): a method's order is that of its whole state. (The attitude alone can converge faster than
the method: MuJoCo's semi-implicit Euler on a plane pendulum has the positions of Störmer–Verlet, second order, while
its velocities are first order; explicit Euler on a steady rotation has a second-order phase but a first-order |q|
growth.)

stable_dt_max: the largest dt whose run over t_end finishes ok with energy_drift <= STABLE_ENERGY_DRIFT, by
doubling/halving from a start until the outcome changes, then geometric bisection to STABILITY_RTOL.

A short ladder (run_short_ladder) is for a family whose sweep dt list has fewer than two points in the asymptotic
range: it walks from the list, doubling dt while the coarsest point is asymptotic or at round-off and halving it while
the finest is above the range or failed (unless a coarser run finished: then it failed for its cost), until
SHORT_TARGET points are asymptotic, a point leaves the range in the walk's direction, dt leaves
[t_end / max_steps, t_end / MIN_STEPS] or (halving) SHORT_POINTS points are spent. Its points are untimed: they are
for the order only. Without an order, its note says where the points lie and why the walk stopped.

A first part (run_first_part) is for a family whose error over the whole span stays above the asymptotic range down to
the steps cap (a long horizon): its order is measured by a short ladder over the case's first part, t_end halved until
the cap leaves room for three asymptotic points (first_part_span); its note says over what span.

The ladders run on the sweep's process pool (harness.run.sweep.worker_pool), one task per family.
"""
from __future__ import annotations

import math
from concurrent.futures import as_completed
from typing import Callable, NamedTuple

import pandas as pd

from .. import budget
from ..analysis import fitting
from ..analysis.fitting import declared_order, fit
from ..analysis.ladders import (FIRST_PART_HALVINGS, FIRST_PART_MARGIN, LADDER, LADDER_COLUMNS,  # noqa: F401
                                LADDER_POINTS, MIN_STEPS, SHORT_LADDER, SHORT_POINTS, SHORT_TARGET, STABILITY_RTOL,
                                STABLE_ENERGY_DRIFT, families, first_part_span, ladder_dts, short_ladder,
                                short_reason, stability_limit, stable, walk)  # (F401: re-exported, this module's API before issue 29)
from ..scenes.cases import CHAOTIC_TAGS, Case, with_overrides  # noqa: F401 (part of this API)
from ..scenes.metrics import state_err
from ..trajectory import Status
from ..run.processes import raise_unless_data
from ..run.measure import measure as run_measure, rate
from ..run.spec import Family, base_row  # noqa: F401 (Family: part of this API)
from ..precision import EPS
from ..run.pool import family_affinity, one_precision_at_a_time
from ..run.workers import WatchedPool
# a point's truth, its single time and the ladders' timing phase (points.py, beside this module: tolerance_ladders
# reads them there); importable from here as before
from .points import TIMING_BUDGET_S, TIMING_REPEATS, _timed, case_truth_on, time_points  # noqa: F401


# ------------------------------------------------------------------------------------------------ one point

def measure(family: Family, dt: float, timed: bool = True, with_truth: bool = True) -> dict:
    """One ladder point (measure.measure): accuracy run, errors against the truth when with_truth (computed on the
    point's grid), then one timed run when timed (timing SINGLE; time_points repeats those that decide). Never
    raises."""
    run = family.run(dt=float(dt))
    try:
        with budget.within("run", budget.configured().run_s):  # the point's truth under a run's budget, as before
            truth = case_truth_on(run) if with_truth else None
    except budget.BudgetExceeded as exc:
        return {**base_row(run, run.grid), "source": LADDER, "status": Status.FAILED.value, "message": str(exc)}
    except Exception as exc:  # a point that breaks is data, as in the sweep
        raise_unless_data(exc)
        return {**base_row(run, run.grid), "source": LADDER, "status": Status.FAILED.value,
                "message": f"truth failed: {type(exc).__name__}: {exc}".splitlines()[0]}
    row = run_measure(run, truth, full=False, timed=_timed if timed else None)
    row.update(source=LADDER, rhs_evals=row.get("_rhs_evals", math.nan), rhs_per_sim_s=math.nan)
    if "_rhs_evals" in row:  # as the engine counts them: a fixed-step run without counts has none here
        row["rhs_per_sim_s"] = rate(row["_rhs_evals"], row["t_end"])
    if with_truth and "attitude_err" in row:
        row["state_err"] = state_err(row)
    return {k: v for k, v in row.items() if k in LADDER_COLUMNS}


# ------------------------------------------------------------------------------------------------ ladders

def run_ladder(family: Family, max_steps: int) -> tuple[list[dict], dict]:
    """The ladder of one family: its points and its convergence row. Never raises."""
    case = family.case
    declared = declared_order(family.engine, family.integrator, family.formulation)
    cap, floor = case.t_end / MIN_STEPS, case.t_end / max_steps
    cache: dict[float, dict] = {}

    def is_stable(dt: float) -> bool:
        cache[dt] = measure(family, dt, timed=False, with_truth=False)
        return stable(cache[dt])

    start = max(case.dt)
    stable_dt, stability_note = stability_limit(is_stable, start, cap, floor)
    top = stable_dt if math.isfinite(stable_dt) else (cap if "stable up to" in stability_note else start)
    # each timed once here; those whose time decides are timed again, alone, later (time_points)
    points = [measure(family, dt) for dt in ladder_dts(top, floor)]
    frame = pd.DataFrame(points, columns=list(LADDER_COLUMNS))
    row = {**family.columns, "stable_dt_max": stable_dt, "source": LADDER,
           **fit(frame, declared, family.precision)}
    if stability_note:
        row["note"] = "; ".join(x for x in (row["note"], stability_note) if x)
    return points, row


def run_short_ladder(family: Family, known: list[dict], max_steps: int) -> tuple[list[dict], dict]:
    """The short ladder of a family whose own dt list (known: the sweep's runs of it, with columns dt, steps, status,
    state_err) has fewer than two asymptotic points: its points (untimed) and its convergence row. Which dt it runs is
    analysis.ladders.short_ladder's; each point is run here (measure: a point that breaks is data, as in the sweep)."""
    declared = declared_order(family.engine, family.integrator, family.formulation)
    return short_ladder(family, known, max_steps, declared, lambda dt: measure(family, dt, timed=False))


def run_first_part(family: Family, points: list[dict], max_steps: int, row: dict) -> tuple[list[dict], dict]:
    """The order of a family whose short ladder found none, its finest ok point above the asymptotic range (or its
    only asymptotic one) at the steps cap: a short ladder over the case's first part (first_part_span) from 4 x the
    part's cap. points: the family's sweep runs and short-ladder points; row: its convergence row. Returns the new
    points (their t_end the part's) and the row: the part's fit where it gives an order, its note saying over what
    span; else the row as it was, its note saying what the part gave. ([], row) where this does not apply."""
    case = family.case
    declared = declared_order(family.engine, family.integrator, family.formulation)
    columns = ["dt", "steps", "status", "state_err"]
    marked = fitting.regimes(pd.DataFrame([{c: p.get(c, math.nan) for c in columns} for p in points],
                                          columns=columns), EPS[family.precision])[0]
    ok = marked[marked["regime"] != fitting.FAILED]
    if math.isfinite(row.get("order", math.nan)) or not math.isfinite(declared) or ok.empty \
            or ok.iloc[-1]["regime"] not in (fitting.ABOVE, fitting.ASYMPTOTIC):
        return [], row
    finest = ok.iloc[-1]
    span = first_part_span(case.t_end, float(finest["dt"]), float(finest["state_err"]), declared, max_steps)
    if not math.isfinite(span):
        return [], row
    start = float(f"{4.0 * span / max_steps:.4g}")
    part = Family(with_overrides(case, t_end=span, dt=[start]), family.engine, family.formulation, family.integrator,
                  family.precision)
    new = [measure(part, start, timed=False) | {"source": SHORT_LADDER}]
    more, fitted = run_short_ladder(part, new, max_steps)
    new += more
    why = (f"over all {case.t_end:g} s, {int((marked['regime'] == fitting.ASYMPTOTIC).sum())} point(s) in the "
           f"asymptotic range down to dt = {finest['dt']:.3g} (state_err {finest['state_err']:.2g}), steps cap t_end / "
           f"{max_steps}")
    if math.isfinite(fitted["order"]):
        note = f"{fitting.FIRST_PART} {span:g} s of {case.t_end:g} s ({why})"
        return new, {**fitted, "note": "; ".join(x for x in (note, fitted["note"]) if x)}
    return new, {**row, "note": "; ".join(x for x in (row["note"], f"over the first {span:g} s no order either "
                                                                     f"({fitted['points']} asymptotic point(s))") if x)}


def _failed_family(family: Family, exc: BaseException, source: str = LADDER) -> tuple[list[dict], dict]:
    """A family whose worker died: no points, and its convergence row says why, with every column of
    fitting.CONVERGENCE_COLUMNS (no order: NaN), as the rows after it are read (analysis.workprecision)."""
    return [], {**dict.fromkeys(fitting.CONVERGENCE_COLUMNS, math.nan), **family.columns, "points": 0,
                "declared_order": declared_order(family.engine, family.integrator, family.formulation),
                "source": source, "note": f"worker failed: {type(exc).__name__}: {exc}".splitlines()[0]}


class _Task(NamedTuple):
    """One family's work on the pool: function(*args) -> (points, convergence row); source: the rows' source column
    (LADDER or SHORT_LADDER); steps: its steps cap (the finest point's), for the pool's cost estimate."""

    function: Callable
    family: Family
    args: tuple
    source: str
    steps: int


def run_ladders(chosen: list[Family], max_steps: int, pool: WatchedPool | None = None,
                progress: Callable[[str], None] | None = None,
                short: list[tuple[Family, list[dict], int]] = (),
                first_parts: list[tuple[Family, list[dict], int, dict]] = (),
                timed: bool = True) -> tuple[list[dict], list[dict]]:
    """Every family's ladder, every short ladder (short: (family, its sweep runs, its steps cap), run_short_ladder)
    and every first part (first_parts: (family, its points, its steps cap, its row), run_first_part), their accuracy
    runs in this process (pool None) or on the sweep's pool, each ladder point timed once there, then with timed the
    ladders' points timed again on its workers (time_points; the short ladders' points stay untimed; timed False leaves that to
    the caller: pipeline.work_precision times only those that decide). Returns (points, convergence rows): the
    ladders' in the order of `chosen`, then the short ladders' in the order of `short`, then the first parts',
    whatever order the families finish in."""
    tasks = [_Task(run_ladder, family, (family, max_steps), LADDER, max_steps) for family in chosen]
    tasks += [_Task(run_short_ladder, family, (family, known, steps), SHORT_LADDER, steps)
              for family, known, steps in short]
    tasks += [_Task(run_first_part, family, (family, known, steps, row), SHORT_LADDER, steps)
              for family, known, steps, row in first_parts]
    results: dict[int, tuple[list[dict], dict]] = {}
    if pool is None:
        for index, task in enumerate(tasks):
            results[index] = task.function(*task.args)
            if progress:
                progress(task.family.label)
    else:
        # as the sweep's runs: a family goes preferably to a worker that has paid its engine's start-up, and an
        # engine whose precision is process-global gets its families one precision at a time (the default run with
        # every extra spent 19 min here: Genesis's short ladders spread over both workers, its precision alternating)
        order = one_precision_at_a_time(list(range(len(tasks))), of=lambda index: tasks[index].family)
        futures = {pool.submit(tasks[index].function, *tasks[index].args,
                               affinity=family_affinity(tasks[index].family, tasks[index].steps)): index
                   for index in order}
        for future in as_completed(futures):
            index = futures[future]
            try:
                results[index] = future.result()
            except Exception as exc:  # a worker that died: the family's row says so
                raise_unless_data(exc)
                results[index] = _failed_family(tasks[index].family, exc, tasks[index].source)
            if progress:
                progress(tasks[index].family.label)
    points, rows = [], []
    for index in range(len(tasks)):
        points += results[index][0]
        rows.append(results[index][1])
    if timed:  # the timing phase, once every accuracy run is done and the pool idle: on its workers, a core each
        time_points([p for p in points if p.get("source") == LADDER], {f.key: f for f in chosen}, pool=pool)
    return points, rows
