"""Every registered engine as a row (`stereodyn engines`): where it comes from, what it runs, whether it is installed.

origin: `built in` (stereodyn's own, its SDK a base dependency), `built in, extra stereodyn[X]` (stereodyn's own, its
SDK an optional extra) or `plug-in from DIST VERSION` (the distribution whose entry point registers it). Loading an
engine imports its adapter (and most adapters their SDK): a missing SDK shows as `not installed` with the adapter's
reason, which names the install command; a broken plug-in shows as `not usable` with what is wrong with it.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cache
from importlib.metadata import PackageNotFoundError, distribution, version

from . import BrokenEngine, UnavailableEngine, _entry_points, loaded
from .declared import formulations, in_default_sweep
# who registers an entry point, and the plug-in distributions of a run's environment: read there, no engine loaded;
# importable from here as before
from ..environment import OWN_DISTRIBUTION, entry_distribution as _distribution, plugin_distributions  # noqa: F401


@dataclass(frozen=True)
class EngineRow:
    """One engine: name, origin, status (`installed` with its packages' versions, or `not installed: REASON`),
    models (formulations), integrators (default-sweep ones marked *), precisions, and the integrators its SDK offers
    that the adapter does not run, each with why (Offer.unmodelled)."""

    name: str
    origin: str
    status: str
    models: tuple[str, ...]
    integrators: tuple[str, ...]
    precisions: tuple[str, ...]
    unmodelled: tuple[tuple[str, str], ...] = ()


def _version(package: str) -> str:
    try:
        return version(package)
    except PackageNotFoundError:
        return "absent"


@cache
def _own_extras() -> frozenset[str]:
    """stereodyn's optional extras (pyproject.toml): an own engine whose name is one has its SDK there."""
    try:
        return frozenset(distribution(OWN_DISTRIBUTION).metadata.get_all("Provides-Extra") or ())
    except PackageNotFoundError:
        return frozenset()


def origin(name: str) -> str:
    """Where the engine comes from (module docstring)."""
    entry = _entry_points()[name]
    dist, dist_version = _distribution(entry)
    if dist.lower() == OWN_DISTRIBUTION:
        return f"built in, extra stereodyn[{name}]" if name in _own_extras() else "built in"
    if dist:
        return f"plug-in from {dist} {dist_version}"
    return f"plug-in ({entry.value}, no distribution)"


def rows() -> list[EngineRow]:
    """Every registered engine, in the registry's order."""
    table = []
    for name in _entry_points():
        engine = loaded(name)
        if isinstance(engine, UnavailableEngine):
            status = "not usable" if isinstance(engine, BrokenEngine) else "not installed"
            table.append(EngineRow(name, origin(name), f"{status}: {engine.reason}", (), (), ()))
            continue
        offers = {i: engine.offer(i) for i in engine.integrators()}
        integrators = [i for i, offer in offers.items() if not offer.unmodelled]
        packages = ", ".join(f"{p} {_version(p)}" for p in engine.about.packages)
        table.append(EngineRow(
            name, origin(name), "installed" + (f" ({packages})" if packages else ""), formulations(engine),
            tuple(i + ("*" if in_default_sweep(engine, i) else "") for i in integrators),
            tuple(dict.fromkeys(p for i in integrators for p in offers[i].precisions)),
            tuple((i, offer.unmodelled) for i, offer in offers.items() if offer.unmodelled)))
    return table


NARROW = 100  # `stereodyn engines` fits this many columns unless --wide (issue 32: 374 columns before)


def render(table: list[EngineRow], wide: bool = True) -> str:
    """The rows as text: one block per engine (the lists are too long for one line). Not wide: each line wrapped to
    NARROW columns, and an engine not installed gives its install command only (the missing module with --wide)."""
    lines = []
    for row in table:
        status = row.status
        if not wide and status.startswith("not installed: ") and "install the extra: " in status:
            status = "not installed: " + status.split("install the extra: ", 1)[1]
        # a plug-in that does not load is named on one line, however long (the one-line rule of a failed load)
        lines += _wrapped(f"{row.name}: {row.origin}; {status}", wide or status.startswith("not usable"), "    ")
        if row.models:
            lines += _wrapped(f"  models: {', '.join(row.models)}", wide, "    ")
        if row.integrators:
            lines += _wrapped(f"  integrators (* in the default sweep): {', '.join(row.integrators)}", wide, "    ")
        if row.precisions:
            lines += _wrapped(f"  precision: {', '.join(row.precisions)}", wide, "    ")
        for integrator, reason in row.unmodelled:  # "not modelled by stereodyn's adapter: why"
            lines += _wrapped(f"  {integrator}: {reason}", wide, "    ")
    return "\n".join(lines)


def _wrapped(text: str, wide: bool, indent: str) -> list[str]:
    import textwrap

    return [text] if wide else textwrap.wrap(text, NARROW, subsequent_indent=indent, break_long_words=False,
                                             break_on_hyphens=False)
