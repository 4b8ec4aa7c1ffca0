"""The command line (DESIGN §5). Exit codes: 0 done (failed runs are data), 1 check failed, 2 bad input, 3 a bug in
stereodyn (harness/errors.py), 130 stopped.

One module per command, as asv lays out its commands, each declaring its arguments (`add_parser(commands)`) beside its
body (`main(args) -> int`); common.py holds what they share, dispatch.py assembles them and is the entry point. This
module puts the Ctrl-C handler for the loading and names the entry point.
"""
from __future__ import annotations

import os
import signal
import sys


# Started as the command (the `stereodyn` script, python -m stereodyn, or python -m stereodyn.harness.cli: while
# locating that, Python loads this package with argv[0] "-m"), Ctrl-C while the modules below load ends in one line;
# main() then puts the command's handler (harness/run/processes.py: on_interrupt). Imported as a library: untouched.
# A pool worker (which imports this module as its __main__'s) ignores Ctrl-C: harness/run/processes.py.
if sys.argv and (os.path.basename(sys.argv[0]) == "stereodyn" or sys.argv[0] == "-m"
                 or sys.argv[0].endswith(os.path.join("stereodyn", "__main__.py"))) \
        and not __import__("stereodyn.harness.run.processes").harness.run.processes.is_worker():
    for _signum in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):  # one line, whichever stops it while loading
        signal.signal(_signum, sys.modules["stereodyn.harness.run.processes"].interrupted_while_loading)
    sys.modules["stereodyn.harness.run.processes"].answer_for_orphans()  # before any plug-in loads

from .dispatch import COMMANDS, command, main, parser  # noqa: E402,F401  (main: the `stereodyn` script's entry point)
