"""The one path from a run to its row: the sweep's runs, the dt ladders' and tolerance ladders' points and every
scene's runs go through measure(). What differs between scenes is done by the scene object (harness.scenes.base):
its grid's truth, its metrics and checks; here nothing branches on a kind. Here too, for every engine, what a
simulation's run() returned is checked (harness.trajectory: problem, then the divergence rule, judged) before any
metric reads it, and whatever a plug-in's code raises, SystemExit and GeneratorExit included, is its run's failed
row."""
from __future__ import annotations

import math
import numbers
import time
from typing import Callable

from .. import budget
from ...reference import plugins
from ..engines import get_engine
from ..errors import InternalError
from ..precision import FLOAT64
from ..scenes import scene_of
from ..trajectory import Status, as_arrays, judged, problem
from ..words import clipped, one_line
from .processes import plugin_fault, raise_unless_data
from ..tables import METRIC_SUFFIXES, value_rule
from .spec import RunKey, base_row


def precision_keyword(run: RunKey) -> dict:
    """precision= for a model's prepare, only where the run is not float64 (a model of a scene that has no
    precision, the sliding ladder's, never gets it)."""
    return {} if run.precision == FLOAT64 else {"precision": run.precision}


def model_of(run: RunKey):
    """The engine's model of the run's scene (Engine.models()); KeyError when the engine has none."""
    return get_engine(run.engine).models()[scene_of(run.case).kind]


def prepare(run: RunKey):
    """(simulation, grid) of a run: the model built (not timed) and the sample times it runs on."""
    return model_of(run).prepare(run.case, run.formulation, run.integrator, run.dt, run.tolerance,
                                 **precision_keyword(run)), run.grid


def prepare_budget(run: RunKey, budgets: budget.Budgets) -> float:
    """The run's prepare budget, s: the sweep's, or its engine's where that declares a longer one
    (Timing.prepare_budget_s)."""
    return max(budgets.prepare_s, get_engine(run.engine).timing.prepare_budget_s or 0.0)


def measure(run: RunKey, truth=None, full: bool = True, keep_states: bool = False,
            timed: Callable[[object, object, RunKey], dict] | None = None, budgets: budget.Budgets | None = None) -> dict:
    """One run's row: base columns, the untimed accuracy run, the scene's metrics (against truth: the scene's truth
    on a set of grids that holds the run's, or None for no errors), with full the sweep's extras (checks, series).
    timed(simulation, grid, run) -> timing columns, when given, times the run after the accuracy run (its warm-up).
    `_accuracy_s` is the prepare-and-run wall time (a budget's measure, not a timing). budgets (default this
    process's, harness.budget): prepare under its prepare budget (prepare_budget), the run with its metrics and checks
    under its run budget; past one, a failed row naming it (and `_budget`, which the store keeps). Never raises: a
    run that breaks is a failed row."""
    budgets = budgets or budget.configured()
    grid = run.grid
    row = base_row(run, grid)
    start = time.perf_counter()
    try:
        scene, model = scene_of(run.case), model_of(run)
        sim = budget.prepared(lambda: model.prepare(run.case, run.formulation, run.integrator, run.dt, run.tolerance,
                                                    **precision_keyword(run)), prepare_budget(run, budgets))
        with budget.within("run", budgets.run_s):
            traj = checked(sim, sim.run(grid), grid, getattr(scene, "trajectory", None),
                           getattr(run.case, "omega0", None))
            row["_accuracy_s"] = time.perf_counter() - start
            # a time of divergence belongs to a diverged row only (judged checked it against the grid): a plug-in's
            # ok trajectory with diverged_at = inf wrote a results.csv every reader refused (issue 46's ninth attack)
            row.update(status=traj.status.value, message=traj.message,
                       diverged_at=traj.diverged_at if traj.status is Status.DIVERGED else math.nan)

            def rerun(case):
                return model.prepare(case, run.formulation, run.integrator, run.dt, run.tolerance,
                                     **precision_keyword(run)).run(grid)

            if traj.status is Status.SKIPPED:  # it did not run this: nothing to measure (a plug-in's word at run time)
                row["message"] = traj.message or f"{type(sim).__qualname__}.run() returned skipped, with no reason"
            else:
                row.update(checked_metrics(scene, scene.metrics(run, model, traj, grid, truth, full, rerun,
                                                                keep_states)))
            budget.check()  # a loop that could not be stopped inside (one compiled call, MJX's) is judged here
        if timed is not None and traj.status is Status.OK:
            row.update(timed(sim, grid, run))
    except budget.BudgetExceeded as exc:  # nothing it measured before the stop counts
        row = {**base_row(run, grid), **budget.failed_row(exc), "_accuracy_s": time.perf_counter() - start}
    except Exception as exc:  # a run that breaks is data: record why and let the sweep go on
        raise_unless_data(exc)  # ... unless Ctrl-C broke it (an SDK may rewrap the KeyboardInterrupt)
        row.setdefault("_accuracy_s", time.perf_counter() - start)
        row.update(status=Status.FAILED.value, message=f"{type(exc).__name__}: {plugins.text_of(exc)}".splitlines()[0])
    except BaseException as exc:  # SystemExit, GeneratorExit, a plug-in's own KeyboardInterrupt: its run's failure
        if not plugin_fault(exc):
            raise  # our bug (InternalError), or the user's Ctrl-C
        text = " ".join(plugins.text_of(exc).split())
        row = {**base_row(run, grid), "status": Status.FAILED.value, "_accuracy_s": time.perf_counter() - start,
               "message": f"{type(exc).__name__}: {text}" if text else type(exc).__name__}
    if isinstance(row.get("message"), str):
        row["message"] = clipped(one_line(" ".join(row["message"].split())))  # a plug-in's lines: one, its runs of space one
    return row


class NoTrajectory(ValueError):
    """A simulation's run() that returned what is no trajectory of its grid: a failed row of a plug-in."""


def checked(sim, traj, grid, expected: type | None = None, omega0=None):
    """What sim.run(grid) returned, checked (harness.trajectory.problem) and judged by the divergence rule (omega0:
    the case's initial rad/s, its scale): an ok trajectory with NaN states is diverged at their time, whichever
    engine made it. Not a trajectory: NoTrajectory (the run's failed row) from a plug-in's simulation, InternalError
    from stereodyn's own (our bug)."""
    why = problem(traj, grid.times, expected)
    if why is not None:
        text = f"{type(sim).__module__}.{type(sim).__qualname__}.run() {why}"
        if plugins.own(type(sim)):
            raise InternalError(f"NoTrajectory: {text}", f"NoTrajectory: {text}\n")
        raise NoTrajectory(text)
    return judged(as_arrays(traj), omega0)


class BadMetric(ValueError):
    """A scene plug-in's metric that no reader of results.csv would accept: a failed row of that run."""


def checked_metrics(scene, metrics: dict) -> dict:
    """A scene's metrics, each number within its column's rule (results.value_rule, which every reader of results.csv
    applies: no negative error, no angle above pi, nothing above 1e100; a metric finite or NaN), so that a run never
    writes a table its readers refuse. BadMetric from a plug-in's scene, InternalError from stereodyn's own."""
    for column, value in metrics.items():
        if isinstance(value, bool) or not isinstance(value, numbers.Real) or math.isnan(value):
            continue
        why = ("must be finite or NaN" if math.isinf(value) and column.endswith(METRIC_SUFFIXES)
               else value_rule(column, float(value)))
        if why:
            text = (f"{type(scene).__module__}.{type(scene).__qualname__}.metrics(): {column} = "
                    f"{plugins.shown(value)}: {why}")
            if plugins.own(type(scene)):
                raise InternalError(f"BadMetric: {text}", f"BadMetric: {text}\n")
            raise BadMetric(text)
    return metrics


def rate(count: float, t_end: float) -> float:
    """count per simulated second, NaN for no count (0 or NaN)."""
    return count / t_end if count and not (isinstance(count, float) and math.isnan(count)) else math.nan
