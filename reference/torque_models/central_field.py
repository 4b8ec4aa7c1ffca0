"""The gravity-gradient torque of a Newtonian attracting centre (002 §III, FORMULARY G15), O the centre of mass:
M = (3μ/r³) H × σH, H the body components of the unit vector centre -> O; in the world that vector is D0 fixed, or
D0 turned about world z by orbit_rate t. Potential: MacCullagh's (3μ/2r³) H·σH.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..rotations import quat_to_matrix
from .base import TorqueModel, register


def gravity_gradient_components(coefficient, sigma, h) -> list:
    """(3μ/r³) H × σH (G15): coefficient 3μ/r³ (1/s²), sigma rows (kg m²), H the body components of the unit vector
    centre -> O."""
    sh = [sigma[i][0] * h[0] + sigma[i][1] * h[1] + sigma[i][2] * h[2] for i in range(3)]
    return [coefficient * (h[1] * sh[2] - h[2] * sh[1]), coefficient * (h[2] * sh[0] - h[0] * sh[2]),
            coefficient * (h[0] * sh[1] - h[1] * sh[0])]


def direction_components(p, at) -> list:
    """D(t) = cos Ωt Da + sin Ωt Db + Dc from the block p (layout of CentralField.parameters)."""
    phase = p[10] * at.t
    cos_phase, sin_phase = at.cos(phase), at.sin(phase)
    return [cos_phase * p[1] + sin_phase * p[4] + p[7], cos_phase * p[2] + sin_phase * p[5] + p[8],
            cos_phase * p[3] + sin_phase * p[6] + p[9]]  # unrolled: an engine's stage calls it (floats)


@register
@dataclass(frozen=True)
class CentralField(TorqueModel):
    """Newtonian attracting centre (002 §III). mu: m^3/s^2; radius: m; direction: (3,) world unit centre -> O at t=0;
    orbit_rate: rad/s about world z. Case table [central_field] (needs com = 0). Potential. Parameters: 3μ/r³,
    Da = (D0x, D0y, 0), Db = ẑ × Da, Dc = (0, 0, D0z) (each in the coordinates' frame), Ω."""

    mu: float
    radius: float
    direction: tuple[float, float, float]
    orbit_rate: float

    key = "central_field"
    schema = (frozenset({"mu", "radius", "direction", "orbit_rate"}), frozenset({"mu", "radius", "direction"}))
    parameter_count = 11
    potential = True
    energy_name = "field"

    @property
    def coefficient(self) -> float:
        """3 μ / r³, 1/s²."""
        return 3.0 * self.mu / self.radius ** 3

    @classmethod
    def parse(cls, reader, data) -> "CentralField":
        reader.table(data, cls.key, cls.schema)
        return cls(
            mu=reader.positive(data["mu"], "central_field.mu"),
            radius=reader.positive(data["radius"], "central_field.radius"),
            direction=tuple(reader.unit(data["direction"], "central_field.direction", 3, "direction", "d").tolist()),
            orbit_rate=reader.number(data.get("orbit_rate", 0.0), "central_field.orbit_rate"))

    def check(self, reader, tables, inertia, com) -> None:
        if np.any(com != 0.0):
            raise reader.fail("body.com", "must be [0, 0, 0] with [central_field] (O is the centre of mass)")

    def parameters(self, frame=None) -> tuple[float, ...]:
        d = np.asarray(self.direction, dtype=float)
        basis = np.eye(3) if frame is None else np.asarray(frame, dtype=float)
        return (self.coefficient, *(basis.T @ np.array([d[0], d[1], 0.0])), *(basis.T @ np.array([-d[1], d[0], 0.0])),
                *(basis.T @ np.array([0.0, 0.0, d[2]])), self.orbit_rate)

    @staticmethod
    def components(p, at) -> list:
        return gravity_gradient_components(p[0], at.sigma, at.body(direction_components(p, at)))

    def potential_energy(self, body, times, quat) -> np.ndarray:
        """MacCullagh's potential (3μ/2r³) H·σH, (n,) J."""
        h = field_direction_body(self, times, quat)
        return 0.5 * self.coefficient * np.einsum("...i,ij,...j->...", h, body.inertia, h)

    @property
    def frame_rate(self) -> float:
        return float(self.orbit_rate)


def field_direction_world(field: CentralField, t) -> np.ndarray:
    """(..., 3) world unit vector centre -> O at times t (...,) s."""
    t = np.asarray(t, dtype=float)
    d = np.asarray(field.direction, dtype=float)
    c, s = np.cos(field.orbit_rate * t), np.sin(field.orbit_rate * t)
    return np.stack([c * d[0] - s * d[1], s * d[0] + c * d[1], np.broadcast_to(d[2], t.shape)], axis=-1)


def field_direction_body(field: CentralField, t, quat: np.ndarray) -> np.ndarray:
    """H = Rᵀ D(t): (..., 3) body frame."""
    return np.einsum("...ji,...j->...i", quat_to_matrix(quat), field_direction_world(field, t))
