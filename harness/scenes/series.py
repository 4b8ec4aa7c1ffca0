"""Decimated time series of a run's invariants and attitude error, for the report's invariant-against-time plots.

Each series is the per-sample quantity whose maximum is the results table's column (same integrals, same scale), reduced
to at most POINTS points by taking the maximum over consecutive buckets of samples, so a plot shows the envelope and
never misses a peak. Stored with the run's record (harness.run.store), so it is kept small.
"""
from __future__ import annotations

import numpy as np

from .cases import Case
from ..trajectory import Trajectory
from ...reference import torques
from ...reference.integrals import INTEGRALS
from ...reference.rotations import attitude_angle, quat_to_matrix

POINTS = 200
DIGITS = 4  # significant digits kept: enough for a log-scale plot, a fifth of the bytes of a full double


def _deviation(case: Case, stem: str, traj: Trajectory) -> np.ndarray:
    """|I(t) - I(0)| / scale per sample (as reference.integrals.drift, before its maximum); NaN where not finite."""
    integral, body = INTEGRALS[stem], case.body
    if stem == "energy" and body.has_external_torque:  # the energy (Jacobi) balance, as harness.scenes.metrics
        if not (np.isfinite(traj.quat).all() and np.isfinite(traj.omega).all()):
            return np.full(len(traj.times), np.nan)
        deviation, scale = torques.energy_balance(body, traj.times, traj.quat, traj.omega)
        return deviation / scale
    with np.errstate(invalid="ignore", over="ignore"):
        values = np.asarray(integral.value(body, traj.quat, traj.omega), dtype=float)
        reference = values[0] if integral.exact is None else integral.exact
        deviation = values - reference
        if deviation.ndim == 2:
            deviation = np.linalg.norm(deviation, axis=-1)
        return np.abs(deviation) / integral.scale(body, traj.quat[0], traj.omega[0])


def _bucket_max(values: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """Max of each bucket, ignoring NaN (an all-NaN bucket stays NaN)."""
    return np.fmax.reduceat(values, starts)


def _rounded(values: np.ndarray) -> list[float | None]:
    return [None if not np.isfinite(v) else float(f"{v:.{DIGITS}g}") for v in values]


def invariant_series(case: Case, traj: Trajectory, applicable: tuple[str, ...],
                     truth_quat: np.ndarray | None = None) -> dict[str, list]:
    """{"t": times (s), integral stem: relative deviation, "attitude_err": rad vs the truth}, at most POINTS points.

    t is the time of each bucket's last sample. attitude_err is NaN beyond the case's horizon, as in the table.
    """
    n = len(traj.times)
    starts = np.arange(0, n, max(1, -(-n // POINTS)))
    ends = np.append(starts[1:], n) - 1
    series: dict[str, list] = {"t": [float(f"{t:.6g}") for t in traj.times[ends]]}
    if not n or not (np.isfinite(traj.quat[0]).all() and np.isfinite(traj.omega[0]).all()):
        return series
    for stem in applicable:
        if stem in INTEGRALS:
            series[stem] = _rounded(_bucket_max(_deviation(case, stem, traj), starts))
    if truth_quat is not None:
        with np.errstate(invalid="ignore"):
            angle = attitude_angle(quat_to_matrix(traj.quat), quat_to_matrix(truth_quat))
        if case.horizon is not None:
            angle = np.where(traj.times <= case.horizon * (1 + 1e-12), angle, np.nan)
        series["attitude_err"] = _rounded(_bucket_max(angle, starts))
    return series
