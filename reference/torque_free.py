"""The torque-free rigid body (Euler–Poinsot) in closed form: ω(t), the attitude, periods, Montgomery's phase.

Any inertia about O (3, 3), symmetric positive definite, diagonal or not: it is diagonalised (eigh, refined in
40-digit decimals), the motion is computed in principal axes e1, e2, e3 (I1 > I2 > I3) and mapped back. Quaternions (w, x, y, z) map body to world
(DESIGN §2); ω is in body components, rad/s; times in s (any real values, any order).

Families (FORMULARY T7–T9; L = |M| the angular momentum, E the kinetic energy):
* L² > 2 E I2: ω circulates about the axis of largest moment; L² < 2 E I2: about the axis of smallest moment.
  Both are written with the encircled axis a, the middle axis b and the third axis c, (f_a, f_b, f_c) right-handed:
  (e1, e2, e3) or (e3, e2, -e1). With τ = λ t + τ0:
      ω_a = s W_a dn τ,   ω_b = W_b sn τ,   ω_c = -d s W_c cn τ       (s = sign ω_a, d = sign(I_a - I_b))
      W_a² = (L² - 2EI_c) / (I_a (I_a - I_c)),  W_b² = (2EI_a - L²) / (I_b (I_a - I_b)),
      W_c² = (2EI_a - L²) / (I_c (I_a - I_c)),  λ² = (I_a - I_b)(L² - 2EI_c) / (I_a I_b I_c),
      m = (I_b - I_c)(2EI_a - L²) / ((I_a - I_b)(L² - 2EI_c)).
  The attitude goes through the invariable plane: R(t) [f_b f_c f_a] = Q0 Rz(φ(t)) Rx(θ(t)) Rz(ψ(t)), where
  (θ, ψ) are the polar angles of m = M/L about f_a in the body (so they follow from ω(t) algebraically) and Q0 is
  constant with Q0 e_z = M/L in the world. The precession angle about M obeys (Celledoni, Fassò, Säfström, Zanna 2008,
  derived afresh here, see `_Triaxial`)
      φ̇ = L (I_b ω_b² + I_c ω_c²) / (I_b² ω_b² + I_c² ω_c²) = L/I_a + L (I_a - I_c)/(I_a I_c) / (1 + ν sn² τ),
      ν = I_a (I_b - I_c) / (I_c (I_a - I_b)) >= 0,
  so φ is linear in t plus an incomplete elliptic integral of the third kind (Carlson R_F, R_J).
* A symmetric body (two equal moments) in closed form with trigonometric functions: precession about M at rate
  L/I_eq composed with a body-fixed spin about the symmetry axis (FORMULARY T7).
* The separatrix L² = 2 E I2 in closed form (FORMULARY T8): ω by tanh and sech; the attitude is a rotation about M
  at rate L/I2 composed with a rotation about the fixed normal of the great circle that m(t) runs along.
* A rotation about a principal axis (or rest) is uniform.

Its home is here, outside reference/exact/ (whose package re-exports it), so that the splitting integrator
(harness.integrators.geometric) steps the free flow without importing every exact solution.
"""
from __future__ import annotations

import abc
import math
from dataclasses import dataclass
from decimal import Decimal, localcontext
from typing import Protocol

import numpy as np
from scipy.special import ellipkm1

from .closed_form import (PRECISE_DIGITS, SYMMETRIC_RTOL, axis_angle_quat, continuous_signs, first_kind,
                          jacobi, principal_frame_precise, third_kind_complete, third_kind_reduced)
from .rotations import matrix_to_quat, quat_mul, quat_normalize, quat_to_matrix



class FreeBody(Protocol):
    """What the flow reads of a body (a reference.body.RigidBody, not imported: the flow never builds or checks one, and
    the splitting integrator imports it without the body's torque registry, tests/test_import_chain.py)."""

    inertia: np.ndarray  # (3, 3) kg m^2 about O, body frame
    has_gravity: bool

# |δ| below this (see separatrix_distance) is the separatrix: a state built on it in double precision has
# |δ| ~ 1e-16, and the motion leaves the separatrix like |δ| e^{λ t}, so a looser bound would be another motion.
SEPARATRIX_TOL = 1e-12


def _wrap(angle: float) -> float:
    """angle (rad) -> (-π, π]."""
    wrapped = math.remainder(angle, 2.0 * math.pi)
    return math.pi if wrapped == -math.pi else wrapped


def _rodrigues(axis: np.ndarray, angle: np.ndarray, vector: np.ndarray) -> np.ndarray:
    """Rotate vector (3,) about the unit axis (3,) by angle (n,) rad -> (n, 3)."""
    angle = np.asarray(angle, dtype=float)[:, None]
    c, s = np.cos(angle), np.sin(angle)
    return c * vector + s * np.cross(axis, vector) + (1.0 - c) * (axis @ vector) * axis


@dataclass(frozen=True, eq=False)
class FreeMotion(abc.ABC):
    """One torque-free motion, fixed by its initial state.

    kind: "major" / "minor" (ω circulates about the axis of largest / smallest moment), "symmetric", "separatrix",
        "uniform" (a rotation about a principal axis, or rest).
    energy: J, kinetic energy E.  momentum: N m s, L = |σω|.
    period: s, period of ω(t) in the body (inf on the separatrix and for a uniform rotation about the middle axis;
        for a uniform rotation about the largest or smallest axis the small-oscillation limit of T9).
    solid_angle: sr, signed area Ω enclosed by M/L on the body sphere over one period (FORMULARY T9; nan when the
        curve does not close).
    precession: rad, the precession angle Φ(T) about M over one period, continuous (not reduced mod 2π).
    """

    kind: str
    energy: float
    momentum: float
    period: float
    solid_angle: float
    precession: float

    @property
    def montgomery_phase(self) -> float:
        """Δθ ≡ 2ET/L - Ω (mod 2π), in (-π, π]: R(t + T) = Rot(M, Δθ) R(t) (FORMULARY T9)."""
        if not (math.isfinite(self.period) and math.isfinite(self.solid_angle)):
            return float("nan")
        return _wrap(2.0 * self.energy * self.period / self.momentum - self.solid_angle)

    @abc.abstractmethod
    def omega(self, times: np.ndarray) -> np.ndarray:
        """(n,) s -> (n, 3) rad/s, body frame."""

    @abc.abstractmethod
    def quat(self, times: np.ndarray) -> np.ndarray:
        """(n,) s -> (n, 4) unit quaternions (w, x, y, z), body -> world, sign continuous between samples."""

    def evaluate(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(n,) s -> (quat (n, 4), omega (n, 3) rad/s body)."""
        return self.quat(times), self.omega(times)


@dataclass(frozen=True, eq=False)
class _Uniform(FreeMotion):
    quat0: np.ndarray = None  # type: ignore[assignment]
    omega0: np.ndarray = None  # type: ignore[assignment]

    def omega(self, times):
        times = np.asarray(times, dtype=float)
        return np.broadcast_to(self.omega0, times.shape + (3,)).copy()

    def quat(self, times):
        times = np.asarray(times, dtype=float)
        speed = np.linalg.norm(self.omega0)
        if speed == 0.0:
            return np.broadcast_to(self.quat0, times.shape + (4,)).copy()
        return quat_mul(self.quat0, axis_angle_quat(self.omega0 / speed, speed * times))


@dataclass(frozen=True, eq=False)
class _Symmetric(FreeMotion):
    """ω = (L/I_eq) m - Λ f_a: R(t) = Rot(M̂, L t / I_eq) R0 Rot(f_a, -Λ t), ω(t) = Rot(f_a, Λ t) ω0."""

    quat0: np.ndarray = None  # type: ignore[assignment]
    omega0: np.ndarray = None  # type: ignore[assignment]
    axis: np.ndarray = None  # type: ignore[assignment]   # f_a, body
    momentum_world: np.ndarray = None  # type: ignore[assignment]  # M̂, world, unit
    precession_rate: float = 0.0  # L / I_eq, rad/s
    spin_rate: float = 0.0  # Λ = (I_a - I_eq) ω_a / I_eq, rad/s

    def omega(self, times):
        return _rodrigues(self.axis, self.spin_rate * np.asarray(times, dtype=float), self.omega0)

    def quat(self, times):
        times = np.asarray(times, dtype=float)
        precession = axis_angle_quat(self.momentum_world, self.precession_rate * times)
        spin = axis_angle_quat(self.axis, -self.spin_rate * times)
        return quat_mul(quat_mul(precession, self.quat0), spin)


@dataclass(frozen=True, eq=False)
class _Triaxial(FreeMotion):
    """The elliptic solution of either family (module docstring).

    The precession rate: with Euler angles (φ, θ, ψ) of the frame G = (f_b, f_c, f_a) about M, FORMULARY C4 gives
    ω_b m_b + ω_c m_c = φ̇ sin²θ and sin²θ = m_b² + m_c², so φ̇ = L (I_b ω_b² + I_c ω_c²) / (L² - I_a² ω_a²). With
    I_a² ω_a² = I_a² W_a² dn² and L² - I_a² W_a² = I_c² W_c² this is L/I_a + L (I_a - I_c)/(I_a I_c (1 + ν sn²)),
    derived here from the two lines above rather than transcribed (the issue warns of a published sign error in
    Celledoni et al.'s λ) and checked against Euler's equations, the kinematics and the truth (tests/test_exact*).
    """

    frame_g: np.ndarray = None  # type: ignore[assignment]  # (3, 3) columns f_b, f_c, f_a, body
    moments: tuple = ()  # (I_a, I_b, I_c)
    amplitudes: tuple = ()  # (s W_a, W_b, -d s W_c): ω_a = amp[0] dn, ω_b = amp[1] sn, ω_c = amp[2] cn
    rate: float = 0.0  # λ, 1/s
    parameter: float = 0.0  # m
    complement: float = 0.0  # 1 - m
    quarter: float = 0.0  # K(m)
    nu: float = 0.0
    tau0: float = 0.0
    third_complete: float = 0.0  # ∫_0^K dτ/(1 + ν sn²)
    third0: float = 0.0  # ∫_0^τ0 dτ/(1 + ν sn²)
    coefficient: float = 0.0  # L (I_a - I_c)/(I_a I_c λ)
    q_fixed: np.ndarray = None  # type: ignore[assignment]  # Q0, (3, 3)
    quat0: np.ndarray = None  # type: ignore[assignment]

    def _functions(self, times):
        tau = self.tau0 + self.rate * np.asarray(times, dtype=float)
        return jacobi(tau, self.parameter, self.quarter, self.complement)

    def _omega_g(self, sn, cn, dn):
        """ω in G = (f_b, f_c, f_a) components, (n, 3)."""
        amp_a, amp_b, amp_c = self.amplitudes
        return np.stack([amp_b * sn, amp_c * cn, amp_a * dn], axis=-1)

    def omega(self, times):
        sn, cn, dn, *_ = self._functions(times)
        return self._omega_g(sn, cn, dn) @ self.frame_g.T

    def quat(self, times):
        times = np.asarray(times, dtype=float)
        sn, cn, dn, j, sn_r, cn_r, dn_r = self._functions(times)
        i_a, i_b, i_c = self.moments
        omega_g = self._omega_g(sn, cn, dn)
        unit_m = omega_g * np.array([i_b, i_c, i_a]) / self.momentum
        phi = self.momentum / i_a * times + self.coefficient * (
            2.0 * j * self.third_complete + third_kind_reduced(sn_r, cn_r, dn_r, self.nu) - self.third0)
        rotation = self.q_fixed @ _rz(phi) @ _polar_frame(unit_m) @ self.frame_g.T
        return continuous_signs(matrix_to_quat(rotation), self.quat0)


@dataclass(frozen=True, eq=False)
class _Separatrix(FreeMotion):
    """FORMULARY T8 with u = λ (t - t0): ω2 = ε W tanh u, ω1 = s1 W1 sech u, ω3 = -ε s1 W3 sech u;
    R(t) = Rot(M̂, W t) Rot(n, θ(t) - θ(0)) R0, θ the angle between m and e2 (cos θ = ε tanh u, sin θ = sech u),
    n the fixed unit normal of the plane of m(t) (world)."""

    axes: np.ndarray = None  # type: ignore[assignment]  # principal e1, e2, e3 columns, body
    amplitudes: tuple = ()  # (s1 W1, ε W, -ε s1 W3)
    rate: float = 0.0  # λ
    u0: float = 0.0
    direction: float = 1.0  # ε
    momentum_world: np.ndarray = None  # type: ignore[assignment]
    normal_world: np.ndarray = None  # type: ignore[assignment]
    quat0: np.ndarray = None  # type: ignore[assignment]

    def omega(self, times):
        u = self.u0 + self.rate * np.asarray(times, dtype=float)
        sech = 1.0 / np.cosh(u)
        a1, a2, a3 = self.amplitudes
        return np.stack([a1 * sech, a2 * np.tanh(u), a3 * sech], axis=-1) @ self.axes.T

    def quat(self, times):
        times = np.asarray(times, dtype=float)
        u = self.u0 + self.rate * times
        # θ = π/2 - ε gd(u), gd(u) = atan(sinh u): differences of gd keep their digits for every u
        turn = -self.direction * (np.arctan(np.sinh(u)) - math.atan(math.sinh(self.u0)))
        w = abs(self.amplitudes[1])
        precession = axis_angle_quat(self.momentum_world, w * times)
        flip = axis_angle_quat(self.normal_world, turn)
        return quat_mul(quat_mul(precession, flip), self.quat0)


def _rz(angle: np.ndarray) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    zero, one = np.zeros_like(c), np.ones_like(c)
    return np.stack([np.stack([c, -s, zero], -1), np.stack([s, c, zero], -1), np.stack([zero, zero, one], -1)], -2)


def _polar_frame(unit_m: np.ndarray) -> np.ndarray:
    """B = Rx(θ) Rz(ψ) with Bᵀ e_z = m, for m (n, 3) in G components (m_b, m_c, m_a) = (sθ sψ, sθ cψ, cθ).

    Built from m itself, never from the angles, so it keeps full accuracy near the pole (small θ)."""
    mb, mc, ma = unit_m[..., 0], unit_m[..., 1], unit_m[..., 2]
    s_theta = np.hypot(mb, mc)
    safe = np.where(s_theta > 0.0, s_theta, 1.0)
    s_psi = np.where(s_theta > 0.0, mb / safe, 0.0)
    c_psi = np.where(s_theta > 0.0, mc / safe, 1.0)
    zero = np.zeros_like(mb)
    return np.stack([np.stack([c_psi, -s_psi, zero], -1),
                     np.stack([ma * s_psi, ma * c_psi, -s_theta], -1),
                     np.stack([mb, mc, ma], -1)], -2)


def _invariants(moments, w) -> tuple:
    """2E (J), L² (N² m² s²), and L² - 2 E I2 from principal moments (I1 >= I2 >= I3) and principal ω (sequences of
    3, float or Decimal), in the precision of the arguments."""
    i1, i2, i3 = moments
    two_energy = i1 * w[0] * w[0] + i2 * w[1] * w[1] + i3 * w[2] * w[2]
    momentum2 = (i1 * w[0]) ** 2 + (i2 * w[1]) ** 2 + (i3 * w[2]) ** 2
    # Σ I_i ω_i² (I_i - I2): the only sum with a cancellation, which is the distance to the separatrix itself
    separatrix = i1 * w[0] * w[0] * (i1 - i2) - i3 * w[2] * w[2] * (i2 - i3)
    return two_energy, momentum2, separatrix


def _principal_state(body: FreeBody, omega0: np.ndarray) -> tuple[list, np.ndarray, list]:
    """Principal moments (Decimal), axes ((3, 3) float, columns e1, e2, e3) and ω in principal components
    (Decimal), refined beyond float64 (see principal_frame_precise)."""
    moments, axes, w = principal_frame_precise(body.inertia, omega0)
    return moments, np.array([[float(x) for x in row] for row in axes]), w


def _symmetric_axis(moments: list, axes: np.ndarray) -> tuple[np.ndarray, float, float] | None:
    """(f_a, I_a, I_eq) if two of the refined moments (Decimal, descending) are equal within SYMMETRIC_RTOL, else
    None. Spherical: f_a = e3, I_a = I_eq."""
    i1, i2, i3 = moments
    tolerance = Decimal(SYMMETRIC_RTOL) * i1
    top, bottom = i1 - i2 <= tolerance, i2 - i3 <= tolerance
    if top and bottom:
        mean = float((i1 + i2 + i3) / 3)
        return axes[:, 2], mean, mean
    if top:
        return axes[:, 2], float(i3), float((i1 + i2) / 2)
    if bottom:
        return axes[:, 0], float(i1), float((i2 + i3) / 2)
    return None


def separatrix_distance(body: FreeBody, omega0: np.ndarray) -> float:
    """δ = (L²/(2E) - I2) / (I1 - I3), dimensionless: > 0 circulates about the largest axis, < 0 about the smallest,
    0 on the separatrix. nan for a symmetric body or a body at rest (no separatrix)."""
    moments, axes, w = _principal_state(body, omega0)
    with localcontext() as context:
        context.prec = PRECISE_DIGITS
        two_energy, _, separatrix = _invariants(moments, w)
        if _symmetric_axis(moments, axes) is not None or two_energy == 0:
            return float("nan")
        return float(separatrix / (two_energy * (moments[0] - moments[2])))


def free_motion(body: FreeBody, quat0: np.ndarray, omega0: np.ndarray) -> FreeMotion:
    """Analyse the torque-free motion from (quat0 (4,) wxyz, omega0 (3,) rad/s body); gravity is ignored.

    On the separatrix (|δ| <= SEPARATRIX_TOL) the separatrix solution is used; for such states the elliptic
    solution's modulus would be 1 to rounding."""
    quat0 = quat_normalize(np.asarray(quat0, dtype=float))
    omega0 = np.asarray(omega0, dtype=float)
    moments_x, axes, w_x = _principal_state(body, omega0)
    with localcontext() as context:
        context.prec = PRECISE_DIGITS
        two_energy_x, momentum2_x, separatrix_x = _invariants(moments_x, w_x)
        momentum = float(momentum2_x.sqrt())
    moments, w = np.array([float(x) for x in moments_x]), np.array([float(x) for x in w_x])
    two_energy, separatrix = float(two_energy_x), float(separatrix_x)
    energy = 0.5 * two_energy

    symmetric = _symmetric_axis(moments_x, axes)
    if symmetric is not None:
        return _symmetric_motion(body, quat0, omega0, symmetric, energy, momentum)

    i1, i2, i3 = moments
    small = [abs(x) == 0.0 for x in w]
    if sum(small) >= 2:  # ω along a principal axis, or rest
        period = float("inf")
        if not small[0] or not small[2]:  # largest or smallest axis: the small-oscillation period (T9, m -> 0)
            speed = float(np.linalg.norm(w))
            period = 2.0 * math.pi / (speed * math.sqrt((i1 - i2) * (i1 - i3) / (i2 * i3) if not small[0]
                                                         else (i1 - i3) * (i2 - i3) / (i1 * i2)))
        return _Uniform("uniform", energy, momentum, period, 0.0 if math.isfinite(period) else float("nan"),
                        float(np.linalg.norm(w)) * period, quat0=quat0, omega0=omega0.copy())

    if abs(separatrix) <= SEPARATRIX_TOL * two_energy * (i1 - i3):
        return _separatrix_motion(body, quat0, omega0, moments, axes, w, energy, momentum)
    return _triaxial_motion(quat0, moments_x, axes, w_x, energy, momentum, separatrix_x)


def _symmetric_motion(body, quat0, omega0, symmetric, energy, momentum) -> FreeMotion:
    axis, i_a, i_eq = symmetric
    if momentum == 0.0:
        return _Uniform("uniform", energy, momentum, float("inf"), float("nan"), float("nan"),
                        quat0=quat0, omega0=omega0.copy())
    momentum_body = np.asarray(body.inertia, dtype=float) @ omega0
    momentum_world = quat_to_matrix(quat0) @ momentum_body / momentum
    spin_rate = (i_a - i_eq) * float(omega0 @ axis) / i_eq
    precession_rate = momentum / i_eq
    period = 2.0 * math.pi / abs(spin_rate) if spin_rate != 0.0 else float("inf")
    if math.isfinite(period):
        # m runs round a circle of colatitude arccos|m_a| about ±f_a, counter-clockwise about the pole iff I_a > I_eq
        polar = abs(float(momentum_body @ axis)) / momentum
        solid = math.copysign(2.0 * math.pi * (1.0 - polar), i_a - i_eq)
        precession = precession_rate * period
    else:
        solid = precession = float("nan")
    return _Symmetric("symmetric", energy, momentum, period, solid, precession, quat0=quat0, omega0=omega0.copy(),
                      axis=axis, momentum_world=momentum_world, precession_rate=precession_rate,
                      spin_rate=spin_rate)


def _triaxial_motion(quat0, moments, axes, w, energy, momentum, separatrix) -> FreeMotion:
    """moments, w, separatrix: Decimal (axes: float); the scalars that carry cancellations or set the period are
    formed in decimal arithmetic and rounded once."""
    e1, e2, e3 = axes.T
    with localcontext() as context:
        context.prec = PRECISE_DIGITS
        i1, i2, i3 = moments
        if separatrix > 0:
            kind, sign_d = "major", 1.0
            frame_f = np.column_stack([e1, e2, e3])
            i_a, i_b, i_c = i1, i2, i3
            w_a, w_b, w_c = w
        else:
            kind, sign_d = "minor", -1.0
            frame_f = np.column_stack([e3, e2, -e1])
            i_a, i_b, i_c = i3, i2, i1
            w_a, w_b, w_c = w[2], w[1], -w[0]
        # 2E I_a - L² and L² - 2E I_c as sums of terms of one sign (no cancellation)
        g = i_b * w_b * w_b * (i_a - i_b) + i_c * w_c * w_c * (i_a - i_c)
        h = i_a * w_a * w_a * (i_a - i_c) + i_b * w_b * w_b * (i_b - i_c)
        amp_a = float((h / (i_a * (i_a - i_c))).sqrt())
        amp_b = float((g / (i_b * (i_a - i_b))).sqrt())
        amp_c = float((g / (i_c * (i_a - i_c))).sqrt())
        parameter = float((i_b - i_c) * g / ((i_a - i_b) * h))
        complement = float((i_a - i_c) * separatrix / ((i_a - i_b) * h))  # 1 - m, from the separatrix distance
        rate = float(((i_a - i_b) * h / (i_a * i_b * i_c)).sqrt())
        nu = float(i_a * (i_b - i_c) / (i_c * (i_a - i_b)))
        m_over_nu = float(i_c * g / (i_a * h))  # m/ν stays finite as the body becomes symmetric
    quarter = float(ellipkm1(complement))
    i_a, i_b, i_c = float(i_a), float(i_b), float(i_c)
    w_a, w_b, w_c = float(w_a), float(w_b), float(w_c)
    sign_s = math.copysign(1.0, w_a)
    sign_c = -sign_d * sign_s
    tau0 = first_kind(w_b / amp_b, w_c / (sign_c * amp_c), w_a / (sign_s * amp_a), quarter)
    third_complete = third_kind_complete(complement, nu)
    sn0, cn0, dn0, j0, sn_r, cn_r, dn_r = jacobi(np.array([tau0]), parameter, quarter, complement)
    third0 = float(2.0 * j0[0] * third_complete + third_kind_reduced(sn_r, cn_r, dn_r, nu)[0])
    coefficient = momentum * (i_a - i_c) / (i_a * i_c * rate)

    period = 4.0 * quarter / rate
    precession = momentum / i_a * period + coefficient * 4.0 * third_complete
    # Ω = d [2π - (I_a W_a √(1+ν) / L) ∫_0^{4K} dn² / (1 + ν sn²) dτ], with dn² = 1 - m sn² split over (1 + ν sn²)
    integral = 4.0 * ((1.0 + m_over_nu) * third_complete - m_over_nu * quarter)
    solid = sign_d * (2.0 * math.pi - i_a * amp_a * math.sqrt(1.0 + nu) / momentum * integral)

    frame_g = frame_f[:, [1, 2, 0]]
    amplitudes = (sign_s * amp_a, amp_b, sign_c * amp_c)
    omega_g0 = np.array([amp_b * sn0[0], sign_c * amp_c * cn0[0], sign_s * amp_a * dn0[0]])
    unit_m0 = omega_g0 * np.array([i_b, i_c, i_a]) / momentum
    q_fixed = quat_to_matrix(quat0) @ frame_g @ _polar_frame(unit_m0[None])[0].T
    return _Triaxial(kind, energy, momentum, period, solid, precession, frame_g=frame_g, moments=(i_a, i_b, i_c),
                     amplitudes=amplitudes, rate=rate, parameter=parameter, complement=complement, quarter=quarter,
                     nu=nu, tau0=tau0,
                     third_complete=third_complete, third0=third0, coefficient=coefficient, q_fixed=q_fixed,
                     quat0=quat0)


def _separatrix_amplitudes(moments: np.ndarray, speed: float) -> tuple[float, float, float]:
    """W1, W3 (rad/s) and λ (1/s) on the separatrix with L = I2 W, W = speed (FORMULARY T8)."""
    i1, i2, i3 = moments
    w1 = speed * math.sqrt(i2 * (i2 - i3) / (i1 * (i1 - i3)))
    w3 = speed * math.sqrt(i2 * (i1 - i2) / (i3 * (i1 - i3)))
    rate = speed * math.sqrt((i1 - i2) * (i2 - i3) / (i1 * i3))
    return w1, w3, rate


def _separatrix_motion(body, quat0, omega0, moments, axes, w, energy, momentum) -> FreeMotion:
    i1, i2, i3 = moments
    speed = momentum / i2
    w1, w3, rate = _separatrix_amplitudes(moments, speed)
    sign1 = math.copysign(1.0, w[0]) if w[0] != 0.0 else -math.copysign(1.0, w[2])
    direction = -sign1 * math.copysign(1.0, w[2]) if w[2] != 0.0 else math.copysign(1.0, w[1])
    # sinh u0 = tanh/sech = ε I2 ω2 / sqrt(I1² ω1² + I3² ω3²): no artanh of a number near ±1
    u0 = math.asinh(direction * i2 * w[1] / math.hypot(i1 * w[0], i3 * w[2]))
    rotation0 = quat_to_matrix(quat0)
    momentum_world = rotation0 @ (np.asarray(body.inertia, dtype=float) @ omega0) / momentum
    # m(t) runs along the great circle through e2 and (I1 W1 s1 e1 - ε s1 I3 W3 e3)/L; n is its normal
    in_plane = (i1 * w1 * sign1 * axes[:, 0] - direction * sign1 * i3 * w3 * axes[:, 2]) / momentum
    normal_world = rotation0 @ np.cross(in_plane, axes[:, 1])
    return _Separatrix("separatrix", energy, momentum, float("inf"), float("nan"), float("nan"), axes=axes,
                       amplitudes=(sign1 * w1, direction * speed, -direction * sign1 * w3), rate=rate, u0=u0,
                       direction=direction, momentum_world=momentum_world, normal_world=normal_world, quat0=quat0)


def separatrix_omega(body: FreeBody, speed: float, phase: float = 0.0, sign1: float = 1.0,
                     direction: float = 1.0) -> np.ndarray:
    """A state on the separatrix (FORMULARY T8), (3,) rad/s body frame, for a triaxial body.

    speed: W = L/I2 > 0 (rad/s), the limit of |ω2| as t -> ±∞. phase: u = λ (t - t0), dimensionless (0 is the
    middle of the flip, where ω2 = 0). sign1 = sign of ω1, direction ε = the sign of ω2 as t -> +∞.
    """
    moments_x, axes, _ = _principal_state(body, np.zeros(3))
    if _symmetric_axis(moments_x, axes) is not None:
        raise ValueError("a symmetric body has no separatrix")
    moments = np.array([float(x) for x in moments_x])
    w1, w3, _ = _separatrix_amplitudes(moments, speed)
    sech = 1.0 / math.cosh(phase)
    principal = np.array([sign1 * w1 * sech, direction * speed * math.tanh(phase), -direction * sign1 * w3 * sech])
    return axes @ principal


def period(body: FreeBody, omega0: np.ndarray) -> float:
    """Period (s) of ω(t) in the body: T9's elliptic formulas (either family), 2π/|Λ| for a symmetric body,
    inf on the separatrix."""
    return free_motion(body, np.array([1.0, 0.0, 0.0, 0.0]), omega0).period


def solid_angle(body: FreeBody, omega0: np.ndarray) -> float:
    """Signed solid angle Ω (sr) enclosed by M/L on the body-fixed unit sphere over one period (FORMULARY T9):
    the area to the left of the oriented curve; > 0 about the largest axis, < 0 about the smallest."""
    return free_motion(body, np.array([1.0, 0.0, 0.0, 0.0]), omega0).solid_angle


def montgomery_phase(body: FreeBody, omega0: np.ndarray) -> float:
    """Δθ (rad, in (-π, π]) with R(t0 + T) = Rot(M̂_world, Δθ) R(t0): Δθ ≡ 2ET/L - Ω (mod 2π) (FORMULARY T9)."""
    return free_motion(body, np.array([1.0, 0.0, 0.0, 0.0]), omega0).montgomery_phase


def precession_per_period(body: FreeBody, omega0: np.ndarray) -> float:
    """Φ(T) (rad): the continuous precession angle about M over one period, with the encircled axis as figure axis;
    equals 2ET/L - Ω + 2π sgn Ω (FORMULARY T9)."""
    return free_motion(body, np.array([1.0, 0.0, 0.0, 0.0]), omega0).precession


def euler_poinsot_check(body: FreeBody, quat0: np.ndarray, omega0: np.ndarray) -> str | None:
    """None if the body is torque-free and ω0 is off the separatrix (|δ| > SEPARATRIX_TOL), else the reason."""
    if body.has_gravity:
        return "the body has a weight moment: Euler–Poinsot needs a torque-free body"
    distance = separatrix_distance(body, omega0)
    if math.isfinite(distance) and abs(distance) <= SEPARATRIX_TOL:
        return f"ω0 is on the separatrix (δ = {distance:.3g}): that is euler_poinsot_separatrix"
    return None


def separatrix_check(body: FreeBody, quat0: np.ndarray, omega0: np.ndarray) -> str | None:
    """None if the body is torque-free and triaxial and ω0 is on the separatrix (|δ| <= SEPARATRIX_TOL)."""
    if body.has_gravity:
        return "the body has a weight moment: Euler–Poinsot needs a torque-free body"
    distance = separatrix_distance(body, omega0)
    if not math.isfinite(distance):
        return "no separatrix: the body is symmetric or at rest"
    if abs(distance) > SEPARATRIX_TOL:
        return f"ω0 is off the separatrix: δ = {distance:.3g}, more than {SEPARATRIX_TOL:g}"
    return None


def euler_poinsot_solve(body: FreeBody, quat0: np.ndarray, omega0: np.ndarray,
                        times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(quat (n, 4), omega (n, 3) rad/s body) of the torque-free motion at times (n,) s (free_motion)."""
    return free_motion(body, quat0, omega0).evaluate(np.asarray(times, dtype=float))
