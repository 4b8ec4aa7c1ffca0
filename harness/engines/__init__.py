"""Engine registry: engines are plug-ins of the entry-point group `stereodyn.engines` (name = "module:Class", the
class a subclass of harness.engines.base.Engine); the built-ins register there in pyproject.toml exactly as a third
party would. Entry points are listed without importing anything and loaded on first use, so a missing SDK only makes its
own runs `skipped`; a broken or old-style plug-in raises EngineError naming it."""
from __future__ import annotations

from functools import cache
from importlib.metadata import EntryPoint, entry_points

from .base import Engine

ENTRY_POINT_GROUP = "stereodyn.engines"
# The truth of every case: this engine's formulation and adaptive integrator (the one spelling of its engine's name
# outside its adapter).
TRUTH_ENGINE, TRUTH_FORMULATION, TRUTH_INTEGRATOR = "reference", "quaternion", "taylor"


class EngineError(ValueError):
    """A plug-in that cannot be used: its entry point does not load, or it is not an Engine subclass."""


@cache
def _entry_points() -> dict[str, EntryPoint]:
    """name -> entry point of every registered engine, in the built-ins' order first, then by name."""
    found: dict[str, EntryPoint] = {}
    for entry in entry_points(group=ENTRY_POINT_GROUP):
        if entry.name in found and found[entry.name].value != entry.value:
            raise EngineError(f"engine plug-in {entry.name!r}: two entry points claim the name "
                              f"({found[entry.name].value} and {entry.value})")
        found[entry.name] = entry
    builtin = ("mujoco", "pinocchio", TRUTH_ENGINE)

    def rank(name: str) -> tuple:  # the built-ins, then stereodyn's optional extras, then third parties, by name
        own = found[name].value.startswith(__name__ + ".")
        return (name not in builtin, not own, builtin.index(name) if name in builtin else 0, name)

    return {name: found[name] for name in sorted(found, key=rank)}


def engine_names() -> tuple[str, ...]:
    return tuple(_entry_points())


class UnavailableEngine(Engine):
    """Stands in for an engine whose SDK cannot be imported: every case is unsupported, with the reason."""

    def __init__(self, name: str, reason: str):
        self.name, self.reason = name, reason

    def integrators(self) -> tuple[str, ...]:
        return ()

    def unsupported(self, case) -> str | None:
        return self.reason

    def unmodelled(self, scene) -> str:
        return self.reason

    def prepare(self, case, integrator, dt, **formulation):
        raise RuntimeError(self.reason)


def _interrupted(exc: BaseException) -> bool:
    """Whether a KeyboardInterrupt is among the causes of exc (an extension module's init wraps it in ImportError)."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return False


def _load(name: str, entry: EntryPoint) -> Engine:
    where = f"engine plug-in {name!r} ({entry.value})"
    try:
        cls = entry.load()
    except ImportError as exc:  # its SDK (or the plug-in's own module) is missing: its runs are skipped
        if _interrupted(exc):  # not missing: Ctrl-C while it loaded (pybind11 reports it as "initialization failed")
            raise KeyboardInterrupt from exc
        return UnavailableEngine(name, f"{name} engine unavailable: {exc}")
    except Exception as exc:
        raise EngineError(f"{where}: does not load: {type(exc).__name__}: {exc}".splitlines()[0]) from exc
    if not (isinstance(cls, type) and issubclass(cls, Engine)):
        raise EngineError(f"{where}: {cls!r} is not a subclass of stereodyn.harness.engines.base.Engine (engines "
                          "written against the old Engine protocol must subclass it since 0.2.0)")
    try:
        engine = cls()
    except Exception as exc:
        raise EngineError(f"{where}: constructing it failed: {type(exc).__name__}: {exc}".splitlines()[0]) from exc
    if engine.name != name:
        raise EngineError(f"{where}: its name attribute is {engine.name!r}, not the entry point's name {name!r}")
    return engine


@cache
def get_engine(name: str) -> Engine:
    """The engine called `name`; KeyError listing the valid names if there is none."""
    registered = _entry_points()
    if name not in registered:
        raise KeyError(f"unknown engine {name!r}; valid: {', '.join(registered)}")
    return _load(name, registered[name])


def engines() -> list[Engine]:
    """Every registered engine, loaded (unavailable ones as UnavailableEngine)."""
    return [get_engine(name) for name in engine_names()]


def engine_for_state_space(state_space: str) -> Engine:
    """The first available engine whose registered integrators work on state_space (harness.testing)."""
    for engine in engines():
        if engine.state_space == state_space and not isinstance(engine, UnavailableEngine):
            return engine
    raise ValueError(f"no engine runs state space {state_space!r}")
