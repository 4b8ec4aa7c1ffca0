"""The built-in integrators on SO(3) x R^3: explicit Runge–Kutta (Munthe-Kaas or naive) from a Butcher tableau, and
the velocity-first Euler step that MuJoCo uses.

Runge–Kutta–Munthe-Kaas (RKMK): write the step as g(t0 + s) = g0 exp(theta(s)); theta obeys the ODE on R^3
    theta' = dexp^-1_theta(v) = v + 1/2 theta x v + c(|theta|) theta x (theta x v),
    c(phi) = (1 - (phi/2) cot(phi/2)) / phi^2 = 1/12 + phi^2/720 + phi^4/30240 + phi^6/1209600 + ...
(left trivialisation: for g = g0 exp(theta), g^-1 g' = dexp_{-theta}(theta') = theta' - 1/2 theta x theta' + ...,
whose inverse has the + sign). That is dexp^-1 in closed form on SO(3), exact for any theta with |theta| < 2 pi
(dexp_coefficient), so any explicit RK method applied to (theta, v) and mapped back through exp keeps its order,
whatever that order is (a truncated series caps it: cut after 1/12, the next term is O(h^4)).
Dropping the correction (theta' = v) is the "naive" scheme, at most 2nd order on the group whatever the tableau.
"""
from __future__ import annotations

import math
from typing import ClassVar

import numpy as np

from .base import BatchLieSystem, Integrator, LieSystem, Stepper, StepperIntegrator
from .tableau import CLASSICAL_RK4, EULER_TABLEAU, ButcherTableau


# Below this phi^2 (phi = |theta| < 0.1 rad) c(phi) is the series to phi^6: the closed form loses ~eps / phi^2 to the
# cancellation in 1 - x cot x, and the series' first omitted term, phi^8 / 47900160, is < 1e-17 there.
DEXP_SERIES_BELOW = 1e-2


def dexp_coefficient(phi2: float) -> float:
    """c(phi) of dexp^-1_theta(u) = u + 1/2 theta x u + c theta x (theta x u) on SO(3); phi2 = |theta|^2 (rad^2)."""
    if phi2 < DEXP_SERIES_BELOW:
        return 1.0 / 12.0 + phi2 * (1.0 / 720.0 + phi2 * (1.0 / 30240.0 + phi2 / 1209600.0))
    half = 0.5 * math.sqrt(phi2)
    return (1.0 - half * math.cos(half) / math.sin(half)) / phi2


def dexp_coefficients(phi2: np.ndarray) -> np.ndarray:
    """dexp_coefficient row by row: phi2 (N,) rad^2 -> c (N,)."""
    series = 1.0 / 12.0 + phi2 * (1.0 / 720.0 + phi2 * (1.0 / 30240.0 + phi2 / 1209600.0))
    large = phi2 >= DEXP_SERIES_BELOW
    if not large.any():
        return series
    half = 0.5 * np.sqrt(np.where(large, phi2, 1.0))
    with np.errstate(all="ignore"):
        closed = (1.0 - half / np.tan(half)) / np.where(large, phi2, 1.0)
    return np.where(large, closed, series)




class ExplicitRK(StepperIntegrator):
    """Explicit Runge–Kutta on the group, driven by `tableau`; `munthe_kaas` selects the dexp^-1 correction.

    Stage i: theta_i = h sum_j a_ij T_j, Y_i = (g exp(theta_i), v + h sum_j a_ij K_j), K_i = accel(t + c_i h, Y_i),
    T_i = dexp^-1_{theta_i}(v_i) (or v_i when munthe_kaas is False). Step: g exp(h sum b_i T_i), v + h sum b_i K_i.
    A subclass sets the tableau and the metadata; `stages` defaults to the tableau's.
    """

    tableau: ClassVar[ButcherTableau]
    munthe_kaas: ClassVar[bool] = True
    symplectic = False
    geometric = True

    def stepper(self, system: LieSystem, h: float) -> Stepper:
        # The arithmetic is done on Python floats, inline: on 3-vectors that is several times cheaper than numpy
        # calls (and than Python helper calls), whose fixed cost dominates at this size; arrays are made only to
        # cross into the system. bench_overhead.py measures the result: ~0.7x the time of a hand-written RKMK4 loop
        # in numpy arithmetic, ~1.2x one fully unrolled on floats.
        accel, retract, array = system.accel, system.retract, np.array
        # Per stage, then once more for the update: the combination sum_j c_j (T_j, K_j) over the non-zero
        # coefficients c_j = h a_ij (or h b_j) as its first (j, c_j) and the rest (zeros cost nothing; the first term
        # initialises the sums), the stage's time offset c_i h (the update's is unused), and whether it is the update.
        # A stage with no terms (theta = 0) has j = None.
        plan = []
        nodes = self.tableau.c + (1.0,)
        for (coefficients, is_update), node in zip([(row, False) for row in self.tableau.a] + [(self.tableau.b, True)],
                                                   nodes):
            pairs = [(j, h * a) for j, a in enumerate(coefficients) if a != 0.0] or [(None, 0.0)]
            plan.append((*pairs[0], tuple(pairs[1:]), node * h, is_update))
        plan = tuple(plan)
        munthe_kaas = self.munthe_kaas

        def step(t, g, v):
            v0, v1, v2 = v.tolist()
            slopes = []  # per stage: (T_i, K_i) as 6 floats
            for j, c, rest, offset, is_update in plan:
                if j is None:  # theta = 0, dv = 0: the stage is the current state itself, T = v
                    k0, k1, k2 = accel(t + offset, g, v).tolist()
                    slopes.append((v0, v1, v2, k0, k1, k2))
                    continue
                s0, s1, s2, s3, s4, s5 = slopes[j]  # theta = sum c T_j, dv = sum c K_j
                t0, t1, t2, d0, d1, d2 = c * s0, c * s1, c * s2, c * s3, c * s4, c * s5
                for j, c in rest:
                    s0, s1, s2, s3, s4, s5 = slopes[j]
                    t0 += c * s0
                    t1 += c * s1
                    t2 += c * s2
                    d0 += c * s3
                    d1 += c * s4
                    d2 += c * s5
                if is_update:
                    break
                u0, u1, u2 = v0 + d0, v1 + d1, v2 + d2
                k0, k1, k2 = accel(t + offset, retract(g, array((t0, t1, t2))), array((u0, u1, u2))).tolist()
                if munthe_kaas:  # T = dexp^-1_theta(u) = u + 1/2 theta x u + c theta x (theta x u), closed form
                    c0, c1, c2 = t1 * u2 - t2 * u1, t2 * u0 - t0 * u2, t0 * u1 - t1 * u0
                    e0, e1, e2 = t1 * c2 - t2 * c1, t2 * c0 - t0 * c2, t0 * c1 - t1 * c0
                    phi2 = t0 * t0 + t1 * t1 + t2 * t2
                    k = (1.0 / 12.0 + phi2 * (1.0 / 720.0 + phi2 * (1.0 / 30240.0 + phi2 / 1209600.0))
                         if phi2 < DEXP_SERIES_BELOW else dexp_coefficient(phi2))  # inline: the usual, small theta
                    u0, u1, u2 = u0 + 0.5 * c0 + k * e0, u1 + 0.5 * c1 + k * e1, u2 + 0.5 * c2 + k * e2
                slopes.append((u0, u1, u2, k0, k1, k2))
            return retract(g, array((t0, t1, t2))), array((v0 + d0, v1 + d1, v2 + d2))

        return step

    def batch_stepper(self, system: BatchLieSystem, h: float) -> Stepper:
        # The same stages in numpy arithmetic on (N, 3) arrays: for a large ensemble the fixed cost of each numpy call
        # is shared by all members, and the N accelerations of a stage are one call into the engine.
        accel, retract, cross = system.accel, system.retract, np.cross
        plan = tuple((tuple((j, h * a) for j, a in enumerate(coefficients) if a != 0.0), node * h, is_update)
                     for (coefficients, is_update), node in zip(
                         [(row, False) for row in self.tableau.a] + [(self.tableau.b, True)], self.tableau.c + (1.0,)))
        munthe_kaas = self.munthe_kaas

        def step(t, g, v):
            slopes = []  # per stage: (T_i, K_i), each (N, 3)
            for pairs, offset, is_update in plan:
                if not pairs:  # theta = 0, dv = 0: the stage is the current state itself, T = v
                    slopes.append((v, accel(t + offset, g, v)))
                    continue
                (j, c), rest = pairs[0], pairs[1:]
                theta, dv = c * slopes[j][0], c * slopes[j][1]
                for j, c in rest:
                    theta = theta + c * slopes[j][0]
                    dv = dv + c * slopes[j][1]
                if is_update:
                    return retract(g, theta), v + dv
                u = v + dv
                k = accel(t + offset, retract(g, theta), u)
                if munthe_kaas:  # T = dexp^-1_theta(u) = u + 1/2 theta x u + c theta x (theta x u), closed form
                    c1 = cross(theta, u)
                    coefficient = dexp_coefficients(np.einsum("ij,ij->i", theta, theta))
                    u = u + 0.5 * c1 + coefficient[:, None] * cross(theta, c1)
                slopes.append((u, k))
            raise AssertionError("a tableau's plan ends with its update")

        return step


class Euler(ExplicitRK):
    name = "euler"
    order = 1
    tableau = EULER_TABLEAU
    description = "explicit Euler on the group: g exp(h v), v + h a(t, g, v)"


class RK4(ExplicitRK):
    name = "rk4"
    order = 4
    tableau = CLASSICAL_RK4
    description = "Runge–Kutta–Munthe-Kaas with the classical RK4 tableau (MuJoCo 4's RK4 on a ball joint)"


class RK4Naive(ExplicitRK):
    name = "rk4_naive"
    order = 2  # the classical tableau without dexp^-1: stage rotations do not commute, the 3rd-order terms are lost
    tableau = CLASSICAL_RK4
    munthe_kaas = False
    description = "classical RK4 tableau through retract without the dexp^-1 correction: only 2nd order on the group"


class SymplecticEuler(Integrator):
    """Velocity first, then attitude with the new velocity: MuJoCo's Euler on a ball joint (no damping)."""

    name = "symplectic_euler"
    order = 1
    stages = 1
    # Not symplectic here: the gyroscopic term makes the body-frame equations non-separable, and the velocity update
    # is explicit Euler on the Lie–Poisson part (for a free body |I v| grows by O(h^2) each step).
    symplectic = False
    geometric = True
    description = "semi-implicit Euler, velocity first: v + h a(t, g, v), then g exp(h v_new) (MuJoCo's Euler)"

    def step(self, system: LieSystem, t: float, g: object, v: np.ndarray, h: float) -> tuple[object, np.ndarray]:
        v = v + h * system.accel(t, g, v)
        return system.retract(g, h * v), v

    def batch_stepper(self, system: BatchLieSystem, h: float) -> Stepper:
        return lambda t, g, v: self.step(system, t, g, v, h)  # the same numpy expressions serve (N, 3) arrays
