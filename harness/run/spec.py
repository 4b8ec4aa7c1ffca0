"""What a run is, once: RunKey (case, engine, model, integrator, dt | tolerance) with its label and store identity;
RunSpec, a key in a sweep's plan (with its row-order ranks); Family, the runs of a key that differ only in dt or in
the requested tolerance (the dt and tolerance ladders); the identity columns of a row."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from ..truth_names import TRUTH_ENGINE, TRUTH_FORMULATION, TRUTH_INTEGRATOR
from ..precision import FLOAT64
from ..grid import TimeGrid, time_grid
from ..trajectory import Status


@dataclass(frozen=True)
class RunKey:
    """One run: a case on an engine's model of its scene with an integrator, and a step (dt; None for an adaptive
    integrator) or, for an adaptive integrator, a requested tolerance (None: the engine's default for it).
    formulation: the engine's model of the scene it runs (a formulation of the rigid body, a model of the sliding
    ladder; results.csv's `formulation` column), "" for an engine with one model."""

    case: Any
    engine: str
    integrator: str
    dt: float | None = None
    formulation: str = ""
    tolerance: float | None = None
    precision: str = FLOAT64  # the run's floating-point precision (Offer.precisions)

    @property
    def family_label(self) -> str:
        precision = self.precision if self.precision != FLOAT64 else ""
        return " ".join(x for x in (self.case.name, self.engine, self.formulation, self.integrator, precision) if x)

    @property
    def label(self) -> str:
        step = "" if self.dt is None else f" dt={self.dt:g}"
        return self.family_label + step + ("" if self.tolerance is None else f" tol={self.tolerance:g}")

    @property
    def is_truth(self) -> bool:
        """The truth's own row (no errors against itself); a tolerance ladder's point of the same method is a run."""
        return (self.engine, self.formulation, self.integrator) == (TRUTH_ENGINE, TRUTH_FORMULATION,
                                                                    TRUTH_INTEGRATOR) and self.tolerance is None

    @property
    def grid(self) -> TimeGrid:
        """The run's sample times: the dt grid, or the case's samples evenly over [0, t_end] for an adaptive run."""
        case = self.case
        return time_grid(case.t_end, case.t_end / (case.samples - 1) if self.dt is None else self.dt, case.samples)

    def identity(self, store, certify: bool) -> dict:
        """Everything its row depends on (harness.run.store.run_identity; run_key(identity) is its store key)."""
        return store.identity(self.case, self.engine, self.formulation, self.integrator, self.dt, certify,
                              self.precision)


@dataclass(frozen=True)
class RunSpec(RunKey):
    """A run of a sweep's plan: its key and the ranks that order its row (engines as listed, integrators and
    formulations in each engine's order)."""

    engine_rank: int = field(default=0, kw_only=True)
    integrator_rank: int = field(default=0, kw_only=True)
    formulation_rank: int = field(default=0, kw_only=True)
    precision_rank: int = field(default=0, kw_only=True)
    keep_states: bool = field(default=False, kw_only=True)  # return the recorded states ("_states"), --save-trajectories
    compared: bool = field(default=False, kw_only=True)  # return them for the cross-engine agreement too


@dataclass(frozen=True)
class Family:
    """Runs of one case x engine x formulation x integrator, which differ only in dt (a dt ladder) or in the
    requested tolerance (a tolerance ladder)."""

    case: Any
    engine: str
    formulation: str
    integrator: str
    precision: str = FLOAT64

    def run(self, dt: float | None = None, tolerance: float | None = None) -> RunKey:
        return RunKey(self.case, self.engine, self.integrator, dt, self.formulation, tolerance, self.precision)

    @property
    def label(self) -> str:
        return self.run().family_label

    @property
    def key(self) -> tuple[str, str, str, str, str]:
        return self.case.name, self.engine, self.formulation, self.integrator, self.precision

    @property
    def columns(self) -> dict:
        """The family's identity columns of a ladder or convergence row."""
        return dict(zip(("case", "engine", "formulation", "integrator", "precision"), self.key))


def base_row(spec: RunKey, grid: TimeGrid | None) -> dict:
    """The columns every row of the run has (identity, grid, and for a RunSpec the private sort keys)."""
    row = {"case": spec.case.name, "engine": spec.engine, "formulation": spec.formulation,
           "integrator": spec.integrator, "precision": spec.precision, "dt": math.nan if spec.dt is None else spec.dt,
           "t_end": grid.t_end if grid is not None else spec.case.t_end,
           "steps": grid.steps if grid is not None else math.nan}
    if isinstance(spec, RunSpec):
        row.update(_engine_rank=spec.engine_rank, _integrator_rank=spec.integrator_rank,
                   _formulation_rank=spec.formulation_rank, _precision_rank=spec.precision_rank,
                   _dt_rank=-(spec.dt if spec.dt is not None else math.inf))
    return row


def skipped_row(spec: RunSpec, reason: str) -> dict:
    grid = None if spec.dt is None else time_grid(spec.case.t_end, spec.dt, spec.case.samples)
    return {**base_row(spec, grid), "status": Status.SKIPPED.value, "message": reason}
