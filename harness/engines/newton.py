"""Newton adapter: the body in a Newton model on Warp's CPU device, stepped by Newton's solvers in float32 (the optional
extra `stereodyn[newton]`; without it the engine's rows are skipped naming the install command).

Two models, named in the formulation column:
* `ball`: one link on a ball joint at O, gravity g d. Newton's ball joint takes its velocity (joint_qd) as the angular
  velocity in the parent's frame, here the world's (measured: a body-frame omega is off by O(1)); its quaternion is
  (x, y, z, w).
* `free`: a free joint, for a body whose centre of mass is O: the pin's reaction then cancels the weight, so the
  model has no gravity; other cases skip it.
States are read from body_q (position, quaternion xyzw) and body_qd ((v_com, omega) in world components): omega_body
= R^T omega_world.

Solvers (the integrator column): `featherstone` (articulated, reduced coordinates; its ball joint is semi-implicit
Euler with a first-order quaternion update), `semi_implicit` (maximal coordinates, joints as penalty springs) and
`xpbd` (position-based). Each solver's angular damping is set to 0 (Newton's default is 0.05 for featherstone and
semi_implicit), joints have no armature, damping or friction. A step launched from Python costs ~1 ms on the CPU
(~80 kernel launches); prepare compiles the kernels (a minute at first, then Warp's kernel cache serves) and captures
one step as a Warp graph (CPU capture): a run replays it, 1-30 µs a step.

External torques are not applied (the run is skipped with the reason): Newton takes them as joint or body forces set
between steps, which the captured step would have to leave every step. Precision: float32 only (Newton's arrays).
"""
from __future__ import annotations

import math

import numpy as np

INSTALL = "pip install 'stereodyn[newton]'"
try:
    import newton
    import warp as wp
except ImportError as exc:  # the registry turns this into skipped rows whose reason is this message
    raise ImportError(f"{exc}; install the extra: {INSTALL}") from exc

from .. import budget
from ..scenes.cases import Case, unphysical_inertia
from .base import FLOAT32, Engine, precession_singular
from ..grid import TimeGrid
from ..trajectory import Status, Trajectory, divergence_message, first_bad_sample
from ...reference.rotations import quat_to_matrix

# Warp prints its device table and, at its default log level, a line for every module it loads
wp.config.quiet = True
wp.config.log_level = max(wp.config.log_level, wp.LOG_WARNING)
DEVICE = "cpu"
BALL, FREE = "ball", "free"
MODELS = (BALL, FREE)
SOLVERS = {"featherstone": "SolverFeatherstone", "semi_implicit": "SolverSemiImplicit", "xpbd": "SolverXPBD"}
# What each solver is (harness.engines.methods): featherstone's ball joint updates the velocity first; its quaternion
# update is first order (q + dt/2 omega q, renormalised), not the exponential map, so it agrees with the other
# semi-implicit Eulers only to O(dt) (measured 8e-5 rad after 200 steps of 1e-2 s against MuJoCo's euler).
METHODS: dict[str, str] = {}
# The default sweep: the general cases at their coarsest dt (the captured step is cheap, but a worker pays Warp's
# module loading, and float32 needs no fine steps to show its floor); every solver, both models where allowed.
DEFAULT_CASES = ("free-asymmetric", "lagrange-top", "kovalevskaya", "heavy-asymmetric")
COARSE_DT = 1e-2


class NewtonSimulation:
    """A case's Newton model and solver with one step captured as a Warp graph; run() resets the state."""

    def __init__(self, case: Case, model: str, solver: str, dt: float):
        self.case, self.dt = case, float(dt)
        body = case.body
        builder = newton.ModelBuilder(gravity=(0.0, 0.0, 0.0))
        inertia = np.asarray(body.inertia_com, dtype=float)
        link = builder.add_link(xform=wp.transform_identity(), com=wp.vec3(*np.asarray(body.com, dtype=float)),
                                inertia=wp.mat33(*inertia.ravel()), mass=float(body.mass))
        quat = np.asarray(case.quat0, dtype=float)
        omega_world = quat_to_matrix(quat) @ np.asarray(case.omega0, dtype=float)
        xyzw = [quat[1], quat[2], quat[3], quat[0]]
        if model == BALL:
            joint = builder.add_joint_ball(-1, link, armature=0.0, damping=0.0, friction=0.0)
            builder.joint_q[0:4], builder.joint_qd[0:3] = xyzw, list(omega_world)
        else:
            joint = builder.add_joint_free(link)
            builder.joint_q[0:7], builder.joint_qd[0:6] = [0.0, 0.0, 0.0, *xyzw], [0.0, 0.0, 0.0, *omega_world]
        builder.add_articulation([joint])
        self.model = builder.finalize(device=DEVICE)
        gravity = body.gravity * np.asarray(body.gravity_direction, dtype=float) if model == BALL else np.zeros(3)
        self.model.set_gravity(tuple(gravity.tolist()))
        self.solver = getattr(newton.solvers, SOLVERS[solver])(self.model, angular_damping=0.0)
        self.state, self.next, self.control = self.model.state(), self.model.state(), self.model.control()
        self.reset()
        self.solver.step(self.state, self.next, self.control, None, self.dt)  # compiles (or loads) the kernels
        self.reset()
        with wp.ScopedCapture(device=DEVICE) as capture:  # one step, its result copied back into self.state
            self.solver.step(self.state, self.next, self.control, None, self.dt)
            for name in ("body_q", "body_qd", "joint_q", "joint_qd"):
                wp.copy(getattr(self.state, name), getattr(self.next, name))
        self.graph = capture.graph

    def reset(self) -> None:
        """The state back at the case's initial joint coordinates and the bodies' poses from them."""
        self.state.joint_q.assign(self.model.joint_q)
        self.state.joint_qd.assign(self.model.joint_qd)
        newton.eval_fk(self.model, self.model.joint_q, self.model.joint_qd, self.state)

    def run(self, grid: TimeGrid) -> Trajectory:
        if grid.dt != self.dt:
            raise ValueError(f"grid dt {grid.dt} differs from the prepared dt {self.dt}")
        self.reset()
        launch, graph = wp.capture_launch, self.graph
        body_q, body_qd = self.state.body_q, self.state.body_qd
        samples = grid.sample_steps.tolist()
        poses = np.full((len(samples), 7), np.nan)
        twists = np.full((len(samples), 6), np.nan)
        poses[0], twists[0] = body_q.numpy()[0], body_qd.numpy()[0]
        recorded = len(samples)
        for i in range(1, len(samples)):  # the hot loop: graph replays, one state read a sample
            for piece in budget.pieces(samples[i - 1], samples[i]):  # the run's wall-time budget
                for _ in piece:
                    launch(graph)
            wp.synchronize_device(DEVICE)
            poses[i], twists[i] = body_q.numpy()[0], body_qd.numpy()[0]
            if not (np.isfinite(poses[i]).all() and np.isfinite(twists[i]).all()):
                recorded = i + 1  # NaN from here on: no need to step further
                break
        with np.errstate(invalid="ignore", over="ignore"):
            quat = poses[:, [6, 3, 4, 5]].astype(float)
            omega = np.einsum("nji,nj->ni", quat_to_matrix(quat), twists[:, 3:6].astype(float))
        quat[recorded:], omega[recorded:] = np.nan, np.nan
        first = first_bad_sample(omega, quat, self.case.omega0)
        if first is None:
            return Trajectory(grid.times, quat, omega, Status.OK, "", math.nan, grid.steps, grid.steps)
        quat[first:] = np.nan
        omega[first:] = np.nan
        diverged_at = float(grid.times[first])
        return Trajectory(grid.times, quat, omega, Status.DIVERGED, divergence_message(diverged_at), diverged_at,
                          samples[first], samples[first])


class NewtonEngine(Engine):
    """Newton's solvers (featherstone, semi_implicit, xpbd) on a ball or free joint, float32 on Warp's CPU device."""

    name = "newton"
    default_formulation = BALL
    # measured: 1-30 µs per replayed step on the loaded 2-core machine (docs/ENGINES.md)
    pass_us = 10.0
    linestyle = (0, (3, 1, 1, 1))
    packages = ("newton", "warp-lang")

    def formulations(self) -> tuple[str, ...]:
        return MODELS

    def integrators(self) -> tuple[str, ...]:
        return tuple(SOLVERS)

    def precisions(self, integrator: str) -> tuple[str, ...]:
        return (FLOAT32,)

    def in_default_sweep(self, integrator: str) -> bool:
        return integrator in SOLVERS

    def declared_order(self, integrator: str) -> float:
        return 1.0 if integrator in SOLVERS else math.nan

    def method(self, integrator: str) -> str:
        return METHODS.get(integrator, "")

    def unsupported(self, case: Case) -> str | None:
        if case.body.has_external_torque:
            return ("newton adapter applies no external torque: Newton takes it as a force set between steps, which "
                    "the captured step graph would have to leave at every step")
        return unphysical_inertia(case) or precession_singular(case)

    def unsupported_run(self, case: Case, formulation: str, integrator: str) -> str | None:
        if formulation == FREE and np.any(np.asarray(case.body.com) != 0.0):
            return ("free: a free body moves as the pinned one only when O is its centre of mass (com = 0); Newton's "
                    "free joint has no pin")
        return None

    def default_run(self, case: Case, formulation: str, integrator: str) -> bool:
        """The general cases only (DEFAULT_CASES), the free model where the scene allows it."""
        return case.name in DEFAULT_CASES and self.unsupported_run(case, formulation, integrator) is None

    def default_dts(self, case: Case, integrator: str, dts: tuple[float, ...]) -> tuple[float, ...]:
        """One coarse step in a default sweep: the largest of the case's at most COARSE_DT (heavy-asymmetric's 0.3 is
        beyond every Euler variant's stability limit: a diverged row says nothing more than MuJoCo's does)."""
        coarse = [dt for dt in dts if dt <= COARSE_DT]
        return (max(coarse),) if coarse else (min(dts),)

    def prepare(self, case: Case, integrator: str, dt: float | None, formulation: str = BALL,
                precision: str = FLOAT32, **options) -> NewtonSimulation:
        if formulation not in MODELS:
            raise KeyError(f"unknown formulation {formulation!r} for the newton engine; valid: {', '.join(MODELS)}")
        if integrator not in SOLVERS:
            raise KeyError(f"unknown integrator {integrator!r} for the newton engine; valid: {', '.join(SOLVERS)}")
        if precision != FLOAT32:
            raise KeyError(f"unknown precision {precision!r} for the newton engine; valid: {FLOAT32}")
        reason = self.unsupported(case) or self.unsupported_run(case, formulation, integrator)
        if reason:
            raise ValueError(f"{case.name}: {reason}")
        if dt is None or not dt > 0:
            raise ValueError(f"integrator {integrator!r} needs a step dt > 0, got {dt!r}")
        return NewtonSimulation(case, formulation, integrator, dt)
