"""The run of an engine stepped one step at a time from Python (Genesis, Newton): the case's external torque
evaluated at every step's start from the step's time and state (torque_mode `step`: exact for a one-stage method), the
state read back at the samples, the divergence rule at each sample, the run's wall-time budget between pieces of
steps."""
from __future__ import annotations

import math
from typing import Callable, Protocol

import numpy as np

from .. import budget
from .base import RigidBodyModel
from ..grid import TimeGrid
from ..trajectory import Status, Trajectory, divergence_limit2, divergence_message, sample_good


class Stepped(Protocol):
    """An engine's model, reset to the case's initial state, as the loop drives it."""

    def step(self) -> None:
        """One step of dt."""

    def read(self) -> tuple[tuple, tuple]:
        """The current (quaternion (w, x, y, z) body -> world, omega (rad/s, body components)), as floats."""

    def apply(self, moment: tuple) -> None:
        """The external torque (N m, body components) of the next step."""


def run_steps(model: Stepped, grid: TimeGrid, omega0, torque: Callable | None) -> Trajectory:
    """Step the model over the grid (reset by the caller); torque(t, quat, omega) -> body torque, or None for a case
    without one. Ends `diverged` at the first sample the divergence rule rejects, or where the torque of a runaway
    state cannot be evaluated (math.cos(inf)); its samples from there on are NaN."""
    step, read, apply, dt = model.step, model.read, model.apply, grid.dt
    limit2 = divergence_limit2(omega0)
    samples = grid.sample_steps.tolist()
    quat = np.full((len(samples), 4), np.nan)
    omega = np.full((len(samples), 3), np.nan)
    quat[0], omega[0] = read()
    bad = None
    for i in range(1, len(samples)):
        pieces = budget.pieces(samples[i - 1], samples[i])  # the run's wall-time budget between pieces
        if torque is None:  # the hot loop: the engine's steps, one state read a sample
            for piece in pieces:
                for _ in piece:
                    step()
        else:  # every step: the torque from the step's time and state, then the step
            try:
                for piece in pieces:
                    for k in piece:
                        apply(torque(k * dt, *read()))
                        step()
            except (ArithmeticError, ValueError):  # a torque of a runaway state: diverged
                bad = i
                break
        q, w = read()
        quat[i], omega[i] = q, w
        if not sample_good(q, w, limit2):  # the divergence rule
            bad = i
            break
    info = {"torque_mode": "none" if torque is None else "step"}
    if bad is None:
        return Trajectory(grid.times, quat, omega, Status.OK, "", math.nan, grid.steps, grid.steps, info=info)
    quat[bad:], omega[bad:] = np.nan, np.nan
    diverged_at = float(grid.times[bad])
    return Trajectory(grid.times, quat, omega, Status.DIVERGED, divergence_message(diverged_at), diverged_at,
                      samples[bad], samples[bad], info=info)


# The default sweep of an engine whose worker pays seconds of import and compilation (Genesis, Newton): the general
# cases at one coarse step each.
DEFAULT_CASES = ("free-asymmetric", "lagrange-top", "kovalevskaya", "heavy-asymmetric")
COARSE_DT = 1e-2


def coarse_dts(dts: tuple[float, ...]) -> tuple[float, ...]:
    """The largest of dts at most COARSE_DT (heavy-asymmetric's 0.3 is beyond every Euler variant's stability limit: a
    diverged row says nothing more than MuJoCo's does), else the smallest."""
    coarse = [dt for dt in dts if dt <= COARSE_DT]
    return (max(coarse),) if coarse else (min(dts),)


def free_body_unsupported(com, why: str) -> str | None:
    """The reason a free-joint model cannot run a body whose centre of mass com (3,) m is not O (why: the engine's
    words), or None."""
    if np.any(np.asarray(com) != 0.0):
        return f"free: a free body moves as the pinned one only when O is its centre of mass (com = 0); {why}"
    return None


class SteppedRigidBody(RigidBodyModel):
    """The rigid body of an engine stepped from Python with a ball and a free model (Genesis, Newton): the free model
    only where O is the centre of mass (`free_words`: the engine's reason otherwise), the torque applied at every step
    (torque_mode `step`), a default sweep of the general cases (DEFAULT_CASES) at one coarse step (coarse_dts)."""

    def __init__(self, engine, variants: tuple[str, ...], free: str, free_words: str):
        super().__init__(engine)
        self._variants, self._free, self._free_words = variants, free, free_words

    def variants(self) -> tuple[str, ...]:
        return self._variants

    def unsupported_run(self, case, variant: str, integrator: str) -> str | None:
        return free_body_unsupported(case.body.com, self._free_words) if variant == self._free else None

    def default_run(self, case, variant: str, integrator: str) -> bool:
        """The general cases only (DEFAULT_CASES), the free model where the scene allows it."""
        return case.name in DEFAULT_CASES and self.unsupported_run(case, variant, integrator) is None

    def default_dts(self, case, integrator: str, dts: tuple[float, ...]) -> tuple[float, ...]:
        return coarse_dts(dts)

    def torque_mode(self, case) -> str:
        return "step" if case.body.has_external_torque else "none"
