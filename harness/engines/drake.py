"""Drake adapter: the body in a MultibodyPlant, stepped by Drake's own integrators (the optional extra
`stereodyn[drake]`; without it the engine's rows are skipped naming the install command).

Two models, named in the formulation column:
* `rpy_ball`: a continuous plant (time_step 0), the body on a BallRpyJoint at O. q = (roll, pitch, yaw) with
  R = Rz(yaw) Ry(pitch) Rx(roll), v = the angular velocity in WORLD components (w_FM_F). The chart is singular at
  pitch = ±90° (gimbal lock): Drake throws when a derivative is evaluated within ~0.001 rad of it, and a step that
  jumps across it is caught at the next sample (cos pitch changed sign); either way the run ends `failed` with the
  time.
* `quaternion_free`: the body on a QuaternionFloatingJoint, q = (qw, qx, qy, qz, position), v = (world angular
  velocity, translational velocity). A free body moves as the pinned one only when O is its centre of mass (the
  pin's reaction force then passes through G and cancels the weight, so the model has no gravity); other cases skip
  it. No chart singularity.

Integrators under Drake's names (ResetIntegratorFromFlags), fixed-step at the run's dt (set_fixed_step_mode), the
error-controlled ones also as adaptive runs named NAME_adaptive (set_target_accuracy(tolerance)); `discrete` is the
discrete plant (time_step = dt: Drake's semi-implicit Euler update, what most Drake users run). States are recorded
by advancing the Simulator to each sample time (the per-step loop stays in C++).

External torques (reference.torques) enter through the plant's applied-generalized-force input port, computed by a
LeafSystem from the context's time and state at every derivative evaluation, every Runge–Kutta stage included
(torque_mode `input_port`); the discrete plant evaluates it once per step, at the step's start.
"""
from __future__ import annotations

import functools
import logging
import math
import time

import numpy as np

from .. import install

INSTALL = install.hint("drake")  # a checkout's or a distribution's form
EPS = float(np.finfo(float).eps)
# A fixed-step run's maximum step is dt (1 + STRETCH_ULPS eps steps). A sample interval of m steps, (j_b - j_a) dt in
# floating point, can exceed m steps of dt accumulated in Drake's clock (t += h, rounded each step) by a few ulps of
# t_end, and Drake's fixed-step mode then ends the interval with an extra step of ~1e-18 s (measured: 746 extra steps
# in 4000 at dt = 1e-3, each a full step's cost). The slack lets the m-th step absorb it; every step is still dt to
# within 8 eps steps relative (2e-9 at 1e6 steps), and the run takes exactly `steps` steps (tests/test_drake.py).
STRETCH_ULPS = 8.0

def _not_an_interrupt(record) -> bool:
    """pydrake logs a Ctrl-C during its import as a multi-line CRITICAL record; the interrupt itself propagates
    (harness.engines) and the command ends in one line."""
    return "KeyboardInterrupt" not in record.getMessage()


logging.getLogger("drake").addFilter(_not_an_interrupt)
try:
    from pydrake.common.eigen_geometry import Quaternion
    from pydrake.math import RollPitchYaw
    from pydrake.multibody.plant import MultibodyPlant
    from pydrake.multibody.tree import BallRpyJoint, QuaternionFloatingJoint, SpatialInertia, UnitInertia
    from pydrake.systems.analysis import GetIntegrationSchemes, ResetIntegratorFromFlags, Simulator
    from pydrake.systems.framework import DiagramBuilder, EventStatus, LeafSystem
except ImportError as exc:  # the registry turns this into skipped rows whose reason is this message
    raise ImportError(f"{exc}; install the extra: {INSTALL}") from exc

from .. import budget
from ..scenes.cases import Case, unphysical_inertia
from .base import RIGID_BODY, SLIDING_LADDER, About, Engine, Offer, RigidBodyModel, Timing, singular_torque
from .offered import names as offered_names, unmodelled as unmodelled_reason
from ..grid import TimeGrid
from ..trajectory import Status, Trajectory, divergence_message, first_bad_sample
from ...reference.rotations import quat_to_matrix
from ...reference.torques import torque_function

RPY_BALL, QUATERNION_FREE = "rpy_ball", "quaternion_free"
MODELS = (RPY_BALL, QUATERNION_FREE)
DISCRETE = "discrete"
ADAPTIVE_SUFFIX = "_adaptive"
# Drake's integration schemes (ResetIntegratorFromFlags names) and the order of the solution each propagates.
FIXED_STEP: dict[str, int] = {
    "explicit_euler": 1, "semi_explicit_euler": 1, "runge_kutta2": 2, "runge_kutta3": 3, "bogacki_shampine3": 3,
    "runge_kutta5": 5, "implicit_euler": 1, "velocity_implicit_euler": 1, "radau1": 1, "radau3": 3,
}
# The schemes with an error estimate: these also run error-controlled (NAME_adaptive).
ERROR_CONTROLLED = ("runge_kutta3", "bogacki_shampine3", "runge_kutta5", "implicit_euler", "velocity_implicit_euler",
                    "radau1", "radau3")
ADAPTIVE: dict[str, str] = {name + ADAPTIVE_SUFFIX: name for name in ERROR_CONTROLLED}
# At fixed steps Drake's implicit schemes still stop their Newton iteration at the target accuracy: at Drake's default
# radau3's error on the Lagrange top (2 s, dt 0.02 .. 0.00125) is off the method's by up to 4x, its local slopes
# 1.8, 3.5, -0.04, 3.0; at 1e-10 they are 3.01, 3.00, 3.00, 3.00 (~1.5x the derivative evaluations). A fixed-step row
# measures the method, so its Newton iteration converges this far.
IMPLICIT = ("implicit_euler", "velocity_implicit_euler", "radau1", "radau3")
NEWTON_ACCURACY = 1e-10
# The main sweep's target accuracy for the adaptive runs (the tolerance contract's default).
DEFAULT_TOLERANCE = 1e-8
# The default sweep (a run that names no integrators): the discrete plant (what most Drake users run), the second-
# and third-order explicit Runge–Kutta schemes at fixed steps, and Drake's default integrator, error-controlled RK3, at
# the default tolerance. Left to --integrators: runge_kutta5 (its fits from the cases' own two or three dts are
# pre-asymptotic, 5.5 on the quick suite, which would fail the order verdict; ~2x an RK3 step), the Euler variants
# (the discrete plant is Drake's first-order method), bogacki_shampine3 (a second RK3) and the implicit schemes
# (3-10x an explicit step: Newton iterations, Jacobians by finite differences). Measured cost of the default sweep's
# Drake rows: docs/ENGINES.md.
# What each scheme is (harness.engines.methods); the discrete plant's update is semi-implicit Euler. Drake's models step
# other coordinates than the ball-joint engines (roll-pitch-yaw, a free quaternion), so a first-order method agrees
# with theirs only to O(dt).
METHODS = {DISCRETE: "semi_implicit_euler", "explicit_euler": "explicit_euler", "semi_explicit_euler":
           "semi_implicit_euler", "runge_kutta2": "rk2", "runge_kutta3": "rk3", "runge_kutta5": "rk5",
           "implicit_euler": "implicit_euler"}
DEFAULT_SWEEP = (DISCRETE, "runge_kutta2", "runge_kutta3", "runge_kutta3" + ADAPTIVE_SUFFIX)
# Schemes of GetIntegrationSchemes() the adapter knows and does not run, with why (offered.unmodelled). A scheme in
# neither table is named as not modelled at run time; tests/test_engine_sdk.py fails until it is in one of them.
NOT_MODELLED = {
    "cenic": "CENIC (pydrake.multibody.cenic) is Drake's convex error-controlled integrator for contact, built "
             "for a plant with a SceneGraph (the adapter's diagram has none); no order declared for it",
}


def offered() -> tuple[str, ...]:
    """The integrators of the installed Drake: the discrete plant (a plant's time_step, always there), then each
    scheme ResetIntegratorFromFlags accepts (GetIntegrationSchemes(), its order) with, for the error-controlled ones
    the adapter knows, their adaptive runs."""
    schemes = tuple(GetIntegrationSchemes())
    return (DISCRETE, *schemes, *(name + ADAPTIVE_SUFFIX for name in ERROR_CONTROLLED if name in schemes))


MODELLED = (DISCRETE, *FIXED_STEP, *ADAPTIVE)


@functools.cache  # offer() asks for every run planned: the package's metadata read 2,000 times was 2 s of a run
def _drake_version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("drake")
    except PackageNotFoundError:
        return "(unknown version)"


def _rpy_to_quat(rpy: np.ndarray) -> np.ndarray:
    """(n, 3) roll, pitch, yaw (R = Rz(y) Ry(p) Rx(r)) -> (n, 4) unit quaternions wxyz, body -> world."""
    half = 0.5 * np.asarray(rpy, dtype=float)
    cr, cp, cy = np.cos(half).T
    sr, sp, sy = np.sin(half).T
    return np.column_stack((cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
                            cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy))


def _rotation(w: float, x: float, y: float, z: float) -> tuple:
    """The rotation matrix (rows, floats) of a quaternion, normalised (as Drake's RotationMatrix(quaternion))."""
    s = 2.0 / (w * w + x * x + y * y + z * z)
    return ((1 - s * (y * y + z * z), s * (x * y - w * z), s * (x * z + w * y)),
            (s * (x * y + w * z), 1 - s * (x * x + z * z), s * (y * z - w * x)),
            (s * (x * z - w * y), s * (y * z + w * x), 1 - s * (x * x + y * y)))


class _AppliedTorque(LeafSystem):
    """The case's external torque as the plant's applied generalized force, from the time and the plant's state:
    evaluated whenever the plant's dynamics are (every stage). The generalized force of both joints' angular
    velocity (world components) is the torque about O in world components: R M_body."""

    def __init__(self, torque, model: str, states: int, velocities: int):
        LeafSystem.__init__(self)
        self._torque, self._rpy = torque, model == RPY_BALL
        self._state = self.DeclareVectorInputPort("state", states)
        self._zeros = [0.0] * (velocities - 3)
        self.DeclareVectorOutputPort("generalized_force", velocities, self._calc)

    def _calc(self, context, output) -> None:
        x = self._state.Eval(context).tolist()
        if self._rpy:
            cr, cp, cy = math.cos(0.5 * x[0]), math.cos(0.5 * x[1]), math.cos(0.5 * x[2])
            sr, sp, sy = math.sin(0.5 * x[0]), math.sin(0.5 * x[1]), math.sin(0.5 * x[2])
            quat = (cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy,
                    cr * cp * sy - sr * sp * cy)
            wx, wy, wz = x[3], x[4], x[5]
        else:
            quat = (x[0], x[1], x[2], x[3])
            wx, wy, wz = x[7], x[8], x[9]
        (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = _rotation(*quat)
        omega = (r00 * wx + r10 * wy + r20 * wz, r01 * wx + r11 * wy + r21 * wz, r02 * wx + r12 * wy + r22 * wz)
        m0, m1, m2 = self._torque(context.get_time(), quat, omega)
        output.SetFromVector([r00 * m0 + r01 * m1 + r02 * m2, r10 * m0 + r11 * m1 + r12 * m2,
                              r20 * m0 + r21 * m1 + r22 * m2] + self._zeros)


def build(case: Case, model: str, time_step: float = 0.0):
    """(diagram, plant, initial state x0) of the case's body: O at the world origin and the body frame's origin,
    inertia about O in body axes (SpatialInertia about the body origin, so no Huygens–Steiner round trip), gravity
    g d (rpy_ball only), the external torque through the generalized-force port. time_step 0: continuous."""
    body_data = case.body
    builder = DiagramBuilder()
    plant = builder.AddSystem(MultibodyPlant(time_step))
    mass = float(body_data.mass)
    unit = np.asarray(body_data.inertia, dtype=float) / mass
    inertia = SpatialInertia(mass, np.asarray(body_data.com, dtype=float),
                             UnitInertia(unit[0, 0], unit[1, 1], unit[2, 2], unit[0, 1], unit[0, 2], unit[1, 2]))
    body = plant.AddRigidBody("body", inertia)
    rotation = Quaternion(np.asarray(case.quat0, dtype=float))
    omega_world = quat_to_matrix(np.asarray(case.quat0, dtype=float)) @ np.asarray(case.omega0, dtype=float)
    if model == RPY_BALL:
        plant.AddJoint(BallRpyJoint("ball", plant.world_frame(), body.body_frame()))
        plant.mutable_gravity_field().set_gravity_vector(
            body_data.gravity * np.asarray(body_data.gravity_direction, dtype=float))
        x0 = np.concatenate([RollPitchYaw(rotation).vector(), omega_world])
    elif model == QUATERNION_FREE:
        plant.AddJoint(QuaternionFloatingJoint("free", plant.world_frame(), body.body_frame()))
        # O = G: the pin's reaction cancels the weight at G, so neither enters the rotation (unsupported_run)
        plant.mutable_gravity_field().set_gravity_vector(np.zeros(3))
        x0 = np.concatenate([case.quat0, np.zeros(3), omega_world, np.zeros(3)])
    else:
        raise KeyError(f"unknown Drake model {model!r}; valid: {', '.join(MODELS)}")
    plant.Finalize()
    torque = torque_function(body_data)
    if torque is not None:
        source = builder.AddSystem(_AppliedTorque(torque, model, plant.num_multibody_states(), plant.num_velocities()))
        builder.Connect(plant.get_state_output_port(), source.get_input_port(0))
        builder.Connect(source.get_output_port(0), plant.get_applied_generalized_force_input_port())
    return builder.Build(), plant, np.asarray(x0, dtype=float)


class DrakeSimulation:
    """A case's Drake model with one integrator: fixed steps of dt, error control at a target accuracy, or the
    discrete plant. run() starts from the case's initial state every time, with a fresh integrator."""

    def __init__(self, case: Case, model: str, integrator: str, dt: float | None, tolerance: float | None):
        self.case, self.model, self.integrator = case, model, integrator
        self.discrete = integrator == DISCRETE
        self.adaptive = integrator in ADAPTIVE
        self.scheme = ADAPTIVE.get(integrator, integrator)
        self.dt = None if self.adaptive else float(dt)
        self.tolerance = DEFAULT_TOLERANCE if tolerance is None else float(tolerance)
        self.diagram, self.plant, self.x0 = build(case, model, self.dt if self.discrete else 0.0)
        self.simulator = Simulator(self.diagram)
        self.torque_mode = "input_port" if case.body.has_external_torque else "none"

    def start(self, max_step: float):
        """The simulator reset to t = 0 and the initial state, with a fresh integrator (none for the discrete
        plant): a run never inherits an adapted step size or statistics from the last one."""
        context = self.simulator.get_mutable_context()
        context.SetTime(0.0)
        if self.discrete:
            context.SetDiscreteState(self.x0)
            integrator = None
        else:
            context.SetContinuousState(self.x0)
            integrator = ResetIntegratorFromFlags(self.simulator, self.scheme, max_step)
            if self.adaptive:
                integrator.set_fixed_step_mode(False)
                integrator.set_target_accuracy(self.tolerance)
            else:
                integrator.set_fixed_step_mode(True)
                if self.scheme in IMPLICIT:
                    integrator.set_target_accuracy(NEWTON_ACCURACY)
        self.simulator.ResetStatistics()
        self.simulator.Initialize()
        return integrator

    def run(self, grid: TimeGrid) -> Trajectory:
        if not self.adaptive and grid.dt != self.dt:
            raise ValueError(f"grid dt {grid.dt} differs from the prepared dt {self.dt}")
        # adaptive: the step is bounded by the sample spacing anyway (states are taken at the sample times)
        integrator = self.start(grid.t_end if self.adaptive else self.dt * (1.0 + STRETCH_ULPS * EPS * grid.steps))
        context = self.simulator.get_context()
        vector = context.get_discrete_state_vector() if self.discrete else context.get_continuous_state_vector()
        times = grid.times.tolist()
        # the hot loop: one AdvanceTo (the steps, in C++) and one copy per sample, nothing else; a state gone
        # non-finite runs on as NaN at the same cost and the divergence rule is applied afterwards
        rows = [self.x0]
        advance, copy, append = self.simulator.AdvanceTo, vector.CopyToVector, rows.append
        out_of_time, check = self._watch(budget.deadline(), grid)
        error = None
        try:
            for t in times[1:]:
                advance(t)
                append(copy())
                check()
        except (RuntimeError, ValueError, OverflowError) as exc:  # a Drake error ends the run at the context's time
            if out_of_time():
                raise budget.exceeded() from None
            error = exc
        stopped = context.get_time()
        recorded = len(rows)
        states = np.full((len(times), self.x0.size), np.nan)
        states[:recorded] = np.concatenate(rows).reshape(recorded, self.x0.size)  # one copy, not one per row
        if self.discrete:  # MultibodyPlant 1.51's discrete step is an unrestricted update
            steps = rhs_evals = (self.simulator.get_num_discrete_updates()
                                 + self.simulator.get_num_unrestricted_updates())
        else:
            steps, rhs_evals = integrator.get_num_steps_taken(), integrator.get_num_derivative_evaluations()
        quat, omega = self.observe(states)
        status, message, bad = Status.OK, "", None
        if error is not None:
            status, bad, message = Status.FAILED, recorded, self.failure(error, stopped)
        if self.model == RPY_BALL:  # a step that jumped across pitch ±90° (no stage landed within Drake's 0.46°)
            crossed = np.flatnonzero(~(np.cos(states[:recorded, 1]) > 0.0))
            crossed = crossed[np.isfinite(states[crossed, 1])]
            if crossed.size and (bad is None or crossed[0] < bad):
                status, bad = Status.FAILED, int(crossed[0])
                message = (f"roll-pitch-yaw chart singularity: pitch crossed ±90° (gimbal lock) between "
                           f"t = {times[bad - 1]:.6g} s and {times[bad]:.6g} s")
        diverged_at = math.nan
        first = first_bad_sample(omega[:recorded], quat[:recorded], self.case.omega0)
        if first is not None and (bad is None or first < bad):
            status, bad, diverged_at = Status.DIVERGED, first, times[first]
            message = divergence_message(diverged_at)
        if bad is not None:
            quat[bad:] = np.nan
            omega[bad:] = np.nan
        return Trajectory(grid.times, quat, omega, status, message, diverged_at, int(steps), int(rhs_evals),
                          info={"torque_mode": self.torque_mode})

    def _watch(self, deadline: float | None, grid: TimeGrid):
        """The run's wall-time budget (harness.budget): (out_of_time() -> whether a step failed on it, check() to call
        after each sample). A fixed-step run whose samples lie at most budget.CHECK_EVERY steps apart is checked
        between samples (check raises BudgetExceeded); an adaptive run, or one with longer spans, gets the simulator's
        monitor, called after every step (the steps run in C++ inside AdvanceTo): past the deadline the step fails.
        The monitor is a call from C++ into Python a step, ~0.6 µs (heavy-asymmetric, 2e4 steps, 1001 samples, this
        2-core machine: runge_kutta2 +13%, radau3 +5%), so the short spans do without it. No monitor and no check
        without a deadline (the timing phase's runs)."""
        self.simulator.clear_monitor()
        if deadline is None:
            return (lambda: False), (lambda: None)
        if not self.adaptive and int(np.diff(grid.sample_steps).max(initial=0)) <= budget.CHECK_EVERY:
            return (lambda: False), budget.check
        clock, diagram, passed = time.monotonic, self.diagram, [False]

        def monitor(context):
            if clock() > deadline:
                passed[0] = True
                return EventStatus.Failed(diagram, "wall-time budget exceeded")
            return EventStatus.Succeeded()

        self.simulator.set_monitor(monitor)
        return (lambda: passed[0]), (lambda: None)

    def failure(self, error: Exception, stopped: float) -> str:
        text = str(error)
        if self.model == RPY_BALL and "singularity" in text and "Rpy" in text:
            # MapVelocityToQDot(): "The RpyBallMobilizer (implementing a BallRpyJoint) ... has reached a singularity"
            context = self.simulator.get_context()
            state = context.get_discrete_state_vector() if self.discrete else context.get_continuous_state_vector()
            return (f"roll-pitch-yaw chart singularity: Drake's BallRpyJoint stopped at pitch "
                    f"{math.degrees(state.GetAtIndex(1)):.4g}° (gimbal lock at ±90°) at t = {stopped:.6g} s")
        return f"Drake: {text.splitlines()[0] if text else type(error).__name__} (t = {stopped:.6g} s)"

    def observe(self, states: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The recorded states as quaternions wxyz body -> world (the free joint's as Drake left them, not
        renormalised) and omega (rad/s) in body components, R^T w_world."""
        with np.errstate(invalid="ignore", over="ignore"):
            if self.model == RPY_BALL:
                quat, w_world = _rpy_to_quat(states[:, :3]), states[:, 3:6]
            else:
                quat, w_world = states[:, :4].copy(), states[:, 7:10]
            omega = np.einsum("nji,nj->ni", quat_to_matrix(quat), w_world)
        return quat, omega


# Why a scene has no Drake model (the skipped row's message).
UNMODELLED = {SLIDING_LADDER: "drake: the sliding ladder needs bilateral constraints, which Drake's continuous "
                              "MultibodyPlant lacks (the discrete plant's are compliant): not modelled exactly"}


def _free_body_refusal(case: Case, formulation: str) -> str | None:
    """Why the model cannot run the case (quaternion_free needs O at the centre of mass), or None."""
    if formulation == QUATERNION_FREE and np.any(np.asarray(case.body.com) != 0.0):
        return ("quaternion_free: a free body moves as the pinned one only when O is its centre of mass "
                "(com = 0); Drake's continuous plant has no exact pin for it")
    return None


class DrakeRigidBody(RigidBodyModel):
    """The rigid body in Drake's MultibodyPlant: models rpy_ball and quaternion_free, the torque on an input port."""

    def variants(self) -> tuple[str, ...]:
        return MODELS

    def unsupported_run(self, case: Case, variant: str, integrator: str) -> str | None:
        return _free_body_refusal(case, variant)

    def default_run(self, case: Case, variant: str, integrator: str) -> bool:
        """The quaternion_free model joins a default sweep only where the scene allows it: elsewhere it is absent,
        not a skipped row (naming it with --integrators still shows the reason)."""
        return _free_body_refusal(case, variant) is None

    def torque_mode(self, case: Case) -> str:
        return "input_port" if case.body.has_external_torque else "none"


class DrakeEngine(Engine):
    """Drake's MultibodyPlant (models rpy_ball and quaternion_free) with Drake's integrators."""

    name = "drake"
    # measured: µs per step of the default sweep's integrators on the suite's cases (docs/ENGINES.md). A short warm-up
    # (its first 256 steps) pays every first-call cost: best of 3 after it against after a whole run, each on its own
    # simulation, interleaved, alternating which first: median ratio 0.996 over 12 fixed-step pairs (discrete,
    # runge_kutta2, runge_kutta3 on 6 cases; 9 within 4 %, the others 0.76-1.18 both ways on one case: the machine's
    # noise), 0.94-1.07 over 11 of 12 runge_kutta3_adaptive pairs (the twelfth 1.6, not reproduced by 4 more pairs of
    # its case). The whole-run warm-ups it replaces cost ~20 s of the default run's 1:42 timing phase (2026-11-27).
    timing = Timing(pass_us=12.0, short_warm_up=True)
    about = About(packages=("drake",), linestyle="-.", formulation=RPY_BALL)

    def integrators(self) -> tuple[str, ...]:
        return offered_names(offered(), MODELLED)

    def offer(self, integrator: str) -> Offer:
        """The order of the solution each scheme propagates (the discrete plant: semi-implicit Euler, 1); the
        adaptive runs have no dt to be compared at: no method."""
        order = 1.0 if integrator == DISCRETE else float(FIXED_STEP.get(ADAPTIVE.get(integrator, integrator),
                                                                           math.nan))
        reason = unmodelled_reason(integrator, offered(), MODELLED, NOT_MODELLED,
                                   f"drake {_drake_version()}'s GetIntegrationSchemes()")
        return Offer(order=order, method=METHODS.get(integrator, ""), adaptive=integrator in ADAPTIVE,
                     default_sweep=integrator in DEFAULT_SWEEP or bool(reason), unmodelled=reason)

    def unsupported(self, case: Case) -> str | None:
        # SpatialInertia::IsPhysicallyValid() refuses a body that breaks the triangle inequality
        return unphysical_inertia(case) or singular_torque(case)

    def models(self) -> dict:
        return {**super().models(), RIGID_BODY: DrakeRigidBody(self)}

    def unmodelled(self, scene) -> str:
        return UNMODELLED.get(scene.kind) or super().unmodelled(scene)

    def prepare(self, case: Case, integrator: str, dt: float | None, formulation: str = RPY_BALL,
                tolerance: float | None = None) -> DrakeSimulation:
        """tolerance: the target accuracy of an adaptive (NAME_adaptive) run, None = DEFAULT_TOLERANCE; fixed-step
        runs ignore it."""
        if formulation not in MODELS:
            raise KeyError(f"unknown formulation {formulation!r} for the Drake engine; valid: {', '.join(MODELS)}")
        if integrator not in MODELLED or integrator not in self.integrators():
            raise KeyError(f"unknown integrator {integrator!r} for the Drake engine; "
                           f"valid: {', '.join(self.integrators())}")
        reason = self.unsupported(case) or _free_body_refusal(case, formulation)
        if reason:
            raise ValueError(f"{case.name}: {reason}")
        if integrator not in ADAPTIVE and (dt is None or not dt > 0):
            raise ValueError(f"integrator {integrator!r} needs a step dt > 0, got {dt!r}")
        if tolerance is not None and not (math.isfinite(tolerance) and tolerance > 0):
            raise ValueError(f"tolerance must be a finite number > 0, got {tolerance!r}")
        return DrakeSimulation(case, formulation, integrator, dt, tolerance)
