"""The integrator registry: the table (state space, name) -> Integrator class and its lookups, re-exported by the
package (harness.integrators, whose __init__ registers the built-ins; importing this module runs it first). An
engine's defaults (engines.base: an integrator's order, whether it joins the default sweep) read the table here: they
need the table, not the methods' modules."""
from __future__ import annotations

from importlib.metadata import entry_points

from ...reference import plugins
from ...reference.registry import Registry

from .base import Integrator, check_step_signature, metadata_problem

ENTRY_POINT_GROUP = "stereodyn.integrators"

_registry: dict[tuple[str, str], type[Integrator]] = {}  # (state_space, name) -> class, in registration order
_plugins_loaded = False
_from_entry_points: set[type] = set()  # the classes an entry point registered: plug-ins (joins_default_sweep)
_failed: dict[str, str] = {}  # a name a plug-in that did not load offers -> its one line (failed_plugin)


def register(cls: type[Integrator]) -> type[Integrator]:
    """Add an Integrator class under (cls.state_space, cls.name) (usable as a decorator). Raises TypeError/ValueError
    on a bad class or a name already taken by another class in the same state space."""
    _check(cls)
    key = (cls.state_space, cls.name)
    existing = _registry.get(key)
    if existing is not None and existing is not cls:
        raise ValueError(f"integrator name {cls.name!r} is already registered for state space {cls.state_space!r} "
                         f"to {existing.__module__}.{existing.__qualname__}")
    _registry[key] = cls
    return cls


def get(name_or_class: str | type[Integrator], state_space: str = "lie") -> type[Integrator]:
    """The Integrator class called name in state_space, or the class itself (checked) when one is given.

    KeyError, listing the valid names of that state space, for an unknown name.
    """
    if isinstance(name_or_class, type):
        return _check(name_or_class)
    _load_plugins()
    try:
        return _registry[(state_space, name_or_class)]
    except KeyError:
        if name_or_class in _failed:
            raise KeyError(f"integrator {name_or_class!r}: {_failed[name_or_class]}") from None
        raise KeyError(f"unknown integrator {name_or_class!r} for state space {state_space!r}; "
                       f"valid: {', '.join(names(state_space))}") from None


def names(state_space: str | None = "lie") -> tuple[str, ...]:
    """Registered names in report order (built-ins first), for one state space (None: all, each name once)."""
    _load_plugins()
    return tuple(dict.fromkeys(n for space, n in _registry if state_space is None or space == state_space))


def state_spaces() -> tuple[str, ...]:
    """The state spaces that have integrators."""
    _load_plugins()
    return tuple(dict.fromkeys(space for space, _ in _registry))


def _check(cls: type) -> type[Integrator]:
    if not (isinstance(cls, type) and issubclass(cls, Integrator)):
        raise TypeError(f"{plugins.shown(cls)} is not an Integrator subclass")
    # a tableau's stages come from it: with no ButcherTableau, metadata_problem names the tableau, not the stages
    missing = [key for key in Integrator.METADATA if not hasattr(cls, key)
               and not (key == "stages" and hasattr(cls, "tableau"))]
    if missing:
        raise TypeError(f"integrator {cls.__qualname__} lacks metadata: {', '.join(missing)}")
    abstract = sorted(getattr(cls, "__abstractmethods__", ()))
    if abstract:
        raise TypeError(f"integrator {cls.__qualname__} does not implement {', '.join(abstract)}")
    why = metadata_problem(cls)
    if why is not None:  # refused at load, naming the field and the rule, before any run
        raise ValueError(f"integrator {cls.__module__}.{cls.__qualname__}: {why}")
    check_step_signature(cls)  # a plug-in written for 0.1 (no time argument) is refused, saying what changed
    return cls


def _load_plugins() -> None:
    """The integrators of the entry-point group, once (reference.registry, as every registry): an entry names a class
    or a list of classes. One that does not load, or whose class the registry refuses, is one warning line, and every
    name it offered (the entry point's, and each class's it got to) answers failed_plugin; the other integrators
    run."""
    global _plugins_loaded
    if _plugins_loaded:
        return
    _plugins_loaded = True
    offered: dict[str, list] = {}  # entry point -> the names a user may ask for: its own, and each class's it got to

    def accept(name: str, loaded) -> None:
        for cls in (loaded if isinstance(loaded, (list, tuple)) else (loaded,)):
            offered.setdefault(name, []).append(getattr(cls, "name", None))
            register(cls)  # TypeError, ValueError: a class the registry refuses
            if not plugins.own(cls):  # stereodyn's own class offered again keeps its default_sweep
                _from_entry_points.add(cls)

    found = Registry("integrator plug-in", ENTRY_POINT_GROUP, accept=accept, failure="not loaded",
                     lister=lambda group: entry_points(group=group))  # this module's name: tests stand theirs in
    for entry_name, line in found.load().items():  # a broken plug-in must not take the built-ins down with it
        plugins.warn(line)
        for name in [entry_name, *offered.get(entry_name, ())]:
            if isinstance(name, str) and name not in names(None):
                _failed.setdefault(name, line)


def failed_plugin(name: str) -> str | None:
    """The one line (plug-in, distribution, error) of the integrator plug-in that offered `name` and did not load;
    None where no such plug-in failed (`--integrators NAME` then says so instead of "unknown")."""
    _load_plugins()
    return _failed.get(name)


def in_default_sweep(name: str) -> bool:
    """Whether a sweep that names no integrators runs `name`: False only when no class registered under it joins the
    default sweep (joins_default_sweep: the slow geometric methods, and plug-ins that do not opt in); a name the
    registry does not hold (an engine's own) is run."""
    _load_plugins()
    classes = [cls for (_, n), cls in _registry.items() if n == name]
    return not classes or any(joins_default_sweep(cls) for cls in classes)


def joins_default_sweep(cls: type[Integrator]) -> bool:
    """Whether a sweep that names no integrators runs the class. A class registered in Python (stereodyn's, a
    script's): its default_sweep (default True). An entry-point plug-in runs only when named, unless its package opts
    in by declaring `default_sweep = True` in a class of its own (inherited from stereodyn's base classes it does not
    count): an installed plug-in, and any false claim it makes, then stays out of other packages' default sweeps."""
    if cls not in _from_entry_points:
        return bool(getattr(cls, "default_sweep", True))
    return any(vars(k).get("default_sweep") is True for k in cls.__mro__ if not plugins.own(k))


def stages(name: str) -> int:
    """Derivative evaluations per step of a registered integrator (in any state space); 1 for a name the registry
    does not know (an engine's own, e.g. MuJoCo's implicit)."""
    for space in state_spaces():
        if name in names(space):
            return get(name, space).stages
    return 1
