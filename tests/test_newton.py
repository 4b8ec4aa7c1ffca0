"""The Newton engine (harness/engines/newton.py, the optional extra stereodyn[newton]): its conventions against
MuJoCo's Euler, torques, the captured step, featherstone's order, a diverged run as a row, and the message when the
extra is missing. Skipped where newton is not installed (but the missing-extra test runs). A first run compiles Warp
kernels for a minute or more (then Warp's kernel cache serves)."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from helpers import assert_skipped_without_sdk, installed_engine

from stereodyn.harness.scenes import metrics
from stereodyn.harness.engines import get_engine
from stereodyn.harness.engines.declared import rigid_body
from stereodyn.harness.analysis.fitting import order_slope
from stereodyn.harness.grid import time_grid
from stereodyn.harness.scenes.cases import find_case
from stereodyn.harness.trajectory import Status
from stereodyn.reference import truth as reference_truth
from stereodyn.reference.rotations import attitude_angle, quat_to_matrix


@pytest.fixture(scope="module")
def newton():
    return installed_engine("newton")


def test_without_the_extra_the_rows_are_skipped_naming_the_install_command():
    assert_skipped_without_sdk("newton", "newton")


@pytest.mark.parametrize("name, model", [("heavy-asymmetric", "ball"), ("free-asymmetric", "free")])
def test_featherstone_follows_mujocos_euler_to_its_quaternion_update(newton, name, model):
    """featherstone's ball and free joints update the velocity first, like MuJoCo's euler; its quaternion update is
    first order rather than the exponential map, so the two differ by O(dt) over a run: 100 steps of 1e-3 s are
    1e-7 .. 1e-6 rad apart (measured 5e-7 rad on heavy-asymmetric, float32 included). A body-frame joint velocity
    (Newton's ball joint takes the parent's, world, frame) or a conjugated quaternion is off by 1e-2 or more."""
    case = find_case(name)
    grid = time_grid(0.1, 1e-3, 11)
    ours = newton.prepare(case, "featherstone", 1e-3, formulation=model).run(grid)
    theirs = get_engine("mujoco").prepare(case, "euler", 1e-3).run(grid)
    assert ours.status is Status.OK
    assert np.max(attitude_angle(quat_to_matrix(ours.quat), quat_to_matrix(theirs.quat))) < 1e-5
    assert np.max(np.abs(ours.omega - theirs.omega)) < 1e-4


@pytest.mark.parametrize("name", ["constant-torque-uniform", "self-excited-conic"])
def test_a_torque_from_the_state_enters_every_step_in_the_world_frame(newton, name):
    """The case's torque (body components) is evaluated at every step's start from the step's time and state and
    applied as the body's world-frame moment (body_f = R M): featherstone then follows MuJoCo's euler as on the
    torque-free cases, 100 steps of 1e-3 s within 3.1e-8 .. 3.4e-8 rad and 3.8e-9 .. 1.1e-7 rad/s (measured). The
    moment left in body components is 1.1e-5 .. 6.4e-5 rad and 2.7e-4 .. 1.4e-3 rad/s off, no torque 1e-3 rad and
    2e-2 rad/s."""
    case = find_case(name)
    grid = time_grid(0.1, 1e-3, 11)
    ours = newton.prepare(case, "featherstone", 1e-3).run(grid)
    theirs = get_engine("mujoco").prepare(case, "euler", 1e-3).run(grid)
    assert ours.status is Status.OK and ours.info["torque_mode"] == "step"
    assert np.max(attitude_angle(quat_to_matrix(ours.quat), quat_to_matrix(theirs.quat))) < 1e-6
    assert np.max(np.abs(ours.omega - theirs.omega)) < 1e-6


def test_the_captured_step_restarts_and_featherstone_is_first_order(newton):
    """Two runs of one prepared model agree bit for bit (the reset); the attitude error against the truth halves with
    the step (lagrange-top, 1 s: fitted 1.0 .. 1.1 measured; float32 round-off stays far below at these steps)."""
    case = dataclasses.replace(find_case("lagrange-top"), t_end=1.0, samples=11)
    dts, errors = [4e-3, 2e-3, 1e-3], []
    for dt in dts:
        grid = time_grid(case.t_end, dt, case.samples)
        simulation = newton.prepare(case, "featherstone", dt)
        first, second = simulation.run(grid), simulation.run(grid)
        assert np.array_equal(first.quat, second.quat)
        truth = reference_truth.truth(case.body, case.quat0, case.omega0, grid.times)
        errors.append(metrics.errors(first, truth.quat, truth.omega, None)["attitude_err"])
    assert abs(order_slope(np.array(dts), np.array(errors)) - 1.0) < 0.2


def test_a_runaway_run_is_a_diverged_row(newton):
    """heavy-asymmetric at dt 0.3 is beyond the stability limit: the run ends `diverged` (NaN or |omega| past the
    rule) at its first bad sample, with the divergence rule's message; the later samples are NaN."""
    case = find_case("heavy-asymmetric")
    grid = time_grid(case.t_end, 0.3, case.samples)
    run = newton.prepare(case, "featherstone", 0.3).run(grid)
    assert run.status is Status.DIVERGED and "not finite or |omega|" in run.message
    bad = int(np.searchsorted(grid.times, run.diverged_at))
    assert np.isnan(run.quat[bad:]).all() and np.isfinite(run.quat[:bad]).all()


def test_the_default_sweep_is_the_general_cases_at_one_coarse_stable_step(newton):
    heavy, torqued = find_case("heavy-asymmetric"), find_case("self-excited-conic")
    model = rigid_body(newton)
    assert model.default_dts(heavy, "featherstone", heavy.dt) == (1e-2,)  # not 0.3: beyond Euler's stability
    assert model.default_run(heavy, "ball", "xpbd") and not model.default_run(heavy, "free", "xpbd")
    assert not model.default_run(find_case("hess"), "ball", "featherstone")
    assert newton.unsupported(torqued) is None and model.torque_mode(torqued) == "step"
    assert not model.default_run(torqued, "ball", "featherstone")  # the general cases only
