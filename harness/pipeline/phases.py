"""The phases of `stereodyn run` as declared steps, each with the values it needs and those it gives:

    truths and sweep -> ladders -> advice -> verdicts -> What to use -> report

harness.cli.run parses the command line into a Request and calls run().
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from .. import budget
from ..run.progress import ProgressBar
from ..run.sweep import SweepOptions
from ..scenes.cases import Case


@dataclass(frozen=True)
class Request:
    """What `stereodyn run` asked for, parsed and checked (harness.cli.run). ladder: the work–precision mode ("full",
    "default", "short" or "off"; analysis.workprecision.plan_ladders); max_steps: --ladder-max-steps (None: the
    mode's cap); budgets: the wall-time budgets, s; figures, self_contained: the report's options; verbose: the drift
    table on stdout."""

    cases: list[Case]
    options: SweepOptions
    ladder: str
    max_steps: int | None
    budgets: budget.Budgets
    figures: bool = True
    self_contained: bool = False
    verbose: bool = False
    quiet: bool = False


@dataclass(frozen=True)
class Phase:
    """One step of run(): step(request, values, pool) reads the values named in needs and returns exactly those named
    in gives. in_pool: it runs on the sweep's worker pool (run() opens one for each stretch of such phases)."""

    name: str
    needs: tuple[str, ...]
    gives: tuple[str, ...]
    step: Callable
    in_pool: bool = False


def _sweep(request: Request, values: dict, pool, progress: ProgressBar) -> dict:
    """Each case's truth, then its runs (harness.run.sweep), and agreement.csv from the states the runs compared."""
    from ..analysis import agreement, decisive
    from ..run.sweep import run_sweep

    compared: list[dict] = []  # the states the cross-engine agreement compares (agreement.csv)
    # only the runs whose time can change an answer are timed with repeats (analysis.decisive)
    results = run_sweep(request.cases, request.options, progress=progress, pool=pool, agreement=compared,
                        final=False, decides=decisive.decisive)
    agreement.write(request.options.out_dir, compared)
    return {"results": results}


def _ladders(request: Request, values: dict, pool, progress: ProgressBar) -> dict:
    """The dt, short and tolerance ladders (pipeline.work_precision.ladders); pareto.csv waits for the verdicts."""
    from .work_precision import ladders

    mode = request.ladder
    if mode != "off":
        progress.stage("work–precision: short ladders" if mode == "short" else
                       f"work–precision: {mode} dt and tolerance ladders"
                       + (" and short ladders" if mode == "default" else ""))
    options = request.options
    measured = ladders(options.out_dir, values["results"], request.cases, list(options.engines),
                                      options.integrators, mode, request.max_steps, pool, write_pareto=False)
    return {"ladders": measured}


def _advice(request: Request, values: dict, pool, progress: ProgressBar) -> dict:
    """advice.csv (pipeline.work_precision.advice)."""
    from .work_precision import advice

    return {"advice": advice(request.options.out_dir, values["results"], values["ladders"], pool)}


def _verdicts(request: Request, values: dict, pool, progress: ProgressBar) -> dict:
    """The check runs (pipeline.checks), then every verdict (analysis.verdicts): verdicts.csv."""
    from ..analysis import verdicts
    from .checks import checked_verdicts

    results = values["results"]
    return {"verdicts": verdicts.evaluate(request.options.out_dir, results, request.cases, checked_verdicts(results))}


def _what_to_use(request: Request, values: dict, pool, progress: ProgressBar) -> dict:
    """pareto.csv, recommending no run of an integrator that failed a verdict (it names it instead), and answers.csv,
    the one answer per case, scope and target (analysis.answers) that the report and the terminal read."""
    from ..analysis import answers, verdicts, workprecision

    path = request.options.out_dir
    failed = verdicts.failed_integrators(values["verdicts"])
    workprecision.rewrite_pareto(path, values["results"], failed)
    return {"pareto": Path(path) / workprecision.PARETO_FILE, "answers": answers.write(path, failed)}


def _report(request: Request, values: dict, pool, progress: ProgressBar) -> dict:
    """report.md, report.html and the figures, the folder marked complete, and the terminal summary's lines."""
    from ..analysis import summary
    from ..report.build import write_reports
    from ..report.markdown import drift_table_text
    from ..run.store import mark_complete

    out, results = request.options.out_dir, values["results"]
    if request.verbose:
        print(drift_table_text(results))
    progress.stage("report: report.md, figures, report.html" if request.figures else "report: report.md, report.html")
    # the figures are drawn on the pool's workers, which have imported most of what drawing needs (the report's own
    # two processes spawned and imported for 5-8 s each in the quick suite)
    markdown, html = write_reports(out, results, self_contained=request.self_contained, figures=request.figures,
                                   render_map=None if pool is None else pool.map)
    mark_complete(out)  # the last write: check, baseline, compare and report read the folder from now on
    elapsed = progress.finish()
    lines = [] if request.quiet else summary.terminal_lines(results, values["verdicts"], out, html, elapsed_s=elapsed)
    return {"markdown": markdown, "html": html, "summary": lines}


PHASES = (
    Phase("truths and sweep", (), ("results",), _sweep, in_pool=True),
    Phase("ladders", ("results",), ("ladders",), _ladders, in_pool=True),
    Phase("advice", ("results", "ladders"), ("advice",), _advice, in_pool=True),
    Phase("verdicts", ("results",), ("verdicts",), _verdicts, in_pool=True),
    Phase("What to use", ("results", "verdicts"), ("pareto", "answers"), _what_to_use, in_pool=True),
    Phase("report", ("results", "verdicts"), ("markdown", "html", "summary"), _report, in_pool=True),
)


def _quiet_engines(out: Path) -> None:
    """MuJoCo appends its warnings to MUJOCO_LOG.TXT in the working directory: put it under the run folder (the adapter
    collects the warnings of a run into its row); worker processes inherit the setting through the environment."""
    os.environ["STEREODYN_MUJOCO_LOG"] = str(Path(out).resolve() / "MUJOCO_LOG.TXT")  # engines.mujoco.LOG_ENV


def run(request: Request, phases: tuple[Phase, ...] = PHASES) -> dict:
    """Every phase in order, under the run folder's lock; each stretch of in_pool phases on one worker pool (Ctrl-C
    anywhere in it ends its workers at once). Returns the values the phases gave, by name."""
    from ..run.store import folder_lock
    from ..run.sweep import worker_pool

    options = request.options
    _quiet_engines(options.out_dir)
    budget.configure(request.budgets)  # workers inherit it
    if options.scheduler:  # before any truth is computed
        from ..run.distributed import check_cluster

        check_cluster(options.scheduler)
    values: dict = {}
    progress = ProgressBar(enabled=not request.quiet)
    try:  # the heartbeat thread (off a terminal) ends with the command, whatever ends it
        with folder_lock(options.out_dir):  # the whole command: a second run into the folder waits for none of it
            index = 0
            while index < len(phases):
                if phases[index].in_pool:
                    with worker_pool(options.jobs) as pool:
                        while index < len(phases) and phases[index].in_pool:
                            _step(phases[index], request, values, pool, progress)
                            index += 1
                else:
                    _step(phases[index], request, values, None, progress)
                    index += 1
    finally:
        progress.finish()
    return values


def _step(phase: Phase, request: Request, values: dict, pool, progress: ProgressBar) -> None:
    missing = [name for name in phase.needs if name not in values]
    if missing:  # a phase list out of order is our bug (harness.errors: exit 3), never a row
        raise AssertionError(f"phase {phase.name!r} needs {', '.join(missing)}, which no earlier phase gives")
    given = phase.step(request, {name: values[name] for name in phase.needs}, pool, progress)
    if set(given) != set(phase.gives):
        raise AssertionError(f"phase {phase.name!r} gave {sorted(given)}, not its declared {sorted(phase.gives)}")
    values.update(given)
