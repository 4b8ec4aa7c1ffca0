"""The core types every layer shares: a run's Status, its recorded Trajectory, and the divergence rule.

Integrators, engines, metrics and the store all import this module; it imports nothing of stereodyn's but the grid.
"""
from __future__ import annotations

import enum
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from stereodyn.harness.grid import TimeGrid


class Status(str, enum.Enum):
    OK = "ok"
    DIVERGED = "diverged"
    FAILED = "failed"
    SKIPPED = "skipped"


# A state whose angular speed passes this many times the initial scale (plus 1 rad/s) counts as diverged:
# no conservative motion of these scenes gets anywhere near it, and NaN follows soon after anyway.
DIVERGENCE_FACTOR = 1e6


@dataclass(frozen=True, eq=False)
class Trajectory:
    """States recorded on a TimeGrid's sample times.

    times: (n,) s.
    quat: (n, 4) attitude quaternion, scalar first (w, x, y, z), body -> world, as the engine left it (not renormalised).
    omega: (n, 3) rad/s, body frame.
    After a divergence the remaining samples are NaN and diverged_at (s) is the first time a state was bad.
    steps: steps taken; rhs_evals: right-hand-side (dynamics) evaluations, where the engine counts them.
    chart_changes: changes of attitude chart made by a formulation with charts (None where there are none).
    """

    times: np.ndarray
    quat: np.ndarray
    omega: np.ndarray
    status: Status = Status.OK
    message: str = ""
    diverged_at: float = float("nan")
    steps: int = 0
    rhs_evals: int = 0
    info: dict = field(default_factory=dict)
    chart_changes: int | None = None


def first_bad_sample(omega: np.ndarray, quat: np.ndarray, omega0: np.ndarray) -> int | None:
    """Index of the first sample that is not finite or whose |omega| is beyond DIVERGENCE_FACTOR, else None."""
    limit = DIVERGENCE_FACTOR * (1.0 + float(np.linalg.norm(omega0)))
    with np.errstate(invalid="ignore"):
        bad = ~np.isfinite(omega).all(axis=1) | ~np.isfinite(quat).all(axis=1) | (np.linalg.norm(omega, axis=1) > limit)
    hits = np.flatnonzero(bad)
    return int(hits[0]) if hits.size else None


def diverged_trajectory(grid: "TimeGrid", quat: np.ndarray, omega: np.ndarray, bad: int, diverged_at: float,
                        steps: int, rhs_evals: int = 0, message: str | None = None) -> Trajectory:
    """A Trajectory whose samples from `bad` on are NaN, with status diverged and message (default: the divergence
    rule's)."""
    quat, omega = quat.copy(), omega.copy()
    quat[bad:] = np.nan
    omega[bad:] = np.nan
    if message is None:
        message = f"state not finite or |omega| beyond {DIVERGENCE_FACTOR:g} x its start at t = {diverged_at:.6g} s"
    return Trajectory(grid.times, quat, omega, Status.DIVERGED, message, diverged_at, steps, rhs_evals)


@dataclass(frozen=True, eq=False)
class SlidingLadderTrajectory:
    """The sliding ladder's recorded states (harness.sliding_ladder): not a body with a fixed point.

    times: (n,) s. state: (n, 6) x, y (m, centre of the rod; wall x = 0, floor y = 0), θ (rad from the wall), and
    their rates (m/s, rad/s). violation: (n,) m, how far the model's ends are off the wall and floor (bilateral:
    the equality residual; unilateral: the contacts' penetration). detach_angle: rad, θ where the wall's push on the
    top reached zero (NaN where not measured).
    """

    times: np.ndarray
    state: np.ndarray
    violation: np.ndarray
    status: Status = Status.OK
    message: str = ""
    diverged_at: float = float("nan")
    steps: int = 0
    detach_angle: float = float("nan")
    info: dict = field(default_factory=dict)
