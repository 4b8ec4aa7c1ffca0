"""MuJoCo adapter: the body on a ball joint at the world origin, rolled out natively with mujoco.rollout.

Ball joint: qpos = quaternion (w, x, y, z) body -> world, qvel = angular velocity in body components (ENGINES.md).
Autoreset is disabled, so a divergence shows as NaN (or a runaway |omega|) in the states, which run() detects.
"""
from __future__ import annotations

import dataclasses
import math

import mujoco
import numpy as np
from mujoco import rollout

from harness.cases import Case
from harness.engines.base import DIVERGENCE_FACTOR, Status, Trajectory, diverged_trajectory
from harness.grid import TimeGrid

# harness name -> (MJCF option value, dynamics evaluations per step)
INTEGRATORS: dict[str, tuple[str, int]] = {
    "euler": ("Euler", 1),
    "implicit": ("implicit", 1),
    "implicitfast": ("implicitfast", 1),
    "rk4": ("RK4", 4),
}

# Steps per rollout call: bounds the state buffer (CHUNK_STEPS x 8 doubles) for long runs; at this size the
# per-call cost is well under 1% of the stepping.
CHUNK_STEPS = 10_000

_FEATURES = ("body_torque", "central_field")
_FULL = mujoco.mjtState.mjSTATE_FULLPHYSICS.value


def _unsupported(case: Case) -> str | None:
    missing = [f"[{name}]" for name in _FEATURES if getattr(case, name) is not None]
    return f"MuJoCo adapter does not model {', '.join(missing)} yet" if missing else None


def _numbers(values) -> str:
    # repr round-trips a double exactly, so the compiled model has the case's numbers to the last bit.
    return " ".join(repr(float(x)) for x in values)


def mjcf(case: Case, integrator: str, dt: float) -> str:
    """The MJCF scene of a case: one body on a ball joint at the world origin, nothing else.

    inertial: mass, pos = O -> G (m, body frame), fullinertia = inertia about the centre of mass (kg m^2, body axes,
    "Ixx Iyy Izz Ixy Ixz Iyz"). gravity = g d (m/s^2, world frame). Everything the scene lacks is disabled.
    Raises KeyError for an unknown integrator and ValueError for a case MuJoCo cannot model exactly.
    """
    if integrator not in INTEGRATORS:
        raise KeyError(f"unknown MuJoCo integrator {integrator!r}; valid: {', '.join(INTEGRATORS)}")
    reason = _unsupported(case)
    if reason:
        raise ValueError(f"{case.name}: {reason}")
    body = case.body
    inertia = np.asarray(body.inertia_com, dtype=float)
    moments = np.linalg.eigvalsh(inertia)
    # MuJoCo silently clamps a fullinertia that is not positive definite (ENGINES.md): refuse it here instead.
    if not moments[0] > 0.0:
        raise ValueError(f"{case.name}: inertia about the centre of mass is not positive definite "
                         f"(principal moments {moments})")
    gravity = body.gravity * np.asarray(body.gravity_direction, dtype=float)
    full_inertia = (inertia[0, 0], inertia[1, 1], inertia[2, 2], inertia[0, 1], inertia[0, 2], inertia[1, 2])
    return f"""<mujoco model="{case.name}">
  <option timestep="{float(dt)!r}" gravity="{_numbers(gravity)}" integrator="{INTEGRATORS[integrator][0]}">
    <flag contact="disable" constraint="disable" equality="disable" frictionloss="disable" limit="disable"
          damper="disable" autoreset="disable"/>
  </option>
  <worldbody>
    <body name="body" pos="0 0 0">
      <joint name="ball" type="ball" pos="0 0 0"/>
      <inertial pos="{_numbers(body.com)}" mass="{float(body.mass)!r}" fullinertia="{_numbers(full_inertia)}"/>
    </body>
  </worldbody>
</mujoco>
"""


class MujocoSimulation:
    """A compiled scene; run() rolls it out from the case's initial state (every call starts afresh)."""

    def __init__(self, case: Case, integrator: str, dt: float):
        self.xml = mjcf(case, integrator, dt)
        self.model = mujoco.MjModel.from_xml_string(self.xml)
        self.data = mujoco.MjData(self.model)
        self.stages = INTEGRATORS[integrator][1]
        self.dt = float(dt)
        self.data.qpos[:] = case.quat0
        self.data.qvel[:] = case.omega0
        self.initial_state = np.empty((1, mujoco.mj_stateSize(self.model, _FULL)))
        mujoco.mj_getState(self.model, self.data, self.initial_state[0], _FULL)
        # Offsets of qpos and qvel in the full-physics state vector (time comes first).
        self._qpos = mujoco.mj_stateSize(self.model, mujoco.mjtState.mjSTATE_TIME.value)
        self._qvel = mujoco.mj_stateSize(self.model, mujoco.mjtState.mjSTATE_TIME | mujoco.mjtState.mjSTATE_QPOS)
        self.limit2 = (DIVERGENCE_FACTOR * (1.0 + float(np.linalg.norm(case.omega0))))**2

    def run(self, grid: TimeGrid) -> Trajectory:
        """Roll out grid.steps steps. MuJoCo's warnings (e.g. the bad-QACC one of a divergence) are collected into
        info["mujoco_warnings"] instead of being printed and appended to MUJOCO_LOG.TXT in the working directory."""
        if grid.dt != self.dt:
            raise ValueError(f"grid dt {grid.dt} differs from the prepared dt {self.dt}")
        messages: list[str] = []
        previous = mujoco.get_mju_user_warning()
        mujoco.set_mju_user_warning(messages.append)  # process-global: restored below
        try:
            trajectory = self._rollout(grid)
        finally:
            mujoco.set_mju_user_warning(previous)
        return dataclasses.replace(trajectory, info={"mujoco_warnings": tuple(messages)}) if messages else trajectory

    def _rollout(self, grid: TimeGrid) -> Trajectory:
        models, datas, iq, iv = [self.model], [self.data], self._qpos, self._qvel
        samples = grid.sample_steps
        quat = np.empty((samples.size, 4))
        omega = np.empty((samples.size, 3))
        quat[0] = self.initial_state[0, iq:iq + 4]
        omega[0] = self.initial_state[0, iv:iv + 3]
        state = self.initial_state.copy()
        buffer = np.empty((1, min(CHUNK_STEPS, grid.steps), state.shape[1]))
        done, next_sample = 0, 1
        while done < grid.steps:
            n = min(CHUNK_STEPS, grid.steps - done)
            rows = buffer[:, :n]  # first axis has length 1, so the slice is still C-contiguous
            # Row i of the output is the state after step done + i + 1. The shapes are right by construction, so the
            # wrapper's checks (and its output allocation) are skipped.
            rollout.rollout(models, datas, state, nstep=n, state=rows, skip_checks=True)
            rows = rows[0]
            end_sample = int(np.searchsorted(samples, done + n, side="right"))
            picked = samples[next_sample:end_sample] - (done + 1)
            quat[next_sample:end_sample] = rows[picked, iq:iq + 4]
            omega[next_sample:end_sample] = rows[picked, iv:iv + 3]
            bad = self._first_bad_row(rows, iq, iv)
            if bad is not None:
                bad_step = done + bad + 1
                first_bad_sample = int(np.searchsorted(samples, bad_step))
                return diverged_trajectory(grid, quat, omega, first_bad_sample, bad_step * grid.dt, done + n,
                                           self.stages * (done + n))
            state[0] = rows[-1]
            done, next_sample = done + n, end_sample
        return Trajectory(grid.times, quat, omega, Status.OK, "", math.nan, grid.steps, self.stages * grid.steps)

    def _first_bad_row(self, rows: np.ndarray, iq: int, iv: int) -> int | None:
        """The divergence rule of harness.engines.base.first_bad_sample, on every step of a chunk."""
        w = rows[:, iv:iv + 3]
        with np.errstate(invalid="ignore", over="ignore"):
            # NaN fails <=, so a non-finite omega is caught too; a non-finite quaternion has a non-finite sum.
            ok = np.einsum("ij,ij->i", w, w) <= self.limit2
            ok &= np.isfinite(rows[:, iq:iq + 4].sum(axis=1))
        if ok.all():
            return None
        return int(np.argmin(ok))


class MujocoEngine:
    name = "mujoco"

    def integrators(self) -> tuple[str, ...]:
        return tuple(INTEGRATORS)

    def unsupported(self, case: Case) -> str | None:
        return _unsupported(case)

    def prepare(self, case: Case, integrator: str, dt: float) -> MujocoSimulation:
        return MujocoSimulation(case, integrator, dt)
