"""Stationary rotations of the torque-free body about its principal axes (FORMULARY T8).

For ω = w e_j (principal axes I1 > I2 > I3, α1 = (I2 - I3)/I1, α3 = (I1 - I2)/I3) the linearised Euler equations
are hyperbolic about e2 (exponents 0, ±|w|√(α1 α3)) and elliptic about e1 and e3.
"""
from __future__ import annotations

import math

import numpy as np

from ..body import RigidBody
from ..closed_form import principal_axes


def _triaxial_moments(body: RigidBody) -> tuple[np.ndarray, np.ndarray]:
    moments, axes = principal_axes(body.inertia)
    if not (moments[0] > moments[1] > moments[2]):
        raise ValueError("stationary-rotation exponents need three distinct principal moments")
    return moments, axes


def lyapunov_exponent(body: RigidBody, rate: float) -> float:
    """|w| √((I1 - I2)(I2 - I3) / (I1 I3)) (1/s): the growth rate of perturbations of the rotation ω = w e2 about
    the middle axis (rate = w, rad/s)."""
    (i1, i2, i3), _ = _triaxial_moments(body)
    return abs(rate) * math.sqrt((i1 - i2) * (i2 - i3) / (i1 * i3))


def unstable_direction(body: RigidBody, rate: float) -> np.ndarray:
    """The unit perturbation δω (3,) body of ω = w e2 that grows like e^{μ t}: the eigenvector (α1 w, μ) of the
    Jacobian [[0, α1 w], [α3 w, 0]] on (δω1, δω3)."""
    (i1, i2, i3), axes = _triaxial_moments(body)
    exponent = lyapunov_exponent(body, rate)
    direction = (i2 - i3) / i1 * rate * axes[:, 0] + exponent * axes[:, 2]
    return direction / np.linalg.norm(direction)


def oscillation_frequencies(body: RigidBody, rate: float) -> tuple[float, float]:
    """Small-oscillation angular frequencies (rad/s) of ω about the stationary rotations ω = w e1 and ω = w e3:
    (|w| √((I1 - I2)(I1 - I3) / (I2 I3)), |w| √((I1 - I3)(I2 - I3) / (I1 I2)))."""
    (i1, i2, i3), _ = _triaxial_moments(body)
    w = abs(rate)
    return w * math.sqrt((i1 - i2) * (i1 - i3) / (i2 * i3)), w * math.sqrt((i1 - i3) * (i2 - i3) / (i1 * i2))
