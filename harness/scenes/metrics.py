"""The results-table metrics (DESIGN §4), computed from recorded states by one piece of code for every engine."""
from __future__ import annotations

import math

import numpy as np
import pandas as pd

from .cases import Case
from ..trajectory import Trajectory
from ...reference import torque_models, torques
# DRIFT_COLUMNS: the registry's (reference.integrals), re-exported where the results table's columns are listed
from ...reference.integrals import DRIFT_COLUMNS, INTEGRALS, applicable, drift  # noqa: F401
from ...reference.rotations import attitude_angle, quat_to_matrix

ERROR_COLUMNS = ("attitude_err", "attitude_err_end", "omega_err")
# The columns the torque models measure (TorqueModel.columns), the registry's at import: precession_axis_drift.
TORQUE_COLUMNS = tuple(column for model in torque_models.models() for column in model.columns)


# The global error of the state, whose order the ladders fit (a method's order is that of its whole state): the largest
# finite one of these columns, NaN without an attitude error. Its one home: the ladders, the advice, fitting's tables
# and harness.testing all take it from state_err.
STATE_ERR_PARTS = ("attitude_err", "omega_err", "casimir_drift")


def state_err(row):
    """max(attitude_err, omega_err, casimir_drift) over the finite ones, NaN where attitude_err is not finite. row: a
    row (a mapping: returns a float) or a table (a DataFrame: returns a Series on its index); a missing part is NaN."""
    table = hasattr(row, "columns")
    parts = np.array([np.asarray(row[c] if c in row else np.full(len(row), np.nan) if table else math.nan, dtype=float)
                      for c in STATE_ERR_PARTS], dtype=float).reshape(len(STATE_ERR_PARTS), -1)
    finite = np.isfinite(parts)
    largest = np.where(finite, parts, -np.inf).max(axis=0)
    out = np.where(finite[0] & finite.any(axis=0), largest, np.nan)
    return pd.Series(out, index=row.index, dtype=float) if table else float(out[0])


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
    """The columns the torque models declare (TorqueModel.columns, e.g. precession_axis_drift, G14) from the case's
    terms (TorqueModel.metrics) over the run's samples; NaN for a model the case lacks, or a sample not finite."""
    out = dict.fromkeys((column for model in torque_models.models() for column in model.columns), math.nan)
    if not (np.isfinite(traj.quat).all() and np.isfinite(traj.omega).all()):
        return out
    body = case.body
    for term in body.torques:
        out.update(term.metrics(body, traj.quat, traj.omega))
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
