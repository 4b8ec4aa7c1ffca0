"""The physical parameters of a rigid body with a fixed point O."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# The torque models' base module, not the package's registry: the body needs the order rule only (the package
# imports every model on its first import all the same).
from .torque_models.base import TorqueModel, ordered

# Relative tolerance of "u is a principal axis" and "σ is diagonal": case numbers are exact or far off.
PRINCIPAL_RTOL = 1e-12


@dataclass(frozen=True, eq=False)
class RigidBody:
    """A rigid body pinned at O, possibly in uniform gravity and under external torques.

    inertia: (3, 3) kg m^2, about O, body frame (the seeds' sigma), symmetric positive definite.
    mass: kg.
    com: (3,) m, body frame, the vector O -> G.
    gravity: m/s^2, magnitude g (0 for a torque-free body).
    gravity_direction: (3,) world frame, unit; the world gravity vector is gravity * gravity_direction.
    torques: the external torques beyond gravity, terms of reference.torque_models' registered models (at most one
    per model), held in registry order; torque(model) reads one (None: absent).
    """

    inertia: np.ndarray
    mass: float
    com: np.ndarray
    gravity: float = 0.0
    gravity_direction: np.ndarray = None  # type: ignore[assignment]
    torques: tuple[TorqueModel, ...] = ()

    def __post_init__(self) -> None:
        direction = (0.0, 0.0, -1.0) if self.gravity_direction is None else self.gravity_direction
        for name, value, shape in (("inertia", self.inertia, (3, 3)), ("com", self.com, (3,)),
                                   ("gravity_direction", direction, (3,))):
            array = np.array(value, dtype=float)
            if array.shape != shape:
                raise ValueError(f"{name} must have shape {shape}, got {array.shape}")
            array.setflags(write=False)
            object.__setattr__(self, name, array)
        object.__setattr__(self, "torques", ordered(self.torques))

    def torque(self, model: type) -> TorqueModel | None:
        """The body's term of a torque model (a class of reference.torque_models), or None."""
        for term in self.torques:
            if type(term) is model:
                return term
        return None

    @property
    def has_gravity(self) -> bool:
        return self.gravity != 0.0 and self.mass != 0.0 and bool(np.any(self.com != 0.0))

    @property
    def has_external_torque(self) -> bool:
        """A torque other than uniform gravity acts (a term in torques)."""
        return bool(self.torques)

    @property
    def weight_moment(self) -> np.ndarray:
        """m g (O -> G), body frame, N m: Grioli's alpha k. Zero without gravity."""
        return self.mass * self.gravity * self.com

    @property
    def inertia_com(self) -> np.ndarray:
        """(3, 3) kg m^2, inertia about the centre of mass, body axes (Huygens–Steiner)."""
        c = self.com
        return self.inertia - self.mass * (c @ c * np.eye(3) - np.outer(c, c))


def principal_frame_for(sigma: np.ndarray, axis: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """(moments (A1, A2, A3), frame (3, 3) columns e1, e2, e3 = axis, right-handed) when axis is a principal axis of
    σ, else None."""
    sigma = np.asarray(sigma, dtype=float)
    axis = np.asarray(axis, dtype=float)
    moments, vectors = np.linalg.eigh(sigma)
    along = np.abs(vectors.T @ axis)
    k = int(np.argmax(along))
    if along[k] < 1.0 - PRINCIPAL_RTOL * 10:
        return None
    others = [i for i in range(3) if i != k]
    e1 = vectors[:, others[0]]
    e2 = np.cross(axis, e1)
    frame = np.column_stack([e1, e2, axis])
    return np.array([moments[others[0]], moments[others[1]], moments[k]]), frame
