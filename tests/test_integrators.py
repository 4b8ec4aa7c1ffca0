"""Lie-group integrators and their registry, on a pure-numpy Euler–Poisson system (no engine SDK involved)."""
from __future__ import annotations

import functools
import math
from importlib.metadata import EntryPoint

import numpy as np
import pytest

import stereodyn.harness.integrators as integrators
from stereodyn.harness.analysis.fitting import order_slope
from stereodyn.harness.trajectory import DIVERGENCE_FACTOR, Status
from stereodyn.harness.grid import time_grid
from stereodyn.harness.integrators import ButcherTableau, ExplicitRK, Integrator, get, names, register
from stereodyn.harness.integrators.lie import RK4, CLASSICAL_RK4
from stereodyn.harness.integrators.vector import VectorRK4
from stereodyn.reference import truth as reference_truth
from stereodyn.reference.body import RigidBody
from stereodyn.reference.euler_poisson import omega_dot
from stereodyn.reference.rotations import attitude_angle, quat_exp, quat_mul, quat_to_matrix

BUILTIN = ("euler", "symplectic_euler", "rk4", "rk4_naive")

# The suite's Lagrange top: diag(1, 1, 0.4) about O, OG = (0, 0, 0.2), g = 9.81 down; a fast spin about the axis.
LAGRANGE = RigidBody(np.diag([1.0, 1.0, 0.4]), 1.0, np.array([0.0, 0.0, 0.2]), 9.81, np.array([0.0, 0.0, -1.0]))
QUAT0 = np.array([math.cos(0.3), math.sin(0.3), 0.0, 0.0])
OMEGA0 = np.array([0.5, 0.0, 15.0])


class QuaternionSystem:
    """Euler–Poisson as a LieSystem: g = unit quaternion (w, x, y, z), v = body angular velocity."""

    def __init__(self, body: RigidBody):
        self.body = body
        self.accel_calls = 0

    def accel(self, t, g, v):
        self.accel_calls += 1
        return omega_dot(self.body, g, v)

    def retract(self, g, theta):
        return quat_mul(g, quat_exp(theta))


def record(g) -> tuple[float, float, float, float]:
    return tuple(g.tolist())


class Heun(ExplicitRK):
    """A tableau-only integrator, as a third party would write one."""

    name = "test_heun"
    order = 2
    tableau = ButcherTableau(a=((0.0, 0.0), (1.0, 0.0)), b=(0.5, 0.5), c=(0.0, 1.0))
    description = "Heun's method, Munthe-Kaas (test plug-in)"


def fitted_order(dts, errors) -> float:
    """Least-squares slope of log(error) against log(dt)."""
    return order_slope(dts, errors)


def final_errors(integrator: Integrator, dts, t_end: float) -> list[float]:
    """Final attitude angle (rad) against the Taylor truth, for each dt."""
    truth = reference_truth.truth(LAGRANGE, QUAT0, OMEGA0, np.array([0.0, t_end]))
    errors = []
    for dt in dts:
        grid = time_grid(t_end, dt, 2)
        assert grid.t_end == pytest.approx(t_end, rel=1e-12)
        run = integrator.integrate(QuaternionSystem(LAGRANGE), QUAT0, OMEGA0, grid, record)
        assert run.status is Status.OK
        errors.append(float(attitude_angle(quat_to_matrix(run.quat[-1]), quat_to_matrix(truth.quat[-1]))))
    return errors


@pytest.fixture
def scratch_registry(monkeypatch):
    """A registry that tests may add to; restored afterwards."""
    monkeypatch.setattr(integrators.registry, "_registry", dict(integrators.registry._registry))
    return integrators.registry._registry


# ------------------------------------------------------------------------------------------------------ registry

def test_builtin_names_in_report_order():
    assert names()[:4] == BUILTIN
    assert names(state_space="no-such-space") == ()


def test_metadata_of_every_integrator():
    expected = {"euler": (1, 1), "symplectic_euler": (1, 1), "rk4": (4, 4), "rk4_naive": (2, 4)}
    for name in names():
        cls = get(name)
        assert cls.name == name
        assert isinstance(cls.order, int) and cls.order >= 1
        # moser_veselov declares 0: it calls no accel (rhs_evals are counted: tests/test_claims.py)
        assert isinstance(cls.stages, int) and cls.stages >= (0 if name == "moser_veselov" else 1)
        assert isinstance(cls.symplectic, bool) and isinstance(cls.geometric, bool)
        assert isinstance(cls.symmetric, bool) and isinstance(cls.casimir_preserving, bool)
        assert cls.state_space == "lie"
        assert cls.description and "\n" not in cls.description
        if name in expected:
            assert (cls.order, cls.stages) == expected[name]
            assert cls.geometric


def test_unknown_name_lists_the_valid_ones():
    with pytest.raises(KeyError) as error:
        get("rk5")
    for name in BUILTIN:
        assert name in str(error.value)


def test_get_accepts_a_class():
    assert get(RK4) is RK4
    assert get(Heun) is Heun                  # need not be registered
    with pytest.raises(TypeError):
        get(dict)


def test_register_as_decorator_and_name_conflicts(scratch_registry):
    @register
    class Mine(Heun):
        name = "test_mine"

    assert get("test_mine") is Mine
    assert register(Mine) is Mine             # registering the same class again is harmless

    class Impostor(Heun):
        name = "rk4"

    with pytest.raises(ValueError, match="already registered"):
        register(Impostor)

    class NoMetadata(Integrator):
        def step(self, system, t, g, v, h):
            return g, v

    with pytest.raises(TypeError, match="lacks metadata"):
        register(NoMetadata)


def test_entry_point_plugins_load_lazily(scratch_registry, monkeypatch, tmp_path):
    (tmp_path / "stereodyn_test_plugin.py").write_text(
        "from stereodyn.harness.integrators import ButcherTableau, ExplicitRK\n"
        "class Ralston(ExplicitRK):\n"
        "    name = 'test_ralston'\n"
        "    order = 2\n"
        "    tableau = ButcherTableau(a=((0.0, 0.0), (2/3, 0.0)), b=(0.25, 0.75), c=(0.0, 2/3))\n"
        "    description = 'Ralston, Munthe-Kaas'\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    group = integrators.ENTRY_POINT_GROUP
    plugins = [EntryPoint("test_ralston", "stereodyn_test_plugin:Ralston", group),
               EntryPoint("broken", "stereodyn_no_such_module:Nothing", group)]
    seen = []

    def fake_entry_points(group):
        seen.append(group)
        return plugins

    monkeypatch.setattr(integrators.registry, "entry_points", fake_entry_points)
    monkeypatch.setattr(integrators.registry, "_plugins_loaded", False)
    with pytest.warns(UserWarning, match="broken"):
        available = names()
    assert seen == [integrators.ENTRY_POINT_GROUP]
    # built-ins first (the anchors, then the geometric methods), then plug-ins
    assert available[:4] == BUILTIN and available[-1:] == ("test_ralston",)
    assert available[4:-1] == ("implicit_midpoint", "strang_free_flow", "moser_veselov")
    assert get("test_ralston").order == 2
    names()
    assert len(seen) == 1                     # loaded once


def test_tableau_is_validated():
    with pytest.raises(ValueError, match="explicit"):
        ButcherTableau(a=((0.5, 0.0), (0.5, 0.0)), b=(0.5, 0.5), c=(0.5, 0.5))
    with pytest.raises(ValueError, match="consistent"):
        ButcherTableau(a=((0.0, 0.0), (1.0, 0.0)), b=(0.5, 0.6), c=(0.0, 1.0))
    with pytest.raises(ValueError, match="shapes"):
        ButcherTableau(a=((0.0,),), b=(0.5, 0.5), c=(0.0, 1.0))
    assert CLASSICAL_RK4.stages == 4


# --------------------------------------------------------------------------------------------------- integrators

# dts in the asymptotic range (the top spins at 15 rad/s): errors from ~1e-2 down to ~1e-8, far above the truth's
# ~1e-15 and the round-off of a few thousand steps.
ORDER_CASES = {
    "euler": ([2e-3, 1e-3, 5e-4], 1.0, (0.8, 1.2)),
    "symplectic_euler": ([2e-3, 1e-3, 5e-4], 1.0, (0.8, 1.2)),
    "rk4": ([1e-2, 5e-3, 2.5e-3], 2.0, (3.7, 4.3)),
    "rk4_naive": ([1e-2, 5e-3, 2.5e-3], 2.0, (1.7, 2.3)),
    "test_heun": ([1e-2, 5e-3, 2.5e-3], 2.0, (1.7, 2.3)),
}


@functools.cache
def order_errors(name: str) -> tuple[float, ...]:
    dts, t_end, _ = ORDER_CASES[name]
    return tuple(final_errors((Heun if name == "test_heun" else get(name))(), dts, t_end))


@pytest.mark.parametrize("name", ORDER_CASES)
def test_fitted_order_on_the_lagrange_top(name):
    dts, _, (low, high) = ORDER_CASES[name]
    order = fitted_order(dts, order_errors(name))
    assert low <= order <= high, order


def test_munthe_kaas_correction_is_what_makes_rk4_fourth_order():
    assert all(a < 1e-2 * b for a, b in zip(order_errors("rk4"), order_errors("rk4_naive")))


@pytest.mark.parametrize("name", BUILTIN)
def test_step_is_the_step_integrate_takes(name):
    integrator = get(name)()
    system = QuaternionSystem(LAGRANGE)
    grid = time_grid(0.05, 1e-2, 6)
    run = integrator.integrate(system, QUAT0, OMEGA0, grid, record)
    g, v = QUAT0, OMEGA0
    for k in range(1, grid.steps + 1):
        g, v = integrator.step(system, (k - 1) * grid.dt, g, v, grid.dt)
        np.testing.assert_array_equal(run.quat[k], g)
        np.testing.assert_array_equal(run.omega[k], v)


@pytest.mark.parametrize("name", BUILTIN)
def test_rhs_evaluations_are_counted(name):
    integrator = get(name)()
    system = QuaternionSystem(LAGRANGE)
    grid = time_grid(0.1, 1e-2, 4)
    run = integrator.integrate(system, QUAT0, OMEGA0, grid, record)
    assert run.steps == grid.steps == 10
    assert run.rhs_evals == system.accel_calls == integrator.stages * grid.steps
    np.testing.assert_array_equal(run.times, grid.times)
    assert run.quat.shape == (grid.times.size, 4) and run.omega.shape == (grid.times.size, 3)


class Runaway:
    """v' = rate v on a static attitude: |v| grows geometrically, so the divergence step is known exactly."""

    rate = 50.0

    def accel(self, t, g, v):
        return self.rate * v

    def retract(self, g, theta):
        return g


def test_divergence_stops_early_at_the_exact_step():
    v0, dt = np.array([1.0, 0.0, 0.0]), 1e-2
    grid = time_grid(10.0, dt, 11)            # samples every 100 steps
    limit = DIVERGENCE_FACTOR * (1.0 + 1.0)
    # explicit Euler: |v_k| = (1 + rate dt)^k, computed the way the integrator does it (floating point)
    speed, expected = 1.0, None
    for k in range(1, grid.steps + 1):
        speed = speed + dt * Runaway.rate * speed
        if speed > limit:
            expected = k
            break
    run = get("euler")().integrate(Runaway(), QUAT0, v0, grid, record)
    assert run.status is Status.DIVERGED
    assert run.diverged_at == pytest.approx(expected * dt, rel=1e-12)
    bad = int(np.searchsorted(grid.sample_steps, expected))
    assert np.isnan(run.quat[bad:]).all() and np.isnan(run.omega[bad:]).all()
    assert np.isfinite(run.quat[:bad]).all() and np.isfinite(run.omega[:bad]).all()
    assert run.steps == grid.sample_steps[bad] < grid.steps     # stopped at the first bad sample
    assert run.rhs_evals == run.steps


class NotANumber(Runaway):
    """Finite until the speed passes 10, then NaN: the non-finite branch of the rule."""

    def accel(self, t, g, v):
        return np.full(3, np.nan) if v @ v > 100.0 else self.rate * v


def test_non_finite_state_is_a_divergence_not_an_exception():
    grid = time_grid(1.0, 1e-2, 3)
    run = get("rk4")().integrate(NotANumber(), QUAT0, np.array([1.0, 0.0, 0.0]), grid, record)
    assert run.status is Status.DIVERGED
    assert 0.0 < run.diverged_at <= 1.0
    assert np.isnan(run.omega[-1]).all()


# ---------------------------------------------------------------------------------------------- vector state space

class LinearSystem:
    """y' = A y on R^2 (a rotation: y = (cos t, -sin t) from (1, 0)) in a single chart that never changes; the
    observed 'omega' is y padded with a zero, the attitude the identity."""

    matrix = np.array([[0.0, 1.0], [-1.0, 0.0]])

    def rhs(self, t, chart, y):
        return self.matrix @ y

    def rechart(self, chart, y):
        return chart, y

    def observe(self, chart, y):
        return (1.0, 0.0, 0.0, 0.0), (float(y[0]), float(y[1]), 0.0)

    def chart_changes(self, chart):
        return chart


class SingularAt(LinearSystem):
    """Raises ArithmeticError in rechart once y[0] < 0 (at t = pi/2), the way a chart reports its singularity."""

    def rechart(self, chart, y):
        if y[0] < 0.0:
            raise ArithmeticError("coordinates singular")
        return chart + 1, y


def test_vector_registry_shares_names_with_the_lie_group_methods(scratch_registry):
    assert names(state_space="vector") == ("euler", "rk4", "implicit_midpoint")
    assert get("rk4", state_space="vector") is VectorRK4 and VectorRK4.tableau is CLASSICAL_RK4
    assert get("rk4") is RK4 and get("rk4").state_space == "lie"
    assert get("rk4", state_space="vector").state_space == "vector"
    assert set(integrators.state_spaces()) == {"lie", "vector"}
    assert names(state_space=None)[:4] == BUILTIN  # each name once
    with pytest.raises(KeyError, match="for state space 'vector'; valid: euler, rk4, implicit_midpoint"):
        get("rk4_naive", state_space="vector")

    class Impostor(integrators.VectorRK):
        name, order, tableau, description = "euler", 1, CLASSICAL_RK4, "not Euler"

    with pytest.raises(ValueError, match="already registered for state space 'vector'"):
        register(Impostor)


@pytest.mark.parametrize("name, order", [("euler", 1.0), ("rk4", 4.0)])
def test_vector_runge_kutta_order_on_a_linear_ode(name, order):
    integrator, errors, dts = get(name, state_space="vector")(), [], (0.02, 0.01, 0.005)
    for dt in dts:
        run = integrator.integrate(LinearSystem(), 0, np.array([1.0, 0.0]), time_grid(1.0, dt, 2))
        assert run.status is Status.OK and run.chart_changes == 0 and run.rhs_evals == integrator.stages * run.steps
        errors.append(abs(run.omega[-1, 0] - math.cos(1.0)) + abs(run.omega[-1, 1] + math.sin(1.0)))
    assert abs(fitted_order(dts, errors) - order) <= 0.1


def test_vector_step_is_the_step_integrate_takes():
    integrator, system = get("rk4", state_space="vector")(), SingularAt()
    grid = time_grid(0.05, 1e-2, 6)
    run = integrator.integrate(system, 0, np.array([1.0, 0.0]), grid)
    chart, y = 0, np.array([1.0, 0.0])
    for k in range(1, grid.steps + 1):
        chart, y = integrator.step(system, (k - 1) * grid.dt, chart, y, grid.dt)
        np.testing.assert_array_equal(run.omega[k, :2], y)
    assert run.chart_changes == chart == grid.steps  # re-charted (counted) after every step


def test_a_singular_chart_ends_the_run_as_diverged_at_the_exact_step():
    dt = 1e-2
    grid = time_grid(3.0, dt, 7)  # samples every 50 steps
    run = get("rk4", state_space="vector")().integrate(SingularAt(), 0, np.array([1.0, 0.0]), grid)
    expected = math.ceil((math.pi / 2) / dt)  # the first step with cos t < 0
    assert run.status is Status.DIVERGED
    assert run.diverged_at == pytest.approx(expected * dt, rel=1e-12)
    assert run.message == f"coordinates singular at t = {expected * dt:.6g} s"
    bad = int(np.searchsorted(grid.sample_steps, expected))
    assert np.isnan(run.omega[bad:]).all() and np.isfinite(run.omega[:bad]).all()
    assert run.steps == expected - 1 and run.chart_changes == run.steps
