"""Ensembles: N initial states of one model stepped together by an integrator's batch_stepper, so that each stage
evaluates the dynamics of all members in one call (Pinocchio: pin.abaInParallel) and the per-call cost of Python and
numpy is shared by the members.

Each member gets the Trajectory a single run from its state would give (the same divergence rule and bookkeeping as
Integrator.integrate), up to the order of floating-point operations: round-off, not method, differences.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from ..trajectory import (Status, Trajectory, divergence_limit2, diverged_trajectory, first_bad_step,
                          samples_good)
from ..grid import TimeGrid
from .base import Stepper


def integrate_ensemble(step: Stepper, stages: int, g0: np.ndarray, v0: np.ndarray, grid: TimeGrid,
                       quat_of: Callable[[np.ndarray], np.ndarray]) -> list[Trajectory]:
    """grid.steps steps of the batched step(t, G, V) -> (G, V) (step k at t = k dt) from (g0 (N, ...), v0 (N, 3)),
    recorded at grid.sample_steps.

    quat_of(g) gives the (M, 4) attitude quaternions (w, x, y, z) of M group elements. A member whose sample is not
    finite or whose |v| passes the divergence limit leaves the ensemble: its steps since the previous sample are
    replayed alone to find the exact bad step, as Integrator.integrate does for a single run.
    """
    v0 = np.array(v0, dtype=float)
    members, samples = v0.shape[0], grid.sample_steps.size
    quats = np.full((members, samples, 4), np.nan)
    omegas = np.full((members, samples, 3), np.nan)
    quats[:, 0], omegas[:, 0] = quat_of(g0), v0
    limit2 = np.array([divergence_limit2(row) for row in v0.tolist()])
    alive = np.arange(members)  # the members still stepping; row i of (g, v) is member alive[i]
    outcomes: dict[int, Trajectory] = {}
    g, v, done, dt = g0, v0, 0, grid.dt
    with np.errstate(all="ignore"):  # overflow on the way to a divergence is an outcome, reported as one
        for k, target in enumerate(grid.sample_steps[1:].tolist(), start=1):
            g_last, v_last, start = g, v, done
            for i in range(done, target):
                g, v = step(i * dt, g, v)
            done = target
            quat = quat_of(g)
            quats[alive, k], omegas[alive, k] = quat, v
            good = samples_good(quat, v, limit2[alive])
            if good.all():
                continue
            for row in np.flatnonzero(~good).tolist():
                member = int(alive[row])
                # Integrator.integrate's replay, on a 1-member ensemble
                bad_step, _ = first_bad_step(step, lambda g1, v1: (quat_of(g1)[0].tolist(), v1[0].tolist()),
                                             g_last[row:row + 1], v_last[row:row + 1], start, target, dt,
                                             float(limit2[member]))
                outcomes[member] = diverged_trajectory(grid, quats[member], omegas[member], k, bad_step * dt,
                                                       done, stages * done)
            alive, g, v = alive[good], g[good], v[good]
            if not alive.size:
                break
    for member in alive.tolist():
        outcomes[member] = Trajectory(grid.times, quats[member], omegas[member], Status.OK, "", np.nan, grid.steps,
                                      stages * grid.steps)
    return [outcomes[m] for m in range(members)]

