"""Pinocchio ensembles (harness.integrators.ensemble, PinocchioEngine.prepare_ensemble): every member must be the
single run from its state, to round-off, including how and when it diverges."""
import dataclasses

import numpy as np
import pinocchio as pin
import pytest

from stereodyn.harness.scenes.cases import find_case, with_overrides
from stereodyn.harness.engines import get_engine
from stereodyn.harness.engines.declared import rigid_body
from stereodyn.harness.trajectory import Status
from stereodyn.harness.engines.pinocchio import build_model, retract_rows
from stereodyn.harness.grid import time_grid

ENGINE = get_engine("pinocchio")


def _members(case, n, spread, seed=0):
    rng = np.random.default_rng(seed)
    return np.tile(case.quat0, (n, 1)), np.asarray(case.omega0) + spread * rng.standard_normal((n, 3))


def _single(case, integrator, dt, omega0, grid, quat0=None):
    state = {"omega0": np.asarray(omega0)} | ({} if quat0 is None else {"quat0": np.asarray(quat0)})
    return ENGINE.prepare(dataclasses.replace(case, **state), integrator, dt).run(grid)


def test_retract_rows_is_pin_integrate():
    model = build_model(find_case("heavy-asymmetric"))
    rng = np.random.default_rng(3)
    q = rng.standard_normal((50, 4)) * (1.0 + 1e-3 * rng.standard_normal((50, 1)))
    q /= np.linalg.norm(q, axis=1)[:, None] * (1.0 + 1e-6)  # slightly off the unit sphere: renormalisation shows
    theta = rng.standard_normal((50, 3)) * np.logspace(-9, 0.5, 50)[:, None]  # down to the small-angle branch
    theta[0] = 0.0
    expected = np.array([pin.integrate(model, qi, ti) for qi, ti in zip(q, theta)])
    assert np.abs(retract_rows(q, theta) - expected).max() < 4e-16 * 4


@pytest.mark.parametrize("integrator", ["rk4", "rk4_naive", "euler", "symplectic_euler"])
def test_members_are_single_runs(integrator):
    # A regular motion (Lagrange top, not chaotic), over 200 steps: explicit Euler amplifies any difference by
    # sqrt(1 + (h |omega|)^2) = 1.011 a step at this spin, 1e9 over the case's 2000 steps, but only 9x over 200.
    case = with_overrides(find_case("lagrange-top"), t_end=2.0)
    dt = 1e-2
    grid = time_grid(case.t_end, dt, case.samples)
    quat0, omega0 = _members(case, 12, 0.05)
    trajectories = rigid_body(ENGINE).prepare_ensemble(case, integrator, dt, quat0, omega0).run(grid)
    assert len(trajectories) == 12
    for i in (0, 5, 11):
        single = _single(case, integrator, dt, omega0[i], grid)
        member = trajectories[i]
        assert member.status is Status.OK and member.steps == single.steps and member.rhs_evals == single.rhs_evals
        assert member.info["ensemble"] == 12
        # the batched arithmetic differs from the single path's only in the order of operations
        assert np.abs(member.quat - single.quat).max() < 1e-11
        assert np.abs(member.omega - single.omega).max() < 1e-10


def test_integrator_without_batch_form_runs_members_one_by_one():
    case = with_overrides(find_case("free-asymmetric"), t_end=2.0)
    grid = time_grid(case.t_end, 1e-2, 50)
    quat0, omega0 = _members(case, 3, 0.1)
    trajectories = rigid_body(ENGINE).prepare_ensemble(case, "implicit_midpoint", 1e-2, quat0, omega0).run(grid)
    for i in range(3):
        single = _single(case, "implicit_midpoint", 1e-2, omega0[i], grid)
        assert np.array_equal(trajectories[i].quat, single.quat)


def test_diverging_members_leave_with_the_single_run_verdict():
    # heavy-asymmetric at dt 0.3 is beyond Pinocchio Euler's stability limit (it diverges at 9.6 s); members hanging
    # at rest (centre of mass straight below O) stay there. Each member must get the single run's verdict.
    case = find_case("heavy-asymmetric")
    dt = 0.3
    grid = time_grid(case.t_end, dt, case.samples)
    down = np.asarray(case.body.gravity_direction, dtype=float)
    com = np.asarray(case.body.com, dtype=float) / np.linalg.norm(case.body.com)
    axis = np.cross(com, down)  # the rotation taking the centre of mass's direction onto gravity's
    angle = np.arctan2(np.linalg.norm(axis), com @ down)
    hanging = np.concatenate(([np.cos(angle / 2)], np.sin(angle / 2) * axis / np.linalg.norm(axis)))
    quat0 = np.array([case.quat0, hanging, case.quat0, hanging])
    omega0 = np.array([case.omega0, np.zeros(3), case.omega0, np.zeros(3)])
    trajectories = rigid_body(ENGINE).prepare_ensemble(case, "euler", dt, quat0, omega0).run(grid)
    statuses = []
    for member, q, w in zip(trajectories, quat0, omega0):
        single = _single(case, "euler", dt, w, grid, q)
        statuses.append(member.status)
        assert member.status is single.status
        assert member.diverged_at == pytest.approx(single.diverged_at, nan_ok=True)
        assert member.message == single.message and member.steps == single.steps
        good = np.isfinite(single.omega[:, 0])
        assert np.array_equal(good, np.isfinite(member.omega[:, 0]))
    assert Status.DIVERGED in statuses and Status.OK in statuses


def test_external_torque_enters_every_member():
    case = with_overrides(find_case("constant-torque-uniform"), t_end=1.0)
    grid = time_grid(case.t_end, 1e-2, 20)
    quat0, omega0 = _members(case, 3, 0.1)
    trajectories = rigid_body(ENGINE).prepare_ensemble(case, "rk4", 1e-2, quat0, omega0).run(grid)
    for i in range(3):
        assert np.abs(trajectories[i].omega - _single(case, "rk4", 1e-2, omega0[i], grid).omega).max() < 1e-12


def test_bad_shapes_and_dt_are_refused():
    case = find_case("lagrange-top")
    with pytest.raises(ValueError, match=r"quat0 \(N, 4\) and omega0 \(N, 3\)"):
        rigid_body(ENGINE).prepare_ensemble(case, "rk4", 1e-2, np.zeros((2, 4)), np.zeros((3, 3)))
    with pytest.raises(KeyError, match="unknown integrator"):
        rigid_body(ENGINE).prepare_ensemble(case, "nope", 1e-2, np.zeros((2, 4)), np.zeros((2, 3)))
    ensemble = rigid_body(ENGINE).prepare_ensemble(case, "rk4", 1e-2, *_members(case, 2, 0.0))
    with pytest.raises(ValueError, match="differs from the prepared dt"):
        ensemble.run(time_grid(1.0, 2e-2, 10))
