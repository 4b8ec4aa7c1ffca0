"""The Drake engine (harness/engines/drake.py, the optional extra stereodyn[drake]): its conventions, agreement with
the truth, torques at every stage, fitted orders, the roll-pitch-yaw chart's singularity, the tolerance keyword, and
the message when the extra is missing. Skipped where pydrake is not installed (but the missing-extra test runs)."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from helpers import assert_skipped_without_sdk

from stereodyn.harness.scenes import metrics
from stereodyn.harness.scenes.cases import find_case, with_overrides
from stereodyn.harness.engines import get_engine
from stereodyn.harness.engines.declared import declared_order, formulations, in_default_sweep, rigid_body
from stereodyn.harness.analysis.fitting import order_slope
from stereodyn.harness.grid import time_grid
from stereodyn.harness.trajectory import Status
from stereodyn.reference import truth as reference_truth
from stereodyn.reference.rotations import attitude_angle, quat_mul, quat_to_matrix


@pytest.fixture(scope="module")
def drake():
    pytest.importorskip("pydrake")
    return get_engine("drake")


def run(engine, case, integrator, dt, model="rpy_ball", tolerance=None, samples=None):
    case = dataclasses.replace(case, samples=samples or case.samples)
    grid = time_grid(case.t_end, dt if dt is not None else case.t_end / (case.samples - 1), case.samples)
    return grid, engine.prepare(case, integrator, dt, formulation=model, tolerance=tolerance).run(grid)


def state_error(case, grid, traj) -> float:
    """max of attitude_err, omega_err and casimir_drift against the truth: convergence.csv's state error."""
    truth = reference_truth.truth(case.body, case.quat0, case.omega0, grid.times)
    err = metrics.errors(traj, truth.quat, truth.omega, None)
    casimir = metrics.drifts(case, traj, ("casimir",))["casimir_drift"]
    return max(err["attitude_err"], err["omega_err"], casimir)


def test_without_the_extra_the_rows_are_skipped_naming_the_install_command():
    """pydrake made unimportable: the registry's stand-in engine skips every case with the adapter's message."""
    assert_skipped_without_sdk("drake", "pydrake")


def test_integrators_orders_adaptivity_and_default_sweep(drake):
    assert formulations(drake) == ("rpy_ball", "quaternion_free")
    for name, order in (("discrete", 1), ("explicit_euler", 1), ("runge_kutta2", 2), ("runge_kutta3", 3),
                        ("bogacki_shampine3", 3), ("runge_kutta5", 5), ("radau3", 3), ("runge_kutta5_adaptive", 5)):
        assert name in drake.integrators() and declared_order(drake, name) == order
    assert drake.offer("runge_kutta3_adaptive").adaptive and not drake.offer("runge_kutta3").adaptive
    assert not drake.offer("discrete").adaptive and not drake.offer("runge_kutta2").adaptive
    assert in_default_sweep(drake, "runge_kutta3") and in_default_sweep(drake, "runge_kutta3_adaptive")
    assert not in_default_sweep(drake, "radau3") and not in_default_sweep(drake, "runge_kutta5")
    heavy, free = find_case("lagrange-top"), find_case("free-asymmetric")
    assert rigid_body(drake).unsupported_run(heavy, "quaternion_free", "runge_kutta3")  # O is not the centre of mass
    assert rigid_body(drake).unsupported_run(free, "quaternion_free", "runge_kutta3") is None


@pytest.mark.parametrize("model", ["rpy_ball", "quaternion_free"])
def test_a_uniform_rotation_gives_our_quaternion_and_body_omega(drake, model):
    """ω along a principal axis of a free body is a uniform rotation: q(t) = q0 ⊗ (cos(|ω|t/2), sin(|ω|t/2) u), ω
    constant in body components. A world-frame ω or a conjugated quaternion would be off by O(1)."""
    q0 = np.array([math.cos(0.25), math.sin(0.25), 0.0, 0.0])  # body z tilted 0.5 rad: pitch stays < 30°
    case = dataclasses.replace(find_case("free-asymmetric"), quat0=q0, omega0=np.array([0.0, 0.0, 1.3]), t_end=2.0)
    grid, traj = run(drake, case, "runge_kutta3", 1e-2, model)
    assert traj.status is Status.OK, traj.message
    half = 0.5 * 1.3 * grid.times
    expected = quat_mul(q0, np.column_stack([np.cos(half), 0 * half, 0 * half, np.sin(half)]))
    angle = attitude_angle(quat_to_matrix(traj.quat), quat_to_matrix(expected))
    # RK3's error, measured 6.9e-8 rad (rpy_ball: the chart's rates vary along the rotation) and 1.5e-10
    # (quaternion_free)
    assert np.max(angle) < 1e-6
    # the state's ω is in world components and constant; in body components it carries the attitude's error
    # (measured 4.6e-8 rad/s on rpy_ball, 6e-16 on quaternion_free)
    assert np.max(np.linalg.norm(traj.omega - [0.0, 0.0, 1.3], axis=1)) <= 1.3 * np.max(angle) * 1.01 + 1e-13
    # the free joint's quaternion is integrated as four numbers, not renormalised: measured |q| - 1 <= 1.5e-8
    norm = np.max(np.abs(np.linalg.norm(traj.quat, axis=1) - 1.0))
    assert norm < (1e-6 if model == "quaternion_free" else 1e-14)
    assert traj.steps == grid.steps  # fixed steps: no extra steps at the sample times
    assert traj.rhs_evals >= 3 * grid.steps


@pytest.mark.parametrize("name,model,bound", [
    ("free-asymmetric", "rpy_ball", 1e-10), ("free-asymmetric", "quaternion_free", 1e-10),
    ("lagrange-top", "rpy_ball", 1e-8), ("heavy-asymmetric", "rpy_ball", 1e-9)])
def test_runge_kutta5_agrees_with_the_truth(drake, name, model, bound):
    """RK5 at dt = 1e-3 over 2 s against the heyoka truth (measured: see bound's comment in each line below)."""
    case = with_overrides(find_case(name), t_end=2.0)
    grid, traj = run(drake, case, "runge_kutta5", 1e-3, model)
    assert traj.status is Status.OK, traj.message
    # measured: free-asymmetric 3e-13 rpy / 2e-13 quaternion; lagrange-top 4e-11; heavy-asymmetric 1e-12
    assert state_error(case, grid, traj) < bound


@pytest.mark.parametrize("name", ["central-field-turning", "self-excited-conic"])
@pytest.mark.parametrize("model", ["rpy_ball", "quaternion_free"])
def test_torques_enter_at_every_stage(drake, name, model):
    """A torque that turns with time (the central field's direction) and one that depends on ω: RK3 fits order 3
    (a torque held over the step would make it first order), and RK5 agrees with the truth."""
    case = with_overrides(find_case(name), t_end=2.0)
    # asymptotic from 0.01 down (rpy_ball on the turning field: local slopes 2.2, 2.5 at dt 0.04, 0.02)
    dts, errors = [0.01, 0.005, 0.0025], []
    for dt in dts:
        grid, traj = run(drake, case, "runge_kutta3", dt, model)
        assert traj.status is Status.OK and traj.info["torque_mode"] == "input_port"
        errors.append(state_error(case, grid, traj))
    assert abs(order_slope(np.array(dts), np.array(errors)) - 3.0) < 0.3  # measured 2.94-3.00
    grid, traj = run(drake, case, "runge_kutta5", 1e-2, model)
    assert state_error(case, grid, traj) < 1e-9  # measured 1e-12 to 4e-11


@pytest.mark.parametrize("integrator,order", [("runge_kutta2", 2), ("runge_kutta3", 3), ("bogacki_shampine3", 3),
                                              ("discrete", 1), ("radau3", 3)])
def test_fixed_step_methods_fit_their_declared_orders(drake, integrator, order):
    """On the Lagrange top over 2 s (convergence.csv's measure: slope of the state error against dt). Measured:
    2.00, 3.00, 3.00, 1.0 and 3.00 (radau3 with its Newton iteration converged to NEWTON_ACCURACY; at Drake's
    default accuracy its local slopes scatter from -0.04 to 3.5)."""
    case = with_overrides(find_case("lagrange-top"), t_end=2.0)
    dts = [0.004, 0.002, 0.001] if order < 3 else [0.008, 0.004, 0.002]
    errors = []
    for dt in dts:
        grid, traj = run(drake, case, integrator, dt)
        assert traj.status is Status.OK and traj.steps == grid.steps
        errors.append(state_error(case, grid, traj))
    fitted = order_slope(np.array(dts), np.array(errors))
    assert abs(fitted - declared_order(drake, integrator)) < 0.3, (fitted, errors)


@pytest.mark.parametrize("rate,path", [(1.0, "stopped"), (0.9995, "crossed")])
def test_the_rpy_chart_singularity_ends_the_run_failed_with_its_time(drake, rate, path):
    """ω = (0, rate, 0) rad/s body from the identity: pitch = rate t reaches 90° at t = π/(2 rate). At rate 1 a stage
    lands on pitch 1.570 rad and Drake throws; at 0.9995 every stage of RK3 at dt 0.01 and of the discrete plant
    misses the singularity by > 0.0015 rad, the step jumps across and the sample after it shows cos(pitch) < 0. The
    quaternion joint has no such chart and runs on."""
    case = dataclasses.replace(find_case("free-asymmetric"), quat0=np.array([1.0, 0.0, 0.0, 0.0]),
                               omega0=np.array([0.0, rate, 0.0]), t_end=3.0)
    crossing = math.pi / 2 / rate
    for integrator in ("runge_kutta3", "discrete") + (("runge_kutta3_adaptive",) if path == "stopped" else ()):
        dt = None if integrator.endswith("_adaptive") else 1e-2
        grid, traj = run(drake, case, integrator, dt, samples=301)
        assert traj.status is Status.FAILED, (integrator, traj.message)
        assert traj.message.startswith("roll-pitch-yaw chart singularity") and path in traj.message, traj.message
        when = float(traj.message.split("t = ")[1].split(" s")[0])
        assert abs(when - crossing) <= 0.011, traj.message  # within a step (sample spacing 0.01 s)
        recorded = np.isfinite(traj.quat[:, 0])
        assert recorded[grid.times < crossing - 0.02].all() and not recorded[grid.times > crossing + 0.02].any()
    grid, traj = run(drake, case, "runge_kutta3", 1e-2, "quaternion_free", samples=301)
    assert traj.status is Status.OK


def test_the_tolerance_keyword_sets_the_target_accuracy(drake):
    """Drake's error-controlled RK3 at 1e-4 and 1e-8 (21 samples, so the sample spacing does not bound the step): the
    tighter one is far more accurate and takes more steps, both counted; None is the contract's default (1e-8); a
    fixed-step run ignores the keyword."""
    case = with_overrides(find_case("heavy-asymmetric"), t_end=2.0)
    results = {}
    for tolerance in (1e-4, 1e-8):
        grid, traj = run(drake, case, "runge_kutta3_adaptive", None, tolerance=tolerance, samples=21)
        assert traj.status is Status.OK and traj.steps > 0 and traj.rhs_evals >= 3 * traj.steps
        results[tolerance] = (state_error(case, grid, traj), traj.steps, traj.rhs_evals)
    loose, tight = results[1e-4], results[1e-8]
    # measured: attitude error 8.1e-5 -> 9.6e-9 rad (about the tolerance), steps 118 -> 2324
    assert tight[0] < loose[0] / 100 and tight[1] > 5 * loose[1] and tight[2] > 5 * loose[2], results
    _, default = run(drake, case, "runge_kutta3_adaptive", None, samples=21)
    _, at_default = run(drake, case, "runge_kutta3_adaptive", None, tolerance=1e-8, samples=21)
    assert default.steps == at_default.steps and np.allclose(default.quat, at_default.quat, rtol=0, atol=1e-15)
    _, a = run(drake, case, "runge_kutta3", 1e-2, tolerance=1e-3)
    _, b = run(drake, case, "runge_kutta3", 1e-2)
    assert a.steps == b.steps and np.allclose(a.quat, b.quat, rtol=0, atol=1e-15)


def test_every_integrator_runs_on_both_models_and_counts_its_work(drake):
    """Each fixed-step scheme takes exactly the grid's steps; each adaptive one reports its steps and derivative
    evaluations (the tolerance contract); short span of the torqued self-excited body (a torque at every stage)."""
    case = with_overrides(find_case("self-excited-conic"), t_end=0.2)
    for model in formulations(drake):
        for integrator in drake.integrators():
            if drake.offer(integrator).unmodelled:  # offered by this Drake, not run (tests/test_engine_sdk.py)
                continue
            dt = None if drake.offer(integrator).adaptive else 1e-2
            grid, traj = run(drake, case, integrator, dt, model, tolerance=1e-6, samples=11)
            assert traj.status is Status.OK, (model, integrator, traj.message)
            assert traj.steps > 0 and traj.rhs_evals >= traj.steps, (model, integrator)
            if dt is not None:
                assert traj.steps == grid.steps, (model, integrator, traj.steps)
            # measured <= 8.3e-4 for the first-order schemes (dt 1e-2 or tolerance 1e-6, over 0.2 s), <= 2.2e-6
            # (runge_kutta2) for the others
            bound = 1e-2 if declared_order(drake, integrator) == 1 else 2e-5
            assert state_error(case, grid, traj) < bound, (model, integrator)


def test_the_default_sweep_has_drake_rows_on_every_case(drake):
    """The plan of a run naming no integrators: every rigid-body case runs rpy_ball, and quaternion_free exactly where
    O is the centre of mass (absent elsewhere, not skipped); the sliding ladder is one skipped row naming why."""
    from stereodyn.harness.scenes.cases import load_suite
    from stereodyn.harness.run.plan import plan

    suite = load_suite()
    specs, skipped = plan(suite, ["drake"], None)
    for case in suite:
        runs = {(s.formulation, s.integrator) for s in specs if s.case.name == case.name}
        rows = [r for r in skipped if r["case"] == case.name]
        if case.kind == "sliding_ladder":
            assert not runs and len(rows) == 1 and "bilateral constraints" in rows[0]["message"]
            continue
        assert {i for _, i in runs} == {"discrete", "runge_kutta2", "runge_kutta3", "runge_kutta3_adaptive"}
        assert ("rpy_ball", "runge_kutta3") in runs
        # nothing skipped but one row per scheme this Drake offers and the adapter does not model (cenic from 1.50)
        unmodelled = [i for i in drake.integrators() if drake.offer(i).unmodelled]
        assert sorted(r["integrator"] for r in rows) == sorted(unmodelled), rows
        assert all(r["message"].startswith("not modelled by stereodyn's adapter: ") for r in rows)
        free_body_at_o = not any(case.body.com)
        assert (("quaternion_free", "runge_kutta3") in runs) == free_body_at_o, case.name
