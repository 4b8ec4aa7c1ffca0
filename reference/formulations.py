"""The formulations of the body with a fixed point, behind one protocol, and their Taylor integration with charts.

A formulation is a choice of state and equations of motion:

    quaternion          (w, x, y, z, ω1, ω2, ω3)   Euler–Poisson with a quaternion (reference.euler_poisson)
    gibbs               (q, q̇)                     Ferrarese's Lagrangian (17''), Gibbs vector q (reference.gibbs)
    gibbs_hamiltonian   (q, p)                     Ferrarese's Hamiltonian form (18)–(19)
    euler_zxz           (φ, θ, ψ, φ̇, θ̇, ψ̇)         Lagrange's equations in ZXZ angles (reference.euler_angles)

The last three are charts of SO(3). A Chart is the reference frame the coordinates are taken in: the world attitude is
R(frame) R_local(y), and gravity enters as the downward vertical in that frame, the central field as its direction
in that frame (reference.truth.torque_parameters with the frame's matrix). Every formulation carries every torque of
reference.torque_models: the charted ones as generalized forces in their coordinates (reference.gibbs,
reference.euler_angles). When the state leaves the chart's
working domain (|q| > 1, a rotation of more than 90° from the frame, for the Gibbs vector; |sin θ| < 0.5 for the
angles) the chart is re-centred on the current attitude (F13's rotated-frame variant: the equations keep their form),
and the change is counted. With chart changes disabled the coordinates are followed towards the singularity, and a
ChartSingularity is raised once they come within SINGULAR_DISTANCE of it (|q| > 20, |sin θ| < 0.0998).

Each formulation has a numpy right-hand side (the reference implementation, vectorised), a heyoka system with the
runtime parameters of reference.expressions, and that system compiled to a function (compiled_rhs, what fixed-step
integrators call); the heyoka pieces are compiled once per formulation and process. integrate_taylor() runs the
system with a terminal event on the chart criterion: stop, re-chart, continue, and sample on the requested times.
"""
from __future__ import annotations

import abc
import functools
import math
import threading
import time
from dataclasses import dataclass
from typing import ClassVar

import heyoka as hy
import numpy as np

from . import euler_angles, euler_poisson, gibbs, torque_models, torques, truth
from . import expressions as ex
from .body import RigidBody
from .rotations import quat_mul, quat_normalize, quat_to_matrix

IDENTITY = np.array([1.0, 0.0, 0.0, 0.0])

# Chart thresholds. Re-centring at |q| = 1 (90°) keeps |q| <= 1, where the metric's condition number is at most
# 2 cond(σ). Re-charting the angles at |sin θ| = 0.5 (θ within 30° of a pole) keeps 1/sin θ <= 2 in the Lagrange
# equations: with 0.1 the tenfold amplification of rounding near the edge made heyoka runs over t = 50 on a
# Lagrange top through θ = 0 up to 4x less accurate (1.2e-12 against 3.6e-13 rad), and they took more Taylor steps.
GIBBS_RECENTRE = 1.0
ZXZ_RECHART = 0.5
# Without chart changes: the coordinates are declared singular within SINGULAR_DISTANCE (rad) of the singular set,
# rotation angle π for the Gibbs vector (|q| > 1/tan(0.05) = 20), θ = 0 or π for the angles. Closer, fixed steps stop
# resolving the coordinates (their rates grow like |q|² and 1/sin θ) and may carry on with a wrong attitude instead
# of failing: rk4 at dt = 0.01 on the Hamiltonian form stalled at |q| = 66 on a free body through π and came back,
# an "ok" run with an error of π. Taylor steps would shrink towards a standstill instead.
SINGULAR_DISTANCE = 0.1
GIBBS_GUARD = 1.0 / math.tan(0.5 * SINGULAR_DISTANCE)
ZXZ_GUARD = math.sin(SINGULAR_DISTANCE)


class ChartSingularity(ArithmeticError):
    """The coordinates reached their chart's singularity with chart changes disabled (message names it)."""


@dataclass(frozen=True, eq=False)
class Chart:
    """The reference frame of a formulation's coordinates.

    frame: (4,) unit quaternion (w, x, y, z): the chart's reference axes c*_h = R(frame) c_h in the world;
        the world attitude is R(frame) R_local.
    down: (3,) unit, the downward vertical in the chart's reference axes, R(frame)ᵀ d.
    changes: chart changes made so far in the run.
    """

    frame: np.ndarray
    down: np.ndarray
    changes: int = 0

    @functools.cached_property
    def frame_floats(self) -> tuple[float, float, float, float]:
        return tuple(self.frame.tolist())


class Formulation(abc.ABC):
    """A formulation bound to a body. State y: (size,) or (..., size) for the vectorised methods.

    Subclasses give the chart-local conversions, the numpy right-hand side and the heyoka system; the base class
    owns the charts. A formulation without charts (charted False) lives in the world frame, its Chart the identity
    forever. A charted one (ChartedFormulation) says when a state leaves its chart: `measure(y)` against a
    threshold, outside when event_direction * (measure - threshold) > 0 (the same test as its heyoka terminal event).
    """

    name: ClassVar[str]
    state_labels: ClassVar[tuple[str, ...]]
    charted: ClassVar[bool] = False
    recentre_threshold: ClassVar[float] = math.nan
    guard_threshold: ClassVar[float] = math.nan
    event_direction: ClassVar[int] = 1
    regular_state: ClassVar[tuple[float, ...]]  # any state where the equations are defined (to build integrators)

    def __init__(self, body: RigidBody):
        self.body = body
        self.sigma = np.array(body.inertia, dtype=float)
        self.sigma_inv = np.linalg.inv(self.sigma)
        self.weight_moment = np.array(body.weight_moment, dtype=float)
        self.gravity_direction = np.array(body.gravity_direction, dtype=float)
        self._sigma_inv_rows = self.sigma_inv.tolist()
        self._compiled_chart: Chart | None = None  # the chart whose parameters _compiled_pars holds
        self._compiled_pars = np.empty(0)
        self._compiled_rhs = None

    @property
    def size(self) -> int:
        return len(self.state_labels)

    # --- per formulation

    @abc.abstractmethod
    def local_state(self, quat_local: np.ndarray, omega: np.ndarray) -> np.ndarray:
        """The state of the attitude quat_local (relative to the chart's frame) and ω (body frame, rad/s)."""

    @abc.abstractmethod
    def local_attitude(self, y: np.ndarray) -> np.ndarray:
        """(..., 4) quaternion of R_local(y)."""

    @abc.abstractmethod
    def omega(self, y: np.ndarray) -> np.ndarray:
        """(..., 3) angular velocity, body frame, rad/s."""

    @abc.abstractmethod
    def rhs(self, t: float, chart: Chart, y: np.ndarray) -> np.ndarray:
        """ẏ at time t (s) and y (size,) or (..., size) in chart (its downward vertical, and its frame for the
        central field's direction); the numpy reference implementation, vectorised."""

    def external_torque(self, t: float, chart: Chart, y: np.ndarray) -> np.ndarray | None:
        """The torques of reference.torques at (t s, y in chart): (..., 3) N m body components, or None for a body
        without them (the world attitude R(frame) R_local(y) gives the field's direction in the body)."""
        if not self.body.has_external_torque:
            return None
        return torques.external_torque(self.body, quat_mul(chart.frame, self.local_attitude(y)), self.omega(y), t)

    @classmethod
    @abc.abstractmethod
    def equations(cls) -> tuple[list, list, object]:
        """heyoka (variables, right-hand sides, chart measure expression or None) in reference.expressions'
        parameters."""

    def fast_rhs(self, t: float, chart: Chart, y: np.ndarray) -> np.ndarray:
        """ẏ at time t (s: a turning central field depends on it, heyoka's time variable) and one state y (size,) in
        chart, from the heyoka equations compiled to a function (compiled_rhs(name)):
        the same right-hand side as the Taylor integrator's, a few µs a call against ~100 µs for rhs() on one state.
        Not thread-safe (it caches the last chart's parameters)."""
        if chart is not self._compiled_chart:
            # The compiled function is looked up with the chart, not at every call: compiled_rhs reads the torque
            # registry (~0.7 µs), which cost 6% of a reference sweep at ~1e6 calls (measured against 0.2.0).
            self._compiled_chart, self._compiled_pars = chart, self.rhs_parameters(chart)
            self._compiled_rhs = compiled_rhs(self.name)
        return self._compiled_rhs(y, pars=self._compiled_pars, time=t)

    # --- charts

    def chart(self, frame: np.ndarray, changes: int = 0) -> Chart:
        frame = np.array(frame, dtype=float)
        return Chart(frame, quat_to_matrix(frame).T @ self.gravity_direction, changes)

    def outside(self, y: np.ndarray, threshold: float) -> bool:
        """The measure is beyond threshold (or not finite)."""
        value = self.event_direction * (self.measure(y) - threshold)
        return not value <= 0.0

    def start(self, quat0: np.ndarray, omega0: np.ndarray, chart_changes: bool = True) -> tuple[Chart, np.ndarray]:
        """Chart and state of the initial condition: coordinates relative to the world if the attitude lies in that
        chart's domain, else (chart changes enabled) re-centred at once, which counts as a change.
        Raises ChartSingularity when chart changes are disabled and the world chart is singular there."""
        quat0 = quat_normalize(np.asarray(quat0, dtype=float))
        omega0 = np.asarray(omega0, dtype=float)
        chart = self.chart(IDENTITY)
        with np.errstate(divide="ignore", invalid="ignore"):  # a Gibbs vector at exactly π is infinite: re-charted
            y = self.local_state(quat0, omega0)
        if self.charted and self.outside(y, self.recentre_threshold):
            if chart_changes:
                frame, local = self.recentred(quat0)
                return self.chart(frame, 1), self.local_state(local, omega0)
            if self.outside(y, self.guard_threshold):
                raise ChartSingularity(self.singularity(y))
        return chart, y

    def observe(self, chart: Chart, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World attitude quaternion (..., 4) and body ω (..., 3) of the state(s) y in chart."""
        return quat_mul(chart.frame, self.local_attitude(y)), self.omega(y)

    def observe_one(self, chart: Chart, y: np.ndarray) -> tuple[tuple, tuple]:
        """observe() of one state (size,), as float tuples, in scalar arithmetic: a fixed-step run records a sample
        every few steps, and numpy's per-call cost on 3-vectors would be ten times the arithmetic."""
        local, omega = self._local_one(y.tolist())
        return _quat_mul_floats(chart.frame_floats, local), omega

    def _local_one(self, y: list) -> tuple[tuple, tuple]:
        """(local quaternion, ω body) of one state given as floats."""
        quat, omega = self.local_attitude(np.array(y)), self.omega(np.array(y))
        return tuple(quat.tolist()), tuple(omega.tolist())

    def rechart(self, chart: Chart, y: np.ndarray) -> tuple[Chart, np.ndarray]:
        """Re-centre the chart on the attitude of y (one more change)."""
        quat, omega = self.observe(chart, y)
        frame, local = self.recentred(quat)
        return self.chart(frame, chart.changes + 1), self.local_state(local, omega)

    def check_chart(self, chart: Chart, y: np.ndarray, chart_changes: bool = True) -> tuple[Chart, np.ndarray]:
        """After a step: re-chart if y left the chart's domain; with chart changes disabled, raise ChartSingularity
        once y is singular instead. Returns (chart, y) unchanged otherwise."""
        if not self.charted:
            return chart, y
        if chart_changes:
            return self.rechart(chart, y) if self.outside(y, self.recentre_threshold) else (chart, y)
        if self.outside(y, self.guard_threshold):
            raise ChartSingularity(self.singularity(y))
        return chart, y

    def rhs_parameters(self, chart: Chart) -> np.ndarray:
        """The parameters of compiled_rhs(name) (the Taylor parameters; the event threshold is unused there)."""
        return self.parameters(chart)

    def parameters(self, chart: Chart, chart_changes: bool = True) -> np.ndarray:
        """The heyoka runtime parameters (reference.truth's layout, truth.parameter_count()) for this body, chart and
        chart policy: the body's and the event threshold (reference.expressions), then the torques with the field's
        directions in the chart's reference frame."""
        threshold = self.recentre_threshold if chart_changes else self.guard_threshold
        return np.concatenate([ex.parameters(self.body, chart.frame, threshold if self.charted else 0.0),
                               truth.torque_parameters(self.body, quat_to_matrix(chart.frame))])


class ChartedFormulation(Formulation):
    """A formulation in a chart of SO(3) that has a singular set: re-centred (or, with chart changes disabled, declared
    singular) by the criterion on measure(y)."""

    charted = True

    @abc.abstractmethod
    def measure(self, y: np.ndarray) -> float:
        """The chart criterion's quantity of one state (q·q, or sin θ)."""

    @abc.abstractmethod
    def recentred(self, quat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """A new chart for the attitude quat: (frame quaternion, local quaternion), the latter well inside it."""

    @abc.abstractmethod
    def singularity(self, y: np.ndarray) -> str:
        """What singularity y reached (for messages)."""


class Quaternion(Formulation):
    """Euler–Poisson with a quaternion attitude: no charts (the truth's formulation)."""

    name = "quaternion"
    state_labels = ("w", "x", "y", "z", "omega1", "omega2", "omega3")
    regular_state = (1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)

    def local_state(self, quat_local, omega):
        return np.concatenate([quat_local, omega], axis=-1)

    def local_attitude(self, y):
        return np.asarray(y)[..., :4]

    def omega(self, y):
        return np.asarray(y)[..., 4:]

    def _local_one(self, y):
        return tuple(y[:4]), tuple(y[4:])

    def rhs(self, t, chart, y):
        quat_dot, omega_dot = euler_poisson.rhs(self.body, y[..., :4], y[..., 4:], t)
        return np.concatenate([quat_dot, omega_dot], axis=-1)

    @classmethod
    def equations(cls):
        variables, rhs = zip(*truth.equations())
        return list(variables), list(rhs), None


class _Gibbs(ChartedFormulation):
    """The Gibbs-vector charts: re-centred when |q| > 1."""

    recentre_threshold = GIBBS_RECENTRE ** 2
    guard_threshold = GIBBS_GUARD ** 2
    event_direction = 1
    regular_state = (0.0,) * 6

    def measure(self, y):
        q0, q1, q2 = y[0], y[1], y[2]
        return q0 * q0 + q1 * q1 + q2 * q2

    def recentred(self, quat):
        return quat_normalize(np.asarray(quat, dtype=float)), IDENTITY.copy()

    def singularity(self, y):
        return (f"Gibbs vector singular: rotation angle reached pi (within {SINGULAR_DISTANCE:g} rad, "
                f"|q| > {GIBBS_GUARD:.3g}) with chart changes disabled")

    def local_attitude(self, y):
        q = np.asarray(y)[..., :3]
        return quat_normalize(np.concatenate([np.ones(q.shape[:-1] + (1,)), q], axis=-1))

    @staticmethod
    def _quat_one(q1: float, q2: float, q3: float) -> tuple:
        scale = 1.0 / math.sqrt(1.0 + q1 * q1 + q2 * q2 + q3 * q3)
        return scale, q1 * scale, q2 * scale, q3 * scale

    @staticmethod
    def _gibbs(quat_local: np.ndarray) -> np.ndarray:
        quat_local = np.asarray(quat_local, dtype=float)
        return quat_local[..., 1:] / quat_local[..., :1]


class Gibbs(_Gibbs):
    """Ferrarese's Lagrangian (17'') with Christoffel symbols; state (q, q̇)."""

    name = "gibbs"
    state_labels = ("q1", "q2", "q3", "qdot1", "qdot2", "qdot3")

    def local_state(self, quat_local, omega):
        q = self._gibbs(quat_local)
        return np.concatenate([q, gibbs.qdot_from_omega_body(q, omega)], axis=-1)

    def rechart(self, chart, y):
        """Re-centre on the attitude of y: Q* = 0, q̇* = ½ ω_body (gibbs.recentre_velocity)."""
        quat = quat_mul(chart.frame, self.local_attitude(y))
        return (self.chart(quat_normalize(quat), chart.changes + 1),
                np.concatenate([np.zeros(3), gibbs.recentre_velocity(y[:3], y[3:])]))

    def omega(self, y):
        y = np.asarray(y)
        return gibbs.omega_body(y[..., :3], y[..., 3:])

    def _local_one(self, y):
        q1, q2, q3, d1, d2, d3 = y
        c = 2.0 / (1.0 + q1 * q1 + q2 * q2 + q3 * q3)  # ω = ρ̄ q̇ (F5)
        omega = (c * (d1 - (q2 * d3 - q3 * d2)), c * (d2 - (q3 * d1 - q1 * d3)), c * (d3 - (q1 * d2 - q2 * d1)))
        return self._quat_one(q1, q2, q3), omega

    def rhs(self, t, chart, y):
        q, qdot = y[..., :3], y[..., 3:]
        return np.concatenate([qdot, gibbs.lagrangian_acceleration(q, qdot, self.sigma, self.weight_moment, chart.down,
                                                                   self.sigma_inv,
                                                                   self.external_torque(t, chart, y))], axis=-1)

    @classmethod
    def equations(cls):
        return gibbs.lagrangian_equations()


class GibbsHamiltonian(_Gibbs):
    """Ferrarese's Hamiltonian form (18)–(19); state (q, p)."""

    name = "gibbs_hamiltonian"
    state_labels = ("q1", "q2", "q3", "p1", "p2", "p3")

    def local_state(self, quat_local, omega):
        q = self._gibbs(quat_local)
        return np.concatenate([q, gibbs.momentum_from_omega(q, omega, self.sigma)], axis=-1)

    def omega(self, y):
        y = np.asarray(y)
        return gibbs.omega_from_momentum(y[..., :3], y[..., 3:], self.sigma_inv)

    def _local_one(self, y):
        q1, q2, q3, p1, p2, p3 = y
        qp = q1 * p1 + q2 * p2 + q3 * p3  # ω = ½ σ⁻¹ Bᵀ p
        b = (p1 - (q2 * p3 - q3 * p2) + qp * q1, p2 - (q3 * p1 - q1 * p3) + qp * q2,
             p3 - (q1 * p2 - q2 * p1) + qp * q3)
        omega = tuple(0.5 * (row[0] * b[0] + row[1] * b[1] + row[2] * b[2]) for row in self._sigma_inv_rows)
        return self._quat_one(q1, q2, q3), omega

    def rhs(self, t, chart, y):
        qdot, pdot = gibbs.hamiltonian_rhs(y[..., :3], y[..., 3:], self.sigma_inv, self.weight_moment, chart.down,
                                           self.external_torque(t, chart, y))
        return np.concatenate([qdot, pdot], axis=-1)

    def rechart(self, chart: Chart, y: np.ndarray) -> tuple[Chart, np.ndarray]:
        """Re-centre on the attitude of y: Q* = 0, p* = Bᵀ p (gibbs.recentre_momentum)."""
        quat = quat_mul(chart.frame, self.local_attitude(y))
        return (self.chart(quat_normalize(quat), chart.changes + 1),
                np.concatenate([np.zeros(3), gibbs.recentre_momentum(y[:3], y[3:])]))

    def hamiltonian(self, chart: Chart, y: np.ndarray) -> np.ndarray:
        """ℋ (19) of the state(s) y in chart (J)."""
        y = np.asarray(y)
        return gibbs.hamiltonian(y[..., :3], y[..., 3:], self.sigma, self.weight_moment, chart.down)

    @classmethod
    def equations(cls):
        return gibbs.hamiltonian_equations()


class EulerZXZ(ChartedFormulation):
    """Lagrange's equations in ZXZ angles; state (φ, θ, ψ, φ̇, θ̇, ψ̇); re-charted when |sin θ| < 0.5."""

    name = "euler_zxz"
    state_labels = ("phi", "theta", "psi", "phidot", "thetadot", "psidot")
    recentre_threshold = ZXZ_RECHART
    guard_threshold = ZXZ_GUARD
    # θ stays in (0, π) inside a chart, so sin θ > 0 there: the test is sin θ < threshold, which also catches a
    # step that crossed the pole.
    event_direction = -1
    regular_state = (0.0, 0.5 * math.pi, 0.0, 0.0, 0.0, 0.0)

    def measure(self, y):
        return math.sin(y[1])

    def recentred(self, quat):
        return euler_angles.recentred_frame(quat)

    def singularity(self, y):
        pole = "0" if math.cos(y[1]) > 0 else "pi"
        return (f"gimbal lock: theta reached {pole} (within {SINGULAR_DISTANCE:g} rad, |sin theta| < "
                f"{ZXZ_GUARD:.3g}) with chart changes disabled")

    def local_state(self, quat_local, omega):
        angles = euler_angles.from_quat(quat_local)
        return np.concatenate([angles, euler_angles.rates_from_omega(angles, omega)], axis=-1)

    def local_attitude(self, y):
        return euler_angles.to_quat(np.asarray(y)[..., :3])

    def omega(self, y):
        y = np.asarray(y)
        return euler_angles.omega_body(y[..., :3], y[..., 3:])

    def _local_one(self, y):
        phi, theta, psi, phid, thetad, psid = y
        ch, sh = math.cos(0.5 * theta), math.sin(0.5 * theta)
        plus, minus = 0.5 * (phi + psi), 0.5 * (phi - psi)
        quat = (ch * math.cos(plus), sh * math.cos(minus), sh * math.sin(minus), ch * math.sin(plus))
        st, ct, sp, cp = math.sin(theta), math.cos(theta), math.sin(psi), math.cos(psi)
        omega = (phid * st * sp + thetad * cp, phid * st * cp - thetad * sp, phid * ct + psid)  # C4
        return quat, omega

    def rhs(self, t, chart, y):
        angles, rates = y[..., :3], y[..., 3:]
        return np.concatenate([rates, euler_angles.lagrange_acceleration(angles, rates, self.sigma,
                                                                         self.weight_moment, chart.down,
                                                                         self.sigma_inv,
                                                                         self.external_torque(t, chart, y))],
                              axis=-1)

    @classmethod
    def equations(cls):
        return euler_angles.lagrange_equations()


def _quat_mul_floats(a: tuple, b: tuple) -> tuple:
    """Hamilton product a ⊗ b of two quaternions given as 4 floats."""
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (aw * bw - ax * bx - ay * by - az * bz, aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx, aw * bz + ax * by - ay * bx + az * bw)


FORMULATIONS: dict[str, type[Formulation]] = {cls.name: cls for cls in (Quaternion, Gibbs, GibbsHamiltonian,
                                                                        EulerZXZ)}


def get(name: str, body: RigidBody) -> Formulation:
    """The formulation called name, bound to body; KeyError listing the valid names."""
    try:
        cls = FORMULATIONS[name]
    except KeyError:
        raise KeyError(f"unknown formulation {name!r}; valid: {', '.join(FORMULATIONS)}") from None
    return cls(body)


# --- compiled right-hand sides and Taylor integration ------------------------------------------------------------

def compiled_rhs(name: str):
    """The right-hand side of formulation `name` compiled by heyoka (hy.cfunc, compact mode) from its equations():
    called as f(y (size,), pars=(truth.parameter_count(),) Formulation.rhs_parameters(chart), time=t). Cached per
    process and set of registered torque models; heyoka's compiled functions are stateless, so threads may share
    one."""
    return _compiled_rhs(name, torque_models.models())


@functools.cache
def _compiled_rhs(name: str, registered: tuple):
    variables, rhs, _ = FORMULATIONS[name].equations()
    return hy.cfunc(rhs, variables, compact_mode=True)


# Seconds spent building each formulation's integrator in this process.
COMPILE_SECONDS: dict[str, float] = {}


def taylor_integrator(name: str, tol: float | None = None) -> tuple[object, threading.Lock]:
    """The compiled heyoka integrator of a charted formulation (tolerance tol, None: truth.TRUTH_TOL; one terminal
    event on the chart measure against parameter 18) and the lock that guards it. Compiled once per process,
    tolerance and set of registered torque models, in compact mode."""
    return _taylor_integrator(name, tol, torque_models.models())


@functools.cache
def _taylor_integrator(name: str, tol: float | None, registered: tuple) -> tuple[object, threading.Lock]:
    cls = FORMULATIONS[name]
    if not cls.charted:
        raise ValueError(f"formulation {name!r} is integrated by reference.truth")
    start = time.perf_counter()
    variables, rhs, measure = cls.equations()
    direction = hy.event_direction.positive if cls.event_direction > 0 else hy.event_direction.negative
    event = hy.t_event(measure - hy.par[ex.THRESHOLD], direction=direction)
    integrator = hy.taylor_adaptive(list(zip(variables, rhs)), np.array(cls.regular_state),
                                    tol=truth.TRUTH_TOL if tol is None else truth.check_tolerance(tol),
                                    pars=np.zeros(truth.parameter_count()), compact_mode=True, t_events=[event])
    COMPILE_SECONDS[name if tol is None else f"{name} tol={tol:g}"] = time.perf_counter() - start
    return integrator, threading.Lock()


# The compiled functions' caches, read through the public functions (as 0.2.0's functools.cache were).
compiled_rhs.cache_info = _compiled_rhs.cache_info
compiled_rhs.cache_clear = _compiled_rhs.cache_clear
taylor_integrator.cache_info = _taylor_integrator.cache_info
taylor_integrator.cache_clear = _taylor_integrator.cache_clear


@dataclass(frozen=True, eq=False)
class FormulationRun:
    """A formulation integrated by heyoka and sampled on a time grid.

    times: (n,) s. quat: (n, 4) wxyz body -> world; omega: (n, 3) rad/s body frame; both NaN after stopped_at.
    steps: Taylor steps. chart_changes: changes made (None for a formulation without charts). wall_s: propagation
    and re-charting time (compilation excluded). stopped_at: s, where a ChartSingularity ended the run (NaN if it
    ran to the end), with its message.
    states: (n, size) the formulation's own coordinates at the samples, each in its chart; frames: (n, 4) that
    chart's frame quaternion (Chart.frame). None for the quaternion formulation (its states are quat, omega).
    """

    times: np.ndarray
    quat: np.ndarray
    omega: np.ndarray
    steps: int
    chart_changes: int | None
    wall_s: float
    stopped_at: float = math.nan
    message: str = ""
    states: np.ndarray | None = None
    frames: np.ndarray | None = None


def integrate_taylor(name: str, body: RigidBody, quat0: np.ndarray, omega0: np.ndarray, times: np.ndarray, *,
                     chart_changes: bool = True, tol: float | None = None,
                     deadline: float | None = None) -> FormulationRun:
    """Integrate formulation `name` from (quat0 (4,) wxyz, omega0 (3,) rad/s body) with heyoka (tolerance tol,
    relative and absolute; None: truth.TRUTH_TOL) and sample at times ((n,) s, increasing, from 0).

    The chart's terminal event stops the propagation; the chart is re-centred and the propagation continues from
    the event time. With chart_changes False the event is the singularity guard instead, and the run stops there.
    "quaternion" at the default tolerance is the truth itself. Heyoka's time runs on across chart changes (the
    turning central field).
    Raises ValueError on bad input or a propagation that fails, truth.OutOfTime past deadline (time.monotonic()).
    """
    times = np.asarray(times, dtype=float)
    if name == Quaternion.name:
        result = truth.truth(body, quat0, omega0, times, tol=tol, deadline=deadline)
        return FormulationRun(result.times, result.quat, result.omega, result.steps, None, result.wall_s)
    formulation = get(name, body)
    if times.ndim != 1 or times.size == 0 or times[0] != 0.0 or not np.all(np.isfinite(times)) \
            or np.any(np.diff(times) <= 0.0):
        raise ValueError("times must be a non-empty, finite, strictly increasing 1-d array starting at 0")
    quat = np.full((times.size, 4), np.nan)
    omega = np.full((times.size, 3), np.nan)
    states = np.full((times.size, formulation.size), np.nan)
    frames = np.full((times.size, 4), np.nan)
    try:
        chart, y = formulation.start(quat0, omega0, chart_changes)
    except ChartSingularity as exc:
        return FormulationRun(times.copy(), quat, omega, 0, 0, 0.0, 0.0, f"{exc} at t = 0 s", states, frames)
    integrator, lock = taylor_integrator(name, tol)
    steps, filled, now, stopped_at, message = 0, 0, 0.0, math.nan, ""
    with lock:
        integrator.time = 0.0
        integrator.state[:] = y
        integrator.pars[:] = formulation.parameters(chart, chart_changes)
        start = time.perf_counter()
        while filled < times.size:
            # propagate_grid wants the grid to start at the current time; that point is a sample only at t = 0.
            sample_now = times[filled] == now
            grid = times[filled:] if sample_now else np.concatenate([[now], times[filled:]])
            outcome, _, _, taken, _, samples = integrator.propagate_grid(grid, callback=truth.step_callback(deadline))
            truth.stopped_at_deadline(outcome, f"{name} propagation", float(integrator.time))
            steps += int(taken)
            samples = np.asarray(samples)[0 if sample_now else 1:]
            if samples.shape[0]:
                taken_now = slice(filled, filled + samples.shape[0])
                quat[taken_now], omega[taken_now] = formulation.observe(chart, samples)
                states[taken_now], frames[taken_now] = samples, chart.frame
                filled += samples.shape[0]
            if outcome == hy.taylor_outcome.time_limit:
                break
            if outcome.value != -1:  # terminal event 0 is reported as -1; anything else is a failure
                raise ValueError(f"{name} propagation stopped with outcome {outcome} at t = {integrator.time}")
            now = float(integrator.time)
            state = np.array(integrator.state)
            if not chart_changes:
                stopped_at, message = now, f"{formulation.singularity(state)} at t = {now:.6g} s"
                break
            chart, state = formulation.rechart(chart, state)
            integrator.state[:] = state
            integrator.pars[:] = formulation.parameters(chart)
        wall = time.perf_counter() - start
    if not np.isnan(stopped_at):
        quat[filled:], omega[filled:] = np.nan, np.nan
    elif not (np.all(np.isfinite(quat)) and np.all(np.isfinite(omega))):
        raise ValueError(f"{name} propagation produced non-finite or missing samples")
    return FormulationRun(times.copy(), quat, omega, steps, chart.changes, wall, stopped_at, message, states, frames)
