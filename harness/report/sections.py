"""report.md's sections as registered plug-ins (as asv's publishers): each has a name, an order and a render function
of the report's Context that returns Markdown lines ([] leaves the section out). The page is every registered section
in order (then name); a new section is one `register` call and touches no other section (DESIGN §7). A third party's
sections are discovered as asv's plug-ins are: a distribution names its module under the entry-point group
`stereodyn.report_sections`, and the report imports it (its `register` calls run) before it lists the sections."""
from __future__ import annotations

from dataclasses import dataclass
from importlib.metadata import entry_points
from pathlib import Path
from typing import Callable

import pandas as pd

from ...reference import plugins


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


class SectionError(ImportError):
    """A report-section plug-in that does not import: one line naming it."""


def register(name: str, order: float) -> Callable:
    """Decorator: register `render(context) -> lines` as the section `name` at `order` (a name registered again is
    replaced: a module imported twice, or a plug-in's own version of a section)."""
    def add(render: Callable[[Context], list[str]]) -> Callable[[Context], list[str]]:
        _REGISTRY[name] = Section(name, float(order), render)
        return render
    return add


def unregister(name: str) -> None:
    _REGISTRY.pop(name, None)


def load_plugins() -> None:
    """Import every module named under ENTRY_POINT_GROUP (each registers its sections); SectionError naming the
    plug-in when one does not import (reference.plugins' guard: any Exception or SystemExit)."""
    for entry in entry_points(group=ENTRY_POINT_GROUP):
        try:
            plugins.load(entry, "report section plug-in")
        except plugins.PluginError as exc:  # a plug-in's own bug: name it, never a traceback from inside the report
            raise SectionError(str(exc)) from None


def registered() -> list[Section]:
    """Every registered section, the plug-ins' included, in the page's order."""
    load_plugins()
    return sorted(_REGISTRY.values(), key=lambda section: (section.order, section.name))


def render(context: Context) -> str:
    """report.md: the sections' lines in order."""
    lines: list[str] = []
    for section in registered():
        lines += section.render(context)
    return "\n".join(lines) + "\n"
