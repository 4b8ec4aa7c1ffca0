"""`stereodyn run`: its arguments parsed into a request for the pipeline (harness.pipeline: the sweep, the
work–precision ladders, the advice, the verdicts, "What to use" and the report), and the terminal's last lines."""
from __future__ import annotations

import sys

from . import BadInput, check_names, output_folder, select_cases


def main(args) -> int:
    from .. import budget
    from ..analysis import verdicts
    from ..pipeline.phases import Request, run
    from ..run.sweep import SweepOptions

    check_names(args)
    if args.certify and args.no_certify:
        raise BadInput("--certify and --no-certify: give one (certifying is the default)")
    chosen = select_cases(args)
    options = SweepOptions(args.engines, args.out, args.integrators, jobs=args.jobs, certify=not args.no_certify,
                           resume=args.resume, scheduler=args.scheduler, save_trajectories=args.save_trajectories)
    mode = ladder_mode(args)
    output_folder(args.out, "--out")
    request = Request(chosen, options, mode, args.ladder_max_steps,
                      budget.Budgets(args.run_budget, args.prepare_budget, args.truth_budget), figures=args.figures,
                      self_contained=args.self_contained, verbose=args.verbose, quiet=args.quiet)
    values = run(request)
    found = values["verdicts"]
    if not args.quiet:  # quiet: nothing on success (a CI log); --strict's failures still go to stderr below
        print("\n".join(values["summary"]))
        print(f"wrote {args.out / 'results.csv'}, {values['markdown']} and {values['html']}")
    if args.strict and verdicts.strict_failures(found):
        print("\n".join(verdicts.summary_lines(found)[1:]), file=sys.stderr)
        return 1
    return 0


def ladder_mode(args) -> str:
    """The work–precision mode (analysis.workprecision.plan_ladders; pareto.csv is written after the verdicts). The
    default suite (no CASE, no --case-file, no --dt) gets the small default ladders; named cases or steps with
    --strict only the short ladders of the integrators no case's dt list gives an order, or whose orders miss on too
    few points (without --strict none); --dt-ladder every family's; --no-ladder none, or with --strict the short
    ladders only."""
    from ..analysis import workprecision

    if args.ladder_max_steps is not None and args.ladder_max_steps < 2 * workprecision.MIN_STEPS:
        raise BadInput(f"--ladder-max-steps: must be >= {2 * workprecision.MIN_STEPS}")
    if args.dt_ladder:
        return "full"
    if args.no_ladder or args.cases or args.case_file or args.dt is not None:
        # --strict judges: a declared order no case's dt list measured, or missed on too few points
        # (verdicts.NOT_ENOUGH), is measured (short ladders) before it is judged, --no-ladder or not (it then means no
        # dt or tolerance ladder); without --strict such a claim is reported "not measured, no reason" or "not enough
        # evidence"
        return "short" if args.strict else "off"
    return "default"
