"""The sliding ladder in a sweep (kind "sliding_ladder", FORMULARY T5): its own runs, metrics and check rows, beside
the rigid-body path of harness.run.sweep (which routes a LadderCase here).

Rows: the equation (engine reference, formulation "theta", integrator taylor: reference.sliding_ladder, whose heyoka event
gives the detachment), every MuJoCo model (formulation "bilateral" or "unilateral", harness.engines.mujoco) with each
MuJoCo integrator and dt, Pinocchio's bilateral model (its constrained dynamics, harness.engines.pinocchio) with
each of its integrators that works on a vector state (sliding_ladder_integrators) and dt. Columns: energy_drift
(the rod's energy, ½ m|v_G|² + ½ (mℓ²/3) θ̇² + m g y, relative to its terms at t = 0), attitude_err / attitude_err_end (|θ − θ_equation|, rad),
omega_err (|θ̇ − θ̇_equation| / max |θ̇_equation|) — for the unilateral model only up to the equation's detachment,
after which the equation (both ends on the axes) no longer describes it. checks.csv: detachment_angle (the
equation's event and the unilateral model's wall push, against arccos((2/3) cos θ0 + 4ℓθ̇0²/(9g))), energy_drift
and constraint_violation (m; theory 0).
"""
from __future__ import annotations

import math

import numpy as np

from . import checks
from .. import budget
from ..engines import get_engine
from ..trajectory import SlidingLadderTrajectory, Status
from ..grid import time_grid
from ..run.processes import raise_if_interrupted
from ...reference import sliding_ladder as ref_ladder

# The models whose rows get a detachment_angle check: the equation's event (the reference engine's "theta") and the
# unilateral model's wall push (MuJoCo's); a bilateral model never leaves the wall.
DETACHING_MODELS = ("theta", "unilateral")


def _grid(spec):
    case = spec.case
    return time_grid(case.t_end, case.t_end / (case.samples - 1) if spec.dt is None else spec.dt, case.samples)


def prepare(spec):
    """The spec's model (Engine.prepare_sliding_ladder; not timed)."""
    return get_engine(spec.engine).prepare_sliding_ladder(spec.case, spec.formulation, spec.integrator, spec.dt)


def run(spec) -> SlidingLadderTrajectory:
    """The spec's untimed run."""
    return prepare(spec).run(_grid(spec))


def timed_run(spec, grid):
    """A fresh, prepared run of the spec for timing: a function of no arguments."""
    sim = prepare(spec)
    return lambda: sim.run(grid)


def execute(spec, base_row: dict, timed: bool = True, budgets: budget.Budgets | None = None) -> dict:
    """One ladder run's row (metrics, checks, and timing when timed); never raises. Within the budgets (harness.budget:
    prepare, then the run with the equation its errors need); past one, a failed row naming it."""
    from ..run import timing
    budgets = budgets or budget.configured()
    row = dict(base_row)
    try:
        ladder, grid = spec.case.ladder, _grid(spec)
        sim = budget.prepared(lambda: prepare(spec), budgets.prepare_s)
        with budget.within("run", budgets.run_s):
            traj: SlidingLadderTrajectory = sim.run(grid)
            row.update(status=traj.status.value, message=traj.message, diverged_at=traj.diverged_at,
                       torque_mode="none")
            equation = ref_ladder.solve(ladder, grid.times, deadline=budget.deadline())
            row.update(metrics(spec, traj, equation))
            row[checks.ROW_KEY] = check_rows(spec, traj, row)
        if timed and traj.status is Status.OK:
            measured = timing.measure(lambda: sim.run(grid))
            row.update(wall_s=measured.best, us_per_step=measured.best / max(1, grid.steps) * 1e6,
                       us_per_step_spread=measured.spread / max(1, grid.steps) * 1e6)
    except budget.BudgetExceeded as exc:  # nothing it measured before the stop counts
        row = {**base_row, **budget.failed_row(exc)}
    except Exception as exc:  # a run that breaks is data
        raise_if_interrupted(exc)
        row.update(status=Status.FAILED.value, message=f"{type(exc).__name__}: {exc}".splitlines()[0])
    return row


def metrics(spec, traj: SlidingLadderTrajectory, equation: ref_ladder.LadderMotion) -> dict:
    ladder = spec.case.ladder
    state = traj.state
    finite = np.isfinite(state).all(axis=1)
    energy = ref_ladder.energy(ladder, state)
    out = {"energy_drift": float(np.max(np.abs(energy[finite] - energy[0]))) / ref_ladder.energy_scale(ladder,
                                                                                                        state[0])}
    keep = np.ones(len(traj.times), bool)
    if spec.formulation == "unilateral" and math.isfinite(equation.detach_time):
        keep = traj.times <= equation.detach_time
    if finite[keep].all():
        angle = np.abs(state[keep, 2] - equation.theta[keep])
        out.update(attitude_err=float(np.max(angle)), attitude_err_end=float(angle[-1]),
                   omega_err=float(np.max(np.abs(state[keep, 5] - equation.theta_dot[keep]))
                                   / (np.max(np.abs(equation.theta_dot[keep])) or 1.0)))
    out["_violation"] = float(np.nanmax(traj.violation)) if np.isfinite(traj.violation).any() else math.nan
    return out


def check_rows(spec, traj: SlidingLadderTrajectory, row: dict) -> list[dict]:
    ladder = spec.case.ladder
    rows = [{"quantity": "energy_drift", "theory": 0.0, "measured": row["energy_drift"]},
            {"quantity": "constraint_violation", "theory": 0.0, "measured": row.pop("_violation")}]
    if spec.formulation in DETACHING_MODELS:
        rows.append({"quantity": "detachment_angle", "theory": ref_ladder.detachment_angle(ladder),
                     "measured": traj.detach_angle})
    ok = traj.status is Status.OK
    for check in rows:
        if not ok:
            check["measured"] = math.nan
        check["error"] = checks.error(check["quantity"], check["theory"], check["measured"])
    return rows
