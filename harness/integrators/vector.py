"""Fixed-step explicit Runge–Kutta on the "vector" state space: y' = f(t, chart, y), y in R^n, in a chart of the
attitude that the system may change between steps (a formulation of reference.formulations).

The same ButcherTableau drives these and the Lie-group methods of harness.integrators.lie: one class here, VectorRK,
and a tableau per method. The system re-charts after every step (never inside one: all stages of a step see the same
chart) and may raise ArithmeticError there when its coordinates became singular, which ends the run as diverged.
"""
from __future__ import annotations

import dataclasses
from typing import ClassVar, Protocol

import numpy as np

from ..trajectory import Trajectory
from ..grid import TimeGrid
from .base import Integrator, Stepper, counting
from .tableau import CLASSICAL_RK4, EULER_TABLEAU, ButcherTableau


class VectorSystem(Protocol):
    """An ODE on R^n in charts. Charts are immutable objects; no method may modify a chart or a y it is given."""

    def rhs(self, t: float, chart: object, y: np.ndarray) -> np.ndarray:
        """y' (n,) at time t (s) and y (n,) in chart. Returns a fresh array."""

    def rechart(self, chart: object, y: np.ndarray) -> tuple[object, np.ndarray]:
        """After a step: (chart, y) unchanged, or a new chart and y's coordinates in it. May raise ArithmeticError."""

    def observe(self, chart: object, y: np.ndarray) -> tuple[tuple, tuple]:
        """The attitude quaternion (w, x, y, z) and body angular velocity (rad/s) of y in chart, as floats."""

    def chart_changes(self, chart: object) -> int | None:
        """Chart changes made up to chart (None for a system without charts)."""


class VectorRK(Integrator):
    """Explicit Runge–Kutta driven by `tableau`: k_i = f(t + c_i h, chart, y + h sum_j a_ij k_j), y + h sum_i b_i k_i,
    then the system re-charts. A subclass sets the tableau and the metadata."""

    tableau: ClassVar[ButcherTableau]
    state_space = "vector"
    symplectic = False
    geometric = False  # nothing keeps a quaternion state on the unit sphere

    def step(self, system: VectorSystem, t: float, chart: object, y: np.ndarray,
             h: float) -> tuple[object, np.ndarray]:
        return self.stepper(system, h)(t, chart, y)

    def stepper(self, system: VectorSystem, h: float) -> Stepper:
        rhs, rechart = system.rhs, system.rechart
        # Per stage, and for the update: the non-zero coefficients h a_ij (h b_j) with their stage j; per stage its
        # time offset c_i h.
        stages = tuple(tuple((j, h * a) for j, a in enumerate(row) if a != 0.0) for row in self.tableau.a)
        offsets = tuple(node * h for node in self.tableau.c)
        update = tuple((j, h * b) for j, b in enumerate(self.tableau.b) if b != 0.0)

        def combine(y: np.ndarray, terms: tuple, slopes: list) -> np.ndarray:
            (first, c), *rest = terms
            out = y + c * slopes[first]  # a new array, so the += below never touch y
            for j, c in rest:
                out += c * slopes[j]
            return out

        def step(t, chart, y):
            slopes = []
            for terms, offset in zip(stages, offsets):
                slopes.append(rhs(t + offset, chart, combine(y, terms, slopes) if terms else y))
            return rechart(chart, combine(y, update, slopes))

        return step

    def integrate(self, system: VectorSystem, chart0: object, y0: np.ndarray, grid: TimeGrid) -> Trajectory:
        """grid.steps steps of grid.dt from (chart0, y0), recorded at grid.sample_steps through system.observe; the
        divergence rule and the step of divergence as in Integrator.integrate. chart_changes: the system's count at
        the last state reached; rhs_evals: the rhs calls counted (Counted)."""
        stepped, calls = counting(system, "rhs")
        trajectory, chart = self._run(self.stepper(stepped, grid.dt), chart0, np.array(y0, dtype=float), grid,
                                      system.observe, calls)
        return dataclasses.replace(trajectory, chart_changes=system.chart_changes(chart))


class VectorEuler(VectorRK):
    name = "euler"
    order = 1
    tableau = EULER_TABLEAU
    description = "explicit Euler on the formulation's coordinates: y + h f(y)"


class VectorRK4(VectorRK):
    name = "rk4"
    order = 4
    tableau = CLASSICAL_RK4
    description = "classical Runge–Kutta 4 on the formulation's coordinates"
