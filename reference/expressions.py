"""heyoka expression helpers and the runtime-parameter layout of the formulations' Taylor integrators.

Vectors are lists of 3 heyoka expressions, matrices lists of 3 rows. Every formulation's integrator takes the same
runtime parameters, so one compiled integrator per formulation serves every body and every chart:

    0..5    σ, inertia about O, body frame (σ11, σ22, σ33, σ12, σ13, σ23), kg m²
    6..11   σ⁻¹, same layout, 1/(kg m²)
    12..14  w = m g (O -> G), body frame, N m (zero without gravity)
    15..17  n, the unit downward vertical in the current chart's reference frame
    18      the threshold of the chart's terminal event (re-chart criterion, or the singularity guard)
    19..    the torque models' blocks, reference.truth's layout (truth.TORQUE_OFFSET; truth.parameter_count() in
            all), a term's world vectors in the chart's reference frame (Formulation.parameters)
"""
from __future__ import annotations

import heyoka as hy
import numpy as np

from .body import RigidBody
from .rotations import quat_to_matrix

SIGMA, SIGMA_INV, WEIGHT_MOMENT, DOWN, THRESHOLD = 0, 6, 12, 15, 18
N_PARS = 19
# Upper-triangle index pairs of a symmetric 3x3 matrix, in the parameter layout above.
SYMMETRIC_ENTRIES = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))


def symmetric(offset: int) -> list[list]:
    """3x3 symmetric matrix of parameters, 6 of them from offset."""
    entry = {pair: hy.par[offset + i] for i, pair in enumerate(SYMMETRIC_ENTRIES)}
    return [[entry[(min(i, j), max(i, j))] for j in range(3)] for i in range(3)]


def vector(offset: int) -> list:
    return [hy.par[offset + i] for i in range(3)]


def dot(a, b):
    return hy.sum([a[i] * b[i] for i in range(3)])


def cross(a, b) -> list:
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def matvec(m, v) -> list:
    return [dot(m[i], v) for i in range(3)]


def transpose(m) -> list[list]:
    return [[m[j][i] for j in range(3)] for i in range(3)]


def matmul(a, b) -> list[list]:
    bt = transpose(b)
    return [[dot(a[i], bt[j]) for j in range(3)] for i in range(3)]


def parameters(body: RigidBody, frame: np.ndarray, threshold: float) -> np.ndarray:
    """The 19 runtime parameters (double precision) for a body, a chart frame ((4,) wxyz quaternion of the chart's
    reference frame in the world) and an event threshold."""
    sigma = np.asarray(body.inertia, dtype=float)
    inverse = np.linalg.inv(sigma)
    down = quat_to_matrix(frame).T @ body.gravity_direction
    return np.concatenate([[sigma[i, j] for i, j in SYMMETRIC_ENTRIES], [inverse[i, j] for i, j in SYMMETRIC_ENTRIES],
                           body.weight_moment, down, [threshold]])
