"""Exact solutions of the body with a fixed point, and the oracle registry the harness uses (DESIGN §3).

An Oracle has a name (the case files' [expect] oracle), a check(body, quat0, omega0) -> None when the oracle's
conditions hold (each to CONDITION_RTOL or the stated tolerance) or the reason in one line, and a
solve(body, quat0, omega0, times) -> (quat (n, 4) wxyz body -> world, omega (n, 3) rad/s body), the exact motion at
the given times (s).

Modules: stationary (Lyapunov exponent and small-oscillation frequencies, FORMULARY T8), heavy (Lagrange, Staude, Grioli,
Hess–Grioli, Mlodzejowski; FORMULARY G5, G9–G11), self_excited (the tanh spin-up and uniform rotations under a
body torque, G12, G13; the torque is part of the RigidBody the check and solve receive), pendulum (the plane pendulum in Jacobi functions).
The torque-free body (both families, symmetric body, separatrix; periods, Montgomery's phase) is
reference/torque_free.py, outside this package so that the splitting integrator imports it alone; its names are
importable from here too.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..body import RigidBody
from . import heavy, self_excited
from ..closed_form import CONDITION_RTOL
from .heavy import (Setup, grioli_body, grioli_precession, grioli_rate, grioli_vertical,
                    hess_frame, hess_grioli, hess_grioli_body, lagrange_precession, lagrange_rates,
                    mlodzejowski, mlodzejowski_axis, sleeping_top_threshold, staude_direction,
                    staude_rate_squared, staude_rotation)
from .pendulum import PendulumMotion, pendulum
from .stationary import lyapunov_exponent, oscillation_frequencies, unstable_direction
from ..torque_free import (SEPARATRIX_TOL, FreeMotion, euler_poinsot_check, euler_poinsot_solve, free_motion,
                           montgomery_phase, period, precession_per_period, separatrix_check, separatrix_distance,
                           separatrix_omega, solid_angle)


@dataclass(frozen=True)
class Oracle:
    name: str
    check: Callable[[RigidBody, np.ndarray, np.ndarray], str | None]
    solve: Callable[[RigidBody, np.ndarray, np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]


ORACLES: dict[str, Oracle] = {oracle.name: oracle for oracle in (
    Oracle("euler_poinsot", euler_poinsot_check, euler_poinsot_solve),
    Oracle("euler_poinsot_separatrix", separatrix_check, euler_poinsot_solve),
    Oracle("lagrange_precession", heavy.lagrange_check, heavy.lagrange_solve),
    Oracle("staude_rotation", heavy.staude_check, heavy.staude_solve),
    Oracle("grioli_precession", heavy.grioli_check, heavy.grioli_solve),
    Oracle("hess_grioli", heavy.hess_grioli_check, heavy.hess_grioli_solve),
    Oracle("mlodzejowski", heavy.mlodzejowski_check, heavy.mlodzejowski_solve),
    # the self-excited body (G12, G13): the torque reaches check and solve through the RigidBody
    Oracle("self_excited_spinup", self_excited.spinup_check, self_excited.spinup_solve),
    Oracle("self_excited_uniform", self_excited.uniform_check, self_excited.uniform_solve),
)}

__all__ = [
    "CONDITION_RTOL", "SEPARATRIX_TOL", "ORACLES", "Oracle", "FreeMotion", "PendulumMotion", "Setup",
    "free_motion", "period", "solid_angle", "montgomery_phase", "precession_per_period", "separatrix_distance",
    "separatrix_omega", "lyapunov_exponent", "unstable_direction", "oscillation_frequencies", "pendulum",
    "lagrange_rates", "sleeping_top_threshold", "lagrange_precession", "staude_direction", "staude_rate_squared",
    "staude_rotation", "grioli_body", "grioli_rate", "grioli_vertical", "grioli_precession", "hess_grioli_body",
    "hess_frame", "hess_grioli", "mlodzejowski_axis", "mlodzejowski",
]
