"""PyBullet adapter: the body as a Featherstone multibody on a spherical joint, stepped by Bullet's own step (the
optional extra `stereodyn[bullet]`; without it the engine's rows are skipped naming the install command).

Model: a fixed, massless base at the world origin and one link on a JOINT_SPHERICAL at O. Bullet takes a link's
inertia as a diagonal in the link's *inertial frame*, so that frame is the principal frame of the inertia about the
centre of mass: position com, orientation V (the columns of V are the principal axes in body components). Bullet then
measures the joint in that frame: the joint's quaternion qj satisfies R(qi) R(qj) = R_body V (qi = quaternion of V)
and its velocity is the angular velocity in the inertial frame, V^T omega_body. The adapter maps at its boundary:
qj = qi* ⊗ q ⊗ qi, q = qi ⊗ qj ⊗ qi*, omega = V omega_joint.

Everything the scene lacks is off: link damping (Bullet's default angular damping is 0.04), joint damping, the
spherical joint's default motor (zero gains, zero force) and the joint-velocity cap (default 100 rad/s). Measured
pitfall: a changeDynamics call that sets localInertiaDiagonal together with damping or maxJointVelocity leaves the
inertia zero (NaN at the first step), so the inertia is set in a call of its own and read back.

Integrator: stepSimulation is semi-implicit Euler (velocity first, then the attitude with the new velocity), in
double precision: it matches MuJoCo's Euler to ~1e-14 (docs/ENGINES.md). External torques (reference.torques) are
evaluated in Python at the start of every step, from the step's time and state, and applied in world components with
applyExternalTorque (Bullet clears it after the step): exact for this one-stage method (torque_mode `step`).
"""
from __future__ import annotations

import math
import os
import sys
import weakref

import numpy as np

from .. import install
from .quiet import native_output_silenced

INSTALL = install.hint("bullet")  # a checkout's or a distribution's form


try:
    with native_output_silenced():  # its import prints "pybullet build time" to fd 2
        import pybullet
except ImportError as exc:  # the registry turns this into skipped rows whose reason is this message
    raise ImportError(f"{exc}; install the extra: {INSTALL}") from exc

from .. import budget
from ..scenes.cases import Case, unphysical_inertia
from .base import RIGID_BODY, About, Engine, Offer, RigidBodyModel, Timing, singular_torque
from ..grid import TimeGrid
from ..trajectory import Status, Trajectory, divergence_limit2, divergence_message, sample_good
from ...reference.rotations import matrix_to_quat, quat_conj, quat_mul
from ...reference.torques import torque_function

STEP = "semi_implicit_euler"
# A speed cap no run of these scenes reaches (the divergence rule ends a run long before: 1e6 x |omega0|).
NO_CAP = 1e30


def _disconnect(client: int) -> None:
    with native_output_silenced():
        pybullet.disconnect(client)


def principal_frame(inertia_com: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(moments (3,) kg m^2, V (3, 3) a proper rotation whose columns are the principal axes in body components)."""
    moments, axes = np.linalg.eigh(np.asarray(inertia_com, dtype=float))
    if np.linalg.det(axes) < 0:
        axes[:, 2] *= -1.0
    return moments, axes


class BulletSimulation:
    """A case's multibody in its own DIRECT physics client; run() resets the joint to the case's initial state."""

    def __init__(self, case: Case, dt: float):
        self.case, self.dt = case, float(dt)
        body = case.body
        moments, self.axes = principal_frame(body.inertia_com)
        self.qi = matrix_to_quat(self.axes)
        with native_output_silenced():
            self.client = client = pybullet.connect(pybullet.DIRECT)
        self._close = weakref.finalize(self, _disconnect, client)
        pybullet.setGravity(*(body.gravity * np.asarray(body.gravity_direction, dtype=float)).tolist(),
                            physicsClientId=client)
        pybullet.setPhysicsEngineParameter(fixedTimeStep=self.dt, numSubSteps=0, physicsClientId=client)
        w, x, y, z = self.qi.tolist()
        self.body = pybullet.createMultiBody(
            baseMass=0.0, baseCollisionShapeIndex=-1, baseVisualShapeIndex=-1, basePosition=[0.0, 0.0, 0.0],
            linkMasses=[float(body.mass)], linkCollisionShapeIndices=[-1], linkVisualShapeIndices=[-1],
            linkPositions=[[0.0, 0.0, 0.0]], linkOrientations=[[0.0, 0.0, 0.0, 1.0]],
            linkInertialFramePositions=[np.asarray(body.com, dtype=float).tolist()],
            linkInertialFrameOrientations=[[x, y, z, w]], linkParentIndices=[0],
            linkJointTypes=[pybullet.JOINT_SPHERICAL], linkJointAxis=[[0.0, 0.0, 1.0]], physicsClientId=client)
        for link in (-1, 0):
            pybullet.changeDynamics(self.body, link, linearDamping=0.0, angularDamping=0.0, jointDamping=0.0,
                                    maxJointVelocity=NO_CAP, physicsClientId=client)
        pybullet.changeDynamics(self.body, 0, localInertiaDiagonal=moments.tolist(), physicsClientId=client)
        stored = np.asarray(pybullet.getDynamicsInfo(self.body, 0, physicsClientId=client)[2])
        if not np.allclose(stored, moments, rtol=1e-12, atol=0.0):
            raise RuntimeError(f"pybullet kept the inertia {stored}, not {moments}")
        pybullet.setJointMotorControlMultiDof(self.body, 0, pybullet.POSITION_CONTROL,
                                              targetPosition=[0.0, 0.0, 0.0, 1.0], positionGain=0.0,
                                              velocityGain=0.0, force=[0.0, 0.0, 0.0], physicsClientId=client)
        qj = quat_mul(quat_mul(quat_conj(self.qi), np.asarray(case.quat0, dtype=float)), self.qi)
        self.joint0 = [float(qj[1]), float(qj[2]), float(qj[3]), float(qj[0])]
        self.velocity0 = (self.axes.T @ np.asarray(case.omega0, dtype=float)).tolist()
        self.torque = torque_function(body)

    def reset(self) -> None:
        """The joint back at the case's initial state (every run starts afresh; nothing else carries over)."""
        pybullet.resetJointStateMultiDof(self.body, 0, targetValue=self.joint0, targetVelocity=self.velocity0,
                                         physicsClientId=self.client)

    def run(self, grid: TimeGrid) -> Trajectory:
        if grid.dt != self.dt:
            raise ValueError(f"grid dt {grid.dt} differs from the prepared dt {self.dt}")
        self.reset()
        client, body, torque, dt = self.client, self.body, self.torque, self.dt
        state, step, apply = pybullet.getJointStateMultiDof, pybullet.stepSimulation, pybullet.applyExternalTorque
        qi, axes, world_frame = tuple(self.qi.tolist()), self.axes.tolist(), pybullet.WORLD_FRAME
        limit2 = divergence_limit2(self.case.omega0)
        samples = grid.sample_steps.tolist()
        joints = np.full((len(samples), 7), np.nan)
        joints[0] = self.joint0 + self.velocity0
        bad = None
        for i in range(1, len(samples)):
            if torque is None:  # the hot loop: Bullet's steps, one state read a sample
                for piece in budget.pieces(samples[i - 1], samples[i]):  # the run's wall-time budget
                    for _ in piece:
                        step(physicsClientId=client)
            else:  # every step: the torque from the step's time and state, in world components, then the step
                try:
                    for k in (k for piece in budget.pieces(samples[i - 1], samples[i]) for k in piece):
                        position, velocity = state(body, 0, physicsClientId=client)[:2]
                        quat, omega, rotation = _body_state(qi, axes, position, velocity)
                        moment = torque(k * dt, quat, omega)
                        apply(body, 0, [sum(r * m for r, m in zip(row, moment)) for row in rotation], world_frame,
                              physicsClientId=client)
                        step(physicsClientId=client)
                except (ArithmeticError, ValueError):  # a torque of a runaway state (math.cos(inf)): diverged
                    bad = i
                    break
            position, velocity = state(body, 0, physicsClientId=client)[:2]
            joints[i, :4], joints[i, 4:] = position, velocity
            quat, omega, _ = _body_state(qi, axes, position, velocity)
            if not sample_good(quat, omega, limit2):  # the divergence rule: stop at the first bad sample
                bad = i
                break
        quat, omega = self.observe(joints)
        mode = "step" if torque is not None else "none"
        if bad is None:
            return Trajectory(grid.times, quat, omega, Status.OK, "", math.nan, grid.steps, grid.steps,
                              info={"torque_mode": mode})
        quat[bad:] = np.nan
        omega[bad:] = np.nan
        diverged_at = float(grid.times[bad])
        return Trajectory(grid.times, quat, omega, Status.DIVERGED, divergence_message(diverged_at), diverged_at,
                          samples[bad], samples[bad], info={"torque_mode": mode})

    def observe(self, joints: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Recorded joint states (n, 7: quaternion xyzw, inertial-frame velocity) -> quaternions wxyz body -> world,
        omega (rad/s) in body components."""
        qj = joints[:, [3, 0, 1, 2]]
        with np.errstate(invalid="ignore", over="ignore"):
            quat = quat_mul(quat_mul(np.broadcast_to(self.qi, qj.shape), qj),
                            np.broadcast_to(quat_conj(self.qi), qj.shape))
            return quat, joints[:, 4:] @ self.axes.T


def _body_state(qi: tuple, axes: list, position, velocity) -> tuple[tuple, tuple, tuple]:
    """One joint state in floats (quaternion xyzw, inertial-frame velocity) -> the body's quaternion wxyz
    (qi ⊗ qj ⊗ qi*), omega in body components (V v) and its rotation matrix's rows (float arithmetic: numpy's
    per-call cost on 3-vectors would be ten times the arithmetic in this per-step path)."""
    x, y, z, w = position
    a, b, c, d = qi
    # p = qi ⊗ qj, then q = p ⊗ qi*
    pw, px, py, pz = (a * w - b * x - c * y - d * z, a * x + b * w + c * z - d * y,
                      a * y - b * z + c * w + d * x, a * z + b * y - c * x + d * w)
    b, c, d = -b, -c, -d
    qw, qx, qy, qz = (pw * a - px * b - py * c - pz * d, pw * b + px * a + py * d - pz * c,
                      pw * c - px * d + py * a + pz * b, pw * d + px * c - py * b + pz * a)
    omega = tuple(row[0] * velocity[0] + row[1] * velocity[1] + row[2] * velocity[2] for row in axes)
    s = 2.0 / (qw * qw + qx * qx + qy * qy + qz * qz)
    rotation = ((1 - s * (qy * qy + qz * qz), s * (qx * qy - qw * qz), s * (qx * qz + qw * qy)),
                (s * (qx * qy + qw * qz), 1 - s * (qx * qx + qz * qz), s * (qy * qz - qw * qx)),
                (s * (qx * qz - qw * qy), s * (qy * qz + qw * qx), 1 - s * (qx * qx + qy * qy)))
    return (qw, qx, qy, qz), omega, rotation


class BulletRigidBody(RigidBodyModel):
    """The rigid body in PyBullet: the torque computed in Python and applied at every step."""

    def torque_mode(self, case: Case) -> str:
        return "step" if case.body.has_external_torque else "none"


class BulletEngine(Engine):
    """PyBullet's Featherstone multibody on a spherical joint, Bullet's semi-implicit Euler step, float64."""

    name = "bullet"
    # measured: 3-6 µs per step from the Python loop on the loaded 2-core machine (docs/ENGINES.md)
    timing = Timing(pass_us=4.0)
    about = About(packages=("pybullet",), linestyle=":")

    def integrators(self) -> tuple[str, ...]:
        return (STEP,)

    def offer(self, integrator: str) -> Offer:
        ours = integrator == STEP
        return Offer(order=1.0 if ours else math.nan, method="semi_implicit_euler" if ours else "",
                     default_sweep=ours)

    def models(self) -> dict:
        return {**super().models(), RIGID_BODY: BulletRigidBody(self)}

    def unsupported(self, case: Case) -> str | None:
        # [body] physical = false: a link's inertia is a physical body's (as MuJoCo's and Drake's; not probed further)
        return unphysical_inertia(case) or singular_torque(case)

    def prepare(self, case: Case, integrator: str, dt: float | None, **options) -> BulletSimulation:
        if integrator != STEP:
            raise KeyError(f"unknown integrator {integrator!r} for the bullet engine; valid: {STEP}")
        reason = self.unsupported(case)
        if reason:
            raise ValueError(f"{case.name}: {reason}")
        if dt is None or not dt > 0:
            raise ValueError(f"integrator {integrator!r} needs a step dt > 0, got {dt!r}")
        return BulletSimulation(case, dt)
