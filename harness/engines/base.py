"""The engine protocol: build a case's model, roll it out with an integrator and a step, return a Trajectory."""
from __future__ import annotations

from typing import TYPE_CHECKING, Protocol

import numpy as np

from stereodyn.harness.trajectory import Trajectory
from stereodyn.reference.torques import PRECESSION_SINGULAR_ANGLE, transverse_angle

if TYPE_CHECKING:
    from stereodyn.harness.cases import Case
    from stereodyn.harness.grid import TimeGrid


class Simulation(Protocol):
    """A model built for one case, integrator and dt; run() steps it from the case's initial state."""

    def run(self, grid: "TimeGrid") -> Trajectory: ...


class Engine(Protocol):
    """An engine. Two methods are optional: formulations() -> tuple[str, ...], the formulations it runs (each run
    then names one, passed to prepare as formulation=...; without the method: none, and rows have formulation ""),
    and adaptive(integrator) -> bool, whether an integrator chooses its own steps (its runs have dt None; without
    the method: none does)."""

    name: str

    def integrators(self) -> tuple[str, ...]:
        """The integrator names this engine runs, in report order."""

    def unsupported(self, case: "Case") -> str | None:
        """Why this engine cannot model the case exactly (the run is then `skipped`), or None."""

    def prepare(self, case: "Case", integrator: str, dt: float) -> Simulation:
        """Build the model (not timed)."""


def precession_singular(case: Case) -> str | None:
    """Torque (41) is singular at ω ∥ u = i3: a case starting within PRECESSION_SINGULAR_ANGLE of it is skipped."""
    if case.precession_torque is None:
        return None
    angle = float(transverse_angle(np.asarray(case.omega0, dtype=float)))
    if angle < PRECESSION_SINGULAR_ANGLE:
        return (f"[precession_torque] singular: omega0 within {angle:.3g} rad of u = i3 (torque (41) needs "
                f">= {PRECESSION_SINGULAR_ANGLE:g} rad)")
    return None
