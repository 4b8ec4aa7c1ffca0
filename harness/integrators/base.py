"""Fixed-step integrators and their bookkeeping.

Two state spaces. "lie": ODEs on SO(3) x R^3 in left-trivialised form, g' = g exp-direction v, v' = accel(t, g, v); the
engine owns the group element g (any object: a quaternion in its own layout, a matrix, ...), the integrator only moves
it through `retract` and reads it through the engine's `record`. "vector" (harness.integrators.vector): an ODE
y' = f(t, chart, y) on R^n in a chart that the system may change between steps. Time t (s) comes first in every
right-hand side and stepper: a Runge–Kutta stage is evaluated at t + c_i h, and the bookkeeping starts step k at
t = k dt (a product, not an accumulated sum).

The base class owns the bookkeeping: stepping on a TimeGrid, recording the samples, detecting divergence and counting
right-hand-side evaluations.
"""
from __future__ import annotations

import abc
import contextlib
import inspect
import math
from typing import Callable, ClassVar, Protocol

import numpy as np

from ...reference import plugins
from .tableau import ButcherTableau
from .. import budget
from ..trajectory import (Status, Trajectory, divergence_limit2, diverged_trajectory, first_bad_step,
                          sample_good)
from ..grid import TimeGrid

# step(t, g, v) -> (g, v): one step from the state (g, v) at time t (s).
Stepper = Callable[[float, object, np.ndarray], tuple[object, np.ndarray]]


class LieSystem(Protocol):
    """The dynamics as an engine exposes them. g values are treated as immutable: neither method may modify one."""

    def accel(self, t: float, g: object, v: np.ndarray) -> np.ndarray:
        """v' (3,), body frame, at time t (s) and the state (g, v); v: (3,) body frame. Returns a fresh array."""

    def retract(self, g: object, theta: np.ndarray) -> object:
        """g (x) exp(theta): theta (3,) a rotation vector in body components (rad). Returns a new g."""


class BatchLieSystem(Protocol):
    """LieSystem for an ensemble of N states stepped together: g (N, ...) the engine's array of group elements,
    v and the results (N, 3) body frame. Rows are independent: row i of a result depends on row i of the inputs only."""

    def accel(self, t: float, g: np.ndarray, v: np.ndarray) -> np.ndarray:
        """v' (N, 3) rad/s^2 at time t (s, one for all rows) and the states (g, v); a fresh array."""

    def retract(self, g: np.ndarray, theta: np.ndarray) -> np.ndarray:
        """g (x) exp(theta) row by row: theta (N, 3) rad, body components; a new array."""


# Whether a run counts its right-hand-side calls (Counted): not while it is timed (harness.run.timing), as its metrics
# are off then, since the count's one Python call an evaluation is 3-8% of a Pinocchio step (thread CPU time, rk4 and
# symplectic_euler, 25 interleaved runs) and belongs to the bookkeeping, not to the stepping that is timed.
_counting = True


@contextlib.contextmanager
def uncounted():
    """Runs inside do not count their right-hand-side calls (rhs_evals: stages * steps, computed)."""
    global _counting
    previous, _counting = _counting, False
    try:
        yield
    finally:
        _counting = previous


def counting(system, method: str) -> tuple[object, Callable[[], int] | None]:
    """(the system to step, the count so far) for a run: Counted, or while uncounted() the system itself and None."""
    if not _counting:
        return system, None
    counted = Counted(system, method)
    return counted, lambda: counted.calls


class Counted:
    """A system whose right-hand side (`method`: "accel" on the group, "rhs" in state space "vector") counts its calls
    in `calls`: a run's rhs_evals are counted, not computed (an iterative method reports what it used). The other
    methods of the protocols are bound as they are (no lookup a call); any other attribute is the wrapped system's.
    The count costs one Python call a evaluation: +155 ns a call measured (timeit, the 2-core machine at load 10;
    a list cell and the protocol's own arguments: *args and an attribute cost +260 ns), against a Pinocchio RK4
    step's ~16 µs of 4 calls: a timed run does not count (uncounted)."""

    def __init__(self, system, method: str):
        self._system, self._count = system, [0]
        inner, count = getattr(system, method), self._count
        if method == "accel":
            def counted(t, g, v):
                count[0] += 1
                return inner(t, g, v)
        else:
            def counted(t, chart, y):
                count[0] += 1
                return inner(t, chart, y)

        setattr(self, method, counted)
        for name in ("retract", "rechart", "observe", "chart_changes"):
            if name != method and hasattr(system, name):
                setattr(self, name, getattr(system, name))

    @property
    def calls(self) -> int:
        """Right-hand-side evaluations so far."""
        return self._count[0]

    def __getattr__(self, name: str):
        return getattr(self._system, name)


class Integrator(abc.ABC):
    """A fixed-step integrator with declared metadata, on SO(3) x R^3 (state_space "lie") unless it says otherwise.

    Subclasses set the class attributes and implement step(); stepper() may be overridden to precompute what depends
    only on the system and h, so the hot loop in integrate() does no repeated work. A subclass that sets a Butcher
    `tableau` gets `stages` from it unless it sets its own.
    """

    name: ClassVar[str]
    order: ClassVar[int]              # global order of accuracy
    stages: ClassVar[int]             # accel evaluations per step
    symplectic: ClassVar[bool]
    geometric: ClassVar[bool]         # the attitude stays on the group (moved only through retract)
    state_space: ClassVar[str] = "lie"
    description: ClassVar[str]
    # Optional metadata: the method claims an energy error bounded in time (no secular drift) on conservative
    # scenes (harness.testing.assert_bounded_energy checks it); it runs in a sweep that names no integrators.
    energy_bounded: ClassVar[bool] = False
    default_sweep: ClassVar[bool] = True
    # Optional metadata (issue 30), each checked by a verdict (harness.analysis.claims): symmetric, a step of h then
    # one of -h returns the start (time-reversible); casimir_preserving, |sigma v|^2 kept at round-off on a free body;
    # iterative, the right-hand-side evaluations of a step vary (an implicit solve): `stages` is then the least a step
    # makes, and rhs_evals reports what it used.
    symmetric: ClassVar[bool] = False
    casimir_preserving: ClassVar[bool] = False
    iterative: ClassVar[bool] = False

    METADATA: ClassVar[tuple[str, ...]] = ("name", "order", "stages", "symplectic", "geometric", "state_space",
                                           "description")

    def __init_subclass__(cls, **kwargs) -> None:
        super().__init_subclass__(**kwargs)
        tableau = cls.__dict__.get("tableau")
        if isinstance(tableau, ButcherTableau) and "stages" not in cls.__dict__:  # anything else: metadata_problem
            cls.stages = tableau.stages

    @abc.abstractmethod
    def step(self, system: LieSystem, t: float, g: object, v: np.ndarray, h: float) -> tuple[object, np.ndarray]:
        """One step of size h (s) from (g, v) at time t (s); returns the new (g, v) (at t + h)."""

    def stepper(self, system: LieSystem, h: float) -> Stepper:
        """A function (t, g, v) -> (g, v) doing one step of size h on system from time t."""
        step = self.step
        return lambda t, g, v: step(system, t, g, v, h)

    def batch_stepper(self, system: "BatchLieSystem", h: float) -> Stepper | None:
        """A function (t, G, V) -> (G, V) doing one step of size h on every member of an ensemble at once, or None when
        the method has no batched form (harness.integrators.ensemble then runs the members one by one).

        G: the engine's (N, ...) array of group elements; V: (N, 3). Row i of the result must depend on row i of the
        input only, and the step must not raise (a member that goes bad shows as non-finite or fast, and is dropped).
        """
        return None

    def integrate(self, system: LieSystem, g0: object, v0: np.ndarray, grid: TimeGrid,
                  record: Callable[[object], tuple[float, float, float, float]]) -> Trajectory:
        """grid.steps steps of grid.dt from (g0, v0), recorded at grid.sample_steps.

        record(g) gives the attitude quaternion (w, x, y, z) of g. A sample that breaks the divergence rule of
        harness.trajectory (not finite, or |v| beyond its limit) stops the run; the steps since the previous sample are
        then replayed one by one to find the exact step where the state went bad (diverged_at = that step * dt).
        rhs_evals counts the accel calls of the run proper (Counted), not those of the replay.
        """
        stepped, calls = counting(system, "accel")
        trajectory, _ = self._run(self.stepper(stepped, grid.dt), g0, np.array(v0, dtype=float), grid,
                                  lambda g, v: (record(g), v.tolist()), calls)
        return trajectory

    def _run(self, step: Stepper, g0: object, v0: object, grid: TimeGrid,
             observe: Callable[[object, object], tuple],
             calls: Callable[[], int] | None = None) -> tuple[Trajectory, object]:
        """The bookkeeping of integrate() for any state space: observe(g, v) gives the sample's attitude quaternion
        (4 floats) and body angular velocity (3 floats). A step that raises ArithmeticError (a system's way to say its
        coordinates became singular) ends the run as diverged at that step, with the exception's text as the message.
        calls() gives the right-hand-side evaluations counted so far (None: stages * steps, computed).
        Returns the trajectory and the g of the last good state."""
        check_stepper(step, type(self))
        quat0, omega0 = observe(g0, v0)
        limit2 = divergence_limit2(omega0)
        # Samples go into flat lists of floats, made arrays once at the end: at one step per sample (1e3 steps, 1e3
        # samples) the per-sample bookkeeping is a third of a Pinocchio step, so it is kept to a few operations.
        quats, omegas = list(quat0), list(omega0)
        g, v, done, dt = g0, v0, 0, grid.dt
        n = grid.sample_steps.size
        good = sample_good
        # the run's wall-time budget, checked between pieces of <= CHECK_EVERY steps; none in the timing phase, whose
        # runs then step plain ranges (budget.pieces costs ~0.15 µs a sample, a few % of a step with a sample a step)
        unbudgeted = budget.deadline() is None
        with np.errstate(all="ignore"):  # overflow on the way to a divergence is an outcome, reported as one
            for target in grid.sample_steps[1:].tolist():
                g_last, v_last, start = g, v, done
                try:
                    for piece in (range(done, target),) if unbudgeted else budget.pieces(done, target):
                        for k in piece:
                            g, v = step(k * dt, g, v)  # t = k dt, not a running sum: no drift of t over 1e6 steps
                except ArithmeticError as exc:
                    used = calls() if calls else None  # before the replay
                    bad_step, g_good = first_bad_step(step, observe, g_last, v_last, start, target, dt, limit2)
                    return diverged_trajectory(grid, _padded(quats, 4, n), _padded(omegas, 3, n), len(omegas) // 3,
                                               bad_step * dt, bad_step - 1,
                                               self.stages * (bad_step - 1) if used is None else used,
                                               f"{exc} at t = {bad_step * dt:.6g} s"), g_good
                done = target
                quat, omega = observe(g, v)
                quats += quat
                omegas += omega
                if not good(quat, omega, limit2):
                    used = calls() if calls else self.stages * done  # before the replay
                    bad_step, g_good = first_bad_step(step, observe, g_last, v_last, start, target, dt, limit2)
                    trajectory = diverged_trajectory(grid, _padded(quats, 4, n), _padded(omegas, 3, n),
                                                     len(omegas) // 3 - 1, bad_step * dt, done, used)
                    return trajectory, g_good
        return Trajectory(grid.times, np.array(quats, dtype=float).reshape(n, 4),
                          np.array(omegas, dtype=float).reshape(n, 3), Status.OK, "", math.nan, grid.steps,
                          calls() if calls else self.stages * grid.steps), g


# What changed in 0.2.0, for the messages that refuse a plug-in written against 0.1.
TIME_CHANGE = "stereodyn 0.2.0 passes time"


def _positional(function) -> list[str] | None:
    """The names of function's positional parameters (bound self excluded), or None when it takes *args or has no
    signature to read."""
    try:
        parameters = inspect.signature(function).parameters.values()
    except (TypeError, ValueError):
        return None
    if any(p.kind is p.VAR_POSITIONAL for p in parameters):
        return None
    return [p.name for p in parameters if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)]


# The largest convergence order a method may declare and a baseline may hold (declared or fitted): err ~ C dt^p with
# p = 100 divides the error by 2^100 = 1e30 when the step halves, more than a double's 16 digits from an error of
# 1 to round-off, so no measured order reaches it; an order above is a typing error or a hand edit. The highest a
# method of the harness declares is 5, the committed default report's fitted orders lie in 0.96 .. 4.15.
MAX_ORDER = 100


# The state spaces an integrator steps on: SO(3) x R^3 (the Pinocchio engine's), a reference formulation's coordinates.
STATE_SPACES = ("lie", "vector")

# The declared properties (Integrator's boolean metadata): each True or False, never a word or a number.
PROPERTIES = ("symplectic", "geometric", "energy_bounded", "symmetric", "casimir_preserving", "iterative",
              "default_sweep")


def order_problem(order) -> str | None:
    """Why a declared order cannot be used (None: it can): a number in (0, MAX_ORDER], not a boolean."""
    if isinstance(order, (bool, np.bool_)) or not isinstance(order, (int, float, np.integer, np.floating)) \
            or not math.isfinite(order) or not 0 < order <= MAX_ORDER:
        return f"order = {plugins.shown(order)}: must be a positive finite number, at most {MAX_ORDER}"
    return None


def metadata_problem(cls: type) -> str | None:
    """Why an Integrator class's declarations cannot be used, naming the field and the rule (None: they can): name
    the name rule's, state_space one of STATE_SPACES, order a positive finite number <= MAX_ORDER (order_problem), a
    tableau-driven method's tableau a ButcherTableau, stages a non-negative integer (an iterative method's least),
    each property (PROPERTIES) a boolean. The registry refuses such a class at load, before any run (an order of
    "four" died in the verdicts after the sweep; NaN was never judged)."""
    problem = plugins.name_problem("name", cls.name, listed=True) or order_problem(cls.order)
    if problem:
        return problem
    # "lie group" was listed, and no engine could run it (issue 46's thirteenth attack)
    if not (type(cls.state_space) is str and cls.state_space in STATE_SPACES):
        return f"state_space = {plugins.shown(cls.state_space)}: must be one of {', '.join(STATE_SPACES)}"
    # a method stepped by a tableau-driven base's stepper (ExplicitRK, VectorRK) needs a tableau: None was exit 3 at
    # its first step, the sweep's other rows lost (issue 46's twelfth attack)
    driven = any(vars(k).get("stepper") is getattr(cls, "stepper", None) for k in cls.__mro__
                 if "tableau" in vars(k).get("__annotations__", {}))
    if driven and not isinstance(getattr(cls, "tableau", None), ButcherTableau):
        return (f"tableau = {plugins.shown(getattr(cls, 'tableau', None), 60)}: must be a ButcherTableau "
                "(harness/integrators/tableau.py)")
    stages = getattr(cls, "stages", None)
    if isinstance(stages, (bool, np.bool_)) or not isinstance(stages, (int, np.integer)) or stages < 0:
        return f"stages = {plugins.shown(stages)}: must be a non-negative integer (an iterative method's least a step)"
    for field in PROPERTIES:
        value = getattr(cls, field, False)
        if not isinstance(value, (bool, np.bool_)):
            return f"{field} = {plugins.shown(value)}: must be True or False"
    if not isinstance(getattr(cls, "description", ""), str):
        return f"description = {plugins.shown(cls.description)}: must be a string"
    return None


def check_step_signature(cls: type) -> None:
    """TypeError when cls.step takes the 0.1 arguments (system, g, v, h) instead of (system, t, g, v, h)."""
    names = _positional(cls.step)
    if names is not None and names[:1] == ["self"] and len(names) == 5:
        old = ", ".join(names[1:])
        raise TypeError(f"{cls.__module__}.{cls.__qualname__}.step({old}): {TIME_CHANGE}: "
                        f"step({names[1]}, t, {', '.join(names[2:])})")


def check_stepper(step: Stepper, cls: type, method: str = "stepper") -> None:
    """TypeError when a stepper built by cls.method takes the 0.1 arguments (g, v) instead of (t, g, v)."""
    names = _positional(step)
    if names is not None and len(names) == 2:
        raise TypeError(f"{cls.__module__}.{cls.__qualname__}.{method}(system, h) returns a step({', '.join(names)}): "
                        f"{TIME_CHANGE}: step(t, {', '.join(names)})")


def _padded(flat: list, width: int, n: int) -> np.ndarray:
    """The first len(flat) / width rows of an (n, width) array of NaN, filled from a flat list of samples."""
    out = np.full((n, width), np.nan)
    rows = len(flat) // width
    out[:rows] = np.array(flat, dtype=float).reshape(rows, width)
    return out


class StepperIntegrator(Integrator):
    """An integrator written as a stepper factory, which precomputes what depends only on the system and h;
    step() builds it for a single step."""

    def step(self, system: LieSystem, t: float, g: object, v: np.ndarray, h: float) -> tuple[object, np.ndarray]:
        return self.stepper(system, h)(t, g, v)

    @abc.abstractmethod
    def stepper(self, system: LieSystem, h: float) -> Stepper:
        """A function (t, g, v) -> (g, v) doing one step of size h on system from time t."""
