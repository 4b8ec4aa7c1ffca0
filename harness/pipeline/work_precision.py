"""The work–precision phases of `stereodyn run`, after the sweep: the ladders analysis.workprecision.plan_ladders chose,
run on the sweep's pool (pipeline.dt_ladders, pipeline.tolerance_ladders), then the step-size advice on the laddered
families (pipeline.advice). The tables, their merging and their writing are analysis.workprecision's.

Outputs in the run folder: ladder.csv (every point), convergence.csv (one row per ladder, per short ladder, and per
other run family of the sweep with two dt or more), tolerance.csv (every tolerance-ladder point), tolerance_fit.csv
(one row per tolerance ladder), pareto.csv (per case and accuracy target, the cheapest run, fixed-step or adaptive),
advice.csv (unless the ladders are off), and the orders as rows of checks.csv (quantity convergence_order, theory =
the declared order).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import pandas as pd

from ..analysis import decisive, workprecision
from ..analysis.fitting import tolerance_fits
from ..analysis.ladders import LADDER, LADDER_COLUMNS, tolerance_frame
from ..analysis.step_advice import ADVICE_COLUMNS, advice_tasks
from ..run.workers import WatchedPool
from ..scenes.cases import Case
from .advice import run_advice
from .dt_ladders import run_ladders, time_points
from .tolerance_ladders import run_ladders as run_tolerance_ladders, start_ladders as start_tolerance_ladders


@dataclass(frozen=True)
class Ladders:
    """What the ladders phase measured: its plan (analysis.workprecision.LadderPlan), ladder.csv's points
    (LADDER_COLUMNS), tolerance.csv's (TOLERANCE_COLUMNS), convergence.csv, and the paths written by name."""

    plan: workprecision.LadderPlan
    ladder: pd.DataFrame
    tolerance: pd.DataFrame
    convergence: pd.DataFrame
    paths: dict[str, Path]


def ladders(out_dir: Path, results: pd.DataFrame, cases: list[Case], engines: list[str],
            integrators: list[str] | None, ladder: str = "default", max_steps: int | None = None,
            pool: WatchedPool | None = None, progress: Callable[[str], None] | None = None,
            write_pareto: bool = True) -> Ladders:
    """The dt, short and tolerance ladders of plan_ladders(ladder) on the sweep's pool (None: in this process), then
    their tables written and the orders appended to checks.csv."""
    plan = workprecision.plan_ladders(results, cases, engines, integrators, ladder, max_steps)
    # the tolerance ladders go on the pool first (they need nothing of the dt ladders): the dt ladders' many tasks
    # fill the other worker while the longest tolerance ladder runs, where it ran alone at the end
    started = start_tolerance_ladders(plan.adaptive, pool, plan.tolerances) if plan.adaptive and pool is not None \
        else None
    points, ladder_rows = run_ladders(plan.chosen, plan.max_steps, pool, progress, plan.short, timed=False) \
        if plan.chosen or plan.short else ([], [])
    first_parts = workprecision.first_part_families(plan.short, points, ladder_rows, plan.sweep_rows, plan.rigid)
    if first_parts:  # a long horizon: the order over the case's first part, where the verdict needs it
        more, parts = run_ladders([], plan.max_steps, pool, progress, first_parts=first_parts, timed=False)
        points += more
        ladder_rows = workprecision.with_first_parts(ladder_rows, parts)
    convergence = workprecision.convergence_rows(ladder_rows, plan.sweep_rows)
    tolerance_points = run_tolerance_ladders(plan.adaptive, pool, progress, plan.tolerances, timed=False,
                                             started=started) if plan.adaptive else []
    _time_deciding(results, points, tolerance_points, plan, pool)
    ladder_df = pd.DataFrame(points, columns=list(LADDER_COLUMNS))
    tolerance_df = tolerance_frame(tolerance_points)
    paths = workprecision.write_tables(out_dir, results, ladder_df, convergence, tolerance_df, write_pareto)
    workprecision.write_order_checks(out_dir, convergence)
    return Ladders(plan, ladder_df, tolerance_df, convergence, paths)


def _time_deciding(results: pd.DataFrame, points: list[dict], tolerance_points: list[dict],
                   plan: workprecision.LadderPlan, pool: WatchedPool | None = None) -> None:
    """The ladders' timing phase: of the points their workers timed once, those whose time can change a "What to use"
    cell (analysis.decisive, among the sweep's runs and every ladder point) timed again on the pool's workers, each
    on a core of its own (None: here), best of points.TIMING_REPEATS (the others keep their single time: `timing`
    SINGLE). In place."""
    dt_points = [p for p in points if p.get("source") == LADDER]
    chosen = decisive.deciding_points(results, dt_points + tolerance_points)
    time_points([p for i, p in enumerate(dt_points) if i in chosen], {f.key: f for f in plan.chosen}, pool=pool)
    time_points([p for i, p in enumerate(tolerance_points, len(dt_points)) if i in chosen],
                {f.key: f for f in plan.adaptive}, "tolerance", pool)


def advice(out_dir: Path, results: pd.DataFrame, measured: Ladders, pool: WatchedPool | None = None,
           progress: Callable[[str], None] | None = None) -> Path | None:
    """advice.csv (pipeline.advice): the laddered families with a fitted order or slope (the dt and tolerance
    ladders: DEFAULT_LADDER's in the default run, every family with --dt-ladder), at
    analysis.workprecision.advice_targets; None (nothing written) when the ladders are off."""
    plan = measured.plan
    if plan.mode == "off":
        return None
    tasks = advice_tasks(plan.chosen, plan.adaptive, results, measured.ladder, measured.tolerance,
                         measured.convergence, tolerance_fits(measured.tolerance))
    table = run_advice(tasks, workprecision.advice_targets(plan.mode), plan.max_steps, pool, progress) \
        if tasks else pd.DataFrame(columns=list(ADVICE_COLUMNS))
    return workprecision.write_advice(out_dir, table)


def analyse(out_dir: Path, results: pd.DataFrame, cases: list[Case], engines: list[str],
            integrators: list[str] | None, ladder: str = "default", max_steps: int | None = None,
            pool: WatchedPool | None = None,
            progress: Callable[[str], None] | None = None, write_pareto: bool = True) -> dict[str, Path]:
    """Both phases, ladders then advice (analysis.workprecision.plan_ladders says what `ladder` means); returns the
    paths written. pool: the sweep's worker pool (harness.run.sweep.worker_pool) the runs go to; None runs them here.
    write_pareto False leaves pareto.csv to the caller (`stereodyn run` writes it once, after the verdicts:
    analysis.workprecision.rewrite_pareto; the table takes seconds in the default run)."""
    measured = ladders(out_dir, results, cases, engines, integrators, ladder, max_steps, pool, progress, write_pareto)
    paths = dict(measured.paths)
    written = advice(out_dir, results, measured, pool, progress)
    if written is not None:
        paths["advice"] = written
    return paths
