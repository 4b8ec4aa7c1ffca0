"""Helpers shared by the exact solutions: principal frames, frames from vectors, Jacobi functions reduced to one
half-period, Carlson forms of the incomplete elliptic integrals, quaternion sign continuity. Outside reference/exact/
so that the torque-free body (reference/torque_free.py) uses them without importing every exact solution."""
from __future__ import annotations

import math
from decimal import Decimal, localcontext

import numpy as np
from scipy.special import elliprf, elliprj

from .rotations import quat_exp

# Tolerance of every oracle condition (relative, see each check). Cases are written with 17 significant digits from
# the constructors here, so a condition holds to rounding (~1e-16) or the state is on another motion; the deviation
# from the oracle then grows with time, so the bound is kept tight.
CONDITION_RTOL = 1e-12

# Two principal moments are equal (the symmetric closed form applies) when their refined PRECISE_DIGITS-digit values
# agree to this: the given inertia is exactly symmetric. A genuine gap, even the 1e-16 left by rounding a rotated
# symmetric tensor, is a triaxial body; the elliptic solution is exact for it (m, ν ~ the gap), whereas the symmetric
# form would err in the spin rate by ~ gap/I (ω_⊥/ω_a)², unbounded as the spin ω_a about the symmetry axis goes to 0
# (measured 2.1e-12 rad over 10 periods of a rotated (3, 1.5, 1.5), ω_⊥/ω_a ~ 40). No asymmetry threshold above
# exact equality is safe for every state, so there is none.
SYMMETRIC_RTOL = 1e-30


def principal_axes(inertia: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Principal moments (3,) kg m², descending I1 >= I2 >= I3, and axes (3, 3): columns e1, e2, e3 in body
    components, right-handed (e3 = e1 × e2)."""
    moments, axes = np.linalg.eigh(np.asarray(inertia, dtype=float))
    moments = moments[::-1].copy()
    axes = axes[:, ::-1].copy()
    if np.linalg.det(axes) < 0:
        axes[:, 2] = -axes[:, 2]
    return moments, axes


# Digits of the decimal arithmetic that refines principal frames: the rounding of the frame and of the invariants
# then sits far below float64, whatever the distance to the separatrix.
PRECISE_DIGITS = 40


def _decimal_matrix_product(a: list, b: list) -> list:
    return [[sum((a[i][k] * b[k][j] for k in range(3)), Decimal(0)) for j in range(3)] for i in range(3)]


def _decimal_transpose(a: list) -> list:
    return [[a[j][i] for j in range(3)] for i in range(3)]


def principal_frame_precise(inertia: np.ndarray, omega: np.ndarray) -> tuple[list, list, list]:
    """Principal moments (descending), axes and ω in principal components, as decimal.Decimal with PRECISE_DIGITS
    digits: moments [I1, I2, I3], axes as 3 rows of the (3, 3) matrix whose columns are e1, e2, e3 (body), and
    w = [ω·e1, ω·e2, ω·e3].

    eigh's axes are off by ~1e-16/gap rad and orthonormal only to ~1e-16, and near the separatrix such errors are
    amplified by 1/|δ| in the period (measured: 3e-11 rad over 10 periods at δ = 7e-4). Gram–Schmidt and three
    Jacobi sweeps on Pᵀ σ P, with σ and ω taken exactly from their float64 entries, remove them.
    """
    _, axes0 = principal_axes(inertia)
    with localcontext() as context:
        context.prec = PRECISE_DIGITS
        sigma = [[Decimal(float(x)) for x in row] for row in np.asarray(inertia, dtype=float)]
        columns = [[Decimal(float(x)) for x in axes0[:, i]] for i in range(3)]

        def dot(u, v):
            return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]

        for _ in range(2):
            e1 = [x / dot(columns[0], columns[0]).sqrt() for x in columns[0]]
            e2 = [x - dot(e1, columns[1]) * y for x, y in zip(columns[1], e1)]
            e2 = [x / dot(e2, e2).sqrt() for x in e2]
            e3 = [e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]]
            columns = [e1, e2, e3]
        axes = _decimal_transpose(columns)
        one = Decimal(1)
        for _ in range(3):
            for p, q in ((0, 1), (0, 2), (1, 2)):
                a = _decimal_matrix_product(_decimal_transpose(axes), _decimal_matrix_product(sigma, axes))
                if a[p][q] == 0:
                    continue
                zeta = (a[q][q] - a[p][p]) / (2 * a[p][q])
                t = (one if zeta >= 0 else -one) / (abs(zeta) + (one + zeta * zeta).sqrt())
                c = one / (one + t * t).sqrt()
                s = t * c
                rotation = [[one if i == j else Decimal(0) for j in range(3)] for i in range(3)]
                rotation[p][p] = rotation[q][q] = c
                rotation[p][q], rotation[q][p] = s, -s
                axes = _decimal_matrix_product(axes, rotation)
        a = _decimal_matrix_product(_decimal_transpose(axes), _decimal_matrix_product(sigma, axes))
        moments = [a[i][i] for i in range(3)]
        # The Jacobi sweeps keep eigh's order, which two moments within ~1 ulp of each other (a rotated symmetric
        # tensor) can leave ascending: sort descending, as every caller assumes (I1 >= I2 >= I3), and negate the
        # last axis after an odd permutation so that the frame stays right-handed.
        order = sorted(range(3), key=lambda i: moments[i], reverse=True)
        if order != [0, 1, 2]:
            odd = sum(order[i] > order[j] for i in range(3) for j in range(i + 1, 3)) % 2 == 1
            moments = [moments[i] for i in order]
            axes = [[row[i] for i in order] for row in axes]
            if odd:
                axes = [[row[0], row[1], -row[2]] for row in axes]
        omega_dec = [Decimal(float(x)) for x in np.asarray(omega, dtype=float)]
        w = [sum((axes[k][i] * omega_dec[k] for k in range(3)), Decimal(0)) for i in range(3)]
    return moments, axes, w


def unit(v: np.ndarray) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


def orthogonal_unit(v: np.ndarray) -> np.ndarray:
    """A unit vector orthogonal to v (3,), built from the coordinate axis least aligned with v."""
    v = unit(v)
    hint = np.eye(3)[np.argmin(np.abs(v))]
    return unit(hint - (hint @ v) * v)


def frame(first: np.ndarray, second_hint: np.ndarray) -> np.ndarray:
    """Right-handed orthonormal (3, 3), columns (a, b, a × b): a along first, b the part of second_hint ⊥ a."""
    a = unit(first)
    b = unit(second_hint - (second_hint @ a) * a)
    return np.column_stack([a, b, np.cross(a, b)])


def rotation_taking(body_vector: np.ndarray, world_vector: np.ndarray, heading: float = 0.0) -> np.ndarray:
    """(3, 3) attitude R with R body_vector = world_vector (both unit after normalising); heading (rad) is the free
    rotation about world_vector, measured from a fixed reference direction."""
    body_frame = frame(body_vector, orthogonal_unit(body_vector))
    w = unit(world_vector)
    x0 = orthogonal_unit(w)
    y0 = np.cross(w, x0)
    world_frame = frame(w, np.cos(heading) * x0 + np.sin(heading) * y0)
    return world_frame @ body_frame.T


def axis_angle_quat(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Quaternions (n, 4) of the rotations by angle (n,) rad about the unit axis (3,)."""
    angle = np.asarray(angle, dtype=float)
    return quat_exp(angle[..., None] * np.asarray(axis, dtype=float))


def continuous_signs(quat: np.ndarray, first: np.ndarray) -> np.ndarray:
    """Flip the signs of quat (n, 4) so that sample 0 has the sign of `first` (4,) and consecutive samples have a
    non-negative dot product (q and -q are the same attitude; a continuous sign is easier to read and to plot)."""
    quat = np.array(quat, dtype=float)
    if quat.shape[0] == 0:
        return quat
    steps = np.where(np.sum(quat[1:] * quat[:-1], axis=-1) < 0.0, -1.0, 1.0)
    signs = np.cumprod(np.concatenate([[1.0 if quat[0] @ first >= 0.0 else -1.0], steps]))
    return quat * signs[:, None]


def jacobi_sncndn(u: np.ndarray, m: float, complement: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """sn, cn, dn of u (n,) for the parameter m, given also its complement 1 - m (both in [0, 1]).

    The arithmetic-geometric mean of Cephes' ellpj (which scipy.special.ellipj wraps), started from √(1 - m) as
    given rather than as 1 - m rounded: near the separatrix 1 - m ~ 1e-6, and forming it from m would lose ten
    digits of it, i.e. of the period. Accurate to a few ulps (absolute) for |u| <= K.
    """
    u = np.asarray(u, dtype=float)
    a, b, c = 1.0, math.sqrt(complement), math.sqrt(m)
    ratios = []
    while abs(c) > 1e-17 * a and len(ratios) < 40:
        a_next = 0.5 * (a + b)
        # c_{n+1} = (a_n - b_n)/2 = c_n² / (4 a_{n+1}): no cancellation
        c = c * c / (4.0 * a_next)
        b = math.sqrt(a * b)
        a = a_next
        ratios.append(c / a)
    phi = (2.0 ** len(ratios)) * a * u
    for ratio in reversed(ratios):
        phi = 0.5 * (phi + np.arcsin(np.clip(ratio * np.sin(phi), -1.0, 1.0)))
    sn, cn = np.sin(phi), np.cos(phi)
    # dn² = 1 - m sn² = cn² + (1 - m) sn²: two positive terms. Cephes' cn / cos(φ0 - φ1) is 0/0 at u = K.
    dn = np.sqrt(cn * cn + complement * sn * sn)
    return sn, cn, dn


def jacobi(u: np.ndarray, m: float, quarter: float, complement: float) -> tuple[np.ndarray, ...]:
    """sn, cn, dn of u (n,) and of its reduction r = u - 2 K j, |r| <= K (K = quarter = K(m), complement = 1 - m).

    Returns (sn_u, cn_u, dn_u, j, sn_r, cn_r, dn_r). The reduction keeps the AGM on a short argument and gives the
    half-period count j that the quasi-periodic integrals need. sn(u) = (-1)^j sn(r), cn(u) = (-1)^j cn(r),
    dn(u) = dn(r).
    """
    u = np.asarray(u, dtype=float)
    j = np.round(u / (2.0 * quarter))
    r = u - 2.0 * quarter * j
    # the AGM on |r| (sn odd, cn and dn even)
    sn_abs, cn_r, dn_r = jacobi_sncndn(np.abs(r), m, complement)
    sn_r = np.copysign(sn_abs, r)
    parity = 1.0 - 2.0 * np.mod(j, 2.0)
    return parity * sn_r, parity * cn_r, dn_r, j, sn_r, cn_r, dn_r


def first_kind(sn: float, cn: float, dn: float, quarter: float) -> float:
    """u in [-2K, 2K] with (sn, cn, dn)(u) = the given triple: the incomplete integral F(am u | m) in Carlson's form,
    sn R_F(cn², dn², 1), reflected about ±K when cn < 0. dn enters directly (not as 1 - m sn²), so u keeps its
    relative accuracy where dn is small (near the separatrix)."""
    base = sn * float(elliprf(cn * cn, dn * dn, 1.0))
    if cn >= 0:
        return base
    return float(np.copysign(2.0 * quarter, sn)) - base


def third_kind_reduced(sn_r: np.ndarray, cn_r: np.ndarray, dn_r: np.ndarray, nu: float) -> np.ndarray:
    """∫_0^r du / (1 + ν sn² u) for |r| <= K, from the Jacobi functions of r (ν >= 0):
    sn R_F(cn², dn², 1) - (ν/3) sn³ R_J(cn², dn², 1, 1 + ν sn²) (Carlson's form of Legendre's Π(-ν; am r | m))."""
    s2 = sn_r * sn_r
    c2 = cn_r * cn_r
    d2 = dn_r * dn_r
    value = sn_r * elliprf(c2, d2, 1.0)
    if nu != 0.0:
        value = value - nu / 3.0 * sn_r * s2 * elliprj(c2, d2, 1.0, 1.0 + nu * s2)
    return value


def third_kind_complete(m_complement: float, nu: float) -> float:
    """∫_0^K du / (1 + ν sn² u) = R_F(0, 1 - m, 1) - (ν/3) R_J(0, 1 - m, 1, 1 + ν)."""
    value = float(elliprf(0.0, m_complement, 1.0))
    if nu != 0.0:
        value -= nu / 3.0 * float(elliprj(0.0, m_complement, 1.0, 1.0 + nu))
    return value
