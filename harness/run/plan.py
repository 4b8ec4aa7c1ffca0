"""The plan of a sweep: every case x engine x integrator x formulation x dt as a RunSpec, and the rows of the runs
skipped up front (the engine cannot model the case). harness.run.sweep executes the plan; harness.workprecision picks
its run families from it."""
from __future__ import annotations

import math
from dataclasses import dataclass

from ..scenes.cases import SLIDING_LADDER, Case
from ..engines import TRUTH_ENGINE, TRUTH_FORMULATION, TRUTH_INTEGRATOR, Engine, get_engine
from ..grid import TimeGrid, time_grid
from ..trajectory import Status


@dataclass(frozen=True)
class RunSpec:
    """One run: a case on an engine with an integrator and a step (dt is None for adaptive integrators), and the
    engine's formulation ("" for an engine without formulations)."""

    case: Case
    engine: str
    integrator: str
    dt: float | None
    engine_rank: int = 0
    integrator_rank: int = 0
    formulation: str = ""
    formulation_rank: int = 0
    keep_states: bool = False  # return the recorded states with the row ("_states"), for --save-trajectories

    @property
    def label(self) -> str:
        dt = "" if self.dt is None else f" dt={self.dt:g}"
        formulation = f" {self.formulation}" if self.formulation else ""
        return f"{self.case.name} {self.engine}{formulation} {self.integrator}{dt}"

    @property
    def is_truth(self) -> bool:
        return (self.engine, self.formulation, self.integrator) == (TRUTH_ENGINE, TRUTH_FORMULATION, TRUTH_INTEGRATOR)


def base_row(spec: RunSpec, grid: TimeGrid | None) -> dict:
    """The columns every row of the spec has (identity, grid, private sort keys)."""
    return {"case": spec.case.name, "engine": spec.engine, "formulation": spec.formulation,
            "integrator": spec.integrator, "dt": math.nan if spec.dt is None else spec.dt,
            "t_end": grid.t_end if grid is not None else spec.case.t_end,
            "steps": grid.steps if grid is not None else math.nan,
            "_engine_rank": spec.engine_rank, "_integrator_rank": spec.integrator_rank,
            "_formulation_rank": spec.formulation_rank, "_dt_rank": -(spec.dt if spec.dt is not None else math.inf)}


def skipped_row(spec: RunSpec, reason: str) -> dict:
    grid = None if spec.dt is None else time_grid(spec.case.t_end, spec.dt, spec.case.samples)
    return {**base_row(spec, grid), "status": Status.SKIPPED.value, "message": reason}


def _sliding_ladder_specs(case, name: str, engine: Engine, engine_rank: int,
                          chosen: list[str]) -> tuple[list[RunSpec], list[dict]]:
    """(runs, skipped rows) of one sliding-ladder case on one engine (harness.scenes.sliding_ladder runs them): each of
    the engine's models (Engine.sliding_ladder_models, in the formulation column) with each of its integrators."""
    models = engine.sliding_ladder_models()
    if not models:
        return [], [skipped_row(RunSpec(case, name, "", None, engine_rank), engine.sliding_ladder_unsupported())]
    runs = []
    for integrator_rank, integrator in enumerate(engine.sliding_ladder_integrators(chosen)):
        for model_rank, model in enumerate(models):
            for dt in ((None,) if engine.adaptive(integrator) else case.dt):
                runs.append(RunSpec(case, name, integrator, dt, engine_rank, integrator_rank, model, model_rank))
    return runs, []


def plan(cases: list[Case], engines: list[str], integrators: list[str] | None) -> tuple[list[RunSpec], list[dict]]:
    """The runs of a sweep, and the rows of runs skipped up front (engine cannot model the case).

    An engine's adaptive integrators (Engine.adaptive) run once per case with dt None, the others once per dt of the
    case; each runs every formulation of the engine (Engine.formulations; "" for an engine without), except the pairs
    the engine leaves out of a sweep that names no integrators (Engine.default_run).
    """
    specs, skipped = [], []
    for engine_rank, name in enumerate(engines):
        engine = get_engine(name)
        chosen = [i for i in engine.integrators()
                  if (integrators is None and engine.in_default_sweep(i))
                  or (integrators is not None and i in integrators)]
        formulations = tuple(engine.formulations()) or ("",)
        for case in cases:
            if case.kind == SLIDING_LADDER:
                ladder_specs, ladder_skipped = _sliding_ladder_specs(case, name, engine, engine_rank, chosen)
                specs += ladder_specs
                skipped += ladder_skipped
                continue
            reason = engine.unsupported(case)
            for integrator_rank, integrator in enumerate(chosen or ([""] if reason else [])):
                dts = (None,) if integrator and engine.adaptive(integrator) else case.dt
                if integrator and integrators is None and dts != (None,):
                    dts = engine.default_dts(case, integrator, tuple(dts))
                for formulation_rank, formulation in enumerate(formulations):
                    if integrator and integrators is None and not engine.default_run(case, formulation, integrator):
                        continue  # the engine leaves this pair out of the default sweep (Engine.default_run)
                    for dt in dts:
                        spec = RunSpec(case, name, integrator, dt, engine_rank, integrator_rank, formulation,
                                       formulation_rank)
                        # a formulation/integrator pair that cannot model the case (Engine.unsupported_run)
                        why = reason or (integrator and engine.unsupported_run(case, formulation, integrator))
                        (skipped.append(skipped_row(spec, why)) if why else specs.append(spec))
    return specs, skipped
