"""The external torques beyond uniform gravity (FORMULARY G12–G15), each defined once: its parameters (a frozen
dataclass a RigidBody holds) and its formula in body components, written in plain arithmetic so that one definition
serves floats (the engines' per-stage closures, reference.torques.torque_function), numpy arrays (reference.torques'
vectorised forms) and heyoka expressions (the truth's equations, reference.truth.torque_expressions).

The formulas take and return 3-sequences of components; a square root, where one is needed, is the caller's (math,
numpy and heyoka each have their own). reference.body imports this module and nothing else of the torques, so the
body and the torque evaluation (reference.torques) do not import each other.
"""
from __future__ import annotations

from dataclasses import dataclass


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

    @property
    def coefficient(self) -> float:
        """3 μ / r³, 1/s²."""
        return 3.0 * self.mu / self.radius ** 3


@dataclass(frozen=True)
class PrecessionTorque:
    """Grioli's generalized-precession torque (41), u = i3 (principal axes at O): theta rad, l N m kg m^2 (the
    coefficient l(p), constant), m3 N m (M3(p), constant)."""

    theta: float
    l: float
    m3: float


def body_torque_components(axis, a, b, omega) -> list:
    """(a + b |ω|²) u (002 eq. 30): axis u, coefficients a (N m), b (N m s²), ω (rad/s) body components."""
    magnitude = a + b * (omega[0] * omega[0] + omega[1] * omega[1] + omega[2] * omega[2])
    return [magnitude * axis[0], magnitude * axis[1], magnitude * axis[2]]


def gravity_gradient_components(coefficient, sigma, h) -> list:
    """(3μ/r³) H × σH (G15): coefficient 3μ/r³ (1/s²), sigma rows (kg m²), H the body components of the unit vector
    centre -> O."""
    sh = [sigma[i][0] * h[0] + sigma[i][1] * h[1] + sigma[i][2] * h[2] for i in range(3)]
    return [coefficient * (h[1] * sh[2] - h[2] * sh[1]), coefficient * (h[2] * sh[0] - h[0] * sh[2]),
            coefficient * (h[0] * sh[1] - h[1] * sh[0])]


def precession_components(a1, a2, a3, cot, ell, m3, omega, rho) -> list:
    """Torque (41) (G14), u = i3, σ = diag(a1, a2, a3): cot = cot θ, ell = l, m3 = M3, ω body components and
    rho = √(ω1² + ω2²) (the caller's square root)."""
    p1, p2, p3 = omega[0], omega[1], omega[2]
    return [((a3 - a2 + a1) * p3 - cot * a1 * rho) * p2 + ell * p1 / a2,
            ((a1 - a3 - a2) * p3 + cot * a2 * rho) * p1 + ell * p2 / a1,
            m3]
