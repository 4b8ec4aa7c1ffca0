"""Case files (DESIGN §3): loading, validation, the suite shipped in the `cases` package."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from reference.body import RigidBody


class CaseError(ValueError):
    """Bad input in a case file. str() is one line: 'FILE: KEY: RULE'."""

    def __init__(self, path: str | Path, key: str, rule: str):
        self.path, self.key, self.rule = str(path), key, rule
        super().__init__(f"{path}: {key}: {rule}")


@dataclass(frozen=True)
class BodyTorque:
    """M = (a + b |omega|^2) axis, body frame (002 eq. 30). axis: (3,) unit, body frame; a: N m; b: N m s^2."""

    axis: tuple[float, float, float]
    a: float
    b: float


@dataclass(frozen=True)
class CentralField:
    """Newtonian attracting centre (002 §III). mu: m^3/s^2; radius: m; direction: (3,) world unit centre -> O at t=0;
    orbit_rate: rad/s about world z."""

    mu: float
    radius: float
    direction: tuple[float, float, float]
    orbit_rate: float


@dataclass(frozen=True, eq=False)
class Case:
    """One scene (DESIGN §3), validated.

    inertia: (3, 3) kg m^2 about O, body frame. com: (3,) m body frame. gravity_direction: (3,) world unit.
    quat0: (4,) initial attitude, scalar first, body -> world, unit. omega0: (3,) rad/s, body frame.
    dt: the steps to sweep, s. path: the file it came from (None for a case built in code).
    """

    name: str
    description: str
    tags: tuple[str, ...]
    mass: float
    com: np.ndarray
    inertia: np.ndarray
    gravity: float                      # 0.0 when the case has no [gravity] table
    gravity_direction: np.ndarray
    quat0: np.ndarray
    omega0: np.ndarray
    t_end: float
    dt: tuple[float, ...]
    samples: int
    oracle: str | None = None
    horizon: float | None = None
    body_torque: BodyTorque | None = None
    central_field: CentralField | None = None
    path: Path | None = None

    @property
    def body(self) -> RigidBody:
        return RigidBody(self.inertia, self.mass, self.com, self.gravity, self.gravity_direction)
