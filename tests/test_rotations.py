"""Attitude charts: round trips, exact values, and the accuracy of the attitude angle at tiny angles."""
import numpy as np
import pytest

from stereodyn.reference.rotations import (attitude_angle, gibbs_compose, gibbs_to_matrix, gibbs_to_quat, matrix_to_gibbs,
                                 matrix_to_quat, matrix_to_zxz, quat_conj, quat_exp, quat_log, quat_mul,
                                 quat_normalize, quat_to_gibbs, quat_to_matrix, skew, zxz_to_matrix)

N = 1000
# Round trips through the charts lose a few ulps per operation; 1e-14 is ~50 ulp.
ROUND_TRIP = 1e-14


@pytest.fixture
def quats():
    rng = np.random.default_rng(20240601)
    return quat_normalize(rng.normal(size=(N, 4)))


def _axis_angle_matrix(axis, angle):
    axis = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    k = skew(axis)
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def test_quat_to_matrix_is_a_rotation_and_a_homomorphism(quats):
    m = quat_to_matrix(quats)
    assert np.max(np.abs(m @ np.swapaxes(m, -1, -2) - np.eye(3))) < ROUND_TRIP
    assert np.max(np.abs(np.linalg.det(m) - 1)) < ROUND_TRIP
    other = np.roll(quats, 1, axis=0)
    assert np.max(np.abs(quat_to_matrix(quat_mul(quats, other)) - m @ quat_to_matrix(other))) < ROUND_TRIP
    assert np.max(np.abs(quat_to_matrix(quat_conj(quats)) - np.swapaxes(m, -1, -2))) < ROUND_TRIP
    # normalises first: a scaled quaternion is the same rotation
    assert np.max(np.abs(quat_to_matrix(3.7 * quats) - m)) < ROUND_TRIP


def test_quat_to_matrix_known_rotation():
    # 90° about z: body x -> world y (v_world = R v_body)
    q = np.array([np.cos(np.pi / 4), 0, 0, np.sin(np.pi / 4)])
    assert np.allclose(quat_to_matrix(q) @ [1, 0, 0], [0, 1, 0], atol=1e-15, rtol=0)
    assert np.allclose(quat_to_matrix(q), _axis_angle_matrix([0, 0, 1], np.pi / 2), atol=1e-15, rtol=0)


def test_matrix_quat_round_trip(quats):
    back = matrix_to_quat(quat_to_matrix(quats))
    assert np.all(back[:, 0] >= 0)
    signed = np.where(quats[:, :1] < 0, -quats, quats)
    assert np.max(np.abs(back - signed)) < ROUND_TRIP
    # near angle π (w ≈ 0) the largest-pivot choice keeps full accuracy
    q_pi = quat_normalize(np.array([1e-9, 0.3, -0.5, 0.8]))
    assert np.max(np.abs(matrix_to_quat(quat_to_matrix(q_pi)) - q_pi)) < ROUND_TRIP


def test_zxz_round_trip(quats):
    m = quat_to_matrix(quats)
    phi, theta, psi = matrix_to_zxz(m)
    assert np.all((theta >= 0) & (theta <= np.pi))
    assert np.max(np.abs(zxz_to_matrix(phi, theta, psi) - m)) < ROUND_TRIP
    rng = np.random.default_rng(7)
    angles = (rng.uniform(-np.pi, np.pi, N), rng.uniform(0.01, np.pi - 0.01, N), rng.uniform(-np.pi, np.pi, N))
    back = matrix_to_zxz(zxz_to_matrix(*angles))
    for given, recovered in zip(angles, back):
        assert np.max(np.abs(np.angle(np.exp(1j * (given - recovered))))) < 1e-12  # angles mod 2π
    # gimbal lock: θ = 0 or π still reproduces the matrix
    for theta0 in (0.0, np.pi, 1e-12):
        m0 = zxz_to_matrix(0.4, theta0, -1.1)
        assert np.max(np.abs(zxz_to_matrix(*matrix_to_zxz(m0)) - m0)) < ROUND_TRIP


def test_zxz_matches_formulary_c1_columns():
    phi, theta, psi = 0.3, 0.8, -0.5
    m = zxz_to_matrix(phi, theta, psi)
    # C1: third column is e'_3 in the fixed basis
    assert np.allclose(m[:, 2], [np.sin(phi) * np.sin(theta), -np.cos(phi) * np.sin(theta), np.cos(theta)],
                       atol=1e-15, rtol=0)
    assert np.allclose(m, _axis_angle_matrix([0, 0, 1], phi) @ _axis_angle_matrix([1, 0, 0], theta)
                       @ _axis_angle_matrix([0, 0, 1], psi), atol=1e-15, rtol=0)


def test_gibbs_round_trips(quats):
    m = quat_to_matrix(quats)
    g = matrix_to_gibbs(m)
    assert np.max(np.abs(gibbs_to_matrix(g) - m)) < ROUND_TRIP
    assert np.max(np.abs(quat_to_matrix(gibbs_to_quat(g)) - m)) < ROUND_TRIP
    assert np.max(np.abs(quat_to_gibbs(quats) - g) / (1 + np.linalg.norm(g, axis=-1, keepdims=True))) < ROUND_TRIP
    g_back = matrix_to_gibbs(gibbs_to_matrix(g))
    # relative: |g| = tan(φ/2) is large near φ = π, and R only fixes g to relative rounding
    assert np.max(np.linalg.norm(g_back - g, axis=-1) / np.linalg.norm(g, axis=-1)) < 1e-13
    # De Finetti: g = u tan(φ/2) is the rotation by φ about u
    axis, angle = np.array([1.0, 2.0, -2.0]) / 3.0, 1.2
    assert np.allclose(gibbs_to_matrix(axis * np.tan(angle / 2)), _axis_angle_matrix(axis, angle), atol=1e-15,
                       rtol=0)
    # F1 inverse vee(R - Rᵀ)/(1 + tr R), written out
    r = m[:5]
    vee = np.stack([r[:, 2, 1] - r[:, 1, 2], r[:, 0, 2] - r[:, 2, 0], r[:, 1, 0] - r[:, 0, 1]], axis=-1)
    assert np.allclose(g[:5], vee / (1 + np.trace(r, axis1=1, axis2=2))[:, None], rtol=1e-12, atol=0)


def test_gibbs_compose_is_the_quaternion_product(quats):
    g, g_prime = quat_to_gibbs(quats[:500]), quat_to_gibbs(quats[500:])
    composed = gibbs_compose(g, g_prime)
    product = quat_to_gibbs(quat_mul(quats[500:], quats[:500]))  # q' ⊗ q: q applied first
    ok = np.abs(1 - np.sum(g * g_prime, axis=-1)) > 1e-3  # away from the composite angle π, where both blow up
    assert ok.sum() > 400
    rel = np.linalg.norm(composed - product, axis=-1) / np.linalg.norm(product, axis=-1)
    assert np.max(rel[ok]) < 1e-12
    assert np.max(np.abs(gibbs_to_matrix(composed[ok])
                         - gibbs_to_matrix(g_prime[ok]) @ gibbs_to_matrix(g[ok]))) < 1e-13


def test_quat_exp_log():
    rng = np.random.default_rng(3)
    rotvecs = rng.normal(size=(N, 3))
    rotvecs *= (rng.uniform(0, np.pi - 1e-6, N) / np.linalg.norm(rotvecs, axis=-1))[:, None]
    q = quat_exp(rotvecs)
    assert np.max(np.abs(np.linalg.norm(q, axis=-1) - 1)) < 1e-15
    assert np.max(np.abs(quat_log(q) - rotvecs)) < ROUND_TRIP
    for v in rotvecs[:20]:
        angle = np.linalg.norm(v)
        assert np.allclose(quat_to_matrix(quat_exp(v)), _axis_angle_matrix(v, angle), atol=1e-15, rtol=0)
    # the series branch near 0 is accurate to relative rounding
    tiny = np.array([3e-9, -4e-9, 1.2e-8])  # |v| = 1.3e-8
    q_tiny = quat_exp(tiny)
    assert np.allclose(q_tiny[1:], 0.5 * tiny, rtol=1e-15, atol=0)
    assert np.allclose(quat_log(q_tiny), tiny, rtol=1e-15, atol=0)
    for small in (5e-5, 2e-4):  # both sides of the series switch
        v = small * np.array([0.6, 0.0, 0.8])
        assert np.allclose(quat_exp(v)[1:], np.sin(small / 2) / small * v, rtol=2e-16, atol=0)
        assert np.allclose(quat_log(quat_exp(v)), v, rtol=1e-14, atol=0)
    assert np.array_equal(quat_exp(np.zeros(3)), [1.0, 0.0, 0.0, 0.0])
    assert np.array_equal(quat_log(np.array([1.0, 0, 0, 0])), [0.0, 0.0, 0.0])
    # -q is the same rotation: log returns the short one
    assert np.allclose(quat_log(-quat_exp([0.1, 0.2, 0.3])), [0.1, 0.2, 0.3], rtol=1e-14, atol=0)


@pytest.mark.parametrize("angle", [1e-14, 1e-12, 1e-10, 1e-6, 1e-3, 0.5, 2.0, np.pi - 1e-3])
def test_attitude_angle_exact(angle, quats):
    base = quat_to_matrix(quats[:50])
    rotated = base @ _axis_angle_matrix([0.2, -0.7, 0.4], angle)
    measured = attitude_angle(base, rotated)
    if angle < 1e-8:
        # The difference of two O(1) matrices carries absolute rounding ~1e-16, so tiny angles between rotated
        # frames are resolved to ~2e-16 absolute (1e-6 relative at 1e-10).
        tolerance = max(1e-6 * angle, 4e-16)
    else:
        # asin amplifies rounding by 1/cos(θ/2) near θ = π (2000x at π - 1e-3): the harness measures small errors.
        tolerance = 1e-14 / np.cos(angle / 2)
    assert np.max(np.abs(measured - angle)) < tolerance
    assert np.array_equal(measured, attitude_angle(rotated, base))  # symmetric


def test_attitude_angle_tiny_angle_from_identity():
    # from the identity no rounding hides the angle: 1e-10 rad is measured to relative rounding
    rotated = quat_to_matrix(quat_exp(np.array([0.0, 0.0, 1e-10])))
    assert abs(attitude_angle(np.eye(3), rotated) - 1e-10) < 1e-10 * 1e-6
    # arccos of the trace would have said 0
    assert np.arccos(min(1.0, (np.trace(rotated) - 1) / 2)) == 0.0
    assert attitude_angle(np.eye(3), np.eye(3)) == 0.0
    # half turn and the clamp of asin at 1
    assert abs(attitude_angle(np.eye(3), np.diag([1.0, -1.0, -1.0])) - np.pi) < 1e-15


def test_skew():
    a, b = np.array([0.3, -1.2, 2.0]), np.array([1.5, 0.4, -0.7])
    assert np.allclose(skew(a) @ b, np.cross(a, b), atol=1e-15, rtol=0)
    assert skew(np.ones((5, 2, 3))).shape == (5, 2, 3, 3)
