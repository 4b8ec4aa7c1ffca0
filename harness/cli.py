"""The command line (DESIGN §5). Exit codes: 0 done (failed runs are data), 1 check failed, 2 bad input, 130 stopped.
"""
from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

from stereodyn.harness import cases as case_files
from stereodyn.harness.cases import CaseError
from stereodyn.harness.engines import engine_names

DEFAULT_OUT = "out"


class BadInput(Exception):
    """A user error outside case files: one line, exit code 2."""


def _list(text: str) -> list[str]:
    return [item.strip() for item in text.split(",") if item.strip()]


def _floats(text: str) -> list[float]:
    try:
        values = [float(item) for item in _list(text)]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated numbers, got {text!r}") from None
    if not values:
        raise argparse.ArgumentTypeError("expected at least one number")
    return values


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="stereodyn", description=__doc__.splitlines()[0])
    commands = parser.add_subparsers(dest="command", required=True)
    commands.add_parser("cases", help="list the suite's cases with tags")
    run = commands.add_parser("run", help="run cases on engines; write results.csv, report.md and report.html")
    run.add_argument("cases", nargs="*", metavar="CASE", help="suite case names or .toml paths (default: the suite)")
    run.add_argument("--case-file", action="append", default=[], metavar="F.toml", help="a case outside the suite")
    run.add_argument("--engines", type=_list, default=list(engine_names()),
                     help=f"comma-separated, default {','.join(engine_names())}")
    run.add_argument("--integrators", type=_list, default=None, help="comma-separated (default: each engine's all)")
    run.add_argument("--dt", type=_floats, default=None, help="comma-separated steps, replacing each case's list")
    run.add_argument("--t-end", type=float, default=None, help="simulated span, replacing each case's t_end")
    run.add_argument("--out", type=Path, default=Path(DEFAULT_OUT), help=f"output folder (default ./{DEFAULT_OUT})")
    run.add_argument("--jobs", type=int, default=None, help="local worker processes (default: all cores)")
    run.add_argument("--certify", action="store_true", help="bound the truth's error by a quadruple-precision rerun")
    run.add_argument("--quiet", action="store_true",
                     help="no progress (a bar on a terminal, one line per phase otherwise, on stderr)")
    run.add_argument("--verbose", action="store_true", help="also print every case's drift table")
    run.add_argument("--resume", action="store_true", help="reuse the runs already stored in --out (DIR/store)")
    run.add_argument("--scheduler", metavar="tcp://HOST:PORT", default=None,
                     help="run on this Dask scheduler's cluster (needs stereodyn[dask]) instead of local processes")
    run.add_argument("--dt-ladder", action="store_true",
                     help="work–precision ladder (about ten dt from the stability limit to the round-off regime) for "
                          "every case x engine x formulation x integrator; default: only the default suite's few "
                          "representative ladders")
    run.add_argument("--no-ladder", action="store_true", help="no dt ladder at all (orders from the dt lists only)")
    run.add_argument("--ladder-max-steps", type=int, default=None, metavar="N",
                     help="smallest ladder dt = t_end / N (default 200000 with --dt-ladder, 40000 otherwise)")
    run.add_argument("--strict", action="store_true",
                     help="exit 1 when a verdict fails (declared against fitted order, bounded energy, the truth's "
                          "invariants, oracle and theory checks), one line per failed verdict")
    run.add_argument("--extremes", action="store_true",
                     help="run the extreme cases (cases/extreme/, tagged extreme) instead of the default suite")
    report = commands.add_parser("report", help="re-render report.md, report.html and figures from DIR")
    report.add_argument("dir", type=Path)
    baseline = commands.add_parser("baseline", help="write the regression baseline of DIR/results.csv")
    baseline.add_argument("dir", type=Path)
    baseline.add_argument("--out", type=Path, required=True, metavar="FILE", help="baseline file to write (JSON)")
    gate = commands.add_parser("check", help="exit 1 and print the rows of DIR that got worse than the baseline")
    gate.add_argument("dir", type=Path)
    gate.add_argument("--baseline", type=Path, required=True, metavar="FILE")
    gate.add_argument("--tolerances", type=Path, default=None, metavar="FILE.toml",
                       help="[default] factor/floor, [metric.NAME] factor/floor, [time] factor")
    gate.add_argument("--factor", type=float, default=None,
                       help="a drift or error may grow to factor * baseline + floor (default 2, every metric)")
    gate.add_argument("--floor", type=float, default=None, help="absolute floor (default 1e-12, every metric)")
    gate.add_argument("--time-factor", type=float, default=None,
                       help="also fail when us_per_step exceeds this factor times the baseline's")
    compare = commands.add_parser("compare", help="two runs side by side: environments, then every row's metrics as "
                                                   "ratios B/A, largest changes first (compare.md, compare.html)")
    compare.add_argument("a", type=Path, metavar="A", help="result directory or baseline file (the reference)")
    compare.add_argument("b", type=Path, metavar="B", help="result directory or baseline file (the new run)")
    compare.add_argument("--out", type=Path, default=None, metavar="DIR", help="where to write (default: B)")
    commands.add_parser("integrators", help="list every integrator `run --integrators` accepts, with its metadata "
                                            "and origin (built in, or the plug-in's distribution)")
    export = commands.add_parser("export", help="write the engine model of a case (MJCF for MuJoCo, URDF)")
    export.add_argument("case", metavar="CASE", help="a suite case name or a .toml path")
    export.add_argument("--format", required=True, choices=("mjcf", "urdf"))
    export.add_argument("--out", type=Path, default=None, metavar="FILE", help="default: standard output")
    export.add_argument("--integrator", default=None, help="MJCF only: MuJoCo integrator (default rk4)")
    export.add_argument("--dt", type=float, default=None, help="MJCF only: timestep (default: the case's first dt)")
    return parser


def _select_cases(args) -> list:
    suite = case_files.load_suite()
    if getattr(args, "extremes", False):
        suite = case_files.load_suite(case_files.suite_dir() / "extreme")
    if args.cases:
        chosen = [case_files.find_case(name, suite) for name in args.cases]
    else:  # --case-file alone runs just those files; nothing at all runs the suite
        chosen = [] if args.case_file else list(suite)
    chosen += [case_files.load_case(path) for path in args.case_file]
    names = [c.name for c in chosen]
    if len(set(names)) != len(names):
        raise BadInput(f"case names must be unique in a run: {', '.join(sorted(names))}")
    if args.dt is not None or args.t_end is not None:
        chosen = [case_files.with_overrides(c, t_end=args.t_end, dt=args.dt) for c in chosen]
    return chosen


def _check_names(args) -> None:
    from stereodyn.harness.engines import get_engine

    unknown = [e for e in args.engines if e not in engine_names()]
    if unknown:
        raise BadInput(f"--engines: unknown engine {', '.join(unknown)}; valid: {', '.join(engine_names())}")
    if args.integrators:
        engines = [get_engine(e) for e in args.engines]
        known = {i for engine in engines for i in engine.integrators()}
        all_available = all(engine.integrators() for engine in engines)
        missing = [i for i in args.integrators if i not in known]
        if missing and all_available:
            raise BadInput(f"--integrators: unknown integrator {', '.join(missing)} for engines "
                           f"{','.join(args.engines)}; valid: {', '.join(sorted(known))}")
    if args.jobs is not None and args.jobs < 1:
        raise BadInput("--jobs: must be >= 1")


def cmd_cases(args) -> int:
    for case in case_files.load_suite():
        print(f"{case.name:20s} [{', '.join(case.tags)}]  {case.description}")
    return 0


def cmd_run(args) -> int:
    from stereodyn.harness.progress import ProgressBar
    from stereodyn.harness.report.build import write_reports
    from stereodyn.harness.report.markdown import drift_table_text
    from stereodyn.harness import summary, verdicts, workprecision
    from stereodyn.harness.runner import run_sweep

    _check_names(args)
    chosen = _select_cases(args)
    progress = ProgressBar(enabled=not args.quiet)
    df = run_sweep(chosen, args.engines, args.integrators, args.out, jobs=args.jobs, certify=args.certify,
                   progress=progress, resume=args.resume, scheduler=args.scheduler)
    _work_precision(args, chosen, df, progress)
    found = verdicts.evaluate(args.out, df, chosen)
    # "What to use" recommends no run of an integrator that failed a verdict (it names it instead)
    workprecision.rewrite_pareto(args.out, df, verdicts.failed_integrators(found))
    if args.verbose:
        print(drift_table_text(df))
    progress.stage("report: report.md, figures, report.html")
    markdown, html = write_reports(args.out, df)
    print("\n".join(summary.terminal_lines(df, found, args.out, html)))
    print(f"wrote {args.out / 'results.csv'}, {markdown} and {html}")
    if args.strict and verdicts.failed(found):
        print("\n".join(verdicts.summary_lines(found)[1:]), file=sys.stderr)
        return 1
    return 0


def _work_precision(args, chosen: list, df, progress=None) -> None:
    """ladder.csv, convergence.csv, pareto.csv and the orders in checks.csv (harness.workprecision). The default
    suite (no CASE, no --case-file, no --dt) gets the small default ladder; --dt-ladder every family's."""
    from stereodyn.harness import workprecision

    if args.ladder_max_steps is not None and args.ladder_max_steps < 2 * workprecision.MIN_STEPS:
        raise BadInput(f"--ladder-max-steps: must be >= {2 * workprecision.MIN_STEPS}")
    if args.dt_ladder:
        mode = "full"
    elif args.no_ladder or args.cases or args.case_file or args.dt is not None:
        mode = "off"
    else:
        mode = "default"
    if mode != "off" and progress is not None:
        progress.stage(f"work–precision: {mode} dt ladder")
    workprecision.analyse(args.out, df, chosen, args.engines, args.integrators, ladder=mode,
                          max_steps=args.ladder_max_steps, jobs=args.jobs)


def cmd_report(args) -> int:
    from stereodyn.harness.report.build import write_reports

    results = args.dir / "results.csv"
    if not results.is_file():
        raise BadInput(f"{results}: file not found")
    markdown, html = write_reports(args.dir)
    print(f"wrote {markdown} and {html}")
    return 0


def cmd_baseline(args) -> int:
    from stereodyn.harness import gate
    from stereodyn.harness.store import read_manifest

    manifest = read_manifest(args.dir) or {}
    rows = gate.write_baseline(gate.read_table(args.dir), args.out, manifest.get("environment"))
    print(f"wrote {args.out} ({rows} rows)")
    return 0


def cmd_check(args) -> int:
    from stereodyn.harness import gate

    tolerances = gate.Tolerances()
    if args.tolerances is not None:
        tolerances = gate.read_tolerances(args.tolerances)
    for option, value in (("--factor", args.factor), ("--time-factor", args.time_factor)):
        if value is not None and not value >= 1.0:
            raise BadInput(f"{option}: must be >= 1, got {value:g}")
    if args.floor is not None and not args.floor >= 0.0:
        raise BadInput(f"--floor: must be >= 0, got {args.floor:g}")
    if args.factor is not None or args.floor is not None:  # the command line overrides the file, for every metric
        override = {k: v for k, v in (("factor", args.factor), ("floor", args.floor)) if v is not None}
        tolerances = dataclasses.replace(
            tolerances, default=dataclasses.replace(tolerances.default, **override),
            per_metric=tuple((m, dataclasses.replace(t, **override)) for m, t in tolerances.per_metric))
    if args.time_factor is not None:
        tolerances = dataclasses.replace(tolerances, time_factor=args.time_factor)
    baseline = gate.read_baseline(args.baseline)
    current = gate.read_table(args.dir)
    findings = gate.compare(current, baseline, tolerances)
    extra = gate.new_rows(current, baseline)
    note = f"; {extra} rows not in the baseline (not checked)" if extra else ""
    if findings:
        print(gate.findings_table(findings))
        rows = len({f.key for f in findings})
        print(f"check failed: {rows} of {len(baseline)} baseline rows got worse than {args.baseline} allows{note}")
        return 1
    print(f"check passed: {len(baseline)} baseline rows, none worse{note}")
    return 0


def cmd_compare(args) -> int:
    from stereodyn.harness.compare import compare

    markdown, html, head = compare(args.a, args.b, args.out)
    print("\n".join(head))
    print(f"wrote {markdown} and {html}")
    return 0


def cmd_integrators(args) -> int:
    from stereodyn.harness.report.method import integrator_rows, listing

    print(listing(integrator_rows()))
    return 0


def cmd_export(args) -> int:
    from stereodyn.harness.export import export
    from stereodyn.harness.results import write_atomic

    text = export(case_files.find_case(args.case), args.format, args.integrator, args.dt)
    if args.out is None:
        sys.stdout.write(text)
    else:
        write_atomic(args.out, text)
        print(f"wrote {args.out}", file=sys.stderr)
    return 0


def main(argv: list[str] | None = None) -> int:
    from stereodyn.harness.gate import GateError
    from stereodyn.harness.distributed import ClusterError
    from stereodyn.harness.export import ExportError
    from stereodyn.harness.store import StoreBusy
    from stereodyn.harness.compare import CompareError

    args = _parser().parse_args(argv)
    commands = {"cases": cmd_cases, "run": cmd_run, "report": cmd_report, "baseline": cmd_baseline,
                "check": cmd_check, "export": cmd_export, "compare": cmd_compare, "integrators": cmd_integrators}
    try:
        return commands[args.command](args)
    except (CaseError, BadInput, GateError, ClusterError, ExportError, StoreBusy, CompareError) as exc:
        print(f"stereodyn: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("stereodyn: interrupted; every finished run is stored (rerun with --resume to go on)", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
