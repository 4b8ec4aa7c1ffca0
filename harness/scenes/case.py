"""What a rigid-body case is (DESIGN §3): the frozen Case that harness.scenes.cases reads from a file and every
layer runs. Its own module, light (the body and the torque terms only), so that the engines' protocol names it without
importing the case files' readers and the exact solutions (tests/test_import_chain.py)."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ...reference.body import RigidBody
from ...reference.torque_models.base import TorqueModel, ordered

RIGID_BODY = "rigid_body"  # the scene kind (top-level `kind`, the default)


@dataclass(frozen=True, eq=False)
class Case:
    """One scene (DESIGN §3), validated.

    inertia: (3, 3) kg m^2 about O, body frame. com: (3,) m body frame. gravity_direction: (3,) world unit.
    quat0: (4,) initial attitude, scalar first, body -> world, unit. omega0: (3,) rad/s, body frame.
    dt: the steps to sweep, s. path: the file it came from (None for a case built in code).
    torques: the external torques beyond gravity (reference.torque_models' terms, registry order; RigidBody's);
    torque(model) reads one (None: absent).
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
    path: Path | None = None
    kind: str = RIGID_BODY
    physical: bool = True               # [body] physical = false: the triangle inequalities are not required
    torques: tuple[TorqueModel, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "torques", ordered(self.torques))

    def torque(self, model: type) -> TorqueModel | None:
        """The case's term of a torque model (a class of reference.torque_models), or None."""
        return next((term for term in self.torques if type(term) is model), None)

    @property
    def body(self) -> RigidBody:
        return RigidBody(self.inertia, self.mass, self.com, self.gravity, self.gravity_direction,
                         torques=self.torques)

    @property
    def source(self) -> str:
        """Where the case came from, for messages: its file, or its name for a case built in code."""
        return str(self.path) if self.path is not None else self.name
