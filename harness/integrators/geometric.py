"""Geometric integrators beyond the explicit anchors: implicit midpoint (on the group and on a formulation's
coordinates), a Strang splitting around the exact torque-free flow, and the discrete Moser–Veselov scheme.

Implicit midpoint on SO(3) x R^3 (left-trivialised, g' = g v, v' = a(t, g, v)):
    v_bar = v_n + Δ/2,  Δ = h a(t_n + h/2, g_n exp(h v_bar / 2), v_bar),
    g_{n+1} = g_n exp(h v_bar),  v_{n+1} = v_n + Δ.
It is symmetric (the step from (g_{n+1}, v_{n+1}) with -h has the same v_bar and midpoint attitude and returns to the
start), hence of even order, 2. For the torque-free body a(t, g, v) = σ⁻¹(σv × v) does not depend on g: the velocity
update is the midpoint rule on Euler's equations, which conserves every quadratic invariant (energy ½ vᵀσv and |σv|²)
exactly and is a Lie–Poisson integrator (Austin, Krishnaprasad and Wang 1993); with gravity the energy error stays
bounded (no drift), as for a symmetric method on a reversible system. Δ is solved by fixed-point iteration from an
explicit Euler predictor until it stops changing (round-off), and added with compensated summation (Kahan), so the
energy of a long run is not spoilt by the rounding of 1e5 additions of a small increment to v.

The splitting and Moser–Veselov need the body itself: they read `system.body` (a reference.body.RigidBody), which the
Pinocchio engine provides; a system without it, or a body with a torque other than uniform gravity, fails the run
with a message saying so.
"""
from __future__ import annotations

import math
from typing import ClassVar

import numpy as np

from .base import Integrator, LieSystem, Stepper, StepperIntegrator
from .vector import VectorRK, VectorSystem
from ...reference.body import RigidBody
from ...reference.torque_free import free_motion  # the free flow's module, not every exact solution's

# Fixed-point iteration: stop when the increment changes by at most this many ulps of its size (round-off); give up
# after MAX_ITERATIONS (the contraction factor is ~h |∂a/∂v| / 2: well below 1/2 wherever the step resolves the
# motion, so 60 iterations are 60 halvings at worst) and end the run as diverged.
CONVERGED_ULPS = 4.0
MAX_ITERATIONS = 60
EPS = float(np.finfo(float).eps)

IDENTITY_WXYZ = np.array([1.0, 0.0, 0.0, 0.0])


class NotConverged(ArithmeticError):
    """The implicit equation of a step has no fixed point the iteration could reach: the step is too large."""


def _quat_to_rotvec(w: float, x: float, y: float, z: float) -> np.ndarray:
    """The rotation vector (rad) of a unit quaternion (w, x, y, z), the shorter way round."""
    if w < 0.0:
        w, x, y, z = -w, -x, -y, -z
    s = math.sqrt(x * x + y * y + z * z)
    if s == 0.0:
        return np.zeros(3)
    angle = 2.0 * math.atan2(s, w)
    return np.array((x, y, z)) * (angle / s)


def _body_of(system, name: str) -> RigidBody:
    body = getattr(system, "body", None)
    if not isinstance(body, RigidBody):
        raise TypeError(f"integrator {name!r} needs a system that exposes its body (system.body, a RigidBody)")
    if body.has_external_torque:
        raise ValueError(f"integrator {name!r} models uniform gravity only; this body has another external torque")
    return body


class ImplicitMidpoint(StepperIntegrator):
    name = "implicit_midpoint"
    order = 2
    stages = 1  # accel evaluations per fixed-point iteration, the least a step makes (iterative: rhs_evals counts all)
    # Not symplectic on T*SO(3): the attitude moves by exp(h v_bar) while the velocity update is the midpoint (Cayley)
    # rule, so the one-step map's defect |J^T Omega J - Omega| scales as h^3 (measured on heavy-asymmetric: 6.7e-3,
    # 7.8e-4, 9.5e-5 at h = 0.2, 0.1, 0.05; strang_free_flow's is 2e-11 at each), harness.integrators.properties.
    symplectic = False
    geometric = True
    symmetric = True
    casimir_preserving = True
    iterative = True
    energy_bounded = True
    default_sweep = False
    description = ("implicit midpoint on the group: v_bar = v + Δ/2, Δ = h a(g exp(h v_bar/2), v_bar), g exp(h v_bar); "
                   "symmetric, order 2; solved by fixed-point iteration to round-off")

    def stepper(self, system: LieSystem, h: float) -> Stepper:
        accel, retract, array = system.accel, system.retract, np.array
        half = 0.5 * h
        carry = [0.0, 0.0, 0.0]  # Kahan compensation of v; a fresh stepper (a fresh run) starts from zero

        def step(t, g, v):
            v0, v1, v2 = v.tolist()
            d0, d1, d2 = (h * a for a in accel(t, g, v).tolist())  # explicit Euler predictor
            mid = t + half
            for _ in range(MAX_ITERATIONS):
                m0, m1, m2 = v0 + 0.5 * d0, v1 + 0.5 * d1, v2 + 0.5 * d2
                n0, n1, n2 = (h * a for a in accel(mid, retract(g, array((half * m0, half * m1, half * m2))),
                                                     array((m0, m1, m2))).tolist())
                change = abs(n0 - d0) + abs(n1 - d1) + abs(n2 - d2)
                d0, d1, d2 = n0, n1, n2
                if change <= CONVERGED_ULPS * EPS * (abs(d0) + abs(d1) + abs(d2)) or change == 0.0:
                    break
            else:
                if not change <= 1e3 * EPS * (abs(d0) + abs(d1) + abs(d2) + 1e-300):  # round-off cycling is fine
                    raise NotConverged(f"implicit midpoint: no fixed point reached in {MAX_ITERATIONS} iterations "
                                       f"(step h = {h:g} s too large)")
            m0, m1, m2 = v0 + 0.5 * d0, v1 + 0.5 * d1, v2 + 0.5 * d2
            g_next = retract(g, array((h * m0, h * m1, h * m2)))
            out = []
            for i, (x, d) in enumerate(((v0, d0), (v1, d1), (v2, d2))):  # Kahan: v + Δ, keeping the lost low bits
                y = d - carry[i]
                t = x + y
                carry[i] = (t - x) - y
                out.append(t)
            return g_next, array(out)

        return step


class ImplicitMidpointVector(VectorRK):
    """Implicit midpoint on a formulation's coordinates: y + Δ, Δ = h f(t + h/2, chart, y + Δ/2). On gibbs_hamiltonian
    (canonical coordinates) it is symplectic; on the quaternion formulation it conserves |q|² and, for the free body,
    the energy exactly (quadratic invariants)."""

    name = "implicit_midpoint"
    order = 2
    stages = 1  # per fixed-point iteration, as on the group
    symplectic = True  # checked on gibbs_hamiltonian, canonical coordinates
    geometric = False
    symmetric = True
    casimir_preserving = True
    iterative = True
    energy_bounded = True
    default_sweep = False
    state_space = "vector"
    description = "implicit midpoint on the formulation's coordinates, fixed-point iteration to round-off"

    def stepper(self, system: VectorSystem, h: float) -> Stepper:
        rhs, rechart = system.rhs, system.rechart
        state = {"chart": None, "carry": None}

        def step(t, chart, y):
            delta = h * rhs(t, chart, y)
            mid = t + 0.5 * h
            for _ in range(MAX_ITERATIONS):
                new = h * rhs(mid, chart, y + 0.5 * delta)
                change = float(np.abs(new - delta).sum())
                delta = new
                size = float(np.abs(delta).sum())
                if change <= CONVERGED_ULPS * EPS * size or change == 0.0:
                    break
            else:
                if not change <= 1e3 * EPS * (size + 1e-300):
                    raise NotConverged(f"implicit midpoint: no fixed point reached in {MAX_ITERATIONS} iterations "
                                       f"(step h = {h:g} s too large)")
            carry = state["carry"] if state["chart"] is chart else np.zeros_like(y)
            corrected = delta - carry
            out = y + corrected
            new_chart, out2 = rechart(chart, out)
            # The compensation is valid only while the coordinates stay in one chart.
            state["carry"] = (out - y) - corrected if new_chart is chart else np.zeros_like(y)
            state["chart"] = new_chart
            return new_chart, out2

        return step


class StrangSplitting(StepperIntegrator):
    """Strang splitting: half a gravity kick, the exact torque-free flow over h (reference.torque_free.free_motion),
    half a kick. The kick is exact (the gravity torque depends on the attitude only: v += τ σ⁻¹ τ_g(g) = τ a(t, g, 0)).
    Symmetric, order 2; exact (to round-off) for the torque-free body."""

    name = "strang_free_flow"
    order = 2
    stages = 2  # accel evaluations per step (two half kicks; none on a torque-free body); the free flow is an
    # elliptic-function evaluation
    symplectic = True
    geometric = True
    symmetric = True
    casimir_preserving = True
    energy_bounded = True
    default_sweep = False
    description = "Strang splitting: half gravity kick, exact torque-free flow (Jacobi elliptic functions), half kick"

    def stepper(self, system: LieSystem, h: float) -> Stepper:
        body = _body_of(system, self.name)
        free = RigidBody(body.inertia, body.mass, body.com)  # the same body without gravity
        heavy = body.has_gravity
        accel, retract, zero = system.accel, system.retract, np.zeros(3)
        times = np.array([h])

        def step(t, g, v):
            if heavy:
                v = v + 0.5 * h * accel(t, g, zero)
            quat, omega = free_motion(free, IDENTITY_WXYZ, v).evaluate(times)
            g = retract(g, _quat_to_rotvec(*quat[0].tolist()))
            v = np.array(omega[0], dtype=float)
            if heavy:
                v = v + 0.5 * h * accel(t + h, g, zero)
            return g, v

        return step


class MoserVeselov(StepperIntegrator):
    """The discrete Moser–Veselov scheme for the torque-free body (equivalent to RATTLE on SO(3)): find the body
    increment Q with h m̂ = Q J − J Qᵀ, J = ½ tr(σ) 1 − σ, m = σv; then g Q and m ← Qᵀ m. With Q the unit quaternion
    (s, u) the equation reads h m = 2 s σu + 2 u × σu, solved for u by fixed-point iteration to round-off. Symplectic,
    order 2; the spatial angular momentum R m is conserved exactly, the energy error is bounded."""

    name = "moser_veselov"
    order = 2
    stages = 0  # it calls no accel (it solves with the inertia): counted, its rhs_evals are 0
    symplectic = True
    geometric = True
    symmetric = True
    casimir_preserving = True
    energy_bounded = True
    default_sweep = False
    description = "discrete Moser–Veselov (RATTLE on SO(3)) for the torque-free body; order 2, symplectic"

    def stepper(self, system: LieSystem, h: float) -> Stepper:
        body = _body_of(system, self.name)
        if body.has_gravity:
            raise ValueError(f"integrator {self.name!r} is for the torque-free body; this one is in uniform gravity")
        sigma = np.array(body.inertia, dtype=float)
        sigma_inv = np.linalg.inv(sigma)
        retract = system.retract

        def step(t, g, v):  # torque-free: nothing depends on t
            m = sigma @ v
            half_hm = 0.5 * h * m
            u = sigma_inv @ half_hm  # s = 1, no cross term: the first-order guess
            for _ in range(MAX_ITERATIONS):
                s = math.sqrt(max(0.0, 1.0 - float(u @ u)))
                if s == 0.0:
                    raise NotConverged(f"Moser–Veselov: no rotation solves the step (h = {h:g} s too large)")
                new = sigma_inv @ (half_hm - np.cross(u, sigma @ u)) / s
                change = float(np.abs(new - u).sum())
                u = new
                if change <= CONVERGED_ULPS * EPS * float(np.abs(u).sum()) or change == 0.0:
                    break
            else:
                raise NotConverged(f"Moser–Veselov: no fixed point reached in {MAX_ITERATIONS} iterations "
                                   f"(h = {h:g} s too large)")
            s = math.sqrt(max(0.0, 1.0 - float(u @ u)))
            q = (s, *u.tolist())
            g = retract(g, _quat_to_rotvec(*q))
            # m_{k+1} = Qᵀ m_k: rotate m by the conjugate quaternion (s, -u)
            t = 2.0 * np.cross(-u, m)
            m_next = m + s * t + np.cross(-u, t)
            return g, sigma_inv @ m_next

        return step


GEOMETRIC: tuple[type[Integrator], ...] = (ImplicitMidpoint, ImplicitMidpointVector, StrangSplitting, MoserVeselov)
