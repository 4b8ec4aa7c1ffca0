"""The results-table metrics (DESIGN §4), computed from recorded states by one piece of code for every engine."""
from __future__ import annotations

import math

import numpy as np

from .cases import Case
from ..trajectory import Trajectory
from ...reference import torques
# DRIFT_COLUMNS: the registry's (reference.integrals), re-exported where the results table's columns are listed
from ...reference.integrals import DRIFT_COLUMNS, INTEGRALS, applicable, drift  # noqa: F401
from ...reference.rotations import attitude_angle, quat_to_matrix

ERROR_COLUMNS = ("attitude_err", "attitude_err_end", "omega_err")


def applicable_integrals(case: Case) -> tuple[str, ...]:
    """The integral names whose structural conditions this case meets (from its initial state;
    reference.integrals.applicable)."""
    return applicable(case.body, case.quat0, case.omega0)


def energy_balance_drift(case: Case, traj: Trajectory) -> float:
    """max over finite samples of |J(t) − J(0) − W(t)| / scale (reference.torques.energy_balance): the work–energy
    balance with a non-potential torque, the energy with MacCullagh's potential for a fixed central field, the Jacobi
    integral for a turning one. NaN if a sample is not finite (the work needs every sample)."""
    if not (np.isfinite(traj.quat).all() and np.isfinite(traj.omega).all()):
        return math.nan
    deviation, scale = torques.energy_balance(case.body, traj.times, traj.quat, traj.omega)
    return float(np.max(deviation) / scale)


def drifts(case: Case, traj: Trajectory, applicable: tuple[str, ...]) -> dict[str, float]:
    """{column: drift} over the run's finite samples; NaN for integrals the case does not have."""
    body = case.body
    out = {}
    for stem, integral in INTEGRALS.items():
        if stem == "energy" and stem in applicable and body.has_external_torque:
            out[integral.column] = energy_balance_drift(case, traj)
            continue
        out[integral.column] = drift(integral, body, traj.quat, traj.omega) if stem in applicable else math.nan
    return out


def torque_metrics(case: Case, traj: Trajectory) -> dict[str, float]:
    """precession_axis_drift (G14): max |e(t) − e(0)| of the world precession axis (40) over the samples, NaN
    without [precession_torque] or when a sample comes within PRECESSION_SINGULAR_ANGLE of ω ∥ u (the axis is
    undefined there)."""
    body = case.body
    if body.precession_torque is None or not (np.isfinite(traj.quat).all() and np.isfinite(traj.omega).all()):
        return {"precession_axis_drift": math.nan}
    if np.min(torques.transverse_angle(traj.omega)) < torques.PRECESSION_SINGULAR_ANGLE:
        return {"precession_axis_drift": math.nan}
    axis = torques.precession_axis(body, traj.quat, traj.omega)
    return {"precession_axis_drift": float(np.max(np.linalg.norm(axis - axis[0], axis=1)))}


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
