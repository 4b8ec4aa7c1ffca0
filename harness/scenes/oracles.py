"""The exact solutions in a sweep (DESIGN §3, §4): a case's oracle evaluated at the truth's sample times, and
oracle_err for every run of the case."""
from __future__ import annotations

import math

import numpy as np

from .cases import Case
from ..trajectory import Trajectory
from ...reference.exact import ORACLES
from ...reference.rotations import attitude_angle, quat_to_matrix

# Samples at t <= horizon * (1 + HORIZON_RTOL) count as within the horizon (as in harness.scenes.metrics.errors): a
# sample time is steps * dt, which can land a rounding error past a horizon that is meant to include it.
HORIZON_RTOL = 1e-12


def exact_attitude(case: Case, times: np.ndarray) -> np.ndarray | None:
    """(n, 4) quaternions (w, x, y, z), body -> world, of the case's exact solution at exactly `times` (s), or None
    for a case without an oracle."""
    if case.oracle is None:
        return None
    quat, _ = ORACLES[case.oracle].solve(case.body, case.quat0, case.omega0, np.asarray(times, dtype=float))
    return quat


def oracle_err(case: Case, traj: Trajectory, times: np.ndarray, exact_quat: np.ndarray | None) -> float:
    """Max attitude angle (rad) between the run and the exact solution over the run's samples up to the horizon.

    times (n,) s and exact_quat (n, 4): the exact solution where the truth was evaluated (the union of every run's
    sample times, so a run's own times are among them exactly). NaN without an oracle, or when the run is not finite
    within the horizon (a maximum over the samples before a blow-up would understate it).
    """
    if exact_quat is None:
        return math.nan
    index = np.searchsorted(times, traj.times)
    if not (np.all(index < len(times)) and np.array_equal(times[np.minimum(index, len(times) - 1)], traj.times)):
        raise ValueError("the exact solution was not evaluated at this run's sample times")
    keep = np.ones(len(traj.times), bool) if case.horizon is None else traj.times <= case.horizon * (1 + HORIZON_RTOL)
    quat = traj.quat[keep]
    if not np.isfinite(quat).all():
        return math.nan
    # quat_to_matrix normalises: an engine's |q| slightly off 1 is the Casimir's business, not an attitude error
    return float(np.max(attitude_angle(quat_to_matrix(quat), quat_to_matrix(exact_quat[index[keep]]))))
