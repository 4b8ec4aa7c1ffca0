"""Ferrarese's Gibbs-vector formulation of the body with a fixed point (seed 000, FORMULARY F1–F13).

The Gibbs vector q = u tan(φ/2) is a chart of SO(3) around the identity, singular at rotation angle π. Components are
in a reference frame (the world, or a chart's rotated frame c*_h, F13); σ and every body vector are in body components.
Notation: Q = [q]×, q² = q·q, B = I + Q + q qᵀ, so that 2ρ̄⁻¹ = B and 2ρ⁻¹ = Bᵀ (F4).

Numpy functions are vectorised over leading axes: q, q̇, p, ω (..., 3), matrices (..., 3, 3). σ is (3, 3), symmetric
positive definite, not necessarily diagonal; the seed's polynomial forms (13), (13'), note (10) take principal moments.
Units: σ kg m², ω rad/s, q dimensionless, q̇ 1/s, p kg m²/s (twice the angular momentum at q = 0), forces N m.

The heavy body: w = m g (O -> G) (body frame, N m) and n the unit downward vertical in the reference frame; the force
function is U = n·R(q) w (note (10) generalised) and V = -U. Every other torque M (reference.torque_models, body
components) enters as Ferrarese's generalized force (16), Q_h = M·∂ω/∂q̇_h = (ρ M)_h, written explicitly: the body
torque and torque (41) have no potential, and the central field's direction turns with time.
"""
from __future__ import annotations

import heyoka as hy
import numpy as np

from . import expressions as ex
from . import truth
from .rotations import skew

# skew(e_r) for r = 0, 1, 2: ∂Q/∂q^r.
_UNIT_SKEWS = skew(np.eye(3))


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.sum(a * b, axis=-1)


def _matvec(m: np.ndarray, v: np.ndarray) -> np.ndarray:
    return np.einsum("...ij,...j->...i", m, v)


def _one_plus_q2(q: np.ndarray) -> np.ndarray:
    """1 + q², (..., 1), for broadcasting against vectors."""
    return 1.0 + _dot(q, q)[..., None]


# --- kinematics (F1–F5) -------------------------------------------------------------------------------------------

def rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """De Finetti's formula (1): R(q) v = v + 2/(1 + q²) q × (v + q × v). Also for complex q (complex-step tests)."""
    q, v = np.asarray(q), np.asarray(v)
    return v + 2.0 / _one_plus_q2(q) * np.cross(q, v + np.cross(q, v))


def rotation_matrix(q: np.ndarray) -> np.ndarray:
    """R(q) = I + 2 (Q + Q²)/(1 + q²), (..., 3, 3) (F1)."""
    big_q = skew(q)
    return np.eye(3) + 2.0 / _one_plus_q2(q)[..., None] * (big_q + big_q @ big_q)


def rho(q: np.ndarray) -> np.ndarray:
    """ρ = 2/(1 + q²) (I + Q), (..., 3, 3) (F4, eq. (7))."""
    return 2.0 / _one_plus_q2(q)[..., None] * (np.eye(3) + skew(q))


def rho_bar(q: np.ndarray) -> np.ndarray:
    """ρ̄ = 2/(1 + q²) (I - Q) = ρᵀ, (..., 3, 3) (F4, eq. (8) corrected)."""
    return 2.0 / _one_plus_q2(q)[..., None] * (np.eye(3) - skew(q))


def omega_body(q: np.ndarray, qdot: np.ndarray) -> np.ndarray:
    """ω in body components, ρ̄ q̇ = 2/(1 + q²) (q̇ - q × q̇) (F5, eq. (9'))."""
    q, qdot = np.asarray(q, dtype=float), np.asarray(qdot, dtype=float)
    return 2.0 / _one_plus_q2(q) * (qdot - np.cross(q, qdot))


def omega_space(q: np.ndarray, qdot: np.ndarray) -> np.ndarray:
    """ω in reference-frame components, ρ q̇ = 2/(1 + q²) (q̇ + q × q̇) (F5, eq. (9))."""
    q, qdot = np.asarray(q, dtype=float), np.asarray(qdot, dtype=float)
    return 2.0 / _one_plus_q2(q) * (qdot + np.cross(q, qdot))


def qdot_from_omega_body(q: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """F5 inverted: q̇ = ½ B ω_body = ½ (ω + q × ω + (q·ω) q)."""
    q, omega = np.asarray(q, dtype=float), np.asarray(omega, dtype=float)
    return 0.5 * (omega + np.cross(q, omega) + _dot(q, omega)[..., None] * q)


def chart_change(q: np.ndarray, q_prime: np.ndarray) -> np.ndarray:
    """F13, rotated-frame variant: the Gibbs vector Q* of R(q) in the chart whose reference frame is c*_h = R(q') c_h,
    with components in that frame: Q* = (q - q' + q × q')/(1 + q·q'), so R(Q*) = R(q')ᵀ R(q).

    In these coordinates (13)–(19) keep their form with the same σ; only the gravity direction changes, n* = R(q')ᵀ n.
    """
    q, q_prime = np.asarray(q, dtype=float), np.asarray(q_prime, dtype=float)
    return (q - q_prime + np.cross(q, q_prime)) / (1.0 + _dot(q, q_prime))[..., None]


def recentre_velocity(q: np.ndarray, qdot: np.ndarray) -> np.ndarray:
    """q̇* of the same motion in the chart re-centred at q (F13 with q' = q, so Q* = 0): q̇* = ½ ω_body
    = (q̇ - q × q̇)/(1 + q²), written without σ and with one division per component."""
    q, qdot = np.asarray(q, dtype=float), np.asarray(qdot, dtype=float)
    return (qdot - np.cross(q, qdot)) / _one_plus_q2(q)


def recentre_momentum(q: np.ndarray, p: np.ndarray) -> np.ndarray:
    """p* of the same motion in the chart re-centred at q: p* = ρ(0) σ ω_body = 2 σ ω_body = Bᵀ p
    = p - q × p + (q·p) q. Written without σ: the round trip p -> ω -> p through σ⁻¹ and σ has a rounding bias
    (σ fl(σ⁻¹) != I) that would add up over the hundreds of changes of a long run."""
    q, p = np.asarray(q, dtype=float), np.asarray(p, dtype=float)
    return p - np.cross(q, p) + _dot(q, p)[..., None] * q


# --- metric (F6, F7) ----------------------------------------------------------------------------------------------

def metric(q: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """a = ρ σ ρ̄ = 4/(1 + q²)² (I + Q) σ (I - Q), (..., 3, 3): T = ½ q̇ᵀ a q̇, for any σ (F6)."""
    big_q = skew(q)
    c = 4.0 / _one_plus_q2(q)[..., None] ** 2
    return c * (np.eye(3) + big_q) @ np.asarray(sigma, dtype=float) @ (np.eye(3) - big_q)


def inverse_metric(q: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """a⁻¹ = ρ̄⁻¹ σ⁻¹ ρ⁻¹ = ¼ B σ⁻¹ Bᵀ, a quartic polynomial in q, for any σ (F7, compact form)."""
    return _inverse_metric(q, np.linalg.inv(np.asarray(sigma, dtype=float)))


def _inverse_metric(q: np.ndarray, sigma_inv: np.ndarray) -> np.ndarray:
    q = np.asarray(q, dtype=float)
    b = np.eye(3) + skew(q) + q[..., :, None] * q[..., None, :]
    return 0.25 * b @ sigma_inv @ np.swapaxes(b, -1, -2)


def metric_ferrarese(q: np.ndarray, moments: np.ndarray) -> np.ndarray:
    """Ferrarese's (13) for principal moments A = (A1, A2, A3) (indices cyclic):
    a_hh = 4/(1+q²)² [A_h + A_{h+1} (q^{h+2})² + A_{h+2} (q^{h+1})²],
    a_{h,h+1} = 4/(1+q²)² [(A_h - A_{h+1}) q^{h+2} - A_{h+2} q^h q^{h+1}]."""
    q = np.asarray(q, dtype=float)
    a = np.asarray(moments, dtype=float)
    c = 4.0 / (1.0 + _dot(q, q)) ** 2
    out = np.empty(q.shape + (3,))
    for h in range(3):
        i, j, k = h, (h + 1) % 3, (h + 2) % 3
        out[..., i, i] = c * (a[i] + a[j] * q[..., k] ** 2 + a[k] * q[..., j] ** 2)
        out[..., i, j] = out[..., j, i] = c * ((a[i] - a[j]) * q[..., k] - a[k] * q[..., i] * q[..., j])
    return out


def inverse_metric_ferrarese(q: np.ndarray, moments: np.ndarray) -> np.ndarray:
    """Ferrarese's (13') for principal moments (indices cyclic):
    4a^hh = [1+(q^h)²]²/A_h + (q^{h+2} - q^h q^{h+1})²/A_{h+1} + (q^{h+1} + q^h q^{h+2})²/A_{h+2},
    4a^{h,h+1} = [1+(q^h)²](q^{h+2} + q^h q^{h+1})/A_h - [1+(q^{h+1})²](q^{h+2} - q^h q^{h+1})/A_{h+1}
                 - (q^{h+1} + q^h q^{h+2})(q^h - q^{h+1} q^{h+2})/A_{h+2}."""
    q = np.asarray(q, dtype=float)
    a = np.asarray(moments, dtype=float)
    out = np.empty(q.shape + (3,))
    for h in range(3):
        i, j, k = h, (h + 1) % 3, (h + 2) % 3
        qi, qj, qk = q[..., i], q[..., j], q[..., k]
        out[..., i, i] = 0.25 * ((1 + qi ** 2) ** 2 / a[i] + (qk - qi * qj) ** 2 / a[j] + (qj + qi * qk) ** 2 / a[k])
        out[..., i, j] = out[..., j, i] = 0.25 * ((1 + qi ** 2) * (qk + qi * qj) / a[i]
                                                  - (1 + qj ** 2) * (qk - qi * qj) / a[j]
                                                  - (qj + qi * qk) * (qi - qj * qk) / a[k])
    return out


def metric_derivative(q: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """∂a_hk/∂q^r as (..., 3, 3, 3) indexed [r, h, k]:
    ∂_r a = -4 q^r/(1 + q²) a + 4/(1 + q²)² (E_r σ (I - Q) - (I + Q) σ E_r), E_r = [e_r]×."""
    q = np.asarray(q, dtype=float)
    sigma = np.asarray(sigma, dtype=float)
    big_q = skew(q)[..., None, :, :]
    one_plus = (1.0 + _dot(q, q))[..., None, None, None]
    c = 4.0 / one_plus ** 2
    a = metric(q, sigma)[..., None, :, :]
    parts = _UNIT_SKEWS @ sigma @ (np.eye(3) - big_q) - (np.eye(3) + big_q) @ sigma @ _UNIT_SKEWS
    return -4.0 * q[..., :, None, None] / one_plus * a + c * parts


def christoffel(q: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """Christoffel symbols of the first kind (rs,k) = ½(∂_r a_sk + ∂_s a_kr - ∂_k a_rs), (..., 3, 3, 3) [r, s, k]."""
    da = metric_derivative(q, sigma)
    return 0.5 * (da + np.einsum("...skr->...rsk", da) - np.einsum("...krs->...rsk", da))


# --- forces (F9, F12) ---------------------------------------------------------------------------------------------

def generalized_force(q: np.ndarray, torque: np.ndarray) -> np.ndarray:
    """(16): F = ρ̄ M = 2/(1 + q²) (M - q × M), M the torque about O in reference-frame components (N m)."""
    q, torque = np.asarray(q, dtype=float), np.asarray(torque, dtype=float)
    return 2.0 / _one_plus_q2(q) * (torque - np.cross(q, torque))


def generalized_force_body(q: np.ndarray, torque_body: np.ndarray) -> np.ndarray:
    """(16) with M in body components: Q_h = M·∂ω_body/∂q̇_h, i.e. Q = ρ̄ᵀ M = ρ M = 2/(1 + q²) (M + q × M) (N m)."""
    q, torque_body = np.asarray(q, dtype=float), np.asarray(torque_body, dtype=float)
    return 2.0 / _one_plus_q2(q) * (torque_body + np.cross(q, torque_body))


def gravity_torque(q: np.ndarray, weight_moment: np.ndarray, down: np.ndarray) -> np.ndarray:
    """Torque of uniform gravity about O, reference-frame components: (R(q) w) × n (N m)."""
    return np.cross(rotate(np.asarray(q, dtype=float), weight_moment), down)


def force_function(q: np.ndarray, weight_moment: np.ndarray, down: np.ndarray) -> np.ndarray:
    """U = n·R(q) w (J): note (10) for any gravity direction n and centre of mass (w = m g OG, body frame).
    Grows as G goes down. Accepts complex q (complex-step tests)."""
    return np.sum(np.asarray(down) * rotate(q, np.asarray(weight_moment)), axis=-1)


def force_function_ferrarese(q: np.ndarray, mass_gravity: float, com: np.ndarray) -> np.ndarray:
    """Ferrarese's note (10) with c3 the downward vertical and G = (x0, y0, z0) in body coordinates:
    U = M g z0 - 2 M g/(1 + q²) [x0 (q2 - q1 q3) - y0 (q1 + q2 q3) + z0 (q1² + q2²)] (the seed omits M g z0)."""
    q = np.asarray(q, dtype=float)
    x0, y0, z0 = np.asarray(com, dtype=float)
    q1, q2, q3 = q[..., 0], q[..., 1], q[..., 2]
    bracket = x0 * (q2 - q1 * q3) - y0 * (q1 + q2 * q3) + z0 * (q1 ** 2 + q2 ** 2)
    return mass_gravity * z0 - 2.0 * mass_gravity / (1.0 + _dot(q, q)) * bracket


# --- Lagrangian (17'') and Hamiltonian (18)–(19) ----------------------------------------------------------------

def momentum(q: np.ndarray, qdot: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """p = ∂T/∂q̇ = a q̇ (F6)."""
    return _matvec(metric(q, sigma), qdot)


def kinetic_energy(q: np.ndarray, qdot: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """T = ½ q̇ᵀ a q̇ (J)."""
    return 0.5 * _dot(qdot, momentum(q, qdot, sigma))


def lagrangian_acceleration(q: np.ndarray, qdot: np.ndarray, sigma: np.ndarray, weight_moment: np.ndarray,
                            down: np.ndarray, sigma_inv: np.ndarray | None = None,
                            torque_body: np.ndarray | None = None) -> np.ndarray:
    """(17''): q̈^h = a^hk [F_k - (rs,k) q̇^r q̇^s], F the generalized force (16) of gravity and of torque_body
    (..., 3) N m, body components, the other external torques (1/s²).

    sigma_inv: σ⁻¹ when the caller has it (saves an inversion per call).
    """
    sigma = np.asarray(sigma, dtype=float)
    sigma_inv = np.linalg.inv(sigma) if sigma_inv is None else sigma_inv
    force = generalized_force(q, gravity_torque(q, weight_moment, down))
    if torque_body is not None:
        force = force + generalized_force_body(q, torque_body)
    geodesic = np.einsum("...rsk,...r,...s->...k", christoffel(q, sigma), qdot, qdot)
    return _matvec(_inverse_metric(q, sigma_inv), force - geodesic)


def hamiltonian(q: np.ndarray, p: np.ndarray, sigma: np.ndarray, weight_moment: np.ndarray,
                down: np.ndarray) -> np.ndarray:
    """(19): ℋ = ½ a^hk p_h p_k - U(q) (J), the energy T + V."""
    return 0.5 * _dot(p, _matvec(inverse_metric(q, sigma), p)) - force_function(q, weight_moment, down)


def hamiltonian_rhs(q: np.ndarray, p: np.ndarray, sigma_inv: np.ndarray, weight_moment: np.ndarray,
                    down: np.ndarray, torque_body: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(18): q̇ = ∂ℋ/∂p, ṗ = -∂ℋ/∂q + Q, with ℋ's quartic kinetic part written out:
    m = σ⁻¹ Bᵀ p (= 2 ω_body), q̇ = ¼ B m, ṗ = -¼ [m × p + (q·m) p + (q·p) m] + F (F = ∇U, eq. (16)) + Q,
    Q = ρ M the generalized force of torque_body (..., 3) N m, body components (the other external torques)."""
    q, p = np.asarray(q, dtype=float), np.asarray(p, dtype=float)
    m = 2.0 * omega_from_momentum(q, p, sigma_inv)
    qdot = 0.25 * (m + np.cross(q, m) + _dot(q, m)[..., None] * q)
    force = generalized_force(q, gravity_torque(q, weight_moment, down))
    if torque_body is not None:
        force = force + generalized_force_body(q, torque_body)
    pdot = -0.25 * (np.cross(m, p) + _dot(q, m)[..., None] * p + _dot(q, p)[..., None] * m) + force
    return qdot, pdot


def omega_from_momentum(q: np.ndarray, p: np.ndarray, sigma_inv: np.ndarray) -> np.ndarray:
    """ω_body = ρ̄ a⁻¹ p = ½ σ⁻¹ Bᵀ p = σ⁻¹ ρ⁻¹ p (rad/s): ρ⁻¹ p is the angular momentum in body components (F8)."""
    q, p = np.asarray(q, dtype=float), np.asarray(p, dtype=float)
    transposed = p - np.cross(q, p) + _dot(q, p)[..., None] * q
    return 0.5 * _matvec(sigma_inv, transposed)


def momentum_from_omega(q: np.ndarray, omega: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """p = ρ σ ω_body (F6 with ω_body = ρ̄ q̇)."""
    return _matvec(rho(q), _matvec(np.asarray(sigma, dtype=float), omega))


# --- the same, as heyoka expressions (runtime parameters: reference.expressions) ---------------------------------

def _metric_expr(q: list, sigma: list) -> list[list]:
    one_plus = 1.0 + ex.dot(q, q)
    c = 4.0 / (one_plus * one_plus)
    plus = [[(1.0 if i == j else 0.0) + s for j, s in enumerate(row)] for i, row in enumerate(_skew_expr(q))]
    minus = ex.transpose(plus)  # (I + Q)ᵀ = I - Q
    product = ex.matmul(ex.matmul(plus, sigma), minus)
    return [[c * product[i][j] for j in range(3)] for i in range(3)]


def _inverse_metric_expr(q: list, sigma_inv: list) -> list[list]:
    skew_q = _skew_expr(q)
    b = [[(1.0 if i == j else 0.0) + skew_q[i][j] + q[i] * q[j] for j in range(3)] for i in range(3)]
    product = ex.matmul(ex.matmul(b, sigma_inv), ex.transpose(b))
    return [[0.25 * product[i][j] for j in range(3)] for i in range(3)]


def _skew_expr(v: list) -> list[list]:
    zero = hy.expression(0.0)
    return [[zero, -v[2], v[1]], [v[2], zero, -v[0]], [-v[1], v[0], zero]]


def _force_function_expr(q: list, weight_moment: list, down: list):
    """U = n·R(q) w = [(1 - q²)(n·w) + 2 (n·q)(q·w) + 2 n·(q × w)]/(1 + q²)."""
    q2 = ex.dot(q, q)
    numerator = ((1.0 - q2) * ex.dot(down, weight_moment) + 2.0 * ex.dot(down, q) * ex.dot(q, weight_moment)
                 + 2.0 * ex.dot(down, ex.cross(q, weight_moment)))
    return numerator / (1.0 + q2)


def _external_force_expr(q: list, omega: list) -> list:
    """Q = ρ M (16), M the torques of reference.torque_models (truth.body_torque_expressions) at ω (body), a vector
    D of the chart's reference frame seen in the body as R(q)ᵀ D = D - 2/(1 + q²) q × (D - q × D)."""
    one_plus = 1.0 + ex.dot(q, q)

    def body_components(d):
        q_cross_d = ex.cross(q, d)
        turned = ex.cross(q, [d[i] - q_cross_d[i] for i in range(3)])
        return [d[i] - 2.0 * turned[i] / one_plus for i in range(3)]

    torque = truth.body_torque_expressions(body_components, omega, ex.symmetric(ex.SIGMA))
    q_cross_m = ex.cross(q, torque)
    return [2.0 * (torque[i] + q_cross_m[i]) / one_plus for i in range(3)]


def lagrangian_equations() -> tuple[list, list, object]:
    """(17'') for heyoka: variables (q1, q2, q3, q̇1, q̇2, q̇3), right-hand sides, and the chart measure q·q.

    The Christoffel symbols and F = ∇U are taken symbolically (hy.diff) from a_hk and U, independently of the numpy
    closed forms above, so the two check each other; the other torques' generalized force is written explicitly
    (_external_force_expr). Parameters: reference.truth's layout.
    """
    variables = hy.make_vars("q1", "q2", "q3", "qd1", "qd2", "qd3")
    q, qdot = variables[:3], variables[3:]
    sigma, sigma_inv = ex.symmetric(ex.SIGMA), ex.symmetric(ex.SIGMA_INV)
    a = _metric_expr(q, sigma)
    potential = _force_function_expr(q, ex.vector(ex.WEIGHT_MOMENT), ex.vector(ex.DOWN))
    q_cross_qdot = ex.cross(q, qdot)
    omega = [2.0 * (qdot[i] - q_cross_qdot[i]) / (1.0 + ex.dot(q, q)) for i in range(3)]  # ρ̄ q̇ (F5)
    external = _external_force_expr(q, omega)
    force = [hy.diff(potential, q[k]) + external[k] for k in range(3)]
    da = [[[hy.diff(a[h][k], q[r]) for k in range(3)] for h in range(3)] for r in range(3)]
    geodesic = [hy.sum([0.5 * (da[r][s][k] + da[s][k][r] - da[k][r][s]) * qdot[r] * qdot[s]
                        for r in range(3) for s in range(3)]) for k in range(3)]
    qddot = ex.matvec(_inverse_metric_expr(q, sigma_inv), [force[k] - geodesic[k] for k in range(3)])
    return variables, list(qdot) + qddot, ex.dot(q, q)


def hamiltonian_expression(q: list, p: list):
    """(19): ℋ = ½ a^hk p_h p_k - U, a heyoka expression (a^hk = ¼ B σ⁻¹ Bᵀ, quartic in q)."""
    kinetic = 0.5 * ex.dot(p, ex.matvec(_inverse_metric_expr(q, ex.symmetric(ex.SIGMA_INV)), p))
    return kinetic - _force_function_expr(q, ex.vector(ex.WEIGHT_MOMENT), ex.vector(ex.DOWN))


def hamiltonian_equations() -> tuple[list, list, object]:
    """(18) for heyoka: variables (q1, q2, q3, p1, p2, p3), q̇ = ∂ℋ/∂p and ṗ = -∂ℋ/∂q + Q (ℋ by hy.diff, the other
    torques' Q = ρ M explicitly), chart measure q·q. Parameters: reference.truth's layout."""
    variables = hy.make_vars("q1", "q2", "q3", "p1", "p2", "p3")
    q, p = variables[:3], variables[3:]
    energy = hamiltonian_expression(q, p)
    qp = ex.dot(q, p)
    q_cross_p = ex.cross(q, p)
    omega = ex.matvec(ex.symmetric(ex.SIGMA_INV), [0.5 * (p[i] - q_cross_p[i] + qp * q[i]) for i in range(3)])
    external = _external_force_expr(q, omega)  # ω = ½ σ⁻¹ Bᵀ p (F8)
    rhs = [hy.diff(energy, p[k]) for k in range(3)] + [-hy.diff(energy, q[k]) + external[k] for k in range(3)]
    return variables, rhs, ex.dot(q, q)
