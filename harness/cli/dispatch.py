"""`stereodyn`'s entry point (harness.cli.main): assemble the commands, load them inside the Ctrl-C handling, parse, run the command,
and turn its errors into exit codes (DESIGN §5): 0 done (failed runs are data), 1 check failed, 2 bad input, 3 a bug
in stereodyn (harness/errors.py), 130 stopped by Ctrl-C, 143 by SIGTERM."""
from __future__ import annotations

import argparse
import importlib
import os
import signal
import sys
import warnings

from ..words import one_line
from .common import BadInput, Parser, load, warn
from ..run.processes import interrupted_while_loading

# The commands, in the order of `stereodyn --help`: each the module of its name in this package.
COMMANDS = ("cases", "run", "report", "baseline", "check", "compare", "history", "matrix", "integrators", "engines",
            "advise", "export")


def command(name: str):
    """A command's module, loaded by name (as asv loads its commands): nothing imports one before, so that
    `import stereodyn.harness.cli` stays light and Ctrl-C while one loads is one line (main)."""
    return importlib.import_module(f"{__package__}.{name}")


def parser() -> argparse.ArgumentParser:
    """`stereodyn`'s parser: every command's, in COMMANDS order (tools/docs_reference.py documents it)."""
    load()  # the argument types check against the case format's and the budgets' limits
    top = Parser(prog="stereodyn", description=" ".join(sys.modules[__package__].__doc__.split("\n\n")[0].split()))
    commands = top.add_subparsers(dest="command", required=True)
    for name in COMMANDS:
        command(name).add_parser(commands)
    return top


# What the interrupt line adds, per command: what to run to go on (a command that keeps nothing says nothing more).
INTERRUPTED = {"run": "; every finished run is stored (rerun with --resume to go on)",
               "matrix": "; the environments built and the runs finished are kept (rerun the same matrix command, "
                         "without --rerun, to go on: it reuses them)"}

def _load() -> None:
    """The modules the commands and their checks need, and every command's module (COMMANDS)."""
    load()
    for name in COMMANDS:
        command(name)


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
        from ..engines import EngineError
        from ..scenes.cases import CaseError
        from ..run.distributed import ClusterError
        from ..export import ExportError
        from ..run.store import FolderNotReady, StoreBusy
        from ..run.results import TableError
        from ..analysis.compare import CompareError
        from ...reference.torque_models import TorqueModelError
    except KeyboardInterrupt:
        print("stereodyn: interrupted", file=sys.stderr)
        return 130
    from ..run import processes
    from ..errors import InternalError, report as report_internal

    processes.forget_interrupts()
    _plugin_warnings_on_one_line()
    if signal.getsignal(signal.SIGINT) in (interrupted_while_loading, signal.default_int_handler):
        signal.signal(signal.SIGINT, processes.on_interrupt)  # loaded: KeyboardInterrupt, handled below

    argv, run_args = _run_arguments(sys.argv[1:] if argv is None else list(argv))
    try:
        args = parser().parse_args(argv)
        if run_args is not None:
            args.run_args = run_args
    except SystemExit as exc:  # the usage error's line is printed already; a caller of main() gets the code
        return exc.code if isinstance(exc.code, int) else 2
    streams = sys.stdout, sys.stderr
    sys.stdout, sys.stderr = _PipeSafe(sys.stdout), _PipeSafe(sys.stderr)
    # SIGTERM (a CI runner's cancel, `kill`) and SIGHUP (a closed terminal) as Ctrl-C: the workers and what they
    # started end with the command
    stops = (signal.SIGTERM, signal.SIGHUP)
    terminate = {signum: signal.signal(signum, processes.on_interrupt) for signum in stops
                 if signal.getsignal(signum) in (signal.SIG_DFL, interrupted_while_loading)}
    try:
        code = command(args.command).main(args)
        sys.stdout.flush()  # here, not at exit: a reader gone (`| head -1`) is met while the status is still ours
    except (CaseError, BadInput, GateError, ClusterError, ExportError, StoreBusy, TableError,
            EngineError, CompareError, FolderNotReady, TorqueModelError) as exc:
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
        for signum, previous in terminate.items():
            signal.signal(signum, signal.SIG_DFL if previous is interrupted_while_loading else previous)
    if code == 130 or processes.interrupted():  # one an SDK swallowed or rewrapped too: never a green run
        signum = processes.terminated()
        if signum:
            print(f"stereodyn: terminated ({signal.Signals(signum).name}){INTERRUPTED.get(args.command, '')}",
                  file=sys.stderr)
            return 128 + signum
        print(f"stereodyn: interrupted{INTERRUPTED.get(args.command, '')}", file=sys.stderr)
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
