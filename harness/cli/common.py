"""What the commands of the command line share (harness.cli): the argument types and option groups their parsers use,
the checks of what a command is given (cases, engines and integrators, output paths), and the one-line warnings.
This module imports only the standard library and harness.words; the modules the checks read are loaded by load(),
inside main()'s Ctrl-C handling (harness.cli.dispatch)."""
from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile
from pathlib import Path

from ..words import one_line  # no import of its own

case_files = CaseError = engine_names = EngineError = budget = None

DEFAULT_OUT = "out"
FIGURES_ENV = "STEREODYN_FIGURES"  # "0": --no-figures by default (a test suite, a CI gate)
GATE_MODES = ("same-machine", "cross-machine")  # harness.analysis.gate.MODES (this module imports no analysis)


def load() -> None:
    """The modules the argument types and the checks read (numpy and the registries behind them)."""
    global case_files, CaseError, engine_names, EngineError, budget
    from .. import budget
    from ..scenes import cases as case_files
    from ..scenes.cases import CaseError
    from ..engines import EngineError, engine_names


class BadInput(Exception):
    """A user error outside case files: one line, exit code 2."""


class Parser(argparse.ArgumentParser):
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


def _seconds_in(text: str, low: float, high: float, what: str) -> float:
    """A number of seconds, finite and in [low, high] (docs/limits.md); what: the noun of its error."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected {what}, got {text[:40]!r}") from None
    if not (math.isfinite(value) and low <= value <= high):
        raise argparse.ArgumentTypeError(f"must be finite and in [{low:g}, {high:g}] s (docs/limits.md), "
                                         f"got {value:g}")
    return value


def _scale(text: str) -> float:
    """A step or a span: in [MIN_SCALE, MAX_MAGNITUDE] like a case file's."""
    return _seconds_in(text, case_files.MIN_SCALE, case_files.MAX_MAGNITUDE, "a number")


def _seconds(text: str) -> float:
    """A wall-time budget: in [MIN_BUDGET_S, MAX_BUDGET_S]."""
    return _seconds_in(text, budget.MIN_BUDGET_S, budget.MAX_BUDGET_S, "a number of seconds")


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


def _figures(parser) -> None:
    """--figures / --no-figures; STEREODYN_FIGURES=0 in the environment makes --no-figures the default (a test suite
    or a CI gate reads only the tables, and drawing is most of a small run's report)."""
    parser.add_argument("--figures", action=argparse.BooleanOptionalAction, default=os.environ.get(FIGURES_ENV) != "0",
                        help="draw the figures of report.md and report.html (default; --no-figures: the tables only, "
                             f"faster, and the default when the environment sets {FIGURES_ENV}=0)")


def budget_options(parser) -> None:
    """--run-budget, --prepare-budget, --truth-budget (harness.budget): `run`'s and `advise`'s, whose failed rows
    name them."""
    for what, default, meaning in (
            ("run", budget.RUN_BUDGET_S, "one row's accuracy run with its metrics and checks (a ladder point's too)"),
            ("prepare", budget.PREPARE_BUDGET_S, "one Engine.prepare: model building and compilation"),
            ("truth", budget.TRUTH_BUDGET_S, "one case's truth and its real128 certification")):
        parser.add_argument(budget.FLAGS[what], type=_seconds, default=default, metavar="S",
                            help=f"wall-time budget of {meaning}, s (default {default:g}); past it the row is "
                                 "failed, its message naming the budget, and --resume redoes it only once the budget "
                                 "is raised")


def budgets_of(args):
    """The budgets the options of budget_options gave."""
    return budget.Budgets(args.run_budget, args.prepare_budget, args.truth_budget)


def _steps(parser) -> None:
    parser.add_argument("--step-factor", type=float, default=1.1,
                        help="a metric's level must change by this factor to be a step (default 1.1)")
    parser.add_argument("--order-step", type=float, default=0.5,
                        help="a fitted order's level must change by this much to be a step (default 0.5)")


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


def output_folder(path: Path, option: str, store: bool = True) -> Path:
    """Create the output folder (and, with store, its store/) and prove it writable, or one line naming the option:
    a path that exists is a folder (a device, a FIFO or a file there is refused, saying what it is)."""
    import stat

    from ..readers import kind

    try:
        mode = os.stat(path).st_mode
    except OSError:  # absent (a new path), or below something that is not a folder: said below
        mode = None
    if mode is not None and not stat.S_ISDIR(mode):
        raise BadInput(f"{option} {path}: is {kind(mode)}, not a folder (give a folder or a new path)")
    try:
        for folder in (path, path / "store") if store else (path,):
            folder.mkdir(parents=True, exist_ok=True)
            with tempfile.TemporaryFile(dir=folder):
                pass
    except OSError as exc:
        if folder != path and folder.exists() and not folder.is_dir():  # it was said of DIR (the twelfth attack)
            raise BadInput(f"{option} {path}: {folder} is not a folder (the run's store; move it away)") from None
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


def check_options(args) -> None:
    """The options' rules that no engine decides, checked before anything is built (run's, and the matrix's for its runs'
    arguments)."""
    from ..analysis import workprecision

    if args.certify and args.no_certify:
        raise BadInput("--certify and --no-certify: give one (certifying is the default)")
    if args.dt_ladder and args.no_ladder:
        raise BadInput("--dt-ladder and --no-ladder: give at most one")
    if args.ladder_max_steps is not None:  # checked before the sweep, not after it
        if args.ladder_max_steps < 2 * workprecision.MIN_STEPS:
            raise BadInput(f"--ladder-max-steps: must be >= {2 * workprecision.MIN_STEPS}, got {args.ladder_max_steps}")
        if args.ladder_max_steps > case_files.MAX_STEPS:
            raise BadInput(f"--ladder-max-steps: must be <= {case_files.MAX_STEPS}, got {args.ladder_max_steps}")


def warn(lines: list[str]) -> None:
    """Warnings, one line each on stderr (a command prints them once what it reads has read: a folder that cannot be
    read is one line, the error)."""
    for line in lines:
        print(f"stereodyn: warning: {one_line(line)}", file=sys.stderr)

