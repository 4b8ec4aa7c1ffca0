"""Grioli's generalized-precession torque (41) with u = i3 and θ, l, M3 constant, σ diagonal (FORMULARY G14): every
initial state precesses about the space-fixed axis e (40). Singular at ω ∥ u. Not potential."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..rotations import quat_to_matrix
from .base import TorqueModel, models, register

# Torque (41) is singular at ω ∥ u; within this angle (rad) of it a run is skipped and the axis drift not measured:
# at 0.05 rad the 1/|ω × u| of (40) amplifies an ω error twentyfold, and the sqrt's derivatives grow as 1/angle.
PRECESSION_SINGULAR_ANGLE = 0.05
MIN_SIN_THETA = 1e-9       # cot θ stays <= 1e9


def precession_components(a1, a2, a3, cot, ell, m3, omega, rho) -> list:
    """Torque (41) (G14), u = i3, σ = diag(a1, a2, a3): cot = cot θ, ell = l, m3 = M3, ω body components and
    rho = √(ω1² + ω2²) (the caller's square root)."""
    p1, p2, p3 = omega[0], omega[1], omega[2]
    return [((a3 - a2 + a1) * p3 - cot * a1 * rho) * p2 + ell * p1 / a2,
            ((a1 - a3 - a2) * p3 + cot * a2 * rho) * p1 + ell * p2 / a1,
            m3]


@register
@dataclass(frozen=True)
class PrecessionTorque(TorqueModel):
    """Grioli's generalized-precession torque (41), u = i3 (principal axes at O): theta rad, l N m kg m^2 (the
    coefficient l(p), constant), m3 N m (M3(p), constant). Case table [precession_torque]: the only torque, diagonal
    inertia. Parameters: cot θ, l, M3, on (1/0), ε: ρ = √(p1² + p2² + ε), ε = 1 when the torque is absent, so the
    Taylor series of √ never meets 0 on a motion with ω ∥ i3."""

    theta: float
    l: float
    m3: float

    key = "precession_torque"
    schema = (frozenset({"theta", "l", "m3"}), frozenset({"theta", "l", "m3"}))
    parameter_count = 5
    columns = ("precession_axis_drift",)

    @classmethod
    def parse(cls, reader, data) -> "PrecessionTorque":
        reader.table(data, cls.key, cls.schema)
        theta = reader.number(data["theta"], "precession_torque.theta")
        if not 0.0 < theta < math.pi:
            raise reader.fail("precession_torque.theta", f"must be in (0, pi) rad, got {theta:g}")
        if math.sin(theta) < MIN_SIN_THETA:
            raise reader.fail("precession_torque.theta", f"sin theta must be >= {MIN_SIN_THETA:g} (cot theta is a "
                                                         f"coefficient of the torque), got theta = {theta:.17g}")
        return cls(theta=theta, l=reader.number(data["l"], "precession_torque.l"),
                   m3=reader.number(data["m3"], "precession_torque.m3"))

    def check(self, reader, tables, inertia, com) -> None:
        others = [f"[{key}]" for key in ("gravity", *(m.key for m in models() if m is not type(self))) if key in tables]
        if others:
            raise reader.fail("precession_torque", f"must be the only torque (G14: every motion precesses only "
                                                   f"under (41) alone), remove {', '.join(others)}")
        if np.any(inertia != np.diag(np.diag(inertia))):
            raise reader.fail("precession_torque", "needs principal body axes (torque (41) is written with "
                                                   "u = i3 in principal components): inertia must be diagonal")

    @classmethod
    def absent(cls) -> tuple[float, ...]:
        return (0.0, 0.0, 0.0, 0.0, 1.0)

    def parameters(self, frame=None) -> tuple[float, ...]:
        return (1.0 / np.tan(self.theta), self.l, self.m3, 1.0, 0.0)

    @staticmethod
    def components(p, at) -> list:
        cot, ell, m3, on, eps = p[0], p[1], p[2], p[3], p[4]
        p1, p2 = at.omega[0], at.omega[1]
        rho = at.sqrt(p1 * p1 + p2 * p2 + eps)
        sigma = at.sigma
        torque = precession_components(sigma[0][0], sigma[1][1], sigma[2][2], cot, ell, m3, at.omega, rho)
        return [on * torque[0], on * torque[1], on * torque[2]]

    def singular(self, omega0) -> str | None:
        angle = float(transverse_angle(np.asarray(omega0, dtype=float)))
        if angle < PRECESSION_SINGULAR_ANGLE:
            return (f"[precession_torque] singular: omega0 within {angle:.3g} rad of u = i3 (torque (41) needs "
                    f">= {PRECESSION_SINGULAR_ANGLE:g} rad)")
        return None

    def metrics(self, body, quat, omega) -> dict[str, float]:
        """precession_axis_drift (G14): max |e(t) − e(0)| of the world precession axis (40), NaN when a sample comes
        within PRECESSION_SINGULAR_ANGLE of ω ∥ u (the axis is undefined there)."""
        if np.min(transverse_angle(omega)) < PRECESSION_SINGULAR_ANGLE:
            return {"precession_axis_drift": math.nan}
        axis = precession_axis(body, quat, omega)
        return {"precession_axis_drift": float(np.max(np.linalg.norm(axis - axis[0], axis=1)))}


def precession_axis(body, quat: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """(40) e = sin θ (ω − (ω·u)u)/|ω × u| + cos θ u in world components, u = i3: (..., 3)."""
    theta = body.torque(PrecessionTorque).theta
    omega = np.asarray(omega, dtype=float)
    transverse = omega * np.array([1.0, 1.0, 0.0])
    with np.errstate(invalid="ignore", divide="ignore"):
        e = np.sin(theta) * transverse / np.linalg.norm(transverse, axis=-1, keepdims=True)
    e = e + np.cos(theta) * np.array([0.0, 0.0, 1.0])
    return np.einsum("...ij,...j->...i", quat_to_matrix(quat), e)


def transverse_angle(omega: np.ndarray) -> np.ndarray:
    """The angle (rad) between ω and u = i3, folded to [0, π/2]: 0 at the singularity of (41)."""
    omega = np.asarray(omega, dtype=float)
    return np.arctan2(np.linalg.norm(omega[..., :2], axis=-1), np.abs(omega[..., 2]))
