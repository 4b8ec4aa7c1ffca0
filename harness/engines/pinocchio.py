"""Pinocchio adapter: the body on a spherical joint, stepped by the harness's own Lie-group integrators.

Pinocchio has no time stepper; it supplies the dynamics (articulated-body algorithm) and the group operation.
Its configuration q is a quaternion stored (x, y, z, w); v and tau are body-frame angular velocity and torque.
External torques (reference.torques) enter as tau, evaluated at every stage of the integrator (torque_mode "stage").
The harness's Lie-group integrators pass no time to a stage, so a torque that depends on time (a central field whose
direction turns) is not modelled: such runs are skipped.
"""
from __future__ import annotations

import dataclasses
import functools

import numpy as np
import pinocchio as pin

from harness import integrators
from harness.cases import Case
from harness.engines.base import Trajectory, precession_singular
from harness.grid import TimeGrid
from reference.torques import torque_function


class PinocchioSystem:
    """The LieSystem of one model: g = q (4,) (x, y, z, w); v (3,) rad/s body frame.

    accel and retract are bound once here, as a closure and a C-level partial, rather than methods: on the hot path
    that saves attribute lookups per call and, for retract, a Python frame (a few percent of an RK4 step).
    """

    def __init__(self, model: "pin.Model", torque=None):
        self.model = model
        self.data = data = model.createData()
        tau, aba, array = np.zeros(model.nv), pin.aba, np.array

        def accel(q: np.ndarray, v: np.ndarray) -> np.ndarray:
            """v' (3,) rad/s^2, body frame. pin.aba returns a fresh array (not a view of data.ddq)."""
            return aba(model, data, q, v, tau)

        def accel_torqued(q: np.ndarray, v: np.ndarray) -> np.ndarray:
            """As accel, with the external torque of this stage's state as tau (time-independent torques only)."""
            x, y, z, w = q.tolist()
            return aba(model, data, q, v, array(torque(0.0, (w, x, y, z), v.tolist())))

        if torque is not None:
            accel = accel_torqued

        self.accel = accel
        self.retract = functools.partial(pin.integrate, model)  # q (x) exp(theta), theta (3,) rad body frame


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


def urdf(case: Case) -> str:
    """build_model's body as URDF, to open in Pinocchio (buildModelFromUrdf) or other URDF tools.

    URDF has no spherical joint. A floating joint would free the fixed point, so the ball joint is a gimbal: three
    continuous joints at O about z, y, x (R = Rz(yaw) Ry(pitch) Rx(roll)) through two massless links. That is the
    same body with the same dynamics, in other coordinates: q = the three angles (Pinocchio stores each as cos, sin),
    v = their rates, singular (not the body, the chart) at pitch = ±90°. URDF has no gravity either: the comment in
    the file gives g d to set in the tool (Pinocchio: model.gravity.linear).
    Raises ValueError for a case this adapter cannot model exactly.
    """
    if case.kind != "rigid_body":
        raise ValueError(f"{case.name}: the Pinocchio adapter does not model the {case.kind} scene")
    reason = PinocchioEngine().unsupported(case)
    present = [f"[{name}]" for name in ("body_torque", "central_field", "precession_torque")
               if getattr(case, name) is not None]
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
<!-- stereodyn case "{case.name}": a rigid body with a fixed point O at the world origin.
     The ball joint at O is a gimbal of three continuous joints (yaw about z, pitch about y, roll about x:
     R = Rz Ry Rx, body -> world) through two massless links; the body's frame is the case's body frame.
     Gravity to set in the tool (URDF has none), world frame, m/s^2: {vector(gravity)} -->
<robot name="{case.name}">
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


class PinocchioEngine:
    name = "pinocchio"

    def integrators(self) -> tuple[str, ...]:
        """The registry's Lie-group integrators: euler, symplectic_euler, rk4, rk4_naive, then plug-ins."""
        return integrators.names(state_space="lie")

    def unsupported(self, case: Case) -> str | None:
        if case.central_field is not None and case.central_field.orbit_rate != 0.0:
            return ("Pinocchio adapter does not model a turning [central_field] (orbit_rate != 0): the harness's "
                    "Lie-group integrators give a stage no time")
        return precession_singular(case)

    def prepare(self, case: Case, integrator: str | type[integrators.Integrator], dt: float) -> PinocchioSimulation:
        reason = self.unsupported(case)
        if reason:
            raise ValueError(f"{case.name}: {reason}")
        cls = integrators.get(integrator)
        if cls.state_space != "lie":
            raise KeyError(f"integrator {cls.name!r} works on state space {cls.state_space!r}, not 'lie'; "
                           f"valid: {', '.join(self.integrators())}")
        return PinocchioSimulation(case, cls(), float(dt))
