"""Integrals: exact values on hand-built states, structural predicates, and the drift bookkeeping."""
import numpy as np
import pytest

from stereodyn.reference.body import RigidBody
from stereodyn.reference.euler_poisson import downward_vertical, omega_dot, rhs
from stereodyn.reference.integrals import INTEGRALS, Integral, drift
from stereodyn.reference.rotations import quat_exp, quat_mul, quat_to_matrix, zxz_to_matrix, matrix_to_quat

G = 9.81
IDENTITY = np.array([1.0, 0.0, 0.0, 0.0])


def _body(moments, com, gravity=G, rotation=None):
    """Body with the given principal moments; rotation (3, 3) turns its principal frame (σ -> R σ Rᵀ, c -> R c)."""
    rotation = np.eye(3) if rotation is None else rotation
    return RigidBody(inertia=rotation @ np.diag(moments) @ rotation.T, mass=1.0, com=rotation @ np.asarray(com),
                     gravity=gravity)


def _value(name, body, quat, omega):
    return INTEGRALS[name].value(body, np.atleast_2d(quat), np.atleast_2d(omega))[0]


def _applies(name, body, quat=IDENTITY, omega=(0.3, -0.2, 1.0)):
    return INTEGRALS[name].applies(body, np.asarray(quat, dtype=float), np.asarray(omega, dtype=float))


ROTATION = zxz_to_matrix(0.7, -1.1, 2.3)


def test_keys_and_names():
    assert set(INTEGRALS) == {"energy", "momentum", "casimir", "lagrange", "kovalevskaya", "chaplygin", "hess",
                              "self_excited"}
    assert all(integral.name == key for key, integral in INTEGRALS.items())


def test_energy_exact_value():
    body = _body((2.0, 1.5, 1.0), (0.1, 0.0, 0.2))
    omega = np.array([0.4, 0.1, 2.0])
    # identity attitude, d = (0, 0, -1): H = (0, 0, -1), V = -m g c·H = +0.2 g (G above O)
    kinetic = 0.5 * (2.0 * 0.16 + 1.5 * 0.01 + 1.0 * 4.0)
    assert _value("energy", body, IDENTITY, omega) == pytest.approx(kinetic + 0.2 * G, rel=1e-15)
    assert INTEGRALS["energy"].scale(body, IDENTITY, omega) == pytest.approx(kinetic + 0.2 * G, rel=1e-15)
    # upside down (half turn about x): G below O, potential -0.2 g; scale uses |V|
    flipped = np.array([0.0, 1.0, 0.0, 0.0])
    assert _value("energy", body, flipped, omega) == pytest.approx(kinetic - 0.2 * G, rel=1e-15)
    assert INTEGRALS["energy"].scale(body, flipped, omega) == pytest.approx(kinetic + 0.2 * G, rel=1e-15)
    # raw quaternions are normalised before the potential is evaluated
    assert _value("energy", body, 1.001 * flipped, omega) == pytest.approx(kinetic - 0.2 * G, rel=1e-15)


def test_energy_non_diagonal_and_any_gravity_direction():
    body = RigidBody(inertia=[[2.0, 0.1, -0.05], [0.1, 1.6, 0.08], [-0.05, 0.08, 1.1]], mass=2.0,
                     com=[0.1, -0.05, 0.25], gravity=G, gravity_direction=[1.0, 0.0, 0.0])
    quat = matrix_to_quat(zxz_to_matrix(0.1, 0.7, 0.3))
    omega = np.array([1.0, -0.5, 2.0])
    vertical = quat_to_matrix(quat).T @ [1.0, 0.0, 0.0]
    expected = 0.5 * omega @ body.inertia @ omega - 2.0 * G * body.com @ vertical
    assert _value("energy", body, quat, omega) == pytest.approx(expected, rel=1e-15)
    assert np.allclose(downward_vertical(body, quat), vertical, atol=1e-16, rtol=0)


def test_momentum_world_vector_and_vertical_component():
    free = _body((2.0, 1.5, 1.0), (0.0, 0.0, 0.0), gravity=0.0)
    omega = np.array([0.4, 0.1, 2.0])
    quarter_z = np.array([np.cos(np.pi / 4), 0.0, 0.0, np.sin(np.pi / 4)])  # body x -> world y
    momentum = _value("momentum", free, quarter_z, omega)
    assert np.allclose(momentum, [-0.15, 0.8, 2.0], atol=1e-15, rtol=0)
    assert INTEGRALS["momentum"].scale(free, quarter_z, omega) == pytest.approx(np.sqrt(0.64 + 0.0225 + 4.0))
    heavy = _body((2.0, 1.5, 1.0), (0.0, 0.0, 0.2))
    # K·d = σω·H, with H = (0, 0, -1) at the identity
    assert _value("momentum", heavy, quarter_z, omega) == pytest.approx(-2.0, rel=1e-15)


def test_casimir_is_raw_norm_squared():
    quat = np.array([[1.0, 0.0, 0.0, 0.0], [1.0 + 1e-10, 0.0, 0.0, 0.0], [0.6, 0.8, 0.0, 0.0]])
    omega = np.zeros((3, 3))
    body = _body((2.0, 1.5, 1.0), (0.0, 0.0, 0.0), gravity=0.0)
    assert np.allclose(INTEGRALS["casimir"].value(body, quat, omega), [1.0, 1.0 + 2e-10, 1.0], rtol=1e-15, atol=0)
    assert drift(INTEGRALS["casimir"], body, quat, omega) == pytest.approx(2e-10, rel=1e-5)
    # measured against 1 even when the first sample is off
    assert drift(INTEGRALS["casimir"], body, quat[1:], omega[1:]) == pytest.approx(2e-10, rel=1e-5)


def test_drift_bookkeeping():
    body = _body((2.0, 1.5, 1.0), (0.0, 0.0, 0.2))
    omega = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.1], [np.nan, np.nan, np.nan], [0.0, 0.0, 0.9]])
    quat = np.tile(IDENTITY, (4, 1))
    # energy 0.5 + 0.2 g at t = 0; |ΔE| max 0.5·(1.21 - 1) = 0.105; NaN sample skipped
    assert drift(INTEGRALS["energy"], body, quat, omega) == pytest.approx(0.105 / (0.5 + 0.2 * G), rel=1e-13)
    # a predicate that fails gives NaN; so does a non-finite initial state
    assert np.isnan(drift(INTEGRALS["kovalevskaya"], body, quat, omega))
    assert np.isnan(drift(INTEGRALS["energy"], body, quat[2:], omega[2:]))
    # a vector integral: Euclidean norm of the difference, over |K0|
    free = _body((2.0, 1.5, 1.0), (0.0, 0.0, 0.0), gravity=0.0)
    spin = np.array([[0.0, 0.0, 1.0], [0.0, 0.1, 1.0]])
    assert drift(INTEGRALS["momentum"], free, quat[:2], spin) == pytest.approx(0.15, rel=1e-13)
    # a body at rest has a zero scale: drift becomes absolute rather than infinite
    assert drift(INTEGRALS["momentum"], free, quat[:2], np.zeros((2, 3))) == 0.0
    assert isinstance(INTEGRALS["energy"], Integral)


def test_lagrange_predicate_and_value():
    top = _body((1.0, 1.0, 0.4), (0.0, 0.0, 0.2))
    assert _applies("lagrange", top)
    assert _value("lagrange", top, IDENTITY, [0.5, 0.0, 15.0]) in (15.0, -15.0)
    assert not _applies("lagrange", _body((1.0, 1.0, 0.4), (0.1, 0.0, 0.2)))  # com off the axis
    assert _applies("lagrange", _body((1.0, 1.0, 0.4), (0.1, 0.0, 0.2), gravity=0.0))  # torque-free: any com
    assert not _applies("lagrange", _body((2.0, 1.5, 1.0), (0.0, 0.0, 0.2)))
    rotated = _body((1.0, 1.0, 0.4), (0.0, 0.0, 0.2), rotation=ROTATION)
    assert _applies("lagrange", rotated)
    assert abs(_value("lagrange", rotated, IDENTITY, ROTATION @ [0.5, 0.0, 15.0])) == pytest.approx(15.0, rel=1e-14)


def test_kovalevskaya_predicate():
    assert _applies("kovalevskaya", _body((2.0, 2.0, 1.0), (0.1, 0.0, 0.0)))
    assert _applies("kovalevskaya", _body((2.0, 2.0, 1.0), (0.06, 0.08, 0.0)))
    assert not _applies("kovalevskaya", _body((2.0, 2.0, 1.1), (0.1, 0.0, 0.0)))
    assert not _applies("kovalevskaya", _body((2.0, 2.0, 1.0), (0.1, 0.0, 0.01)))  # com off the plane
    assert not _applies("kovalevskaya", _body((2.0, 2.0, 1.0), (0.1, 0.0, 0.0), gravity=0.0))
    assert _applies("kovalevskaya", _body((2.0, 2.0, 1.0), (0.1, 0.0, 0.0), rotation=ROTATION))
    assert _applies("kovalevskaya", _body((1.0, 2.0, 2.0), (0.0, 0.0, 0.1)))  # distinct axis is body x


def test_kovalevskaya_value_exact_and_frame_free():
    body = _body((2.0, 2.0, 1.0), (0.1, 0.0, 0.0))
    omega = np.array([0.5, -0.3, 1.5])
    quat = matrix_to_quat(zxz_to_matrix(0.2, 1.0, 0.4))
    h = quat_to_matrix(quat).T @ [0.0, 0.0, -1.0]
    # G6 for k = (1, 0, 0), H downward: (p1² - p2² + α/A3 H1)² + (2 p1 p2 + α/A3 H2)², α = m g l
    a = 0.1 * G / 1.0
    expected = (0.25 - 0.09 + a * h[0]) ** 2 + (2 * 0.5 * -0.3 + a * h[1]) ** 2
    assert _value("kovalevskaya", body, quat, omega) == pytest.approx(expected, rel=1e-14)
    # a rotated, non-diagonal inertia with the state rotated alike gives the same number
    rotated = _body((2.0, 2.0, 1.0), (0.1, 0.0, 0.0), rotation=ROTATION)
    q_rot = quat_mul(quat, matrix_to_quat(ROTATION.T))  # body axes turned by ROTATION
    assert np.allclose(quat_to_matrix(q_rot).T @ [0, 0, -1], ROTATION @ h, atol=1e-15, rtol=0)
    assert _value("kovalevskaya", rotated, q_rot, ROTATION @ omega) == pytest.approx(expected, rel=1e-13)
    # com in the plane at 53°: same modulus as rotating the state about u3 by that angle
    spin_axis = quat_exp(np.array([0.0, 0.0, np.arctan2(0.8, 0.6)]))
    turned = _body((2.0, 2.0, 1.0), (0.06, 0.08, 0.0))
    q_turn = quat_mul(quat, quat_exp(np.array([0.0, 0.0, -np.arctan2(0.8, 0.6)])))
    r = quat_to_matrix(spin_axis)
    assert _value("kovalevskaya", turned, q_turn, r @ omega) == pytest.approx(expected, rel=1e-13)
    scale = INTEGRALS["kovalevskaya"].scale(body, quat, omega)
    assert scale == pytest.approx((0.34 + a * np.hypot(h[0], h[1])) ** 2, rel=1e-14)


def test_kovalevskaya_derivative_is_zero_only_for_the_kovalevskaya_body():
    """d|w|²/dt from the Euler–Poisson right-hand side: 0 to rounding when A1 = A2 = 2 A3, not otherwise."""
    quat = matrix_to_quat(zxz_to_matrix(0.2, 1.0, 0.4))
    omega = np.array([0.5, -0.3, 1.5])
    h = 1e-6
    for moments, vanishes in (((2.0, 2.0, 1.0), True), ((2.0, 2.0, 1.2), False)):
        for com in ((0.1, 0.0, 0.0), (0.06, 0.08, 0.0)):
            body = _body(moments, com, rotation=ROTATION)
            q0, w0 = quat_mul(quat, matrix_to_quat(ROTATION.T)), ROTATION @ omega
            dq, dw = rhs(body, q0, w0)
            rate = (_value("kovalevskaya", body, q0 + h * dq, w0 + h * dw)
                    - _value("kovalevskaya", body, q0 - h * dq, w0 - h * dw)) / (2 * h)
            scale = INTEGRALS["kovalevskaya"].scale(body, q0, w0)
            # central difference: truncation ~h² and cancellation ~1e-16/h, both < 1e-9 here
            assert (abs(rate) / scale < 1e-8) == vanishes


def test_chaplygin_predicate_and_value():
    body = _body((4.0, 4.0, 1.0), (0.1, 0.0, 0.0))
    # K_H = σω·H = 0 with H = (0, 0, -1) at the identity: ω3 = 0
    omega = np.array([0.3, -0.2, 0.0])
    assert _applies("chaplygin", body, IDENTITY, omega)
    assert not _applies("chaplygin", body, IDENTITY, (0.3, -0.2, 0.5))  # K_H != 0
    assert not _applies("chaplygin", _body((4.0, 4.0, 1.1), (0.1, 0.0, 0.0)), IDENTITY, omega)
    assert not _applies("chaplygin", _body((2.0, 2.0, 1.0), (0.1, 0.0, 0.0)), IDENTITY, omega)
    # F = (p1² + p2²) p3 + λ² p1 H3, λ² = m g |c| / A3; tilted state with K_H = 0
    quat = quat_exp(np.array([0.4, 0.0, 0.0]))
    h = quat_to_matrix(quat).T @ [0.0, 0.0, -1.0]
    omega = np.array([0.3, 0.7, 0.0])
    omega[2] = -(4.0 * omega[1] * h[1]) / h[2]  # σω·H = 4 p2 H2 + p3 H3 = 0
    assert _applies("chaplygin", body, quat, omega)
    lambda2 = 0.1 * G / 1.0
    expected = (0.09 + 0.49) * omega[2] + lambda2 * 0.3 * h[2]
    assert _value("chaplygin", body, quat, omega) == pytest.approx(expected, rel=1e-14)
    rotated = _body((4.0, 4.0, 1.0), (0.1, 0.0, 0.0), rotation=ROTATION)
    q_rot = quat_mul(quat, matrix_to_quat(ROTATION.T))
    assert _applies("chaplygin", rotated, q_rot, ROTATION @ omega)
    assert _value("chaplygin", rotated, q_rot, ROTATION @ omega) == pytest.approx(expected, rel=1e-13)


def test_chaplygin_derivative_vanishes_with_zero_vertical_momentum():
    body = _body((4.0, 4.0, 1.0), (0.1, 0.0, 0.0), rotation=ROTATION)
    quat = quat_mul(quat_exp(np.array([0.4, 0.0, 0.0])), matrix_to_quat(ROTATION.T))
    h = downward_vertical(body, quat)
    omega = np.cross(ROTATION @ [0.3, 0.7, 0.0], h)
    omega -= (body.inertia @ omega) @ h / (body.inertia @ h @ h) * h  # make σω·H = 0 exactly (to rounding)
    assert _applies("chaplygin", body, quat, omega)
    dq, dw = rhs(body, quat, omega)
    step = 1e-6
    rate = (_value("chaplygin", body, quat + step * dq, omega + step * dw)
            - _value("chaplygin", body, quat - step * dq, omega - step * dw)) / (2 * step)
    assert abs(rate) / INTEGRALS["chaplygin"].scale(body, quat, omega) < 1e-8


def test_hess_predicate_and_value():
    # A = (6, 5, 3), k ∝ (1/2, 0, 1): (A2 - A3) A1 k1² = (A1 - A2) A3 k3²  (12·1/4 = 3·1), FORMULARY G7
    com = np.array([0.5, 0.0, 1.0]) / G
    body = _body((6.0, 5.0, 3.0), com)
    k = com / np.linalg.norm(com)
    momentum = 0.4 * np.array([k[2], 0.0, -k[0]]) + [0.0, 3.5, 0.0]  # σω ⊥ k
    omega = momentum / np.array([6.0, 5.0, 3.0])
    assert abs((np.diag([6.0, 5.0, 3.0]) @ omega) @ k) < 1e-16
    assert _applies("hess", body, IDENTITY, omega)
    assert not _applies("hess", body, IDENTITY, omega + [0.0, 0.0, 0.1])  # K·k != 0
    assert not _applies("hess", _body((6.0, 5.0, 3.0), [0.5, 0.0, 0.9]), IDENTITY, omega)  # not a circular section
    assert not _applies("hess", _body((6.0, 5.0, 3.0), com, gravity=0.0), IDENTITY, omega)
    rotated = _body((6.0, 5.0, 3.0), com, rotation=ROTATION)
    assert _applies("hess", rotated, IDENTITY, ROTATION @ omega)
    assert _value("hess", body, IDENTITY, omega + [0.0, 0.0, 0.1]) == pytest.approx(0.3 * k[2], rel=1e-14)
    # the Hess manifold is invariant: d(K·k)/dt = 0 where K·k = 0
    for candidate, state in ((body, omega), (rotated, ROTATION @ omega)):
        quat = quat_exp(np.array([0.3, -0.5, 0.2]))
        assert abs(omega_dot(candidate, quat, state) @ candidate.inertia @ (candidate.com / np.linalg.norm(com))) \
            < 1e-14
    # control: the same state on a body whose k is not normal to a circular section leaves the plane
    other_k = np.array([0.5, 0.0, 0.9]) / np.linalg.norm([0.5, 0.0, 0.9])
    other = _body((6.0, 5.0, 3.0), other_k / G)
    other_omega = (0.4 * np.array([other_k[2], 0.0, -other_k[0]]) + [0.0, 3.5, 0.0]) / np.array([6.0, 5.0, 3.0])
    assert abs(omega_dot(other, quat, other_omega) @ other.inertia @ other_k) > 1e-3


def test_value_normalises_raw_quaternions():
    body = _body((2.0, 2.0, 1.0), (0.1, 0.0, 0.0))
    quat = matrix_to_quat(zxz_to_matrix(0.2, 1.0, 0.4))
    omega = np.array([0.5, -0.3, 1.5])
    for name in ("energy", "momentum", "kovalevskaya"):
        assert _value(name, body, 1.01 * quat, omega) == pytest.approx(_value(name, body, quat, omega), rel=1e-14)
