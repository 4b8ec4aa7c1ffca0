"""MuJoCo Warp adapter: MuJoCo's Warp back-end (`mujoco-warp`, the optional extra `stereodyn[warp]`) on the CPU,
float32 (the only precision it has).

The model is MuJoCo's own scene of the case (harness.engines.mujoco.scene: one body on a ball joint at O), one world,
put on Warp's CPU device with mujoco_warp.put_model; states are read back at the sample times. qpos is the
quaternion (w, x, y, z) body -> world, qvel the body angular velocity, as in MuJoCo C.

Warp compiles its kernels on first use (~40 s on this machine kind, then cached on disk in Warp's kernel cache, ~1 s
to load in a new process): prepare() steps a scratch copy of the data once, so that compiling and loading are never
timed. Warp's CPU kernels run in the calling thread (one thread per worker, the timing contract of ENGINES.md), and
every read-back synchronises, so a run's time is the finished computation.

MuJoCo Warp has no autoreset (a diverged state stays NaN, as this harness wants): put_model refuses the flag that
disables it, so the scene's flag is cleared. Torques as in the MJX adapter: a constant body torque through
qfrc_applied; a torque that depends on the state or the time is not modelled (no per-stage callback).
"""
from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np

from .. import install
from .base import FLOAT32, About, Timing, require_modules
from .quiet import native_output_silenced

INSTALL = install.hint("warp")  # a checkout's or a distribution's form
require_modules(INSTALL, "warp", "mujoco_warp")  # imported on the first prepare (_sdk): 5-10 s

from .. import budget
from ..scenes.cases import Case
from .backends import MujocoBackend
from .mujoco import scene_state, torque_mode
from ..grid import TimeGrid
from ..trajectory import Status, Trajectory, divergence_limit2, divergence_message, sample_good

DEVICE = "cpu"
MODEL_NAME = "stereodyn"  # one name for every case's model (as the MJX adapter's)

# harness name (MuJoCo's, lower case) -> dynamics evaluations per step
INTEGRATORS: dict[str, int] = {"euler": 1, "rk4": 4, "implicitfast": 1, "implicit": 1}
ORDERS = {"euler": 1.0, "rk4": 4.0, "implicitfast": 1.0, "implicit": 1.0}
METHODS = {"euler": "semi_implicit_euler", "rk4": "rk4", "implicitfast": "semi_implicit_euler"}
# The default sweep: euler and rk4 at one coarse step (stepping.coarse_dts) on the four general cases
# (stepping.DEFAULT_CASES; 0.03-0.1 ms a step with the captured graph, ~5 ms a step without it); every other case and
# step runs with --engines warp (and --dt).
DEFAULT_SWEEP = ("euler", "rk4")


def _constant_torque_only(case: Case) -> str | None:
    if torque_mode(case) in ("none", "qfrc_applied"):
        return None
    return ("warp: the case's torque depends on the state or the time and must be evaluated at every Runge-Kutta "
            "stage; MuJoCo Warp has no per-stage callback (mjcb_passive)")


def compiled_model(case: Case, integrator: str, dt: float) -> tuple:
    """(MjModel, MjData at the initial state) of MuJoCo's scene of the case, with the autoreset flag cleared (MuJoCo
    Warp has no autoreset and refuses it): harness.engines.mujoco.scene_state."""
    if integrator not in INTEGRATORS:
        raise KeyError(f"unknown MuJoCo Warp integrator {integrator!r}; valid: {', '.join(INTEGRATORS)}")
    return scene_state(case, integrator, dt, MODEL_NAME, autoreset=False)


@functools.cache
def _sdk():
    """(warp, mujoco_warp), imported; Warp quiet: no banner, no line per kernel module on stdout (set before
    mujoco_warp loads its modules)."""
    import warp as wp

    wp.config.quiet = True
    wp.config.log_level = wp.LOG_WARNING
    with native_output_silenced():  # without a GPU, Warp's C code prints a CUDA-driver warning to fd 2 at init
        wp.init()
    import mujoco_warp as mjw

    return wp, mjw


def _arrays(data) -> list:
    """Every Warp array of a MuJoCo Warp Data (nested dataclasses included), in field order."""
    wp, found = _sdk()[0], []
    for field in dataclasses.fields(data):
        value = getattr(data, field.name)
        if isinstance(value, wp.array):
            found.append(value)
        elif dataclasses.is_dataclass(value) and not isinstance(value, type):
            found.extend(_arrays(value))
    return found


class WarpSimulation:
    """A case's scene on MuJoCo Warp (one world, CPU, float32) with one integrator and dt; run() starts from the
    case's initial state every time.

    A step launches ~80 kernels from Python, which costs ~5 ms a step on the CPU; Warp's graph capture (CPU capture,
    Warp >= 1.19) records them once and replays them natively at ~0.03 ms a step with bit-identical results
    (tests/test_warp.py compares the two). prepare captures two graphs on one device Data: a step, and the reset of
    every array of that Data from a pristine copy (the initial state)."""

    def __init__(self, case: Case, integrator: str, dt: float):
        wp, mjw = _sdk()
        self.case, self.dt, self.stages = case, float(dt), INTEGRATORS[integrator]
        self.torque_mode = torque_mode(case)
        mj_model, mj_data = compiled_model(case, integrator, dt)
        self.limit2 = divergence_limit2(case.omega0)
        with wp.ScopedDevice(DEVICE):
            self.model = mjw.put_model(mj_model)
            mjw.step(self.model, mjw.put_data(mj_model, mj_data))  # compile or load the kernels, on a scratch copy
            self.initial = mjw.put_data(mj_model, mj_data)
            self.data = mjw.put_data(mj_model, mj_data)
            with wp.ScopedCapture() as capture:
                mjw.step(self.model, self.data)
            self.step_graph = capture.graph
            with wp.ScopedCapture() as capture:
                for target, source in zip(_arrays(self.data), _arrays(self.initial)):
                    wp.copy(target, source)
            self.reset_graph = capture.graph
            wp.synchronize()

    def run(self, grid: TimeGrid) -> Trajectory:
        if grid.dt != self.dt:
            raise ValueError(f"grid dt {grid.dt} differs from the prepared dt {self.dt}")
        samples = grid.sample_steps
        quat = np.full((samples.size, 4), np.nan)
        omega = np.full((samples.size, 3), np.nan)
        wp = _sdk()[0]
        launch, step, qpos, qvel = wp.capture_launch, self.step_graph, self.data.qpos, self.data.qvel
        with wp.ScopedDevice(DEVICE):
            launch(self.reset_graph)
            quat[0], omega[0] = qpos.numpy()[0], qvel.numpy()[0]  # as float32 holds them
            done = 0
            for index, target in enumerate(samples[1:].tolist(), start=1):
                for piece in budget.pieces(done, target):  # the run's wall-time budget
                    for _ in piece:
                        launch(step)
                done = target
                quat[index], omega[index] = qpos.numpy()[0], qvel.numpy()[0]  # a read-back synchronises
                if not sample_good(quat[index].tolist(), omega[index].tolist(), self.limit2):
                    diverged_at = float(grid.times[index])
                    quat[index:], omega[index:] = np.nan, np.nan
                    return Trajectory(grid.times, quat, omega, Status.DIVERGED, divergence_message(diverged_at),
                                      diverged_at, done, self.stages * done, info={"torque_mode": self.torque_mode})
        return Trajectory(grid.times, quat, omega, Status.OK, "", math.nan, grid.steps, self.stages * grid.steps,
                          info={"torque_mode": self.torque_mode})


class WarpEngine(MujocoBackend):
    """MuJoCo Warp 4.0 on the CPU, one world, float32: euler, rk4, implicitfast, implicit."""

    name = "warp"
    # The installed MuJoCo Warp offers discrete (MuJoCo 3.13's constraint solve and velocity update in one operation); not
    # yet run and measured on this back-end, so said rather than run (tests/test_engine_sdk.py)
    not_modelled = {"discrete": "MuJoCo Warp's discrete is not yet run and measured by stereodyn (MuJoCo's own is)"}
    # measured in the quick suite on the 2-core machine (issue 29): 39 µs a euler step, 80 rk4, read-backs included
    # (the graph-captured step; 4.7 ms was the launched one, docs/ENGINES.md). startup_s: a fresh process's first
    # prepare took 35 s with Warp's kernel cache cold and 2.7-5 s warm; a worker's Warp runs in the quick suite with
    # every extra took 18-25 s in all cold, 2-3 s warm (2 idle cores, 2026-11-27): 12 s between, under MJX's.
    timing = Timing(pass_us=40.0, startup_s=12.0)
    about = About(packages=("mujoco-warp", "warp-lang", "mujoco"), linestyle=(0, (1, 1)))
    stages, orders, methods, default_sweep = INTEGRATORS, ORDERS, METHODS, DEFAULT_SWEEP
    sdk_enum = ("mujoco_warp._src.types", "IntegratorType")  # its integrators, read from the installed SDK (offered.py)
    run_precisions, coarse_default_step = (FLOAT32,), True
    torque_refusal = staticmethod(_constant_torque_only)

    def prepare(self, case: Case, integrator: str, dt: float, precision: str = FLOAT32) -> WarpSimulation:
        if integrator not in INTEGRATORS:
            raise KeyError(f"unknown integrator {integrator!r} for the MuJoCo Warp engine; "
                           f"valid: {', '.join(INTEGRATORS)}")
        if precision != FLOAT32:
            raise KeyError(f"MuJoCo Warp runs in {FLOAT32} only, not {precision!r}")
        reason = self.unsupported(case) or _constant_torque_only(case)
        if reason:
            raise ValueError(f"{case.name}: {reason}")
        if dt is None or not dt > 0:
            raise ValueError(f"integrator {integrator!r} needs a step dt > 0, got {dt!r}")
        return WarpSimulation(case, integrator, dt)
