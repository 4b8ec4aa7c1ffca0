"""`stereodyn run`: the sweep, the work–precision ladders, the verdicts, the report and the terminal summary."""
from __future__ import annotations

import os
import sys
from pathlib import Path

from . import BadInput, check_names, output_folder, select_cases


def main(args) -> int:
    from ..run.progress import ProgressBar
    from ..report.build import write_reports
    from ..report.markdown import drift_table_text
    from ..analysis import agreement, decisive, summary, verdicts, workprecision
    from ..run.sweep import SweepOptions, run_sweep, worker_pool
    from .. import budget

    from ..run.store import folder_lock, mark_complete

    check_names(args)
    if args.certify and args.no_certify:
        raise BadInput("--certify and --no-certify: give one (certifying is the default)")
    chosen = select_cases(args)
    options = SweepOptions(args.engines, args.out, args.integrators, jobs=args.jobs, certify=not args.no_certify,
                           resume=args.resume, scheduler=args.scheduler, save_trajectories=args.save_trajectories)
    progress = ProgressBar(enabled=not args.quiet)
    output_folder(args.out, "--out")
    _quiet_engines(args.out)
    budget.configure(budget.Budgets(args.run_budget, args.prepare_budget, args.truth_budget))  # workers inherit it
    if args.scheduler:  # before any truth is computed
        from ..run.distributed import check_cluster

        check_cluster(args.scheduler)
    with folder_lock(args.out):  # the whole command: a second run into --out waits for none of it to interleave
        # one pool for the sweep and the dt ladders; Ctrl-C anywhere in it ends its workers at once
        with worker_pool(options.jobs, options.engines) as pool:
            compared: list[dict] = []  # the states the cross-engine agreement compares (agreement.csv)
            # only the runs whose time can change an answer are timed with repeats (analysis.decisive)
            df = run_sweep(chosen, options, progress=progress, pool=pool, agreement=compared, final=False,
                           decides=decisive.decisive)
            agreement.write(args.out, compared)
            del compared
            _work_precision(args, options, chosen, df, pool, progress)
        found = verdicts.evaluate(args.out, df, chosen)
        # "What to use" recommends no run of an integrator that failed a verdict (it names it instead)
        workprecision.rewrite_pareto(args.out, df, verdicts.failed_integrators(found))
        if args.verbose:
            print(drift_table_text(df))
        progress.stage("report: report.md, figures, report.html" if args.figures else "report: report.md, report.html")
        markdown, html = write_reports(args.out, df, self_contained=args.self_contained, figures=args.figures)
        mark_complete(args.out)  # the last write: check, baseline, compare and report read the folder from now on
        if not args.quiet:  # quiet: nothing on success (a CI log); --strict's failures still go to stderr below
            print("\n".join(summary.terminal_lines(df, found, args.out, html)))
    if not args.quiet:
        print(f"wrote {args.out / 'results.csv'}, {markdown} and {html}")
    if args.strict and verdicts.strict_failures(found):
        print("\n".join(verdicts.summary_lines(found)[1:]), file=sys.stderr)
        return 1
    return 0


def _quiet_engines(out: Path) -> None:
    """MuJoCo appends its warnings to MUJOCO_LOG.TXT in the working directory: put it under --out (the adapter
    collects the warnings of a run into its row); worker processes inherit the setting through the environment."""
    os.environ["STEREODYN_MUJOCO_LOG"] = str(Path(out).resolve() / "MUJOCO_LOG.TXT")  # engines.mujoco.LOG_ENV


def _work_precision(args, options, chosen: list, df, pool=None, progress=None) -> None:
    """ladder.csv, convergence.csv, tolerance.csv, tolerance_fit.csv, advice.csv and the orders in checks.csv
    (analysis.workprecision; pareto.csv is main()'s, after the verdicts). The default suite (no CASE, no --case-file,
    no --dt) gets the small default ladders; named cases or steps with --strict only the short ladders of the
    integrators no case's dt list gives an order, or whose orders miss on too few points (without --strict none);
    --dt-ladder every family's; --no-ladder none, or with --strict the short ladders only."""
    from ..analysis import workprecision

    if args.ladder_max_steps is not None and args.ladder_max_steps < 2 * workprecision.MIN_STEPS:
        raise BadInput(f"--ladder-max-steps: must be >= {2 * workprecision.MIN_STEPS}")
    if args.dt_ladder:
        mode = "full"
    elif args.no_ladder or args.cases or args.case_file or args.dt is not None:
        # --strict judges: a declared order no case's dt list measured, or missed on too few points
        # (verdicts.NOT_ENOUGH), is measured (short ladders) before it is judged, --no-ladder or not (it then means no
        # dt or tolerance ladder); without --strict such a claim is reported "not measured, no reason" or "not enough
        # evidence"
        mode = "short" if args.strict else "off"
    else:
        mode = "default"
    if mode != "off" and progress is not None:
        progress.stage("work–precision: short ladders" if mode == "short" else
                       f"work–precision: {mode} dt and tolerance ladders"
                       + (" and short ladders" if mode == "default" else ""))
    workprecision.analyse(options.out_dir, df, chosen, list(options.engines), options.integrators, ladder=mode,
                          max_steps=args.ladder_max_steps, pool=pool, write_pareto=False)  # main() writes it
