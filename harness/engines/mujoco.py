"""MuJoCo adapter: the body on a ball joint at the world origin, rolled out natively with mujoco.rollout.

Ball joint: qpos = quaternion (w, x, y, z) body -> world, qvel = angular velocity in body components (ENGINES.md).
Autoreset is disabled, so a divergence shows as NaN (or a runaway |omega|) in the states, which run() detects.

External torques (reference.torques; Trajectory.info["torque_mode"] says how each entered): torques constant in the
body frame (TorqueModel.constant: a body torque with b = 0) through qfrc_applied set once before the first step
("qfrc_applied"); any torque that depends
on the state or the time through mjcb_passive ("passive_callback"), which MuJoCo calls at every force evaluation,
every RK4 stage included, with that stage's qpos, qvel and time. Refreshing qfrc_applied from Python between steps
instead would hold the torque through the stages and make RK4 first order (tests/test_torques.py shows it). Torqued
scenes are stepped from Python with mj_step (the callback is process-global: set for the run, restored after).

The sliding ladder (harness.scenes.sliding_ladder) is built here too, as planar rods: sliding_ladder_simulation().
"""
from __future__ import annotations

import dataclasses
import math
import os

from xml.sax.saxutils import quoteattr

# No rendering here: without this, importing mujoco imports glfw, which starts a Python subprocess to read its
# library's version (~0.1 s in every process; a Ctrl-C during it printed that child's "Fatal Python error").
os.environ.setdefault("MUJOCO_GL", "disable")
import mujoco  # noqa: E402
import numpy as np  # noqa: E402
from mujoco import rollout  # noqa: E402

from .. import budget
from ..scenes.cases import Case, unphysical_inertia
from ..trajectory import (SlidingLadderTrajectory, Status, Trajectory, divergence_limit2,
                          diverged_trajectory, sample_good, samples_good)
from .base import RIGID_BODY, SLIDING_LADDER, About, Engine, Offer, RigidBodyModel, SceneModel, Timing, singular_torque
from .offered import names as offered_names, unmodelled as unmodelled_reason
from ..grid import TimeGrid
from ...reference.torques import torque_function

# Where MuJoCo's warnings outside a run go (a run collects its own, MuJoCoSimulation.run): the file named by this
# environment variable (`stereodyn run` sets DIR/MUJOCO_LOG.TXT), never stderr nor the working directory's
# MUJOCO_LOG.TXT, which MuJoCo's default handler appends to.
LOG_ENV = "STEREODYN_MUJOCO_LOG"


def _log_warning(message: str) -> None:
    path = os.environ.get(LOG_ENV)
    if path:
        try:
            with open(path, "a", encoding="utf-8") as log:
                log.write(f"WARNING: {message}\n")
        except OSError:
            pass  # a log that cannot be written loses a warning, never a run


mujoco.set_mju_user_warning(_log_warning)

# The integrators the adapter models: harness name (mjtIntegrator's member without mjINT_, lower case) -> (MJCF option
# value, dynamics evaluations per step). Which of them a run has is read from the installed MuJoCo (offered()):
# discrete exists from 3.13.
INTEGRATORS: dict[str, tuple[str, int]] = {
    "euler": ("Euler", 1),
    "implicit": ("implicit", 1),
    "implicitfast": ("implicitfast", 1),
    "rk4": ("RK4", 4),
    "discrete": ("discrete", 1),
}
# mjtIntegrator members the adapter knows and does not run, with why (offered.unmodelled; none today). A member in
# neither table is named as not modelled at run time; tests/test_engine_sdk.py fails until it is in one of them.
NOT_MODELLED: dict[str, str] = {}
ENUM_PREFIX = "mjINT_"


def offered() -> tuple[str, ...]:
    """The integrators the installed MuJoCo offers: mjtIntegrator's members, in its order, as harness names."""
    return tuple(name[len(ENUM_PREFIX):].lower() for name in mujoco.mjtIntegrator.__members__
                 if name.startswith(ENUM_PREFIX))


def integrator_names() -> tuple[str, ...]:
    """The engine's integrators: the modelled ones this MuJoCo offers, then the ones it offers that are not modelled
    (offered.names)."""
    return offered_names(offered(), tuple(INTEGRATORS))


def not_modelled(integrator: str) -> str:
    """Why the adapter does not run an integrator of the installed MuJoCo ("" when it does)."""
    return unmodelled_reason(integrator, offered(), INTEGRATORS, NOT_MODELLED,
                             f"mujoco {mujoco.__version__}'s mjtIntegrator")

# Steps per rollout call: bounds the state buffer (CHUNK_STEPS x 8 doubles) for long runs; at this size the
# per-call cost is well under 1% of the stepping.
CHUNK_STEPS = 10_000

_FULL = mujoco.mjtState.mjSTATE_FULLPHYSICS.value


def _unsupported(case: Case) -> str | None:
    # MuJoCo's compiler refuses a body that breaks the triangle inequality (balanceinertia would alter it silently)
    return unphysical_inertia(case) or singular_torque(case)


def torque_mode(case: Case) -> str:
    """How the case's external torque enters: "none", "qfrc_applied" (constant, set once) or "passive_callback"."""
    if not case.body.has_external_torque:
        return "none"
    if all(term.constant for term in case.torques):  # constant in the body frame: applied once
        return "qfrc_applied"
    return "passive_callback"


def _runtime_torques(case: Case) -> str | None:
    """The MJCF scene cannot hold a torque that enters at run time (export refuses it)."""
    present = [f"[{term.key}]" for term in case.torques]
    if present:
        return (f"{', '.join(present)} enters the MuJoCo adapter at run time (qfrc_applied or a passive callback), "
                f"which an MJCF file cannot hold")
    return None


def _numbers(values) -> str:
    # repr round-trips a double exactly, so the compiled model has the case's numbers to the last bit.
    return " ".join(repr(float(x)) for x in values)


def mjcf(case: Case, integrator: str, dt: float) -> str:
    """The MJCF scene of a case: one body on a ball joint at the world origin, nothing else.

    inertial: mass, pos = O -> G (m, body frame), fullinertia = inertia about the centre of mass (kg m^2, body axes,
    "Ixx Iyy Izz Ixy Ixz Iyz"). gravity = g d (m/s^2, world frame). Everything the scene lacks is disabled.
    Raises KeyError for an unknown integrator and ValueError for a case MuJoCo cannot model exactly.
    """
    reason = _runtime_torques(case)
    if reason:
        raise ValueError(f"{case.name}: {reason}")
    return scene(case, integrator, dt)


def scene(case: Case, integrator: str, dt: float, model_name: str | None = None, raised: float = 0.0) -> str:
    """mjcf() without the export's refusal of run-time torques (the MJX and MuJoCo Warp adapters build on it).
    model_name: the model's name (default the case's). raised: kg m^2 added to each principal moment about the
    centre of mass (compiled(): a lamina's smallest change MuJoCo accepts)."""
    if integrator not in INTEGRATORS:
        raise KeyError(f"unknown MuJoCo integrator {integrator!r}; valid: {', '.join(INTEGRATORS)}")
    body = case.body
    inertia = np.asarray(body.inertia_com, dtype=float) + raised * np.eye(3)
    moments = np.linalg.eigvalsh(inertia)
    # MuJoCo silently clamps a fullinertia that is not positive definite (ENGINES.md): refuse it here instead.
    if not moments[0] > 0.0:
        raise ValueError(f"{case.name}: inertia about the centre of mass is not positive definite "
                         f"(principal moments {moments})")
    gravity = body.gravity * np.asarray(body.gravity_direction, dtype=float)
    full_inertia = (inertia[0, 0], inertia[1, 1], inertia[2, 2], inertia[0, 1], inertia[0, 2], inertia[1, 2])
    return f"""<mujoco model={quoteattr(case.name if model_name is None else model_name)}>
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


# A lamina (a thin disk: principal moments about the centre of mass mr^2/4, mr^2/4, mr^2/2, exactly A + B = C) is a
# physical body, but MuJoCo's compiler diagonalises fullinertia itself and checks A + B >= C without tolerance
# (user_objects.cc: "inertia must satisfy A + B >= C; use 'balanceinertia'", which would make all three equal): the
# rounded eigenvalues of a rotated lamina fall below the equality by an ulp or two. The smallest change it accepts is
# found by trying: each principal moment raised by ULPS x eps x the largest one, ULPS = 1, 2, 4, ... up to this cap
# (measured: 1 on each of 7 refused orientations of a disk, ~2e-16 relative, far below every error the rows report,
# which are against the truth of the unchanged body). Past it, a body MuJoCo refuses stays refused.
LAMINA_MAX_ULPS = 64
LAMINA_REFUSAL = "A + B >= C"


def compiled(case: Case, integrator: str, dt: float,
             model_name: str | None = None) -> tuple[str, "mujoco.MjModel", str]:
    """(MJCF, compiled model, note) of the case's scene: note "" when MuJoCo accepts the body as it is, else the
    smallest raise of its principal moments (LAMINA_MAX_ULPS) that MuJoCo accepts, in words for the row."""
    xml = scene(case, integrator, dt, model_name=model_name)
    try:
        return xml, mujoco.MjModel.from_xml_string(xml), ""
    except ValueError as exc:
        if LAMINA_REFUSAL not in str(exc) or unphysical_inertia(case):
            raise
        refusal = exc
    largest = float(np.linalg.eigvalsh(np.asarray(case.body.inertia_com, dtype=float))[-1])
    ulps = 1
    while ulps <= LAMINA_MAX_ULPS:
        raised = ulps * np.finfo(float).eps * largest
        xml = scene(case, integrator, dt, model_name=model_name, raised=raised)
        try:
            model = mujoco.MjModel.from_xml_string(xml)
        except ValueError:
            ulps *= 2
            continue
        return xml, model, (f"MuJoCo's model: principal moments about the centre of mass raised by {raised:.3g} kg "
                            f"m^2 ({ulps} ulp of the largest, {largest:.6g}), the smallest change its compiler "
                            f"accepts for this lamina (A + B = C, which it checks without tolerance)")
    raise ValueError(f"{case.name}: MuJoCo cannot represent this lamina (A + B = C about the centre of mass): its "
                     f"compiler refuses it even with the principal moments raised by {LAMINA_MAX_ULPS} ulp "
                     f"({refusal})") from refusal


def scene_state(case: Case, integrator: str, dt: float, model_name: str, energy: bool = True,
                autoreset: bool = True) -> tuple["mujoco.MjModel", "mujoco.MjData"]:
    """scene() compiled, and its data at the case's initial state (a constant torque in qfrc_applied): what MuJoCo's
    back-ends (MJX, MuJoCo Warp) put on their device, so that no other adapter imports mujoco. energy False clears
    the energy flag (MJX refuses it; the energies come from the states anyway); autoreset False clears the
    autoreset-disable flag (MuJoCo Warp has no autoreset and refuses it)."""
    _, model, _ = compiled(case, integrator, dt, model_name=model_name)
    if not energy:
        model.opt.enableflags &= ~int(mujoco.mjtEnableBit.mjENBL_ENERGY)
    if not autoreset:
        model.opt.disableflags &= ~int(mujoco.mjtDisableBit.mjDSBL_AUTORESET)
    data = mujoco.MjData(model)
    data.qpos[:] = case.quat0
    data.qvel[:] = case.omega0
    if torque_mode(case) == "qfrc_applied":
        data.qfrc_applied[:] = torque_function(case.body)(0.0, tuple(case.quat0), tuple(case.omega0))
    return model, data


class MujocoSimulation:
    """A compiled scene; run() rolls it out from the case's initial state (every call starts afresh)."""

    def __init__(self, case: Case, integrator: str, dt: float):
        self.xml, self.model, self.note = compiled(case, integrator, dt)
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
        self.limit2 = divergence_limit2(case.omega0)

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
        if self.note:  # the row says how MuJoCo's body differs from the case's (compiled())
            message = f"{trajectory.message}; {self.note}" if trajectory.message else self.note
            trajectory = dataclasses.replace(trajectory, message=message)
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
            budget.check()  # the run's wall-time budget, between chunks (each ~10 ms of C)
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
        """The divergence rule (harness.trajectory.samples_good) on every step of a chunk."""
        ok = samples_good(rows[:, iq:iq + 4], rows[:, iv:iv + 3], self.limit2)
        if ok.all():
            return None
        return int(np.argmin(ok))


class TorqueSimulation(MujocoSimulation):
    """A scene with an external torque (reference.torques), stepped with mj_step from Python: qfrc_applied set once
    for a constant torque, else a passive callback that every stage sees (module docstring)."""

    def __init__(self, case: Case, integrator: str, dt: float):
        super().__init__(case, integrator, dt)
        self.mode = torque_mode(case)
        self.torque = torque_function(case.body)
        self.quat0 = np.array(case.quat0, dtype=float)
        self.omega0 = np.array(case.omega0, dtype=float)

    def _passive(self, model, data) -> None:
        qpos, qvel = data.qpos, data.qvel
        m = self.torque(data.time, (qpos[0], qpos[1], qpos[2], qpos[3]), (qvel[0], qvel[1], qvel[2]))
        passive = data.qfrc_passive
        passive[0] += m[0]
        passive[1] += m[1]
        passive[2] += m[2]

    def run(self, grid: TimeGrid) -> Trajectory:
        trajectory = super().run(grid)
        return dataclasses.replace(trajectory, info={**trajectory.info, "torque_mode": self.mode})

    def _rollout(self, grid: TimeGrid) -> Trajectory:
        model, data = self.model, self.data
        mujoco.mj_resetData(model, data)
        data.qpos[:] = self.quat0
        data.qvel[:] = self.omega0
        previous = mujoco.get_mjcb_passive()
        if self.mode == "qfrc_applied":
            data.qfrc_applied[:] = self.torque(0.0, tuple(self.quat0), tuple(self.omega0))
        else:
            mujoco.set_mjcb_passive(self._passive)  # process-global: restored below
        try:
            return self._step_all(grid)
        finally:
            if self.mode != "qfrc_applied":
                mujoco.set_mjcb_passive(previous)

    def _step_all(self, grid: TimeGrid) -> Trajectory:
        model, data, step = self.model, self.data, mujoco.mj_step
        samples = grid.sample_steps
        quat = np.full((samples.size, 4), np.nan)
        omega = np.full((samples.size, 3), np.nan)
        quat[0], omega[0] = data.qpos, data.qvel
        done = 0
        unbudgeted = budget.deadline() is None  # the timing phase's runs: plain ranges (as Integrator._run)
        for index, target in enumerate(samples[1:].tolist(), start=1):
            for piece in (range(done, target),) if unbudgeted else budget.pieces(done, target):
                for _ in piece:
                    step(model, data)
            done = target
            quat[index], omega[index] = data.qpos, data.qvel
            if not sample_good(quat[index].tolist(), omega[index].tolist(), self.limit2):
                return diverged_trajectory(grid, quat, omega, index, done * grid.dt, done, self.stages * done)
        return Trajectory(grid.times, quat, omega, Status.OK, "", math.nan, grid.steps, self.stages * grid.steps)


# The sliding ladder (harness.scenes.sliding_ladder, FORMULARY T5). Soft constraints and contacts relax on this
# time constant (s):
# the smallest MuJoCo keeps stable at the suite's steps (it clamps solref's time constant to >= 2 dt), so the
# constraint violation it leaves is as small as MuJoCo allows.
LADDER_SOLREF = 2e-3
# Capsule radius of the unilateral ladder, as a fraction of the half length: the ends' sphere centres then slide on
# the lines x = r and y = r, exactly the ideal ladder shifted by (r, r) (its dynamics unchanged).
LADDER_RADIUS = 0.01
LADDER_MODELS = ("bilateral", "unilateral")


def ladder_mjcf(ladder, model: str, integrator: str, dt: float) -> str:
    """The MJCF scene of a sliding ladder (z up: the wall is x = 0, the floor z = 0; θ turns about -y).

    bilateral: the top end slides on the wall (a slide joint, zero at height 2 l) and carries the rod on a hinge;
    the foot end is held on a floor slider by a connect equality (at qpos0 the rod hangs with its end on the foot's
    origin, which is how MuJoCo places the connect point on body2). A uniform rod is split exactly into two end point masses m/12 (on the
    two sliders, each moving along its axis only, so their rotational inertia, needed to compile, never enters)
    and a rod body of mass 5m/6 with inertia m l^2/6 about its centre: same mass, centre and m l^2/3 about G.
    unilateral: one free planar rod (slide x, slide z, hinge) whose capsule touches a wall and a floor plane through
    frictionless contacts (condim 1), which can only push.
    """
    if integrator not in INTEGRATORS:
        raise KeyError(f"unknown MuJoCo integrator {integrator!r}; valid: {', '.join(INTEGRATORS)}")
    m, l, g = float(ladder.mass), float(ladder.half_length), float(ladder.g)
    option = (f'<option timestep="{float(dt)!r}" gravity="0 0 {-g!r}" integrator="{INTEGRATORS[integrator][0]}">')
    solref = f'solref="{LADDER_SOLREF!r} 1"'
    if model == "bilateral":
        end, rod_inertia = m / 12.0, m * l * l / 6.0
        return f"""<mujoco model="ladder-bilateral">
  {option}
    <flag contact="disable" frictionloss="disable" limit="disable" damper="disable" autoreset="disable"/>
  </option>
  <worldbody>
    <body name="top" pos="0 0 {2 * l!r}">
      <joint name="top_slide" type="slide" axis="0 0 1"/>
      <inertial pos="0 0 0" mass="{end!r}" diaginertia="{end * l * l!r} {end * l * l!r} {end * l * l!r}"/>
      <body name="rod">
        <joint name="hinge" type="hinge" axis="0 -1 0"/>
        <inertial pos="0 0 {-l!r}" mass="{m - 2 * end!r}" diaginertia="{rod_inertia!r} {rod_inertia!r} {rod_inertia / 100!r}"/>
      </body>
    </body>
    <body name="foot">
      <joint name="foot_slide" type="slide" axis="1 0 0"/>
      <inertial pos="0 0 0" mass="{end!r}" diaginertia="{end * l * l!r} {end * l * l!r} {end * l * l!r}"/>
    </body>
  </worldbody>
  <equality>
    <connect body1="rod" body2="foot" anchor="0 0 {-2 * l!r}" {solref}/>
  </equality>
</mujoco>
"""
    if model == "unilateral":
        radius, inertia = LADDER_RADIUS * l, m * l * l / 3.0
        return f"""<mujoco model="ladder-unilateral">
  {option}
    <flag equality="disable" frictionloss="disable" limit="disable" damper="disable" autoreset="disable"/>
  </option>
  <worldbody>
    <geom name="floor" type="plane" size="0 0 1" condim="1" {solref}/>
    <geom name="wall" type="plane" size="0 0 1" zaxis="1 0 0" condim="1" {solref}/>
    <body name="rod">
      <joint name="x" type="slide" axis="1 0 0"/>
      <joint name="z" type="slide" axis="0 0 1"/>
      <joint name="hinge" type="hinge" axis="0 -1 0"/>
      <inertial pos="0 0 0" mass="{m!r}" diaginertia="{inertia!r} {inertia!r} {inertia / 100!r}"/>
      <geom type="capsule" fromto="0 0 {l!r} 0 0 {-l!r}" size="{radius!r}" condim="1" {solref} contype="1" conaffinity="0"/>
    </body>
  </worldbody>
</mujoco>
"""
    raise KeyError(f"unknown ladder model {model!r}; valid: {', '.join(LADDER_MODELS)}")


class LadderSimulation:
    """A sliding ladder in MuJoCo (ladder_mjcf), stepped with mj_step; records every step's horizontal velocity of
    the rod's centre, whose change over a step is the wall's push (the only horizontal force) times dt / m."""

    def __init__(self, ladder, model: str, integrator: str, dt: float):
        self.ladder, self.variant, self.dt = ladder, model, float(dt)
        self.xml = ladder_mjcf(ladder, model, integrator, dt)
        self.model = mujoco.MjModel.from_xml_string(self.xml)
        self.data = mujoco.MjData(self.model)
        self.stages = INTEGRATORS[integrator][1]

    def _start(self) -> None:
        mujoco.mj_resetData(self.model, self.data)
        l, theta, rate = self.ladder.half_length, self.ladder.theta0, self.ladder.theta_dot0
        qpos, qvel = self.data.qpos, self.data.qvel
        if self.variant == "bilateral":  # top_slide, hinge, foot_slide
            qpos[:] = (2 * l * (math.cos(theta) - 1.0), theta, 2 * l * math.sin(theta))
            qvel[:] = (-2 * l * math.sin(theta) * rate, rate, 2 * l * math.cos(theta) * rate)
        else:  # x, z, hinge of the centre, on the axes shifted by the capsule radius
            r = LADDER_RADIUS * l
            qpos[:] = (r + l * math.sin(theta), r + l * math.cos(theta), theta)
            qvel[:] = (l * math.cos(theta) * rate, -l * math.sin(theta) * rate, rate)

    def _planar(self) -> tuple[list[float], float]:
        """(x, y, θ, ẋ, ẏ, θ̇) in the ideal ladder's axes, and the constraint violation (m)."""
        l, qpos, qvel = self.ladder.half_length, self.data.qpos, self.data.qvel
        if self.variant == "bilateral":
            z_top, theta, x_foot = qpos
            z_top += 2 * l
            dz_top, rate, _ = qvel
            s, c = math.sin(theta), math.cos(theta)
            state = [l * s, z_top - l * c, theta, l * c * rate, dz_top + l * s * rate, rate]
            foot = (2 * l * s - x_foot, z_top - 2 * l * c)  # the rod's end against the floor slider's point
            return state, math.hypot(*foot)
        r = LADDER_RADIUS * l
        x, z, theta = qpos
        s, c = math.sin(theta), math.cos(theta)
        state = [x - r, z - r, theta, qvel[0], qvel[1], qvel[2]]
        penetration = max(0.0, -(state[0] - l * s), -(state[1] - l * c))  # top inside the wall, foot in the floor
        return state, penetration

    def run(self, grid: TimeGrid) -> SlidingLadderTrajectory:
        if grid.dt != self.dt:
            raise ValueError(f"grid dt {grid.dt} differs from the prepared dt {self.dt}")
        self._start()
        samples = grid.sample_steps
        state = np.full((samples.size, 6), np.nan)
        violation = np.full(samples.size, np.nan)
        speed = np.empty(grid.steps + 1)  # ẋ of the centre after each step
        angle = np.empty(grid.steps + 1)
        first, violation[0] = self._planar()
        state[0], speed[0], angle[0] = first, first[3], first[2]
        worst, sample = violation[0], 1
        model, data, step = self.model, self.data, mujoco.mj_step
        for index in (index for piece in budget.pieces(1, grid.steps + 1) for index in piece):
            step(model, data)
            current, off = self._planar()
            speed[index], angle[index] = current[3], current[2]
            worst = max(worst, off)
            if sample < samples.size and samples[sample] == index:
                state[sample], violation[sample] = current, worst
                worst, sample = 0.0, sample + 1
            if not math.isfinite(current[2] + current[5]):
                return SlidingLadderTrajectory(grid.times, state, violation, Status.DIVERGED,
                                        f"state not finite at t = {index * grid.dt:.6g} s", index * grid.dt, index)
        return SlidingLadderTrajectory(grid.times, state, violation, Status.OK, "", math.nan, grid.steps,
                                self._detachment(speed, angle))

    def _detachment(self, speed: np.ndarray, angle: np.ndarray) -> float:
        """θ where the wall's push (∝ Δẋ per step, placed at the step's mid-angle) reaches zero for good: the zero of
        the line through the last two steps that pushed (the soft contact's push rings at first, so the first sign
        change is not the detachment; once the top is off the wall no horizontal force acts and Δẋ is exactly 0).
        NaN for the bilateral model (its wall also pulls) or when the top never leaves the wall."""
        if self.variant != "unilateral":
            return math.nan
        push = np.diff(speed)
        middle = 0.5 * (angle[1:] + angle[:-1])
        pushing = np.flatnonzero(push > 0.0)
        if pushing.size < 2 or pushing[-1] == push.size - 1:
            return math.nan
        j = int(pushing[-1])
        f0, f1 = push[j - 1], push[j]
        return float(middle[j] + (middle[j] - middle[j - 1]) * f1 / (f0 - f1))


# Declared orders of MuJoCo's integrators (ENGINES.md: its Euler is semi-implicit, implicit/implicitfast are first
# order, RK4 on a ball joint is RKMK, 4th order in MuJoCo 4; discrete is the implicit velocity update in the metric
# M + hD + h^2 K, which on this scene, without damping, stiffness or constraints, is Euler's update: first order).
ORDERS = {"euler": 1, "implicit": 1, "implicitfast": 1, "rk4": 4, "discrete": 1}
# What each integrator is (harness.engines.methods): Euler updates the velocity first; implicitfast and discrete on a
# ball joint are the same update (implicitfast's gyroscopic treatment is for free bodies, discrete's metric adds only
# damping and stiffness: both bit-identical to Euler here, ENGINES.md); implicit is MuJoCo's own.
METHODS = {"euler": "semi_implicit_euler", "implicitfast": "semi_implicit_euler", "discrete": "semi_implicit_euler",
           "rk4": "rk4"}
DEFAULT_MJCF_INTEGRATOR = "rk4"


class MujocoRigidBody(RigidBodyModel):
    """The rigid body in MuJoCo C: its torque entered as qfrc_applied or through mjcb_passive; exported as MJCF."""

    def torque_mode(self, case: Case) -> str:
        return torque_mode(case)

    def export(self, case: Case, fmt: str, integrator: str | None, dt: float | None) -> str:
        """MJCF: the scene with an integrator (default rk4) and a timestep (default the case's first dt)."""
        if unphysical_inertia(case):
            raise ValueError(f"{case.name}: {unphysical_inertia(case)}")
        return mjcf(case, integrator or DEFAULT_MJCF_INTEGRATOR, case.dt[0] if dt is None else dt)


class MujocoEngine(Engine):
    name = "mujoco"
    # measured on the suite's four general cases (2-core AMD EPYC): 1.2-1.9 µs per stage per step
    timing = Timing(pass_us=1.5)
    about = About(packages=("mujoco",), linestyle="-", export_formats=("mjcf",))

    def offer(self, integrator: str) -> Offer:
        return Offer(order=float(ORDERS.get(integrator, math.nan)), method=METHODS.get(integrator, ""),
                     unmodelled=not_modelled(integrator))

    def integrators(self) -> tuple[str, ...]:
        return integrator_names()

    def unsupported(self, case: Case) -> str | None:
        return _unsupported(case)

    def prepare(self, case: Case, integrator: str, dt: float) -> MujocoSimulation:
        reason = _unsupported(case)
        if reason:
            raise ValueError(f"{case.name}: {reason}")
        if case.body.has_external_torque:
            return TorqueSimulation(case, integrator, dt)
        return MujocoSimulation(case, integrator, dt)

    def models(self) -> dict:
        return {**super().models(), RIGID_BODY: MujocoRigidBody(self), SLIDING_LADDER: LadderModel()}


class LadderModel(SceneModel):
    """The sliding ladder (harness.scenes.sliding_ladder) as planar rods: rows name the model (bilateral,
    unilateral) in the formulation column."""

    def variants(self) -> tuple[str, ...]:
        return LADDER_MODELS

    def export(self, case, fmt: str, integrator: str | None, dt: float | None) -> str:
        raise ValueError(f"{case.name}: the sliding ladder has two MuJoCo models (bilateral, unilateral): "
                         "ladder_mjcf(case.ladder, model, integrator, dt) writes either")

    def prepare(self, case, variant: str, integrator: str, dt: float | None,
                tolerance: float | None = None) -> LadderSimulation:
        return LadderSimulation(case.ladder, variant, integrator, dt)
