"""The sliding ladder in a sweep (kind "sliding_ladder", FORMULARY T5): its own runs, metrics and check rows, beside
the rigid body's (harness.scenes.rigid_body), through the same run -> row path (harness.run.measure).

Rows: the equation (engine reference, formulation "theta", integrator taylor: reference.sliding_ladder, whose heyoka event
gives the detachment), every MuJoCo model (formulation "bilateral" or "unilateral", harness.engines.mujoco) with each
MuJoCo integrator and dt, Pinocchio's bilateral model (its constrained dynamics, harness.engines.pinocchio) with
each of its integrators that works on a vector state (its LadderModel.integrators) and dt. Columns: energy_drift
(the rod's energy, ½ m|v_G|² + ½ (mℓ²/3) θ̇² + m g y, relative to its terms at t = 0), attitude_err /
attitude_err_end (|θ − θ_equation| modulo 2π, in [0, π], rad), omega_err (|θ̇ − θ̇_equation| /
max |θ̇_equation|) — for the unilateral model only up to the equation's detachment, after which the equation (both
ends on the axes) no longer describes it. checks.csv: detachment_angle (the equation's event and the unilateral
model's wall push, against arccos((2/3) cos θ0 + 4ℓθ̇0²/(9g))), energy_drift and constraint_violation (m; theory 0).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .. import budget
from ..grid import TimeGrid
from ..trajectory import SlidingLadderTrajectory, Status
from ...reference import sliding_ladder as ref_ladder
from .base import register
from .cases import SLIDING_LADDER, LadderCase
from .checks import ROW_KEY, error as check_error

# The models whose rows get a detachment_angle check: the equation's event (the reference engine's "theta") and the
# unilateral model's wall push (MuJoCo's); a bilateral model never leaves the wall.
DETACHING_MODELS = ("theta", "unilateral")
TOP = (frozenset({"name", "description", "tags", "kind", "ladder", "run"}), frozenset({"kind", "ladder", "run"}))
LADDER = (frozenset({"mass", "half_length", "theta0", "theta_dot0", "g"}),
          frozenset({"mass", "half_length", "theta0", "g"}))


class SlidingLadderScene:
    kind = SLIDING_LADDER
    title = "the sliding ladder"
    needs_truth = False    # each run is compared with the equation solved on its own grid
    keeps_states = False   # its state is the rod's planar one, not a body's (quat, omega)
    work_precision = False  # orders and floors are about the body with a fixed point; MuJoCo's constraints are soft
    trajectory = SlidingLadderTrajectory  # what its models' run() returns (harness.run.measure checks it)
    columns = ("energy_drift", "attitude_err", "attitude_err_end", "omega_err", "torque_mode")

    def parse(self, parser, data: dict) -> LadderCase:
        parser.table(data, "ladder_case", TOP)
        name, description, tags = parser.words(data)
        table = parser.table(data["ladder"], "ladder", LADDER)
        theta0 = parser.number(table["theta0"], "ladder.theta0")
        if not 0.0 < theta0 < 0.5 * math.pi:
            raise parser.fail("ladder.theta0", f"must be in (0, pi/2) rad (from the wall), got {theta0:g}")
        theta_dot0 = parser.number(table.get("theta_dot0", 0.0), "ladder.theta_dot0")
        if theta_dot0 < 0.0:
            raise parser.fail("ladder.theta_dot0", f"must be >= 0 (the ladder slides down), got {theta_dot0:g}")
        ladder = ref_ladder.Ladder(mass=parser.positive(table["mass"], "ladder.mass"),
                                   half_length=parser.positive(table["half_length"], "ladder.half_length"),
                                   theta0=theta0, theta_dot0=theta_dot0, g=parser.positive(table["g"], "ladder.g"))
        if not ref_ladder.detachment_cosine(ladder) < math.cos(theta0):
            raise parser.fail("ladder.theta_dot0", "the wall would pull at t = 0 (cos theta_detach = "
                                                   f"{ref_ladder.detachment_cosine(ladder):.6g} >= cos theta0): "
                                                   "too fast a start")
        t_end, dt, samples = parser.run(data["run"])
        return LadderCase(name=name, description=description, tags=tags, ladder=ladder, t_end=t_end, dt=dt,
                          samples=samples, path=Path(parser.path))

    def truth(self, case: LadderCase, grids: list[TimeGrid], certify: bool) -> None:
        return None  # the equation is solved on each run's own grid (metrics)

    def metrics(self, run, model, traj: SlidingLadderTrajectory, grid: TimeGrid, truth, full: bool, rerun,
                keep_states: bool = False) -> dict:
        out = {"torque_mode": "none"}
        equation = ref_ladder.solve(run.case.ladder, grid.times, deadline=budget.deadline())
        out.update(ladder_metrics(run, traj, equation))
        violation = out.pop("_violation")
        if full:
            out[ROW_KEY] = check_rows(run, traj, out["energy_drift"], violation)
        return out


def ladder_metrics(spec, traj: SlidingLadderTrajectory, equation: ref_ladder.LadderMotion) -> dict:
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
        # the angle between the two rods on the circle, in [0, pi] as every attitude error (results.ANGLES); only an
        # angle beyond pi is wrapped: adding pi to an error of 4.6e-14 rounds it to a multiple of ulp(pi), 4.4e-16
        delta = state[keep, 2] - equation.theta[keep]
        angle = np.abs(delta)
        far = angle > np.pi
        angle[far] = np.abs(np.remainder(delta[far] + np.pi, 2 * np.pi) - np.pi)
        out.update(attitude_err=float(np.max(angle)), attitude_err_end=float(angle[-1]),
                   omega_err=float(np.max(np.abs(state[keep, 5] - equation.theta_dot[keep]))
                                   / (np.max(np.abs(equation.theta_dot[keep])) or 1.0)))
    out["_violation"] = float(np.nanmax(traj.violation)) if np.isfinite(traj.violation).any() else math.nan
    return out


def check_rows(spec, traj: SlidingLadderTrajectory, energy_drift: float, violation: float) -> list[dict]:
    ladder = spec.case.ladder
    rows = [{"quantity": "energy_drift", "theory": 0.0, "measured": energy_drift},
            {"quantity": "constraint_violation", "theory": 0.0, "measured": violation}]
    if spec.formulation in DETACHING_MODELS:
        rows.append({"quantity": "detachment_angle", "theory": ref_ladder.detachment_angle(ladder),
                     "measured": traj.detach_angle})
    ok = traj.status is Status.OK
    for check in rows:
        if not ok:
            check["measured"] = math.nan
        check["error"] = check_error(check["quantity"], check["theory"], check["measured"])
    return rows


SCENE = register(SlidingLadderScene())
