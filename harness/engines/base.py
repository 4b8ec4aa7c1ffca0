"""The engine base class: build a case's model, roll it out with an integrator and a step, return a Trajectory."""
from __future__ import annotations

import importlib.util
import math
from dataclasses import dataclass
import warnings
from typing import TYPE_CHECKING, Protocol

import numpy as np

from ..trajectory import Trajectory

if TYPE_CHECKING:
    from ..scenes.cases import Case
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
    if tuple(engine.precisions(integrator)) != (FLOAT64,):
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


class Engine:
    """The base class of an engine plug-in (entry-point group `stereodyn.engines`, harness.engines). Subclass it, set
    `name`, implement the three required methods; every other hook has the default written here, which is what an
    engine that does not override it gets. The harness calls these methods only, never getattr.

    Required: integrators(), unsupported(case), prepare(case, integrator, dt, **formulation).
    """

    name: str = ""
    # The state space ("lie" or "vector", harness.integrators) of the registered integrators this engine runs, if
    # any: their declared orders come from the registry, and harness.testing runs an integrator of that space here.
    state_space: str | None = None
    # The formulation harness.testing runs a registered integrator on ("" for an engine without formulations).
    default_formulation: str = ""
    # Cost of one right-hand-side evaluation of one step, µs (the sweep's scheduler ranks runs by it:
    # harness.run.sweep).
    pass_us: float = 5.0
    # Matplotlib line style of this engine's lines in the report's figures.
    linestyle: str = "-."
    # Distributions whose versions can change this engine's results: they key the store (harness.environment).
    packages: tuple[str, ...] = ()
    # Model formats `stereodyn export` can write through export(case, fmt, integrator, dt).
    export_formats: tuple[str, ...] = ()
    # Documented departures of this engine's integrators from their declared behaviour (KnownDeviation).
    known_deviations: tuple[KnownDeviation, ...] = ()
    # True when the engine's precision is set for its whole process (Genesis's gs.init): building a model of one
    # precision releases the models of the other, so the timing phases prepare and time its runs one precision at a
    # time (harness.run.timing.groups).
    process_global_precision: bool = False
    # True when a run's first steps pay every first-call cost of the whole run (nothing is compiled or allocated per
    # grid length): the timing phases then warm a run up on its first few hundred steps instead of the whole run
    # (harness.run.timing.warm_up). False (the default) warms up on the whole run, which any engine is safe with.
    short_warm_up: bool = False
    # The prepare budget (s) this engine's runs get at least, for an engine whose first preparation in a process
    # imports and compiles for minutes: a run's prepare budget is the larger of this and the sweep's
    # (--prepare-budget; harness.run.measure.prepare_budget). None: the sweep's.
    prepare_budget_s: float | None = None
    _legacy_ladder = False  # set for a 0.2.0 plug-in that still implements the sliding ladder's four hooks

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        legacy = [hook for hook in _LEGACY_LADDER_HOOKS if hook in vars(cls)]
        if legacy:
            warnings.warn(f"engine {cls.__name__}: {', '.join(legacy)} are replaced by Engine.models() "
                          "(DESIGN §7); they still run the sliding ladder through an adapter", DeprecationWarning,
                          stacklevel=2)
            cls._legacy_ladder = "prepare_sliding_ladder" in legacy or cls._legacy_ladder

    # ---------------------------------------------------------------------------------------------- required

    def integrators(self) -> tuple[str, ...]:
        """The integrator names this engine runs, in report order."""
        raise NotImplementedError(f"engine {self.name!r} does not implement integrators()")

    def unsupported(self, case: "Case") -> str | None:
        """Why this engine cannot model the case exactly (the run is then `skipped`), or None."""
        raise NotImplementedError(f"engine {self.name!r} does not implement unsupported(case)")

    def prepare(self, case: "Case", integrator: str, dt: float | None, **formulation) -> Simulation:
        """Build the model (not timed). formulation=... is passed when formulations() is not empty.

        tolerance=... (keyword, float | None) is passed for an adaptive integrator (adaptive(integrator) True): None,
        or not passed, is the engine's default tolerance for it (the sweep's row, dt None: 1e-8 unless the engine
        says otherwise in docs/ENGINES.md); a float is the requested tolerance, applied as both the relative and the
        absolute tolerance (scipy: rtol = atol = tol; heyoka: tol; Drake: set_target_accuracy(tol)). The tolerance
        ladders (analysis.tolerance_ladders) pass 1e-3 ... 1e-13. A fixed-step integrator accepts and ignores it. The
        adaptive run's Trajectory fills steps (accepted steps) and rhs_evals (right-hand-side evaluations), both > 0
        where the method has them.
        """
        raise NotImplementedError(f"engine {self.name!r} does not implement prepare(case, integrator, dt)")

    # ---------------------------------------------------------------------------------------------- optional

    def formulations(self) -> tuple[str, ...]:
        """The formulations it runs; each run names one (prepare(..., formulation=...)). Default: none, and rows have
        formulation ""."""
        return ()

    def in_default_sweep(self, integrator: str) -> bool:
        """Whether a sweep that names no integrators runs this one on this engine. Default: the registry's
        in_default_sweep (False for classes declaring default_sweep = False, and for entry-point plug-ins that do not
        opt in with default_sweep = True; an engine's own name is run)."""
        from .. import integrators

        return integrators.in_default_sweep(integrator)

    def precisions(self, integrator: str) -> tuple[str, ...]:
        """The floating-point precisions (FLOAT64, FLOAT32) the integrator runs in, each a row of its own. Default:
        float64 only. An engine declaring anything else gets prepare(..., precision=...) on every run."""
        return (FLOAT64,)

    def method(self, integrator: str) -> str:
        """What the integrator is, in the vocabulary of harness.engines.methods ("semi_implicit_euler", "rk4", ...):
        runs of the same method and dt on a case are compared across engines (agreement.csv). Default: the
        registry's method of a registered integrator; "" (compared with nothing) for one it does not know."""
        from .methods import registered_method  # (not `from . import methods`: the package imports this module)

        return registered_method(integrator, self.state_space or "lie")

    def adaptive(self, integrator: str) -> bool:
        """Whether an integrator chooses its own steps (its runs have dt None; prepare takes tolerance=...). Default:
        none does."""
        return False

    def default_run(self, case: "Case", formulation: str, integrator: str) -> bool:
        """Whether a sweep that names no integrators (no --integrators) runs this formulation/integrator pair on the
        case (harness.run.plan). Default: every pair. An engine leaves out costly variants whose findings a smaller
        selection already shows; naming the integrator runs it everywhere."""
        return True

    def default_dts(self, case: "Case", integrator: str, dts: tuple[float, ...]) -> tuple[float, ...]:
        """The steps of the case's dt list a sweep that names no integrators runs. Default: all of them; an engine
        that costs milliseconds a step keeps a coarse one."""
        return dts

    def unsupported_run(self, case: "Case", formulation: str, integrator: str) -> str | None:
        """Why one formulation/integrator pair cannot model the case (the run is `skipped`), or None (default)."""
        return None

    def torque_mode(self, case: "Case") -> str:
        """How the case's external torques enter the model (results column torque_mode) when the trajectory does not
        say (Trajectory.info["torque_mode"]). Default "none"."""
        return "none"

    def declared_order(self, integrator: str) -> float:
        """The order an integrator claims (convergence.csv's declared_order). Default: the registry's order in
        state_space; NaN for an integrator the registry does not know (override for the engine's own)."""
        from .. import integrators

        try:
            return float(integrators.get(integrator, self.state_space or "lie").order)
        except KeyError:
            return math.nan

    def formulation_order(self, formulation: str, integrator: str) -> float:
        """The order the integrator has on one of the engine's models (formulations), for an engine whose integrator
        is another method on another model (convergence.csv's declared_order, the order verdict). Default:
        declared_order(integrator) on every model."""
        return self.declared_order(integrator)

    def prepare_ensemble(self, case: "Case", integrator: str, dt: float, quat0: np.ndarray, omega0: np.ndarray,
                         threads: int = 1) -> "EnsembleSimulation":
        """N initial states (quat0 (N, 4) wxyz, omega0 (N, 3) rad/s) stepped together. Default: not supported."""
        raise NotImplementedError(f"engine {self.name!r} does not run ensembles")

    def models(self) -> dict[str, "SceneModel"]:
        """The scenes this engine models: scene kind (harness.scenes) -> its model of that scene. A case of a kind
        not listed gives one skipped row (unmodelled). Default: the rigid body with a fixed point, through the hooks
        above (prepare, formulations, unsupported, ...), as every engine of 0.2.0 does. An engine that models another
        scene adds its model: {**super().models(), "sliding_ladder": MyLadderModel()}."""
        models: dict[str, SceneModel] = {RIGID_BODY: RigidBodyModel(self)}
        if type(self)._legacy_ladder:
            models[SLIDING_LADDER] = _LegacyLadderModel(self)
        return models

    def unmodelled(self, scene) -> str:
        """Why this engine has no model of the scene (harness.scenes.base.Scene): the skipped row's message."""
        return f"{self.name} adapter does not model {scene.title}"

    def export(self, case: "Case", fmt: str, integrator: str | None, dt: float | None) -> str:
        """The model text in one of export_formats."""
        raise NotImplementedError(f"engine {self.name!r} exports no format")


RIGID_BODY, SLIDING_LADDER = "rigid_body", "sliding_ladder"  # scene kinds (harness.scenes) the defaults name
_LEGACY_LADDER_HOOKS = ("sliding_ladder_models", "sliding_ladder_integrators", "prepare_sliding_ladder",
                        "sliding_ladder_unsupported")


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
        return None

    def default_run(self, case, variant: str, integrator: str) -> bool:
        """Whether a sweep that names no integrators runs the pair. Default: every pair."""
        return True

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
    """The rigid body with a fixed point as an engine models it through the Engine hooks (0.2.0's protocol)."""

    def __init__(self, engine: Engine):
        self.engine = engine

    def variants(self) -> tuple[str, ...]:
        return tuple(self.engine.formulations())

    def unsupported(self, case) -> str | None:
        return self.engine.unsupported(case)

    def unsupported_run(self, case, variant: str, integrator: str) -> str | None:
        return self.engine.unsupported_run(case, variant, integrator)

    def default_run(self, case, variant: str, integrator: str) -> bool:
        return self.engine.default_run(case, variant, integrator)

    def torque_mode(self, case) -> str:
        return self.engine.torque_mode(case)

    def precisions(self, integrator: str) -> tuple[str, ...]:
        return tuple(self.engine.precisions(integrator))

    def export(self, case, fmt: str, integrator: str | None, dt: float | None) -> str:
        return self.engine.export(case, fmt, integrator, dt)

    def prepare(self, case, variant: str, integrator: str, dt: float | None, tolerance: float | None = None,
                precision: str = FLOAT64):
        # formulation= only for an engine with formulations, tolerance= only when requested, precision= only for an
        # engine that declares another precision than float64: the 0.2.0 signatures
        extra = prepare_keywords(self.engine, variant, integrator, precision)
        extra |= {} if tolerance is None else {"tolerance": tolerance}
        return self.engine.prepare(case, integrator, dt, **extra)


class _LegacyLadderModel(SceneModel):
    """The sliding ladder of a 0.2.0 plug-in that implements Engine.prepare_sliding_ladder and its three siblings."""

    def __init__(self, engine: Engine):
        self.engine = engine

    def variants(self) -> tuple[str, ...]:
        return tuple(self.engine.sliding_ladder_models())

    def integrators(self, chosen: list[str]) -> list[str]:
        hook = getattr(self.engine, "sliding_ladder_integrators", None)  # optional in 0.2.0 (default: all)
        return list(chosen) if hook is None else list(hook(chosen))

    def prepare(self, case, variant: str, integrator: str, dt: float | None, tolerance: float | None = None):
        return self.engine.prepare_sliding_ladder(case, variant, integrator, dt)


class EnsembleSimulation(Protocol):
    """An engine's model run from N initial states at once."""

    def run(self, grid: "TimeGrid") -> list[Trajectory]: ...


def singular_torque(case: Case) -> str | None:
    """Why a torque of the case is not defined at its initial state (TorqueModel.singular, e.g. torque (41) near
    ω ∥ u = i3), so that its runs are skipped; None."""
    return next((reason for term in case.torques if (reason := term.singular(case.omega0)) is not None), None)


precession_singular = singular_torque  # 0.2.0's name
