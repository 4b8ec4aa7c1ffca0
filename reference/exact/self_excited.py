"""Exact motions of the self-excited body (FORMULARY G12, G13): M = (a + b |ω|²) u fixed in the body, the only torque.

* self_excited_spinup (32): ω ∥ u, u a principal axis, a > 0 > b, |p3(0)| < s = √(−a/b): p3 = s tanh(k t + c),
  k = √(−ab)/A3, c = artanh(p3(0)/s); the body turns about the fixed axis R0 u by λ(t) = ∫ p3 dt =
  (−A3/b)(log cosh(k t + c) − log cosh c).
* self_excited_uniform (33), (37)–(38): a uniform rotation, ω0 × σω0 = M(ω0) (σω̇ = σω × ω + M = 0): ω stays ω0 and
  R(t) = R0 exp(t [ω0]×).
"""
from __future__ import annotations

import math

import numpy as np

from ..body import RigidBody, principal_frame_for
from ..closed_form import CONDITION_RTOL
from ..rotations import quat_exp, quat_mul
from ..torque_models.body_torque import BodyTorque, body_torque_components


def _only_body_torque(body: RigidBody) -> str | None:
    if body.torque(BodyTorque) is None:
        return "needs a [body_torque]"
    if body.has_gravity or len(body.torques) != 1:
        return "the body torque must be the only torque (no gravity, no central field)"
    return None


def _log_cosh(x: np.ndarray) -> np.ndarray:
    x = np.abs(x)
    return x + np.log1p(np.exp(-2.0 * x)) - math.log(2.0)


def spinup_check(body: RigidBody, quat0: np.ndarray, omega0: np.ndarray) -> str | None:
    reason = _only_body_torque(body)
    if reason:
        return reason
    torque = body.torque(BodyTorque)
    u = np.asarray(torque.axis, dtype=float)
    if principal_frame_for(body.inertia, u) is None:
        return "the torque axis must be a principal axis at O"
    omega0 = np.asarray(omega0, dtype=float)
    if np.linalg.norm(np.cross(omega0, u)) > CONDITION_RTOL * max(1.0, float(np.linalg.norm(omega0))):
        return "omega0 must be parallel to the torque axis (p1 = p2 = 0)"
    if not (torque.a > 0.0 > torque.b):
        return f"needs a > 0 > b for the tanh spin-up (a = {torque.a:g}, b = {torque.b:g})"
    if abs(omega0 @ u) >= math.sqrt(-torque.a / torque.b):
        return "needs |omega0 . u| < sqrt(-a/b) (below the stable uniform rotation)"
    return None


def spinup_solve(body: RigidBody, quat0: np.ndarray, omega0: np.ndarray,
                 times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    torque = body.torque(BodyTorque)
    u = np.asarray(torque.axis, dtype=float)
    (_, _, a3), _ = principal_frame_for(body.inertia, u)
    times = np.asarray(times, dtype=float)
    s = math.sqrt(-torque.a / torque.b)
    k = math.sqrt(-torque.a * torque.b) / a3
    c = math.atanh(float(np.asarray(omega0, dtype=float) @ u) / s)
    spin = s * np.tanh(k * times + c)
    angle = (-a3 / torque.b) * (_log_cosh(k * times + c) - _log_cosh(np.array(c)))
    quat = quat_mul(np.asarray(quat0, dtype=float), quat_exp(angle[:, None] * u))
    return quat, spin[:, None] * u


def uniform_check(body: RigidBody, quat0: np.ndarray, omega0: np.ndarray) -> str | None:
    reason = _only_body_torque(body)
    if reason:
        return reason
    omega0 = np.asarray(omega0, dtype=float)
    momentum = body.inertia @ omega0
    torque = body.torque(BodyTorque)
    residual = np.cross(momentum, omega0) + np.array(body_torque_components(torque.axis, torque.a, torque.b, omega0))
    scale = float(np.linalg.norm(momentum) * np.linalg.norm(omega0)) + abs(torque.a) \
        + abs(torque.b) * float(omega0 @ omega0)
    if np.linalg.norm(residual) > CONDITION_RTOL * scale:
        return (f"not a uniform rotation: |sigma omega0 x omega0 + M(omega0)| = {np.linalg.norm(residual):.3g} "
                f"(needs <= {CONDITION_RTOL:g} x {scale:.3g})")
    return None


def uniform_solve(body: RigidBody, quat0: np.ndarray, omega0: np.ndarray,
                  times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    times = np.asarray(times, dtype=float)
    omega0 = np.asarray(omega0, dtype=float)
    quat = quat_mul(np.asarray(quat0, dtype=float), quat_exp(times[:, None] * omega0))
    return quat, np.broadcast_to(omega0, (times.size, 3)).copy()
