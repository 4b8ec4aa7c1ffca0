"""The core types every layer shares: a run's Status, its recorded Trajectory, and the divergence rule, which
`judged` applies to whatever a simulation's run() returned (harness.run.measure: every engine's, built-in or plug-in).

Integrators, engines, metrics and the store all import this module; it imports nothing of stereodyn's but the grid.
"""
from __future__ import annotations

import dataclasses
import enum
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Callable

import numpy as np

from ..reference import plugins

if TYPE_CHECKING:
    from .grid import TimeGrid


class Status(str, enum.Enum):
    OK = "ok"
    DIVERGED = "diverged"
    FAILED = "failed"
    SKIPPED = "skipped"


# A state whose angular speed passes this many times the initial scale (plus 1 rad/s) counts as diverged:
# no conservative motion of these scenes gets anywhere near it, and NaN follows soon after anyway.
DIVERGENCE_FACTOR = 1e6


@dataclass(frozen=True, eq=False)
class Trajectory:
    """States recorded on a TimeGrid's sample times.

    times: (n,) s.
    quat: (n, 4) attitude quaternion, scalar first (w, x, y, z), body -> world, as the engine left it (not renormalised).
    omega: (n, 3) rad/s, body frame.
    After a divergence the remaining samples are NaN and diverged_at (s) is the first time a state was bad.
    steps: steps taken; rhs_evals: right-hand-side (dynamics) evaluations, where the engine counts them.
    chart_changes: changes of attitude chart made by a formulation with charts (None where there are none).
    """

    times: np.ndarray
    quat: np.ndarray
    omega: np.ndarray
    status: Status = Status.OK
    message: str = ""
    diverged_at: float = float("nan")
    steps: int = 0
    rhs_evals: int = 0
    info: dict = field(default_factory=dict)
    chart_changes: int | None = None


def divergence_limit2(omega0) -> float:
    """The square of the divergence rule's limit on |omega| (rad/s)^2 for a run that starts at omega0 (3,)."""
    w0, w1, w2 = (float(w) for w in omega0)
    return (DIVERGENCE_FACTOR * (1.0 + math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)))**2


def sample_good(quat, omega, limit2: float) -> bool:
    """The divergence rule on one sample (4 and 3 floats), in float arithmetic: cheap enough for the per-sample hot
    path of harness.integrators.base. A sample is good when |omega|^2 <= limit2 and the quaternion is finite."""
    w0, w1, w2 = omega
    # NaN and inf fail the comparison, so it also catches a non-finite omega; a sum of the quaternion's components is
    # finite exactly when all of them are (inf - inf is NaN).
    return w0 * w0 + w1 * w1 + w2 * w2 <= limit2 and math.isfinite(quat[0] + quat[1] + quat[2] + quat[3])


def samples_good(quat: np.ndarray, omega: np.ndarray, limit2) -> np.ndarray:
    """sample_good row by row: quat (n, 4), omega (n, 3), limit2 a float or (n,); a bool (n,) array."""
    with np.errstate(invalid="ignore", over="ignore"):
        return (np.einsum("ij,ij->i", omega, omega) <= limit2) & np.isfinite(quat.sum(axis=1))


def first_bad_sample(omega: np.ndarray, quat: np.ndarray, omega0: np.ndarray) -> int | None:
    """Index of the first sample that breaks the divergence rule (not finite, or |omega| beyond DIVERGENCE_FACTOR
    times (1 + |omega0|)), else None."""
    hits = np.flatnonzero(~samples_good(np.asarray(quat, dtype=float), np.asarray(omega, dtype=float),
                                        divergence_limit2(omega0)))
    return int(hits[0]) if hits.size else None


def first_bad_step(step, observe, g, v, start: int, end: int, dt: float, limit2: float) -> tuple[int, object]:
    """Replay a stepper step(t, g, v) -> (g, v) from the last good sample (step index start, state (g, v)) to the
    first step whose state breaks the rule (observe(g, v) gives its quaternion and omega floats) or whose step raises
    ArithmeticError: that step's index, and the g of the state before it. Step k starts at t = k * dt."""
    for index in range(start + 1, end + 1):
        try:
            g_next, v = step((index - 1) * dt, g, v)
        except ArithmeticError:
            return index, g
        if not sample_good(*observe(g_next, v), limit2):
            return index, g
        g = g_next
    return end, g  # not reached for a deterministic step; the sample itself is the bound


# The quaternion is as the engine left it (not renormalised): one whose norm grew or shrank by the divergence factor
# is no attitude any more (a plug-in's 1e150 gave |q|^2 - 1 = 1e300, which no reader accepts; 0 gave an ok row with
# no attitude error: issue 46's eighth attack). Applied after the run (judged), not in the engines' stepping loops:
# the largest |q|^2 of an ok row of the default suite is 721 (explicit Euler, 2026-12-04), far inside.
QUAT_NORM_FACTOR = DIVERGENCE_FACTOR


def _first_bad_norm(quat: np.ndarray) -> int | None:
    """Index of the first sample whose quaternion's norm is outside [1 / QUAT_NORM_FACTOR, QUAT_NORM_FACTOR]
    (NaN: not this rule's), else None."""
    with np.errstate(over="ignore", invalid="ignore"):
        norm2 = np.einsum("ij,ij->i", quat, quat)
    hits = np.flatnonzero((norm2 > QUAT_NORM_FACTOR ** 2) | (norm2 < QUAT_NORM_FACTOR ** -2))
    return int(hits[0]) if hits.size else None


def divergence_message(diverged_at: float) -> str:
    """The divergence rule's message for a run that broke it at diverged_at (s)."""
    return f"state not finite or |omega| beyond {DIVERGENCE_FACTOR:g} x its start at t = {diverged_at:.6g} s"


def norm_message(diverged_at: float) -> str:
    """The quaternion-norm rule's message (_first_bad_norm) for a run that broke it at diverged_at (s)."""
    return (f"quaternion norm outside [{1 / QUAT_NORM_FACTOR:g}, {QUAT_NORM_FACTOR:g}] (no attitude) at "
            f"t = {diverged_at:.6g} s")


def diverged_trajectory(grid: "TimeGrid", quat: np.ndarray, omega: np.ndarray, bad: int, diverged_at: float,
                        steps: int, rhs_evals: int = 0, message: str | None = None) -> Trajectory:
    """A Trajectory whose samples from `bad` on are NaN, with status diverged and message (default: the divergence
    rule's)."""
    quat, omega = quat.copy(), omega.copy()
    quat[bad:] = np.nan
    omega[bad:] = np.nan
    if message is None:
        message = divergence_message(diverged_at)
    return Trajectory(grid.times, quat, omega, Status.DIVERGED, message, diverged_at, steps, rhs_evals)


def _real(array: np.ndarray) -> bool:
    """Whether an array holds real numbers (integers or floats; not text, objects, booleans or complex)."""
    return np.issubdtype(array.dtype, np.integer) or np.issubdtype(array.dtype, np.floating)


def _array_problem(name: str, value, shape: tuple) -> str | None:
    """Why `value` is not a real numeric array of `shape`, or None."""
    try:  # an SDK's array type (JAX's, Warp's) reads as numpy's
        array = np.asarray(value) if isinstance(value, (list, tuple)) or hasattr(value, "__array__") else None
    except Exception:  # an array-like that does not convert is no array of numbers
        array = None
    if array is None or not _real(array):
        return f"{name} is {type(value).__name__}, not an array of numbers"
    if array.shape != shape:
        return f"{name} has shape {array.shape}, not {shape} ({shape[0]} samples)"
    return None


# The most steps or right-hand-side evaluations a run can report: 1e15 is some 11 days of one run at 1e9 evaluations a
# second; divided by the shortest t_end a case may have (1e-9 s, docs/limits.md) it stays far below the 1e100 every
# reader of results.csv accepts (harness.tables.MAX_VALUE). A larger count (inf, 10**200) made rhs_per_sim_s a number
# no reader accepts: the run ended as "a bug in stereodyn" (issue 46's second attack).
MAX_COUNT = 1e15


def problem(traj, times: np.ndarray, expected: type | None = None) -> str | None:
    """Why what a simulation's run() returned is no trajectory on its grid's sample `times` ((n,) s), or None: an
    object of the scene's class (expected; None: any with the fields below), a Status, a message in words, arrays of
    numbers of one row per sample (Trajectory: times, quat (n, 4), omega (n, 3); SlidingLadderTrajectory: times,
    state (n, 6), violation (n,)), and its times the grid's (_times_problem). A plug-in's answer is checked before any
    metric reads it (its bug is its row)."""
    samples = len(times)
    if expected is not None and not isinstance(traj, expected):
        return f"returned {type(traj).__name__}, not a {expected.__name__}"
    if not isinstance(getattr(traj, "status", None), Status):
        return f"returned {type(traj).__name__}, whose status is not a Status"
    whose = f"returned a {type(traj).__name__} whose"
    if not isinstance(getattr(traj, "message", ""), str):
        return f"{whose} message is {type(traj.message).__name__}, not text"
    shapes = {"times": (samples,)}
    if isinstance(traj, Trajectory):
        shapes.update(quat=(samples, 4), omega=(samples, 3))
    elif isinstance(traj, SlidingLadderTrajectory):
        shapes.update(state=(samples, 6), violation=(samples,))
    for name, shape in shapes.items():
        why = _array_problem(name, getattr(traj, name, None), shape)
        if why is not None:
            return f"{whose} {why}"
    why = _times_problem(np.asarray(traj.times, dtype=float), np.asarray(times, dtype=float))
    if why is not None:
        return f"{whose} {why}"
    for name in ("steps", "rhs_evals"):
        value = getattr(traj, name, 0)
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)) \
                or not 0 <= value <= MAX_COUNT:  # an SDK's integer type or a float count is read as a count; text,
            return f"{whose} {name} is {plugins.text_of(value, repr)}, not a count"  # -1, NaN, inf or 1e200 is not
    if not isinstance(getattr(traj, "info", {}), dict):
        return f"{whose} info is {type(traj.info).__name__}, not a dict"
    if traj.status is Status.DIVERGED and _divergence_time(traj) is None:  # a diverged row says when (issue 46, F11)
        at = plugins.shown(getattr(traj, "diverged_at", None), 40)
        return (f"{whose} status is diverged at diverged_at = {at}, not a time of its grid, and no sample breaks "
                "the divergence rule")
    return None


ARRAYS = ("times", "quat", "omega", "state", "violation")  # a trajectory's per-sample fields (problem checks them)


def as_arrays(traj):
    """traj with its per-sample fields (ARRAYS) as float numpy arrays: a plug-in's lists, tuples or integer arrays,
    which problem() accepts as numbers of the right shape, were a traceback in the metrics, exit 3 "a bug in
    stereodyn" (issue 46's twelfth attack), and so was an ndarray subclass (np.matrix: the fourteenth). A plain
    floating numpy array is left as it is (a float32 run's stay float32)."""
    if not dataclasses.is_dataclass(traj):
        return traj
    fields = {f.name for f in dataclasses.fields(traj)}
    changed = {name: _plain(getattr(traj, name)) for name in ARRAYS if name in fields
               and not (type(getattr(traj, name)) is np.ndarray
                        and np.issubdtype(getattr(traj, name).dtype, np.floating))}
    return dataclasses.replace(traj, **changed) if changed else traj


def _plain(value) -> np.ndarray:
    """value as a plain ndarray: of its own floating type, else float."""
    floating = isinstance(value, np.ndarray) and np.issubdtype(value.dtype, np.floating)
    return np.asarray(value, dtype=value.dtype if floating else float)


def _times_problem(got: np.ndarray, grid: np.ndarray) -> str | None:
    """Why a trajectory's times are not its grid's sample times, or None. Every metric compares sample i with the
    truth at the grid's time i: reversed or shifted times gave an ok row with wrong errors (issue 46's tenth attack).
    Within a thousandth of the grid's smallest spacing (a time summed step by step drifts by some 1e-12 s; the next
    sample is a whole spacing away), or 1e-9 of the span for a grid of one sample."""
    if not got.size:
        return None
    gaps = np.diff(grid)
    tolerance = 1e-3 * float(gaps.min()) if gaps.size else 1e-9 * max(1.0, abs(float(grid[-1])))
    off = np.abs(got - grid)
    if not np.isfinite(got).all() or off.max() > tolerance:
        i = int(np.argmax(~np.isfinite(got) | (off > tolerance)))
        return f"times[{i}] is {float(got[i])!r:.25}, not the grid's sample time {float(grid[i])!r:.25} s"
    return None


def _divergence_time(traj) -> float | None:
    """When a diverged trajectory diverged: its diverged_at where that is a time of its span, else its first sample
    that breaks the divergence rule; None where neither says."""
    times = np.asarray(traj.times, dtype=float)
    at = getattr(traj, "diverged_at", math.nan)
    if isinstance(at, (int, float, np.integer, np.floating)) and not isinstance(at, (bool, np.bool_)) \
            and times[0] <= at <= times[-1] + 1e-9 * max(1.0, abs(times[-1])):
        return float(at)
    first = _first_bad(traj)
    return None if first is None else float(times[first[0]])


def _first_bad(traj, omega0=None) -> tuple[int, Callable[[float], str]] | None:
    """The first sample that breaks the divergence rule and the rule's message: a Trajectory's by first_bad_sample
    (the scale: omega0, the case's initial rad/s (3,), where given, else its first sample's) or by its quaternion's
    norm (_first_bad_norm), any other's first row of `state` with a value not finite; None where none does (or it has
    no state)."""
    if isinstance(traj, Trajectory):
        quat, omega = np.asarray(traj.quat, dtype=float), np.asarray(traj.omega, dtype=float)
        hits = [(first_bad_sample(omega, quat, omega[0] if omega0 is None else omega0), divergence_message),
                (_first_bad_norm(quat), norm_message)]
        return min(((i, said) for i, said in hits if i is not None), key=lambda hit: hit[0], default=None)
    state = getattr(traj, "state", None)
    if not isinstance(state, np.ndarray) or not _real(state) or state.ndim < 1:
        return None
    rows = np.isfinite(state.reshape(len(state), -1)).all(axis=1)
    hits = np.flatnonzero(~rows)
    return (int(hits[0]), divergence_message) if hits.size else None


def judged(traj, omega0=None):
    """traj with the divergence rule applied (_first_bad; omega0: the case's initial rad/s (3,), the scale of |omega|,
    so that a first sample of 1e300 rad/s is no scale of its own): an ok trajectory with a sample that breaks it
    becomes diverged at that sample's time, its samples from there on NaN (the rule as an integrator applies it, for
    every engine; an engine that finds the exact step sets diverged itself). Others unchanged."""
    fields = {f.name for f in dataclasses.fields(traj)} if dataclasses.is_dataclass(traj) else set()
    if not {"status", "message", "diverged_at"} <= fields:
        return traj
    if traj.status is Status.DIVERGED:  # an engine's own verdict, with its time (from its states where it gave none)
        at = _divergence_time(traj)
        return traj if at is None or at == traj.diverged_at else dataclasses.replace(traj, diverged_at=at)
    if traj.status is not Status.OK:
        return traj
    first = _first_bad(traj, omega0)
    if first is None:
        return traj
    bad, said = first
    at = float(np.asarray(traj.times, dtype=float)[bad])
    blanked = {}
    for name in {"quat", "omega", "state"} & fields:
        value = getattr(traj, name)
        if isinstance(value, np.ndarray):
            value = value.astype(float)  # a copy: the engine's arrays stay as they were
            value[bad:] = np.nan
            blanked[name] = value
    return dataclasses.replace(traj, **blanked, status=Status.DIVERGED,
                               message=said(at), diverged_at=at)


@dataclass(frozen=True, eq=False)
class SlidingLadderTrajectory:
    """The sliding ladder's recorded states (harness.scenes.sliding_ladder): not a body with a fixed point.

    times: (n,) s. state: (n, 6) x, y (m, centre of the rod; wall x = 0, floor y = 0), θ (rad from the wall), and
    their rates (m/s, rad/s). violation: (n,) m, how far the model's ends are off the wall and floor (bilateral:
    the equality residual; unilateral: the contacts' penetration). detach_angle: rad, θ where the wall's push on the
    top reached zero (NaN where not measured).
    """

    times: np.ndarray
    state: np.ndarray
    violation: np.ndarray
    status: Status = Status.OK
    message: str = ""
    diverged_at: float = float("nan")
    steps: int = 0
    detach_angle: float = float("nan")
    info: dict = field(default_factory=dict)
