"""The core types every layer shares: a run's Status, its recorded Trajectory, and the divergence rule.

Integrators, engines, metrics and the store all import this module; it imports nothing of stereodyn's but the grid.
"""
from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from .grid import TimeGrid


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


def divergence_limit2(omega0) -> float:
    """The square of the divergence rule's limit on |omega| (rad/s)^2 for a run that starts at omega0 (3,)."""
    w0, w1, w2 = (float(w) for w in omega0)
    return (DIVERGENCE_FACTOR * (1.0 + math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)))**2


def sample_good(quat, omega, limit2: float) -> bool:
    """The divergence rule on one sample (4 and 3 floats), in float arithmetic: cheap enough for the per-sample hot
    path of harness.integrators.base. A sample is good when |omega|^2 <= limit2 and the quaternion is finite."""
    w0, w1, w2 = omega
    # NaN and inf fail the comparison, so it also catches a non-finite omega; a sum of the quaternion's components is
    # finite exactly when all of them are (inf - inf is NaN).
    return w0 * w0 + w1 * w1 + w2 * w2 <= limit2 and math.isfinite(quat[0] + quat[1] + quat[2] + quat[3])


def samples_good(quat: np.ndarray, omega: np.ndarray, limit2) -> np.ndarray:
    """sample_good row by row: quat (n, 4), omega (n, 3), limit2 a float or (n,); a bool (n,) array."""
    with np.errstate(invalid="ignore", over="ignore"):
        return (np.einsum("ij,ij->i", omega, omega) <= limit2) & np.isfinite(quat.sum(axis=1))


def first_bad_sample(omega: np.ndarray, quat: np.ndarray, omega0: np.ndarray) -> int | None:
    """Index of the first sample that breaks the divergence rule (not finite, or |omega| beyond DIVERGENCE_FACTOR
    times (1 + |omega0|)), else None."""
    hits = np.flatnonzero(~samples_good(np.asarray(quat, dtype=float), np.asarray(omega, dtype=float),
                                        divergence_limit2(omega0)))
    return int(hits[0]) if hits.size else None


def first_bad_step(step, observe, g, v, start: int, end: int, dt: float, limit2: float) -> tuple[int, object]:
    """Replay a stepper step(t, g, v) -> (g, v) from the last good sample (step index start, state (g, v)) to the
    first step whose state breaks the rule (observe(g, v) gives its quaternion and omega floats) or whose step raises
    ArithmeticError: that step's index, and the g of the state before it. Step k starts at t = k * dt."""
    for index in range(start + 1, end + 1):
        try:
            g_next, v = step((index - 1) * dt, g, v)
        except ArithmeticError:
            return index, g
        if not sample_good(*observe(g_next, v), limit2):
            return index, g
        g = g_next
    return end, g  # not reached for a deterministic step; the sample itself is the bound


def divergence_message(diverged_at: float) -> str:
    """The divergence rule's message for a run that broke it at diverged_at (s)."""
    return f"state not finite or |omega| beyond {DIVERGENCE_FACTOR:g} x its start at t = {diverged_at:.6g} s"


def diverged_trajectory(grid: "TimeGrid", quat: np.ndarray, omega: np.ndarray, bad: int, diverged_at: float,
                        steps: int, rhs_evals: int = 0, message: str | None = None) -> Trajectory:
    """A Trajectory whose samples from `bad` on are NaN, with status diverged and message (default: the divergence
    rule's)."""
    quat, omega = quat.copy(), omega.copy()
    quat[bad:] = np.nan
    omega[bad:] = np.nan
    if message is None:
        message = divergence_message(diverged_at)
    return Trajectory(grid.times, quat, omega, Status.DIVERGED, message, diverged_at, steps, rhs_evals)


@dataclass(frozen=True, eq=False)
class SlidingLadderTrajectory:
    """The sliding ladder's recorded states (harness.scenes.sliding_ladder): not a body with a fixed point.

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
