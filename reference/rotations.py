"""Attitude charts and their changes: quaternion, rotation matrix, ZXZ Euler angles, Gibbs vector.

Conventions (DESIGN §2, FORMULARY §0): R maps body components to world components, v_world = R v_body.
Quaternions are scalar-first (w, x, y, z) and R(q) is the rotation v -> q (0, v) q*. Every function is vectorised
over leading axes: quaternions (..., 4), vectors (..., 3), matrices (..., 3, 3), angles (...).
"""
from __future__ import annotations

import numpy as np

# Below this rotation angle (rad) quat_exp / quat_log switch to their Taylor series: the truncation error of the
# series is below 1e-20 there, and the closed forms would divide by a number that is losing digits.
_SERIES_ANGLE = 1e-4


def skew(v: np.ndarray) -> np.ndarray:
    """(..., 3) -> (..., 3, 3), the matrix of v × ·."""
    v = np.asarray(v, dtype=float)
    zero = np.zeros(v.shape[:-1])
    x, y, z = v[..., 0], v[..., 1], v[..., 2]
    return np.stack([np.stack([zero, -z, y], axis=-1),
                     np.stack([z, zero, -x], axis=-1),
                     np.stack([-y, x, zero], axis=-1)], axis=-2)


def quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product a ⊗ b, (..., 4) × (..., 4) -> (..., 4); R(a ⊗ b) = R(a) R(b)."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    aw, av = a[..., :1], a[..., 1:]
    bw, bv = b[..., :1], b[..., 1:]
    w = aw * bw - np.sum(av * bv, axis=-1, keepdims=True)
    v = aw * bv + bw * av + np.cross(av, bv)
    return np.concatenate([w, v], axis=-1)


def quat_conj(q: np.ndarray) -> np.ndarray:
    """(w, x, y, z) -> (w, -x, -y, -z); the inverse rotation for a unit quaternion."""
    q = np.asarray(q, dtype=float)
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def quat_normalize(q: np.ndarray) -> np.ndarray:
    """q / |q|, (..., 4)."""
    q = np.asarray(q, dtype=float)
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """(..., 4) -> (..., 3, 3) rotation matrix; q is normalised first."""
    w, x, y, z = np.moveaxis(quat_normalize(q), -1, 0)
    xx, yy, zz = x * x, y * y, z * z
    xy, xz, yz = x * y, x * z, y * z
    wx, wy, wz = w * x, w * y, w * z
    return np.stack([np.stack([1 - 2 * (yy + zz), 2 * (xy - wz), 2 * (xz + wy)], axis=-1),
                     np.stack([2 * (xy + wz), 1 - 2 * (xx + zz), 2 * (yz - wx)], axis=-1),
                     np.stack([2 * (xz - wy), 2 * (yz + wx), 1 - 2 * (xx + yy)], axis=-1)], axis=-2)


def matrix_to_quat(m: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotation matrix -> (..., 4) unit quaternion with w >= 0.

    Shepperd's method: of the four expressions 4w², 4x², 4y², 4z² (each a combination of the trace and one diagonal
    entry) the largest is taken as pivot, so the square root and the division never lose digits.
    """
    m = np.asarray(m, dtype=float)
    m00, m11, m22 = m[..., 0, 0], m[..., 1, 1], m[..., 2, 2]
    # Rows: the quaternion times 4·(pivot component), for pivot w, x, y, z.
    candidates = np.stack([
        np.stack([1 + m00 + m11 + m22, m[..., 2, 1] - m[..., 1, 2], m[..., 0, 2] - m[..., 2, 0],
                  m[..., 1, 0] - m[..., 0, 1]], axis=-1),
        np.stack([m[..., 2, 1] - m[..., 1, 2], 1 + m00 - m11 - m22, m[..., 0, 1] + m[..., 1, 0],
                  m[..., 0, 2] + m[..., 2, 0]], axis=-1),
        np.stack([m[..., 0, 2] - m[..., 2, 0], m[..., 0, 1] + m[..., 1, 0], 1 - m00 + m11 - m22,
                  m[..., 1, 2] + m[..., 2, 1]], axis=-1),
        np.stack([m[..., 1, 0] - m[..., 0, 1], m[..., 0, 2] + m[..., 2, 0], m[..., 1, 2] + m[..., 2, 1],
                  1 - m00 - m11 + m22], axis=-1),
    ], axis=-2)
    pivots = np.stack([candidates[..., i, i] for i in range(4)], axis=-1)
    best = np.argmax(pivots, axis=-1)
    chosen = np.take_along_axis(candidates, best[..., None, None], axis=-2)[..., 0, :]
    q = quat_normalize(chosen)
    return np.where(q[..., :1] < 0, -q, q)


def quat_exp(rotvec: np.ndarray) -> np.ndarray:
    """(..., 3) rotation vector θ u (rad) -> (..., 4) unit quaternion (cos θ/2, u sin θ/2); exact, series near 0."""
    rotvec = np.asarray(rotvec, dtype=float)
    angle = np.linalg.norm(rotvec, axis=-1, keepdims=True)
    small = angle < _SERIES_ANGLE
    safe = np.where(small, 1.0, angle)
    angle2 = angle * angle
    # sin(θ/2)/θ = 1/2 - θ²/48 + θ⁴/3840 - ...
    factor = np.where(small, 0.5 - angle2 / 48.0 + angle2 * angle2 / 3840.0, np.sin(0.5 * safe) / safe)
    return np.concatenate([np.cos(0.5 * angle), factor * rotvec], axis=-1)


def quat_log(q: np.ndarray) -> np.ndarray:
    """(..., 4) quaternion -> (..., 3) rotation vector θ u with θ in [0, π] (the shorter of q and -q).

    Inverse of quat_exp; q is normalised first.
    """
    q = quat_normalize(q)
    q = np.where(q[..., :1] < 0, -q, q)
    w = q[..., :1]
    v = q[..., 1:]
    s = np.linalg.norm(v, axis=-1, keepdims=True)
    # θ = 2 atan2(s, w); for small s/w use 2 atan(x)/s = (2/w)(1 - x²/3 + x⁴/5), x = s/w, to avoid 0/0.
    small = s < 0.5 * _SERIES_ANGLE * w
    x2 = np.where(small, (s / np.where(small, w, 1.0)) ** 2, 0.0)
    series = 2.0 / np.where(small, w, 1.0) * (1.0 - x2 / 3.0 + x2 * x2 / 5.0)
    closed = 2.0 * np.arctan2(s, w) / np.where(small, 1.0, s)
    return np.where(small, series, closed) * v


def _rz(angle: np.ndarray) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    zero, one = np.zeros_like(c), np.ones_like(c)
    return np.stack([np.stack([c, -s, zero], -1), np.stack([s, c, zero], -1), np.stack([zero, zero, one], -1)], -2)


def _rx(angle: np.ndarray) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    zero, one = np.zeros_like(c), np.ones_like(c)
    return np.stack([np.stack([one, zero, zero], -1), np.stack([zero, c, -s], -1), np.stack([zero, s, c], -1)], -2)


def zxz_to_matrix(phi, theta, psi) -> np.ndarray:
    """Euler angles (rad, each (...)) -> (..., 3, 3): R = Rz(φ) Rx(θ) Rz(ψ) (FORMULARY C1)."""
    phi, theta, psi = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in (phi, theta, psi)))
    return _rz(phi) @ _rx(theta) @ _rz(psi)


def matrix_to_zxz(m: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(..., 3, 3) -> (φ, θ, ψ), each (...), with θ in [0, π] and φ, ψ in (-π, π].

    φ comes from the third column (sin θ sin φ, -sin θ cos φ, cos θ); θ and ψ from Rz(-φ) R = Rx(θ) Rz(ψ), whose
    entries are of full size, so the matrix is reproduced to rounding even where φ and ψ are ill-defined
    (θ near 0 or π, where only φ ± ψ matters; there φ = 0 is chosen when the third column is exactly vertical).
    """
    m = np.asarray(m, dtype=float)
    col_x, col_y = m[..., 0, 2], -m[..., 1, 2]
    phi = np.where((col_x == 0.0) & (col_y == 0.0), 0.0, np.arctan2(col_x, col_y))
    rest = _rz(-phi) @ m
    theta = np.arctan2(-rest[..., 1, 2], rest[..., 2, 2])
    psi = np.arctan2(-rest[..., 0, 1], rest[..., 0, 0])
    return phi, theta, psi


def gibbs_to_matrix(g: np.ndarray) -> np.ndarray:
    """Gibbs vector g = u tan(φ/2), (..., 3) -> (..., 3, 3): R = I + 2 (G + G²)/(1 + g²) (De Finetti, FORMULARY F1)."""
    g = np.asarray(g, dtype=float)
    big_g = skew(g)
    g2 = np.sum(g * g, axis=-1)[..., None, None]
    return np.eye(3) + 2.0 / (1.0 + g2) * (big_g + big_g @ big_g)


def matrix_to_gibbs(m: np.ndarray) -> np.ndarray:
    """(..., 3, 3) -> (..., 3) Gibbs vector; singular (infinite) at rotation angle π.

    F1's inverse vee(R - Rᵀ)/(1 + tr R) equals v/w for the quaternion (w, v) of R; it is computed as v/w from
    Shepperd's quaternion, which keeps its digits near angle π where 1 + tr R cancels.
    """
    q = matrix_to_quat(m)
    return quat_to_gibbs(q)


def gibbs_to_quat(g: np.ndarray) -> np.ndarray:
    """(..., 3) Gibbs vector -> (..., 4) unit quaternion (1, g)/sqrt(1 + g²), w > 0."""
    g = np.asarray(g, dtype=float)
    q = np.concatenate([np.ones(g.shape[:-1] + (1,)), g], axis=-1)
    return quat_normalize(q)


def quat_to_gibbs(q: np.ndarray) -> np.ndarray:
    """(..., 4) quaternion -> (..., 3) Gibbs vector v/w (same for q and -q; infinite at w = 0)."""
    q = np.asarray(q, dtype=float)
    return q[..., 1:] / q[..., :1]


def gibbs_compose(g: np.ndarray, g_prime: np.ndarray) -> np.ndarray:
    """Gibbs vector of R'' = R(g') R(g) (g applied first): (g + g' + g' × g)/(1 - g·g') (FORMULARY F3)."""
    g = np.asarray(g, dtype=float)
    g_prime = np.asarray(g_prime, dtype=float)
    denominator = 1.0 - np.sum(g * g_prime, axis=-1, keepdims=True)
    return (g + g_prime + np.cross(g_prime, g)) / denominator


def attitude_angle(m1: np.ndarray, m2: np.ndarray) -> np.ndarray:
    """Geodesic angle (rad, (...)) between two attitudes given as (..., 3, 3) rotation matrices.

    ‖R1 - R2‖_F = 2√2 sin(θ/2), so θ = 2 asin(‖R1 - R2‖_F / (2√2)). Unlike arccos((tr(R1 R2ᵀ) - 1)/2), this keeps
    its relative accuracy for angles far below 1e-8 (DESIGN §2).
    """
    diff = np.asarray(m1, dtype=float) - np.asarray(m2, dtype=float)
    norm = np.sqrt(np.sum(diff * diff, axis=(-2, -1)))
    return 2.0 * np.arcsin(np.minimum(1.0, norm / (2.0 * np.sqrt(2.0))))
