"""The heavy body's particular motions (FORMULARY G5, G9, G10, G11): constructors of bodies and initial states,
the conditions each motion needs, and the exact motions.

Conventions (FORMULARY §0, DESIGN §2): d = the world unit downward direction (body.gravity_direction), up = -d;
H = Rᵀ d the downward vertical in body components; w = α k = m g (O -> G) the weight moment (body.weight_moment),
α = |w|; the gravity torque is w × H. Quaternions (w, x, y, z) map body to world; ω is in body components, rad/s.

Each motion has a constructor returning a Setup (body, quat0, omega0), a `*_check(body, quat0, omega0)` that returns
None when the state is on the motion (to CONDITION_RTOL, relative) or the reason in one line, and a
`*_solve(body, quat0, omega0, times)` that returns the exact motion (quat (n, 4), omega (n, 3)) through that state.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..body import RigidBody
from ..closed_form import (CONDITION_RTOL, axis_angle_quat, continuous_signs, orthogonal_unit,
                           principal_axes, rotation_taking, unit)
from .pendulum import pendulum
from ..rotations import matrix_to_quat, quat_mul, quat_normalize, quat_to_matrix


@dataclass(frozen=True, eq=False)
class Setup:
    """A body and an initial state on one of the exact motions.

    body: the RigidBody. quat0: (4,) unit quaternion (w, x, y, z), body -> world. omega0: (3,) rad/s, body frame.
    oracle: the name in reference.exact.ORACLES whose check accepts this state and whose solve gives the motion.
    """

    body: RigidBody
    quat0: np.ndarray
    omega0: np.ndarray
    oracle: str

    def motion(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(n,) s -> (quat (n, 4), omega (n, 3) rad/s body): the exact motion from this state."""
        # every Setup names one of this module's own solutions (the registry reference.exact.ORACLES imports this
        # module, so the lookup stays here rather than going through the registry)
        return _SOLVES[self.oracle](self.body, self.quat0, self.omega0, np.asarray(times, dtype=float))


def _rodrigues(axis: np.ndarray, angle: np.ndarray, vector: np.ndarray) -> np.ndarray:
    """Rotate vector (3,) about the unit axis (3,) by angle (n,) rad -> (n, 3)."""
    angle = np.asarray(angle, dtype=float)[:, None]
    c, s = np.cos(angle), np.sin(angle)
    return c * vector + s * np.cross(axis, vector) + (1.0 - c) * (axis @ vector) * axis


def _down(body: RigidBody) -> np.ndarray:
    return unit(body.gravity_direction)


def _vertical(body: RigidBody, quat0: np.ndarray) -> np.ndarray:
    """H0 = R0ᵀ d, (3,) body."""
    return quat_to_matrix(quat_normalize(np.asarray(quat0, dtype=float))).T @ _down(body)


def _gravity_reason(body: RigidBody) -> str | None:
    if not body.has_gravity:
        return "the body has no weight moment (gravity, mass and centre of mass offset are all needed)"
    return None


def _setup(body: RigidBody, rotation: np.ndarray, omega0: np.ndarray, oracle: str) -> Setup:
    return Setup(body, matrix_to_quat(rotation), np.asarray(omega0, dtype=float), oracle)


# --- Lagrange's regular precession and the sleeping top (G5) -----------------------------------------------------

def _lagrange_top(body: RigidBody) -> tuple[np.ndarray, float, float, float] | str:
    """(k, A1, A3, α) of a top symmetric about its centre-of-mass line, or the reason it is not one."""
    reason = _gravity_reason(body)
    if reason:
        return reason
    sigma = np.asarray(body.inertia, dtype=float)
    alpha = float(np.linalg.norm(body.weight_moment))
    k = body.weight_moment / alpha
    a3 = float(k @ sigma @ k)
    e = orthogonal_unit(k)
    f = np.cross(k, e)
    scale = float(np.trace(sigma))
    transverse = abs(e @ sigma @ e - f @ sigma @ f) + 2.0 * abs(e @ sigma @ f)
    if np.linalg.norm(sigma @ k - a3 * k) > CONDITION_RTOL * scale or transverse > CONDITION_RTOL * scale:
        return "the inertia is not symmetric about the centre-of-mass line (Lagrange: A1 = A2, k on the third axis)"
    return k, 0.5 * float(e @ sigma @ e + f @ sigma @ f), a3, alpha


def _require(value):
    if isinstance(value, str):
        raise ValueError(value)
    return value


def lagrange_rates(body: RigidBody, tilt: float, spin: float) -> tuple[float, float]:
    """Both precession rates φ̇ (rad/s) of the regular precession with the figure axis k at angle `tilt` (rad) from
    the upward vertical and spin ω·k = `spin` (rad/s): the roots of φ̇ (A3 ω3 - A1 φ̇ cos θ) = α (G5), as
    (slow, fast); nan where there is no real root (and the fast root where cos θ = 0)."""
    _, a1, a3, alpha = _require(_lagrange_top(body))
    c = math.cos(tilt)
    momentum = a3 * spin
    if c == 0.0:
        return (alpha / momentum if momentum != 0.0 else float("nan")), float("nan")
    discriminant = momentum * momentum - 4.0 * a1 * alpha * c
    if discriminant < 0.0:
        return float("nan"), float("nan")
    # the larger root by the formula, the smaller as the product of roots over it (no cancellation)
    large = 0.5 * (momentum + math.copysign(math.sqrt(discriminant), momentum if momentum != 0.0 else 1.0))
    roots = sorted((alpha / large, large / (a1 * c)), key=abs)
    return roots[0], roots[1]


def sleeping_top_threshold(body: RigidBody) -> float:
    """The spin r_c = 2 √(A1 α) / A3 (rad/s) above which the sleeping top (G above O) is linearly stable:
    A3² r² > 4 A1 α (G5)."""
    _, a1, a3, alpha = _require(_lagrange_top(body))
    return 2.0 * math.sqrt(a1 * alpha) / a3


def lagrange_precession(body: RigidBody, tilt: float, spin: float, root: str = "slow",
                        heading: float = 0.0) -> Setup:
    """Regular precession of the Lagrange top: figure axis at `tilt` rad from the upward vertical (0: the sleeping
    top, G above O; π: hanging), spin ω·k = `spin` rad/s, precession rate the "slow" or "fast" root of
    lagrange_rates; heading (rad) turns the whole state about the vertical. At tilt 0 or π, ω0 = spin k."""
    k, _, _, _ = _require(_lagrange_top(body))
    up = -_down(body)
    horizontal = orthogonal_unit(up)
    horizontal = math.cos(heading) * horizontal + math.sin(heading) * np.cross(up, horizontal)
    axis_world = math.cos(tilt) * up + math.sin(tilt) * horizontal
    rotation = rotation_taking(k, axis_world)
    if math.sin(tilt) == 0.0:
        return _setup(body, rotation, spin * k, "lagrange_precession")
    slow, fast = lagrange_rates(body, tilt, spin)
    rate = {"slow": slow, "fast": fast}[root]
    if not math.isfinite(rate):
        raise ValueError(f"no real {root} precession rate for tilt {tilt} and spin {spin} (G5 discriminant < 0)")
    up_body = rotation.T @ up
    omega0 = rate * up_body + (spin - rate * math.cos(tilt)) * k
    return _setup(body, rotation, omega0, "lagrange_precession")


def _lagrange_split(body, quat0, omega0):
    """(k, u0 = R0ᵀ up, φ̇, ψ̇, residuals) with ω0 = φ̇ u0 + ψ̇ k + (rest ⊥ both)."""
    k, a1, a3, alpha = _require(_lagrange_top(body))
    up_body = -_vertical(body, quat0)
    omega0 = np.asarray(omega0, dtype=float)
    c = float(up_body @ k)
    sin2 = float(np.sum(np.cross(up_body, k) ** 2))
    if sin2 <= CONDITION_RTOL ** 2:
        return k, up_body, 0.0, float(omega0 @ k), float(np.linalg.norm(np.cross(omega0, k))), 0.0
    a = (omega0 @ up_body - c * (omega0 @ k)) / sin2
    b = (omega0 @ k - c * (omega0 @ up_body)) / sin2
    rest = float(np.linalg.norm(omega0 - a * up_body - b * k))
    spin = float(omega0 @ k)
    relation = a * (a3 * spin - a1 * a * c) - alpha
    scale = abs(a * a3 * spin) + abs(a1 * a * a * c) + alpha
    return k, up_body, float(a), float(b), rest, relation / scale


def lagrange_check(body: RigidBody, quat0: np.ndarray, omega0: np.ndarray) -> str | None:
    """A Lagrange top (A1 = A2 about k) in regular precession: ω0 in the plane of k and the vertical, and G5's
    relation between φ̇, ω3 and θ (or a sleeping/hanging top spinning about k)."""
    top = _lagrange_top(body)
    if isinstance(top, str):
        return top
    _, _, _, _, rest, relation = _lagrange_split(body, quat0, omega0)
    scale = max(float(np.linalg.norm(omega0)), np.finfo(float).tiny)
    if rest > CONDITION_RTOL * scale:
        return f"ω0 is not in the plane of the figure axis and the vertical (off by {rest / scale:.3g} relative)"
    if abs(relation) > CONDITION_RTOL:
        return f"the precession rate misses φ̇(A3 ω3 - A1 φ̇ cos θ) = α by {relation:.3g} relative"
    return None


def lagrange_solve(body, quat0, omega0, times):
    """R(t) = Rot(up, φ̇ t) R0 Rot(k, ψ̇ t), ω(t) = φ̇ R(t)ᵀ up + ψ̇ k (a uniform rotation for the sleeping top)."""
    times = np.asarray(times, dtype=float)
    quat0 = quat_normalize(np.asarray(quat0, dtype=float))
    k, up_body, rate, spin, _, _ = _lagrange_split(body, quat0, omega0)
    up = -_down(body)
    quat = quat_mul(quat_mul(axis_angle_quat(up, rate * times), quat0), axis_angle_quat(k, spin * times))
    omega = rate * _rodrigues(k, -spin * times, up_body) + spin * k
    return quat, omega


# --- Staude's permanent rotations (G9) ---------------------------------------------------------------------------

def staude_direction(body: RigidBody, parameter: float, branch: float = 1.0) -> np.ndarray:
    """A generator γ (3,) unit, body, of Staude's cone: γ = ±(σ - parameter I)⁻¹ k normalised (sign of branch), so
    that σγ - parameter γ ∥ k and γ, σγ, k are coplanar (G9). parameter (kg m²) runs over the reals except the
    principal moments. Ω² is odd in γ, so of the two opposite generators at most one carries a rotation."""
    _require(_gravity_reason(body))
    sigma = np.asarray(body.inertia, dtype=float)
    return math.copysign(1.0, branch) * unit(np.linalg.solve(sigma - parameter * np.eye(3), body.weight_moment))


def staude_rate_squared(body: RigidBody, gamma: np.ndarray) -> float:
    """Ω² (rad²/s²) = ((w × γ)·(γ × σγ)) / |γ × σγ|² for the rotation ω = Ω γ about the downward vertical γ (G9,
    w = α k); only where it is > 0 does the rotation exist."""
    gamma = unit(gamma)
    sigma_gamma = np.asarray(body.inertia, dtype=float) @ gamma
    normal = np.cross(gamma, sigma_gamma)
    return float(np.cross(body.weight_moment, gamma) @ normal / (normal @ normal))


def staude_rotation(body: RigidBody, gamma: np.ndarray, sign: float = 1.0, heading: float = 0.0) -> Setup:
    """The permanent rotation ω = Ω γ about the vertical with H = γ (γ on the cone, Ω² > 0), Ω = sign √Ω²."""
    gamma = unit(gamma)
    sigma = np.asarray(body.inertia, dtype=float)
    k = unit(body.weight_moment)
    cone = abs(np.linalg.det(np.column_stack([gamma, sigma @ gamma, k]))) / np.linalg.norm(sigma @ gamma)
    if cone > CONDITION_RTOL:
        raise ValueError(f"γ is off Staude's cone by {cone:.3g} (det[γ, σγ, k] / |σγ|)")
    rate2 = staude_rate_squared(body, gamma)
    if not rate2 > 0.0:
        raise ValueError(f"Ω² = {rate2:.6g} <= 0 on this generator: no permanent rotation there")
    rotation = rotation_taking(gamma, _down(body), heading)
    return _setup(body, rotation, math.copysign(math.sqrt(rate2), sign) * gamma, "staude_rotation")


def staude_check(body: RigidBody, quat0: np.ndarray, omega0: np.ndarray) -> str | None:
    """A permanent rotation about the vertical: ω0 ∥ H0 and ω0 × σω0 = w × H0 (or rest in an equilibrium)."""
    reason = _gravity_reason(body)
    if reason:
        return reason
    vertical = _vertical(body, quat0)
    omega0 = np.asarray(omega0, dtype=float)
    sigma = np.asarray(body.inertia, dtype=float)
    speed = float(np.linalg.norm(omega0))
    if np.linalg.norm(np.cross(omega0, vertical)) > CONDITION_RTOL * speed:
        return "ω0 is not along the vertical"
    weight = np.linalg.norm(body.weight_moment)
    residual = np.linalg.norm(np.cross(omega0, sigma @ omega0) - np.cross(body.weight_moment, vertical))
    if residual > CONDITION_RTOL * (speed * np.linalg.norm(sigma @ omega0) + weight):
        return f"not a permanent rotation: |ω × σω - w × H| = {residual:.3g} (γ off the cone or Ω² wrong)"
    return None


def staude_solve(body, quat0, omega0, times):
    """R(t) = Rot(d, Ω t) R0, ω(t) = Ω H0 with Ω = ω0·H0."""
    times = np.asarray(times, dtype=float)
    quat0 = quat_normalize(np.asarray(quat0, dtype=float))
    vertical = _vertical(body, quat0)
    rate = float(np.asarray(omega0, dtype=float) @ vertical)
    quat = quat_mul(axis_angle_quat(_down(body), rate * times), quat0)
    return quat, np.broadcast_to(rate * vertical, times.shape + (3,)).copy()


# --- Grioli's regular precession of the asymmetric top (G10) -----------------------------------------------------

def grioli_body(moments: tuple[float, float, float], mass: float, distance: float, gravity: float = 9.81,
                branch: float = 1.0) -> RigidBody:
    """A body with principal moments (A1 > A2 > A3) at O on the body axes and the centre of mass at `distance` (m)
    along a normal of a circular section of the inertia ellipsoid: k = (√((A1-A2)/(A1-A3)), 0, branch
    √((A2-A3)/(A1-A3))) (G10)."""
    a1, a2, a3 = (float(x) for x in moments)
    if not a1 > a2 > a3 > 0.0:
        raise ValueError("Grioli's precession needs principal moments A1 > A2 > A3 > 0")
    k = np.array([math.sqrt((a1 - a2) / (a1 - a3)), 0.0, math.copysign(math.sqrt((a2 - a3) / (a1 - a3)), branch)])
    return RigidBody(np.diag([a1, a2, a3]), mass, distance * k, gravity)


def _grioli_geometry(body: RigidBody) -> tuple[np.ndarray, np.ndarray, float, float, float] | str:
    """(k, e2 the middle axis, A_f = k·σk, |σk|, α) or the reason the body is not a Grioli body."""
    reason = _gravity_reason(body)
    if reason:
        return reason
    moments, axes = principal_axes(body.inertia)
    a1, a2, a3 = moments
    if not (a1 - a2 > CONDITION_RTOL * a1 and a2 - a3 > CONDITION_RTOL * a1):
        return "Grioli's precession needs three distinct principal moments"
    alpha = float(np.linalg.norm(body.weight_moment))
    k = body.weight_moment / alpha
    k1 = float(k @ axes[:, 0])
    if abs(k @ axes[:, 1]) > CONDITION_RTOL or abs(k1 * k1 * (a1 - a3) - (a1 - a2)) > CONDITION_RTOL * (a1 - a3):
        return "the centre of mass is not on a normal of a circular section of the inertia ellipsoid (G10)"
    sigma_k = np.asarray(body.inertia, dtype=float) @ k
    return k, axes[:, 1], float(k @ sigma_k), float(np.linalg.norm(sigma_k)), alpha


def grioli_rate(body: RigidBody) -> float:
    """n = √(α / |σk|) (rad/s): ω = n (c + k), |ω|² = 2 α cos χ / A_f (the corrected (23) of G10)."""
    _, _, _, norm_sigma_k, alpha = _require(_grioli_geometry(body))
    return math.sqrt(alpha / norm_sigma_k)


def grioli_vertical(body: RigidBody, axis: np.ndarray) -> np.ndarray:
    """H (3,) body, for the precession axis c (unit, ⊥ k): [s - (c·s) c - A_f c + (c·s) k] / |σk|, s = σk - A_f k
    (G10); H·c = -cos χ = -A_f / |σk|."""
    k, _, a_f, norm_sigma_k, _ = _require(_grioli_geometry(body))
    s = np.asarray(body.inertia, dtype=float) @ k - a_f * k
    c = np.asarray(axis, dtype=float)
    cs = float(c @ s)
    return (s - cs * c - a_f * c + cs * k) / norm_sigma_k


def grioli_precession(body: RigidBody, phase: float = 0.0, sign: float = 1.0, heading: float = 0.0,
                      axis: np.ndarray | None = None) -> Setup:
    """Grioli's precession with precession axis c (body, unit, ⊥ k; by default cos(phase) e2 + sin(phase) k × e2,
    e2 the middle principal axis, which is ⊥ k): ω0 = n (c + k), n = sign grioli_rate, H0 = grioli_vertical(c);
    heading turns the state about the vertical. sign -1 is the time reverse."""
    k, e2, _, _, _ = _require(_grioli_geometry(body))
    if axis is None:
        c = math.cos(phase) * e2 + math.sin(phase) * np.cross(k, e2)
    else:
        c = unit(axis)
        if abs(c @ k) > CONDITION_RTOL:
            raise ValueError(f"the precession axis must be perpendicular to k (c·k = {c @ k:.3g})")
    rotation = rotation_taking(grioli_vertical(body, c), _down(body), heading)
    return _setup(body, rotation, math.copysign(grioli_rate(body), sign) * (c + k), "grioli_precession")


def _grioli_axis(body, omega0) -> tuple[np.ndarray, float, np.ndarray]:
    """(c, n, k) with ω0 = n (c + k)."""
    k = unit(body.weight_moment)
    omega0 = np.asarray(omega0, dtype=float)
    rate = float(omega0 @ k)
    return omega0 / rate - k, rate, k


def grioli_check(body: RigidBody, quat0: np.ndarray, omega0: np.ndarray) -> str | None:
    """A Grioli body (k normal to a circular section) with ω0 = n (c + k), c ⊥ k unit, n² = α/|σk|, H0 = H(c)."""
    geometry = _grioli_geometry(body)
    if isinstance(geometry, str):
        return geometry
    k, _, _, norm_sigma_k, alpha = geometry
    if float(np.asarray(omega0, dtype=float) @ k) == 0.0:
        return "ω0·k = 0: not a Grioli precession (ω = n (c + k), n ≠ 0)"
    c, rate, _ = _grioli_axis(body, omega0)
    if abs(c @ k) > CONDITION_RTOL or abs(np.linalg.norm(c) - 1.0) > CONDITION_RTOL:
        return "ω0 is not of the form n (c + k) with c a unit vector ⊥ k"
    if abs(rate * rate * norm_sigma_k / alpha - 1.0) > CONDITION_RTOL:
        return f"n² = {rate * rate:.17g} but α/|σk| = {alpha / norm_sigma_k:.17g}"
    miss = float(np.linalg.norm(_vertical(body, quat0) - grioli_vertical(body, unit(c))))
    if miss > CONDITION_RTOL:
        return f"the vertical misses Grioli's H(c) by {miss:.3g}"
    return None


def grioli_solve(body, quat0, omega0, times):
    """R(t) = Rot(c_world, n t) R0 Rot(k, n t), ω(t) = n (c(t) + k), with c(t) = Rot(k, -n t) c the fixed axis
    seen in the body."""
    times = np.asarray(times, dtype=float)
    quat0 = quat_normalize(np.asarray(quat0, dtype=float))
    c, rate, k = _grioli_axis(body, omega0)
    c = unit(c - (c @ k) * k)
    axis_world = quat_to_matrix(quat0) @ c
    quat = quat_mul(quat_mul(axis_angle_quat(axis_world, rate * times), quat0), axis_angle_quat(k, rate * times))
    return quat, rate * (_rodrigues(k, -rate * times, c) + k)


# --- Hess–Grioli precessions and Mlodzejowski rotations (G11) ----------------------------------------------------

def hess_grioli_body(a1: float, a3: float, a1_prime: float, mass: float, distance: float,
                     gravity: float = 9.81) -> RigidBody:
    """G11's body in its own frame (i3 along OG, i1 the middle principal axis): σ = [[A1, 0, 0], [0, A2, -A1'],
    [0, -A1', A3]] with the Hess condition (A1 - A2) A3 + A1'² = 0, i.e. A2 = A1 + A1'²/A3; com = (0, 0, distance)."""
    a2 = a1 + a1_prime * a1_prime / a3
    inertia = np.array([[a1, 0.0, 0.0], [0.0, a2, -a1_prime], [0.0, -a1_prime, a3]])
    return RigidBody(inertia, mass, np.array([0.0, 0.0, distance]), gravity)


def hess_frame(body: RigidBody) -> tuple[np.ndarray, tuple[float, float, float, float]] | str:
    """G11's frame, (3, 3) with columns i1 (middle principal axis), i2 = i3 × i1, i3 = k (body components), and
    (A1, A2, A3, A1') with σ i1 = A1 i1, A2 = i2·σi2, A3 = i3·σi3, A1' = -i2·σi3 >= 0; or the reason the body is not
    a Hess body (k ⊥ the middle axis and (A1 - A2) A3 + A1'² = 0, i.e. σ⁻¹ isotropic on k⊥)."""
    reason = _gravity_reason(body)
    if reason:
        return reason
    sigma = np.asarray(body.inertia, dtype=float)
    moments, axes = principal_axes(sigma)
    if not (moments[0] - moments[1] > CONDITION_RTOL * moments[0]
            and moments[1] - moments[2] > CONDITION_RTOL * moments[0]):
        return "a Hess body needs three distinct principal moments"
    k = unit(body.weight_moment)
    i1 = axes[:, 1]
    if abs(i1 @ k) > CONDITION_RTOL:
        return "the centre of mass is not in the plane of the largest and smallest principal axes (Hess)"
    i1 = unit(i1 - (i1 @ k) * k)
    i2 = np.cross(k, i1)
    a1p = -float(i2 @ sigma @ k)
    if a1p < 0.0:
        i1, i2, a1p = -i1, -i2, -a1p
    a1, a2, a3 = float(i1 @ sigma @ i1), float(i2 @ sigma @ i2), float(k @ sigma @ k)
    if abs((a1 - a2) * a3 + a1p * a1p) > CONDITION_RTOL * a1 * a3:
        return f"the Hess condition (A1 - A2) A3 + A1'² = 0 fails by {((a1 - a2) * a3 + a1p * a1p) / (a1 * a3):.3g}"
    return np.column_stack([i1, i2, k]), (a1, a2, a3, a1p)


def hess_grioli(body: RigidBody, b1: float, b1_dot: float, b2: float, n: float = 0.0,
                heading: float = 0.0) -> Setup:
    """The Hess–Grioli precession of G11 at angles b1, b2 (rad), rate ḃ1 (rad/s) and phase n (rad):
    ω = -ḃ1 (sin b2 i1 - cos b2 i2) - ḃ2 i3 with ḃ2 = -(A1'/A3) ḃ1 cos b2, H = sin(b1 + n)(cos b2 i1 + sin b2 i2)
    - cos(b1 + n) i3 (G11 (25)–(27)). cos b2 = 0 is a Mlodzejowski rotation."""
    frame_g, (a1, _, a3, a1p) = _require(hess_frame(body))
    b2_dot = -a1p / a3 * b1_dot * math.cos(b2)
    omega_g = np.array([-b1_dot * math.sin(b2), b1_dot * math.cos(b2), -b2_dot])
    theta = b1 + n
    vertical_g = np.array([math.sin(theta) * math.cos(b2), math.sin(theta) * math.sin(b2), -math.cos(theta)])
    rotation = rotation_taking(frame_g @ vertical_g, _down(body), heading)
    return _setup(body, rotation, frame_g @ omega_g, "hess_grioli")


def hess_grioli_check(body: RigidBody, quat0: np.ndarray, omega0: np.ndarray) -> str | None:
    """A Hess body with K·k = 0 (the Hess manifold) and K·H0 = 0 (zero vertical angular momentum), K = σω0."""
    geometry = hess_frame(body)
    if isinstance(geometry, str):
        return geometry
    momentum = np.asarray(body.inertia, dtype=float) @ np.asarray(omega0, dtype=float)
    size = float(np.linalg.norm(momentum))
    if abs(momentum @ unit(body.weight_moment)) > CONDITION_RTOL * size:
        return "K·k ≠ 0: the state is off the Hess manifold"
    if abs(momentum @ _vertical(body, quat0)) > CONDITION_RTOL * size:
        return "K·H ≠ 0: the Hess–Grioli precessions have zero vertical angular momentum"
    return None


def _gudermannian_branch(b2_cos: float, b2_sin: float, a1p: float, a3: float, delta_b1: np.ndarray):
    """cos b2, sin b2 after b1 has advanced by delta_b1 (n,): ∫ db2 / cos b2 = -(A1'/A3) Δb1 (G11 (25)); with
    y = gd⁻¹(b2) on the branch of b2 (cos b2 > 0, or b2 - π), cos b2 = ±sech y, sin b2 = ±tanh y."""
    if b2_cos == 0.0:
        ones = np.ones_like(delta_b1)
        return b2_cos * ones, b2_sin * ones
    side = math.copysign(1.0, b2_cos)
    y = math.asinh(b2_sin / b2_cos) - side * a1p / a3 * delta_b1
    return side / np.cosh(y), side * np.tanh(y)


def hess_grioli_solve(body, quat0, omega0, times):
    """b1 from the pendulum θ̈ = (α/A1) sin θ, θ = b1 + n (Jacobi functions), b2 by the Gudermannian, the attitude
    from H(t) and the fixed horizontal direction e(t) = (sin b2, -cos b2, 0) of K: R(t) = [d, e_w, d × e_w]
    [H, e, H × e]ᵀ."""
    times = np.asarray(times, dtype=float)
    quat0 = quat_normalize(np.asarray(quat0, dtype=float))
    frame_g, (a1, _, a3, a1p) = _require(hess_frame(body))
    omega0 = np.asarray(omega0, dtype=float)
    vertical_g = frame_g.T @ _vertical(body, quat0)
    momentum_g = frame_g.T @ (np.asarray(body.inertia, dtype=float) @ omega0)
    planar = math.hypot(momentum_g[0], momentum_g[1])
    if planar > 0.0:  # K = A1 ḃ1 (-sin b2, cos b2, 0) with ḃ1 > 0
        b2_sin, b2_cos, b1_dot = -momentum_g[0] / planar, momentum_g[1] / planar, planar / a1
    else:  # at rest: b2 from the horizontal part of H = sin θ (cos b2, sin b2, 0) - cos θ i3, sin θ >= 0
        horizontal = math.hypot(vertical_g[0], vertical_g[1])
        b2_cos, b2_sin = (vertical_g[0] / horizontal, vertical_g[1] / horizontal) if horizontal > 0 else (1.0, 0.0)
        b1_dot = 0.0
    theta0 = math.atan2(vertical_g[0] * b2_cos + vertical_g[1] * b2_sin, -vertical_g[2])
    alpha = float(np.linalg.norm(body.weight_moment))
    # θ = ϑ + π turns θ̈ = (α/A1) sin θ into the pendulum ϑ̈ = -(α/A1) sin ϑ
    swing = pendulum(theta0 - math.pi, b1_dot, math.sqrt(alpha / a1), times)
    theta_sin, theta_cos = -swing.sin, -swing.cos
    cos_b2, sin_b2 = _gudermannian_branch(b2_cos, b2_sin, a1p, a3, swing.angle - (theta0 - math.pi))
    b1_rate = swing.rate
    b2_rate = -a1p / a3 * b1_rate * cos_b2
    omega = np.stack([-b1_rate * sin_b2, b1_rate * cos_b2, -b2_rate], axis=-1) @ frame_g.T
    vertical = np.stack([theta_sin * cos_b2, theta_sin * sin_b2, -theta_cos], axis=-1) @ frame_g.T
    horizontal = np.stack([sin_b2, -cos_b2, np.zeros_like(sin_b2)], axis=-1) @ frame_g.T
    horizontal0 = frame_g @ np.array([b2_sin, -b2_cos, 0.0])
    return _attitude_from_vertical(body, quat0, vertical, horizontal, horizontal0), omega


def _attitude_from_vertical(body, quat0, vertical, horizontal, horizontal0):
    """Quaternions (n, 4) of R(t) = [d, e_w, d × e_w] [H, e, H × e]ᵀ, with e_w = R0 e(0) the fixed world direction of
    the body vector e(t) ⊥ H(t) (n, 3); horizontal0 = e(0) (3,)."""
    down = _down(body)
    fixed = quat_to_matrix(quat0) @ horizontal0
    world = np.column_stack([down, fixed, np.cross(down, fixed)])
    body_frames = np.stack([vertical, horizontal, np.cross(vertical, horizontal)], axis=-1)
    rotation = world @ np.swapaxes(body_frames, -1, -2)
    return continuous_signs(matrix_to_quat(rotation), quat0)


def mlodzejowski_axis(body: RigidBody) -> np.ndarray:
    """The principal axis (3,) unit, body, perpendicular to OG about which the body can swing as a compound pendulum
    (for a Hess body: the middle axis, G11). Raises if there is none, or if two qualify (com on a principal axis)."""
    _require(_gravity_reason(body))
    _, axes = principal_axes(body.inertia)
    k = unit(body.weight_moment)
    candidates = [axes[:, i] for i in range(3) if abs(axes[:, i] @ k) <= CONDITION_RTOL]
    if len(candidates) != 1:
        raise ValueError(f"{len(candidates)} principal axes are perpendicular to OG: name the axis")
    return candidates[0]


def mlodzejowski(body: RigidBody, angle: float, rate: float, axis: np.ndarray | None = None,
                 heading: float = 0.0) -> Setup:
    """A Mlodzejowski rotation: ω0 = rate e about the horizontal principal axis e ⊥ OG (mlodzejowski_axis unless
    given), with the downward vertical at `angle` rad from k about e (H0 = Rot(e, angle) k; 0: G below O)."""
    e = mlodzejowski_axis(body) if axis is None else unit(axis)
    k = unit(body.weight_moment)
    vertical = math.cos(angle) * k + math.sin(angle) * np.cross(e, k)
    rotation = rotation_taking(vertical, _down(body), heading)
    return _setup(body, rotation, rate * e, "mlodzejowski")


def _swing_axis(body, quat0, omega0) -> np.ndarray:
    """The body axis e of the swing: ω0's direction, or k × H0 from rest."""
    omega0 = np.asarray(omega0, dtype=float)
    vertical = _vertical(body, quat0)
    k = unit(body.weight_moment)
    speed = float(np.linalg.norm(omega0))
    if speed > 0.0:
        return omega0 / speed
    across = np.cross(k, vertical)
    if np.linalg.norm(across) > 0.0:
        return unit(across)
    # at rest in an equilibrium (G straight below or above O): any principal axis ⊥ k describes it
    _, axes = principal_axes(body.inertia)
    for i in range(3):
        if abs(axes[:, i] @ k) <= CONDITION_RTOL:
            return axes[:, i]
    return orthogonal_unit(k)


def mlodzejowski_check(body: RigidBody, quat0: np.ndarray, omega0: np.ndarray) -> str | None:
    """ω0 along a principal axis e (or k × H0 from rest) with e ⊥ k and e horizontal (e·H0 = 0)."""
    reason = _gravity_reason(body)
    if reason:
        return reason
    e = _swing_axis(body, quat0, omega0)
    sigma = np.asarray(body.inertia, dtype=float)
    moment = float(e @ sigma @ e)
    if np.linalg.norm(sigma @ e - moment * e) > CONDITION_RTOL * np.trace(sigma):
        return "ω0 is not along a principal axis"
    if abs(e @ unit(body.weight_moment)) > CONDITION_RTOL:
        return "the rotation axis is not perpendicular to OG"
    if abs(e @ _vertical(body, quat0)) > CONDITION_RTOL:
        return "the rotation axis is not horizontal"
    return None


def mlodzejowski_solve(body, quat0, omega0, times):
    """With ϑ the angle from k to H about e: A_e ϑ̈ = -α sin ϑ (a compound pendulum); R(t) = Rot(e_w, ϑ0 - ϑ(t)) R0,
    ω(t) = -ϑ̇ e."""
    times = np.asarray(times, dtype=float)
    quat0 = quat_normalize(np.asarray(quat0, dtype=float))
    e = _swing_axis(body, quat0, omega0)
    k = unit(body.weight_moment)
    vertical = _vertical(body, quat0)
    angle0 = math.atan2(float(np.cross(k, vertical) @ e), float(k @ vertical))
    moment = float(e @ np.asarray(body.inertia, dtype=float) @ e)
    alpha = float(np.linalg.norm(body.weight_moment))
    swing = pendulum(angle0, -float(np.asarray(omega0, dtype=float) @ e), math.sqrt(alpha / moment), times)
    axis_world = quat_to_matrix(quat0) @ e
    quat = quat_mul(axis_angle_quat(axis_world, angle0 - swing.angle), quat0)
    return quat, -swing.rate[:, None] * e


# The solution of each oracle a Setup can name (reference.exact.ORACLES lists the same functions with their checks).
_SOLVES = {"lagrange_precession": lagrange_solve, "staude_rotation": staude_solve, "grioli_precession": grioli_solve,
           "hess_grioli": hess_grioli_solve, "mlodzejowski": mlodzejowski_solve}
