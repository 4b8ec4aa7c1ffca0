"""The command line (DESIGN §5). Exit codes: 0 done (failed runs are data), 1 check failed, 2 bad input, 3 a bug in
stereodyn (harness/errors.py), 130 stopped.

This module holds the parser, the checks commands share and the dispatch; each command is a module of this package
(run.py, check.py, ...) with a `main(args) -> int`.
"""
from __future__ import annotations

import os
import signal
import sys


def _interrupted_while_loading(signum, frame) -> None:
    sys.stderr.write("stereodyn: interrupted\n")
    os._exit(130)


# Started as the command (the `stereodyn` script, python -m stereodyn, or python -m stereodyn.harness.cli: while
# locating that, Python loads this package with argv[0] "-m"), Ctrl-C while the modules below load ends in one line;
# main() then puts the command's handler (harness/run/processes.py: on_interrupt). Imported as a library: untouched.
# A pool worker (which imports this module as its __main__'s) ignores Ctrl-C: harness/run/processes.py.
if sys.argv and (os.path.basename(sys.argv[0]) == "stereodyn" or sys.argv[0] == "-m"
                 or sys.argv[0].endswith(os.path.join("stereodyn", "__main__.py"))) \
        and not __import__("stereodyn.harness.run.processes").harness.run.processes.is_worker():
    signal.signal(signal.SIGINT, _interrupted_while_loading)

import argparse  # noqa: E402  (after the handler, on purpose)
import importlib  # noqa: E402
import math  # noqa: E402
import tempfile  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

# The command's modules (numpy, the SDKs behind them) are imported by main() inside its Ctrl-C handling (_load), so an
# interrupt while they load ends in one line, not a traceback: this module imports only the standard library.
case_files = CaseError = engine_names = EngineError = budget = None
# Each command is the module of its name in this package, with main(args) -> int.
COMMANDS = ("cases", "run", "report", "baseline", "check", "export", "advise", "compare", "integrators", "engines",
            "history", "matrix")
_commands: dict = {}

DEFAULT_OUT = "out"
FIGURES_ENV = "STEREODYN_FIGURES"  # "0": --no-figures by default (a test suite, a CI gate)
GATE_MODES = ("same-machine", "cross-machine")  # harness.analysis.gate.MODES (this module imports no analysis)


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


def _path(text: str) -> Path:
    """A path option: an empty one would be the current folder (--out '' wrote the tables there)."""
    if not text.strip():
        raise argparse.ArgumentTypeError("an empty path")
    return Path(text)


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


def _seconds(text: str) -> float:
    """A wall-time budget: finite, in [MIN_BUDGET_S, MAX_BUDGET_S] s (docs/limits.md)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number of seconds, got {text[:40]!r}") from None
    if not (math.isfinite(value) and budget.MIN_BUDGET_S <= value <= budget.MAX_BUDGET_S):
        raise argparse.ArgumentTypeError(f"must be finite and in [{budget.MIN_BUDGET_S:g}, {budget.MAX_BUDGET_S:g}] "
                                         f"s (docs/limits.md), got {value:g}")
    return value


def _targets(text: str) -> list[float]:
    """Accuracy targets: rad, each finite and in (0, 1)."""
    values = []
    for item in (item.strip() for item in text.split(",")):
        try:
            value = float(item)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a number, got {item[:40]!r}") from None
        if not (math.isfinite(value) and 0.0 < value < 1.0):
            raise argparse.ArgumentTypeError(f"must be in (0, 1) rad, got {value:g}")
        values.append(value)
    return values


def _parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="stereodyn", description=__doc__.splitlines()[0])
    commands = parser.add_subparsers(dest="command", required=True)
    commands.add_parser("cases", help="list the suite's cases with tags")
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
    for what, default, meaning in (
            ("run", budget.RUN_BUDGET_S, "one row's accuracy run with its metrics and checks (a ladder point's too)"),
            ("prepare", budget.PREPARE_BUDGET_S, "one Engine.prepare: model building and compilation"),
            ("truth", budget.TRUTH_BUDGET_S, "one case's truth and its real128 certification")):
        run.add_argument(budget.FLAGS[what], type=_seconds, default=default, metavar="S",
                         help=f"wall-time budget of {meaning}, s (default {default:g}); past it the row is failed, "
                              "its message naming the budget, and --resume redoes it only once the budget is raised")
    run.add_argument("--extremes", action="store_true",
                     help="run the extreme cases (cases/extreme/, tagged extreme) instead of the default suite")
    report = commands.add_parser("report", help="re-render report.md, report.html and figures from DIR")
    report.add_argument("dir", type=_path)
    _allow_partial(report)
    report.add_argument("--self-contained", action="store_true",
                        help="embed the figures in report.html (one file to send; larger) instead of linking them")
    _figures(report)
    baseline = commands.add_parser("baseline", help="write the regression baseline of DIR/results.csv")
    baseline.add_argument("dir", type=_path)
    baseline.add_argument("--out", type=_path, required=True, metavar="FILE", help="baseline file to write (JSON)")
    baseline.add_argument("--mode", choices=GATE_MODES, default=GATE_MODES[0],
                          help="what `check` will compare against it, recorded in the file: same-machine (the "
                               "default; the same machine and library versions, factor 1.05) or cross-machine "
                               "(another CPU or versions, factor 2)")
    _allow_partial(baseline)
    gate = commands.add_parser("check", help="exit 1 and print the rows of DIR that got worse than the baseline")
    gate.add_argument("dir", type=_path)
    gate.add_argument("--baseline", type=_path, required=True, metavar="FILE")
    _allow_partial(gate)
    gate.add_argument("--tolerances", type=_path, default=None, metavar="FILE.toml",
                       help="[default] factor/floor, [metric.NAME] factor/floor, [time] factor")
    gate.add_argument("--mode", choices=GATE_MODES, default=None,
                       help="the default tolerance: same-machine (factor 1.05) or cross-machine (factor 2); default: "
                            "the mode the baseline records (cross-machine for a baseline that records none)")
    gate.add_argument("--factor", type=float, default=None,
                       help="a drift or error may grow to factor * baseline + floor (default: the mode's, every "
                            "metric)")
    gate.add_argument("--floor", type=float, default=None, help="absolute floor (default 1e-12, every metric)")
    gate.add_argument("--time-factor", type=float, default=None,
                       help="also fail when us_per_step exceeds this factor times the baseline's (only on one idle "
                            "machine: a loaded one moves timings by more, docs/DESIGN.md §4, Baselines)")
    gate.add_argument("--junit", type=_path, default=None, metavar="FILE",
                       help="also write JUnit XML: one test case per baseline row and fitted order")
    gate.add_argument("--quiet", action="store_true", help="print nothing on success, only the failures otherwise")
    compare = commands.add_parser("compare", help="two runs side by side: environments, then every row's metrics as "
                                                   "ratios B/A, largest changes first (OUT/compare.md, OUT/compare.html)")
    compare.add_argument("a", type=_path, metavar="A", help="result directory or baseline file (the reference)")
    compare.add_argument("b", type=_path, metavar="B", help="result directory or baseline file (the new run)")
    compare.add_argument("--out", type=_path, default=None, metavar="DIR", help="where to write (default: B)")
    compare.add_argument("--format", choices=("pages", "pr"), default="pages",
                         help="pages (default): write compare.md, compare.html, compare.csv; pr: also print a "
                              "markdown summary of at most 60 lines for a pull request (OUT/compare-pr.md)")
    _allow_partial(compare)
    _history_parser(commands)
    _matrix_parser(commands)
    listed = commands.add_parser("integrators", help="list every integrator `run --integrators` accepts, with its "
                                                     "metadata and origin (built in, or the plug-in's distribution)")
    engines = commands.add_parser("engines", help="list every registered engine: origin (built in, or the plug-in's "
                                                  "distribution and version), installed or the install command, "
                                                  "models, integrators, precision")
    for listing in (listed, engines):  # 100 columns by default (issue 32)
        listing.add_argument("--wide", action="store_true", help="every column and reason in full, however wide")
    advise = commands.add_parser("advise", help="the largest dt (or tolerance) of an engine's integrators that "
                                                 "reaches an accuracy on a case, checked by runs")
    advise.add_argument("case", metavar="CASE_OR_FILE", help="a suite case name or a .toml path")
    advise.add_argument("--engine", required=True, help="the engine whose integrators to advise on")
    advise.add_argument("--integrator", type=_list, default=None,
                        help="comma-separated (default: the engine's default sweep with a declared order or error "
                             "control)")
    advise.add_argument("--formulation", default=None, help="the engine's model (default quaternion, or its first)")
    advise.add_argument("--target", type=_targets, default=None,
                        help="max attitude error over the case's horizon, rad, comma-separated (default 1e-3,1e-6,1e-9)")
    advise.add_argument("--t-end", type=_scale, default=None, help="simulated span, replacing the case's t_end")
    advise.add_argument("--max-steps", type=_count, default=None, metavar="N",
                        help="smallest dt tried = t_end / N (default 200000)")
    export = commands.add_parser("export", help="write the engine model of a case (MJCF for MuJoCo, URDF)")
    export.add_argument("case", metavar="CASE", help="a suite case name or a .toml path")
    export.add_argument("--format", required=True, help="a model format of an engine: mjcf (MuJoCo), urdf (Pinocchio)")
    export.add_argument("--out", type=_path, default=None, metavar="FILE", help="default: standard output")
    export.add_argument("--integrator", default=None, help="MJCF only: MuJoCo integrator (default rk4)")
    export.add_argument("--dt", type=_scale, default=None, help="MJCF only: timestep (default: the case's first dt)")
    return parser


def _figures(parser) -> None:
    """--figures / --no-figures; STEREODYN_FIGURES=0 in the environment makes --no-figures the default (a test suite
    or a CI gate reads only the tables, and drawing is most of a small run's report)."""
    parser.add_argument("--figures", action=argparse.BooleanOptionalAction, default=os.environ.get(FIGURES_ENV) != "0",
                        help="draw the figures of report.md and report.html (default; --no-figures: the tables only, "
                             f"faster, and the default when the environment sets {FIGURES_ENV}=0)")


def _history_parser(commands) -> None:
    history = commands.add_parser("history", help="result folders or baselines in order (commit, date, an engine's "
                                                   "version): each metric, status and fitted order over the "
                                                   "sequence, steps flagged (OUT/history.html, OUT/history*.csv)")
    history.add_argument("dirs", type=_path, nargs="+", metavar="DIR", help="result folders or baseline files")
    history.add_argument("--by", default="date", metavar="date|commit|given|PACKAGE",
                         help="order by runs.json's date (default), git commit (in --repo's history), as given, or "
                              "the version of a package the environment records (e.g. mujoco)")
    history.add_argument("--repo", type=_path, default=Path("."), help="the git repository for --by commit")
    history.add_argument("--out", type=_path, default=Path("history"), help="where to write (default ./history)")
    _steps(history)
    _allow_partial(history)


def _steps(parser) -> None:
    parser.add_argument("--step-factor", type=float, default=1.1,
                        help="a metric's level must change by this factor to be a step (default 1.1)")
    parser.add_argument("--order-step", type=float, default=0.5,
                        help="a fitted order's level must change by this much to be a step (default 0.5)")


def _matrix_parser(commands) -> None:
    matrix = commands.add_parser("matrix", help="the same runs in one isolated environment per package "
                                                "specification (uv), then their history and a compare of each "
                                                "neighbouring pair; run arguments after --")
    matrix.add_argument("specs", nargs="+", metavar="SPEC",
                        help="one environment's requirements, space-separated ('mujoco==3.3.7', 'mujoco==4.0.0 "
                             "pin==3.4.0')")
    matrix.add_argument("--cross", action="store_true",
                        help="one environment per combination of the specs' packages (a cross product)")
    matrix.add_argument("--out", type=_path, default=Path("matrix"), help="where to write (default ./matrix)")
    matrix.add_argument("--stereodyn", default=None, metavar="PATH_OR_REQUIREMENT",
                        help="the stereodyn installed in each environment (default: this checkout's source, or "
                             "stereodyn==VERSION)")
    matrix.add_argument("--overlay", action="store_true",
                        help="install only the specs over this environment's packages (their new dependencies at "
                             "this environment's versions): fast, not isolated")
    matrix.add_argument("--rerun", action="store_true",
                        help="run again where an earlier matrix ran the same environment and arguments (default: "
                             "reuse its results)")
    _steps(matrix)
    matrix.set_defaults(run_args=None)


def _allow_partial(parser) -> None:
    parser.add_argument("--allow-partial", action="store_true",
                        help="read a folder an unfinished (interrupted or killed) sweep left, as it is")


def select_cases(args) -> list:
    suite = case_files.load_suite()
    if getattr(args, "extremes", False):
        suite = case_files.load_suite(case_files.suite_dir() / "extreme")
    if args.cases:
        chosen = [case_files.find_case(name, suite) for name in args.cases]
    else:  # --case-file alone runs just those files; nothing at all (or --extremes) runs the suite
        chosen = [] if args.case_file and not getattr(args, "extremes", False) else list(suite)
    chosen += [case_files.load_case(path) for path in args.case_file]
    names = [c.name for c in chosen]
    if len(set(names)) != len(names):
        raise BadInput(f"case names must be unique in a run: {', '.join(sorted(names))}")
    if args.dt is not None or args.t_end is not None:
        chosen = [override(c, args) for c in chosen]
    return chosen


def override(case, args):
    """The case with --t-end / --dt; a value they make invalid is the option's fault, not the case file's."""
    try:
        return case_files.with_overrides(case, t_end=args.t_end, dt=args.dt)
    except CaseError as exc:
        option = "--dt" if args.dt is not None else "--t-end"
        raise BadInput(f"{option}: with case {case.name!r}" + (f" (t_end {case.t_end:g})" if args.t_end is None else
                                                                "") + f": {exc.rule}") from None


def output_folder(path: Path, option: str) -> Path:
    """Create the output folder (and its store/) and prove it writable, or one line naming the option."""
    try:
        for folder in (path, path / "store"):
            folder.mkdir(parents=True, exist_ok=True)
            with tempfile.TemporaryFile(dir=folder):
                pass
    except OSError as exc:
        raise BadInput(f"{option} {path}: not a writable folder ({exc.strerror or type(exc).__name__})") from None
    return path


def output_file(path: Path, option: str) -> Path:
    """A file to write: a regular file or a new path (the write replaces the path by a rename: a device node, a FIFO
    or a symbolic link would be replaced, not written through), in a folder that exists and is writable. Checked
    before anything is written, even a probe."""
    import stat

    from ..readers import kind

    folder = path.parent if str(path.parent) else Path(".")
    if path.is_dir():
        raise BadInput(f"{option} {path}: is a folder, not a file")
    try:
        mode = os.lstat(path).st_mode
    except OSError:  # absent (a new path), or its folder is not one: said below
        mode = None
    if mode is not None and not stat.S_ISREG(mode):
        raise BadInput(f"{option} {path}: is {kind(mode)}, not a regular file (give a regular file or a new path)")
    if not folder.is_dir():
        raise BadInput(f"{option} {path}: folder {folder} does not exist")
    try:
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError as exc:
        raise BadInput(f"{option} {path}: cannot write in {folder} ({exc.strerror or type(exc).__name__})") from None
    return path


def check_names(args) -> None:
    """The run's engines and integrators, checked before anything is written. --engines given: every engine named
    loads (a broken plug-in is EngineError, exit 2, naming it); not given: every registered engine, a broken plug-in
    left out with one warning line naming it and why."""
    from ..engines import BrokenEngine, UnavailableEngine, get_engine, loaded

    if args.engines is None:
        every = [loaded(name) for name in engine_names()]
        warn([f"{engine.reason}; its runs are left out" for engine in every if isinstance(engine, BrokenEngine)])
        # integrators named: the default engines are those that offer one of them (an engine not installed offers
        # nothing it could run: no skipped rows for it); none named: every engine, its missing SDK a skipped row
        absent = [engine.reason for engine in every if type(engine) is UnavailableEngine]
        args.engines = [engine.name for engine in every if not isinstance(engine, BrokenEngine)
                        and (not args.integrators or not isinstance(engine, UnavailableEngine))]
    else:
        absent = []
    unknown = [e for e in args.engines if e not in engine_names()]
    if unknown:
        raise BadInput(f"--engines: unknown engine {', '.join(unknown)}; valid: {', '.join(engine_names())}")
    engines = [get_engine(e) for e in args.engines]  # EngineError for a broken plug-in, before the folder is touched
    if args.integrators:
        known = {i for engine in engines for i in engine.integrators()}
        missing = [i for i in args.integrators if i not in known]
        # an engine whose SDK is missing lists no integrators: a name may be its, so the message says how to get it
        absent = list(dict.fromkeys(absent + [e.reason for e in engines if isinstance(e, UnavailableEngine)]))
        from .. import integrators as registry

        broken = [f"{name}: {registry.failed_plugin(name)}" for name in missing if registry.failed_plugin(name)]
        if broken:  # a plug-in that did not load is named with its error, never "unknown"
            raise BadInput(f"--integrators: {broken[0]}")
        if missing:
            raise BadInput(f"--integrators: unknown integrator {', '.join(missing)} for engines "
                           f"{','.join(args.engines)}; valid: {', '.join(sorted(known))}"
                           + (f" (not installed: {'; '.join(absent)})" if absent else ""))
    if getattr(args, "dt_ladder", False) and args.no_ladder:
        raise BadInput("--dt-ladder and --no-ladder: give at most one")
    if getattr(args, "ladder_max_steps", None) is not None:
        from ..analysis import workprecision

        if args.ladder_max_steps < 2 * workprecision.MIN_STEPS:  # checked before the sweep, not after it
            raise BadInput(f"--ladder-max-steps: must be >= {2 * workprecision.MIN_STEPS}, got {args.ladder_max_steps}")
        if args.ladder_max_steps > case_files.MAX_STEPS:
            raise BadInput(f"--ladder-max-steps: must be <= {case_files.MAX_STEPS}, got {args.ladder_max_steps}")


def _load() -> None:
    global case_files, CaseError, engine_names, EngineError, budget
    from .. import budget
    from ..scenes import cases as case_files
    from ..scenes.cases import CaseError
    from ..engines import EngineError, engine_names
    # Loaded by name (as asv loads its commands): this package never imports a command module itself, so each may
    # import the helpers above from it.
    _commands.update({name: importlib.import_module(f"{__name__}.{name}").main for name in COMMANDS})


def main(argv: list[str] | None = None) -> int:
    # Numeric warnings (overflow in a diverging run, which is data) and MuJoCo's are not for stderr; the workers
    # inherit the environment variable.
    # A case name in a script the plot font lacks (CJK) is drawn as boxes; matplotlib's warning about it is noise too.
    warnings.filterwarnings("ignore", category=RuntimeWarning)
    warnings.filterwarnings("ignore", message="Glyph .* missing from font", category=UserWarning)
    os.environ.setdefault("PYTHONWARNINGS", "ignore::RuntimeWarning,ignore:Glyph:UserWarning")
    try:
        _load()
        from ..analysis.gate import GateError
        from ..run.distributed import ClusterError
        from ..export import ExportError
        from ..run.store import FolderNotReady, StoreBusy
        from ..run.results import TableError
        from ..analysis.compare import CompareError
    except KeyboardInterrupt:
        print("stereodyn: interrupted", file=sys.stderr)
        return 130
    from ..run import processes
    from ..errors import InternalError, report as report_internal

    processes.forget_interrupts()
    _plugin_warnings_on_one_line()
    if signal.getsignal(signal.SIGINT) in (_interrupted_while_loading, signal.default_int_handler):
        signal.signal(signal.SIGINT, processes.on_interrupt)  # loaded: KeyboardInterrupt, handled below

    argv, run_args = _run_arguments(sys.argv[1:] if argv is None else list(argv))
    try:
        args = _parser().parse_args(argv)
        if run_args is not None:
            args.run_args = run_args
    except SystemExit as exc:  # the usage error's line is printed already; a caller of main() gets the code
        return exc.code if isinstance(exc.code, int) else 2
    streams = sys.stdout, sys.stderr
    sys.stdout, sys.stderr = _PipeSafe(sys.stdout), _PipeSafe(sys.stderr)
    try:
        code = _commands[args.command](args)
        sys.stdout.flush()  # here, not at exit: a reader gone (`| head -1`) is met while the status is still ours
    except (CaseError, BadInput, GateError, ClusterError, ExportError, StoreBusy, TableError, EngineError,
            CompareError, FolderNotReady) as exc:
        code = _error(str(exc))
    except OSError as exc:  # a path the checks above could not foresee (a disk full, a folder gone mid-run)
        where = f"{exc.filename}: " if exc.filename else ""
        code = _error(f"{where}{exc.strerror or exc}")
    except KeyboardInterrupt:
        code = 130
    except InternalError as exc:  # a bug of ours met where failures are data (harness/errors.py): never a row
        if processes.interrupted():
            code = 130
        else:
            report_internal(exc)
            return 3
    finally:
        sys.stdout, sys.stderr = streams
    if code == 130 or processes.interrupted():  # one an SDK swallowed or rewrapped too: never a green run
        print("stereodyn: interrupted; every finished run is stored (rerun with --resume to go on)", file=sys.stderr)
        return 130
    return code


class _PipeSafe:
    """A text stream whose reader may leave (`stereodyn check ... | head -1`): the first write or flush that meets a
    closed pipe points the file descriptor at /dev/null, and the command goes on to its own exit status, with no
    "Broken pipe" error (exit 2) nor Python's "Exception ignored" at exit."""

    def __init__(self, stream):
        self._stream = stream

    def write(self, text: str) -> int:
        try:
            return self._stream.write(text)
        except BrokenPipeError:
            self._gone()
            return len(text)

    def flush(self) -> None:
        try:
            self._stream.flush()
        except BrokenPipeError:
            self._gone()

    def _gone(self) -> None:
        try:  # what the buffer still holds, and every later write, goes to /dev/null
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, self._stream.fileno())
            os.close(devnull)
        except (OSError, ValueError, AttributeError):  # a stream without a descriptor (a test's capture)
            pass

    def __getattr__(self, name):
        return getattr(self._stream, name)


def _run_arguments(argv: list[str]) -> tuple[list[str], list[str] | None]:
    """`matrix SPEC ... -- RUN ARGUMENTS`: the arguments after the first -- are the runs' (argparse would take them
    as more specs)."""
    if argv[:1] == ["matrix"] and "--" in argv:
        at = argv.index("--")
        return argv[:at], argv[at + 1:]
    return argv, None


def _plugin_warnings_on_one_line() -> None:
    """A plug-in left out (reference.plugins.PluginWarning) is one `stereodyn: warning:` line, as the command's own
    warnings; every other warning as Python shows it."""
    from ...reference.plugins import PluginWarning

    shown = warnings.showwarning
    if getattr(shown, "plugin_lines", False):
        return

    def show(message, category, filename, lineno, file=None, line=None):
        if issubclass(category, PluginWarning):
            warn([str(message)])
        else:
            shown(message, category, filename, lineno, file, line)

    show.plugin_lines = True
    warnings.showwarning = show


def _error(message: str) -> int:
    """Bad input: one line on stderr, exit 2."""
    print(f"stereodyn: error: {one_line(message)}", file=sys.stderr)
    return 2


def warn(lines: list[str]) -> None:
    """Warnings, one line each on stderr (a command prints them once what it reads has read: a folder that cannot be
    read is one line, the error)."""
    for line in lines:
        print(f"stereodyn: warning: {one_line(line)}", file=sys.stderr)


def one_line(text: str) -> str:
    """A newline or other control character in a name or a path, escaped: a message stays one line."""
    return "".join(c if c.isprintable() else ascii(c)[1:-1] for c in text)
