"""The certified truth: Taylor integration (heyoka) of Euler–Poisson with a quaternion attitude.

State (w, x, y, z, ω1, ω2, ω3): scalar-first quaternion, angular velocity in body components (DESIGN §2).
Runtime parameters: inertia about O (6: σ11, σ22, σ33, σ12, σ13, σ23), its inverse (same layout), m g c (3, body
frame) and the world downward direction d (3); index 18 is unused (the charted formulations' event threshold), then
the parameter blocks of every registered torque model (reference.torque_models, in registry order: torque_parameters),
so one compiled integrator per precision serves every body and every scene. It is compiled on first use and cached
in the module (per set of registered models); each call resets its time, state and parameters.

The attitude matrix inside the right-hand side is the homogeneous quadratic form of q (no division by |q|²): the
kinematics q̇ = ½ q ⊗ (0, ω) conserve |q| exactly, so this is R(q) to the integrator's tolerance and keeps the
right-hand side polynomial. The compiled right-hand side of the quaternion formulation (reference.formulations,
what the reference engine's fixed-step integrators step) is these equations too: off the unit sphere it is not
reference.euler_poisson's numpy form, which normalises q (the difference is documented there and pinned by
tests/test_quaternion_rhs.py).

An integrator holds mutable state: each process compiles its own, and a lock serialises threads within one.
"""
from __future__ import annotations

import functools
import math
import threading
import time
from dataclasses import dataclass

import heyoka as hy
import numpy as np

from .body import RigidBody
from .deadline import OutOfTime  # noqa: F401 (its path before issue 29; reference.* raise it)
from .rotations import attitude_angle, quat_to_matrix
from .torque_models import At, components, models

TRUTH_TOL = 1e-16       # double precision; the issue requires <= 1e-15
TRUTH_TOL_QUAD = 1e-32  # real128 (about 34 significant digits)
# Taylor steps one truth may take: the suite's truths take 6-2205 (long-horizon, 1000 s; measured on the 2-core
# dev machine), ~10 µs each; a body whose motion needs more (a torque far above its inertia's scale) is reported as
# not representable in ~10 s instead of running for hours.
MAX_TRUTH_STEPS = 1_000_000

PRECISIONS = ("double", "quad")


def step_callback(deadline: float | None):
    """heyoka's step callback that stops a propagation once time.monotonic() passes deadline; None without one."""
    if deadline is None:
        return None
    clock = time.monotonic
    return lambda integrator: clock() <= deadline


def stopped_at_deadline(outcome, what: str, reached: float) -> None:
    """Raise OutOfTime when a propagation's outcome is the step callback's stop."""
    if outcome == hy.taylor_outcome.cb_stop:
        raise OutOfTime(f"{what} stopped at its wall-time deadline at t = {reached:.6g} s")

_FP_TYPE = {"double": float, "quad": hy.real128}
_TOLERANCE = {"double": TRUTH_TOL, "quad": TRUTH_TOL_QUAD}
# Upper-triangle index pairs of a symmetric 3x3 matrix, in the parameter layout above.
_SYMMETRIC_ENTRIES = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))
# The torque models' parameter blocks follow the 18 of the body and gravity and the unused index 18; each model
# declares its block (TorqueModel.parameters, absent): for the built-ins 19..23 the body torque, 24..34 the central
# field, 35..39 torque (41).
TORQUE_OFFSET = 19


def parameter_count() -> int:
    """The runtime parameters of every formulation's heyoka systems (reference.formulations): TORQUE_OFFSET and the
    registered models' blocks."""
    return TORQUE_OFFSET + sum(model.parameter_count for model in models())


@dataclass(frozen=True, eq=False)
class TruthResult:
    """A truth trajectory sampled on a given time grid.

    times: (n,) s, the requested grid (times[0] = 0).
    quat: (n, 4) unit quaternion (w, x, y, z), body -> world, float64 (rounded from real128 for precision "quad").
    omega: (n, 3) rad/s, body frame, float64.
    steps: Taylor steps taken.
    wall_s: s, propagation time only (compilation excluded).
    """

    times: np.ndarray
    quat: np.ndarray
    omega: np.ndarray
    steps: int
    wall_s: float


def _symmetric(offset: int) -> list[list]:
    """3x3 matrix of expressions from 6 parameters starting at offset."""
    entry = {pair: hy.par[offset + i] for i, pair in enumerate(_SYMMETRIC_ENTRIES)}
    return [[entry[(min(i, j), max(i, j))] for j in range(3)] for i in range(3)]


def _cross(a, b) -> list:
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def equations() -> list[tuple]:
    """Euler–Poisson + quaternion kinematics as heyoka (variable, right-hand side) pairs in the runtime parameters
    above (FORMULARY §0, G3; the torques of reference.torques, G12–G15)."""
    w, x, y, z, o1, o2, o3 = hy.make_vars("w", "x", "y", "z", "o1", "o2", "o3")
    v, omega = [x, y, z], [o1, o2, o3]
    sigma = _symmetric(0)
    sigma_inv = _symmetric(6)
    weight_moment = [hy.par[12], hy.par[13], hy.par[14]]
    down = [hy.par[15], hy.par[16], hy.par[17]]

    # H = Rᵀ d with R = (w² - v·v) I + 2 v vᵀ + 2 w [v]×.
    v_dot_d = _dot(v, down)
    v_cross_d = _cross(v, down)
    scalar = w * w - _dot(v, v)
    vertical = [scalar * down[i] + 2.0 * v_dot_d * v[i] - 2.0 * w * v_cross_d[i] for i in range(3)]

    momentum = [_dot(sigma[i], omega) for i in range(3)]
    gyroscopic = _cross(momentum, omega)
    gravity = _cross(weight_moment, vertical)
    external = torque_expressions(w, v, omega, sigma)
    torque = [gyroscopic[i] + gravity[i] + external[i] for i in range(3)]
    omega_dot = [_dot(sigma_inv[i], torque) for i in range(3)]

    # q̇ = ½ q ⊗ (0, ω)
    v_cross_omega = _cross(v, omega)
    quat_dot = [-0.5 * _dot(v, omega)] + [0.5 * (w * omega[i] + v_cross_omega[i]) for i in range(3)]
    return list(zip([w, x, y, z, o1, o2, o3], quat_dot + omega_dot))


def _body_components(w, v, vector) -> list:
    """Rᵀ x for R = (w² - v·v) I + 2 v vᵀ + 2 w [v]× (homogeneous in q, as the vertical above)."""
    v_dot_x = _dot(v, vector)
    v_cross_x = _cross(v, vector)
    scalar = w * w - _dot(v, v)
    return [scalar * vector[i] + 2.0 * v_dot_x * v[i] - 2.0 * w * v_cross_x[i] for i in range(3)]


def body_torque_expressions(body_components, omega, sigma) -> list:
    """The sum of every registered torque model's formula (reference.torque_models, body frame) as heyoka
    expressions of its parameter block: body_components(v) gives Rᵀ v for a vector v in the coordinates' frame, ω
    and σ the body's. A body without a model has that model's absent() block, whose torque vanishes. Every
    formulation's equations take them from here (reference.gibbs, reference.euler_angles)."""
    at = At(hy.time, omega, sigma, body_components, hy.sqrt, hy.cos, hy.sin)
    offset, total = TORQUE_OFFSET, None
    for model in models():
        block = [hy.par[offset + i] for i in range(model.parameter_count)]
        offset += model.parameter_count
        terms = components(model, block, at)
        total = terms if total is None else [total[i] + terms[i] for i in range(3)]
    return total if total is not None else [hy.expression(0.0)] * 3


def torque_expressions(w, v, omega, sigma) -> list:
    """body_torque_expressions() with Rᵀ from the quaternion (w, v) (homogeneous in q)."""
    return body_torque_expressions(lambda vector: _body_components(w, v, vector), omega, sigma)


def torque_parameters(body: RigidBody, frame_matrix: np.ndarray | None = None) -> np.ndarray:
    """The torque parameters (float64): every registered model's block, the body's term's or absent(), in registry
    order; frame_matrix (3, 3): the coordinates' frame in the world (identity for the quaternion formulation)."""
    blocks = []
    for model in models():
        term = body.torque(model)
        blocks.append(model.absent() if term is None else term.parameters(frame_matrix))
    return np.array([value for block in blocks for value in block], dtype=float)


# Seconds spent building each integrator in this process: ~0.17 s (double) and ~0.19 s (quad) cold, ~0.015 s when
# heyoka's on-disk JIT cache (~/.cache/heyoka) already holds the code.
COMPILE_SECONDS: dict[str, float] = {}


def taylor_integrator(precision: str = "double", tol: float | None = None) -> tuple[object, threading.Lock]:
    """The compiled heyoka integrator for a precision ("double" or "quad") and a tolerance (None: the truth's,
    TRUTH_TOL or TRUTH_TOL_QUAD), and the lock that guards it.

    Compiled once per process, tolerance and set of registered torque models (heyoka picks the Taylor order from
    the tolerance; compact mode: one small function per operation kind, so compilation is fast and independent of
    the body); the compile time is recorded in COMPILE_SECONDS[precision] (COMPILE_SECONDS[f"{precision}
    tol={tol:g}"] for another tolerance).
    """
    return _taylor_integrator(precision, tol, models())


@functools.cache
def _taylor_integrator(precision: str, tol: float | None, registered: tuple) -> tuple[object, threading.Lock]:
    if precision not in PRECISIONS:
        raise ValueError(f"precision must be one of {PRECISIONS}, got {precision!r}")
    fp_type = _FP_TYPE[precision]
    start = time.perf_counter()
    integrator = hy.taylor_adaptive(
        equations(),
        np.array([1.0, 0, 0, 0, 0, 0, 0]).astype(fp_type),
        tol=fp_type(_TOLERANCE[precision] if tol is None else check_tolerance(tol)),
        pars=np.zeros(parameter_count()).astype(fp_type),
        compact_mode=True,
        fp_type=fp_type,
    )
    COMPILE_SECONDS[precision if tol is None else f"{precision} tol={tol:g}"] = time.perf_counter() - start
    return integrator, threading.Lock()


# The compiled integrators' cache, read through the public function (as 0.2.0's functools.cache was).
taylor_integrator.cache_info = _taylor_integrator.cache_info
taylor_integrator.cache_clear = _taylor_integrator.cache_clear


def check_tolerance(tol: float) -> float:
    """tol as a float; ValueError unless it is finite and > 0 (a requested tolerance of an adaptive integrator)."""
    value = float(tol)
    if not (math.isfinite(value) and value > 0.0):
        raise ValueError(f"tolerance must be a finite number > 0, got {tol!r}")
    return value


def _parameters(body: RigidBody, fp_type) -> np.ndarray:
    """The runtime parameters, computed in the integrator's precision.

    The inverse inertia is the adjugate over the determinant in that precision, so a quadruple-precision run sees
    the body itself and not a double-rounded inverse (this matters on unstable invariant manifolds such as Hess').
    """
    sigma = np.asarray(body.inertia, dtype=float).astype(fp_type)
    cof = np.empty((3, 3), dtype=sigma.dtype)
    for i in range(3):
        for j in range(3):
            r = [k for k in range(3) if k != i]
            c = [k for k in range(3) if k != j]
            cof[i, j] = (sigma[r[0], c[0]] * sigma[r[1], c[1]] - sigma[r[0], c[1]] * sigma[r[1], c[0]]) \
                * (1 if (i + j) % 2 == 0 else -1)
    det = sigma[0, 0] * cof[0, 0] + sigma[0, 1] * cof[0, 1] + sigma[0, 2] * cof[0, 2]
    inverse = cof.T / det
    mass_gravity = fp_type(float(body.mass)) * fp_type(float(body.gravity))
    weight_moment = np.asarray(body.com, dtype=float).astype(fp_type) * mass_gravity
    down = np.asarray(body.gravity_direction, dtype=float).astype(fp_type)
    return np.concatenate([np.array([sigma[i, j] for i, j in _SYMMETRIC_ENTRIES]),
                           np.array([inverse[i, j] for i, j in _SYMMETRIC_ENTRIES]),
                           weight_moment, down, np.zeros(1).astype(fp_type),
                           torque_parameters(body).astype(fp_type)])


def truth(body: RigidBody, quat0: np.ndarray, omega0: np.ndarray, times: np.ndarray, *,
          precision: str = "double", tol: float | None = None, deadline: float | None = None) -> TruthResult:
    """Integrate from (quat0 (4,) wxyz, omega0 (3,) rad/s body) and sample at times ((n,) s, increasing, from 0).

    precision "double" (tolerance TRUTH_TOL) or "quad" (heyoka real128, TRUTH_TOL_QUAD; results rounded to float64);
    tol: another tolerance (relative and absolute, heyoka's tol), e.g. a loose one for a tolerance ladder: the run
    is then no truth. quat0 is normalised in the working precision. Raises ValueError on bad input or an
    unsuccessful propagation, OutOfTime when time.monotonic() passes deadline (None: no deadline) before the end.
    """
    integrator, lock = taylor_integrator(precision, tol)
    fp_type = _FP_TYPE[precision]
    times = np.asarray(times, dtype=float)
    quat0 = np.asarray(quat0, dtype=float)
    omega0 = np.asarray(omega0, dtype=float)
    if times.ndim != 1 or times.size == 0 or times[0] != 0.0 or not np.all(np.isfinite(times)) \
            or np.any(np.diff(times) <= 0.0):
        raise ValueError("times must be a non-empty, finite, strictly increasing 1-d array starting at 0")
    if quat0.shape != (4,) or omega0.shape != (3,) or not (np.all(np.isfinite(quat0))
                                                           and np.all(np.isfinite(omega0))):
        raise ValueError(f"quat0 must be finite with shape (4,) and omega0 with shape (3,), "
                         f"got {quat0.shape} and {omega0.shape}")
    quat_wp = quat0.astype(fp_type)
    norm = np.sqrt(np.sum(quat_wp * quat_wp))
    if not norm > 0:
        raise ValueError("quat0 must be non-zero")
    state = np.concatenate([quat_wp / norm, omega0.astype(fp_type)])

    with lock:
        integrator.time = fp_type(0.0)
        integrator.state[:] = state
        integrator.pars[:] = _parameters(body, fp_type)
        start = time.perf_counter()
        outcome, _, _, steps, _, samples = integrator.propagate_grid(times.astype(fp_type),
                                                                     max_steps=MAX_TRUTH_STEPS,
                                                                     callback=step_callback(deadline))
        wall = time.perf_counter() - start
        reached = float(integrator.time)
    stopped_at_deadline(outcome, f"truth propagation ({precision})", reached)
    # propagate_grid reports time_limit when it reached the last grid point.
    if outcome == hy.taylor_outcome.step_limit:
        raise ValueError(f"truth propagation ({precision}) took more than {MAX_TRUTH_STEPS} Taylor steps before "
                         f"t = {times[-1]:g}: the motion's rates are beyond what this tolerance resolves in time")
    if outcome != hy.taylor_outcome.time_limit:
        raise ValueError(f"truth propagation ({precision}) stopped with outcome {outcome} before t = {times[-1]}; "
                         "the motion is not representable (non-finite state) at this tolerance")
    samples = np.asarray(samples).astype(float)
    if samples.shape[0] != times.size or not np.all(np.isfinite(samples)):
        raise ValueError(f"truth propagation ({precision}) produced non-finite or missing samples")
    return TruthResult(times=times.copy(), quat=samples[:, :4], omega=samples[:, 4:], steps=int(steps),
                       wall_s=wall)


# The truth's error bounds (truth_bound). u: the unit round-off of float64.
UNIT_ROUNDOFF = 2.0 ** -53
# ANGLE_ROUNDING: how far reference.rotations.attitude_angle(quat_to_matrix(q1), quat_to_matrix(q2)), evaluated in
# float64, can be from the true angle between the rotations of two float64 quaternions at the small angles met here
# (1e-16..1e-12 rad). Its error is absolute (the matrix entries are O(1), each rounded to ~u), not relative to the
# angle.
# Measured: at most 8.9 u over 2e5 random unit pairs (numpy, AMD EPYC, against mpmath at 40 digits); 16 u leaves ~1.8x
# headroom. (Adding up every rounding of the normalisation, the 9 entries and the Frobenius norm gives ~85 u; those
# errors never align in practice, and a bound 5x the measured worst would swamp the truth's own ~1e-14 rad.)
ANGLE_ROUNDING = 16 * UNIT_ROUNDOFF
# truth_err = max_t a(t) + ATTITUDE_ALLOWANCE, with a(t) = attitude_angle between the double truth q_d and the real128
# truth q_q rounded to float64 (q̃_q), both in float64. It bounds both the double truth's true error e and what anyone
# measures in float64 against a reference R correct to >= 20 digits (e.g. mpmath at 40), rounded to float64:
#   e       <= angle(q_d, q_q) + ε_q                       ε_q: the real128 truth's own error (tolerance 1e-32; < 1e-25)
#           <= angle(q_d, q̃_q) + 2u + ε_q                  rounding q_q to float64 moves each component by <= u|q|,
#                                                           its rotation by <= 2u rad
#           <= a + ANGLE_ROUNDING + 2u + ε_q               our comparison's own rounding
#   measured = attitude_angle(q_d, R̃) <= e + 2u + ANGLE_ROUNDING   (the reference's rounding and that comparison's)
# hence ATTITUDE_ALLOWANCE = 2 ANGLE_ROUNDING + 4u (+ ε_q, below u): 36 u = 4.0e-15 rad.
ATTITUDE_ALLOWANCE = 2 * ANGLE_ROUNDING + 4 * UNIT_ROUNDOFF
# truth_omega_err = max_t |ω_d - ω̃_q| / max_t |ω̃_q| + OMEGA_ALLOWANCE (relative, as metrics.errors' omega_err). The
# subtraction of two close float64 vectors is exact (Sterbenz); rounding ω_q to float64 (ours) and the auditor's
# reference to float64 each move a component by <= u |ω_i|, i.e. <= u max|ω| in norm: 2u; the norm and the division
# add a few u *relative to the tiny difference*, far below u. 4u leaves 2x headroom.
OMEGA_ALLOWANCE = 4 * UNIT_ROUNDOFF


@dataclass(frozen=True)
class TruthBound:
    """Bounds on the double-precision truth's error on a time grid (truth_bound).

    attitude: rad, on the geodesic angle between its attitude and the exact one; omega: relative, on
    max |ω - ω_exact| / max |ω_exact|. Both include the allowance for a float64 comparison (ATTITUDE_ALLOWANCE,
    OMEGA_ALLOWANCE), so they hold for anyone's float64 check against a reference correct to >= 20 digits.
    """

    attitude: float
    omega: float


def truth_bound(body: RigidBody, quat0: np.ndarray, omega0: np.ndarray, times: np.ndarray,
                deadline: float | None = None) -> TruthBound:
    """The bounds of the double truth's error over `times`, from a quadruple-precision (real128) rerun (derivation
    above ATTITUDE_ALLOWANCE). Costs one real128 propagation: ~0.1-0.3 s for the suite's cases. OutOfTime past
    deadline (time.monotonic())."""
    double = truth(body, quat0, omega0, times, precision="double", deadline=deadline)
    quad = truth(body, quat0, omega0, times, precision="quad", deadline=deadline)
    attitude = float(np.max(attitude_angle(quat_to_matrix(double.quat), quat_to_matrix(quad.quat))))
    scale = float(np.max(np.linalg.norm(quad.omega, axis=1))) or 1.0
    omega = float(np.max(np.linalg.norm(double.omega - quad.omega, axis=1))) / scale
    return TruthBound(attitude + ATTITUDE_ALLOWANCE, omega + OMEGA_ALLOWANCE)


def truth_error(body: RigidBody, quat0: np.ndarray, omega0: np.ndarray, times: np.ndarray) -> float:
    """The bound (rad) on the double truth's attitude error over times: truth_bound(...).attitude."""
    return truth_bound(body, quat0, omega0, times).attitude
