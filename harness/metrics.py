"""The results-table metrics (DESIGN §4), computed from recorded states by one piece of code for every engine."""
from __future__ import annotations

import math

import numpy as np

from harness.cases import Case
from harness.engines.base import Trajectory
from reference.integrals import INTEGRALS, drift
from reference.rotations import attitude_angle, quat_to_matrix

# Drift columns in table order; each is INTEGRALS[stem] where the reference implements it.
DRIFT_COLUMNS = ("energy_drift", "momentum_drift", "casimir_drift", "lagrange_drift", "kovalevskaya_drift",
                 "chaplygin_drift", "hess_drift", "self_excited_drift")
ERROR_COLUMNS = ("attitude_err", "attitude_err_end", "omega_err")


def applicable_integrals(case: Case) -> tuple[str, ...]:
    """The integral names whose structural conditions this case meets (from its initial state)."""
    body = case.body
    return tuple(name for name, integral in INTEGRALS.items() if integral.applies(body, case.quat0, case.omega0))


def drifts(case: Case, traj: Trajectory, applicable: tuple[str, ...]) -> dict[str, float]:
    """{column: drift} over the run's finite samples; NaN for integrals the case does not have."""
    body = case.body
    out = {}
    for column in DRIFT_COLUMNS:
        stem = column.removesuffix("_drift")
        out[column] = drift(INTEGRALS[stem], body, traj.quat, traj.omega) if stem in applicable else math.nan
    return out


def errors(traj: Trajectory, truth_quat: np.ndarray, truth_omega: np.ndarray,
           horizon: float | None) -> dict[str, float]:
    """Attitude and angular-velocity errors against the truth on the same sample times, up to the horizon.

    attitude_err / attitude_err_end: max / last geodesic angle (rad) over samples with t <= horizon;
    omega_err: max |omega - omega_truth| / max |omega_truth| over the same samples.
    NaN when the run diverged within that range: a maximum over the samples before a blow-up would understate it.
    """
    keep = np.ones(len(traj.times), bool) if horizon is None else traj.times <= horizon * (1 + 1e-12)
    quat, omega = traj.quat[keep], traj.omega[keep]
    if not (np.isfinite(quat).all() and np.isfinite(omega).all()):
        return dict.fromkeys(ERROR_COLUMNS, math.nan)
    angle = attitude_angle(quat_to_matrix(quat), quat_to_matrix(truth_quat[keep]))
    scale = np.max(np.linalg.norm(truth_omega[keep], axis=1))
    omega_err = np.max(np.linalg.norm(omega - truth_omega[keep], axis=1)) / (scale or 1.0)
    return {"attitude_err": float(np.max(angle)), "attitude_err_end": float(angle[-1]), "omega_err": float(omega_err)}
