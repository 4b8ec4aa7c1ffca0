"""MJX adapter: MuJoCo's JAX back-end (`mujoco-mjx`, the optional extra `stereodyn[mjx]`), in float64 or float32.

The model is MuJoCo's own scene of the case (harness.engines.mujoco.scene: one body on a ball joint at O), put on
the device with mjx.put_model. qpos is the quaternion (w, x, y, z) body -> world, qvel the body angular velocity, as
in MuJoCo C. A run is one jitted function of (model, data, steps per sample interval, how many intervals): a loop over
the sample intervals, each a lax.fori_loop of mjx.step, into SLOTS rows, so the whole rollout is compiled once per
integrator, precision and model structure in a process, whatever the grid, and every case reuses it (the model is an
argument, not a constant). Under a wall-time budget (the sweep's accuracy runs) the rollout goes CHUNK sample
intervals a call, the budget checked between calls (the same numbers, bit for bit). prepare() compiles (never
timed); run() waits for the result (jax.block_until_ready) before it returns. jax and mujoco.mjx are imported on
the first prepare.

Precision: JAX's `jax_enable_x64` is a process-wide flag whose value at trace time fixes every dtype, so each run
traces, compiles and calls its function inside `jax.enable_x64(precision == "float64")`: float32 and float64 runs
coexist in one worker, each compiled under its own setting (jit caches the two apart).

Torques: a constant body torque enters through qfrc_applied, set once (MJX keeps it through every RK4 stage); a torque
that depends on the state or the time needs a per-stage callback, which MJX lacks: such cases are absent from a
default sweep and `skipped` with the reason when named.
"""
from __future__ import annotations

import functools
import json
import math
import os
import time
from types import SimpleNamespace

import numpy as np

from .. import install

INSTALL = install.hint("mjx")  # a checkout's or a distribution's form

# One XLA thread per worker: `--jobs N` then means N busy cores for this engine as for every other (the timing
# contract, docs/ENGINES.md). XLA reads the flags when its CPU backend starts, so they are set before jax is imported;
# flags a user set already are kept.
_XLA_THREADS = "--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1"
if "xla_cpu_multi_thread_eigen" not in os.environ.get("XLA_FLAGS", ""):
    os.environ["XLA_FLAGS"] = f"{os.environ.get('XLA_FLAGS', '')} {_XLA_THREADS}".strip()
from .base import FLOAT32, FLOAT64, About, KnownDeviation, Timing, require_modules

# jax and mujoco.mjx are imported on the first prepare (_sdk: 2-8 s); loading the adapter only checks them
require_modules(INSTALL, "jax", "mujoco.mjx")

from .. import budget
from ..environment import user_cache
from ..scenes.cases import Case
from .backends import MujocoBackend
from .mujoco import scene_state, torque_mode
from ..grid import TimeGrid
from ..trajectory import Status, Trajectory, divergence_message, first_bad_sample

# harness name (MuJoCo's, lower case) -> dynamics evaluations per step. MJX has no `implicit` integrator.
INTEGRATORS: dict[str, int] = {"euler": 1, "rk4": 4, "implicitfast": 1}
# The orders MuJoCo documents (the same as MuJoCo C's, harness.engines.mujoco.ORDERS): what the fit compares against.
ORDERS = {"euler": 1.0, "rk4": 4.0, "implicitfast": 1.0}
# What each integrator is (harness.engines.methods): MuJoCo's Euler updates the velocity first; implicitfast on a ball
# joint is the same update (its gyroscopic treatment is for free bodies).
METHODS = {"euler": "semi_implicit_euler", "rk4": "rk4", "implicitfast": "semi_implicit_euler"}
# implicitfast equals euler on a ball joint (measured: bit for bit against MuJoCo C euler): a second row of the same
# numbers, left to --integrators.
DEFAULT_SWEEP = ("euler", "rk4")
# MJX 3.17's RK4 integrates the ball joint's quaternion as MuJoCo 3.x's did (stages combined by quaternion
# integration, not Runge-Kutta-Munthe-Kaas): 2nd order on the attitude. MuJoCo C 4.0 made it 4th order (RKMK,
# FORMULARY H2). Measured here: MJX rk4 reproduces MuJoCo C 3.17 bit for bit and differs from C 4.0 by 1e-4 .. 2e-3
# in state (docs/ENGINES.md).
RK4_DEVIATION = KnownDeviation(
    integrator="rk4", quantity="order", expected=2.0, tolerance=0.3,
    reference="MJX 3.17 RK4 on ball/free joints is MuJoCo 3.x's (quaternion stages, 2nd order); MuJoCo 4.0.0 "
              "changelog: RK4 on quaternions is Runge-Kutta-Munthe-Kaas (4th order); no mujoco-mjx 4.x release yet")


# Every case's model has this name: names are static fields of an MJX model, so a name per case would compile the
# rollout again for each case. MuJoCo compiles a body whose inertia is diagonal about its origin as a "simple" one
# (another static structure): two compilations per integrator and precision cover the suite.
MODEL_NAME = "stereodyn"
# The default sweep's cases: the four general ones (stepping.DEFAULT_CASES). Each run costs 15-60 µs a step, and a
# compilation 5-30 s per integrator, precision and model structure in each worker; the rest run with --engines mjx.


def _constant_torque_only(case: Case) -> str | None:
    """Why MJX cannot apply the case's torque exactly (None where it can)."""
    mode = torque_mode(case)
    if mode in ("none", "qfrc_applied"):
        return None
    return ("mjx: the case's torque depends on the state or the time and must be evaluated at every Runge-Kutta "
            "stage; MJX has no per-stage callback (mjcb_passive), and setting qfrc_applied once per step would make "
            "rk4 first order")


def compiled_model(case: Case, integrator: str, dt: float) -> tuple:
    """(MjModel, MjData at the initial state) of MuJoCo's scene of the case, with what MJX cannot run switched off
    (the energy flag): harness.engines.mujoco.scene_state."""
    if integrator not in INTEGRATORS:
        raise KeyError(f"unknown MJX integrator {integrator!r}; valid: {', '.join(INTEGRATORS)}")
    return scene_state(case, integrator, dt, MODEL_NAME, energy=False)


# This process's start-up as it happens (issue 29: one start-up per worker): SDK imports and rollout compilations,
# counted inside the code paths that do them (_sdk's body, _compiled's miss), not read off the caches. startups()
# returns them; where the environment names a file (STARTUP_LOG_ENV, inherited by the pool's spawned workers), each
# one also appends a JSON line there: {"pid", "event": "import" | "compilation", "key", "seconds"}, so a test or a
# user can count them per worker process (tests/test_mjx.py).
STARTUP_LOG_ENV = "STEREODYN_MJX_STARTUP_LOG"
_IMPORTS: list[int] = [0]
_COMPILATIONS: dict[tuple, int] = {}  # (precision, integrator, structure number) -> compilations
_STRUCTURES: list = []  # the pytree structures this process compiled for, in order: a structure's number (the
# structure's text holds object addresses, so it names nothing across processes; its number is this process's)


def startups() -> dict:
    """What this process has paid for MJX so far: {"imports": times the SDK was imported (jax, mujoco.mjx and the
    rollout's definition: 1 after the first prepare, 0 before), "compilations": {(precision, integrator, structure
    number): times that rollout was traced and compiled}}. The structure number is the order in
    which this process first compiled for a model structure (one serves every case that shares it)."""
    return {"imports": _IMPORTS[0], "compilations": dict(_COMPILATIONS)}


def _record(event: str, key: tuple | None, seconds: float) -> None:
    """Count an import or a compilation (startups), and append it to the file STARTUP_LOG_ENV names, if any: one
    line written at once (O_APPEND), so the workers of a pool can share the file."""
    if key is None:
        _IMPORTS[0] += 1
    else:
        _COMPILATIONS[key] = _COMPILATIONS.get(key, 0) + 1
    path = os.environ.get(STARTUP_LOG_ENV)
    if path:
        line = json.dumps({"pid": os.getpid(), "event": event, "key": None if key is None else list(key),
                           "seconds": round(seconds, 3)}) + "\n"
        fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
        try:
            os.write(fd, line.encode())
        finally:
            os.close(fd)


@functools.cache
def _sdk() -> SimpleNamespace:
    """jax, jax.numpy, mujoco.mjx and the jitted rollout, imported on the first prepare. Compiled rollouts persist on
    disk (JAX's compilation cache), so a worker loads what another one, or an earlier run, compiled (5-30 s each, one
    per integrator, precision and model structure) instead of compiling it again; a cache the user chose
    (JAX_COMPILATION_CACHE_DIR) is kept."""
    started = time.perf_counter()
    import jax
    from jax import numpy as jnp
    from mujoco import mjx

    if not jax.config.jax_compilation_cache_dir:
        jax.config.update("jax_compilation_cache_dir", str(user_cache("jax")))

    @jax.jit
    def rollout(model, data, counts, intervals):
        """The states after each of the first `intervals` sample intervals, and the last: counts (SLOTS,) int32
        steps per interval, intervals int32 <= SLOTS -> (data, (qpos (SLOTS, 4), qvel (SLOTS, 3))), the rows past
        `intervals` zero. A loop of `intervals` turns, not a scan over the SLOTS: a slot past them costs nothing."""
        def interval(i, carry):
            state, qpos, qvel = carry
            state = jax.lax.fori_loop(0, counts[i], lambda _, d: mjx.step(model, d), state)
            return state, qpos.at[i].set(state.qpos), qvel.at[i].set(state.qvel)

        rows = (jnp.zeros((counts.size, data.qpos.size), data.qpos.dtype),
                jnp.zeros((counts.size, data.qvel.size), data.qvel.dtype))
        data, qpos, qvel = jax.lax.fori_loop(0, intervals, interval, (data, *rows))
        return data, (qpos, qvel)

    _record("import", None, time.perf_counter() - started)
    return SimpleNamespace(jax=jax, jnp=jnp, mjx=mjx, rollout=rollout)


# Compiled rollouts of this process: (precision, integrator, pytree structure of (model, data)) -> jax's Compiled.
# The structure holds a model's static fields, so one entry serves every case that shares them.
_COMPILED: dict[tuple, object] = {}
# The precision of the last trace: switching it clears jax's caches first. jax 0.10 caches the trace of a jitted
# helper (jnp.tril, called by MJX's rungekutta4 on its float64 numpy tableau) across jax_enable_x64 settings, so rk4
# traced in one precision after the other fails to lower ("func.call op operand type mismatch: expected
# tensor<3x3xf32>, provided tensor<3x3xf64>"), in either order (tests/test_mjx.py). The Compiled objects above are
# kept: clearing jax's caches does not touch them.
_last_traced: list[str] = []
# The rollout's rows: every grid shares its shape, so one compilation per integrator, precision and structure serves
# every grid, every chunk and every case of that structure in a process. A rollout compiled per grid shape (as before
# issue 29) compiled 3 per structure in the quick suite (its two grids and the chunk): 36 compilations, 196 s of a
# worker with JAX's cache warm. 1024 holds a suite case's grid (at most 1000 intervals) in one call; a longer grid
# goes SLOTS intervals a call. A call costs ~0.3 ms of dispatch (MJX's data is a large pytree), so the timed runs,
# which have no budget, go in as few calls as that allows.
SLOTS = 1024
# Under a wall-time budget (the sweep's accuracy runs) a run is CHUNK sample intervals per call, the budget checked
# between calls: one compiled call cannot be stopped inside.
CHUNK = 64


def _compiled(precision: str, integrator: str, model, data):
    """The Compiled rollout (SLOTS rows): from this process's cache, else traced and compiled (under the precision's
    jax_enable_x64, already entered by the caller)."""
    sdk = _sdk()
    structure = sdk.jax.tree_util.tree_structure((model, data))
    key = (precision, integrator, structure)
    if key not in _COMPILED:
        if _last_traced and _last_traced[-1] != precision:
            sdk.jax.clear_caches()
        _last_traced[:] = [precision]
        started = time.perf_counter()
        _COMPILED[key] = sdk.rollout.lower(model, data, np.zeros(SLOTS, np.int32), np.int32(0)).compile()
        if structure not in _STRUCTURES:
            _STRUCTURES.append(structure)
        _record("compilation", (precision, integrator, _STRUCTURES.index(structure)), time.perf_counter() - started)
    return _COMPILED[key]


class MjxSimulation:
    """A case's scene on MJX with one integrator, dt and precision, compiled in the constructor; run() starts from the
    case's initial state every time (the jitted function is pure)."""

    def __init__(self, case: Case, integrator: str, dt: float, precision: str):
        self.case, self.integrator, self.dt, self.precision = case, integrator, float(dt), precision
        self.x64 = precision == FLOAT64
        self.stages = INTEGRATORS[integrator]
        self.torque_mode = torque_mode(case)
        model, data = compiled_model(case, integrator, dt)
        sdk = _sdk()
        with sdk.jax.enable_x64(self.x64):
            self.model = sdk.mjx.put_model(model)
            self.data = sdk.mjx.put_data(model, data)
            # compile now (not timed) the rollout every run uses: compiled on a timed run, the worker's single time
            # (timing.timed_once) held the compilation (measured 1.5-26 s against runs of milliseconds)
            _compiled(precision, integrator, self.model, self.data)

    def run(self, grid: TimeGrid) -> Trajectory:
        if grid.dt != self.dt:
            raise ValueError(f"grid dt {grid.dt} differs from the prepared dt {self.dt}")
        sdk = _sdk()
        counts = np.diff(grid.sample_steps).astype(np.int32)
        budgeted = budget.deadline() is not None  # then CHUNK intervals a call, the budget checked between calls
        per_call = CHUNK if budgeted else SLOTS
        with sdk.jax.enable_x64(self.x64):  # the function is called under the setting it was compiled with
            rollout = _compiled(self.precision, self.integrator, self.model, self.data)
            data, parts = self.data, []
            for start in range(0, max(counts.size, 1), per_call):  # one call even for an empty grid
                part = counts[start:start + per_call]
                slots = np.zeros(SLOTS, np.int32)
                slots[:part.size] = part
                data, states = rollout(self.model, data, slots, np.int32(part.size))
                q, v = sdk.jax.block_until_ready(states)
                parts.append((np.asarray(q)[:part.size], np.asarray(v)[:part.size]))
                if budgeted:
                    budget.check()
            qpos = np.concatenate([q for q, _ in parts])
            qvel = np.concatenate([v for _, v in parts])
        quat = np.empty((grid.times.size, 4))
        omega = np.empty((grid.times.size, 3))
        # the initial state as the device holds it (float32 rounds it: part of that precision's error)
        quat[0], omega[0] = np.asarray(self.data.qpos, dtype=float), np.asarray(self.data.qvel, dtype=float)
        quat[1:], omega[1:] = np.asarray(qpos, dtype=float), np.asarray(qvel, dtype=float)
        status, message, diverged_at = Status.OK, "", math.nan
        bad = first_bad_sample(omega, quat, self.case.omega0)
        if bad is not None:
            diverged_at = float(grid.times[bad])
            status, message = Status.DIVERGED, divergence_message(diverged_at)
            quat[bad:], omega[bad:] = np.nan, np.nan
        steps = grid.steps if bad is None else int(grid.sample_steps[bad])
        return Trajectory(grid.times, quat, omega, status, message, diverged_at, steps, self.stages * steps,
                          info={"torque_mode": self.torque_mode})


class MjxEngine(MujocoBackend):
    """MuJoCo's JAX back-end (MJX 3.17) on the CPU: euler, rk4, implicitfast, each in float64 and float32."""

    name = "mjx"
    # The installed MJX offers discrete (MuJoCo 3.13's constraint solve and velocity update in one operation); not
    # yet run and measured on this back-end, so said rather than run (tests/test_engine_sdk.py)
    not_modelled = {"discrete": "MJX's discrete is not yet run and measured by stereodyn (MuJoCo's own is)"}
    # measured on the loaded 2-core machine: 12-30 µs per euler step, 40-60 µs per rk4 step (docs/ENGINES.md).
    # startup_s, measured on the project's 2-core machine under load 3-4 (another test run beside it), nice 19: the
    # first prepare in a fresh process (heavy-asymmetric float64, dt 0.01, under a budget as a sweep's worker prepares
    # it: SDK import 0.9-1.3 s, then the grid's and the chunk's rollouts) took 14 s (euler) and 26 s (rk4) with JAX's
    # persistent cache cold, 4 s and 6 s warm (compiling the chunk's alone, before prepare compiled both: 7-14 s cold,
    # 3 s warm). A worker then pays a compilation per integrator, precision and model structure it meets
    # (startups()): 4 in a sweep of two cases of one structure, euler and rk4, both precisions (tests/test_mjx.py);
    # a second worker mostly finds the first's compilations in JAX's cache. A worker's compilations in all: 35-48 s
    # cold in the quick suite with every extra (12 rollouts; 2 idle cores, 2026-11-27), 10-16 s warm. 20 s sits
    # between: more than Warp's, as measured cold and warm, so the sweep queues MJX's runs before Warp's
    # (pool.queue_key), and a second worker takes MJX's runs only when their queued cost outweighs it
    # (harness.run.workers).
    timing = Timing(pass_us=15.0, startup_s=20.0)
    about = About(packages=("mujoco-mjx", "jax", "jaxlib", "mujoco"), linestyle=(0, (3, 1, 1, 1)))
    stages, orders, methods, default_sweep = INTEGRATORS, ORDERS, METHODS, DEFAULT_SWEEP
    sdk_enum = ("mujoco.mjx._src.types", "IntegratorType")  # its integrators, read from the installed SDK (offered.py)
    run_precisions, deviations = (FLOAT64, FLOAT32), {"rk4": RK4_DEVIATION}
    torque_refusal = staticmethod(_constant_torque_only)

    def prepare(self, case: Case, integrator: str, dt: float, precision: str = FLOAT64) -> MjxSimulation:
        if integrator not in INTEGRATORS:
            raise KeyError(f"unknown integrator {integrator!r} for the MJX engine; valid: {', '.join(INTEGRATORS)}")
        if precision not in (FLOAT64, FLOAT32):
            raise KeyError(f"unknown precision {precision!r} for the MJX engine; valid: {FLOAT64}, {FLOAT32}")
        reason = self.unsupported(case) or _constant_torque_only(case)
        if reason:
            raise ValueError(f"{case.name}: {reason}")
        if dt is None or not dt > 0:
            raise ValueError(f"integrator {integrator!r} needs a step dt > 0, got {dt!r}")
        return MjxSimulation(case, integrator, dt, precision)
