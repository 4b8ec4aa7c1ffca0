"""The heavy body's particular motions (FORMULARY G5, G9, G10, G11) against the truth: Lagrange's regular precession
and the sleeping top, Staude's rotations, Grioli's precession, Hess–Grioli precessions and Mlodzejowski rotations."""
import math

import numpy as np
import pytest

from stereodyn.reference.body import RigidBody
from stereodyn.reference.exact import (ORACLES, grioli_body, grioli_precession, grioli_rate, grioli_vertical, hess_frame,
                             hess_grioli, hess_grioli_body, lagrange_precession, lagrange_rates, mlodzejowski,
                             mlodzejowski_axis, sleeping_top_threshold, staude_direction, staude_rate_squared,
                             staude_rotation)
from stereodyn.reference.euler_poisson import downward_vertical
from stereodyn.reference.rotations import attitude_angle, quat_to_matrix, zxz_to_matrix
from stereodyn.reference.truth import truth

G = 9.81
# The bound for an oracle against the truth (within the horizon of an unstable motion).
ORACLE_BOUND = 1e-11
TILTED = (0.6, 0.0, -0.8)
ROTATED = zxz_to_matrix(0.5, -0.8, 1.9)
IDENTITY = np.array([1.0, 0.0, 0.0, 0.0])


def _rotated(body, direction=TILTED):
    inertia = ROTATED @ body.inertia @ ROTATED.T
    return RigidBody(0.5 * (inertia + inertia.T), body.mass, ROTATED @ body.com, body.gravity, np.array(direction))


def _oracle_errors(body, quat0, omega0, oracle, span, samples=201, precision="double"):
    """(max attitude angle, max |ω - ω_truth| / max |ω_truth|) between the oracle and the truth over [0, span]."""
    assert ORACLES[oracle].check(body, quat0, omega0) is None
    times = np.linspace(0.0, span, samples)
    quat, omega = ORACLES[oracle].solve(body, quat0, omega0, times)
    reference = truth(body, quat0, omega0, times, precision=precision)
    attitude = float(np.max(attitude_angle(quat_to_matrix(quat), quat_to_matrix(reference.quat))))
    scale = max(float(np.max(np.abs(reference.omega))), 1e-300)
    return attitude, float(np.max(np.abs(omega - reference.omega))) / scale


# --- Lagrange (G5) ------------------------------------------------------------------------------------------------

TOP = RigidBody(np.diag([1.0, 1.0, 0.4]), 1.0, np.array([0.0, 0.0, 0.2]), G)


@pytest.mark.parametrize("tilt, spin", [(0.6, 15.0), (2.0, 15.0), (1.2, -9.0), (1.5, 10.0)])
def test_lagrange_rates_are_the_roots_of_g5(tilt, spin):
    alpha, a1, a3 = 0.2 * G, 1.0, 0.4
    slow, fast = lagrange_rates(TOP, tilt, spin)
    for rate in (slow, fast):
        if math.isfinite(rate):
            assert rate * (a3 * spin - a1 * rate * math.cos(tilt)) == pytest.approx(alpha, rel=1e-13)
    if math.cos(tilt) != 0.0:
        assert slow * fast == pytest.approx(alpha / (a1 * math.cos(tilt)), rel=1e-13)  # Vieta
        assert abs(slow) < abs(fast)


@pytest.mark.parametrize("tilt, root", [(0.6, "slow"), (0.6, "fast"), (2.0, "slow"), (2.0, "fast")])
@pytest.mark.parametrize("rotated", [False, True])
def test_lagrange_precession_against_truth(tilt, root, rotated):
    """Neutrally stable: t = 100 in double. Measured <= 3.4e-13 rad (attitude), <= 3e-13 relative (ω)."""
    body = _rotated(TOP) if rotated else TOP
    setup = lagrange_precession(body, tilt, 15.0, root, heading=0.3)
    attitude, omega_err = _oracle_errors(body, setup.quat0, setup.omega0, "lagrange_precession", 100.0)
    assert attitude <= ORACLE_BOUND and omega_err <= ORACLE_BOUND
    # no nutation: the figure axis keeps its angle to the vertical
    times = np.linspace(0.0, 100.0, 201)
    run = truth(body, setup.quat0, setup.omega0, times)
    cos_tilt = downward_vertical(body, run.quat) @ (body.com / np.linalg.norm(body.com))
    assert np.ptp(cos_tilt) <= 1e-12


def test_sleeping_top_threshold():
    """A3² r² > 4 A1 α: a 1e-7 rad/s kick stays at ~5e-7 rad of tilt at 1.01 r_c, and grows past 0.1 rad at
    0.99 r_c (growth rate 0.091/s, G5) over t = 100."""
    threshold = sleeping_top_threshold(TOP)
    assert threshold == pytest.approx(2.0 * math.sqrt(1.0 * 0.2 * G) / 0.4, rel=1e-15)
    assert math.isnan(lagrange_rates(TOP, 0.0, 0.99 * threshold)[0])
    assert math.isfinite(lagrange_rates(TOP, 0.0, 1.01 * threshold)[0])
    times = np.linspace(0.0, 100.0, 1001)
    tilts = {}
    for factor in (1.01, 0.99):
        setup = lagrange_precession(TOP, 0.0, factor * threshold)
        assert ORACLES["lagrange_precession"].check(TOP, setup.quat0, setup.omega0) is None
        run = truth(TOP, setup.quat0, setup.omega0 + np.array([1e-7, 0.0, 0.0]), times)
        tilts[factor] = float(np.max(np.arccos(np.clip(quat_to_matrix(run.quat)[:, 2, 2], -1.0, 1.0))))
    assert tilts[1.01] < 1e-6 and tilts[0.99] > 0.1


def test_sleeping_top_oracle_within_its_horizon():
    """Just below the threshold the sleeping top is unstable; its exact motion (a uniform spin about the vertical)
    holds in the truth from the exact state."""
    setup = lagrange_precession(TOP, 0.0, 0.99 * sleeping_top_threshold(TOP))
    attitude, omega_err = _oracle_errors(TOP, setup.quat0, setup.omega0, "lagrange_precession", 50.0)
    assert attitude <= ORACLE_BOUND and omega_err <= ORACLE_BOUND


# --- Staude (G9) --------------------------------------------------------------------------------------------------

HEAVY = RigidBody(np.array([[2.0, 0.1, -0.05], [0.1, 1.6, 0.08], [-0.05, 0.08, 1.1]]), 1.0,
                  np.array([0.1, -0.05, 0.25]), G)


@pytest.mark.parametrize("parameter", [-5.0, 0.5, 1.3, 1.8, 3.0, 10.0])
def test_staude_rotations_against_truth(parameter):
    """Six generators of the cone (Ω² is odd in γ, so the branch with Ω² > 0 is taken). Two of them (-5, 0.5) are
    unstable: round-off grows like e^{1.3 t}, to 1.1e-12 by t = 8 (measured), the horizon here."""
    gamma = -staude_direction(HEAVY, parameter)
    sigma_gamma = HEAVY.inertia @ gamma
    assert abs(np.linalg.det(np.column_stack([gamma, sigma_gamma, HEAVY.com]))) < 1e-15
    rate2 = staude_rate_squared(HEAVY, gamma)
    assert rate2 > 0 and staude_rate_squared(HEAVY, -gamma) == pytest.approx(-rate2, rel=1e-15)
    # Ω² γ × σγ = w × γ: the permanent rotation balances the weight
    assert np.allclose(rate2 * np.cross(gamma, sigma_gamma), np.cross(HEAVY.weight_moment, gamma), atol=1e-14)
    setup = staude_rotation(HEAVY, gamma, -1.0, heading=0.4)
    attitude, omega_err = _oracle_errors(HEAVY, setup.quat0, setup.omega0, "staude_rotation", 8.0)
    assert attitude <= ORACLE_BOUND and omega_err <= ORACLE_BOUND


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_staude_rotation_exact_state_in_quad(sign):
    """Every number exact in binary: σ13 = 1/4, w = (1/4, 0, 1/2), γ = H0 = (0, 0, -1) (R0 = I), Ω² = w1/σ13 = 1.
    The real128 truth then stays on the rotation whatever its stability."""
    body = RigidBody(np.array([[2.0, 0.0, 0.25], [0.0, 1.5, 0.0], [0.25, 0.0, 1.0]]), 1.0, np.array([0.25, 0.0, 0.5]),
                     1.0)
    assert staude_rate_squared(body, np.array([0.0, 0.0, -1.0])) == 1.0
    omega0 = np.array([0.0, 0.0, -sign])
    attitude, omega_err = _oracle_errors(body, IDENTITY, omega0, "staude_rotation", 40.0, precision="quad")
    assert attitude <= ORACLE_BOUND and omega_err <= ORACLE_BOUND


# --- Grioli (G10) -------------------------------------------------------------------------------------------------

# k = (3, 0, 4)/5 exactly: A1 - A2 = 9/16, A2 - A3 = 1; com = (3/8, 0, 1/2)
GRIOLI = grioli_body((2.5625, 2.0, 1.0), 1.0, 0.625, G)


@pytest.mark.parametrize("phase", [0.0, 1.0, 2.5])
@pytest.mark.parametrize("rotated", [False, True])
def test_grioli_precession_in_the_truth(phase, rotated):
    """The issue's acceptance over t = 100: |ω|² = 2 α cos χ / A_f and the precession axis c = ω/n - k fixed in
    space, both to 1e-12 (measured <= 6e-15 and <= 3e-13); and the oracle against the truth."""
    body = _rotated(GRIOLI) if rotated else GRIOLI
    assert np.allclose(np.linalg.norm(GRIOLI.com) * np.array([0.6, 0.0, 0.8]), GRIOLI.com, rtol=0, atol=1e-16)
    setup = grioli_precession(body, phase, heading=0.7)
    times = np.linspace(0.0, 100.0, 1001)
    run = truth(body, setup.quat0, setup.omega0, times)
    alpha = np.linalg.norm(body.weight_moment)
    k = body.com / np.linalg.norm(body.com)
    a_f = 2.5625 - 2.0 + 1.0
    cos_chi = a_f / np.linalg.norm(body.inertia @ k)
    speed2 = np.sum(run.omega ** 2, axis=1)
    assert np.max(np.abs(speed2 / (2.0 * alpha * cos_chi / a_f) - 1.0)) <= 1e-12
    rate = grioli_rate(body)
    axis_world = np.einsum("nij,nj->ni", quat_to_matrix(run.quat), run.omega / rate - k)
    assert np.max(np.linalg.norm(axis_world - axis_world[0], axis=1)) <= 1e-12
    # H·c = -cos χ
    c0 = setup.omega0 / rate - k
    assert grioli_vertical(body, c0) @ c0 == pytest.approx(-cos_chi, abs=1e-15)
    attitude, omega_err = _oracle_errors(body, setup.quat0, setup.omega0, "grioli_precession", 100.0)
    assert attitude <= ORACLE_BOUND and omega_err <= ORACLE_BOUND


def test_grioli_precession_from_a_given_axis():
    k = GRIOLI.com / np.linalg.norm(GRIOLI.com)
    c = np.array([-0.8, 0.0, 0.6])  # ⊥ k = (0.6, 0, 0.8)
    setup = grioli_precession(GRIOLI, axis=c)
    assert setup.omega0 == pytest.approx(grioli_rate(GRIOLI) * (c + k), rel=1e-15)
    assert setup.omega0 == pytest.approx(grioli_precession(GRIOLI, phase=math.pi / 2).omega0, abs=1e-15)
    with pytest.raises(ValueError, match="perpendicular"):
        grioli_precession(GRIOLI, axis=np.array([1.0, 0.0, 0.0]))


def test_grioli_needs_the_circular_section():
    off = RigidBody(np.diag([2.5625, 2.0, 1.0]), 1.0, np.array([0.4, 0.0, 0.5]), G)
    assert "circular section" in ORACLES["grioli_precession"].check(off, IDENTITY, np.array([0.1, 0.2, 0.3]))
    with pytest.raises(ValueError, match="circular section"):
        grioli_precession(off)


# --- Hess–Grioli and Mlodzejowski (G11) ---------------------------------------------------------------------------

# FORMULARY G11's exactly representable body: A1 = 5/4, A2 = 3/2, A3 = 1, A1' = 1/2 (Hess: (A1 - A2) A3 + A1'² = 0),
# α = 3/4, com on i3.
HESS = hess_grioli_body(1.25, 1.0, 0.5, 1.0, 1.0, 0.75)


def test_hess_body_and_frame():
    assert np.array_equal(HESS.inertia, [[1.25, 0.0, 0.0], [0.0, 1.5, -0.5], [0.0, -0.5, 1.0]])
    frame, (a1, a2, a3, a1p) = hess_frame(HESS)
    assert np.array_equal(frame, np.eye(3)) and (a1, a2, a3, a1p) == (1.25, 1.5, 1.0, 0.5)
    assert np.array_equal(mlodzejowski_axis(HESS), [1.0, 0.0, 0.0])
    not_hess = RigidBody(np.diag([1.25, 1.5, 1.0]), 1.0, np.array([0.0, 0.0, 1.0]), 0.75)
    assert "Hess" in hess_frame(not_hess) or "plane" in hess_frame(not_hess)


# R0 = I or a half turn about x (quaternions exact), d = (0, 0, -1) or (1, 0, 0): H0 is (0, 0, ∓1) or (1, 0, 0),
# and ω0 = ḃ1 (0, 1, A1'/A3) (b2 = 0) is exact, so K·k = K·H = 0 hold exactly in real128.
HESS_STATES = [((0.0, 0.0, -1.0), (1.0, 0.0, 0.0, 0.0), 0.5), ((1.0, 0.0, 0.0), (1.0, 0.0, 0.0, 0.0), 1.25),
               ((0.0, 0.0, -1.0), (0.0, 1.0, 0.0, 0.0), -2.0)]


@pytest.mark.parametrize("direction, quat0, b1_dot", HESS_STATES)
def test_hess_grioli_exact_state_in_quad(direction, quat0, b1_dot):
    """Unstable (FORMULARY §6), so exact data and the real128 truth; t = 40 as in G11's check."""
    body = RigidBody(HESS.inertia, 1.0, HESS.com, 0.75, np.array(direction))
    omega0 = b1_dot * np.array([0.0, 1.0, 0.5])
    attitude, omega_err = _oracle_errors(body, np.array(quat0), omega0, "hess_grioli", 40.0, precision="quad")
    assert attitude <= ORACLE_BOUND and omega_err <= ORACLE_BOUND


@pytest.mark.parametrize("b1, b1_dot, b2", [(0.3, 0.4, 0.2), (1.0, 2.0, -0.7), (0.0, 0.5, 2.5), (2.0, 0.0, 0.3)])
@pytest.mark.parametrize("rotated", [False, True])
def test_hess_grioli_against_truth_within_horizon(b1, b1_dot, b2, rotated):
    """Constructor states (rounded to float64) in the double truth up to t = 10 (G11: 4.3e-14 up to t = 12)."""
    body = _rotated(HESS) if rotated else HESS
    setup = hess_grioli(body, b1, b1_dot, b2, 0.4, heading=0.3)
    attitude, omega_err = _oracle_errors(body, setup.quat0, setup.omega0, "hess_grioli", 10.0)
    assert attitude <= ORACLE_BOUND and omega_err <= ORACLE_BOUND


def test_hess_grioli_momentum_is_fixed_and_horizontal():
    """K = -A1 ḃ1 (sin b2, -cos b2, 0) keeps its direction in space and stays horizontal (G11 (28))."""
    setup = hess_grioli(HESS, 1.0, 2.0, -0.7, 0.4)
    times = np.linspace(0.0, 10.0, 101)
    quat, omega = setup.motion(times)
    momentum_world = np.einsum("nij,nj->ni", quat_to_matrix(quat), omega @ HESS.inertia)
    direction = momentum_world / np.linalg.norm(momentum_world, axis=1)[:, None]
    assert np.max(np.linalg.norm(np.cross(direction, direction[0]), axis=1)) <= 1e-13
    assert np.max(np.abs(momentum_world @ HESS.gravity_direction)) <= 1e-13


@pytest.mark.parametrize("direction, rate", [((0.0, 0.0, -1.0), 1.5), ((0.0, 1.0, 0.0), -0.25),
                                             ((0.0, 0.0, 1.0), 0.0)])
def test_mlodzejowski_exact_state_in_quad(direction, rate):
    """A swing about the middle axis i1 (unstable, so exact data and real128): over the top, a libration, and rest
    at G above O (an equilibrium)."""
    body = RigidBody(HESS.inertia, 1.0, HESS.com, 0.75, np.array(direction))
    attitude, omega_err = _oracle_errors(body, IDENTITY, np.array([rate, 0.0, 0.0]), "mlodzejowski", 40.0,
                                         precision="quad")
    assert attitude <= ORACLE_BOUND and omega_err <= ORACLE_BOUND


@pytest.mark.parametrize("angle, rate", [(0.3, 0.5), (2.5, -1.0), (0.0, 3.0), (3.0, 0.0)])
def test_mlodzejowski_against_truth_within_horizon(angle, rate):
    """Rotated axes leave ~1e-16 off the middle axis, which grows like e^{1.4 t} in the fastest swing (rate 3):
    1.2e-12 by t = 6 (measured), the horizon here."""
    setup = mlodzejowski(_rotated(HESS), angle, rate, heading=1.0)
    attitude, omega_err = _oracle_errors(setup.body, setup.quat0, setup.omega0, "mlodzejowski", 6.0)
    assert attitude <= ORACLE_BOUND and omega_err <= ORACLE_BOUND


def test_mlodzejowski_on_a_body_that_is_not_hess():
    """Any principal axis perpendicular to OG carries the compound-pendulum swing (here the largest axis of a body
    with its com in the plane of the other two), stable or not."""
    body = RigidBody(np.diag([2.0, 1.5, 1.0]), 1.0, np.array([0.0, 0.3, 0.4]), G)
    setup = mlodzejowski(body, 1.0, 2.0)
    assert np.array_equal(np.abs(setup.omega0) > 0, [True, False, False])
    attitude, omega_err = _oracle_errors(body, setup.quat0, setup.omega0, "mlodzejowski", 20.0)
    assert attitude <= ORACLE_BOUND and omega_err <= ORACLE_BOUND
