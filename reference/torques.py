"""External torques beyond uniform gravity (FORMULARY G12–G15): the sums over a body's terms (reference.torque_models,
one module per model) in numpy, in the engines' per-stage float closure (torque_function), their energies, work and
invariants.

The built-in models: BodyTorque (G12), CentralField (G15), PrecessionTorque (G14; see their modules).

Conserved quantities and balances (the report's definitions):
* potential terms (a fixed field direction): E = ½ σω·ω − α k·H_g + Σ V (for the field MacCullagh's potential
  (3μ/2r³) H·σH);
* a term whose scene is stationary in a frame turning at rate Ω about world z (the turning field direction): the
  Jacobi integral J = E − Ω K_z, K_z = ẑ·Rσω, conserved because the scene is stationary in the frame turning with the
  orbit (derivation: with ω_rel = ω − Ω z_b, z_b = Rᵀẑ, the Lagrangian ½(ω_rel + Ω z_b)·σ(ω_rel + Ω z_b) − V(H) does
  not depend on time, and its Jacobi function ∂L/∂ω_rel·ω_rel − L = ½σω·ω − Ω z_b·σω + V);
* any non-potential torque M_np (body torque, torque (41)): J(t) − J(0) − ∫ M_np·(ω − Ω z_b) dt = 0 (with Ω = 0 the
  work–energy balance E(t) − E(0) − ∫ M·ω dt).
"""
from __future__ import annotations

import math

import numpy as np
from scipy.interpolate import make_interp_spline

# principal_frame_for, PRINCIPAL_RTOL: the body's (reference.body, which the exact solutions read without the
# torques' sums); imported from here too.
from .body import PRINCIPAL_RTOL, RigidBody, principal_frame_for  # noqa: F401
from .rotations import quat_to_matrix
# The torques' parameters and formulas (defined once in reference.torque_models; re-exported here, where 0.1 code
# imports them from).
from .torque_models import (At, BodyTorque, CentralField, PrecessionTorque,  # noqa: F401
                            body_torque_components, gravity_gradient_components,
                            precession_components)
from .torque_models import components as model_components
from .torque_models.central_field import (field_direction_body,  # noqa: F401
                                          field_direction_world)
from .torque_models.precession import (PRECESSION_SINGULAR_ANGLE, precession_axis,  # noqa: F401
                                       transverse_angle)

# Degree of the spline through the samples of M·ω whose antiderivative is the work: error O(h^8) on smooth samples,
# far below the 1e-12 the truth's balance is judged against for the suite's sample spacings (h |ω| <= 0.05).
WORK_SPLINE_DEGREE = 7


# --- evaluation ---------------------------------------------------------------------------------------------------

def _components(omega) -> np.ndarray:
    """(..., 3) -> the three (...) component arrays."""
    return np.moveaxis(np.asarray(omega, dtype=float), -1, 0)


def body_torque(torque: BodyTorque, omega: np.ndarray) -> np.ndarray:
    """(a + b |ω|²) u: (..., 3) N m, body frame (torque_models.body_torque_components, vectorised)."""
    return np.stack(body_torque_components(torque.axis, torque.a, torque.b, _components(omega)), axis=-1)


def gravity_gradient(field: CentralField, sigma: np.ndarray, h: np.ndarray) -> np.ndarray:
    """(3μ/r³) H × σH: (..., 3) N m, body frame (torque_models.gravity_gradient_components, vectorised)."""
    return np.stack(gravity_gradient_components(field.coefficient, np.asarray(sigma, dtype=float).tolist(),
                                                _components(h)), axis=-1)


def precession_torque(torque: PrecessionTorque, sigma: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """Torque (41), (..., 3) N m body frame; σ diagonal (principal axes), u = i3 (torque_models.precession_components,
    vectorised)."""
    a1, a2, a3 = np.diag(sigma).tolist()
    p = _components(omega)
    rho = np.sqrt(p[0] * p[0] + p[1] * p[1])
    m1, m2, m3 = precession_components(a1, a2, a3, 1.0 / math.tan(torque.theta), torque.l, torque.m3, p, rho)
    return np.stack([m1, m2, np.broadcast_to(m3, m1.shape)], axis=-1)


def _numpy_at(body: RigidBody, t, quat, omega: np.ndarray) -> At:
    """The point for numpy arrays: omega (..., 3), quat (..., 4) (None: only terms that ignore the attitude may use
    it), t s broadcast to the samples."""
    components = _components(omega)

    def body_components(vector):
        rotation = quat_to_matrix(quat)
        shape = np.broadcast_shapes(rotation.shape[:-2], np.shape(t), *(np.shape(v) for v in vector))
        world = np.stack([np.broadcast_to(v, shape) for v in vector], axis=-1)
        return _components(np.einsum("...ji,...j->...i", rotation, world))

    return At(t=t, omega=components, sigma=np.asarray(body.inertia, dtype=float).tolist(), body=body_components,
              sqrt=np.sqrt, cos=np.cos, sin=np.sin)


def _term_torque(term, at: At, shape: tuple) -> np.ndarray:
    """One term's torque (shape) N m, body frame, at the numpy point at."""
    return np.stack([np.broadcast_to(m, shape[:-1]) for m in model_components(term, term.parameters(), at)], axis=-1)


def nonpotential_torque(body: RigidBody, omega: np.ndarray, quat: np.ndarray | None = None, t=0.0) -> np.ndarray:
    """The torques without a potential (TorqueModel.potential False: body torque, torque (41), ...): (..., 3) N m,
    body frame, at omega (..., 3) rad/s body (and quat (..., 4), t s for a term that depends on them)."""
    omega = np.asarray(omega, dtype=float)
    shape = omega.shape if quat is None else np.broadcast_shapes(omega.shape, np.shape(quat)[:-1] + (3,))
    total = np.zeros(shape)
    at = _numpy_at(body, t, quat, omega)
    for term in body.torques:
        if not term.potential:
            total = total + _term_torque(term, at, shape)
    return total


def external_torque(body: RigidBody, quat: np.ndarray, omega: np.ndarray, t=0.0) -> np.ndarray:
    """Every torque of the body's terms at (t s, quat (..., 4), omega (..., 3)): (..., 3) N m, body frame (not
    gravity)."""
    omega = np.asarray(omega, dtype=float)
    shape = np.broadcast_shapes(omega.shape, np.shape(quat)[:-1] + (3,))
    # the non-potential terms first, then the potential ones: the order of the sums before the terms (same bits)
    total = np.broadcast_to(nonpotential_torque(body, omega, quat, t), shape)
    at = _numpy_at(body, np.broadcast_to(np.asarray(t, dtype=float), shape[:-1]), quat, omega)
    for term in body.torques:
        if term.potential:
            total = total + _term_torque(term, at, shape)
    return np.array(total)


def point_mass_torque(mu: float, radius: float, h: np.ndarray, masses: np.ndarray, points: np.ndarray) -> np.ndarray:
    """The exact Newtonian torque (50) about O on point masses (kg) at points (n, 3) m (body frame, from O), from a
    centre at distance radius along -h (h (3,) body, unit, centre -> O): μ Σ m η × (PQ)/|PQ|³ with PQ = -r h - η."""
    to_centre = -radius * np.asarray(h, dtype=float) - points
    distance = np.linalg.norm(to_centre, axis=1)
    return mu * np.sum(masses[:, None] * np.cross(points, to_centre) / distance[:, None] ** 3, axis=0)


# --- energies, invariants -----------------------------------------------------------------------------------------

def field_potential(body: RigidBody, times: np.ndarray, quat: np.ndarray) -> np.ndarray:
    """MacCullagh's potential (3μ/2r³) H·σH (n,) J; zero without a central field."""
    field = body.torque(CentralField)
    return np.zeros(np.shape(times)) if field is None else field.potential_energy(body, times, quat)


def _orbit_rate(body: RigidBody) -> float:
    """Ω of the frame in which the scene is stationary (a term's frame_rate; 0 for none)."""
    return next((term.frame_rate for term in body.torques if term.frame_rate != 0.0), 0.0)


def energy_terms(body: RigidBody, times: np.ndarray, quat: np.ndarray, omega: np.ndarray) -> dict[str, np.ndarray]:
    """The terms of the Jacobi function J = T + V_gravity + Σ V_term − Ω K_z (E for Ω = 0), each (n,) J: kinetic,
    gravity, each potential term's energy_name ("field"), orbit."""
    quat, omega = np.asarray(quat, dtype=float), np.asarray(omega, dtype=float)
    rotation = quat_to_matrix(quat)
    momentum = omega @ body.inertia
    terms = {"kinetic": 0.5 * np.einsum("...i,...i->...", omega, momentum),
             "gravity": -np.einsum("...ji,j,i->...", rotation, body.gravity_direction, body.weight_moment),
             **{term.energy_name: term.potential_energy(body, times, quat) for term in body.torques
                if term.potential}}
    rate = _orbit_rate(body)
    if rate != 0.0:
        terms["orbit"] = -rate * np.einsum("...j,...j->...", rotation[..., 2, :], momentum)
    return terms


def work(body: RigidBody, times: np.ndarray, quat: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """W(t) = ∫₀ᵗ M_np·(ω − Ω z_b) dt (n,) J, the work of the non-potential torques (in the turning frame), from the
    samples by the antiderivative of a degree-WORK_SPLINE_DEGREE interpolating spline (fewer points: lower degree)."""
    times = np.asarray(times, dtype=float)
    omega = np.asarray(omega, dtype=float)
    relative = omega.copy()
    rate = _orbit_rate(body)
    if rate != 0.0:
        relative = relative - rate * quat_to_matrix(quat)[..., 2, :]
    power = np.einsum("...i,...i->...", nonpotential_torque(body, omega, quat, times), relative)
    if not np.any(power):
        return np.zeros_like(times)
    degree = min(WORK_SPLINE_DEGREE, len(times) - 1)
    if degree % 2 == 0:  # interpolating splines of even degree need other boundary conditions: one degree less
        degree -= 1
    spline = make_interp_spline(times, power, k=degree).antiderivative()
    return spline(times) - spline(times[0])


def has_nonpotential_torque(body: RigidBody) -> bool:
    return any(not term.potential for term in body.torques)


def energy_balance(body: RigidBody, times: np.ndarray, quat: np.ndarray, omega: np.ndarray) -> tuple[np.ndarray,
                                                                                                       float]:
    """(|J(t) − J(0) − W(t)| (n,) J, scale J): the deviation of the energy (Jacobi) balance and its scale, the sum of
    the absolute values of J's terms at t = 0 and of the largest |W|. Finite samples only; NaN where not finite."""
    terms = energy_terms(body, times, quat, omega)
    value = sum(terms.values())
    done = work(body, times, quat, omega) if has_nonpotential_torque(body) else np.zeros_like(value)
    scale = sum(abs(float(term[0])) for term in terms.values()) + float(np.max(np.abs(done)))
    return np.abs(value - value[0] - done), (scale if scale != 0.0 else 1.0)


def self_excited_applies(body: RigidBody) -> bool:
    """(36) holds: the only torque is a body torque along a principal axis i3 with A3 ≠ A1, A2 (G12)."""
    if body.torque(BodyTorque) is None or len(body.torques) != 1 or body.has_gravity:
        return False
    found = principal_frame_for(body.inertia, np.asarray(body.torque(BodyTorque).axis))
    if found is None:
        return False
    (a1, a2, a3), _ = found
    return abs(a3 - a1) > PRINCIPAL_RTOL * a3 and abs(a3 - a2) > PRINCIPAL_RTOL * a3


def self_excited_terms(body: RigidBody, omega: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The two terms of the conic-cylinder invariant (36), A1/(A2−A3) p1² and A2/(A3−A1) p2²."""
    (a1, a2, a3), frame = principal_frame_for(body.inertia, np.asarray(body.torque(BodyTorque).axis))
    p = np.asarray(omega, dtype=float) @ frame
    return a1 / (a2 - a3) * p[..., 0] ** 2, a2 / (a3 - a1) * p[..., 1] ** 2


def self_excited_value(body: RigidBody, omega: np.ndarray) -> np.ndarray:
    first, second = self_excited_terms(body, omega)
    return first - second


def _body_components(quat, vector) -> tuple:
    """Rᵀ v for floats, R from the normalised quaternion (w, x, y, z) (engines' quaternions drift off unit length by
    round-off)."""
    w, x, y, z = quat
    inv = 1.0 / (w * w + x * x + y * y + z * z)
    r00, r01, r02 = 1 - 2 * (y * y + z * z) * inv, 2 * (x * y - w * z) * inv, 2 * (x * z + w * y) * inv
    r10, r11, r12 = 2 * (x * y + w * z) * inv, 1 - 2 * (x * x + z * z) * inv, 2 * (y * z - w * x) * inv
    r20, r21, r22 = 2 * (x * z - w * y) * inv, 2 * (y * z + w * x) * inv, 1 - 2 * (x * x + y * y) * inv
    dx, dy, dz = vector
    return (r00 * dx + r10 * dy + r20 * dz, r01 * dx + r11 * dy + r21 * dz, r02 * dx + r12 * dy + r22 * dz)


class _FloatAt:
    """At (torque_models.base) in floats for one torque_function, reused from call to call: the function sets t, quat
    and omega, the terms read them. An engine evaluates the torque at every stage of every step, and a fresh At (a
    named tuple and a closure over quat) cost ~0.3 µs a call, +15% on a Pinocchio Euler step of a torque case
    (measured against 0.2.0's direct formulas). Not thread-safe, as an engine's simulation is not."""

    __slots__ = ("t", "quat", "omega", "sigma")
    sqrt, cos, sin = staticmethod(math.sqrt), staticmethod(math.cos), staticmethod(math.sin)

    def __init__(self, sigma: list):
        self.t, self.quat, self.omega, self.sigma = 0.0, (1.0, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0), sigma

    def body(self, vector) -> tuple:
        return _body_components(self.quat, vector)


def torque_function(body: RigidBody):
    """f(t s, quat (w, x, y, z) floats, omega (3 floats, rad/s body)) -> (3 floats) N m body frame: every torque of
    the body's terms, in scalar arithmetic (an engine calls it at every stage of every step; numpy's per-call cost on
    3-vectors would be ten times the arithmetic). None for a body without them. Not thread-safe (_FloatAt)."""
    if not body.has_external_torque:
        return None
    # Python floats: numpy scalars in the blocks would cost ~10x per operation
    at = _FloatAt(np.asarray(body.inertia, dtype=float).tolist())
    terms = [(term.components, tuple(map(float, term.parameters()))) for term in body.torques]
    # The formulas of torque_models on floats: a few function calls a stage (~0.2-1.5 µs on the 2-core dev machine),
    # against ~2-5 µs for pin.aba's stage.
    if len(terms) == 1:
        (components, parameters), = terms

        def evaluate_one(t, quat, omega):
            at.t, at.quat, at.omega = t, quat, omega
            return components(parameters, at)

        return evaluate_one

    def evaluate(t, quat, omega):
        at.t, at.quat, at.omega = t, quat, omega
        m = [0.0, 0.0, 0.0]
        for components, parameters in terms:
            m0, m1, m2 = components(parameters, at)
            m[0] += m0
            m[1] += m1
            m[2] += m2
        return m

    return evaluate
