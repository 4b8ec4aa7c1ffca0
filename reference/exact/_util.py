"""Helpers shared by the exact solutions: principal frames, frames from vectors, Jacobi functions reduced to one
half-period, Carlson forms of the incomplete elliptic integrals, quaternion sign continuity."""
from __future__ import annotations

import numpy as np
from scipy.special import ellipj, elliprf, elliprj

from reference.rotations import quat_exp

# Tolerance of every oracle condition (relative, see each check). Cases are written with 17 significant digits from
# the constructors here, so a condition holds to rounding (~1e-16) or the state is on another motion; the deviation
# from the oracle then grows with time, so the bound is kept tight.
CONDITION_RTOL = 1e-12

# Two principal moments closer than this (relative) are treated as equal: the gap is then indistinguishable from the
# rounding of an eigendecomposition, and the symmetric closed form errs by at most gap/I |ω| t.
SYMMETRIC_RTOL = 8.0 * np.finfo(float).eps


def principal_axes(inertia: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Principal moments (3,) kg m², descending I1 >= I2 >= I3, and axes (3, 3): columns e1, e2, e3 in body
    components, right-handed (e3 = e1 × e2)."""
    moments, axes = np.linalg.eigh(np.asarray(inertia, dtype=float))
    moments = moments[::-1].copy()
    axes = axes[:, ::-1].copy()
    if np.linalg.det(axes) < 0:
        axes[:, 2] = -axes[:, 2]
    return moments, axes


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
    if quat[0] @ first < 0:
        quat[0] = -quat[0]
    for i in range(1, quat.shape[0]):
        if quat[i] @ quat[i - 1] < 0:
            quat[i] = -quat[i]
    return quat


def jacobi(u: np.ndarray, m: float, quarter: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                                                  np.ndarray, np.ndarray, np.ndarray]:
    """sn, cn, dn of u (n,) and of its reduction r = u - 2 K j, |r| <= K (K = quarter = K(m)).

    Returns (sn_u, cn_u, dn_u, j, sn_r, cn_r, dn_r). The reduction keeps scipy's AGM (Cephes ellpj) on a short
    argument, where it is accurate to a few ulps, and gives the half-period count j that the quasi-periodic
    integrals need. sn(u) = (-1)^j sn(r), cn(u) = (-1)^j cn(r), dn(u) = dn(r).
    """
    u = np.asarray(u, dtype=float)
    j = np.round(u / (2.0 * quarter))
    r = u - 2.0 * quarter * j
    # ellpj on |r| (sn odd, cn and dn even) so the AGM never sees a negative argument
    sn_abs, cn_r, dn_r, _ = ellipj(np.abs(r), m)
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
