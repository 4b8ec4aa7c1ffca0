"""What the harness reads of an engine beyond its groups (Engine.PROTOCOL): its declarations completed by the
registry's defaults, and its model of the rigid body. Plain functions of the engine; an engine never defines them."""
from __future__ import annotations

import math

from .base import RIGID_BODY, Engine, KnownDeviation, RigidBodyModel, SceneModel
from .methods import registered_method


def rigid_body(engine: Engine) -> SceneModel:
    """The engine's model of the rigid body (models()), RigidBodyModel(engine) where it lists none."""
    model = engine.models().get(RIGID_BODY)
    return model if isinstance(model, SceneModel) else RigidBodyModel(engine)


def formulations(engine: Engine) -> tuple[str, ...]:
    """The rigid-body model's variants (results.csv's formulation column; none: ())."""
    return tuple(rigid_body(engine).variants())


def in_default_sweep(engine: Engine, integrator: str) -> bool:
    """Whether a sweep that names no integrators runs it: Offer.default_sweep, else the registry's rule."""
    declared = engine.offer(integrator).default_sweep
    if declared is not None:
        return bool(declared)
    from ..integrators.registry import in_default_sweep as registry_default  # the table, not the methods' modules

    return registry_default(integrator)


def method(engine: Engine, integrator: str) -> str:
    """Its method in harness.engines.methods' vocabulary: Offer.method, else the registry's ("" for none)."""
    declared = engine.offer(integrator).method
    if declared is not None:
        return declared
    return registered_method(integrator, engine.about.state_space or "lie")


def declared_order(engine: Engine, integrator: str) -> float:
    """Its declared order: Offer.order, else the registry's in the engine's state space (NaN for an unknown name)."""
    order = float(engine.offer(integrator).order)
    if not math.isnan(order):
        return order
    from ..integrators.registry import get

    try:
        return float(get(integrator, engine.about.state_space or "lie").order)
    except KeyError:
        return math.nan


def formulation_order(engine: Engine, formulation: str, integrator: str) -> float:
    """Its declared order on one formulation: Offer.orders' entry, else declared_order."""
    return float(dict(engine.offer(integrator).orders).get(formulation, declared_order(engine, integrator)))


def known_deviations(engine: Engine) -> tuple[KnownDeviation, ...]:
    """The known deviations (Offer.deviation) its integrators declare, in their order."""
    if type(engine).integrators is Engine.integrators:  # none to declare (the registry refuses such an engine at load)
        return ()
    return tuple(d for i in engine.integrators() if (d := engine.offer(i).deviation) is not None)
