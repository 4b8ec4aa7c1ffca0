"""report.md's sections as registered plug-ins (as asv's publishers): each has a name, an order and a render function
of the report's Context that returns Markdown lines ([] leaves the section out). The page is every registered section
in order (then name); a new section is one `register` call and touches no other section (DESIGN §7). A third party's
sections are discovered as asv's plug-ins are: a distribution names its module under the entry-point group
`stereodyn.report_sections`, and the report imports it (its `register` calls run) before it lists the sections.
stereodyn's own section modules are the registry's built-in table (BUILT_IN, reference.registry): found the same way,
never through an import line elsewhere that could be forgotten (tests/test_registries.py checks the table holds every
module that registers a section). A plug-in that does not import, or whose section raises or exits while it renders
(or returns what is not a list of lines), is one warning line naming it; the report renders without it. A plug-in's
section renders in a forked child process (Linux, macOS), so that one that kills its process, crashes in C or hangs
past SECTION_BUDGET_S ends that child, not the command: a warning too. stereodyn's own sections render here, not
guarded: their bug is a traceback."""
from __future__ import annotations

import os
import pickle
import secrets
import select
import signal
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import pandas as pd

from ...reference import plugins
from ...reference.registry import Registry
from ..run.processes import kill_group, own_process_group, parent_death_signal


@dataclass(frozen=True)
class Context:
    """What a section may read: the output folder, and what the report loaded from it once.

    results: results.csv; series: (case, engine, formulation, integrator, dt key) -> the run's invariant series
    (harness.series); env: the sweep's environment (runs.json) or None; case_figures: case -> the Markdown lines of
    its figures; tolerance_figures: case -> the relative path of its tolerance figure.
    """

    out_dir: Path
    results: pd.DataFrame
    series: dict
    env: dict | None
    case_figures: dict
    tolerance_figures: dict


@dataclass(frozen=True)
class Section:
    name: str
    order: float
    render: Callable[[Context], list[str]]


ENTRY_POINT_GROUP = "stereodyn.report_sections"
_REGISTRY: dict[str, Section] = {}
# stereodyn's own modules that register sections (each registers its own at import)
BUILT_IN = tuple(f"{__package__}.{module}" for module in (
    "markdown", "build", "verdicts", "workprecision", "agreement", "method", "history"))
SECTIONS = Registry("report section plug-in", ENTRY_POINT_GROUP, BUILT_IN)


def register(name: str, order: float) -> Callable:
    """Decorator: register `render(context) -> lines` as the section `name` at `order` (a name registered again is
    replaced: a module imported twice). A plug-in's section may not take a built-in section's name: TypeError, so
    its module does not load, one warning (it replaced "summary" in silence: issue 46's eighth attack; engines and
    integrators refuse a built-in's name the same way)."""
    why = plugins.name_problem("name", name)  # the heading and the warning line that name it
    if why:
        raise TypeError(f"report section {plugins.shown(name)}: {why}")

    def add(render: Callable[[Context], list[str]]) -> Callable[[Context], list[str]]:
        held = _REGISTRY.get(name)
        if held is not None and plugins.own(held.render) and not plugins.own(render):
            raise TypeError(f"report section {name!r}: the name of a built-in section; a plug-in's section takes a "
                            "name of its own")
        _REGISTRY[name] = Section(name, float(order), render)
        return render
    return add


def unregister(name: str) -> None:
    _REGISTRY.pop(name, None)


def load_plugins() -> None:
    """Import the built-in section modules and every module named under ENTRY_POINT_GROUP (each registers its
    sections), once; a plug-in that does not import (reference.plugins' guard: any Exception or SystemExit) is one
    warning line naming it, said once, and the other sections render."""
    SECTIONS.load_or_warn()


def registered() -> list[Section]:
    """Every registered section, the plug-ins' included, in the page's order."""
    load_plugins()
    return sorted(_REGISTRY.values(), key=lambda section: (section.order, section.name))


def _lines(section: Section, context: Context) -> list[str]:
    """A section's lines: a plug-in's behind the guard (reference.plugins) in a child process of its own (_apart),
    checked to be a list of text; [] and one warning line naming it when it fails."""
    if plugins.own(section.render):
        return section.render(context)
    where = plugins.describe_class(section.render, f"report section plug-in {section.name!r}")
    try:
        return _apart(section, context, where) if hasattr(os, "fork") else _guarded(section, context, where)
    except plugins.PluginError as exc:
        plugins.warn(str(exc))
        return []


def _guarded(section: Section, context: Context, where: str) -> list[str]:
    with plugins.guard(f"{where} left out"):
        lines = section.render(context)
        if not isinstance(lines, list) or not all(isinstance(line, str) for line in lines):
            raise TypeError(f"render returned {type(lines).__name__}, not a list of lines of text")
    # a plain list of plain str, what the pipe of _apart carries: a list or str subclass the section defined inside
    # render cannot be pickled (it was a traceback: issue 46's eighth attack); str.__str__ copies a subclass's text
    return [str.__str__(line) for line in lines]


# A plug-in section's wall-time budget: the built-in sections of the default report take ~1 s all together.
SECTION_BUDGET_S = 120.0


def _apart(section: Section, context: Context, where: str) -> list[str]:
    """_guarded in a forked child, its answer (the lines, the PluginError's line, or what else it raised: Ctrl-C, our
    bug) pickled back through a pipe; a child that dies without one, or runs past SECTION_BUDGET_S, is one warning
    line, as a PluginError is (a section that called os.kill on its process ended `run` and `report`: issue 46's
    fourth attack). The child leads a group of its own and marks what it starts, as a pool worker does
    (processes.own_process_group): its os.killpg(0, ...) is not the command's, and what it leaves is ended."""
    read, write = os.pipe()
    marker = secrets.token_hex(8)  # in the environment of what the child starts: found once the child is gone
    parent = os.getpid()
    pid = os.fork()
    if pid == 0:  # the child: answer, then end without the parent's exit handlers
        os.close(read)
        try:
            # it dies with the command, as a pool worker does: a SIGKILLed `run` or `report` left it rendering under
            # init past its budget (issue 46's thirteenth attack); the signal covers every moment after this check
            parent_death_signal()
            if os.getppid() != parent:
                os._exit(1)
            signal.signal(signal.SIGINT, signal.SIG_IGN)  # as a worker: a KeyboardInterrupt here is the plug-in's
            for signum in (signal.SIGTERM, signal.SIGHUP):  # the command's handler: a signal to the child is its end
                signal.signal(signum, signal.SIG_DFL)
            own_process_group(marker)  # as a worker: its os.killpg(0, ...) is not the command's (fifth attack), what it
            # starts is its to end (kill_group below)
            try:
                answer = ("lines", _guarded(section, context, where))
            except plugins.PluginError as exc:
                answer = ("plugin", str(exc))
            except BaseException as exc:  # Ctrl-C, or stereodyn's own bug: the parent raises it
                answer = ("raise", exc)
            try:
                data = pickle.dumps(answer)
            except Exception as exc:  # what our own bug raised and cannot be sent: raised in the parent as text
                data = pickle.dumps(("raise", RuntimeError(f"{type(exc).__name__}: {exc}")))
            with os.fdopen(write, "wb") as out:
                out.write(data)
            for stream in (sys.stdout, sys.stderr):
                stream.flush()
        finally:
            os._exit(0)
    os.close(write)
    chunks, deadline, ended = [], time.monotonic() + SECTION_BUDGET_S, False
    try:
        with os.fdopen(read, "rb") as pipe:
            while (left := deadline - time.monotonic()) > 0:
                if select.select([pipe], [], [], left)[0]:
                    chunk = os.read(pipe.fileno(), 1 << 20)
                    if not chunk:
                        ended = True
                        break
                    chunks.append(chunk)
    finally:
        if not ended:  # past its budget, or Ctrl-C here
            os.kill(pid, signal.SIGKILL)
        kill_group(pid, marker)  # and what it started and left (its group, descendants, marked), before it is reaped
        _, status = os.waitpid(pid, 0)
    if not ended:
        return _left_out(f"{where} left out: did not finish within {SECTION_BUDGET_S:g} s")
    try:
        kind, value = pickle.loads(b"".join(chunks))
    except Exception:  # no answer: the process ended inside the render
        code = os.waitstatus_to_exitcode(status)
        how = f"killed by {signal.Signals(-code).name}" if code < 0 else f"exit code {code}"
        return _left_out(f"{where} left out: its process died ({how})")
    if kind == "raise":
        raise value
    return _left_out(value) if kind == "plugin" else value


def _left_out(line: str) -> list[str]:
    plugins.warn(line)
    return []


def render(context: Context) -> str:
    """report.md: the sections' lines in order (a plug-in's section that fails left out, with a warning)."""
    lines: list[str] = []
    for section in registered():
        lines += _lines(section, context)
    return "\n".join(lines) + "\n"
