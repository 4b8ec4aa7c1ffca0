"""The self-excited body's torque M = (a + b |ω|²) u, u fixed in the body (002 eq. 30, FORMULARY G12)."""
from __future__ import annotations

from dataclasses import dataclass

from .base import TorqueModel, register


def body_torque_components(axis, a, b, omega) -> list:
    """(a + b |ω|²) u (002 eq. 30): axis u, coefficients a (N m), b (N m s²), ω (rad/s) body components."""
    magnitude = a + b * (omega[0] * omega[0] + omega[1] * omega[1] + omega[2] * omega[2])
    return [magnitude * axis[0], magnitude * axis[1], magnitude * axis[2]]


@register
@dataclass(frozen=True)
class BodyTorque(TorqueModel):
    """M = (a + b |omega|^2) axis, body frame (002 eq. 30). axis: (3,) unit, body frame; a: N m; b: N m s^2.
    Case table [body_torque]: axis, a, b. Not potential (it does work). Parameters: u (3), a, b."""

    axis: tuple[float, float, float]
    a: float
    b: float

    key = "body_torque"
    schema = (frozenset({"axis", "a", "b"}), frozenset({"axis", "a", "b"}))
    parameter_count = 5
    oracles = ("self_excited_spinup", "self_excited_uniform")

    @classmethod
    def parse(cls, reader, data) -> "BodyTorque":
        reader.table(data, cls.key, cls.schema)
        axis = reader.unit(data["axis"], "body_torque.axis", 3, "axis", "axis")
        return cls(axis=tuple(axis.tolist()), a=reader.number(data["a"], "body_torque.a"),
                   b=reader.number(data["b"], "body_torque.b"))

    def parameters(self, frame=None) -> tuple[float, ...]:
        return (*self.axis, self.a, self.b)

    @staticmethod
    def components(p, at) -> list:
        return body_torque_components(p[0:3], p[3], p[4], at.omega)

    @property
    def constant(self) -> bool:
        return self.b == 0.0
