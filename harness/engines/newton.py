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

External torques (reference.torques) are evaluated in Python at the start of every step from the step's time and
state and written, as the world-frame moment R M, into the state's body_f, which the captured step reads on every
replay (torque_mode `step`, harness.engines.stepping). Precision: float32 only (Newton's arrays).
"""
from __future__ import annotations

import functools
import math

import numpy as np

from .. import install
from .base import FLOAT32, RIGID_BODY, About, Engine, Offer, Timing, singular_torque, require_modules
from .quiet import native_output_silenced

INSTALL = install.hint("newton")  # a checkout's or a distribution's form
require_modules(INSTALL, "newton", "warp")  # imported on the first prepare (_sdk): 4-8 s

from ..scenes.cases import Case, unphysical_inertia
from .stepping import SteppedRigidBody, run_steps
from ..grid import TimeGrid
from ..trajectory import Trajectory
from ...reference.rotations import quat_to_matrix
from ...reference.torques import torque_function

DEVICE = "cpu"
BALL, FREE = "ball", "free"
MODELS = (BALL, FREE)
SOLVERS = {"featherstone": "SolverFeatherstone", "semi_implicit": "SolverSemiImplicit", "xpbd": "SolverXPBD"}
# What each solver is (harness.engines.methods): featherstone's ball joint updates the velocity first; its quaternion
# update is first order (q + dt/2 omega q, renormalised), not the exponential map, so it agrees with the other
# semi-implicit Eulers only to O(dt) (measured 8e-5 rad after 200 steps of 1e-2 s against MuJoCo's euler).
METHODS: dict[str, str] = {}
# The orders claimed: featherstone's first-order step (measured 1.02 on lagrange-top). Newton documents no order for
# semi_implicit and xpbd, and the default run's ladders measure none to claim (float32, 2 idle cores): xpbd's attitude
# error does not fall with dt (kovalevskaya 0.35 rad at dt 1.25e-4 and 6.25e-5 over 2.5 s; lagrange-top 0.24), and
# semi_implicit's penalty joint has a floor near 1.6e-2 rad (free-asymmetric over 10 s: 0.034, 0.020, 0.016, 0.019,
# 0.029 at dt 8e-3 ... 5e-4). No claim, so no order verdict; convergence.csv still reports what a ladder fits.
ORDERS = {"featherstone": 1.0}
# The default sweep: the general cases at their coarsest dt (the captured step is cheap, but a worker pays Warp's
# module loading, and float32 needs no fine steps to show its floor); every solver, both models where allowed.


@functools.cache
def _sdk():
    """(newton, warp), imported; Warp quiet (its device table and, at its default log level, a line for every module
    it loads)."""
    import newton
    import warp as wp

    wp.config.quiet = True
    wp.config.log_level = max(wp.config.log_level, wp.LOG_WARNING)
    with native_output_silenced():  # without a GPU, Warp's C code prints a CUDA-driver warning to fd 2 at init
        wp.init()
    return newton, wp


class NewtonSimulation:
    """A case's Newton model and solver with one step captured as a Warp graph; run() resets the state."""

    def __init__(self, case: Case, model: str, solver: str, dt: float):
        newton, wp = self.newton, self.wp = _sdk()
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
        # numpy views of the state's arrays (Warp's CPU arrays share their memory): the pose (position, quaternion
        # xyzw), the twist ((v, omega) world), the external wrench ((f, moment) world) the captured step reads
        self.pose, self.twist = self.state.body_q.numpy()[0], self.state.body_qd.numpy()[0]
        self.wrench = self.state.body_f.numpy()[0]
        self.torque = torque_function(body)

    def reset(self) -> None:
        """The state back at the case's initial joint coordinates and the bodies' poses from them, no external
        torque."""
        self.state.joint_q.assign(self.model.joint_q)
        self.state.joint_qd.assign(self.model.joint_qd)
        self.newton.eval_fk(self.model, self.model.joint_q, self.model.joint_qd, self.state)
        self.state.body_f.zero_()

    def step(self) -> None:
        self.wp.capture_launch(self.graph)

    def read(self) -> tuple[tuple, tuple]:
        """(quaternion wxyz, omega in body components) as floats, from body_q (xyzw) and body_qd's world omega."""
        self.wp.synchronize_device(DEVICE)
        x, y, z, w = self.pose[3:7].tolist()
        quat = (w, x, y, z)
        return quat, _rotate(quat, self.twist[3:6].tolist(), inverse=True)

    def apply(self, moment: tuple) -> None:
        """The torque (body components) as the body's external wrench of the next step (body_f: world frame, a pure
        moment)."""
        w, x, y, z = self.pose[[6, 3, 4, 5]].tolist()
        self.wrench[3:6] = _rotate((w, x, y, z), moment)

    def run(self, grid: TimeGrid) -> Trajectory:
        if grid.dt != self.dt:
            raise ValueError(f"grid dt {grid.dt} differs from the prepared dt {self.dt}")
        self.reset()
        return run_steps(self, grid, self.case.omega0, self.torque)


def _rotate(quat: tuple, v, inverse: bool = False) -> tuple:
    """R v (R^T v with inverse) for the unit quaternion (w, x, y, z), in float arithmetic (a per-step path):
    v + 2 w (u x v) + 2 u x (u x v), u = (x, y, z) (-u for R^T)."""
    w, x, y, z = quat
    if inverse:
        x, y, z = -x, -y, -z
    a, b, c = v
    tx, ty, tz = 2.0 * (y * c - z * b), 2.0 * (z * a - x * c), 2.0 * (x * b - y * a)
    return (a + w * tx + y * tz - z * ty, b + w * ty + z * tx - x * tz, c + w * tz + x * ty - y * tx)


class NewtonEngine(Engine):
    """Newton's solvers (featherstone, semi_implicit, xpbd) on a ball or free joint, float32 on Warp's CPU device."""

    name = "newton"
    # measured: 1-30 µs per replayed step on the loaded 2-core machine (docs/ENGINES.md). startup_s: a fresh process's
    # first prepare (Warp's kernels for Newton) took 44 s with the kernel cache cold and 5.3 s warm (2 cores, issue 29):
    # 20 s between.
    timing = Timing(pass_us=10.0, startup_s=20.0)
    about = About(packages=("newton", "warp-lang"), linestyle=(0, (3, 1, 1, 1)), formulation=BALL)

    def integrators(self) -> tuple[str, ...]:
        return tuple(SOLVERS)

    def offer(self, integrator: str) -> Offer:
        return Offer(order=ORDERS.get(integrator, math.nan), method=METHODS.get(integrator, ""),
                     default_sweep=integrator in SOLVERS, precisions=(FLOAT32,))

    def unsupported(self, case: Case) -> str | None:
        return unphysical_inertia(case) or singular_torque(case)

    def models(self) -> dict:
        return {**super().models(), RIGID_BODY: SteppedRigidBody(self, MODELS, FREE, "Newton's free joint has no pin")}

    def prepare(self, case: Case, integrator: str, dt: float | None, formulation: str = BALL,
                precision: str = FLOAT32, **options) -> NewtonSimulation:
        if formulation not in MODELS:
            raise KeyError(f"unknown formulation {formulation!r} for the newton engine; valid: {', '.join(MODELS)}")
        if integrator not in SOLVERS:
            raise KeyError(f"unknown integrator {integrator!r} for the newton engine; valid: {', '.join(SOLVERS)}")
        if precision != FLOAT32:
            raise KeyError(f"unknown precision {precision!r} for the newton engine; valid: {FLOAT32}")
        reason = self.unsupported(case) or self.models()[RIGID_BODY].unsupported_run(case, formulation, integrator)
        if reason:
            raise ValueError(f"{case.name}: {reason}")
        if dt is None or not dt > 0:
            raise ValueError(f"integrator {integrator!r} needs a step dt > 0, got {dt!r}")
        return NewtonSimulation(case, formulation, integrator, dt)
