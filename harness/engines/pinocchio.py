"""Pinocchio adapter: the body on a spherical joint, stepped by the harness's own Lie-group integrators.

Pinocchio has no time stepper; it supplies the dynamics (articulated-body algorithm) and the group operation.
Its configuration q is a quaternion stored (x, y, z, w); v and tau are body-frame angular velocity and torque.
External torques (reference.torques) enter as tau, evaluated at every stage of the integrator at the stage's time
t + c_i h (torque_mode "stage"), so a torque that depends on time (a central field whose direction turns) is modelled.
"""
from __future__ import annotations

import dataclasses
import functools
import math
from xml.sax.saxutils import quoteattr

import numpy as np
import pinocchio as pin

from .. import integrators
from .. import budget
from ..scenes.cases import Case
from ..trajectory import SlidingLadderTrajectory, Status, Trajectory
from .base import RIGID_BODY, SLIDING_LADDER, About, Engine, RigidBodyModel, SceneModel, Timing, singular_torque
from ..grid import TimeGrid
from ..integrators.base import check_stepper
from ..integrators.ensemble import integrate_ensemble
from ...reference import sliding_ladder as ref_ladder
from ...reference.torques import torque_function


class PinocchioSystem:
    """The LieSystem of one model: g = q (4,) (x, y, z, w); v (3,) rad/s body frame.

    accel and retract are bound once here, as a closure and a C-level partial, rather than methods: on the hot path
    that saves attribute lookups per call and, for retract, a Python frame (a few percent of an RK4 step).
    """

    def __init__(self, model: "pin.Model", torque=None):
        self.model = model
        self.data = data = model.createData()
        tau, aba, array = np.zeros(model.nv), pin.aba, np.array

        def accel(t: float, q: np.ndarray, v: np.ndarray) -> np.ndarray:
            """v' (3,) rad/s^2, body frame. pin.aba returns a fresh array (not a view of data.ddq)."""
            return aba(model, data, q, v, tau)

        def accel_torqued(t: float, q: np.ndarray, v: np.ndarray) -> np.ndarray:
            """As accel, with the external torque of this stage's time and state as tau."""
            x, y, z, w = q.tolist()
            return aba(model, data, q, v, array(torque(t, (w, x, y, z), v.tolist())))

        if torque is not None:
            accel = accel_torqued

        self.accel = accel
        self.retract = functools.partial(pin.integrate, model)  # q (x) exp(theta), theta (3,) rad body frame


class PinocchioBatchSystem:
    """The BatchLieSystem of one model (harness.integrators.base): g (N, 4) quaternions (x, y, z, w), one per row;
    v (N, 3) rad/s body frame. accel is one pin.abaInParallel call over the rows on `threads` threads; retract is
    pin.integrate's q (x) exp(theta) with its first-order renormalisation, in numpy arithmetic."""

    def __init__(self, model: "pin.Model", threads: int, torque=None):
        pool = pin.ModelPool(model, threads)
        aba = pin.abaInParallel

        def accel(t: float, q: np.ndarray, v: np.ndarray) -> np.ndarray:
            # abaInParallel wants (nq, N) column-major blocks: the transpose of a C-ordered (N, nq) array is one,
            # without a copy, and writing into out.T fills out.
            q, v = np.ascontiguousarray(q), np.ascontiguousarray(v)
            tau = np.zeros_like(v) if torque is None else np.array(
                [torque(t, (w, x, y, z), omega) for (x, y, z, w), omega in zip(q.tolist(), v.tolist())])
            out = np.empty_like(v)
            aba(threads, pool, q.T, v.T, tau.T, out.T)
            return out

        self.accel = accel
        self.retract = retract_rows


def retract_rows(q: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """q (x) exp(theta) row by row, (N, 4) xyzw and (N, 3) rad, renormalised to first order as pin.integrate does."""
    angle = np.sqrt(np.einsum("ij,ij->i", theta, theta))
    half_sinc = 0.5 * np.sinc(angle / (2.0 * np.pi))  # sin(angle / 2) / angle, exact at 0
    ex, ey, ez = (theta * half_sinc[:, None]).T
    ew = np.cos(0.5 * angle)
    x, y, z, w = q.T
    out = np.column_stack((w * ex + x * ew + y * ez - z * ey, w * ey - x * ez + y * ew + z * ex,
                           w * ez + x * ey - y * ex + z * ew, w * ew - x * ex - y * ey - z * ez))
    out *= (1.5 - 0.5 * np.einsum("ij,ij->i", out, out))[:, None]
    return out


def record(q: np.ndarray) -> tuple[float, float, float, float]:
    """Pinocchio's (x, y, z, w) as the harness's (w, x, y, z)."""
    x, y, z, w = q.tolist()
    return w, x, y, z


def build_model(case: Case) -> "pin.Model":
    """One body on a spherical joint at the origin; inertia about the centre of mass (Pinocchio's Inertia wants it)."""
    body = case.body
    model = pin.Model()
    joint = model.addJoint(0, pin.JointModelSpherical(), pin.SE3.Identity(), "ball")
    model.appendBodyToJoint(joint, pin.Inertia(float(body.mass), np.array(body.com, dtype=float),
                                               np.array(body.inertia_com, dtype=float)), pin.SE3.Identity())
    model.gravity.linear = body.gravity * np.asarray(body.gravity_direction, dtype=float)
    return model


def _comment(name: str) -> str:
    """A case name inside an XML comment, which may not hold "--" (nor end in "-")."""
    return '"' + name.replace("-", "\N{HYPHEN}") + '"' if "--" in name or name.endswith("-") else f'"{name}"'


def urdf(case: Case) -> str:
    """build_model's body as URDF, to open in Pinocchio (buildModelFromUrdf) or other URDF tools.

    URDF has no spherical joint. A floating joint would free the fixed point, so the ball joint is a gimbal: three
    continuous joints at O about z, y, x (R = Rz(yaw) Ry(pitch) Rx(roll)) through two massless links. That is the
    same body with the same dynamics, in other coordinates: q = the three angles (Pinocchio stores each as cos, sin),
    v = their rates, singular (not the body, the chart) at pitch = ±90°. URDF has no gravity either: the comment in
    the file gives g d to set in the tool (Pinocchio: model.gravity.linear).
    Raises ValueError for a case this adapter cannot model exactly.
    """
    reason = PinocchioEngine().unsupported(case)
    present = [f"[{term.key}]" for term in case.torques]
    if present and not reason:
        reason = f"{', '.join(present)} enters the Pinocchio adapter at run time (tau), which URDF cannot hold"
    if reason:
        raise ValueError(f"{case.name}: {reason}")
    body = case.body
    inertia = np.asarray(body.inertia_com, dtype=float)
    gravity = body.gravity * np.asarray(body.gravity_direction, dtype=float)
    number = lambda x: repr(float(x))  # noqa: E731 - repr round-trips a double exactly
    vector = lambda v: " ".join(number(x) for x in v)  # noqa: E731
    joints = []
    for name, parent, child, axis in (("yaw", "world", "gimbal_yaw", "0 0 1"), ("pitch", "gimbal_yaw", "gimbal_pitch",
                                      "0 1 0"), ("roll", "gimbal_pitch", "body", "1 0 0")):
        joints.append(f'  <joint name="{name}" type="continuous">\n    <parent link="{parent}"/>\n'
                      f'    <child link="{child}"/>\n    <origin xyz="0 0 0" rpy="0 0 0"/>\n'
                      f'    <axis xyz="{axis}"/>\n  </joint>')
    return f"""<?xml version="1.0"?>
<!-- stereodyn case {_comment(case.name)}: a rigid body with a fixed point O at the world origin.
     The ball joint at O is a gimbal of three continuous joints (yaw about z, pitch about y, roll about x:
     R = Rz Ry Rx, body -> world) through two massless links; the body's frame is the case's body frame.
     Gravity to set in the tool (URDF has none), world frame, m/s^2: {vector(gravity)} -->
<robot name={quoteattr(case.name)}>
  <link name="world"/>
  <link name="gimbal_yaw"/>
  <link name="gimbal_pitch"/>
  <link name="body">
    <inertial>
      <origin xyz="{vector(body.com)}" rpy="0 0 0"/>
      <mass value="{number(body.mass)}"/>
      <inertia ixx="{number(inertia[0, 0])}" ixy="{number(inertia[0, 1])}" ixz="{number(inertia[0, 2])}" \
iyy="{number(inertia[1, 1])}" iyz="{number(inertia[1, 2])}" izz="{number(inertia[2, 2])}"/>
    </inertial>
  </link>
{chr(10).join(joints)}
</robot>
"""


class PinocchioSimulation:
    """A case's model with one integrator and dt; run() starts from the case's initial state every time."""

    def __init__(self, case: Case, integrator: integrators.Integrator, dt: float):
        self.integrator = integrator
        self.dt = dt
        self.system = PinocchioSystem(build_model(case), torque_function(case.body))
        self.torque_mode = "stage" if case.body.has_external_torque else "none"
        self.system.body = case.body  # for integrators that use the body itself (harness.integrators.geometric)
        w, x, y, z = np.asarray(case.quat0, dtype=float)
        self.q0 = np.array([x, y, z, w])
        self.v0 = np.array(case.omega0, dtype=float)

    def run(self, grid: TimeGrid) -> Trajectory:
        if grid.dt != self.dt:
            raise ValueError(f"grid dt {grid.dt} differs from the prepared dt {self.dt}")
        trajectory = self.integrator.integrate(self.system, self.q0, self.v0, grid, record)
        return dataclasses.replace(trajectory, info={**trajectory.info, "torque_mode": self.torque_mode})


class PinocchioEnsemble:
    """A case's model with one integrator and dt, run from N initial states at once (PinocchioEngine.prepare_ensemble).

    quat0: (N, 4) (w, x, y, z) body -> world; omega0: (N, 3) rad/s body frame. run() gives one Trajectory per member,
    the one PinocchioSimulation.run would give from that state up to round-off (the arithmetic is batched, not the
    method). An integrator without a batch_stepper runs the members one after the other.
    """

    def __init__(self, case: Case, simulation: PinocchioSimulation, quat0: np.ndarray, omega0: np.ndarray,
                 threads: int):
        quat0, omega0 = np.array(quat0, dtype=float, ndmin=2), np.array(omega0, dtype=float, ndmin=2)
        if quat0.shape[1:] != (4,) or omega0.shape != (quat0.shape[0], 3):
            raise ValueError(f"an ensemble wants quat0 (N, 4) and omega0 (N, 3), got {quat0.shape} and {omega0.shape}")
        # the single run's model, system (for integrators without a batched form) and settings
        self.integrator, self.dt = simulation.integrator, simulation.dt
        self.single, self.torque_mode = simulation.system, simulation.torque_mode
        self.batch = PinocchioBatchSystem(simulation.system.model, threads, torque_function(case.body))
        self.q0 = np.ascontiguousarray(quat0[:, [1, 2, 3, 0]])
        self.v0 = omega0

    def run(self, grid: TimeGrid) -> list[Trajectory]:
        if grid.dt != self.dt:
            raise ValueError(f"grid dt {grid.dt} differs from the prepared dt {self.dt}")
        step = self.integrator.batch_stepper(self.batch, grid.dt)
        if step is not None:
            check_stepper(step, type(self.integrator), "batch_stepper")
        if step is None:
            trajectories = [self.integrator.integrate(self.single, q, v, grid, record)
                            for q, v in zip(self.q0, self.v0)]
        else:
            trajectories = integrate_ensemble(step, self.integrator.stages, self.q0, self.v0, grid,
                                              lambda q: q[:, [3, 0, 1, 2]])
        return [dataclasses.replace(t, info={**t.info, "torque_mode": self.torque_mode, "ensemble": len(self.v0)})
                for t in trajectories]


class PinocchioRigidBody(RigidBodyModel):
    """The rigid body in Pinocchio: exported as URDF, and run as ensembles."""

    def export(self, case: Case, fmt: str, integrator: str | None, dt: float | None) -> str:
        """URDF: the body, its ball joint as a three-joint gimbal. A URDF holds no stepper: an integrator or a dt is
        refused rather than silently dropped."""
        if integrator is not None or dt is not None:
            raise ValueError(f"--{'integrator' if integrator is not None else 'dt'}: applies to a format that holds a "
                             f"stepper (mjcf), not to {fmt}")
        return urdf(case)

    def prepare_ensemble(self, case: Case, integrator: str | type[integrators.Integrator], dt: float,
                         quat0: np.ndarray, omega0: np.ndarray, threads: int = 1) -> "PinocchioEnsemble":
        """The case's body from N initial states (quat0 (N, 4) wxyz, omega0 (N, 3) rad/s) stepped together; the
        accelerations of each stage are one pin.abaInParallel call on `threads` OpenMP threads. Worth it from tens
        of members on: below that the fixed cost of the numpy calls dominates. threads > 1 only on idle cores: OpenMP
        threads contending with other processes (a sweep's workers) made a 64-member RK4 ensemble 6x slower."""
        return PinocchioEnsemble(case, self.engine.prepare(case, integrator, dt), quat0, omega0, threads)


class PinocchioEngine(Engine):
    name = "pinocchio"
    # measured on the suite's four general cases (2-core AMD EPYC): 2.4-2.9 µs per stage per step; Python step loops
    # over compiled right-hand sides: nothing is built per grid length (a short warm-up)
    timing = Timing(pass_us=2.6, short_warm_up=True)
    about = About(packages=("pin",), linestyle="--", export_formats=("urdf",), state_space="lie")

    def integrators(self) -> tuple[str, ...]:
        """The registry's Lie-group integrators: euler, symplectic_euler, rk4, rk4_naive, then plug-ins."""
        return integrators.names(state_space="lie")

    def unsupported(self, case: Case) -> str | None:
        return singular_torque(case)

    def prepare(self, case: Case, integrator: str | type[integrators.Integrator], dt: float) -> PinocchioSimulation:
        reason = self.unsupported(case)
        if reason:
            raise ValueError(f"{case.name}: {reason}")
        cls = integrators.get(integrator)
        if cls.state_space != "lie":
            raise KeyError(f"integrator {cls.name!r} works on state space {cls.state_space!r}, not 'lie'; "
                           f"valid: {', '.join(self.integrators())}")
        return PinocchioSimulation(case, cls(), float(dt))

    def models(self) -> dict:
        return {**super().models(), RIGID_BODY: PinocchioRigidBody(self), SLIDING_LADDER: LadderModel()}


class LadderModel(SceneModel):
    """The sliding ladder (harness.scenes.sliding_ladder): rows name the model in the formulation column."""

    def variants(self) -> tuple[str, ...]:
        return LADDER_MODELS

    def integrators(self, chosen: list[str]) -> list[str]:
        """The chosen integrators that step the ladder: those that also work on a vector state (its configuration
        is R³, not the rotation group)."""
        vector = set(integrators.names(state_space="vector"))
        return [name for name in chosen if name in vector]

    def prepare(self, case, variant: str, integrator: str, dt: float | None,
                tolerance: float | None = None) -> "PinocchioLadderSimulation":
        return PinocchioLadderSimulation(case.ladder, variant, integrator, dt)


# --- the sliding ladder (harness.scenes.sliding_ladder, FORMULARY T5) -------------------------------------------
# One model: the rod's ends held on the wall and the floor by two bilateral constraints, solved exactly at every stage
# by Pinocchio's constrained dynamics (pin.forwardDynamics with the constraint Jacobian: the KKT system of M, J and
# the drift J̇v, Lagrange multipliers for the two normal forces). A unilateral wall needs contact complementarity,
# which this adapter does not build.
LADDER_MODELS = ("bilateral",)


def ladder_model(ladder) -> tuple["pin.Model", int, int]:
    """(model, top frame, foot frame) of the planar rod, z up: a slide along x, a slide along z and a hinge about -y
    (angle θ from the wall, as MuJoCo's ladder), the rod (mass m, m ℓ²/3 about its centre) on the hinge, its ends
    at ∓ℓ along the body z axis (top = G + ℓ(−sin θ, cos θ), foot = G + ℓ(sin θ, −cos θ))."""
    m, l = float(ladder.mass), float(ladder.half_length)
    model = pin.Model()
    model.gravity = pin.Motion(np.array([0.0, 0.0, -float(ladder.g), 0.0, 0.0, 0.0]))
    slide_x = model.addJoint(0, pin.JointModelPX(), pin.SE3.Identity(), "x")
    slide_z = model.addJoint(slide_x, pin.JointModelPZ(), pin.SE3.Identity(), "z")
    hinge = model.addJoint(slide_z, pin.JointModelRevoluteUnaligned(np.array([0.0, -1.0, 0.0])), pin.SE3.Identity(),
                           "hinge")
    inertia = m * l * l / 3.0
    # only the inertia about y enters the planar motion; the other two just make the body's inertia definite
    model.appendBodyToJoint(hinge, pin.Inertia(m, np.zeros(3), np.diag([inertia, inertia, inertia / 100.0])),
                            pin.SE3.Identity())
    frames = []
    for name, end in (("top", l), ("foot", -l)):
        placement = pin.SE3(np.eye(3), np.array([0.0, 0.0, end]))
        frames.append(model.addFrame(pin.Frame(name, hinge, placement, pin.FrameType.OP_FRAME)))
    return model, frames[0], frames[1]


class LadderSystem:
    """The constrained rod as a harness VectorSystem (no charts): y = (x, z, θ, ẋ, ż, θ̇), the planar state of
    reference.sliding_ladder (z is its y). rhs solves M a + b = Jᵀλ, J a + J̇v = 0 (pin.forwardDynamics), J the
    rows of the top's x and the foot's z velocity; data.lambda_c then holds the wall's and the floor's push (N)."""

    def __init__(self, ladder):
        self.model, self.top, self.foot = ladder_model(ladder)
        self.data = ladder_data = self.model.createData()
        model, top, foot = self.model, self.top, self.foot
        frame = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
        jacobian, drift = np.empty((2, 3)), np.empty(2)
        zero, all_terms, dynamics = np.zeros(3), pin.computeAllTerms, pin.forwardDynamics
        frame_jacobian, classical = pin.getFrameJacobian, pin.getFrameClassicalAcceleration

        def rhs(t: float, chart: object, y: np.ndarray) -> np.ndarray:
            q, v = y[:3], y[3:]
            all_terms(model, ladder_data, q, v)  # M, b, the joint Jacobians and the velocity-product accelerations
            jacobian[0] = frame_jacobian(model, ladder_data, top, frame)[0]
            jacobian[1] = frame_jacobian(model, ladder_data, foot, frame)[2]
            drift[0] = classical(model, ladder_data, top, frame).linear[0]  # J̇v: the ends' acceleration at a = 0
            drift[1] = classical(model, ladder_data, foot, frame).linear[2]
            return np.concatenate([v, dynamics(model, ladder_data, zero, jacobian, drift)])

        self.rhs = rhs

    @staticmethod
    def rechart(chart: object, y: np.ndarray) -> tuple[object, np.ndarray]:
        return chart, y


class PinocchioLadderSimulation:
    """A sliding ladder in Pinocchio (LadderSystem) stepped by the harness's "vector" integrator of that name."""

    def __init__(self, ladder, model: str, integrator: str, dt: float):
        if model not in LADDER_MODELS:
            raise KeyError(f"unknown ladder model {model!r} for the Pinocchio adapter; "
                           f"valid: {', '.join(LADDER_MODELS)}")
        self.ladder, self.variant, self.dt = ladder, model, float(dt)
        self.integrator = integrators.get(integrator, state_space="vector")()
        self.system = LadderSystem(ladder)

    def run(self, grid: TimeGrid) -> SlidingLadderTrajectory:
        if grid.dt != self.dt:
            raise ValueError(f"grid dt {grid.dt} differs from the prepared dt {self.dt}")
        ladder = self.ladder
        y = ref_ladder.planar_state(ladder, ladder.theta0, ladder.theta_dot0)
        samples = grid.sample_steps
        state = np.full((samples.size, 6), np.nan)
        state[0] = y
        step, dt, done = self.integrator.stepper(self.system, grid.dt), grid.dt, 0
        with np.errstate(all="ignore"):
            for sample, target in enumerate(samples[1:].tolist(), start=1):
                for piece in budget.pieces(done, target):
                    for k in piece:
                        _, y = step(k * dt, None, y)
                done = target
                state[sample] = y
                if not np.all(np.isfinite(y)):
                    return SlidingLadderTrajectory(grid.times, state, ref_ladder.constraint_violation(ladder, state),
                                                   Status.DIVERGED, f"state not finite by t = {target * dt:.6g} s",
                                                   target * dt, target)
        return SlidingLadderTrajectory(grid.times, state, ref_ladder.constraint_violation(ladder, state), Status.OK,
                                       "", math.nan, grid.steps)
