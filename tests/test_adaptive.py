"""Adaptive integrators of the reference engine: scipy's solve_ivp methods (harness.integrators.scipy_ivp) against the
truth, with their counts, chart changes and failures, and the tolerance keyword of Engine.prepare (heyoka's taylor
included)."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from test_euler_angles import lagrange_through_vertical

from stereodyn.harness.pipeline import tolerance_ladders
from stereodyn.harness.analysis import fitting
from stereodyn.harness.scenes.cases import find_case, with_overrides
from stereodyn.harness.engines.reference import ReferenceEngine
from stereodyn.harness.engines.declared import formulations
from stereodyn.harness.grid import time_grid
from stereodyn.harness.integrators import scipy_ivp
from stereodyn.harness.scenes.rigid_body import truth_grid
from stereodyn.harness.trajectory import Status
from stereodyn.reference import truth
from stereodyn.reference.rotations import attitude_angle, quat_to_matrix

ENGINE = ReferenceEngine()


def _free(t_end: float = 10.0):
    return with_overrides(find_case("free-asymmetric"), t_end=t_end)


def _attitude_error(case, run) -> float:
    reference = truth.truth(case.body, case.quat0, case.omega0, run.times)
    return float(np.max(attitude_angle(quat_to_matrix(run.quat), quat_to_matrix(reference.quat))))


def test_scipy_methods_are_adaptive_integrators_of_the_reference_engine():
    assert set(scipy_ivp.METHODS) <= set(ENGINE.integrators())
    assert all(ENGINE.offer(name).adaptive for name in scipy_ivp.METHODS) and ENGINE.offer("taylor").adaptive
    assert not ENGINE.offer("rk4").adaptive


def test_dop853_error_shrinks_with_the_tolerance_on_a_torque_free_case():
    """scipy's DOP853 on free-asymmetric (10 s) at 1e-4 ... 1e-10, errors against the truth on the sweep's grid."""
    case = _free()
    family = tolerance_ladders.AdaptiveFamily(case, "reference", "quaternion", "scipy_dop853")
    points = tolerance_ladders.run_ladder(family, tuple(10.0 ** -k for k in range(4, 11)))
    assert [p["status"] for p in points] == ["ok"] * 7, [p["message"] for p in points]
    errors = [p["state_err"] for p in points]
    # each decade of tolerance buys accuracy (measured: 9.9e-04 at 1e-4 ... 1.4e-09 at 1e-10)
    assert all(b < a for a, b in zip(errors, errors[1:])), errors
    assert errors[-1] < 3e-9
    fit = fitting.tolerance_fit(pd.DataFrame(points))
    # the slope of log error against log tolerance over 1e-4 ... 1e-10, all 7 points above round-off: measured 0.99
    # here (1.01 over the case's 20 s, 1.00 on heavy-asymmetric): an error proportional to the tolerance, ~20x it
    assert fit["points"] == 7 and 0.85 <= fit["slope"] <= 1.15, fit
    assert fit["below_tol"] == 0 and 5 < fit["max_err_over_tol"] < 100
    # counts: every accepted step costs DOP853 12 evaluations (plus a few for the first step's choice)
    assert all(p["rhs_evals"] >= 12 * p["steps"] for p in points)
    assert all(b["steps"] > a["steps"] for a, b in zip(points, points[1:]))


@pytest.mark.parametrize("integrator", sorted(scipy_ivp.METHODS))
def test_every_scipy_method_reaches_its_default_tolerance_on_the_sweep_grid(integrator):
    """Each method at the default tolerance (1e-8) over 5 s of free-asymmetric: the sweep's row."""
    case = _free(5.0)
    run = ENGINE.prepare(case, integrator, None, formulation="quaternion").run(truth_grid(case))
    assert run.status is Status.OK and run.steps > 0 and run.rhs_evals > run.steps
    # measured 3.1e-9 (Radau), 2.7e-8 (RK45), 1.6e-7 (LSODA), 1.7e-7 (DOP853), 2.1e-7 (BDF): the global error over 5 s
    # is up to ~20 times the tolerance
    assert _attitude_error(case, run) < 3e-6
    assert run.info["tolerance"] == scipy_ivp.DEFAULT_TOLERANCE
    if integrator in ("scipy_radau", "scipy_bdf"):
        # the finite-difference Jacobians' evaluations are counted (scipy's nfev leaves them out): 7 a Jacobian
        # (measured Radau 920 = 885 + 5 x 7, BDF 299 = 291 + 1 x 7 + 1)
        assert run.info["scipy_njev"] >= 1 and run.rhs_evals >= run.info["scipy_nfev"] + 7 * run.info["scipy_njev"]


@pytest.mark.parametrize("formulation", ["gibbs", "gibbs_hamiltonian", "euler_zxz"])
def test_a_charted_formulation_changes_chart_under_solve_ivp(formulation):
    """The Lagrange top through the upward vertical: the ZXZ chart meets its pole and the Gibbs chart turns past
    90 degrees; each re-charts (restarting the solver) and the run agrees with the truth."""
    case = lagrange_through_vertical()
    grid = truth_grid(case)
    run = ENGINE.prepare(case, "scipy_dop853", None, formulation=formulation, tolerance=1e-10).run(grid)
    assert run.status is Status.OK and run.chart_changes > 0
    # measured 3.0e-9 (gibbs, 24 changes), 3.4e-8 (gibbs_hamiltonian, 24), 8.2e-10 (euler_zxz, 6) rad over 10 s at
    # tol 1e-10 (heyoka at its truth tolerance: ~1e-12)
    assert _attitude_error(case, run) < 3e-7


def test_without_chart_changes_the_gimbal_lock_ends_a_scipy_run_diverged():
    case = lagrange_through_vertical()
    grid = truth_grid(case)
    run = ENGINE.prepare(case, "scipy_dop853", None, formulation="euler_zxz", chart_changes=False).run(grid)
    assert run.status is Status.DIVERGED and run.message.startswith("gimbal lock: theta reached 0")
    # the guard (|sin θ| < 0.0998) trips at t = 0.3302 s; an adaptive run sees it at the end of that step, before the
    # passage through the pole at t = 0.38 s
    assert 0.329 < run.diverged_at < 0.38
    bad = np.searchsorted(grid.times, run.diverged_at, side="right")  # the samples up to the step's end are kept
    assert np.isnan(run.quat[bad:]).all() and np.isfinite(run.quat[:bad]).all()


class _Blowup:
    """y' = y², y(0) = 1: infinite at t = 1, with an attitude and omega that stay quiet (no divergence rule)."""

    def rhs(self, t, chart, y):
        return y * y

    def rechart(self, chart, y):
        return chart, y

    def observe(self, chart, y):
        return (1.0, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0)

    def chart_changes(self, chart):
        return None


def test_a_solver_failure_is_a_failed_run_with_scipys_message():
    grid = time_grid(2.0, 0.01, 21)
    run = scipy_ivp.ScipyIVP("scipy_rk45", 1e-8).integrate(_Blowup(), None, np.array([1.0]), grid)
    assert run.status is Status.FAILED and run.message.startswith("scipy RK45: Required step size")
    assert np.isnan(run.quat[11:]).all() and np.isfinite(run.quat[:10]).all()  # samples up to t = 0.9 s kept
    capped = scipy_ivp.ScipyIVP("scipy_rk45", 1e-8, max_steps=5).integrate(_Blowup(), None, np.array([1.0]), grid)
    assert capped.status is Status.FAILED and "more than 5 steps" in capped.message


class _Breaks(_Blowup):
    """y' = 1 until t = 0.5 s, then a right-hand side that raises (as a singular Jacobian's LU would)."""

    def rhs(self, t, chart, y):
        if t > 0.5:
            raise ValueError("array must not contain infs or NaNs\nsecond line")
        return np.ones_like(y)


def test_an_exception_inside_a_step_is_a_failed_run_with_its_message():
    grid = time_grid(1.0, 0.01, 11)
    run = scipy_ivp.ScipyIVP("scipy_radau", 1e-6).integrate(_Breaks(), None, np.array([0.0]), grid)
    assert run.status is Status.FAILED and "\n" not in run.message
    assert run.message.startswith("scipy Radau: ValueError: array must not contain infs or NaNs at t = ")
    assert np.isfinite(run.quat[0]).all() and np.isnan(run.quat[-1]).all()  # kept up to the last accepted step


def test_a_tolerance_below_scipys_floor_is_refused():
    with pytest.raises(ValueError, match="100 eps"):
        ENGINE.prepare(_free(), "scipy_dop853", None, tolerance=1e-15)


def test_taylor_takes_the_tolerance_keyword():
    """heyoka's taylor at tol 1e-6 is no truth any more; at the default it agrees with the truth to round-off."""
    case = _free()
    grid = truth_grid(case)
    loose = ENGINE.prepare(case, "taylor", None, formulation="quaternion", tolerance=1e-6).run(grid)
    default = ENGINE.prepare(case, "taylor", None, formulation="quaternion").run(grid)
    # measured 1.3e-07 rad at tol 1e-6 (free-asymmetric, 10 s), 0 at the default (the same computation as the truth)
    assert 1e-9 < _attitude_error(case, loose) < 1e-5
    assert _attitude_error(case, default) < 1e-13
    gibbs = ENGINE.prepare(case, "taylor", None, formulation="gibbs", tolerance=1e-6).run(grid)
    # measured 2.7e-6 rad, 13 chart changes
    assert gibbs.chart_changes > 0 and 1e-9 < _attitude_error(case, gibbs) < 3e-5
    # a fixed-step integrator accepts the keyword and ignores it
    fixed = ENGINE.prepare(case, "rk4", 1e-2, tolerance=1e-3).run(time_grid(case.t_end, 1e-2, 11))
    assert fixed.status is Status.OK


def test_the_default_sweep_runs_the_explicit_scipy_methods_on_the_quaternion_only():
    """SceneModel.default_run: a sweep that names no integrators plans scipy_rk45, scipy_dop853 and scipy_lsoda on the
    quaternion formulation (the cost measured in docs/ENGINES.md); naming one runs it on every formulation."""
    from stereodyn.harness.run.plan import plan

    case = _free()
    specs, _ = plan([case], ["reference"], None)
    scipy_runs = {(s.formulation, s.integrator, s.dt) for s in specs if s.integrator in scipy_ivp.METHODS}
    assert scipy_runs == {("quaternion", name, None) for name in ("scipy_rk45", "scipy_dop853", "scipy_lsoda")}
    assert {s.formulation for s in specs if s.integrator == "taylor"} == set(formulations(ENGINE))
    named, _ = plan([case], ["reference"], ["scipy_radau"])
    assert {(s.formulation, s.integrator) for s in named} == {(f, "scipy_radau") for f in formulations(ENGINE)}
