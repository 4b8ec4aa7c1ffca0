"""The one discovery mechanism of every registry (DESIGN §7): a member is found either in the registry's built-in
table (stereodyn's own modules, listed in code) or under its entry-point group (another distribution's, or stereodyn's
own engines, which pyproject.toml registers exactly as a third party would). Both are loaded by `Registry.load`, the
built-ins first; a plug-in's entry point loads behind the guard (reference.plugins), a built-in's module does not (a bug
of ours is a traceback). Here, in the bottom layer, so that the torque models may use it.

What a member *is* stays the registry's business (a module whose import registers sections or torque models, an
engine class, a list of integrator classes): `load` hands each loaded object to the registry's `accept`, and records
every failure as one line naming the plug-in (`failed`); the registry then decides whether a failure is bad input or
a warning. A built-in table's module that does not import is our bug, never a recorded failure."""
from __future__ import annotations

import importlib
from dataclasses import dataclass, field
from importlib.metadata import EntryPoint, entry_points
from typing import Any, Callable

from . import plugins


@dataclass
class Registry:
    """One registry's discovery: `what` names a member in messages ("report section plug-in"); `group` is its
    entry-point group; `builtins` the modules of stereodyn's own members, imported in this order (their import
    registers them); `accept(name, obj)` takes each loaded entry point's object (raising to refuse it: behind the
    guard, so a refusal is a failure naming the plug-in). `failed`: entry-point name -> its one line, after load()."""

    what: str
    group: str
    builtins: tuple[str, ...] = ()
    accept: Callable[[str, Any], None] | None = None
    # the words of a failure after the plug-in's description; None: "does not load" (its import) or "is refused"
    # (accept)
    failure: str | None = None
    # the group's entry points (default importlib.metadata's; a registry whose tests stand in their own passes one)
    lister: Callable[[str], Any] | None = None
    failed: dict[str, str] = field(default_factory=dict)
    _loaded: bool = False

    def entry_points(self) -> list[EntryPoint]:
        """The group's entry points, without importing them (one per name and value: a distribution seen twice on
        sys.path counts once)."""
        seen: dict[tuple[str, str], EntryPoint] = {}
        for entry in (self.lister or (lambda group: entry_points(group=group)))(self.group):
            seen.setdefault((entry.name, entry.value), entry)
        return list(seen.values())

    def load(self) -> dict[str, str]:
        """Import the built-ins, then every entry point of the group (once per process); returns `failed`. A plug-in
        that does not load, or that accept() refuses, is one line `WHAT 'NAME' (VALUE, distribution DIST VERSION)
        does not load: ERROR`; the others load all the same."""
        if self._loaded:
            return self.failed
        self._loaded = True
        for module in self.builtins:
            importlib.import_module(module)
        for entry in self.entry_points():
            where = plugins.describe(entry, self.what)
            try:
                with plugins.guard(f"{where} {self.failure or 'does not load'}"):
                    obj = entry.load()
                if self.accept is not None:
                    with plugins.guard(f"{where} {self.failure or 'is refused'}"):
                        self.accept(entry.name, obj)
            except plugins.PluginError as exc:
                self.failed.setdefault(entry.name, str(exc))
        return self.failed

    def load_or_warn(self) -> None:
        """load(), each failure one warning line (PluginWarning, said once by the command): for a registry whose
        failed plug-in leaves only itself out (report sections, scenes)."""
        if not self._loaded:
            for line in self.load().values():
                plugins.warn(line)

    def reset(self) -> None:
        """Forget what was loaded (tests: a registry seen again after its entry points changed)."""
        self._loaded = False
        self.failed.clear()
