"""Canarutto's ZXZ Euler angles (FORMULARY C1–C5) and Lagrange's equations in them: exact identities, the numpy
equations against the heyoka ones, and the gimbal lock with chart changes on and off."""
from __future__ import annotations

import numpy as np
import pytest

from stereodyn.harness.scenes.cases import Case
from stereodyn.harness.trajectory import Status
from stereodyn.harness.engines.reference import ReferenceEngine
from stereodyn.harness.grid import time_grid
from stereodyn.reference import euler_angles, formulations, truth
from stereodyn.reference.body import RigidBody
from stereodyn.reference.rotations import attitude_angle, quat_to_matrix, zxz_to_matrix

HEAVY = RigidBody(np.array([[2.0, 0.1, -0.05], [0.1, 1.6, 0.08], [-0.05, 0.08, 1.1]]), 1.0,
                  np.array([0.1, -0.05, 0.25]), 9.81,
                  np.array([0.3, -0.2, -0.933]) / np.linalg.norm([0.3, -0.2, -0.933]))
LAGRANGE = RigidBody(np.diag([1.0, 1.0, 0.4]), 1.0, np.array([0.0, 0.0, 0.2]), 9.81, np.array([0.0, 0.0, -1.0]))


@pytest.fixture(scope="module")
def rng():
    return np.random.default_rng(3)


def random_angles(rng, n: int, margin: float = 0.2) -> np.ndarray:
    """(φ, θ, ψ) with θ at least `margin` rad from the poles."""
    return np.stack([rng.uniform(-np.pi, np.pi, n), rng.uniform(margin, np.pi - margin, n),
                     rng.uniform(-np.pi, np.pi, n)], axis=1)


def vee(m: np.ndarray) -> np.ndarray:
    return np.stack([m[..., 2, 1], m[..., 0, 2], m[..., 1, 0]], axis=-1)


# ------------------------------------------------------------------------------------------------------- C1–C5

def test_c1_matrix_and_quaternion(rng):
    angles = random_angles(rng, 500, margin=0.0)
    matrix = euler_angles.rotation_matrix(angles)
    np.testing.assert_allclose(matrix, zxz_to_matrix(angles[:, 0], angles[:, 1], angles[:, 2]), rtol=0, atol=1e-15)
    np.testing.assert_allclose(quat_to_matrix(euler_angles.to_quat(angles)), matrix, rtol=0, atol=1e-15)
    np.testing.assert_allclose(euler_angles.from_quat(euler_angles.to_quat(angles)), angles, rtol=0, atol=1e-13)


def test_c3_c4_angular_velocity(rng):
    """C3 is vee(Ṙ Rᵀ) and C4 is vee(Rᵀ Ṙ) (Ṙ by central differences); C4 inverted gives the rates back."""
    angles, rates = random_angles(rng, 100), rng.normal(size=(100, 3))
    h = 1e-6
    r_dot = (euler_angles.rotation_matrix(angles + h * rates) - euler_angles.rotation_matrix(angles - h * rates)) / (
        2 * h)
    r = euler_angles.rotation_matrix(angles)
    # central differences: truncation h² |R'''| and rounding eps/h, ~1e-10 for these rates
    np.testing.assert_allclose(euler_angles.omega_space(angles, rates), vee(r_dot @ np.swapaxes(r, 1, 2)), atol=1e-8)
    np.testing.assert_allclose(euler_angles.omega_body(angles, rates), vee(np.swapaxes(r, 1, 2) @ r_dot), atol=1e-8)
    omega = euler_angles.omega_body(angles, rates)
    np.testing.assert_allclose(euler_angles.rates_from_omega(angles, omega), rates, rtol=0, atol=1e-13)


def test_c5_kinetic_energy(rng):
    """C5 as printed equals ½ ω'·σω' for principal moments, and its symmetric and rod special cases."""
    angles, rates = random_angles(rng, 200, margin=0.0), rng.normal(size=(200, 3))
    moments = np.array([2.0, 1.5, 1.0])
    np.testing.assert_allclose(euler_angles.kinetic_energy_canarutto(angles, rates, moments),
                               euler_angles.kinetic_energy(angles, rates, np.diag(moments)), rtol=1e-14)
    theta, (phid, thetad, psid) = angles[:, 1], rates.T
    symmetric = (0.5 * (1.5 * np.sin(theta) ** 2 + np.cos(theta) ** 2) * phid ** 2 + 0.5 * 1.5 * thetad ** 2
                 + 0.5 * psid ** 2 + np.cos(theta) * phid * psid)
    np.testing.assert_allclose(euler_angles.kinetic_energy_canarutto(angles, rates, [1.5, 1.5, 1.0]), symmetric,
                               rtol=1e-14)
    rod = 0.5 * 2.0 * (np.sin(theta) ** 2 * phid ** 2 + thetad ** 2)
    np.testing.assert_allclose(euler_angles.kinetic_energy_canarutto(angles, rates, [2.0, 2.0, 0.0]), rod, rtol=1e-14)


def test_mass_matrix_is_the_hessian_and_singular_at_the_poles(rng):
    angles, rates = random_angles(rng, 50), rng.normal(size=(50, 3))
    mass = euler_angles.mass_matrix(angles, HEAVY.inertia)
    np.testing.assert_allclose(0.5 * np.einsum("ni,nij,nj->n", rates, mass, rates),
                               euler_angles.kinetic_energy(angles, rates, HEAVY.inertia), rtol=1e-14)
    np.testing.assert_allclose(np.linalg.det(mass), np.sin(angles[:, 1]) ** 2 * np.linalg.det(HEAVY.inertia),
                               rtol=1e-12)


def test_generalized_force_is_the_gradient_of_the_force_function(rng):
    """Q = Jᵀ M (virtual work) equals ∂U/∂α, U = n·R(α) w (complex step), any gravity direction and centre of mass."""
    angles = random_angles(rng, 100)
    weight_moment, down = HEAVY.weight_moment, HEAVY.gravity_direction
    force = euler_angles.generalized_force(angles, euler_angles.gravity_torque(angles, weight_moment, down))
    for k in range(3):
        step = np.zeros(3)
        step[k] = 1e-30
        gradient = np.imag(euler_angles.force_function(angles + 1j * step, weight_moment, down)) / 1e-30
        np.testing.assert_allclose(gradient, force[:, k], rtol=0, atol=1e-15)


def test_lagrange_equations_are_euler_poisson(rng):
    """The angles' accelerations give ω̇' = d/dt(J α̇) equal to the Euler equations' (central differences)."""
    angles, rates = random_angles(rng, 50), rng.normal(size=(50, 3))
    accel = euler_angles.lagrange_acceleration(angles, rates, HEAVY.inertia, HEAVY.weight_moment,
                                               HEAVY.gravity_direction)
    h = 1e-6
    omega_dot = (euler_angles.omega_body(angles + h * rates, rates + h * accel)
                 - euler_angles.omega_body(angles - h * rates, rates - h * accel)) / (2 * h)
    omega = euler_angles.omega_body(angles, rates)
    torque = np.cross(omega @ HEAVY.inertia, omega) + euler_angles.gravity_torque(angles, HEAVY.weight_moment,
                                                                                 HEAVY.gravity_direction)
    expected = np.linalg.solve(HEAVY.inertia, torque.T).T
    assert np.max(np.abs(omega_dot - expected)) <= 1e-7 * (1 + np.max(np.abs(expected)))  # central differences


def test_numpy_equations_match_the_heyoka_equations(rng):
    """The hand-derived numpy Lagrange equations against the heyoka ones, whose ∂T/∂α, ∂U/∂α and d/dt ∂T/∂α̇ are
    taken symbolically (hy.diff) from T = ½ ω'·σω' and U."""
    formulation = formulations.get("euler_zxz", HEAVY)
    chart = formulation.chart(np.array([0.9, 0.1, -0.3, 0.2]) / np.linalg.norm([0.9, 0.1, -0.3, 0.2]))
    states = np.concatenate([random_angles(rng, 100), rng.normal(size=(100, 3))], axis=1)
    numpy_rhs = formulation.rhs(0.0, chart, states)
    pars = np.repeat(formulation.rhs_parameters(chart)[:, None], len(states), axis=1)
    heyoka_rhs = formulations.compiled_rhs("euler_zxz")(states.T.copy(), pars=pars, time=np.zeros(len(states))).T
    scale = 1.0 + np.max(np.abs(numpy_rhs), axis=1, keepdims=True)
    # θ within 0.2 rad of a pole: 1/sin θ up to 5 multiplies the rounding of both
    assert np.max(np.abs(numpy_rhs - heyoka_rhs) / scale) <= 1e-13


def test_rechart_references_the_angles_to_a_rotated_frame(rng):
    """Near gimbal lock the chart is re-referenced so the angles become (0, π/2, 0), the attitude and ω unchanged."""
    formulation = formulations.get("euler_zxz", HEAVY)
    chart = formulation.chart(np.array([1.0, 0.0, 0.0, 0.0]))
    state = np.array([0.4, 0.05, -1.2, 0.3, -0.2, 1.5])  # sin θ = 0.05 < 0.5: outside the chart's domain
    new_chart, new_state = formulation.check_chart(chart, state)
    assert new_chart.changes == 1
    np.testing.assert_allclose(new_state[:3], [0.0, np.pi / 2, 0.0], atol=1e-15)
    (quat, omega), (new_quat, new_omega) = formulation.observe(chart, state), formulation.observe(new_chart, new_state)
    assert attitude_angle(quat_to_matrix(quat), quat_to_matrix(new_quat)) <= 1e-15
    np.testing.assert_allclose(new_omega, omega, rtol=0, atol=1e-15)
    np.testing.assert_allclose(new_chart.down, quat_to_matrix(new_chart.frame).T @ HEAVY.gravity_direction, atol=0)


# --------------------------------------------------------------------------------------------------- gimbal lock

def through_identity(body: RigidBody, omega: np.ndarray, before: float) -> tuple[np.ndarray, np.ndarray]:
    """The state `before` seconds ahead of the attitude identity (θ = 0) with body angular velocity omega: integrated
    backwards as the time-reversed motion (R(-t), -ω(-t)), which is a motion of the same body."""
    run = truth.truth(body, np.array([1.0, 0.0, 0.0, 0.0]), -np.asarray(omega), np.array([0.0, before]))
    return run.quat[-1], -run.omega[-1]


def lagrange_through_vertical() -> Case:
    """The suite's Lagrange top on a motion whose axis passes through the upward vertical (θ = 0) at t = 5 s, and
    first at t = 0.38 s: it nutates from the vertical to θ = 2.45 rad and back."""
    quat0, omega0 = through_identity(LAGRANGE, np.array([2.0, 0.0, 3.0]), 5.0)
    return Case(name="lagrange-through-vertical", description="", tags=(), mass=LAGRANGE.mass, com=LAGRANGE.com,
                inertia=LAGRANGE.inertia, gravity=LAGRANGE.gravity, gravity_direction=LAGRANGE.gravity_direction,
                quat0=quat0, omega0=omega0, t_end=10.0, dt=(1e-3,), samples=201)


@pytest.mark.parametrize("integrator, dt", [("taylor", None), ("rk4", 1e-3), ("rk4", 1e-2), ("euler", 1e-3)])
def test_without_chart_changes_gimbal_lock_ends_the_run_with_its_reason(integrator, dt):
    case = lagrange_through_vertical()
    grid = time_grid(case.t_end, dt or case.t_end / (case.samples - 1), case.samples)
    engine = ReferenceEngine()
    run = engine.prepare(case, integrator, dt, formulation="euler_zxz", chart_changes=False).run(grid)
    assert run.status in (Status.DIVERGED, Status.FAILED)
    assert run.message.startswith("gimbal lock: theta reached 0") and "chart changes disabled" in run.message
    # The guard trips within SINGULAR_DISTANCE (0.1 rad) of the pole, at t = 0.3302 s (θ̇ = -2 rad/s there), a step
    # later at the most for fixed steps, and before the passage at t = 0.38 s.
    assert 0.329 < run.diverged_at <= 0.3302 + (dt or 0.0)
    bad = np.searchsorted(grid.times, run.diverged_at)
    assert np.isnan(run.quat[bad:]).all() and np.isfinite(run.quat[:bad]).all()
    # With chart changes, the same motion runs through and agrees with the truth.
    charted = engine.prepare(case, integrator, dt, formulation="euler_zxz").run(grid)
    assert charted.status is Status.OK and charted.chart_changes > 0
    reference = truth.truth(case.body, case.quat0, case.omega0, grid.times)
    error = np.max(attitude_angle(quat_to_matrix(charted.quat), quat_to_matrix(reference.quat)))
    bound = {None: 1e-12, 1e-3: 1e-8, 1e-2: 1e-4}[dt] if integrator != "euler" else 1e-1
    assert error <= bound, error


def test_singular_initial_state_without_chart_changes_fails_at_once():
    case = lagrange_through_vertical()
    at_the_pole = Case(**{**case.__dict__, "quat0": np.array([1.0, 0.0, 0.0, 0.0])})
    grid = time_grid(1.0, 1e-2, 11)
    for integrator, dt in (("taylor", None), ("rk4", 1e-2)):
        run = ReferenceEngine().prepare(at_the_pole, integrator, dt, formulation="euler_zxz",
                                        chart_changes=False).run(grid)
        assert run.status is Status.DIVERGED and run.diverged_at == 0.0 and "gimbal lock" in run.message
        assert np.isnan(run.quat).all()
    started = ReferenceEngine().prepare(at_the_pole, "rk4", 1e-2, formulation="euler_zxz").run(grid)
    assert started.status is Status.OK and started.chart_changes >= 1  # re-charted at t = 0
