"""Pinocchio adapter: the body on a spherical joint, stepped by the harness's own Lie-group integrators.

Pinocchio has no time stepper; it supplies the dynamics (articulated-body algorithm) and the group operation.
Its configuration q is a quaternion stored (x, y, z, w); v and tau are body-frame angular velocity and torque.
"""
from __future__ import annotations

import functools

import numpy as np
import pinocchio as pin

from harness import integrators
from harness.cases import Case
from harness.engines.base import Trajectory
from harness.grid import TimeGrid

_FEATURES = ("body_torque", "central_field")


class PinocchioSystem:
    """The LieSystem of one model: g = q (4,) (x, y, z, w); v (3,) rad/s body frame.

    accel and retract are bound once here, as a closure and a C-level partial, rather than methods: on the hot path
    that saves attribute lookups per call and, for retract, a Python frame (a few percent of an RK4 step).
    """

    def __init__(self, model: "pin.Model"):
        self.model = model
        self.data = data = model.createData()
        tau, aba = np.zeros(model.nv), pin.aba

        def accel(q: np.ndarray, v: np.ndarray) -> np.ndarray:
            """v' (3,) rad/s^2, body frame. pin.aba returns a fresh array (not a view of data.ddq)."""
            return aba(model, data, q, v, tau)

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


class PinocchioSimulation:
    """A case's model with one integrator and dt; run() starts from the case's initial state every time."""

    def __init__(self, case: Case, integrator: integrators.Integrator, dt: float):
        self.integrator = integrator
        self.dt = dt
        self.system = PinocchioSystem(build_model(case))
        w, x, y, z = np.asarray(case.quat0, dtype=float)
        self.q0 = np.array([x, y, z, w])
        self.v0 = np.array(case.omega0, dtype=float)

    def run(self, grid: TimeGrid) -> Trajectory:
        if grid.dt != self.dt:
            raise ValueError(f"grid dt {grid.dt} differs from the prepared dt {self.dt}")
        return self.integrator.integrate(self.system, self.q0, self.v0, grid, record)


class PinocchioEngine:
    name = "pinocchio"

    def integrators(self) -> tuple[str, ...]:
        """The registry's Lie-group integrators: euler, symplectic_euler, rk4, rk4_naive, then plug-ins."""
        return integrators.names(state_space="lie")

    def unsupported(self, case: Case) -> str | None:
        missing = [f"[{name}]" for name in _FEATURES if getattr(case, name) is not None]
        return f"Pinocchio adapter does not model {', '.join(missing)} yet" if missing else None

    def prepare(self, case: Case, integrator: str | type[integrators.Integrator], dt: float) -> PinocchioSimulation:
        reason = self.unsupported(case)
        if reason:
            raise ValueError(f"{case.name}: {reason}")
        cls = integrators.get(integrator)
        if cls.state_space != "lie":
            raise KeyError(f"integrator {cls.name!r} works on state space {cls.state_space!r}, not 'lie'; "
                           f"valid: {', '.join(self.integrators())}")
        return PinocchioSimulation(case, cls(), float(dt))
