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
(gs.destroy, gs.init), which releases every model built before: such a model's run() raises (its row, or its timing,
is then lost, never wrong). The MJCF is loaded with align=False, which keeps the body frame as written (a probe with
the default align=True saw a wrong initial energy; with this MJCF 1.4.5 gave the same states either way, measured).

External torques (reference.torques) are evaluated in Python at the start of every step from the step's time and
state and set as the dofs' control force (torque_mode `step`: exact for the one-stage Euler; the implicit
integrators see it as a constant over the step). Model building and the first step, which compiles the step's kernels,
happen in prepare (not timed): a first build compiles for minutes, later ones load the kernel cache.
"""
from __future__ import annotations

import importlib.util
import math
import os
import tempfile
from xml.sax.saxutils import quoteattr

import numpy as np

INSTALL = "pip install 'stereodyn[genesis]'"
# Genesis does not declare torch; importing it costs 15-30 s, so the SDK is imported on the first prepare and only
# its presence is checked here (the registry turns an ImportError into skipped rows whose reason is this message).
for _module in ("genesis", "torch"):
    _spec = importlib.util.find_spec(_module)
    if _spec is None or _spec.origin is None:  # absent, or a folder an uninstall left behind (a namespace package)
        raise ImportError(f"No module named {_module!r}; install the extra: {INSTALL} (Genesis also needs torch: "
                          f"the CPU wheel is enough)")

from .. import budget
from ..scenes.cases import Case, unphysical_inertia
from .base import FLOAT32, FLOAT64, Engine, precession_singular
from ..grid import TimeGrid
from ..trajectory import Status, Trajectory, divergence_limit2, divergence_message, sample_good
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
# The default sweep: the general cases at their coarsest dt (each step costs 0.3-0.6 ms from Python; a build 0.5-20 s
# from the kernel cache), Genesis's default integrator and euler, both precisions; the rest with --engines genesis.
DEFAULT_CASES = ("free-asymmetric", "lagrange-top", "kovalevskaya", "heavy-asymmetric")
COARSE_DT = 1e-2
DEFAULT_SWEEP = ("euler", "approximate_implicitfast")
# A torque no dof limit may clamp (Genesis's default dofs force range is finite).
NO_LIMIT = 1e30

_context = {"precision": None, "generation": 0}


def _genesis(precision: str):
    """The genesis module initialised on the CPU at this precision (re-initialised when it was at the other)."""
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

    def _state(self) -> tuple[np.ndarray, np.ndarray]:
        q = self.entity.get_qpos().cpu().numpy().astype(float)
        v = self.entity.get_dofs_velocity().cpu().numpy().astype(float)
        return q[self.offset:self.offset + 4], v[self.offset:self.offset + 3]

    def run(self, grid: TimeGrid) -> Trajectory:
        if grid.dt != self.dt:
            raise ValueError(f"grid dt {grid.dt} differs from the prepared dt {self.dt}")
        self.reset()
        step, torque, dt, offset = self.scene.step, self.torque, self.dt, self.offset
        limit2 = divergence_limit2(self.case.omega0)
        samples = grid.sample_steps.tolist()
        quat = np.full((len(samples), 4), np.nan)
        omega = np.full((len(samples), 3), np.nan)
        quat[0], omega[0] = self.q0[offset:], self.v0[offset:]
        force = np.zeros(self.entity.n_dofs)
        bad = None
        for i in range(1, len(samples)):
            if torque is None:  # the hot loop: Genesis's steps, one state read a sample
                for piece in budget.pieces(samples[i - 1], samples[i]):  # the run's wall-time budget
                    for _ in piece:
                        step()
            else:  # every step: the torque from the step's time and state (body components), then the step
                try:
                    for k in (k for piece in budget.pieces(samples[i - 1], samples[i]) for k in piece):
                        q, w = self._state()
                        force[offset:offset + 3] = torque(k * dt, tuple(q.tolist()), tuple(w.tolist()))
                        self.entity.control_dofs_force(force)
                        step()
                except (ArithmeticError, ValueError):  # a torque of a runaway state (math.cos(inf)): diverged
                    bad = i
                    break
            quat[i], omega[i] = self._state()
            if not sample_good(quat[i].tolist(), omega[i].tolist(), limit2):  # the divergence rule
                bad = i
                break
        mode = "none" if torque is None else "step"
        if bad is None:
            return Trajectory(grid.times, quat, omega, Status.OK, "", math.nan, grid.steps, grid.steps,
                              info={"torque_mode": mode})
        quat[bad:] = np.nan
        omega[bad:] = np.nan
        diverged_at = float(grid.times[bad])
        return Trajectory(grid.times, quat, omega, Status.DIVERGED, divergence_message(diverged_at), diverged_at,
                          samples[bad], samples[bad], info={"torque_mode": mode})


class GenesisEngine(Engine):
    """Genesis's rigid solver (models ball and free) on the CPU, float64 and float32."""

    name = "genesis"
    default_formulation = BALL
    # measured: 300-600 µs per step from the Python loop on the loaded 2-core machine (docs/ENGINES.md)
    pass_us = 400.0
    linestyle = "--"
    packages = ("genesis-world", "torch")

    def formulations(self) -> tuple[str, ...]:
        return MODELS

    def integrators(self) -> tuple[str, ...]:
        return INTEGRATORS

    def precisions(self, integrator: str) -> tuple[str, ...]:
        return PRECISIONS

    def in_default_sweep(self, integrator: str) -> bool:
        return integrator in DEFAULT_SWEEP

    def declared_order(self, integrator: str) -> float:
        return 1.0 if integrator in INTEGRATORS else math.nan

    def method(self, integrator: str) -> str:
        return METHODS.get(integrator, "")

    def unsupported(self, case: Case) -> str | None:
        # MuJoCo's compiler (Genesis parses MJCF through it) refuses an unphysical inertia
        return unphysical_inertia(case) or precession_singular(case)

    def unsupported_run(self, case: Case, formulation: str, integrator: str) -> str | None:
        if formulation == FREE and np.any(np.asarray(case.body.com) != 0.0):
            return ("free: a free body moves as the pinned one only when O is its centre of mass (com = 0); Genesis "
                    "has no exact pin for it")
        return None

    def default_run(self, case: Case, formulation: str, integrator: str) -> bool:
        """The general cases only (DEFAULT_CASES), the free model where the scene allows it."""
        return case.name in DEFAULT_CASES and self.unsupported_run(case, formulation, integrator) is None

    def default_dts(self, case: Case, integrator: str, dts: tuple[float, ...]) -> tuple[float, ...]:
        """One coarse step in a default sweep: the largest of the case's at most COARSE_DT (heavy-asymmetric's 0.3 is
        beyond every Euler variant's stability limit: a diverged row says nothing more than MuJoCo's does)."""
        coarse = [dt for dt in dts if dt <= COARSE_DT]
        return (max(coarse),) if coarse else (min(dts),)

    def torque_mode(self, case: Case) -> str:
        return "step" if case.body.has_external_torque else "none"

    def prepare(self, case: Case, integrator: str, dt: float | None, formulation: str = BALL,
                precision: str = FLOAT64, **options) -> GenesisSimulation:
        if formulation not in MODELS:
            raise KeyError(f"unknown formulation {formulation!r} for the genesis engine; valid: {', '.join(MODELS)}")
        if integrator not in INTEGRATORS:
            raise KeyError(f"unknown integrator {integrator!r} for the genesis engine; valid: {', '.join(INTEGRATORS)}")
        if precision not in PRECISIONS:
            raise KeyError(f"unknown precision {precision!r} for the genesis engine; valid: {', '.join(PRECISIONS)}")
        reason = self.unsupported(case) or self.unsupported_run(case, formulation, integrator)
        if reason:
            raise ValueError(f"{case.name}: {reason}")
        if dt is None or not dt > 0:
            raise ValueError(f"integrator {integrator!r} needs a step dt > 0, got {dt!r}")
        return GenesisSimulation(case, formulation, integrator, dt, precision)
