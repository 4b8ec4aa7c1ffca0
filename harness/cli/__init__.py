"""The command line (DESIGN §5). Exit codes: 0 done (failed runs are data), 1 check failed, 2 bad input, 3 a bug in
stereodyn (harness/errors.py), 130 stopped.

One module per command, as asv lays out its commands, each declaring its arguments (`add_parser(commands)`) beside its
body (`main(args) -> int`); common.py holds what they share, dispatch.py the entry point. This module assembles them
and imports only the standard library.
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

# The commands, in the order of `stereodyn --help`: each the module of its name in this package.
COMMANDS = ("cases", "run", "report", "baseline", "check", "compare", "history", "matrix", "integrators", "engines",
            "advise", "export")


def command(name: str):
    """A command's module, loaded by name (as asv loads its commands): this package imports none itself, so that
    `import stereodyn.harness.cli` stays light and Ctrl-C while one loads is one line (dispatch.main)."""
    return importlib.import_module(f"{__name__}.{name}")


def parser() -> argparse.ArgumentParser:
    """`stereodyn`'s parser: every command's, in COMMANDS order (tools/docs_reference.py documents it)."""
    from . import common

    common.load()  # the argument types check against the case format's and the budgets' limits
    top = common.Parser(prog="stereodyn", description=__doc__.splitlines()[0])
    commands = top.add_subparsers(dest="command", required=True)
    for name in COMMANDS:
        command(name).add_parser(commands)
    return top


from .dispatch import main  # noqa: E402,F401  (the `stereodyn` script's entry point)
