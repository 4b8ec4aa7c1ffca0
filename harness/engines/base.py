"""The engine base class: build a case's model, roll it out with an integrator and a step, return a Trajectory."""
from __future__ import annotations

import importlib.util
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

import numpy as np

from ..trajectory import Trajectory

if TYPE_CHECKING:
    from ..scenes.case import Case
    from ..grid import TimeGrid


from ..precision import EPS, FLOAT32, FLOAT64, PRECISIONS  # noqa: F401 (part of this API)


@dataclass(frozen=True)
class KnownDeviation:
    """A documented way an engine's integrator departs from what it declares, with its upstream reference.

    quantity: what is measured ("order": the fitted convergence order, analysis.verdicts); expected: the value the
    deviation predicts, matched within tolerance; reference: where upstream documents (or fixes) it. While the
    measurement matches it the integrator's verdict reads `known` (not failed; --strict passes); when it stops
    matching and meets the declared value instead, the verdict reads `fixed upstream?`.
    """

    integrator: str
    quantity: str
    expected: float
    tolerance: float
    reference: str


def prepare_keywords(engine: "Engine", formulation: str, integrator: str, precision: str = FLOAT64) -> dict:
    """The keywords a run passes to engine.prepare besides (case, integrator, dt): its formulation where the engine
    has formulations, its precision where the engine declares any other than float64 only (an engine written before
    precisions existed never receives one)."""
    keywords: dict = {"formulation": formulation} if formulation else {}
    if tuple(engine.offer(integrator).precisions) != (FLOAT64,):
        keywords["precision"] = precision
    return keywords


def require_modules(install: str, *modules: str) -> None:
    """Raise ImportError naming the install command when a module of an engine's SDK is absent, without importing it
    (importlib.util.find_spec; a folder an uninstall left behind, a namespace package, counts as absent). An adapter
    calls it when the registry loads it and imports its SDK on its first prepare, so that loading the adapter (the
    registry, `stereodyn engines`) costs no SDK import; the registry turns the ImportError into skipped rows whose
    reason is this message."""
    for module in modules:
        try:
            spec = importlib.util.find_spec(module)
        except (ImportError, ValueError):  # a dotted name whose parent is absent, or a module set to None
            spec = None
        if spec is None or spec.origin is None:
            raise ImportError(f"No module named {module!r}; install the extra: {install}")


class Simulation(Protocol):
    """A model built for one case, integrator and dt; run() steps it from the case's initial state."""

    def run(self, grid: "TimeGrid") -> Trajectory: ...


@dataclass(frozen=True)
class Offer:
    """What an engine declares of one of its integrators (Engine.offer): the integrators-offered group.

    order: the order it claims (convergence.csv's declared_order, the order verdict); NaN: the registry's order in the
    engine's state space (NaN for a name the registry does not know). orders: (formulation, order) pairs where the
    integrator is another method on one of the engine's models (Genesis's implicitfast is the implicit midpoint rule,
    order 2, on a free body). method: what it is in harness.engines.methods' vocabulary (runs of one method and dt are
    compared across engines, agreement.csv); None: the registry's method, "" for one it does not know. adaptive:
    it chooses its own steps (rows with dt None; prepare gets tolerance=...). default_sweep: whether a sweep that names
    no integrators runs it; None: the registry's rule (True for an engine's own names). precisions: FLOAT64, FLOAT32,
    each a row of its own (an engine declaring any other than float64 gets prepare(..., precision=...)). deviation: a
    documented departure from what it declares (KnownDeviation), or None. unmodelled: why the adapter does not run
    an integrator its SDK offers ("not modelled by stereodyn's adapter: ...", harness.engines.offered; "": it runs):
    one skipped row per case, and a line of `stereodyn engines`.
    """

    order: float = math.nan
    orders: tuple[tuple[str, float], ...] = ()
    method: str | None = None
    adaptive: bool = False
    default_sweep: bool | None = None
    precisions: tuple[str, ...] = (FLOAT64,)
    deviation: KnownDeviation | None = None
    unmodelled: str = ""


@dataclass(frozen=True)
class Timing:
    """The engine's timing declarations, read by the scheduler and the timing phases.

    pass_us: µs of one right-hand-side evaluation of one step (the scheduler's cost model, harness.run.pool).
    startup_s: s a worker pays once for this engine before its first run (SDK import, compilations); 0.0: none
    declared. short_warm_up: a run's first steps pay every first-call cost (nothing is built per grid length), so the
    timing phases warm it up on its first few hundred steps (harness.run.timing.warm_up); False warms up on the whole
    run, safe for any engine. process_global_precision: building a model of one precision releases the other's
    (Genesis's gs.init): the timing phases prepare and time its runs one precision at a time. prepare_budget_s: the
    least prepare budget (s) its runs get, for a first preparation that compiles for minutes (the larger of it and
    --prepare-budget holds); None: the sweep's.
    """

    pass_us: float = 5.0
    startup_s: float = 0.0
    short_warm_up: bool = False
    process_global_precision: bool = False
    prepare_budget_s: float | None = None


@dataclass(frozen=True)
class About:
    """How the rest of stereodyn places the engine. packages: distributions whose versions can change its results
    (they key the store, harness.environment). linestyle: Matplotlib line style of its lines in the report's figures.
    export_formats: model formats `stereodyn export` can write (its rigid-body model's export()). state_space: the
    state space ("lie" or "vector", harness.integrators) of the registered integrators it runs, None for none; their
    orders come from the registry, and harness.testing runs an integrator of that space here, on `formulation` ("" for
    an engine without formulations)."""

    packages: tuple[str, ...] = ()
    linestyle: str | tuple = "-."
    export_formats: tuple[str, ...] = ()
    state_space: str | None = None
    formulation: str = ""


_MODEL = "its RigidBodyModel subclass's {} (models())"
# The names an engine of stereodyn 0.2.0 defined, each with its spelling since 0.3.0 (CHANGELOG.md's migration table).
# A class that defines one is refused when it is made (Engine.__init_subclass__): its plug-in does not load, in one
# line naming the first of them (harness.engines' guard), and nothing of it is emulated.
OLD_NAMES = {
    **{name: f"timing = Timing({name}=...)" for name in ("pass_us", "startup_s", "short_warm_up",
                                                          "process_global_precision", "prepare_budget_s")},
    **{name: f"about = About({name}=...)" for name in ("packages", "linestyle", "export_formats", "state_space")},
    "default_formulation": "about = About(formulation=...)",
    "formulations": _MODEL.format("variants()"),
    **{name: _MODEL.format(f"{name}()") for name in ("default_run", "default_dts", "unsupported_run", "torque_mode",
                                                     "export", "prepare_ensemble")},
    "in_default_sweep": "offer(integrator) returning Offer(default_sweep=...)",
    "precisions": "offer(integrator) returning Offer(precisions=...)",
    "method": "offer(integrator) returning Offer(method=...)",
    "adaptive": "offer(integrator) returning Offer(adaptive=...)",
    "declared_order": "offer(integrator) returning Offer(order=...)",
    "formulation_order": "offer(integrator) returning Offer(orders=...)",
    "known_deviations": "offer(integrator) returning Offer(deviation=...)",
    **{name: 'models() returning {**super().models(), "sliding_ladder": a SceneModel}'
       for name in ("sliding_ladder_models", "sliding_ladder_integrators", "prepare_sliding_ladder",
                    "sliding_ladder_unsupported")},
}


class Engine:
    """The base class of an engine plug-in (entry-point group `stereodyn.engines`, harness.engines): the protocol an
    author writes is PROTOCOL, every name of it but the three required methods with a default here.

    Required: integrators(), unsupported(case), prepare(case, integrator, dt, **keywords). Groups: `offer(integrator)`
    (an Offer: order, method, adaptive, default sweep, precisions, known deviation), `timing` (Timing), `about`
    (About), and the scenes it models: `models()` (scene kind -> SceneModel: the rigid body through RigidBodyModel,
    whose subclass holds the engine's formulations, default runs and steps, run-level refusals, torque mode, export)
    and `unmodelled(scene)`.

    These are Engine's only public names: the harness reads the groups themselves, and what it derives from them
    with the registry's defaults (declared order, method, default sweep, the rigid-body model) through
    harness.engines.declared. A class that defines a name of 0.2.0's protocol (OLD_NAMES) is refused with a TypeError
    naming it and its spelling now.
    """

    PROTOCOL = ("name", "integrators", "unsupported", "prepare", "offer", "timing", "about", "models", "unmodelled")

    name: str = ""
    timing: Timing = Timing()
    about: About = About()

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        old = next((name for name in vars(cls) if name in OLD_NAMES), None)
        if old is not None:
            raise TypeError(f"engine {cls.__module__}.{cls.__qualname__} defines {old!r}, a name of stereodyn 0.2.0's "
                            f"engine protocol: since 0.3.0 declare {OLD_NAMES[old]} (docs/ENGINE_PLUGIN.md)")

    # ---------------------------------------------------------------------------------------------- required

    def integrators(self) -> tuple[str, ...]:
        """The integrator names this engine runs, in report order."""
        raise NotImplementedError(f"engine {self.name!r} does not implement integrators()")

    def unsupported(self, case: "Case") -> str | None:
        """Why this engine cannot model the case exactly (the run is then `skipped`), or None."""
        raise NotImplementedError(f"engine {self.name!r} does not implement unsupported(case)")

    def prepare(self, case: "Case", integrator: str, dt: float | None, **formulation) -> Simulation:
        """Build the model (not timed). formulation=... is passed when the rigid-body model has variants.

        tolerance=... (keyword, float | None) is passed for an adaptive integrator (Offer.adaptive): None, or not
        passed, is the engine's default tolerance for it (the sweep's row, dt None: 1e-8 unless the engine says
        otherwise in docs/ENGINES.md); a float is the requested tolerance, applied as both the relative and the
        absolute tolerance (scipy: rtol = atol = tol; heyoka: tol; Drake: set_target_accuracy(tol)). The tolerance
        ladders pass 1e-3 ... 1e-13. A fixed-step integrator accepts and ignores it. The adaptive run's Trajectory
        fills steps (accepted steps) and rhs_evals (right-hand-side evaluations), both > 0 where the method has them.
        precision=... is passed where Offer.precisions is other than float64 only.
        """
        raise NotImplementedError(f"engine {self.name!r} does not implement prepare(case, integrator, dt)")

    # ---------------------------------------------------------------------------------------------- groups

    def offer(self, integrator: str) -> Offer:
        """What the engine declares of one of its integrators. Default: Offer(), the registry's declarations."""
        return Offer()

    def models(self) -> dict[str, "SceneModel"]:
        """The scenes this engine models: scene kind (harness.scenes) -> its model of that scene. A case of a kind
        not listed gives one skipped row (unmodelled). Default: the rigid body with a fixed point through
        RigidBodyModel (prepare, unsupported and the defaults). An engine with
        formulations, default runs or an export returns its RigidBodyModel subclass; one that models another scene
        adds its model: {**super().models(), "sliding_ladder": MyLadderModel()}."""
        return {RIGID_BODY: RigidBodyModel(self)}

    def unmodelled(self, scene) -> str:
        """Why this engine has no model of the scene (harness.scenes.base.Scene): the skipped row's message."""
        return f"{self.name} adapter does not model {scene.title}"


RIGID_BODY, SLIDING_LADDER = "rigid_body", "sliding_ladder"  # scene kinds (harness.scenes) the defaults name


class SceneModel:
    """An engine's model of one scene (Engine.models()): which runs it has and how to build one. Every hook but
    prepare has a default here."""

    def variants(self) -> tuple[str, ...]:
        """The model's variants, one per run (results.csv's formulation column). Default: none ("")."""
        return ()

    def integrators(self, chosen: list[str]) -> list[str]:
        """The integrators of the sweep's selection (the engine's, chosen) that run this model. Default: all."""
        return list(chosen)

    def unsupported(self, case) -> str | None:
        """Why the model cannot run the case exactly (its rows are skipped), or None."""
        return None

    def unsupported_run(self, case, variant: str, integrator: str) -> str | None:
        """Why one variant/integrator pair cannot run the case (its row is skipped), or None."""
        return None

    def default_run(self, case, variant: str, integrator: str) -> bool:
        """Whether a sweep that names no integrators runs the pair on the case (harness.run.plan). Default: every
        pair; a model leaves out costly variants whose findings a smaller selection already shows (naming the
        integrator runs it everywhere)."""
        return True

    def default_dts(self, case, integrator: str, dts: tuple[float, ...]) -> tuple[float, ...]:
        """The steps of the case's dt list a sweep that names no integrators runs. Default: all of them; a model that
        costs milliseconds a step keeps a coarse one."""
        return dts

    def precisions(self, integrator: str) -> tuple[str, ...]:
        """The precisions this model runs an integrator in (a scene other than the rigid body: float64)."""
        return (FLOAT64,)

    def torque_mode(self, case) -> str:
        """How external torques enter the model (results column torque_mode) when the trajectory does not say."""
        return "none"

    def prepare(self, case, variant: str, integrator: str, dt: float | None, tolerance: float | None = None):
        """The simulation of one run (not timed): its run(grid) returns the scene's trajectory."""
        raise NotImplementedError(f"{type(self).__name__} does not implement prepare")

    def export(self, case, fmt: str, integrator: str | None, dt: float | None) -> str:
        """The model as text in one of the engine's export_formats (`stereodyn export`). Default: none."""
        raise ValueError(f"{case.name}: no {fmt} export of this scene's model")


class RigidBodyModel(SceneModel):
    """The rigid body with a fixed point as an engine models it: prepare and unsupported are the engine's, the rest
    the defaults (SceneModel's), which an engine's subclass overrides (its variants are the formulations)."""

    def __init__(self, engine: Engine):
        self.engine = engine

    def unsupported(self, case) -> str | None:
        return self.engine.unsupported(case)

    def precisions(self, integrator: str) -> tuple[str, ...]:
        return tuple(self.engine.offer(integrator).precisions)

    def export(self, case, fmt: str, integrator: str | None, dt: float | None) -> str:
        raise NotImplementedError(f"engine {self.engine.name!r} exports no format")

    def prepare_ensemble(self, case, integrator: str, dt: float, quat0: np.ndarray, omega0: np.ndarray,
                         threads: int = 1) -> "EnsembleSimulation":
        """N initial states stepped together. Default: not supported."""
        raise NotImplementedError(f"engine {self.engine.name!r} does not run ensembles")

    def prepare(self, case, variant: str, integrator: str, dt: float | None, tolerance: float | None = None,
                precision: str = FLOAT64):
        # Engine.prepare gets formulation= only where the model has variants, tolerance= only when requested,
        # precision= only where the engine declares another precision than float64 (prepare_keywords)
        extra = prepare_keywords(self.engine, variant, integrator, precision)
        extra |= {} if tolerance is None else {"tolerance": tolerance}
        return self.engine.prepare(case, integrator, dt, **extra)


class EnsembleSimulation(Protocol):
    """An engine's model run from N initial states at once."""

    def run(self, grid: "TimeGrid") -> list[Trajectory]: ...


def singular_torque(case: Case) -> str | None:
    """Why a torque of the case is not defined at its initial state (TorqueModel.singular, e.g. torque (41) near
    ω ∥ u = i3), so that its runs are skipped; None."""
    return next((reason for term in case.torques if (reason := term.singular(case.omega0)) is not None), None)

