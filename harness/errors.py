"""Our bugs are never data.

A run that breaks inside an engine (a diverging simulation, an SDK's refusal, a plug-in's own fault) is a failed row
with its reason, and the sweep goes on. A programming error in stereodyn's own code is not: a row would ship it as a
measurement (issue 28: an AttributeError in the advice code became 28 "truth failed" rows of the committed report).
Each place that records a failure as data asks `raise_if_internal` first; an internal error then leaves every
`except Exception` (InternalError is a BaseException, as KeyboardInterrupt is), crosses the process pool intact
(pickled with its traceback's text) and ends the command with exit 3 and the traceback (harness.cli).

What counts as ours: an exception of a programming-error type (PROGRAMMING_ERRORS) whose innermost frame, leaving out
the standard library and the numerical libraries we call (numpy, scipy, pandas), lies in stereodyn's own files. An
engine SDK's, a plug-in's or a test's frame there makes it data.
"""
from __future__ import annotations

import os
import sys
import sysconfig
import traceback
from pathlib import Path

# Raised by Python itself on code that is wrong (or raised by our code on a request it should never have received: a
# plan that asks an adapter for an integrator it lacks is a bug of the plan). ZeroDivisionError: Python's own float
# division in our code (numpy's gives inf, which the row's checks judge). Not ValueError, the other ArithmeticErrors,
# RuntimeError, LinAlgError, ImportError, NotImplementedError, MemoryError: engines and numerics raise those on data.
PROGRAMMING_ERRORS = (AttributeError, NameError, TypeError, KeyError, IndexError, AssertionError, ZeroDivisionError)

# stereodyn's packages, wherever setuptools' package-dir put their folders (_ours)
_PACKAGES = ("stereodyn", "stereodyn.harness", "stereodyn.reference", "stereodyn.cases")
_TOOLS = tuple(str(Path(p).resolve()) + os.sep for p in {sysconfig.get_paths()["stdlib"],
                                                          sysconfig.get_paths()["platstdlib"]})
_TOOL_PACKAGES = ("numpy", "scipy", "pandas")


class InternalError(BaseException):
    """A bug in stereodyn's own code, met where failures are recorded as data. Carries the original exception's
    one-line text and its formatted traceback (text, so that it survives a process pool)."""

    def __init__(self, summary: str, details: str):
        super().__init__(summary, details)
        self.summary, self.details = summary, details

    def __str__(self) -> str:
        return self.summary


def _is_tool(filename: str) -> bool:
    if filename.startswith("<frozen"):
        return True
    path = os.path.realpath(filename)
    if any(f"{os.sep}{name}{os.sep}" in path for name in _TOOL_PACKAGES) and "site-packages" in path:
        return True
    return path.startswith(_TOOLS) and "site-packages" not in path


def _ours() -> tuple[str, ...]:
    """The folders of stereodyn's packages loaded now: a frame of a package not yet imported cannot exist."""
    return tuple(str(Path(folder).resolve()) + os.sep for name in _PACKAGES
                 if (package := sys.modules.get(name)) is not None for folder in getattr(package, "__path__", ()))


def _is_ours(filename: str) -> bool:
    return os.path.realpath(filename).startswith(_ours())


def is_internal(exc: BaseException) -> bool:
    """Whether exc is a programming error raised in stereodyn's own code (module docstring)."""
    if isinstance(exc, InternalError):
        return True
    if not isinstance(exc, PROGRAMMING_ERRORS):
        return False
    frames = [frame.filename for frame in traceback.extract_tb(exc.__traceback__)]
    for filename in reversed(frames):  # innermost first
        if not _is_tool(filename):
            return _is_ours(filename)
    return False


def as_internal(exc: BaseException) -> BaseException:
    """exc, or the InternalError it is (a pool worker's answer: the traceback is here, not in the parent)."""
    if is_internal(exc) and not isinstance(exc, InternalError):
        return InternalError(f"{type(exc).__name__}: {exc}".splitlines()[0], "".join(traceback.format_exception(exc)))
    return exc


def raise_if_internal(exc: BaseException) -> None:
    """In an `except Exception` that records a failure as data: our own bug is no data (module docstring)."""
    internal = as_internal(exc)
    if isinstance(internal, InternalError):
        raise internal from (None if internal is exc else exc)


def report(exc: InternalError, stream=None) -> None:
    """The command's last words on an internal error: the traceback, then one line that says what it is."""
    stream = stream or sys.stderr
    stream.write(exc.details if exc.details.endswith("\n") else exc.details + "\n")
    stream.write(f"stereodyn: internal error (a bug in stereodyn, not in an engine; please report it with the "
                 f"traceback above): {exc.summary}\n")
