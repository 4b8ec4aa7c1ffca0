"""The command line (DESIGN §5). Exit codes: 0 done (failed runs are data), 1 check failed, 2 bad input, 130 stopped.
"""
from __future__ import annotations

import os
import signal
import sys


def _interrupted_while_loading(signum, frame) -> None:
    sys.stderr.write("stereodyn: interrupted\n")
    os._exit(130)


# Started as the command (the `stereodyn` script, python -m stereodyn or this file), Ctrl-C while the modules below
# load ends in one line; main() puts Python's handler back once they are in. Imported as a library: untouched.
if sys.argv and (os.path.basename(sys.argv[0]) == "stereodyn" or __name__ == "__main__"
                 or sys.argv[0].endswith(os.path.join("stereodyn", "__main__.py"))):
    signal.signal(signal.SIGINT, _interrupted_while_loading)

import argparse  # noqa: E402  (after the handler, on purpose)
import dataclasses  # noqa: E402
import math  # noqa: E402
import tempfile  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

# The command's modules (numpy, the SDKs behind them) are imported by main() inside its Ctrl-C handling (_load), so an
# interrupt while they load ends in one line, not a traceback: this module imports only the standard library.
case_files = CaseError = engine_names = EngineError = None

DEFAULT_OUT = "out"


class BadInput(Exception):
    """A user error outside case files: one line, exit code 2."""


class _Parser(argparse.ArgumentParser):
    """argparse with a one-line error (exit 2) instead of the usage block plus the error."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {' '.join(message.split())}\n")


def _list(text: str) -> list[str]:
    """Comma-separated names: none at all, an empty item or a name twice is an error (it would run nothing, or
    every row twice)."""
    items = [item.strip() for item in text.split(",")]
    if not any(items):
        raise argparse.ArgumentTypeError("expected at least one comma-separated name, got none")
    if not all(items):
        raise argparse.ArgumentTypeError(f"empty name in {text!r}")
    twice = sorted({item for item in items if items.count(item) > 1})
    if twice:
        raise argparse.ArgumentTypeError(f"{', '.join(twice)} given twice")
    return items


def _count(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text[:40]!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be >= 1, got {value}")
    return value


def _floats(text: str) -> list[float]:
    items = [item.strip() for item in text.split(",") if item.strip()]
    try:
        values = [_scale(item) for item in items]
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    if not values:
        raise argparse.ArgumentTypeError("expected at least one number")
    if len(values) > case_files.MAX_DTS:
        raise argparse.ArgumentTypeError(f"at most {case_files.MAX_DTS} steps, got {len(values)}")
    return values


def _scale(text: str) -> float:
    """A step or a span: finite, in [MIN_SCALE, MAX_MAGNITUDE] like a case file's (docs/limits.md)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text[:40]!r}") from None
    if not math.isfinite(value) or not case_files.MIN_SCALE <= value <= case_files.MAX_MAGNITUDE:
        raise argparse.ArgumentTypeError(f"must be finite and in [{case_files.MIN_SCALE:g}, "
                                         f"{case_files.MAX_MAGNITUDE:g}] s (docs/limits.md), got {value:g}")
    return value


def _parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="stereodyn", description=__doc__.splitlines()[0])
    commands = parser.add_subparsers(dest="command", required=True)
    commands.add_parser("cases", help="list the suite's cases with tags")
    run = commands.add_parser("run", help="run cases on engines; write results.csv, report.md and report.html")
    run.add_argument("cases", nargs="*", metavar="CASE", help="suite case names or .toml paths (default: the suite)")
    run.add_argument("--case-file", action="append", default=[], metavar="F.toml", help="a case outside the suite")
    run.add_argument("--engines", type=_list, default=list(engine_names()),
                     help=f"comma-separated, default {','.join(engine_names())}")
    run.add_argument("--integrators", type=_list, default=None, help="comma-separated (default: each engine's all)")
    run.add_argument("--dt", type=_floats, default=None, help="comma-separated steps, replacing each case's list")
    run.add_argument("--t-end", type=_scale, default=None, help="simulated span, replacing each case's t_end")
    run.add_argument("--out", type=Path, default=Path(DEFAULT_OUT), help=f"output folder (default ./{DEFAULT_OUT})")
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
    run.add_argument("--quiet", action="store_true",
                     help="no progress (a bar on a terminal, one line per phase otherwise, on stderr)")
    run.add_argument("--verbose", action="store_true", help="also print every case's drift table")
    run.add_argument("--resume", action="store_true", help="reuse the runs already stored in --out (DIR/store)")
    run.add_argument("--scheduler", metavar="tcp://HOST:PORT", default=None,
                     help="run on this Dask scheduler's cluster (needs stereodyn[dask]) instead of local processes")
    run.add_argument("--dt-ladder", action="store_true",
                     help="work–precision ladder (about ten dt from the stability limit to the round-off regime) for "
                          "every case x engine x formulation x integrator, and a tolerance ladder (1e-3 ... 1e-13) "
                          "for every adaptive one; default: only the default suite's few representative ladders")
    run.add_argument("--no-ladder", action="store_true",
                     help="no dt ladder and no tolerance ladder at all (orders from the dt lists only)")
    run.add_argument("--ladder-max-steps", type=_count, default=None, metavar="N",
                     help="smallest ladder dt = t_end / N (default 200000 with --dt-ladder, 40000 otherwise)")
    run.add_argument("--strict", action="store_true",
                     help="exit 1 when a verdict fails (declared against fitted order, bounded energy, the truth's "
                          "invariants, oracle and theory checks), one line per failed verdict")
    run.add_argument("--extremes", action="store_true",
                     help="run the extreme cases (cases/extreme/, tagged extreme) instead of the default suite")
    report = commands.add_parser("report", help="re-render report.md, report.html and figures from DIR")
    report.add_argument("dir", type=Path)
    report.add_argument("--self-contained", action="store_true",
                        help="embed the figures in report.html (one file to send; larger) instead of linking them")
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
                                                   "ratios B/A, largest changes first (OUT/compare.md, OUT/compare.html)")
    compare.add_argument("a", type=Path, metavar="A", help="result directory or baseline file (the reference)")
    compare.add_argument("b", type=Path, metavar="B", help="result directory or baseline file (the new run)")
    compare.add_argument("--out", type=Path, default=None, metavar="DIR", help="where to write (default: B)")
    commands.add_parser("integrators", help="list every integrator `run --integrators` accepts, with its metadata "
                                            "and origin (built in, or the plug-in's distribution)")
    export = commands.add_parser("export", help="write the engine model of a case (MJCF for MuJoCo, URDF)")
    export.add_argument("case", metavar="CASE", help="a suite case name or a .toml path")
    export.add_argument("--format", required=True, help="a model format of an engine: mjcf (MuJoCo), urdf (Pinocchio)")
    export.add_argument("--out", type=Path, default=None, metavar="FILE", help="default: standard output")
    export.add_argument("--integrator", default=None, help="MJCF only: MuJoCo integrator (default rk4)")
    export.add_argument("--dt", type=_scale, default=None, help="MJCF only: timestep (default: the case's first dt)")
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
        chosen = [_override(c, args) for c in chosen]
    return chosen


def _override(case, args):
    """The case with --t-end / --dt; a value they make invalid is the option's fault, not the case file's."""
    try:
        return case_files.with_overrides(case, t_end=args.t_end, dt=args.dt)
    except CaseError as exc:
        option = "--dt" if args.dt is not None else "--t-end"
        raise BadInput(f"{option}: with case {case.name!r}" + (f" (t_end {case.t_end:g})" if args.t_end is None else
                                                                "") + f": {exc.rule}") from None


def _output_folder(path: Path, option: str) -> Path:
    """Create the output folder (and its store/) and prove it writable, or one line naming the option."""
    try:
        for folder in (path, path / "store"):
            folder.mkdir(parents=True, exist_ok=True)
            with tempfile.TemporaryFile(dir=folder):
                pass
    except OSError as exc:
        raise BadInput(f"{option} {path}: not a writable folder ({exc.strerror or type(exc).__name__})") from None
    return path


def _output_file(path: Path, option: str) -> Path:
    """A file to write: its folder must exist and be writable, and the path not be a folder."""
    folder = path.parent if str(path.parent) else Path(".")
    if path.is_dir():
        raise BadInput(f"{option} {path}: is a folder, not a file")
    if not folder.is_dir():
        raise BadInput(f"{option} {path}: folder {folder} does not exist")
    try:
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError as exc:
        raise BadInput(f"{option} {path}: cannot write in {folder} ({exc.strerror or type(exc).__name__})") from None
    return path


def _check_names(args) -> None:
    from stereodyn.harness.engines import UnavailableEngine, get_engine

    unknown = [e for e in args.engines if e not in engine_names()]
    if unknown:
        raise BadInput(f"--engines: unknown engine {', '.join(unknown)}; valid: {', '.join(engine_names())}")
    if args.integrators:
        engines = [get_engine(e) for e in args.engines]
        known = {i for engine in engines for i in engine.integrators()}
        missing = [i for i in args.integrators if i not in known]
        # an engine whose SDK is missing lists no integrators: a name may be its, so the message says how to get it
        absent = [e.reason for e in engines if isinstance(e, UnavailableEngine)]
        if missing:
            raise BadInput(f"--integrators: unknown integrator {', '.join(missing)} for engines "
                           f"{','.join(args.engines)}; valid: {', '.join(sorted(known))}"
                           + (f" (not installed: {'; '.join(absent)})" if absent else ""))
    if getattr(args, "dt_ladder", False) and args.no_ladder:
        raise BadInput("--dt-ladder and --no-ladder: give at most one")
    if getattr(args, "ladder_max_steps", None) is not None:
        from stereodyn.harness import workprecision

        if args.ladder_max_steps < 2 * workprecision.MIN_STEPS:  # checked before the sweep, not after it
            raise BadInput(f"--ladder-max-steps: must be >= {2 * workprecision.MIN_STEPS}, got {args.ladder_max_steps}")
        if args.ladder_max_steps > case_files.MAX_STEPS:
            raise BadInput(f"--ladder-max-steps: must be <= {case_files.MAX_STEPS}, got {args.ladder_max_steps}")


def cmd_cases(args) -> int:
    for case in case_files.load_suite():
        print(f"{case.name:20s} [{', '.join(case.tags)}]  {case.description}")
    return 0


def cmd_run(args) -> int:
    from stereodyn.harness.run.progress import ProgressBar
    from stereodyn.harness.report.build import write_reports
    from stereodyn.harness.report.markdown import drift_table_text
    from stereodyn.harness import summary, verdicts, workprecision
    from stereodyn.harness.run.sweep import run_sweep, worker_pool

    from stereodyn.harness.run.store import folder_lock

    _check_names(args)
    if args.certify and args.no_certify:
        raise BadInput("--certify and --no-certify: give one (certifying is the default)")
    chosen = _select_cases(args)
    progress = ProgressBar(enabled=not args.quiet)
    _output_folder(args.out, "--out")
    _quiet_engines(args.out)
    with folder_lock(args.out):  # the whole command: a second run into --out waits for none of it to interleave
        # one pool for the sweep and the dt ladders; Ctrl-C anywhere in it ends its workers at once
        with worker_pool(args.jobs, tuple(args.engines)) as pool:
            df = run_sweep(chosen, args.engines, args.integrators, args.out, jobs=args.jobs,
                           certify=not args.no_certify, progress=progress, resume=args.resume,
                           scheduler=args.scheduler, save_trajectories=args.save_trajectories, pool=pool)
            _work_precision(args, chosen, df, pool, progress)
        found = verdicts.evaluate(args.out, df, chosen)
        # "What to use" recommends no run of an integrator that failed a verdict (it names it instead)
        workprecision.rewrite_pareto(args.out, df, verdicts.failed_integrators(found))
        if args.verbose:
            print(drift_table_text(df))
        progress.stage("report: report.md, figures, report.html")
        markdown, html = write_reports(args.out, df, self_contained=args.self_contained)
        print("\n".join(summary.terminal_lines(df, found, args.out, html)))
    print(f"wrote {args.out / 'results.csv'}, {markdown} and {html}")
    if args.strict and verdicts.strict_failures(found):
        print("\n".join(verdicts.summary_lines(found)[1:]), file=sys.stderr)
        return 1
    return 0


def _quiet_engines(out: Path) -> None:
    """MuJoCo appends its warnings to MUJOCO_LOG.TXT in the working directory: put it under --out (the adapter
    collects the warnings of a run into its row); worker processes inherit the setting through the environment."""
    os.environ["STEREODYN_MUJOCO_LOG"] = str(Path(out).resolve() / "MUJOCO_LOG.TXT")  # engines.mujoco.LOG_ENV


def _work_precision(args, chosen: list, df, pool=None, progress=None) -> None:
    """ladder.csv, convergence.csv, tolerance.csv, tolerance_fit.csv, pareto.csv and the orders in checks.csv
    (harness.workprecision). The default suite (no CASE, no --case-file, no --dt) gets the small default ladders;
    named cases or steps with --strict only the short ladders of the integrators no case's dt list gives an order
    (without --strict none); --dt-ladder every family's; --no-ladder none."""
    from stereodyn.harness import workprecision

    if args.ladder_max_steps is not None and args.ladder_max_steps < 2 * workprecision.MIN_STEPS:
        raise BadInput(f"--ladder-max-steps: must be >= {2 * workprecision.MIN_STEPS}")
    if args.dt_ladder:
        mode = "full"
    elif args.no_ladder:
        mode = "off"
    elif args.cases or args.case_file or args.dt is not None:
        # --strict judges: a declared order no case's dt list measured is measured (short ladders) before it is
        # judged; without it such a claim is reported "not measured, no reason"
        mode = "short" if args.strict else "off"
    else:
        mode = "default"
    if mode != "off" and progress is not None:
        progress.stage("work–precision: short ladders" if mode == "short" else
                       f"work–precision: {mode} dt and tolerance ladders"
                       + (" and short ladders" if mode == "default" else ""))
    workprecision.analyse(args.out, df, chosen, args.engines, args.integrators, ladder=mode,
                          max_steps=args.ladder_max_steps, pool=pool)


def cmd_report(args) -> int:
    from stereodyn.harness.report.build import write_reports

    from stereodyn.harness.run.results import TableError
    from stereodyn.harness.run.store import folder_lock

    results = args.dir / "results.csv"
    if not results.is_file():
        raise BadInput(f"{results}: file not found")
    _output_folder(args.dir, "report DIR")
    with folder_lock(args.dir):
        try:
            markdown, html = write_reports(args.dir, self_contained=args.self_contained)
        except (KeyError, ValueError, TypeError, IndexError, AttributeError) as exc:
            if isinstance(exc, TableError):
                raise
            # a table that read but does not hold what stereodyn writes (a column of text where numbers belong, ...)
            raise BadInput(f"{args.dir}: malformed tables, cannot render the report "
                           f"({type(exc).__name__}: {' '.join(str(exc).split())[:160]})") from None
    print(f"wrote {markdown} and {html}")
    return 0


def cmd_baseline(args) -> int:
    from stereodyn.harness import gate
    from stereodyn.harness.run.store import read_manifest

    _output_file(args.out, "--out")
    manifest = read_manifest(args.dir) or {}
    table, orders = gate.read_table(args.dir), gate.read_orders(args.dir)
    rows = gate.write_baseline(table, args.out, manifest.get("environment"), orders)
    print(f"wrote {args.out} ({rows} rows, {0 if orders is None else len(orders)} fitted orders)")
    return 0


def cmd_check(args) -> int:
    from stereodyn.harness import gate

    tolerances = gate.Tolerances()
    if args.tolerances is not None:
        tolerances = gate.read_tolerances(args.tolerances)
    # An infinite factor or floor would pass any drift (--factor inf passed a 1e6x regression): finite only.
    for option, value in (("--factor", args.factor), ("--time-factor", args.time_factor)):
        if value is not None and not (math.isfinite(value) and value >= 1.0):
            raise BadInput(f"{option}: must be a finite number >= 1, got {value:g}")
    if args.floor is not None and not (math.isfinite(args.floor) and args.floor >= 0.0):
        raise BadInput(f"--floor: must be a finite number >= 0, got {args.floor:g}")
    if args.factor is not None or args.floor is not None:  # the command line overrides the file, for every metric
        override = {k: v for k, v in (("factor", args.factor), ("floor", args.floor)) if v is not None}
        tolerances = dataclasses.replace(
            tolerances, default=dataclasses.replace(tolerances.default, **override),
            per_metric=tuple((m, dataclasses.replace(t, **override)) for m, t in tolerances.per_metric))
    if args.time_factor is not None:
        tolerances = dataclasses.replace(tolerances, time_factor=args.time_factor)
    from stereodyn.harness.run.store import read_manifest

    base = gate.read_baseline_file(args.baseline)
    baseline = base.rows
    current = gate.read_table(args.dir)
    used = sorted({m for row in baseline for m in gate.metric_columns(row) if row.get(m) is not None})
    missing = [m for m in used if m not in current.columns]
    if missing:  # else every row would read as NaN, i.e. worse
        raise BadInput(f"{args.dir / 'results.csv'}: missing columns {', '.join(missing)} (the baseline has them)")
    orders = gate.read_orders(args.dir) if base.orders else None
    changes = gate.environment_changes(base.environment, (read_manifest(args.dir) or {}).get("environment"))
    print(f"environment: {', '.join(changes)}" if changes else "environment: as in the baseline")
    findings = gate.compare(current, baseline, tolerances)
    order_findings = gate.compare_orders(orders, base.orders)
    extra = gate.new_rows(current, baseline)
    note = f"; {extra} rows not in the baseline (not checked)" if extra else ""
    if findings or order_findings:
        for line in gate.summary(findings + order_findings):
            print(line)
        print(gate.findings_table(findings + order_findings))
        worse = len({f.key for f in findings if f.what != "missing"})
        gone = sum(f.what == "missing" for f in findings)
        parts = []
        if worse:
            parts.append(f"{worse} of {len(baseline)} baseline rows got worse than {args.baseline} allows")
        if gone:
            parts.append(f"{gone} of {len(baseline)} baseline rows missing")
        if order_findings:
            parts.append(f"{len(order_findings)} of {len(base.orders)} fitted orders fell")
        print(f"check failed: {'; '.join(parts)}{note}")
        return 1
    orders_note = f", {len(base.orders)} fitted orders" if base.orders else ""
    print(f"check passed: {len(baseline)} baseline rows{orders_note}, none worse{note}")
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
    from stereodyn.harness.run.results import write_atomic

    if args.out is not None:
        _output_file(args.out, "--out")
    text = export(case_files.find_case(args.case), args.format, args.integrator, args.dt)
    if args.out is None:
        sys.stdout.write(text)
    else:
        write_atomic(args.out, text)
        print(f"wrote {args.out}", file=sys.stderr)
    return 0


def _load() -> None:
    global case_files, CaseError, engine_names, EngineError
    from stereodyn.harness.scenes import cases as case_files
    from stereodyn.harness.scenes.cases import CaseError
    from stereodyn.harness.engines import EngineError, engine_names


def main(argv: list[str] | None = None) -> int:
    # Numeric warnings (overflow in a diverging run, which is data) and MuJoCo's are not for stderr; the workers
    # inherit the environment variable.
    # A case name in a script the plot font lacks (CJK) is drawn as boxes; matplotlib's warning about it is noise too.
    warnings.filterwarnings("ignore", category=RuntimeWarning)
    warnings.filterwarnings("ignore", message="Glyph .* missing from font", category=UserWarning)
    os.environ.setdefault("PYTHONWARNINGS", "ignore::RuntimeWarning,ignore:Glyph:UserWarning")
    try:
        _load()
        from stereodyn.harness.gate import GateError
        from stereodyn.harness.run.distributed import ClusterError
        from stereodyn.harness.export import ExportError
        from stereodyn.harness.run.store import StoreBusy
        from stereodyn.harness.run.results import TableError
        from stereodyn.harness.compare import CompareError
    except KeyboardInterrupt:
        print("stereodyn: interrupted", file=sys.stderr)
        return 130
    if signal.getsignal(signal.SIGINT) is _interrupted_while_loading:
        signal.signal(signal.SIGINT, signal.default_int_handler)  # loaded: KeyboardInterrupt, handled below

    try:
        args = _parser().parse_args(argv)
    except SystemExit as exc:  # the usage error's line is printed already; a caller of main() gets the code
        return exc.code if isinstance(exc.code, int) else 2
    commands = {"cases": cmd_cases, "run": cmd_run, "report": cmd_report, "baseline": cmd_baseline,
                "check": cmd_check, "export": cmd_export, "compare": cmd_compare, "integrators": cmd_integrators}
    try:
        return commands[args.command](args)
    except (CaseError, BadInput, GateError, ClusterError, ExportError, StoreBusy, TableError, EngineError,
            CompareError) as exc:
        print(f"stereodyn: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:  # a path the checks above could not foresee (a disk full, a folder gone mid-run)
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"stereodyn: error: {where}{exc.strerror or exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("stereodyn: interrupted; every finished run is stored (rerun with --resume to go on)", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
