"""The physical parameters of a rigid body with a fixed point O."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from stereodyn.reference.torque_models import BodyTorque, CentralField, PrecessionTorque


@dataclass(frozen=True, eq=False)
class RigidBody:
    """A rigid body pinned at O, possibly in uniform gravity.

    inertia: (3, 3) kg m^2, about O, body frame (the seeds' sigma), symmetric positive definite.
    mass: kg.
    com: (3,) m, body frame, the vector O -> G.
    gravity: m/s^2, magnitude g (0 for a torque-free body).
    gravity_direction: (3,) world frame, unit; the world gravity vector is gravity * gravity_direction.
    body_torque, central_field, precession_torque: the external torques of reference.torques (None: absent).
    """

    inertia: np.ndarray
    mass: float
    com: np.ndarray
    gravity: float = 0.0
    gravity_direction: np.ndarray = None  # type: ignore[assignment]
    body_torque: BodyTorque | None = None
    central_field: CentralField | None = None
    precession_torque: PrecessionTorque | None = None

    def __post_init__(self) -> None:
        direction = (0.0, 0.0, -1.0) if self.gravity_direction is None else self.gravity_direction
        for name, value, shape in (("inertia", self.inertia, (3, 3)), ("com", self.com, (3,)),
                                   ("gravity_direction", direction, (3,))):
            array = np.array(value, dtype=float)
            if array.shape != shape:
                raise ValueError(f"{name} must have shape {shape}, got {array.shape}")
            array.setflags(write=False)
            object.__setattr__(self, name, array)

    @property
    def has_gravity(self) -> bool:
        return self.gravity != 0.0 and self.mass != 0.0 and bool(np.any(self.com != 0.0))

    @property
    def has_external_torque(self) -> bool:
        """A torque other than uniform gravity acts (reference.torques)."""
        return (self.body_torque is not None or self.central_field is not None
                or self.precession_torque is not None)

    @property
    def weight_moment(self) -> np.ndarray:
        """m g (O -> G), body frame, N m: Grioli's alpha k. Zero without gravity."""
        return self.mass * self.gravity * self.com

    @property
    def inertia_com(self) -> np.ndarray:
        """(3, 3) kg m^2, inertia about the centre of mass, body axes (Huygens–Steiner)."""
        c = self.com
        return self.inertia - self.mass * (c @ c * np.eye(3) - np.outer(c, c))
