"""`stereodyn run`: its arguments parsed into a request for the pipeline (harness.pipeline: the sweep, the
work–precision ladders, the advice, the verdicts, "What to use" and the report), and the terminal's last lines."""
from __future__ import annotations

from pathlib import Path

import sys

from .common import (BadInput, budget_options, budgets_of, check_names, check_options, _count, DEFAULT_OUT, _figures,
                     _floats, _list, output_folder, _path, _scale, select_cases)


def add_parser(commands) -> None:
    run = commands.add_parser("run", help="run cases on engines; write results.csv, report.md and report.html")
    run.add_argument("cases", nargs="*", metavar="CASE", help="suite case names or .toml paths (default: the suite)")
    run.add_argument("--case-file", action="append", default=[], metavar="F.toml", help="a case outside the suite")
    # The default is resolved by check_names, not here: building the parser loads no plug-in (one that is broken or
    # claims a built-in's name must not stop every command, `stereodyn cases` included)
    run.add_argument("--engines", type=_list, default=None,
                     help="comma-separated (default: every registered engine, `stereodyn engines`, a broken plug-in "
                          "left out with a warning)")
    run.add_argument("--integrators", type=_list, default=None, help="comma-separated (default: each engine's all)")
    run.add_argument("--dt", type=_floats, default=None, help="comma-separated steps, replacing each case's list")
    run.add_argument("--t-end", type=_scale, default=None, help="simulated span, replacing each case's t_end")
    run.add_argument("--out", type=_path, default=Path(DEFAULT_OUT), help=f"output folder (default ./{DEFAULT_OUT})")
    run.add_argument("--jobs", type=_count, default=None, help="local worker processes (default: all cores)")
    run.add_argument("--no-certify", action="store_true",
                     help="skip the quadruple-precision rerun (~0.2 s a case) that bounds each truth's error "
                          "(truth_err, truth_omega_err are then empty)")
    run.add_argument("--certify", action="store_true", help="accepted for old scripts: certifying is the default")
    run.add_argument("--save-trajectories", action="store_true",
                     help="also write each run's recorded states, the truth's included, to "
                          "DIR/trajectories/<key>.npz (times, quat wxyz body->world, omega body, truth_quat and "
                          "truth_omega on the same times; case, engine, formulation, integrator, dt) and their "
                          "index, DIR/trajectories/index.csv")
    run.add_argument("--self-contained", action="store_true",
                     help="embed the figures in report.html (one file to send; larger) instead of linking "
                          "DIR/figures/")
    _figures(run)
    run.add_argument("--quiet", action="store_true",
                     help="print nothing on success: no progress (a bar on a terminal, one line per phase otherwise, "
                          "on stderr), no summary; warnings and --strict's failed verdicts still go to stderr")
    run.add_argument("--verbose", action="store_true", help="also print every case's drift table")
    run.add_argument("--resume", action="store_true", help="reuse the runs already stored in --out (DIR/store)")
    run.add_argument("--scheduler", metavar="tcp://HOST:PORT", default=None,
                     help="run on this Dask scheduler's cluster (needs stereodyn[dask]) instead of local processes")
    run.add_argument("--dt-ladder", action="store_true",
                     help="work–precision ladder (about ten dt from the stability limit to the round-off regime) for "
                          "every case x engine x formulation x integrator, and a tolerance ladder (1e-3 ... 1e-13) "
                          "for every adaptive one; default: only the default suite's few representative ladders")
    run.add_argument("--no-ladder", action="store_true",
                     help="no dt ladder and no tolerance ladder (orders from the dt lists; with --strict the short "
                          "ladders its verdicts need still run)")
    run.add_argument("--ladder-max-steps", type=_count, default=None, metavar="N",
                     help="smallest ladder dt = t_end / N (default 200000 with --dt-ladder, 40000 otherwise)")
    run.add_argument("--strict", action="store_true",
                     help="exit 1 when a verdict fails (declared against fitted order, bounded energy, the truth's "
                          "invariants, oracle and theory checks), one line per failed verdict")
    budget_options(run)
    run.add_argument("--extremes", action="store_true",
                     help="run the extreme cases (cases/extreme/, tagged extreme) instead of the default suite")


def main(args) -> int:
    from ..analysis import verdicts
    from ..pipeline.phases import Request, run
    from ..run.sweep import SweepOptions

    check_options(args)
    check_names(args)
    chosen = select_cases(args)
    options = SweepOptions(args.engines, args.out, args.integrators, jobs=args.jobs, certify=not args.no_certify,
                           resume=args.resume, scheduler=args.scheduler, save_trajectories=args.save_trajectories)
    mode = ladder_mode(args)
    refuse_foreign_tables(args.out)
    output_folder(args.out, "--out")
    request = Request(chosen, options, mode, args.ladder_max_steps,
                      budgets_of(args), figures=args.figures,
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


def refuse_foreign_tables(out: Path) -> None:
    """--out naming a folder that holds a run's tables (results.csv, report.md, ...) but no runs.json: they are not a
    stereodyn run's (another tool's, or a user's own), and the sweep would overwrite them. A run folder of ours (its
    runs.json, even a killed sweep's) is rerun or resumed in place."""
    from ..report.index import ENTRIES, INDEX_FILE
    from ..run.store import MANIFEST, STORE_DIR

    if not out.is_dir() or (out / MANIFEST).exists() or (out / STORE_DIR).is_dir():
        return
    # the tables and pages a run writes: the index's entries but folders, the index (a README.md not ours is left as
    # it is), MuJoCo's log (appended to) and other commands' files
    written = [name for name, what in ENTRIES.items() if not name.endswith("/") and name not in (INDEX_FILE, "MUJOCO_LOG.TXT")
               and not what.startswith("`stereodyn")]
    found = [name for name in written if (out / name).exists()]
    if found:
        raise BadInput(f"--out {out}: holds {', '.join(found)} but no {MANIFEST}: not a stereodyn run folder, and the "
                       "run would overwrite them; give an empty folder or a new path")


def ladder_mode(args) -> str:
    """The work–precision mode (analysis.workprecision.plan_ladders; pareto.csv is written after the verdicts). The
    default suite (no CASE, no --case-file, no --dt) gets the small default ladders; named cases or steps with
    --strict only the short ladders of the integrators no case's dt list gives an order, or whose orders miss on too
    few points (without --strict none); --dt-ladder every family's; --no-ladder none, or with --strict the short
    ladders only."""
    if args.dt_ladder:
        return "full"
    if args.no_ladder or args.cases or args.case_file or args.dt is not None:
        # --strict judges: a declared order no case's dt list measured, or missed on too few points
        # (verdicts.NOT_ENOUGH), is measured (short ladders) before it is judged, --no-ladder or not (it then means no
        # dt or tolerance ladder); without --strict such a claim is reported "not measured, no reason" or "not enough
        # evidence"
        return "short" if args.strict else "off"
    return "default"
