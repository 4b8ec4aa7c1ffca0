"""The plan of a sweep: every case x engine x integrator x formulation x dt x precision as a RunSpec, and the rows of the runs
skipped up front (the engine cannot model the case). harness.run.sweep executes the plan; analysis.workprecision picks
its run families from it."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from ...reference import plugins
from ..engines import EngineError, UnavailableEngine, declared, get_engine
from ..precision import FLOAT64, precisions_problem
from ..scenes import scene_of
from ..trajectory import Status
from ..words import one_line
from .processes import raise_unless_data
from .spec import RunKey, RunSpec, base_row, skipped_row  # noqa: F401 (base_row, RunKey: part of this API)


@dataclass(frozen=True)
class Selection:
    """The integrators a sweep runs on one engine, resolved from the names asked for (--integrators, SweepOptions):
    those of them the engine has, in its order; none asked for, the engine's default sweep (default True:
    engines.declared.in_default_sweep), which also takes the rigid body's default steps (SceneModel.default_dts) and
    leaves out the pairs its models decline (SceneModel.default_run)."""

    integrators: tuple[str, ...]
    default: bool

    @classmethod
    def of(cls, engine, names: Sequence[str] | None) -> "Selection":
        if names is None:
            return cls(tuple(i for i in engine.integrators() if declared.in_default_sweep(engine, i)), True)
        return cls(tuple(i for i in engine.integrators() if i in names), False)


def plan(cases: list, engines: list[str], integrators: Sequence[str] | None) -> tuple[list[RunSpec], list[dict]]:
    """The runs of a sweep, and the rows of runs skipped up front (engine cannot model the case).

    Each case runs on each engine's model of its scene (Engine.models(); an engine without one gives one skipped row,
    Engine.unmodelled). An engine's adaptive integrators (Offer.adaptive) run once per case with dt None, the others
    once per dt of the case; each runs every variant of the model (SceneModel.variants: the rigid body's
    formulations, engines.declared.formulations; "" for a model without), except the pairs the model leaves out of
    a sweep that names no integrators (SceneModel.default_run). integrators: the names asked for, None for each
    engine's default sweep (Selection, resolved here once per engine). With integrators named, an engine that
    offers none of them has no rows at all (an engine whose SDK is missing, whose offer is unknown, keeps its
    skipped rows with the reason; `stereodyn run` leaves it out unless --engines names it).
    """
    specs, skipped = [], []
    for engine_rank, name in enumerate(engines):
        engine = get_engine(name)
        ask = Hooks(engine, name)
        selection = ask("integrators()", Selection.of, engine, integrators)
        if not selection.default and not selection.integrators and not isinstance(engine, UnavailableEngine):
            continue  # it offers none of the integrators named: no rows, not a skipped row per case
        models = ask("models()", engine.models)
        rigid = ask("models()", declared.rigid_body, engine)  # whose default_dts a default sweep takes
        for case in cases:
            scene = scene_of(case)
            model = models.get(scene.kind)
            if model is None:
                skipped.append(skipped_row(RunSpec(case, name, "", None, engine_rank=engine_rank),
                                           ask("unmodelled(scene)", engine.unmodelled, scene)))
                continue
            ask.model = model
            reason = ask.reason("unsupported(case)", model.unsupported, case)
            variants = tuple(ask("variants()", model.variants, rule=_names)) or ("",)
            chosen = ask("integrators(names)", model.integrators, list(selection.integrators), rule=_names)
            for integrator_rank, integrator in enumerate(chosen or ([""] if reason else [])):
                # an integrator the SDK offers that the adapter does not run (Offer.unmodelled): one skipped row
                offer = ask(f"offer({integrator!r})", engine.offer, integrator) if integrator else None
                unmodelled = offer.unmodelled if offer else ""
                dts = (None,) if integrator and (offer.adaptive or unmodelled) else case.dt
                if integrator and selection.default and dts != (None,):
                    dts = tuple(ask("default_dts(...)", rigid.default_dts, case, integrator, tuple(dts),
                                    rule=lambda answer, listed=tuple(dts): _steps_of(answer, listed)))
                for formulation_rank, formulation in enumerate(variants[:1] if unmodelled else variants):
                    if integrator and selection.default and not ask("default_run(...)", model.default_run, case,
                                                                     formulation, integrator, rule=flag):
                        continue  # the engine leaves this pair out of the default sweep (SceneModel.default_run)
                    # the precisions the engine's model of this scene runs (SceneModel.precisions)
                    precisions = ask("precisions(integrator)", model.precisions, integrator, rule=precisions_problem) \
                        if integrator else (FLOAT64,)
                    # a formulation/integrator pair that cannot model the case (SceneModel.unsupported_run)
                    why = reason or unmodelled or (integrator and ask.reason(
                        "unsupported_run(...)", model.unsupported_run, case, formulation, integrator))
                    for dt in dts:
                        for precision_rank, precision in enumerate(precisions):
                            spec = RunSpec(case, name, integrator, dt, formulation, precision=precision,
                                           engine_rank=engine_rank, integrator_rank=integrator_rank,
                                           formulation_rank=formulation_rank, precision_rank=precision_rank)
                            (skipped.append(_not_run(spec, why)) if why else specs.append(spec))
    return specs, skipped


class HookFailed(str):
    """A reason not to run that is a planning hook's failure (it raised or exited: Hooks.reason): its rows are
    failed, not skipped, which says the engine cannot model the case (issue 46's thirteenth attack)."""


def _not_run(spec: RunSpec, why: str) -> dict:
    """The row of a run the plan does not run: skipped with its reason, or failed where a hook failed (HookFailed)."""
    row = skipped_row(spec, why)
    return {**row, "status": Status.FAILED.value} if isinstance(why, HookFailed) else row


def agreement_candidates(specs: list[RunSpec]) -> set[int]:
    """Indices of the fixed-step rigid-body runs whose states the cross-engine agreement compares: those whose
    integrator names a method (engines.declared.method) that another engine also runs on the same case and dt."""
    methods = {}
    for index, spec in enumerate(specs):
        if spec.dt is not None and scene_of(spec.case).keeps_states:  # a scene whose states are (quat, omega)
            method = declared.method(get_engine(spec.engine), spec.integrator)
            if method:
                methods[index] = (spec.case.name, spec.dt, method)
    engines: dict[tuple, set[str]] = {}
    for index, key in methods.items():
        engines.setdefault(key, set()).add(specs[index].engine)
    return {index for index, key in methods.items() if len(engines[key]) > 1}


def _names(answer) -> str | None:
    ok = isinstance(answer, (tuple, list)) and all(isinstance(a, str) for a in answer)
    return None if ok else "must be a tuple of names"


def _steps_of(answer, listed: tuple[float, ...]) -> str | None:
    """default_dts' rule: steps of the case's dt list, each once (SceneModel.default_dts). A step of its own ran on
    a grid the truth does not sample, above t_end or 2**1000 s (an IndexError or a traceback, exit 3 or 1), and one
    step twice wrote rows with one key that every reader refused (issue 46's twelfth attack)."""
    rule = f"must be steps of the case's dt list ({', '.join(f'{dt:g}' for dt in listed)}), each at most once"
    ok = isinstance(answer, (tuple, list)) and all(
        isinstance(a, (int, float)) and not isinstance(a, bool) and a in listed for a in answer) \
        and len(set(answer)) == len(answer)
    return None if ok else rule


def flag(answer) -> str | None:
    """A yes/no hook's rule (default_run): "yes" or an object is no answer."""
    return None if isinstance(answer, (bool, np.bool_)) else "must be True or False"


class Hooks:
    """An engine's planning hooks, called for plan(): a plug-in's (its engine, or the model it gives, not stereodyn's
    own: our RigidBodyModel asks the engine) behind the guard. ask(what, hook, *args): a declaration; its failure
    (any raise, sys.exit, os._exit) is one line naming the plug-in and the hook (EngineError, exit 2: it was exit 3
    with nothing said, or a traceback: issue 46's eighth attack). ask.reason(...): a reason not to run a case or a
    pair, None or text; its failure is the reason of failed rows (HookFailed), named. Our own code's failure is a bug.
    `stereodyn advise` asks through it too (analysis.step_advice.families_to_advise)."""

    def __init__(self, engine, name: str):
        self.engine, self.name, self.model = engine, name, None

    def _own(self) -> bool:
        return plugins.own(type(self.engine)) and (self.model is None or plugins.own(type(self.model)))

    def __call__(self, what: str, hook, *args, rule: Callable | None = None):
        """hook(*args); rule(answer) -> why it is no answer a plan can use, or None (a plug-in's answer only)."""
        if self._own():
            return hook(*args)
        try:
            with plugins.guard(f"engine plug-in {self.name!r}: {what} failed"):
                answer = hook(*args)
        except plugins.PluginError as exc:
            raise EngineError(one_line(str(exc))) from None
        why = rule(answer) if rule is not None else None
        if why:  # an object for a list of steps was a traceback in the plan (issue 46's tenth attack)
            raise EngineError(one_line(f"engine plug-in {self.name!r}: {what} returned {plugins.shown(answer)}: {why}"))
        return answer

    def reason(self, what: str, hook, *args) -> str | None:
        if self._own():
            try:
                return hook(*args)
            except Exception as exc:
                raise_unless_data(exc)  # our own code's is a bug (harness.errors)
                return HookFailed(f"engine {self.name!r}: {what} raised {type(exc).__name__}: "
                                  f"{plugins.text_of(exc)}"[:300])
        try:
            with plugins.guard(self.name):
                why = hook(*args)
        except plugins.PluginError as exc:
            error = exc.error
            said = plugins.text_of(error)
            return HookFailed(one_line(f"engine {self.name!r}: {what} raised {type(error).__name__}: {said}")[:300])
        if not isinstance(why, (str, type(None))):  # 42 was the reason "42" (issue 46's ninth attack)
            raise EngineError(f"engine plug-in {self.name!r}: {what} returned {plugins.shown(why)}, not a reason "
                              "(text, or None to run)")
        # a plug-in's lines one, as measure makes a run's message: its runs of space (a newline) one space
        return None if why is None else one_line(" ".join(why.split()))


