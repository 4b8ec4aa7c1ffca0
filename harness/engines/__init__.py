"""Engine registry: engines are plug-ins of the entry-point group `stereodyn.engines` (name = "module:Class", the
class a subclass of harness.engines.base.Engine); the built-ins register there in pyproject.toml exactly as a third
party would. Entry points are listed without importing anything and loaded on first use, behind the plug-in guard
(reference.plugins: any Exception or SystemExit, never Ctrl-C), so a missing SDK only makes its own runs `skipped`; a
broken or old-style plug-in (it does not load, exits, is no Engine subclass, lacks a required method) raises EngineError
naming it where it is asked for, and is left out of every listing of all engines. A third party's entry point that
claims a built-in's name is refused with a warning; the built-in keeps it."""
from __future__ import annotations

import math
from functools import cache
from importlib.metadata import EntryPoint

from ...reference import plugins
from ...reference.registry import Registry
from .base import About, Engine, Offer, RigidBodyModel, SceneModel, Timing
from ..budget import MAX_BUDGET_S, MIN_BUDGET_S
from ..precision import precisions_problem
from ..truth_names import TRUTH_ENGINE, TRUTH_FORMULATION, TRUTH_INTEGRATOR  # noqa: F401 (this API: the truth's names)

ENTRY_POINT_GROUP = "stereodyn.engines"
# The engines' discovery (reference.registry): every engine, stereodyn's own included, is an entry point (no built-in
# table: pyproject.toml registers the built-ins), listed without importing and loaded one by one on first use (_load).
ENGINES = Registry("engine plug-in", ENTRY_POINT_GROUP)


class EngineError(ValueError):
    """A plug-in that cannot be used: its entry point does not load, or it is not an Engine subclass."""


def _own(entry: EntryPoint) -> bool:
    """Whether stereodyn registers the entry point itself (a built-in engine, or one of its optional extras)."""
    return entry.value.startswith(__name__ + ".")


@cache
def _entry_points() -> dict[str, EntryPoint]:
    """name -> entry point of every registered engine, in the built-ins' order first, then by name. Two entry points
    claiming one name (the same one installed twice aside): stereodyn's own keeps it and the other is refused; two
    third parties' are both refused; each refusal a PluginWarning naming both (never an error: this runs in every
    command that lists engines)."""
    claims: dict[str, list[EntryPoint]] = {}
    for entry in ENGINES.entry_points():
        why = plugins.name_problem("its entry point's name", entry.name, listed=True)
        if why:  # every table and report names the engine: the one name rule (an engine `_hy` ran, and every reader
            plugins.warn(f"{plugins.describe(entry, 'engine plug-in')} is not loaded: {why}")  # refused its rows)
            continue
        claims.setdefault(entry.name, []).append(entry)
    found: dict[str, EntryPoint] = {}
    for name, entries in claims.items():
        own = [entry for entry in entries if _own(entry)]
        if len(entries) == 1 or len(own) == 1:
            found[name] = own[0] if own else entries[0]
        kept = found.get(name)
        for entry in entries:
            if entry is not kept:
                others = [plugins.describe(other, "engine") for other in entries if other is not entry]
                plugins.warn(f"{plugins.describe(entry, 'engine plug-in')} is not loaded: the name is "
                             + (f"stereodyn's own, {others[0]}" if kept is not None else
                                f"claimed by {'; '.join(others)} too, and neither is loaded")
                             + "; rename the plug-in's entry point")
    builtin = ("mujoco", "pinocchio", TRUTH_ENGINE)

    def rank(name: str) -> tuple:  # the built-ins, then stereodyn's optional extras, then third parties, by name
        return (name not in builtin, not _own(found[name]), builtin.index(name) if name in builtin else 0, name)

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


def _load(name: str, entry: EntryPoint) -> Engine:
    """The engine of an entry point, checked (_check); UnavailableEngine when a module it imports is missing (its SDK
    not installed: its runs are skipped), EngineError naming it when the plug-in is broken. Behind the plug-in guard:
    a SystemExit is a broken plug-in, Ctrl-C stays Ctrl-C."""
    where = plugins.describe(entry, "engine plug-in")
    try:
        cls = plugins.load(entry, "engine plug-in")
    except plugins.PluginError as exc:
        if exc.missing and _own(entry):  # its SDK is missing: its runs are skipped, the extra named (summary)
            return UnavailableEngine(name, f"{name} engine unavailable: {exc.error}")
        if exc.missing:  # a plug-in's SDK or module: skipped too, with its own line (no extra of ours installs it)
            return UnavailableEngine(name, str(exc))
        raise EngineError(str(exc)) from exc
    if not (isinstance(cls, type) and issubclass(cls, Engine)):
        raise EngineError(f"{where}: {plugins.shown(cls)} is not a subclass of "
                          "stereodyn.harness.engines.base.Engine (engines written against the old Engine protocol "
                          "must subclass it since 0.2.0)")
    try:
        with plugins.guard(f"{where}: constructing it failed"):
            engine = cls()
        if engine.name != name:
            raise EngineError(f"{where}: its name attribute is {plugins.shown(engine.name)}, not the entry point's "
                              f"name {name!r}")
        _check(engine, where)
    except plugins.PluginError as exc:
        raise EngineError(str(exc)) from exc
    return engine


# Engine's methods a plug-in must implement (base.py raises NotImplementedError): integrators() always, the other two
# when the engine models the rigid body through the base class's hooks (Engine.models' default).
_REQUIRED, _RIGID_BODY_HOOKS = ("integrators",), ("unsupported", "prepare")


def _check(engine: Engine, where: str) -> None:
    """Refuse, at load, an engine a sweep would fail on later with a traceback: a required method not implemented,
    integrators() or models() that raise or return the wrong type (PluginError or EngineError naming it)."""
    with plugins.guard(f"{where}: integrators() failed"):
        names = engine.integrators() if type(engine).integrators is not Engine.integrators else None
    with plugins.guard(f"{where}: models() failed"):
        models = engine.models()
    required = _REQUIRED + (_RIGID_BODY_HOOKS if isinstance(models, dict) and any(
        isinstance(model, RigidBodyModel) for model in models.values()) else ())
    missing = [method for method in required if getattr(type(engine), method) is getattr(Engine, method)]
    if missing:
        raise EngineError(f"{where}: does not implement {', '.join(m + '()' for m in missing)} (required of an "
                          "Engine, harness/engines/base.py)")
    if not (isinstance(names, (tuple, list)) and all(isinstance(n, str) for n in names)):
        raise EngineError(f"{where}: integrators() returned {plugins.shown(names)}, not a tuple of names")
    if not names:  # no run at all: `run --engines NAME` would end "done" having run nothing (issue 46, F9)
        raise EngineError(f"{where}: integrators() returned {plugins.shown(names)}: an engine offers at least one "
                          "integrator")
    _check_timing(engine.timing, where)
    _check_about(engine.about, where)
    if not isinstance(models, dict):
        raise EngineError(f"{where}: models() returned {plugins.shown(models)}, not a dict")
    lists = [("integrators()", "an integrator", tuple(names))]  # each name is in every row and listing line
    for kind, model in models.items():  # the formulations: results.csv's column
        if isinstance(model, SceneModel):
            with plugins.guard(f"{where}: models()[{plugins.shown(kind, 40)}].variants() failed"):
                variants = model.variants()
            if not (isinstance(variants, (tuple, list))):
                raise EngineError(f"{where}: models()[{plugins.shown(kind, 40)}].variants() returned "
                                  f"{plugins.shown(variants)}, not a tuple")
            lists.append((f"models()[{plugins.shown(kind, 40)}].variants()", "a formulation", tuple(variants)))
    for i, kind in enumerate(models):
        why = plugins.name_problem(f"models() key {i}", kind)
        if why:
            raise EngineError(f"{where}: {why}")
    for field, noun, values in lists:
        for i, value in enumerate(values):
            why = plugins.name_problem(f"{field}[{i}]", value, listed=field == "integrators()")
            if why:
                raise EngineError(f"{where}: {why}")
        if len(set(values)) < len(values):  # two runs under one key: a table its readers refuse
            raise EngineError(f"{where}: {field} = {plugins.shown(values)}: names {noun} twice")
    for integrator in names:  # what the plan, the verdicts and the listing read of each integrator
        _check_offer(engine, integrator, where)


def _check_timing(timing, where: str) -> None:
    """Refuse, at load, timing declarations the scheduler and the budgets cannot use (a negative or NaN cost queued
    its runs anywhere; a negative prepare budget failed every run: issue 46's fifth attack)."""
    if not isinstance(timing, Timing):
        raise EngineError(f"{where}: timing = {plugins.shown(timing)}: must be a harness.engines.base.Timing")
    for field, low, optional in (("pass_us", 0.0, False), ("startup_s", 0.0, False), ("prepare_budget_s", 0.0, True)):
        value = getattr(timing, field)
        if optional and value is None:
            continue
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) \
                or value < low or (field == "prepare_budget_s" and not MIN_BUDGET_S <= value <= MAX_BUDGET_S):
            raise EngineError(f"{where}: timing.{field} = {plugins.shown(value)}: must be a finite number "
                              + (f"in [{MIN_BUDGET_S:g}, {MAX_BUDGET_S:g}] s or None" if optional else ">= 0"))
    for field in ("short_warm_up", "process_global_precision"):  # "no" is truthy: a flag the planner reads as bool()
        value = getattr(timing, field)
        if not isinstance(value, bool):
            raise EngineError(f"{where}: timing.{field} = {plugins.shown(value)}: must be True or False")


# Matplotlib's named line styles; a dash tuple (offset, (on, off, ...)) is the other form About.linestyle takes.
LINESTYLES = ("-", "--", "-.", ":", "solid", "dashed", "dashdot", "dotted")


def _check_about(about, where: str) -> None:
    """Refuse, at load, an About the store, the listings and the figures cannot use (packages=42 or about=None were a
    traceback in the sweep or in `stereodyn engines`, linestyle=42 one when the figures were drawn: issue 46's eighth
    attack)."""
    if not isinstance(about, About):
        raise EngineError(f"{where}: about = {plugins.shown(about)}: must be a harness.engines.base.About")
    rules = {"packages": "a tuple of distribution names", "export_formats": "a tuple of format names"}
    for field, rule in rules.items():
        value = getattr(about, field)
        if not (isinstance(value, (tuple, list)) and all(isinstance(v, str) and v.strip() and v.isprintable()
                                                          for v in value)):  # a newline printed raw in the report
            raise EngineError(f"{where}: about.{field} = {plugins.shown(value)}: must be {rule}, each one line")
    style = about.linestyle
    dashes = isinstance(style, tuple) and len(style) == 2 and isinstance(style[0], (int, float)) \
        and isinstance(style[1], tuple) and style[1] and all(isinstance(d, (int, float)) and not isinstance(d, bool)
                                                              and math.isfinite(d) and d >= 0 for d in style[1])
    if style not in LINESTYLES and not dashes:
        raise EngineError(f"{where}: about.linestyle = {plugins.shown(style)}: must be one of "
                          f"{', '.join(LINESTYLES)} or a dash tuple (offset, (on, off, ...))")
    from ..integrators.base import STATE_SPACES

    space = about.state_space  # "curved" was accepted, and no registered integrator steps on it (the 13th attack)
    if not (space is None or (type(space) is str and space in STATE_SPACES)):
        raise EngineError(f"{where}: about.state_space = {plugins.shown(space)}: must be one of "
                          f"{', '.join(STATE_SPACES)} or None")
    if not (isinstance(about.formulation, str) and about.formulation.isprintable()):
        raise EngineError(f"{where}: about.formulation = {plugins.shown(about.formulation)}: must be one line of text")


def _check_offer(engine: Engine, integrator: str, where: str) -> None:
    """Refuse, at load, an offer() that raises or is no Offer, or an order no verdict can judge (NaN: the registry's;
    otherwise harness.integrators.base.order_problem's rule, the integrators' own)."""
    from ..integrators.base import order_problem

    with plugins.guard(f"{where}: offer({integrator!r}) failed"):
        offer = engine.offer(integrator)
    if not isinstance(offer, Offer):
        raise EngineError(f"{where}: offer({integrator!r}) returned {plugins.shown(offer)}, not an Offer")
    orders = [("order", offer.order)] if not (isinstance(offer.order, float) and math.isnan(offer.order)) else []
    try:
        orders += [(f"orders[{plugins.shown(formulation, 40)}]", order) for formulation, order in offer.orders]
    except (TypeError, ValueError):
        raise EngineError(f"{where}: offer({integrator!r}).orders = {plugins.shown(offer.orders)}: must be "
                          "(formulation, order) pairs") from None
    for field, order in orders:
        problem = order_problem(order)
        if problem:
            raise EngineError(f"{where}: offer({integrator!r}).{field}{problem.removeprefix('order')}")
    # what a row's key and the plan read (issue 46's fourth attack, F5: a precision named twice wrote two rows under
    # one key, which every reader refused; adaptive="yes" ran as adaptive)
    why = precisions_problem(offer.precisions)
    if why:
        raise EngineError(f"{where}: offer({integrator!r}).precisions = {plugins.shown(offer.precisions)}: {why}")
    for field, allowed in (("adaptive", (True, False)), ("default_sweep", (True, False, None))):
        value = getattr(offer, field)
        if not any(value is a for a in allowed):
            raise EngineError(f"{where}: offer({integrator!r}).{field} = {plugins.shown(value)}: must be "
                              f"{' or '.join(map(str, allowed))}")


@cache
def get_engine(name: str) -> Engine:
    """The engine called `name`; KeyError listing the valid names if there is none."""
    registered = _entry_points()
    if name not in registered:
        raise KeyError(f"unknown engine {name!r}; valid: {', '.join(registered)}")
    return _load(name, registered[name])


def engines() -> list[Engine]:
    """Every registered engine, loaded (unavailable ones, and broken plug-ins, as UnavailableEngine with the reason)."""
    return [loaded(name) for name in engine_names()]


class BrokenEngine(UnavailableEngine):
    """Stands in for a broken plug-in (EngineError, the reason) where every engine is listed."""


def loaded(name: str) -> Engine:
    """get_engine(name), or a broken plug-in as a BrokenEngine: for what lists every engine (`stereodyn engines`, a
    sweep's default engines), where one broken plug-in must not stop the rest."""
    try:
        return get_engine(name)
    except EngineError as exc:
        return BrokenEngine(name, str(exc))


def engine_for_state_space(state_space: str) -> Engine:
    """The first available engine whose registered integrators work on state_space (harness.testing)."""
    for engine in engines():
        if engine.about.state_space == state_space and not isinstance(engine, UnavailableEngine):
            return engine
    raise ValueError(f"no engine runs state space {state_space!r}")
