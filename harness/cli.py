"""The command line (DESIGN §5). Exit codes: 0 done (runs may have failed: that is data), 2 bad input."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from harness import cases as case_files
from harness.cases import CaseError
from harness.engines import engine_names

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
    run = commands.add_parser("run", help="run cases on engines; write results.csv and report.md")
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
    run.add_argument("--quiet", action="store_true", help="no progress lines")
    report = commands.add_parser("report", help="re-render report.md from DIR/results.csv")
    report.add_argument("dir", type=Path)
    return parser


def _select_cases(args) -> list:
    suite = case_files.load_suite()
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
    from harness.engines import get_engine

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
    from harness.report.markdown import drift_table_text, write_report
    from harness.runner import run_sweep, stderr_progress

    _check_names(args)
    chosen = _select_cases(args)
    progress = None if args.quiet else stderr_progress
    df = run_sweep(chosen, args.engines, args.integrators, args.out, jobs=args.jobs, certify=args.certify,
                   progress=progress)
    print(drift_table_text(df))
    report = write_report(df, args.out)
    print(f"wrote {args.out / 'results.csv'} and {report}")
    return 0


def cmd_report(args) -> int:
    from harness.report.markdown import write_report
    from harness.results import read_results

    results = args.dir / "results.csv"
    if not results.is_file():
        raise BadInput(f"{results}: file not found")
    print(f"wrote {write_report(read_results(results), args.dir)}")
    return 0


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    try:
        return {"cases": cmd_cases, "run": cmd_run, "report": cmd_report}[args.command](args)
    except (CaseError, BadInput) as exc:
        print(f"stereodyn: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("stereodyn: interrupted; results.csv holds every run that finished", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
