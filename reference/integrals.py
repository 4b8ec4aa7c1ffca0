"""First integrals and invariant relations of the body with a fixed point (FORMULARY G3–G8), with their drift.

Each Integral says when it applies (structural conditions on the body and, for invariant relations, on the initial
state), how to evaluate it along a recorded trajectory, and the scale that makes its drift relative (DESIGN §4: the
sum of the absolute values of its terms at t = 0; for a dot product the product of the norms, for a vector its norm).

Quaternions given to `value` may be slightly off unit length (engines' raw output): they are normalised before R is
built, except by the Casimir, which measures exactly that defect. Inertia tensors may be non-diagonal: principal
frames come from numpy.linalg.eigh and are made right-handed.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from . import torques
from .body import RigidBody
from .euler_poisson import downward_vertical
from .rotations import quat_to_matrix
from .torque_models.central_field import CentralField

# Relative tolerance of the structural conditions (equal moments, com in a plane, K_H = 0, ...). A case satisfies
# them to rounding (1e-16) or not at all; 1e-9 leaves room for moments computed from a rotated inertia tensor.
STRUCTURE_RTOL = 1e-9


def _never(body: RigidBody) -> bool:
    return False


def _always(body: RigidBody) -> bool:
    return True


@dataclass(frozen=True)
class Integral:
    """A conserved quantity of the motion: the one declaration of its drift column (DESIGN §7).

    name: column stem; the drift column is f"{name}_drift" (`column`), in INTEGRALS' order.
    applies(body, quat0 (4,), omega0 (3,) rad/s body) -> bool: the structural conditions hold.
    value(body, quat (n, 4), omega (n, 3) rad/s body) -> (n,) or (n, 3) (a world vector).
    scale(body, quat0, omega0) -> float > 0: what a drift is divided by.
    exact: the value the integral must keep whatever the initial state (the Casimir's 1), or None to measure the
        drift from the value at t = 0.
    under_torque(body) -> bool: it keeps its meaning under the body's external torque (the energy as its balance,
        harness.metrics); without one, `applies` alone decides.
    Display, read by every table, figure and page: short (the drift tables' header), label (the invariants
    figure's axis; None: not drawn), graded (report.html colours its cells by size), definition (the report's
    Definitions).
    """

    name: str
    applies: Callable[[RigidBody, np.ndarray, np.ndarray], bool]
    value: Callable[[RigidBody, np.ndarray, np.ndarray], np.ndarray]
    scale: Callable[[RigidBody, np.ndarray, np.ndarray], float]
    exact: float | None = None
    under_torque: Callable[[RigidBody], bool] = _never
    short: str = ""
    label: str | None = None
    graded: bool = True
    definition: str = ""

    @property
    def column(self) -> str:
        return f"{self.name}_drift"


def drift(integral: Integral, body: RigidBody, quat: np.ndarray, omega: np.ndarray) -> float:
    """max over finite samples of |I(t) - I(0)| / scale (Euclidean norm for a vector integral).

    quat (n, 4), omega (n, 3) rad/s body, sample 0 is t = 0. NaN if the integral does not apply, or if the initial
    value or every sample is non-finite (a diverged run keeps the drift of its finite samples).
    """
    quat = np.atleast_2d(np.asarray(quat, dtype=float))
    omega = np.atleast_2d(np.asarray(omega, dtype=float))
    if quat.shape[0] == 0 or not (np.all(np.isfinite(quat[0])) and np.all(np.isfinite(omega[0]))):
        return float("nan")
    if not integral.applies(body, quat[0], omega[0]):
        return float("nan")
    values = np.asarray(integral.value(body, quat, omega), dtype=float)
    reference = values[0] if integral.exact is None else integral.exact
    deviation = values - reference
    if deviation.ndim == 2:
        deviation = np.linalg.norm(deviation, axis=-1)
    deviation = np.abs(deviation)
    finite = deviation[np.isfinite(deviation)]
    if finite.size == 0:
        return float("nan")
    return float(np.max(finite) / integral.scale(body, quat[0], omega[0]))


def _nonzero(scale: float) -> float:
    """A scale that is exactly 0 (a body at rest, say) would make every drift infinite: use 1 (absolute drift)."""
    return float(scale) if scale != 0.0 else 1.0


def _as_rows(quat: np.ndarray, omega: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return np.asarray(quat, dtype=float), np.asarray(omega, dtype=float)


def _close(a: float, b: float) -> bool:
    return abs(a - b) <= STRUCTURE_RTOL * max(abs(a), abs(b))


def _principal(body: RigidBody) -> tuple[np.ndarray, np.ndarray]:
    """Principal moments (ascending) and a right-handed frame: columns of the (3, 3) matrix are the axes."""
    moments, axes = np.linalg.eigh(body.inertia)
    if np.linalg.det(axes) < 0:
        axes[:, 2] = -axes[:, 2]
    return moments, axes


def _plane_frame(axis: np.ndarray, hint: np.ndarray) -> np.ndarray:
    """Right-handed (3, 3) frame (e1, e2, axis) as columns, e1 along the part of hint orthogonal to axis."""
    e1 = hint - (hint @ axis) * axis
    e1 = e1 / np.linalg.norm(e1)
    return np.column_stack([e1, np.cross(axis, e1), axis])


def _equatorial_frame(body: RigidBody) -> tuple[np.ndarray, float]:
    """For a body with two equal larger moments: frame (e1, e2, u3), u3 the axis of the smallest moment A3.

    e1 lies along the com's part in the equatorial plane (any e1 in that plane serves the Kovalevskaya modulus; this
    choice is the Goryachev–Chaplygin frame), or along the middle principal axis when the com has no such part.
    """
    moments, axes = _principal(body)
    u3 = axes[:, 0]
    com_plane = body.com - (body.com @ u3) * u3
    hint = com_plane if np.linalg.norm(com_plane) > 0.0 else axes[:, 1]
    return _plane_frame(u3, hint), float(moments[0])


def _com_in_plane(body: RigidBody, normal: np.ndarray) -> bool:
    return abs(body.com @ normal) <= STRUCTURE_RTOL * np.linalg.norm(body.com)


# --- energy (G3) --------------------------------------------------------------------------------------------------

def _kinetic(body: RigidBody, omega: np.ndarray) -> np.ndarray:
    return 0.5 * np.einsum("...i,ij,...j->...", omega, body.inertia, omega)


def _potential(body: RigidBody, quat: np.ndarray) -> np.ndarray:
    return -downward_vertical(body, quat) @ body.weight_moment


def _energy_value(body, quat, omega):
    quat, omega = _as_rows(quat, omega)
    return _kinetic(body, omega) + _potential(body, quat)


def _energy_scale(body, quat0, omega0):
    quat0, omega0 = _as_rows(quat0, omega0)
    return _nonzero(abs(_kinetic(body, omega0)) + abs(_potential(body, quat0)))


# --- angular momentum about O (G3, G4) --------------------------------------------------------------------------

def _momentum_value(body, quat, omega):
    """World vector K = R σω without torque; its vertical component K·d = σω·H under gravity; K·D along a fixed
    central field's direction D (the gravity-gradient torque H × σH has no component along H)."""
    quat, omega = _as_rows(quat, omega)
    momentum_body = omega @ body.inertia
    field = body.torque(CentralField)
    if field is not None:
        world = np.einsum("...ij,...j->...i", quat_to_matrix(quat), momentum_body)
        return world @ np.asarray(field.direction, dtype=float)
    if body.has_gravity:
        return np.einsum("...i,...i->...", momentum_body, downward_vertical(body, quat))
    return np.einsum("...ij,...j->...i", quat_to_matrix(quat), momentum_body)


def _momentum_scale(body, quat0, omega0):
    return _nonzero(np.linalg.norm(body.inertia @ np.asarray(omega0, dtype=float)))


# --- Casimir -----------------------------------------------------------------------------------------------------

def _casimir_value(body, quat, omega):
    """|q|² of the raw quaternion: the R built homogeneously from q is |q|² times a rotation, so this is |H|."""
    quat = np.asarray(quat, dtype=float)
    return np.sum(quat * quat, axis=-1)


# --- Lagrange (G5) -----------------------------------------------------------------------------------------------

def _symmetry_axis(body: RigidBody) -> np.ndarray | None:
    """The axis of the distinct principal moment of a symmetric body (None if the moments are all distinct).

    For a spherical body any axis is one: the com direction is the one whose component of ω gravity conserves.
    """
    moments, axes = _principal(body)
    low_pair, high_pair = _close(moments[0], moments[1]), _close(moments[1], moments[2])
    if low_pair and high_pair:
        norm = np.linalg.norm(body.com)
        return body.com / norm if norm > 0.0 else axes[:, 2]
    if high_pair:
        return axes[:, 0]
    if low_pair:
        return axes[:, 2]
    return None


def _lagrange_applies(body, quat0, omega0):
    axis = _symmetry_axis(body)
    if axis is None:
        return False
    return (not body.has_gravity) or bool(
        np.linalg.norm(np.cross(body.com, axis)) <= STRUCTURE_RTOL * np.linalg.norm(body.com))


def _lagrange_value(body, quat, omega):
    axis = _symmetry_axis(body)
    if axis is None:  # value is also called on bodies that fail the predicate (tests); the largest moment's axis
        axis = _principal(body)[1][:, 2]
    return np.asarray(omega, dtype=float) @ axis


def _lagrange_scale(body, quat0, omega0):
    return _nonzero(np.linalg.norm(omega0))


# --- Kovalevskaya (G6) -------------------------------------------------------------------------------------------

def _kovalevskaya_applies(body, quat0, omega0):
    moments, axes = _principal(body)
    return (body.has_gravity and _close(moments[1], moments[2]) and _close(moments[1], 2.0 * moments[0])
            and _com_in_plane(body, axes[:, 0]))


def _kovalevskaya_parts(body, quat, omega):
    """(p1 + i p2)², (m g/A3)(c1 + i c2)(H1 + i H2) in the equatorial frame."""
    frame, a3 = _equatorial_frame(body)
    quat, omega = _as_rows(quat, omega)
    p = omega @ frame
    h = downward_vertical(body, quat) @ frame
    c = body.com @ frame
    spin = (p[..., 0] + 1j * p[..., 1]) ** 2
    weight = body.mass * body.gravity / a3 * (c[0] + 1j * c[1]) * (h[..., 0] + 1j * h[..., 1])
    return spin, weight


def _kovalevskaya_value(body, quat, omega):
    """|w|², w = (p1 + i p2)² + (m g/A3)(c1 + i c2)(H1 + i H2); plus sign because H points down (G6)."""
    spin, weight = _kovalevskaya_parts(body, quat, omega)
    return np.abs(spin + weight) ** 2


def _kovalevskaya_scale(body, quat0, omega0):
    spin, weight = _kovalevskaya_parts(body, quat0, omega0)
    return _nonzero(float((np.abs(spin) + np.abs(weight)) ** 2))


# --- Goryachev–Chaplygin (G8) -----------------------------------------------------------------------------------

def _momentum_along_vertical_is_zero(body, quat0, omega0) -> bool:
    momentum = body.inertia @ np.asarray(omega0, dtype=float)
    vertical = downward_vertical(body, np.asarray(quat0, dtype=float))
    return abs(momentum @ vertical) <= STRUCTURE_RTOL * np.linalg.norm(momentum) * np.linalg.norm(vertical)


def _chaplygin_applies(body, quat0, omega0):
    moments, axes = _principal(body)
    return (body.has_gravity and _close(moments[1], moments[2]) and _close(moments[1], 4.0 * moments[0])
            and _com_in_plane(body, axes[:, 0]) and _momentum_along_vertical_is_zero(body, quat0, omega0))


def _chaplygin_terms(body, quat, omega):
    """(p1² + p2²) p3 and λ² p1 H3, λ² = m g |c| / A3, in the frame with e1 along the com."""
    frame, a3 = _equatorial_frame(body)
    quat, omega = _as_rows(quat, omega)
    p = omega @ frame
    h = downward_vertical(body, quat) @ frame
    lambda2 = body.mass * body.gravity * (body.com @ frame[:, 0]) / a3
    return (p[..., 0] ** 2 + p[..., 1] ** 2) * p[..., 2], lambda2 * p[..., 0] * h[..., 2]


def _chaplygin_value(body, quat, omega):
    spin, weight = _chaplygin_terms(body, quat, omega)
    return spin + weight


def _chaplygin_scale(body, quat0, omega0):
    spin, weight = _chaplygin_terms(body, quat0, omega0)
    return _nonzero(float(abs(spin) + abs(weight)))


# --- Hess invariant relation (G7) --------------------------------------------------------------------------------

def _com_direction(body: RigidBody) -> np.ndarray:
    norm = np.linalg.norm(body.com)
    return body.com / norm if norm > 0.0 else np.array([0.0, 0.0, 1.0])


def _hess_applies(body, quat0, omega0):
    if not body.has_gravity:
        return False
    moments, _ = _principal(body)
    if _close(moments[0], moments[1]) or _close(moments[1], moments[2]):
        return False
    k = _com_direction(body)
    plane = _plane_frame(k, np.eye(3)[np.argmin(np.abs(k))])[:, :2]
    gyration = plane.T @ np.linalg.inv(body.inertia) @ plane  # σ⁻¹ restricted to k⊥
    isotropic = (abs(gyration[0, 0] - gyration[1, 1]) + 2.0 * abs(gyration[0, 1])
                 <= STRUCTURE_RTOL * np.trace(gyration))
    momentum = body.inertia @ np.asarray(omega0, dtype=float)
    return bool(isotropic and abs(momentum @ k) <= STRUCTURE_RTOL * np.linalg.norm(momentum))


def _hess_value(body, quat, omega):
    """K·k = σω·k, which stays 0 on the Hess manifold."""
    return (np.asarray(omega, dtype=float) @ body.inertia) @ _com_direction(body)


def _hess_scale(body, quat0, omega0):
    return _nonzero(np.linalg.norm(body.inertia @ np.asarray(omega0, dtype=float)))


def _self_excited_value(body, quat, omega):
    return torques.self_excited_value(body, np.asarray(omega, dtype=float))


def _self_excited_scale(body, quat0, omega0):
    first, second = torques.self_excited_terms(body, np.asarray(omega0, dtype=float))
    return _nonzero(float(abs(first) + abs(second)))


def _momentum_under_torque(body: RigidBody) -> bool:
    """K along a central field's fixed direction is conserved: no orbit rate, no gravity, no other torque."""
    field = body.torque(CentralField)
    return field is not None and field.orbit_rate == 0.0 and not body.has_gravity and len(body.torques) == 1


# The registry of drift columns, in table order. A new invariant is one entry here (DESIGN §7): the results table,
# the drift tables (report.md, --verbose), report.html's grading, the invariants figure and the Definitions read it.
INTEGRALS: dict[str, Integral] = {
    "energy": Integral("energy", lambda body, quat0, omega0: True, _energy_value, _energy_scale,
                       under_torque=_always, short="energy", label="energy |E−E₀|/scale",
                       definition="kinetic + potential of uniform gravity (under an external torque the balance "
                                  "below)"),
    "momentum": Integral("momentum", lambda body, quat0, omega0: True, _momentum_value, _momentum_scale,
                         under_torque=_momentum_under_torque, short="momentum", label="momentum drift",
                         definition="the world angular momentum K about O for a torque-free body, its vertical "
                                    "component K.d under gravity"),
    "casimir": Integral("casimir", lambda body, quat0, omega0: True, _casimir_value,
                        lambda body, quat0, omega0: 1.0, exact=1.0, under_torque=_always, short="casimir",
                        definition="| |q|^2 - 1 | of the recorded quaternion (= ||H| - 1| for the heavy body)"),
    "lagrange": Integral("lagrange", _lagrange_applies, _lagrange_value, _lagrange_scale, short="lagrange",
                         label="Lagrange ω₃ drift", definition="omega along the symmetry axis"),
    "kovalevskaya": Integral("kovalevskaya", _kovalevskaya_applies, _kovalevskaya_value, _kovalevskaya_scale,
                             short="kovalevskaya", label="Kovalevskaya integral",
                             definition="|(p1 + i p2)^2 + (m g / A3)(c1 + i c2)(H1 + i H2)|^2 with H the downward "
                                        "vertical in body axes"),
    "chaplygin": Integral("chaplygin", _chaplygin_applies, _chaplygin_value, _chaplygin_scale, short="chaplygin",
                          label="Goryachev–Chaplygin", definition="(p1^2 + p2^2) p3 + lambda^2 p1 H3"),
    "hess": Integral("hess", _hess_applies, _hess_value, _hess_scale, short="hess", label="Hess K·k drift",
                     definition="K.k"),
    # (36), the conic-cylinder invariant of a body torque along a principal axis (G12)
    "self_excited": Integral("self_excited", lambda body, quat0, omega0: torques.self_excited_applies(body),
                             _self_excited_value, _self_excited_scale, under_torque=_always, short="self_excited",
                             label="self-excited (36)",
                             definition="the conic-cylinder invariant (36) A1/(A2-A3) p1^2 - A2/(A3-A1) p2^2 in the "
                                        "principal frame with i3 along the torque axis (any torque along i3, no "
                                        "other torque)"),
}
DRIFT_COLUMNS = tuple(integral.column for integral in INTEGRALS.values())


def applicable(body: RigidBody, quat0: np.ndarray, omega0: np.ndarray) -> tuple[str, ...]:
    """The names of the integrals this body and initial state have: structural conditions, and under an external
    torque only those that keep their meaning."""
    return tuple(name for name, integral in INTEGRALS.items() if integral.applies(body, quat0, omega0)
                 and (not body.has_external_torque or integral.under_torque(body)))
