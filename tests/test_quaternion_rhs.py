"""Which R(q) the reference's quaternion right-hand side uses off the unit sphere (issue 30, item 6): the compiled one
that the reference engine's fixed-step integrators step is the homogeneous R~(q) = |q|² R(q/|q|)
(reference/truth.py), while reference.euler_poisson's numpy form normalises q first. An engine author reproducing
the reference's rk4 needs the homogeneous form (docs/ENGINE_PLUGIN.md)."""
import numpy as np
import pytest

from stereodyn.harness.engines import get_engine
from stereodyn.harness.grid import time_grid
from stereodyn.harness.scenes.cases import load_case, suite_dir
from stereodyn.reference import euler_poisson, formulations
from stereodyn.reference.rotations import quat_to_matrix

DT, STEPS = 0.01, 200


@pytest.fixture(scope="module")
def case():
    return load_case(suite_dir() / "lagrange-top.toml")


def homogeneous(q: np.ndarray) -> np.ndarray:
    """(w² - v·v) I + 2 v vᵀ + 2 w [v]×, written here independently of reference/truth.py."""
    w, v = q[0], q[1:]
    skew = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    return (w * w - v @ v) * np.eye(3) + 2.0 * np.outer(v, v) + 2.0 * w * skew


def euler_poisson_rhs(body, y: np.ndarray, attitude) -> np.ndarray:
    """Euler–Poisson under uniform gravity as an engine author would write it, R from attitude(q)."""
    q, omega = y[:4], y[4:]
    w, v = q[0], q[1:]
    q_dot = np.concatenate([[-0.5 * v @ omega], 0.5 * (w * omega + np.cross(v, omega))])
    vertical = attitude(q).T @ body.gravity_direction
    torque = np.cross(body.inertia @ omega, omega) + np.cross(body.weight_moment, vertical)
    return np.concatenate([q_dot, np.linalg.solve(body.inertia, torque)])


def rk4(body, y0: np.ndarray, attitude) -> np.ndarray:
    states, y = [y0], y0
    for _ in range(STEPS):
        k1 = euler_poisson_rhs(body, y, attitude)
        k2 = euler_poisson_rhs(body, y + 0.5 * DT * k1, attitude)
        k3 = euler_poisson_rhs(body, y + 0.5 * DT * k2, attitude)
        k4 = euler_poisson_rhs(body, y + DT * k3, attitude)
        y = y + DT / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        states.append(y)
    return np.array(states)


def test_the_compiled_quaternion_rhs_is_homogeneous_off_the_unit_sphere(case):
    """At |q| = 1.1 the compiled ω̇ is the homogeneous form's; the numpy form (normalised q) differs by the gravity
    torque's factor |q|² - 1 = 0.21."""
    body = case.body
    q = 1.1 * np.array([0.8, 0.2, -0.4, 0.4]) / np.linalg.norm([0.8, 0.2, -0.4, 0.4])
    y = np.concatenate([q, [0.5, -0.3, 15.0]])
    formulation = formulations.get("quaternion", body)
    compiled = formulation.fast_rhs(0.0, formulation.chart(np.array([1.0, 0.0, 0.0, 0.0])), y)
    np.testing.assert_allclose(compiled, euler_poisson_rhs(body, y, homogeneous), rtol=0, atol=1e-12)
    numpy_form = np.concatenate(euler_poisson.rhs(body, y[:4], y[4:]))
    np.testing.assert_allclose(numpy_form, euler_poisson_rhs(body, y, quat_to_matrix), rtol=0, atol=1e-12)
    gravity = np.linalg.solve(body.inertia, np.cross(body.weight_moment, quat_to_matrix(q).T @ body.gravity_direction))
    np.testing.assert_allclose(compiled[4:] - numpy_form[4:], 0.21 * gravity, rtol=1e-9, atol=1e-13)


def test_an_independent_rk4_matches_the_reference_only_with_the_homogeneous_form(case):
    """The reference engine's quaternion rk4 over 200 steps of lagrange-top: a hand-written RK4 with the homogeneous
    R agrees to round-off (measured 2.6e-15 on the quaternion, 1.9e-15 rad/s on ω), with the normalised R it is
    7.7e-7 off (|q| drifts by 5e-7 over these steps)."""
    run = get_engine("reference").prepare(case, "rk4", DT, formulation="quaternion").run(
        time_grid(STEPS * DT, DT, STEPS + 1))
    y0 = np.concatenate([case.quat0, case.omega0])
    same = rk4(case.body, y0, homogeneous)
    assert np.abs(same[:, :4] - run.quat).max() < 1e-13  # 40x the 2.6e-15 measured
    assert np.abs(same[:, 4:] - run.omega).max() < 1e-12  # ω is ~15 rad/s: 1.9e-15 measured
    normalised = rk4(case.body, y0, quat_to_matrix)
    assert np.abs(normalised[:, :4] - run.quat).max() > 1e-8  # measured 7.7e-7
