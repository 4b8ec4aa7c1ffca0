"""The sliding ladder (FORMULARY T5, seed 001 Example 7): a uniform rod of length 2ℓ whose top slides down a
frictionless wall (the axis Oy) and whose foot slides along a frictionless floor (Ox), θ measured from the wall.

While both ends touch: θ̈ = 3g/(4ℓ) sin θ (5.23), E = (2/3) m ℓ² θ̇² + m g ℓ cos θ, and the wall pushes with
Φ1 = m ℓ (θ̈ cos θ − θ̇² sin θ) = m ℓ sin θ (3g/(4ℓ) cos θ − θ̇²) (5.21), the floor with
Φ2 = m g − m ℓ (θ̈ sin θ + θ̇² cos θ) (corrected 5.22). Φ1 changes sign where cos θ = (2/3) cos θ0 + 4ℓθ̇0²/(9g)
(from rest: (2/3) cos θ0): a wall that can only push lets the top go there.

Planar state of the rod for every model (the equation, or an engine's free rod): centre G = (x, y), the angle θ of the
rod from the vertical (foot at G + ℓ(sin θ, −cos θ)), and their rates; energy ½ m |v_G|² + ½ (m ℓ²/3) θ̇² + m g y.
"""
from __future__ import annotations

import functools
import math
import threading
from dataclasses import dataclass

import heyoka as hy
import numpy as np

from .truth import step_callback, stopped_at_deadline

# The Taylor tolerance of the reference ladder: machine precision, as the truth's.
LADDER_TOL = 1e-16


@dataclass(frozen=True)
class Ladder:
    """mass kg; half_length ℓ m; theta0 rad from the wall; theta_dot0 rad/s; g m/s²."""

    mass: float
    half_length: float
    theta0: float
    theta_dot0: float
    g: float


@dataclass(frozen=True, eq=False)
class LadderMotion:
    """The equation's motion at times (n,) s: theta (n,) rad, theta_dot (n,) rad/s; detach_time s and detach_angle
    rad where Φ1 = 0 (NaN if not reached within the span), found by a heyoka event."""

    times: np.ndarray
    theta: np.ndarray
    theta_dot: np.ndarray
    detach_time: float
    detach_angle: float


def detachment_cosine(ladder: Ladder) -> float:
    """cos θ where Φ1 = 0 on the equation's motion: (2/3) cos θ0 + 4 ℓ θ̇0² / (9 g)."""
    return 2.0 / 3.0 * math.cos(ladder.theta0) + 4.0 * ladder.half_length * ladder.theta_dot0 ** 2 / (9.0 * ladder.g)


def detachment_angle(ladder: Ladder) -> float:
    """arccos of detachment_cosine (rad): FORMULARY T5's arccos((2/3) cos θ0) from rest."""
    return math.acos(detachment_cosine(ladder))


def angular_acceleration(ladder: Ladder, theta):
    """θ̈ = 3g/(4ℓ) sin θ (5.23)."""
    return 0.75 * ladder.g / ladder.half_length * np.sin(theta)


def wall_force(ladder: Ladder, theta, theta_dot):
    """Φ1 (N), the wall's push on the top, along +x."""
    return ladder.mass * ladder.half_length * np.sin(theta) * (
        0.75 * ladder.g / ladder.half_length * np.cos(theta) - np.asarray(theta_dot) ** 2)


def floor_force(ladder: Ladder, theta, theta_dot):
    """Φ2 (N), the floor's push on the foot, along +y (corrected 5.22)."""
    m, l = ladder.mass, ladder.half_length
    return m * ladder.g - m * l * (angular_acceleration(ladder, theta) * np.sin(theta)
                                   + np.asarray(theta_dot) ** 2 * np.cos(theta))


def planar_state(ladder: Ladder, theta, theta_dot) -> np.ndarray:
    """(n, 6): x, y, θ, ẋ, ẏ, θ̇ of the rod with both ends on the axes."""
    theta, theta_dot = np.asarray(theta, dtype=float), np.asarray(theta_dot, dtype=float)
    l = ladder.half_length
    return np.stack([l * np.sin(theta), l * np.cos(theta), theta, l * np.cos(theta) * theta_dot,
                     -l * np.sin(theta) * theta_dot, theta_dot], axis=-1)


def energy(ladder: Ladder, state: np.ndarray) -> np.ndarray:
    """½ m |v_G|² + ½ (m ℓ²/3) θ̇² + m g y (J) of planar states (n, 6)."""
    state = np.asarray(state, dtype=float)
    m, l = ladder.mass, ladder.half_length
    return (0.5 * m * (state[..., 3] ** 2 + state[..., 4] ** 2) + m * l * l / 6.0 * state[..., 5] ** 2
            + m * ladder.g * state[..., 1])


def energy_scale(ladder: Ladder, state0: np.ndarray) -> float:
    """Sum of the absolute values of the energy's terms at t = 0 (DESIGN §4)."""
    m, l = ladder.mass, ladder.half_length
    kinetic = 0.5 * m * (state0[3] ** 2 + state0[4] ** 2) + m * l * l / 6.0 * state0[5] ** 2
    return abs(kinetic) + abs(m * ladder.g * state0[1]) or 1.0


def end_points(ladder: Ladder, state: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(top (n, 2), foot (n, 2)) positions (m) of the rod's ends."""
    state = np.asarray(state, dtype=float)
    along = ladder.half_length * np.stack([np.sin(state[..., 2]), -np.cos(state[..., 2])], axis=-1)
    centre = state[..., :2]
    return centre - along, centre + along


def constraint_violation(ladder: Ladder, state: np.ndarray) -> np.ndarray:
    """(n,) m: max(|x_top|, |y_foot|), how far the ends are off their axes (bilateral constraints)."""
    top, foot = end_points(ladder, state)
    return np.maximum(np.abs(top[..., 0]), np.abs(foot[..., 1]))


@functools.cache
def _integrator(with_event: bool) -> tuple[object, threading.Lock]:
    """(θ, θ̇) with parameter 3g/(4ℓ); with_event: a terminal event on Φ1/(mℓ sin θ) = 3g/(4ℓ) cos θ − θ̇² = 0
    (a second integrator without it samples the grid, which a terminal event would stop)."""
    theta, theta_dot = hy.make_vars("theta", "theta_dot")
    k = hy.par[0]
    events = [hy.t_event(k * hy.cos(theta) - theta_dot * theta_dot)] if with_event else []
    integrator = hy.taylor_adaptive([(theta, theta_dot), (theta_dot, k * hy.sin(theta))], [0.1, 0.0],
                                    tol=LADDER_TOL, pars=[1.0], t_events=events)
    return integrator, threading.Lock()


def _reset(integrator, ladder: Ladder) -> None:
    integrator.time = 0.0
    integrator.state[:] = (ladder.theta0, ladder.theta_dot0)
    integrator.pars[0] = 0.75 * ladder.g / ladder.half_length


def solve(ladder: Ladder, times: np.ndarray, deadline: float | None = None) -> LadderMotion:
    """The equation (5.23) from (θ0, θ̇0) at times ((n,) s, increasing, from 0), and where Φ1 changes sign.
    truth.OutOfTime when time.monotonic() passes deadline (None: none) first."""
    times = np.asarray(times, dtype=float)
    detach_time = detach = math.nan
    integrator, lock = _integrator(True)
    with lock:
        _reset(integrator, ladder)
        outcome = integrator.propagate_until(float(times[-1]), callback=step_callback(deadline))[0]
        stopped_at_deadline(outcome, "ladder propagation", float(integrator.time))
        if outcome.value == -1:  # the terminal event: Φ1 = 0 within the span
            detach_time, detach = float(integrator.time), float(integrator.state[0])
    integrator, lock = _integrator(False)
    with lock:
        _reset(integrator, ladder)
        outcome, *_, samples = integrator.propagate_grid(times, callback=step_callback(deadline))
        stopped_at_deadline(outcome, "ladder propagation", float(integrator.time))
    samples = np.asarray(samples)
    if outcome != hy.taylor_outcome.time_limit or samples.shape[0] != times.size:
        raise ValueError(f"ladder propagation stopped with outcome {outcome} before t = {times[-1]}")
    return LadderMotion(times.copy(), samples[:, 0].copy(), samples[:, 1].copy(), detach_time, detach)
