"""Canarutto's ZXZ Euler angles (seed 003, FORMULARY C1–C5) and Lagrange's equations of the body with a fixed point.

Angles α = (φ, θ, ψ) (rad), R = Rz(φ) Rx(θ) Rz(ψ) relative to a reference frame (the world, or a chart's rotated
frame); rates α̇ (rad/s). The chart is singular at θ = 0 and θ = π (gimbal lock), where φ and ψ rotate about the same
axis: det J = -sin θ below.

Kinetic energy T = ½ ω'·σ ω' with ω' = J(θ, ψ) α̇ the body components of ω (C4), for any σ (C5 for principal
moments); potential V = -U, U = n·R(α) w with w = m g (O -> G) (body frame, N m) and n the unit downward vertical in the
reference frame. Lagrange's equations d/dt ∂T/∂α̇ - ∂T/∂α = ∂U/∂α + Q give M(α) α̈ = f with M = Jᵀ σ J; Q = Jᵀ M
(Q_h = M·∂ω'/∂α̇_h) is the generalized force of every other torque M (reference.torque_models, body components),
written explicitly (the body torque and torque (41) have no potential; the central field's direction turns).

Numpy functions are vectorised over leading axes: angles and rates (..., 3), matrices (..., 3, 3).
"""
from __future__ import annotations

import heyoka as hy
import numpy as np

from . import expressions as ex
from . import truth
from .rotations import matrix_to_zxz, quat_mul, quat_to_matrix


def _split(angles: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    angles = np.asarray(angles)
    return angles[..., 0], angles[..., 1], angles[..., 2]


def _rows(*rows) -> np.ndarray:
    return np.stack([np.stack(row, axis=-1) for row in rows], axis=-2)


def rotation_matrix(angles: np.ndarray) -> np.ndarray:
    """C1, the printed matrix: columns are the body axes e'_i in the reference frame (..., 3, 3). Accepts complex
    angles (complex-step tests)."""
    phi, theta, psi = _split(angles)
    cf, sf, ct, st, cp, sp = np.cos(phi), np.sin(phi), np.cos(theta), np.sin(theta), np.cos(psi), np.sin(psi)
    return _rows((cf * cp - sf * ct * sp, -cf * sp - sf * ct * cp, sf * st),
                 (sf * cp + cf * ct * sp, -sf * sp + cf * ct * cp, -cf * st),
                 (st * sp, st * cp, ct))


def to_quat(angles: np.ndarray) -> np.ndarray:
    """(..., 3) -> (..., 4) unit quaternion (w, x, y, z) of Rz(φ) Rx(θ) Rz(ψ), a product of half-angle quaternions."""
    phi, theta, psi = _split(np.asarray(angles, dtype=float))
    zero = np.zeros_like(phi)
    about_z = lambda a: np.stack([np.cos(0.5 * a), zero, zero, np.sin(0.5 * a)], axis=-1)  # noqa: E731
    about_x = np.stack([np.cos(0.5 * theta), np.sin(0.5 * theta), zero, zero], axis=-1)
    return quat_mul(quat_mul(about_z(phi), about_x), about_z(psi))


def from_quat(quat: np.ndarray) -> np.ndarray:
    """(..., 4) -> (..., 3) angles with θ in [0, π] (rotations.matrix_to_zxz)."""
    return np.stack(matrix_to_zxz(quat_to_matrix(quat)), axis=-1)


def jacobian(angles: np.ndarray) -> np.ndarray:
    """J with ω' = J α̇ (C4), (..., 3, 3):
    ω'1 = φ̇ sin θ sin ψ + θ̇ cos ψ, ω'2 = φ̇ sin θ cos ψ - θ̇ sin ψ, ω'3 = φ̇ cos θ + ψ̇."""
    _, theta, psi = _split(angles)
    ct, st, cp, sp = np.cos(theta), np.sin(theta), np.cos(psi), np.sin(psi)
    zero, one = np.zeros_like(theta), np.ones_like(theta)
    return _rows((st * sp, cp, zero), (st * cp, -sp, zero), (ct, zero, one))


def inverse_jacobian(angles: np.ndarray) -> np.ndarray:
    """J⁻¹ = (1/sin θ) [[sin ψ, cos ψ, 0], [sin θ cos ψ, -sin θ sin ψ, 0], [-cos θ sin ψ, -cos θ cos ψ, sin θ]]."""
    _, theta, psi = _split(angles)
    ct, st, cp, sp = np.cos(theta), np.sin(theta), np.cos(psi), np.sin(psi)
    zero = np.zeros_like(theta)
    return _rows((sp, cp, zero), (st * cp, -st * sp, zero), (-ct * sp, -ct * cp, st)) / st[..., None, None]


def _jacobian_theta(theta, psi) -> np.ndarray:
    """∂J/∂θ."""
    ct, st, cp, sp = np.cos(theta), np.sin(theta), np.cos(psi), np.sin(psi)
    zero = np.zeros_like(theta)
    return _rows((ct * sp, zero, zero), (ct * cp, zero, zero), (-st, zero, zero))


def _jacobian_psi(theta, psi) -> np.ndarray:
    """∂J/∂ψ."""
    st, cp, sp = np.sin(theta), np.cos(psi), np.sin(psi)
    zero = np.zeros_like(theta)
    return _rows((st * cp, -sp, zero), (-st * sp, -cp, zero), (zero, zero, zero))


def _matvec(m: np.ndarray, v: np.ndarray) -> np.ndarray:
    return np.einsum("...ij,...j->...i", m, v)


def omega_body(angles: np.ndarray, rates: np.ndarray) -> np.ndarray:
    """ω' = J α̇, body components (C4), rad/s."""
    return _matvec(jacobian(angles), np.asarray(rates, dtype=float))


def omega_space(angles: np.ndarray, rates: np.ndarray) -> np.ndarray:
    """ω in reference-frame components (C3):
    (cos φ θ̇ + sin φ sin θ ψ̇, sin φ θ̇ - cos φ sin θ ψ̇, φ̇ + cos θ ψ̇)."""
    phi, theta, _ = _split(np.asarray(angles, dtype=float))
    phid, thetad, psid = _split(np.asarray(rates, dtype=float))
    cf, sf, ct, st = np.cos(phi), np.sin(phi), np.cos(theta), np.sin(theta)
    return np.stack([cf * thetad + sf * st * psid, sf * thetad - cf * st * psid, phid + ct * psid], axis=-1)


def rates_from_omega(angles: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """α̇ = J⁻¹ ω' (singular at sin θ = 0)."""
    return _matvec(inverse_jacobian(angles), np.asarray(omega, dtype=float))


def kinetic_energy_canarutto(angles: np.ndarray, rates: np.ndarray, moments: np.ndarray) -> np.ndarray:
    """C5 for principal moments (A, B, C) (J):
    T = ½[sin²θ (A sin²ψ + B cos²ψ) + C cos²θ] φ̇² + ½(A cos²ψ + B sin²ψ) θ̇² + ½ C ψ̇²
        + (A - B) sin θ sin ψ cos ψ φ̇ θ̇ + C cos θ φ̇ ψ̇."""
    _, theta, psi = _split(np.asarray(angles, dtype=float))
    phid, thetad, psid = _split(np.asarray(rates, dtype=float))
    a, b, c = np.asarray(moments, dtype=float)
    ct, st, cp, sp = np.cos(theta), np.sin(theta), np.cos(psi), np.sin(psi)
    return (0.5 * (st ** 2 * (a * sp ** 2 + b * cp ** 2) + c * ct ** 2) * phid ** 2
            + 0.5 * (a * cp ** 2 + b * sp ** 2) * thetad ** 2 + 0.5 * c * psid ** 2
            + (a - b) * st * sp * cp * phid * thetad + c * ct * phid * psid)


def kinetic_energy(angles: np.ndarray, rates: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """T = ½ ω'·σ ω' with ω' from C4, any σ (J)."""
    omega = omega_body(angles, rates)
    return 0.5 * np.sum(omega * _matvec(np.asarray(sigma, dtype=float), omega), axis=-1)


def mass_matrix(angles: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """M = Jᵀ σ J = ∂²T/∂α̇² (kg m²), singular at sin θ = 0 (det M = sin²θ det σ)."""
    j = jacobian(angles)
    return np.swapaxes(j, -1, -2) @ np.asarray(sigma, dtype=float) @ j


def force_function(angles: np.ndarray, weight_moment: np.ndarray, down: np.ndarray) -> np.ndarray:
    """U = n·R(α) w (J). Accepts complex angles (complex-step tests)."""
    return np.einsum("i,...ij,j->...", np.asarray(down), rotation_matrix(angles), np.asarray(weight_moment))


def generalized_force(angles: np.ndarray, torque_body: np.ndarray) -> np.ndarray:
    """Q = Jᵀ M, M the torque about O in body components (virtual work M·ω' = Q·α̇), N m."""
    return _matvec(np.swapaxes(jacobian(angles), -1, -2), np.asarray(torque_body, dtype=float))


def gravity_torque(angles: np.ndarray, weight_moment: np.ndarray, down: np.ndarray) -> np.ndarray:
    """M = w × H, H = R(α)ᵀ n the downward vertical in body components (N m)."""
    vertical = np.einsum("...ji,j->...i", rotation_matrix(np.asarray(angles, dtype=float)), np.asarray(down))
    return np.cross(weight_moment, vertical)


def lagrange_acceleration(angles: np.ndarray, rates: np.ndarray, sigma: np.ndarray, weight_moment: np.ndarray,
                          down: np.ndarray, sigma_inv: np.ndarray | None = None,
                          torque_body: np.ndarray | None = None) -> np.ndarray:
    """α̈ from Lagrange's equations (rad/s²): with p = ∂T/∂α̇ = Jᵀ σ ω' and J̇ = ∂J/∂θ θ̇ + ∂J/∂ψ ψ̇,
    M α̈ = Q + ∂T/∂α - J̇ᵀ σ ω' - Jᵀ σ J̇ α̇, ∂T/∂α_k = (∂J/∂α_k α̇)·σ ω' (∂J/∂φ = 0), M⁻¹ = J⁻¹ σ⁻¹ J⁻ᵀ;
    Q = Jᵀ (gravity's torque + torque_body), torque_body (..., 3) N m body components (the other torques)."""
    angles, rates = np.asarray(angles, dtype=float), np.asarray(rates, dtype=float)
    sigma = np.asarray(sigma, dtype=float)
    sigma_inv = np.linalg.inv(sigma) if sigma_inv is None else sigma_inv
    _, theta, psi = _split(angles)
    j, j_theta, j_psi = jacobian(angles), _jacobian_theta(theta, psi), _jacobian_psi(theta, psi)
    omega = _matvec(j, rates)
    spin = _matvec(sigma, omega)  # σ ω', the angular momentum in body components
    dt_theta = np.sum(_matvec(j_theta, rates) * spin, axis=-1)
    dt_psi = np.sum(_matvec(j_psi, rates) * spin, axis=-1)
    partials = np.stack([np.zeros_like(dt_theta), dt_theta, dt_psi], axis=-1)
    j_dot = j_theta * rates[..., 1, None, None] + j_psi * rates[..., 2, None, None]
    jt = np.swapaxes(j, -1, -2)
    torque = gravity_torque(angles, weight_moment, down)
    if torque_body is not None:
        torque = torque + torque_body
    force = _matvec(jt, torque)
    f = (force + partials - _matvec(np.swapaxes(j_dot, -1, -2), spin)
         - _matvec(jt, _matvec(sigma, _matvec(j_dot, rates))))
    j_inv = inverse_jacobian(angles)
    return _matvec(j_inv, _matvec(sigma_inv, _matvec(np.swapaxes(j_inv, -1, -2), f)))


def recentred_frame(quat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A chart far from gimbal lock at the attitude quat: reference frame R Rx(-π/2), in which the angles are
    (0, π/2, 0). Returns (frame quaternion (4,), local quaternion (4,) = that of Rx(π/2))."""
    half = np.sqrt(0.5)
    frame = quat_mul(np.asarray(quat, dtype=float), np.array([half, -half, 0.0, 0.0]))
    return frame / np.linalg.norm(frame), np.array([half, half, 0.0, 0.0])


# --- the same, as heyoka expressions (runtime parameters: reference.expressions) ---------------------------------

def _rotation_expr(phi, theta, psi) -> list[list]:
    cf, sf, ct, st, cp, sp = hy.cos(phi), hy.sin(phi), hy.cos(theta), hy.sin(theta), hy.cos(psi), hy.sin(psi)
    return [[cf * cp - sf * ct * sp, -cf * sp - sf * ct * cp, sf * st],
            [sf * cp + cf * ct * sp, -sf * sp + cf * ct * cp, -cf * st],
            [st * sp, st * cp, ct]]


def lagrange_equations() -> tuple[list, list, object]:
    """Lagrange's equations for heyoka: variables (φ, θ, ψ, φ̇, θ̇, ψ̇), right-hand sides, chart measure sin θ.

    p = ∂T/∂α̇, ∂T/∂α, ∂U/∂α and ṗ's explicit part are taken symbolically (hy.diff) from T = ½ ω'·σω' (C4) and U;
    the other torques' Q = Jᵀ M explicitly, M at H = Rᵀ D(t); the mass matrix is inverted in closed form,
    M⁻¹ = J⁻¹ σ⁻¹ J⁻ᵀ. Parameters: reference.truth's layout.
    """
    variables = hy.make_vars("phi", "theta", "psi", "phid", "thetad", "psid")
    angles, rates = variables[:3], variables[3:]
    _, theta, psi = angles
    ct, st, cp, sp = hy.cos(theta), hy.sin(theta), hy.cos(psi), hy.sin(psi)
    phid, thetad, psid = rates
    omega = [st * sp * phid + cp * thetad, st * cp * phid - sp * thetad, ct * phid + psid]  # C4
    kinetic = 0.5 * ex.dot(omega, ex.matvec(ex.symmetric(ex.SIGMA), omega))
    rotation = _rotation_expr(*angles)
    potential = ex.dot(ex.vector(ex.DOWN), ex.matvec(rotation, ex.vector(ex.WEIGHT_MOMENT)))
    momentum = [hy.diff(kinetic, rates[k]) for k in range(3)]
    torque = truth.body_torque_expressions(  # Rᵀ D for a vector D of the chart's reference frame
        lambda d: [hy.sum([rotation[j][i] * d[j] for j in range(3)]) for i in range(3)], omega, ex.symmetric(ex.SIGMA))
    jacobian_t = [[st * sp, st * cp, ct], [cp, -sp, 0.0], [0.0, 0.0, 1.0]]  # Jᵀ (C4)
    external = ex.matvec(jacobian_t, torque)
    f = [hy.diff(kinetic, angles[k]) + hy.diff(potential, angles[k]) + external[k]
         - hy.sum([hy.diff(momentum[k], angles[i]) * rates[i] for i in range(3)]) for k in range(3)]
    j_inv = [[sp / st, cp / st, 0.0], [cp, -sp, 0.0], [-ct * sp / st, -ct * cp / st, 1.0]]
    j_inv_t = ex.transpose(j_inv)
    accel = ex.matvec(j_inv, ex.matvec(ex.symmetric(ex.SIGMA_INV), ex.matvec(j_inv_t, f)))
    return variables, list(rates) + accel, st
