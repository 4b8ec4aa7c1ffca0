"""The reference engine: the classical formulations integrated by heyoka (the truth rows)."""
from __future__ import annotations

from dataclasses import dataclass

from harness.cases import Case
from harness.engines.base import Status, Trajectory
from harness.grid import TimeGrid
from reference import truth


@dataclass(frozen=True)
class _TaylorSimulation:
    case: Case

    def run(self, grid: TimeGrid) -> Trajectory:
        result = truth.truth(self.case.body, self.case.quat0, self.case.omega0, grid.times)
        return Trajectory(grid.times, result.quat, result.omega, Status.OK, steps=result.steps,
                          info={"wall_s": result.wall_s})


class ReferenceEngine:
    """Euler–Poisson with quaternion attitude, integrated by heyoka's adaptive Taylor method (integrator `taylor`)."""

    name = "reference"
    formulations = ("quaternion",)

    def integrators(self) -> tuple[str, ...]:
        return ("taylor",)

    def unsupported(self, case: Case) -> str | None:
        for table, present in (("body_torque", case.body_torque), ("central_field", case.central_field)):
            if present is not None:
                return f"reference engine does not model [{table}] yet"
        return None

    def prepare(self, case: Case, integrator: str, dt: float | None) -> _TaylorSimulation:
        if integrator != "taylor":
            raise KeyError(f"unknown integrator {integrator!r} for the reference engine; valid: taylor")
        return _TaylorSimulation(case)
