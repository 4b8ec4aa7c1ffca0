"""Genesis adapter: the body as an MJCF entity in a Genesis scene on the CPU backend, stepped by Genesis's rigid
solver (the optional extra `stereodyn[genesis]`, which needs torch; without them the engine's rows are skipped naming
the install command).

Two models, named in the formulation column:
* `ball`: one body on a ball joint at O, gravity g d. qpos is the quaternion (w, x, y, z) body -> world and the dofs'
  velocity the angular velocity in body components, as MuJoCo's.
* `free`: a free joint (qpos = position, quaternion; dofs = linear velocity, body angular velocity) for a body whose
  centre of mass is O: the pin's reaction then cancels the weight, so the model has no gravity; other cases skip it.
  Genesis's implicitfast treats a free body's gyroscopic term implicitly (it keeps the energy to round-off), unlike
  MuJoCo's; on the ball joint implicitfast is Euler.

Integrators under Genesis's names (gs.integrator): `euler` (semi-implicit: velocity first), `implicitfast`,
`approximate_implicitfast` (Genesis's default). Precision: float64 and float32 (gs.init(precision=...)). Genesis's
precision is process-global: gs.init once per process. A model of the other precision re-initialises Genesis
(gs.destroy, gs.init), which releases every model built before: such a model's run() raises (never a wrong number).
The engine says so (process_global_precision): the timing phases prepare and time its runs one precision at a time. The MJCF is loaded with align=False, which keeps the body frame as written (a probe with
the default align=True saw a wrong initial energy; with this MJCF 1.4.5 gave the same states either way, measured).

External torques (reference.torques) are evaluated in Python at the start of every step from the step's time and
state and set as the dofs' control force (torque_mode `step`: exact for the one-stage Euler; the implicit
integrators see it as a constant over the step). Model building and the first step, which compiles the step's kernels,
happen in prepare (not timed): a first build compiles for minutes, later ones load the kernel cache; the engine's
prepare budget is longer than the sweep's default (prepare_budget_s).
"""
from __future__ import annotations

import math
import os
import tempfile
from xml.sax.saxutils import quoteattr

import numpy as np

from .. import install
from .base import FLOAT32, FLOAT64, RIGID_BODY, About, Engine, Offer, Timing, singular_torque, require_modules

INSTALL = install.hint("genesis")  # a checkout's or a distribution's form
# Genesis does not declare torch; importing it costs 15-30 s, so the SDK is imported on the first prepare and only
# its presence is checked here.
require_modules(f"{INSTALL} (Genesis also needs torch: the CPU wheel is enough)", "genesis", "torch")

from ..scenes.cases import Case, unphysical_inertia
from .stepping import SteppedRigidBody, run_steps
from ..grid import TimeGrid
from ..trajectory import Trajectory
from ...reference.torques import torque_function

BALL, FREE = "ball", "free"
MODELS = (BALL, FREE)
INTEGRATORS = ("euler", "implicitfast", "approximate_implicitfast")
# their gs.integrator members
_MEMBERS = {"euler": "Euler", "implicitfast": "implicitfast", "approximate_implicitfast": "approximate_implicitfast"}
PRECISIONS = (FLOAT64, FLOAT32)
# What each integrator is on the ball joint (harness.engines.methods): the same semi-implicit Euler as MuJoCo's euler
# (measured: 1e-15 apart over 200 steps); on the free body implicitfast is Genesis's own.
METHODS = {"euler": "semi_implicit_euler"}
# The integrators that step a standalone free body by the implicit midpoint rule (Genesis PR #3074), order 2 there
MIDPOINT_ON_FREE = ("implicitfast", "approximate_implicitfast")
# The default sweep: the general cases at their coarsest dt (each step costs 0.3-0.6 ms from Python; a build 0.5-20 s
# from the kernel cache), Genesis's default integrator and euler, both precisions; the rest with --engines genesis.
DEFAULT_SWEEP = ("euler", "approximate_implicitfast")
# A torque no dof limit may clamp (Genesis's default dofs force range is finite).
NO_LIMIT = 1e30

_context = {"precision": None, "generation": 0}
# The files of the frames that apply Quadrants' module-level kernel decorators while Genesis imports (below)
IMPORT_FRAME_FILES = ("<frozen importlib._bootstrap>", "<frozen importlib._bootstrap_external>")


def spare_import_scans() -> None:
    """Tell inspect at once that no module holds importlib's frozen frames (its answer all along), before Genesis
    imports.

    Quadrants (Genesis's kernel language) reads the source line of the frame that applied each of its ~2,900
    decorators; at module level that frame is importlib's, a file inspect.getmodule cannot map, so each call walks the
    whole of sys.modules, and answers None. In a worker that holds JAX and MuJoCo (~1,600 modules) this was 24 of
    Genesis's 32 s of import and init; seeded, 9.5 s (genesis-world 1.4.5, 2 cores, measured; issue 29). Quadrants
    PR #804 (open) drops the scan upstream.
    """
    import inspect

    for file in IMPORT_FRAME_FILES:  # a name no module has: getmodule's sys.modules.get(...) is None, as the scan's
        inspect.modulesbyfile.setdefault(file, file)


def _genesis(precision: str):
    """The genesis module initialised on the CPU at this precision (re-initialised when it was at the other)."""
    spare_import_scans()
    import genesis as gs

    if _context["precision"] != precision:
        if _context["precision"] is not None:
            gs.destroy()
        gs.init(backend=gs.cpu, precision="64" if precision == FLOAT64 else "32", logging_level="error")
        _context["precision"] = precision
        _context["generation"] += 1
    return gs


def _numbers(values) -> str:
    return " ".join(repr(float(x)) for x in values)


def mjcf(case: Case, model: str) -> str:
    """The case's body in MJCF: inertia about the centre of mass (fullinertia), on a ball joint at the world origin
    (gravity g d) or a free joint (O is the centre of mass: no gravity)."""
    body = case.body
    inertia = np.asarray(body.inertia_com, dtype=float)
    full = (inertia[0, 0], inertia[1, 1], inertia[2, 2], inertia[0, 1], inertia[0, 2], inertia[1, 2])
    gravity = body.gravity * np.asarray(body.gravity_direction, dtype=float) if model == BALL else np.zeros(3)
    joint = '<joint name="ball" type="ball" pos="0 0 0"/>' if model == BALL else '<freejoint name="free"/>'
    return f"""<mujoco model={quoteattr(case.name)}>
  <option gravity="{_numbers(gravity)}"/>
  <worldbody>
    <body name="body" pos="0 0 0">
      {joint}
      <inertial pos="{_numbers(body.com)}" mass="{float(body.mass)!r}" fullinertia="{_numbers(full)}"/>
    </body>
  </worldbody>
</mujoco>
"""


class GenesisSimulation:
    """A case's Genesis scene, built and its step compiled; run() resets it to the case's initial state."""

    def __init__(self, case: Case, model: str, integrator: str, dt: float, precision: str):
        gs = _genesis(precision)
        self.generation = _context["generation"]
        self.case, self.model, self.dt, self.precision = case, model, float(dt), precision
        body = case.body
        gravity = body.gravity * np.asarray(body.gravity_direction, dtype=float) if model == BALL else np.zeros(3)
        with tempfile.TemporaryDirectory() as folder:
            path = os.path.join(folder, "body.xml")
            with open(path, "w") as handle:
                handle.write(mjcf(case, model))
            self.scene = gs.Scene(
                sim_options=gs.options.SimOptions(dt=self.dt, substeps=1, gravity=tuple(gravity.tolist())),
                rigid_options=gs.options.RigidOptions(integrator=getattr(gs.integrator, _MEMBERS[integrator]),
                                                      enable_collision=False, enable_joint_limit=False),
                show_viewer=False)
            self.entity = self.scene.add_entity(gs.morphs.MJCF(file=path, align=False))
            self.scene.build()
        self.offset = 0 if model == BALL else 3  # the quaternion's and the angular velocity's place in q and v
        position = np.zeros(3) if model == FREE else np.zeros(0)
        self.q0 = np.concatenate([position, np.asarray(case.quat0, dtype=float)])
        self.v0 = np.concatenate([position, np.asarray(case.omega0, dtype=float)])
        self.torque = torque_function(body)
        self.force = np.zeros(self.entity.n_dofs)
        if self.torque is not None:
            dofs = self.entity.n_dofs
            self.entity.set_dofs_force_range(np.full(dofs, -NO_LIMIT), np.full(dofs, NO_LIMIT))
        self.reset()
        self.scene.step()  # compiles the step's kernels (tens of seconds at first; not timed)

    def reset(self) -> None:
        """The scene back at the case's initial state, no control force (every run starts afresh)."""
        if self.generation != _context["generation"]:
            raise RuntimeError(f"genesis: this {self.precision} model was released when the process re-initialised "
                               f"Genesis at {_context['precision']} (its precision is process-global)")
        self.scene.reset()
        self.entity.set_qpos(self.q0)
        self.entity.set_dofs_velocity(self.v0)
        if self.torque is not None:
            self.entity.control_dofs_force(np.zeros(self.entity.n_dofs))

    def step(self) -> None:
        self.scene.step()

    def read(self) -> tuple[tuple, tuple]:
        """(quaternion wxyz, omega in body components) as floats (harness.engines.stepping)."""
        q = self.entity.get_qpos().cpu().numpy()
        v = self.entity.get_dofs_velocity().cpu().numpy()
        return tuple(q[self.offset:self.offset + 4].tolist()), tuple(v[self.offset:self.offset + 3].tolist())

    def apply(self, moment: tuple) -> None:
        """The torque (body components) as the dofs' control force of the next step."""
        self.force[self.offset:self.offset + 3] = moment
        self.entity.control_dofs_force(self.force)

    def run(self, grid: TimeGrid) -> Trajectory:
        if grid.dt != self.dt:
            raise ValueError(f"grid dt {grid.dt} differs from the prepared dt {self.dt}")
        self.reset()
        return run_steps(self, grid, self.case.omega0, self.torque)


class GenesisEngine(Engine):
    """Genesis's rigid solver (models ball and free) on the CPU, float64 and float32."""

    name = "genesis"
    # measured: 300-600 µs per step from the Python loop on the loaded 2-core machine (docs/ENGINES.md). gs.init's
    # precision holds for the process: the timing phases time one precision's runs at a time. A first prepare in a
    # process imports Genesis (15-30 s) and builds its kernels cold (80-107 s), measured under load 14 on 2 cores:
    # past the sweep's default 120 s. 600 s keeps ~4x that; later prepares take 0.5-20 s. startup_s: a fresh process's
    # first prepare took 59 s with the caches cold and 30-37 s warm on 2 cores (issue 29; genesis-world 1.4.5, torch
    # 2.13 CPU): 45 s between. Since spare_import_scans: 56 s cold (import and init 9.4 s, a cold build 46.5 s), 18 s
    # warm (10.0 + 8.0), idle; 45 s kept, which a first run on a machine (the README's commands) pays nearly whole.
    timing = Timing(pass_us=400.0, startup_s=45.0, process_global_precision=True, prepare_budget_s=600.0)
    about = About(packages=("genesis-world", "torch"), linestyle="--", formulation=BALL)

    def integrators(self) -> tuple[str, ...]:
        return INTEGRATORS

    def offer(self, integrator: str) -> Offer:
        """Every integrator is order 1 on the ball joint; on the free body implicitfast and approximate_implicitfast
        are the implicit midpoint rule (Genesis PR #3074: a standalone free body's rotation solved at the midpoint
        velocity): order 2 (measured 2.00 on free-asymmetric)."""
        known = integrator in INTEGRATORS
        return Offer(order=1.0 if known else math.nan, orders=((FREE, 2.0),) if integrator in MIDPOINT_ON_FREE else (),
                     method=METHODS.get(integrator, ""), default_sweep=integrator in DEFAULT_SWEEP,
                     precisions=PRECISIONS)

    def unsupported(self, case: Case) -> str | None:
        # MuJoCo's compiler (Genesis parses MJCF through it) refuses an unphysical inertia
        return unphysical_inertia(case) or singular_torque(case)

    def models(self) -> dict:
        return {**super().models(), RIGID_BODY: SteppedRigidBody(self, MODELS, FREE, "Genesis has no exact pin for it")}

    def prepare(self, case: Case, integrator: str, dt: float | None, formulation: str = BALL,
                precision: str = FLOAT64, **options) -> GenesisSimulation:
        if formulation not in MODELS:
            raise KeyError(f"unknown formulation {formulation!r} for the genesis engine; valid: {', '.join(MODELS)}")
        if integrator not in INTEGRATORS:
            raise KeyError(f"unknown integrator {integrator!r} for the genesis engine; valid: {', '.join(INTEGRATORS)}")
        if precision not in PRECISIONS:
            raise KeyError(f"unknown precision {precision!r} for the genesis engine; valid: {', '.join(PRECISIONS)}")
        reason = self.unsupported(case) or self.models()[RIGID_BODY].unsupported_run(case, formulation, integrator)
        if reason:
            raise ValueError(f"{case.name}: {reason}")
        if dt is None or not dt > 0:
            raise ValueError(f"integrator {integrator!r} needs a step dt > 0, got {dt!r}")
        return GenesisSimulation(case, formulation, integrator, dt, precision)
