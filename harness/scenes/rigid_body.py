"""The rigid body with a fixed point (DESIGN §3, the default kind): its case (harness.scenes.cases.Case), its truth
(heyoka, reference.truth), its metrics (drifts of the first integrals, errors against the truth and the exact
solution), its checks against theory and its invariant series."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import budget, integrators as integrator_registry
from ..grid import TimeGrid, time_grid
from ..trajectory import Trajectory
from ...reference import truth as reference_truth
from .base import register
from .cases import RIGID_BODY, Case
from .checks import ROW_KEY, measure as measure_checks
from .metrics import (DRIFT_COLUMNS, ERROR_COLUMNS, TORQUE_COLUMNS, applicable_integrals, drifts, errors,
                      torque_metrics)
from .metrics import state_err  # noqa: F401 (its path before issue 29; its home is metrics)
from .oracles import exact_attitude, oracle_err
from .series import invariant_series


@dataclass(frozen=True, eq=False)
class CaseTruth:
    """The truth of one case on the union of every run's sample times.

    times: (n,) s, sorted; quat: (n, 4) wxyz body -> world; omega: (n, 3) rad/s body frame.
    truth_err: rad, a bound on the truth's attitude error up to the case's horizon; truth_omega_err: a bound on its
    relative omega error (reference.truth.truth_bound: a quadruple-precision rerun plus the rounding of a float64
    comparison); both NaN when not certified (--no-certify).
    exact_quat: (n, 4) the case's exact solution (harness.scenes.oracles) at the same times, or None without an oracle.
    """

    times: np.ndarray
    quat: np.ndarray
    omega: np.ndarray
    truth_err: float
    applicable: tuple[str, ...]
    exact_quat: np.ndarray | None = None
    truth_omega_err: float = math.nan

    def on(self, grid: TimeGrid) -> tuple[np.ndarray, np.ndarray]:
        """The truth at exactly the grid's sample times."""
        index = np.searchsorted(self.times, grid.times)
        if not np.array_equal(self.times[index], grid.times):
            raise ValueError("truth was not evaluated on this grid's sample times")
        return self.quat[index], self.omega[index]


def truth_grid(case: Case) -> TimeGrid:
    """The truth row's own grid (and an adaptive run's): the case's samples evenly over [0, t_end]."""
    return time_grid(case.t_end, case.t_end / (case.samples - 1), case.samples)


def compute_truth(case: Case, dts: tuple[float, ...], certify: bool, budget_s: float | None = None) -> CaseTruth:
    """The truth on every grid of the case's dt list and its own grid (the sweep's), certified by a real128 rerun
    when certify; both within the truth budget (budget_s, default harness.budget's configured one)."""
    with budget.within("truth", budget.configured().truth_s if budget_s is None else budget_s):
        return SCENE.truth(case, [time_grid(case.t_end, dt, case.samples) for dt in dts] + [truth_grid(case)],
                           certify)


def rhs_per_sim_s(dt: float | None, integrator: str, rhs_evals: int, steps: float, t_end: float) -> float:
    """Right-hand-side evaluations per simulated second: the engine's count, or for a fixed-step run of an engine that
    does not count them, steps x the integrator's stages; NaN for an adaptive run that does not count."""
    if rhs_evals:
        return rhs_evals / t_end
    if dt is None or not math.isfinite(steps):
        return math.nan
    return steps * integrator_registry.stages(integrator) / t_end


class RigidBodyScene:
    kind = RIGID_BODY
    title = "the rigid body with a fixed point"
    needs_truth = True
    keeps_states = True
    work_precision = True
    trajectory = Trajectory  # what its models' run() returns (harness.run.measure checks it)
    columns = (*DRIFT_COLUMNS, *ERROR_COLUMNS, "oracle_err", "truth_err", "truth_omega_err", "chart_changes",
               "torque_mode", *TORQUE_COLUMNS, "rhs_per_sim_s")

    def parse(self, parser, data: dict) -> Case:
        return parser.rigid_body(data)

    def truth(self, case: Case, grids: list[TimeGrid], certify: bool) -> CaseTruth:
        times = np.unique(np.concatenate([g.times for g in grids]))
        # within the caller's budget (harness.budget.within): heyoka stops at its deadline
        result = reference_truth.truth(case.body, case.quat0, case.omega0, times, deadline=budget.deadline())
        bound = reference_truth.TruthBound(math.nan, math.nan)
        if certify:
            horizon = case.horizon if case.horizon is not None else case.t_end
            certified = truth_grid(case).times
            bound = reference_truth.truth_bound(case.body, case.quat0, case.omega0,
                                                certified[certified <= horizon * (1 + 1e-12)],
                                                deadline=budget.deadline())
        return CaseTruth(times, result.quat, result.omega, bound.attitude, applicable_integrals(case),
                         exact_attitude(case, times), bound.omega)

    def metrics(self, run, model, traj, grid: TimeGrid, truth: CaseTruth | None, full: bool, rerun,
                keep_states: bool = False) -> dict:
        case = run.case
        out = {"chart_changes": math.nan if traj.chart_changes is None else traj.chart_changes,
               "torque_mode": traj.info.get("torque_mode") or model.torque_mode(case), "_rhs_evals": traj.rhs_evals}
        steps = grid.steps
        if run.dt is None:
            out["steps"] = steps = traj.steps
        out["rhs_per_sim_s"] = rhs_per_sim_s(run.dt, run.integrator, traj.rhs_evals, steps, grid.t_end)
        applicable = truth.applicable if truth is not None else applicable_integrals(case)
        out.update(drifts(case, traj, applicable))
        if full:
            if keep_states:  # with the truth on the run's own times, so that each file is audited on its own
                truth_quat, truth_omega = truth.on(grid)
                out["_states"] = {"times": traj.times, "quat": traj.quat, "omega": traj.omega,
                                  "truth_quat": truth_quat, "truth_omega": truth_omega}
            out.update(torque_metrics(case, traj))
            out["_series"] = invariant_series(case, traj, applicable, truth.on(grid)[0])
            out["oracle_err"] = oracle_err(case, traj, truth.times, truth.exact_quat)
            # theory checks; the perturbed reruns some of them need are untimed, like the accuracy run
            out[ROW_KEY] = measure_checks(case, traj, rerun)
        if truth is not None:
            if not run.is_truth:
                truth_quat, truth_omega = truth.on(grid)
                out.update(errors(traj, truth_quat, truth_omega, case.horizon))
            if full:
                out.update(truth_err=truth.truth_err, truth_omega_err=truth.truth_omega_err)
        return out


SCENE = register(RigidBodyScene())
