"""stereodyn.reference.exact: the oracle registry, every exact motion substituted back into the Euler–Poisson equations and the
quaternion kinematics, the checks' teeth, and the elliptic building blocks."""
import dataclasses
import math

import numpy as np
import pytest
from scipy.integrate import quad, solve_ivp
from scipy.special import ellipj, ellipk

from stereodyn.reference.body import RigidBody
from stereodyn.reference.euler_poisson import downward_vertical, quat_dot
from stereodyn.reference.exact import (ORACLES, Oracle, Setup, free_motion, grioli_body, grioli_precession, hess_grioli,
                             hess_grioli_body, lagrange_precession, mlodzejowski, pendulum, separatrix_omega,
                             staude_direction, staude_rotation)
from stereodyn.reference.closed_form import first_kind, jacobi, third_kind_complete, third_kind_reduced
from stereodyn.reference.rotations import matrix_to_quat, zxz_to_matrix

G = 9.81
QUAT = matrix_to_quat(zxz_to_matrix(0.3, 1.2, -0.4))
ROTATED = zxz_to_matrix(0.5, -0.8, 1.9)


def _rotated(body: RigidBody, direction=(0.0, 0.0, -1.0)) -> RigidBody:
    """The same body seen in body axes turned by ROTATED (a non-diagonal inertia), under a tilted gravity."""
    inertia = ROTATED @ body.inertia @ ROTATED.T
    return RigidBody(0.5 * (inertia + inertia.T), body.mass, ROTATED @ body.com, body.gravity, np.array(direction))


def _free(inertia, omega):
    body = RigidBody(np.asarray(inertia, dtype=float), 1.0, np.zeros(3))
    oracle = "euler_poinsot_separatrix" if omega is None else "euler_poinsot"
    omega0 = separatrix_omega(body, 1.2, -1.0) if omega is None else np.array(omega)
    return Setup(body, QUAT, omega0, oracle)


def _setups() -> dict[str, Setup]:
    top = RigidBody(np.diag([1.0, 1.0, 0.4]), 1.0, np.array([0.0, 0.0, 0.2]), G)
    heavy = RigidBody(np.array([[2.0, 0.1, -0.05], [0.1, 1.6, 0.08], [-0.05, 0.08, 1.1]]), 1.0,
                      np.array([0.1, -0.05, 0.25]), G)
    grioli = grioli_body((2.5625, 2.0, 1.0), 1.0, 0.625, G)
    hess = hess_grioli_body(1.25, 1.0, 0.5, 1.0, 1.0, 0.75)
    tilted = (0.6, 0.0, -0.8)
    return {
        "free major": _free(np.diag([2.7, 1.9, 1.1]), (1.0, 0.2, 0.3)),
        "free minor rotated": _free(ROTATED @ np.diag([2.7, 1.9, 1.1]) @ ROTATED.T, (0.1, 0.3, 1.2)),
        "free symmetric": _free(np.diag([2.0, 2.0, 1.0]), (0.3, -0.5, 1.1)),
        "free separatrix": _free(np.diag([3.0, 2.0, 1.0]), None),
        "lagrange slow": lagrange_precession(top, 0.6, 15.0, "slow", heading=0.3),
        "lagrange fast rotated": lagrange_precession(_rotated(top, tilted), 1.0, 12.0, "fast", heading=0.2),
        "sleeping top": lagrange_precession(top, 0.0, 8.0),
        "staude": staude_rotation(heavy, -staude_direction(heavy, 1.3), 1.0, heading=0.4),
        "staude rotated": staude_rotation(_rotated(heavy, tilted), -staude_direction(_rotated(heavy, tilted), 3.0)),
        "grioli": grioli_precession(grioli, 1.0, 1.0, heading=0.7),
        "grioli rotated": grioli_precession(_rotated(grioli, tilted), 2.5, -1.0),
        "hess-grioli": hess_grioli(hess, 1.0, 2.0, -0.7, 0.4, heading=0.3),
        "hess-grioli rotated": hess_grioli(_rotated(hess, tilted), 0.3, 0.4, 2.6, 0.4),
        "mlodzejowski": mlodzejowski(hess, 2.5, -1.0),
        "mlodzejowski rotated": mlodzejowski(_rotated(hess, tilted), 0.3, 3.0, heading=1.0),
    }


SETUPS = _setups()


def test_registry_names_and_shape():
    assert list(ORACLES) == ["euler_poinsot", "euler_poinsot_separatrix", "lagrange_precession", "staude_rotation",
                             "grioli_precession", "hess_grioli", "mlodzejowski", "self_excited_spinup",
                             "self_excited_uniform"]
    assert [field.name for field in dataclasses.fields(Oracle)] == ["name", "check", "solve"]
    assert all(name == oracle.name for name, oracle in ORACLES.items())
    with pytest.raises(dataclasses.FrozenInstanceError):
        ORACLES["euler_poinsot"].name = "x"


@pytest.mark.parametrize("name", list(SETUPS))
def test_constructors_satisfy_their_oracle_and_start_at_the_state(name):
    setup = SETUPS[name]
    oracle = ORACLES[setup.oracle]
    assert oracle.check(setup.body, setup.quat0, setup.omega0) is None
    times = np.array([0.0, 0.7, 3.0])
    quat, omega = oracle.solve(setup.body, setup.quat0, setup.omega0, times)
    assert quat.shape == (3, 4) and omega.shape == (3, 3)
    # same sign as given, not just the same attitude; 1e-15 where the attitude goes through a matrix
    assert np.max(np.abs(quat[0] - setup.quat0)) <= 1e-15
    assert np.max(np.abs(omega[0] - setup.omega0)) <= 4e-15 * max(1.0, np.linalg.norm(setup.omega0))
    assert np.max(np.abs(np.linalg.norm(quat, axis=1) - 1.0)) <= 4e-16


def _derivative(function, t, step):
    """8th-order central difference of function(times (n,)) -> (n, k) at the times t (m,)."""
    weights = np.array([1 / 280, -4 / 105, 1 / 5, -4 / 5, 0.0, 4 / 5, -1 / 5, 4 / 105, -1 / 280])
    offsets = np.arange(-4, 5) * step
    values = function((t[:, None] + offsets[None, :]).ravel()).reshape(t.size, 9, -1)
    return np.einsum("j,mjk->mk", weights, values) / step


@pytest.mark.parametrize("name", list(SETUPS))
def test_exact_motions_satisfy_euler_poisson_and_kinematics(name):
    """Substitution: σω̇ + ω × σω = w × H(t) and q̇ = ½ q ⊗ (0, ω), with the derivatives of the closed forms by
    8th-order differences (step 1e-3 / |ω|: truncation ~1e-20, rounding ~1e-13 of the scale)."""
    setup = SETUPS[name]
    body, solve = setup.body, ORACLES[setup.oracle].solve
    times = np.linspace(0.0, 9.0, 7)
    speed = max(1.0, float(np.max(np.abs(solve(body, setup.quat0, setup.omega0, np.linspace(0, 9, 50))[1]))))
    step = 1e-3 / speed

    quat, omega = solve(body, setup.quat0, setup.omega0, times)
    omega_dot = _derivative(lambda t: solve(body, setup.quat0, setup.omega0, t)[1], times, step)
    torque = np.cross(body.weight_moment, downward_vertical(body, quat)) if body.has_gravity else 0.0
    momentum = omega @ body.inertia
    residual = omega_dot @ body.inertia + np.cross(omega, momentum) - torque
    scale = np.max(np.abs(np.cross(omega, momentum))) + np.linalg.norm(body.weight_moment)
    assert np.max(np.abs(residual)) <= 1e-9 * scale

    quat_rate = _derivative(lambda t: solve(body, setup.quat0, setup.omega0, t)[0], times, step)
    assert np.max(np.abs(quat_rate - quat_dot(quat, omega))) <= 1e-9 * speed


@pytest.mark.parametrize("name", ["free major", "lagrange slow", "staude", "grioli", "hess-grioli", "mlodzejowski"])
def test_checks_have_teeth(name):
    """The constructor's state passes; the same state with ω0 nudged by 1e-6 (relative) or with gravity switched off
    (where the motion needs it) is refused with a one-line reason. (The free body: any torque-free state is a
    Euler–Poinsot motion, so gravity is what is switched on.)"""
    setup = SETUPS[name]
    check = ORACLES[setup.oracle].check
    nudged = setup.omega0 + 1e-6 * np.linalg.norm(setup.omega0) * np.array([1.0, -2.0, 3.0]) / math.sqrt(14.0)
    if setup.oracle == "euler_poinsot":
        heavy = RigidBody(setup.body.inertia, 1.0, np.array([0.0, 0.0, 0.1]), G)
        reason = check(heavy, setup.quat0, setup.omega0)
    else:
        reason = check(setup.body, setup.quat0, nudged)
        free = RigidBody(setup.body.inertia, setup.body.mass, setup.body.com, 0.0)
        assert isinstance(check(free, setup.quat0, setup.omega0), str)
    assert isinstance(reason, str) and reason and "\n" not in reason


def test_separatrix_oracle_and_euler_poinsot_split_the_states():
    body = RigidBody(np.diag([3.0, 2.0, 1.0]), 1.0, np.zeros(3))
    on = separatrix_omega(body, 1.2, 0.5)
    off = on * np.array([1.0 + 1e-8, 1.0, 1.0])
    assert ORACLES["euler_poinsot_separatrix"].check(body, QUAT, on) is None
    assert "separatrix" in ORACLES["euler_poinsot"].check(body, QUAT, on)
    assert ORACLES["euler_poinsot"].check(body, QUAT, off) is None
    assert "off the separatrix" in ORACLES["euler_poinsot_separatrix"].check(body, QUAT, off)
    symmetric = RigidBody(np.diag([2.0, 2.0, 1.0]), 1.0, np.zeros(3))
    assert "symmetric" in ORACLES["euler_poinsot_separatrix"].check(symmetric, QUAT, np.array([1.0, 0.0, 0.0]))
    assert free_motion(body, QUAT, np.array([0.0, 1.2, 0.0])).kind == "uniform"


# --- the elliptic building blocks ---------------------------------------------------------------------------------

@pytest.mark.parametrize("m", [0.0, 1e-12, 0.3, 0.9, 1.0 - 1e-6])
def test_jacobi_functions_match_scipy_and_reduce(m):
    quarter = float(ellipk(m))
    u = np.linspace(-9.0 * quarter, 9.0 * quarter, 301)
    sn, cn, dn, j, *_ = jacobi(u, m, quarter, 1.0 - m)
    reference = np.array(ellipj(np.abs(u), m)[:3])
    reference[0] *= np.sign(u)
    # scipy's AGM without reduction at |u| up to 9K: both agree to a few ulps of the argument
    assert np.max(np.abs(np.array([sn, cn, dn]) - reference)) <= 2e-14
    assert np.max(np.abs(sn * sn + cn * cn - 1.0)) <= 4e-16
    assert np.max(np.abs(dn * dn + m * sn * sn - 1.0)) <= 4e-16
    assert np.array_equal(j, np.round(u / (2.0 * quarter)))


@pytest.mark.parametrize("m", [0.1, 0.7, 1.0 - 1e-6])
def test_first_kind_inverts_the_jacobi_functions(m):
    quarter = float(ellipk(m))
    for u in np.linspace(-1.99 * quarter, 1.99 * quarter, 23):
        sn, cn, dn, _ = ellipj(abs(u), m)
        # scipy's ellpj at m = 1 - 1e-6, given m and not 1 - m, is itself off by ~1e-14 relative
        assert first_kind(math.copysign(sn, u), cn, dn, quarter) == pytest.approx(u, abs=2e-14 * quarter)


@pytest.mark.parametrize("m, nu", [(0.2, 0.0), (0.5, 0.3), (0.9, 4.0), (1.0 - 1e-6, 0.7)])
def test_third_kind_against_quadrature(m, nu):
    quarter = float(ellipk(m))
    for u in (0.3 * quarter, -0.8 * quarter, quarter):
        sn, cn, dn, _ = ellipj(abs(u), m)
        value = third_kind_reduced(np.array([math.copysign(sn, u)]), np.array([cn]), np.array([dn]), nu)[0]
        expected = math.copysign(quad(lambda x: 1.0 / (1.0 + nu * ellipj(x, m)[0] ** 2), 0.0, abs(u),
                                      epsabs=0.0, epsrel=1e-13, limit=200)[0], u)
        assert value == pytest.approx(expected, rel=1e-13)
    assert third_kind_complete(1.0 - m, nu) == pytest.approx(
        third_kind_reduced(np.array([1.0]), np.array([0.0]), np.array([math.sqrt(1.0 - m)]), nu)[0], rel=1e-14)


@pytest.mark.parametrize("angle0, rate0", [(0.3, 0.1), (2.9, -0.5), (-1.0, 3.0), (1.0, -3.0), (math.pi, 0.5),
                                           (7.0, 0.2), (0.0, 0.0), (math.pi, 0.0), (-math.pi, 1e-3)])
def test_pendulum_against_an_integration(angle0, rate0):
    frequency = 1.3
    times = np.linspace(0.0, 6.0, 121)
    motion = pendulum(angle0, rate0, frequency, times)
    assert motion.angle[0] == angle0 and motion.rate[0] == pytest.approx(rate0, abs=1e-15)
    assert np.max(np.abs(motion.sin - np.sin(motion.angle))) <= 1e-14
    assert np.max(np.abs(motion.cos - np.cos(motion.angle))) <= 1e-14
    energy = (0.5 * motion.rate / frequency) ** 2 + np.sin(0.5 * motion.angle) ** 2
    assert np.ptp(energy) <= 1e-14
    if rate0 == 0.0 and math.sin(angle0) == 0.0:
        return  # equilibria stay put; an integrator would drift off the unstable one from sin(π) = 1.2e-16
    integrated = solve_ivp(lambda t, y: [y[1], -frequency ** 2 * math.sin(y[0])], (0.0, 6.0), [angle0, rate0],
                           t_eval=times, rtol=1e-13, atol=1e-13, method="DOP853")
    # DOP853 at 1e-13 is itself accurate to ~1e-11 here
    assert np.max(np.abs(motion.angle - integrated.y[0])) <= 1e-10
    assert np.max(np.abs(motion.rate - integrated.y[1])) <= 1e-10


def test_pendulum_separatrix_and_whole_turns():
    frequency = 0.8
    times = np.linspace(0.0, 30.0, 301)
    on = pendulum(0.0, 2.0 * frequency, frequency, times)  # e = 1 exactly: creeps up to the top
    assert np.all(np.diff(on.angle) > 0) and on.angle[-1] == pytest.approx(math.pi, abs=1e-9)
    over = pendulum(0.0, 2.5 * frequency, frequency, times)  # rotation: the angle keeps counting turns
    assert np.all(np.diff(over.angle) > 0) and over.angle[-1] > 4.0 * math.pi
