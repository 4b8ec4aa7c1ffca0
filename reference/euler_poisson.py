"""Euler–Poisson equations with a quaternion attitude, in numpy (FORMULARY §0, G3).

σ ω̇ = σω × ω + M,  M = m g c × H,  H = Rᵀ d,  q̇ = ½ q ⊗ (0, ω).

σ is the inertia about O (any symmetric positive definite matrix, not necessarily diagonal), c the vector O -> G,
d the world unit downward direction, H Grioli's downward vertical in body components. ω is in body components.
quat (..., 4) and omega (..., 3) broadcast against each other.

Two forms of R(q) for a quaternion off the unit sphere (a fixed-step run's, whose |q| drifts: casimir_drift). Here R
is built from the normalised quaternion (rotations.quat_to_matrix): the invariants of a recorded state use this. The
reference engine's right-hand side, what its fixed-step integrators step and the truth integrates, is the compiled
one of reference/truth.py: the homogeneous R~(q) = (w² - v·v) I + 2 v vᵀ + 2 w [v]× = |q|² R(q/|q|), a polynomial,
with no division by |q|². The two agree on |q| = 1; off it a torque that depends on
the attitude differs (gravity's by the factor |q|²).
An engine that reproduces the reference's quaternion rk4 to round-off uses the homogeneous form (1e-15 on
lagrange-top; with the normalised form 1e-6: tests/test_quaternion_rhs.py, docs/ENGINE_PLUGIN.md).
"""
from __future__ import annotations

import numpy as np

from .body import RigidBody
from .rotations import quat_mul, quat_to_matrix
from .torques import external_torque


def downward_vertical(body: RigidBody, quat: np.ndarray) -> np.ndarray:
    """H = Rᵀ d: (..., 4) -> (..., 3), unit, body frame (the gravity direction as seen from the body)."""
    rotation = quat_to_matrix(quat)
    return np.einsum("...ji,j->...i", rotation, body.gravity_direction)


def gravity_torque(body: RigidBody, quat: np.ndarray) -> np.ndarray:
    """M = m g c × H: (..., 4) -> (..., 3) N m, body frame, about O."""
    return np.cross(body.weight_moment, downward_vertical(body, quat))


def omega_dot(body: RigidBody, quat: np.ndarray, omega: np.ndarray, t=0.0) -> np.ndarray:
    """ω̇ = σ⁻¹(σω × ω + M): (..., 4), (..., 3) -> (..., 3) rad/s², body frame; t (s) places a turning central
    field (reference.torques)."""
    omega = np.asarray(omega, dtype=float)
    momentum = omega @ body.inertia  # σ symmetric, so ω σ = (σ ω)ᵀ row-wise
    torque = np.cross(momentum, omega)
    if body.has_gravity:
        torque = torque + gravity_torque(body, quat)
    if body.has_external_torque:
        torque = torque + external_torque(body, quat, omega, t)
    torque = np.broadcast_to(torque, np.broadcast_shapes(torque.shape, np.shape(quat)[:-1] + (3,)))
    return np.linalg.solve(body.inertia, torque[..., None])[..., 0]


def quat_dot(quat: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """q̇ = ½ q ⊗ (0, ω): (..., 4), (..., 3) body rad/s -> (..., 4) 1/s. Preserves |q| exactly."""
    omega = np.asarray(omega, dtype=float)
    pure = np.concatenate([np.zeros(omega.shape[:-1] + (1,)), omega], axis=-1)
    return 0.5 * quat_mul(quat, pure)


def rhs(body: RigidBody, quat: np.ndarray, omega: np.ndarray, t=0.0) -> tuple[np.ndarray, np.ndarray]:
    """(q̇, ω̇) of the Euler–Poisson system: (..., 4), (..., 3) -> ((..., 4), (..., 3)); t in s."""
    return quat_dot(quat, omega), omega_dot(body, quat, omega, t)
