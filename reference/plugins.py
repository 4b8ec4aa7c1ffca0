"""The one guard around another distribution's code (DESIGN §7): loading a plug-in's entry point (engines,
integrators, torque models, report sections, scenes) or calling one of its hooks (a torque model's parse and
components, a scene's parse, an engine's integrators()).

Whatever the plug-in raises, any Exception, SystemExit and GeneratorExit too (a plug-in calling sys.exit(3) at import
must not end the command with code 3 and nothing said, nor a `raise GeneratorExit` with a traceback), becomes
PluginError: one line naming the plug-in (its entry point and distribution) and the error; each registry turns it into
that plug-in's unavailability, or bad input. The user's Ctrl-C is never caught, nor an ImportError an extension module's
init raised from one: Ctrl-C stays Ctrl-C; a KeyboardInterrupt the plug-in's code raised (code_raised) is its failure
like any other. A plug-in that calls os._exit inside the guard (at import, in a report section) would end the command at
once, saying nothing: in the guarded thread os._exit raises ProcessExit (a SystemExit) instead, and is that plug-in's
failure. Here, in the bottom layer, because reference/ (torque models) may not import harness/ and harness/ imports
reference/.
"""
from __future__ import annotations

import multiprocessing
import os
import re
import signal
import threading
import warnings
from contextlib import contextmanager
from typing import Any, Callable, Iterator


def text_of(value: Any, show: Callable[[Any], str] = str, width: int | None = None) -> str:
    """show(value) (str, or repr) for a message about a plug-in's value or error, at most width characters. An
    object whose __str__ or __repr__ raises, or answers no text, is shown by its type: written into a message, it
    was a traceback wherever the message was made (issue 46's thirteenth attack). The user's Ctrl-C goes on."""
    try:
        text = show(value)
        if not isinstance(text, str):
            raise TypeError(f"{show.__name__}() returned {type(text).__name__}")
    except (Exception, SystemExit, GeneratorExit, KeyboardInterrupt) as exc:
        if isinstance(exc, KeyboardInterrupt) and not code_raised(exc):
            raise
        text = f"<{type(value).__name__} object: its {show.__name__}() raised {type(exc).__name__}>"
    text = str.__str__(text)  # a str subclass's own methods are the plug-in's too
    return text if width is None else text[:width]


def shown(value: Any, width: int = 80) -> str:
    """A plug-in's value as a message shows it: its repr, at most width characters (text_of)."""
    return text_of(value, repr, width)


class PluginError(Exception):
    """A plug-in's code failed. str(): `WHERE: TYPE: MESSAGE`, one line; error: what it raised."""

    def __init__(self, where: str, error: BaseException):
        self.where, self.error = where, error
        text = text_of(error).strip().splitlines()
        super().__init__(f"{where}: {type(error).__name__}" + (f": {text[0]}" if text else ""))

    @property
    def missing(self) -> bool:
        """Whether it is an ImportError: a module (an SDK) that is not installed, not a broken plug-in."""
        return isinstance(self.error, ImportError)

    def __reduce__(self):
        """Pickled (a pool worker's task sends it back) as its line: the plug-in's own exception may not pickle, and
        Exception's default, cls(*args), cannot rebuild this one (the truth of a case whose torque plug-in's
        components() raised was a traceback, exit 3)."""
        return _from_line, (self.where, str(self), self.missing)


def _from_line(where: str, line: str, missing: bool) -> PluginError:
    """A PluginError rebuilt from its line; its error a plain one (ImportError where it was one) of the same text."""
    exc = PluginError.__new__(PluginError)
    Exception.__init__(exc, line)
    exc.where, exc.error = where, (ImportError if missing else Exception)(line.removeprefix(f"{where}: "))
    return exc


class ProcessExit(SystemExit):
    """os._exit(code) called by a plug-in's code inside the guard, raised instead of ending the process."""


_real_exit = os._exit
_guarded: dict[int, int] = {}  # thread id -> guards it is inside
_guarded_lock = threading.Lock()


def _exit_in_guard(code: int) -> None:
    """os._exit while a guard is open: a guarded thread raises ProcessExit, any other exits as asked."""
    if threading.get_ident() in _guarded:
        raise ProcessExit(f"called os._exit({code})")
    _real_exit(code)


def _forget_guards() -> None:  # a process forked inside a guard exits as it asks
    _guarded.clear()
    os._exit = _real_exit


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_guards)


@contextmanager
def _exits_raise() -> Iterator[None]:
    """os._exit raises ProcessExit in this thread for the block (ProcessExit)."""
    me = threading.get_ident()
    with _guarded_lock:
        _guarded[me] = _guarded.get(me, 0) + 1
        os._exit = _exit_in_guard
    try:
        yield
    finally:
        with _guarded_lock:
            _guarded[me] -= 1
            if not _guarded[me]:
                del _guarded[me]
            if not _guarded:
                os._exit = _real_exit


class PluginWarning(UserWarning):
    """A plug-in left out (it does not load, or claims a name already taken); the command line prints it as one
    line."""


def interrupted(exc: BaseException | None) -> bool:
    """Whether a KeyboardInterrupt is among the causes of exc (an extension module's init wraps it in ImportError)."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return False


def code_raised(exc: BaseException) -> bool:
    """Whether a KeyboardInterrupt was raised by code (a plug-in's `raise KeyboardInterrupt`), not by the user's
    Ctrl-C: where SIGINT is ignored (a pool worker), or where the process's SIGINT handler says it took no Ctrl-C (a
    handler with a `took_ctrl_c()` attribute: harness.run.processes.on_interrupt). Under Python's own handler it
    cannot be told apart: the user's."""
    if not isinstance(exc, KeyboardInterrupt):
        return False
    handler = signal.getsignal(signal.SIGINT)
    took = getattr(handler, "took_ctrl_c", None)
    return handler is signal.SIG_IGN or (took is not None and not took())


@contextmanager
def guard(where: str, passing: tuple[type[BaseException], ...] = ()) -> Iterator[None]:
    """Run a plug-in's code: PluginError(where, error) for any Exception, SystemExit, GeneratorExit or other
    BaseException it raises (not stereodyn's own, not the user's Ctrl-C), except the types in `passing` (a hook's own
    way to refuse input, e.g. a case file's error), which go through unchanged."""
    try:
        with _exits_raise():
            yield
    except passing:
        raise
    except KeyboardInterrupt as exc:
        if code_raised(exc):
            raise PluginError(where, exc) from exc
        raise
    except (Exception, SystemExit, GeneratorExit) as exc:
        if interrupted(exc):  # not the plug-in's failure: Ctrl-C while it loaded
            raise KeyboardInterrupt from exc
        raise PluginError(where, exc) from exc
    except BaseException as exc:  # a plug-in's bare BaseException (it was a traceback: issue 46's fourth attack, F3)
        if own(type(exc)):  # stereodyn's own (harness.errors.InternalError: a bug of ours) goes on
            raise
        raise PluginError(where, exc) from exc


# What a name (a case's, an engine's, an integrator's, a formulation's; any name a plug-in declares) may not hold: the
# characters Markdown reads as markup. Every report, compare and history table shows names as they are: a case named
# "a`x`<b>" opened a code span and bold for the rest of report.md (issue 46's eleventh attack, F3).
MARKUP = "\\`*[]<>|~&#!"


# An underscore opens emphasis at a word's start or end ("_x_" showed as an italic x), not inside a word (my_case).
_EMPHASIS = re.compile(r"(?<![^\W_])_|_(?![^\W_])")


def markup_problem(value: str) -> str | None:
    """Why a name would not show as itself in Markdown (it holds one of MARKUP, or an underscore at a word's start
    or end), or None."""
    found = sorted({c for c in value if c in MARKUP} | ({"_"} if _EMPHASIS.search(value) else set()))
    return (f"must hold none of {' '.join(MARKUP)}, nor an underscore at a word's start or end (Markdown markup; it "
            f"holds {' '.join(found)})") if found else None


def name_problem(field: str, value: Any, listed: bool = False) -> str | None:
    """Why a name a plug-in declares (an integrator's name and state space, a scene's kind, a torque model's key, a
    report section's name, an engine's integrators and formulations) cannot be used, naming the field and the rule;
    None when it can. Every table row and listing line holds such names: a newline in one split them (one rule for
    every kind of plug-in). listed: a name the command line takes in a comma-separated list (--integrators): no comma
    (`a,b` was listed as valid and could never be chosen)."""
    if type(value) is not str or not value:  # a str subclass's methods are the plug-in's (its repr may raise)
        return f"{field} = {shown(value)}: must be a non-empty string (str)"
    if not value.isprintable() or value != value.strip():
        return f"{field} = {shown(value)}: must be one line of printable characters, no space at its ends"
    why = markup_problem(value)
    if why:
        return f"{field} = {shown(value)}: {why}"
    if listed and "," in value:
        return f"{field} = {shown(value)}: must hold no comma (the command line's lists are comma-separated)"
    return None


def describe(entry: Any, what: str) -> str:
    """`WHAT 'NAME' (VALUE, distribution DIST VERSION)` for an entry point (the distribution where it has one)."""
    dist = getattr(entry, "dist", None)
    origin = ""
    if dist is not None:
        name = dist.metadata["Name"] or ""
        origin = f", distribution {name} {dist.version or ''}".rstrip() if name else ""
    return f"{what} {getattr(entry, 'name', '?')!r} ({getattr(entry, 'value', '?')}{origin})"


def own(obj: Any) -> bool:
    """Whether a class (or function) is stereodyn's own: its bugs are ours, a traceback, never a plug-in's failure."""
    return getattr(obj, "__module__", "").split(".")[0] == "stereodyn"


def describe_class(cls: type, what: str) -> str:
    """`WHAT (MODULE.CLASS, distribution DIST)` for a class a plug-in registered (its distribution where the installed
    ones name its top-level module)."""
    from importlib.metadata import packages_distributions

    module = getattr(cls, "__module__", "?")
    dists = packages_distributions().get(module.split(".")[0], [])
    return f"{what} ({module}.{getattr(cls, '__qualname__', '?')}" + (
        f", distribution {', '.join(dict.fromkeys(dists))})" if dists else ")")


def load(entry: Any, what: str) -> Any:
    """entry.load() behind the guard: PluginError `WHAT 'NAME' (VALUE, distribution ...) does not load: ...`."""
    with guard(f"{describe(entry, what)} does not load"):
        return entry.load()


def warn(message: str) -> None:
    """A PluginWarning, said once by the command: a pool's worker process (which loads the same plug-ins) stays
    quiet. One line where Python shows it too (a plug-in's CI calling harness.testing): placed at `stereodyn:0`, not
    at a line of stereodyn's source, which would print that line under it and point the reader at the wrong file."""
    if multiprocessing.parent_process() is None:
        warnings.warn_explicit(message, PluginWarning, "stereodyn", 0)
