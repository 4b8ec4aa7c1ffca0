"""The exact torque-free motion against the real128 truth: both families, symmetric bodies, the separatrix, periods,
Montgomery's phase, and the stationary rotations' exponents (FORMULARY T7–T9)."""
import math

import numpy as np
import pytest
from scipy.special import ellipk

from stereodyn.reference.body import RigidBody
from stereodyn.reference.exact import (free_motion, lyapunov_exponent, montgomery_phase, oscillation_frequencies, period,
                             precession_per_period, separatrix_distance, separatrix_omega, solid_angle,
                             unstable_direction)
from stereodyn.reference.closed_form import principal_frame_precise
from stereodyn.reference.rotations import attitude_angle, matrix_to_quat, quat_to_matrix, zxz_to_matrix
from stereodyn.reference.truth import truth

# The bound for the exact attitude against the real128 truth over 10 periods. Measured: <= 5e-13 (the
# oracle's float64 rates over ~1000 rad of rotation).
ATTITUDE_BOUND = 1e-12
# Bodies and states are drawn outside this distance of the separatrix (the condition).
SEPARATRIX_MARGIN = 1e-6


def _random_body(rng, rotated):
    while True:
        moments = np.sort(rng.uniform(0.5, 3.0, 3))[::-1]
        # a physical body (triangle inequality) with clearly distinct moments (symmetric bodies are tested apart)
        if moments[0] < moments[1] + moments[2] and min(moments[0] - moments[1], moments[1] - moments[2]) > 0.02:
            break
    inertia = np.diag(moments)
    if rotated:
        frame = zxz_to_matrix(*rng.uniform(-math.pi, math.pi, 3))
        inertia = frame @ inertia @ frame.T
        inertia = 0.5 * (inertia + inertia.T)
    return RigidBody(inertia, 1.0, np.zeros(3))


def _random_states(count, seed):
    """count (body, quat0, omega0), half of the bodies with a non-diagonal inertia, |δ| > SEPARATRIX_MARGIN."""
    rng = np.random.default_rng(seed)
    states = []
    while len(states) < count:
        body = _random_body(rng, rotated=len(states) % 2 == 1)
        omega0 = rng.normal(size=3) * rng.uniform(0.3, 3.0)
        if abs(separatrix_distance(body, omega0)) <= SEPARATRIX_MARGIN:
            continue
        quat0 = matrix_to_quat(zxz_to_matrix(*rng.uniform(-math.pi, math.pi, 3)))
        states.append((body, quat0, omega0))
    return states


def _error_over_periods(body, quat0, omega0, periods=10, samples=201):
    motion = free_motion(body, quat0, omega0)
    # A rotated spherical tensor is triaxial by ~1e-16: its period is ~6e16 s (λ ~ the gaps), beyond any truth run,
    # so very long (or infinite) periods are checked over 100 s (measured there: 1.7e-14 rad).
    span = periods * motion.period if motion.period <= 1e4 else 100.0
    times = np.linspace(0.0, span, samples)
    reference = truth(body, quat0, omega0, times, precision="quad")
    quat, omega = motion.evaluate(times)
    attitude = float(np.max(attitude_angle(quat_to_matrix(quat), quat_to_matrix(reference.quat))))
    omega_err = float(np.max(np.abs(omega - reference.omega)) / np.max(np.abs(reference.omega)))
    return motion, attitude, omega_err


def _check_random_bodies(count, seed):
    kinds, worst = set(), 0.0
    for body, quat0, omega0 in _random_states(count, seed):
        motion, attitude, omega_err = _error_over_periods(body, quat0, omega0)
        kinds.add(motion.kind)
        worst = max(worst, attitude)
        assert attitude <= ATTITUDE_BOUND, (motion.kind, separatrix_distance(body, omega0), attitude)
        assert omega_err <= ATTITUDE_BOUND
    assert kinds == {"major", "minor"}
    return worst


def test_random_triaxial_bodies_against_quad_truth():
    """The fast version of the acceptance sweep: 10 bodies (5 with non-diagonal inertia), both families."""
    _check_random_bodies(10, seed=4)


@pytest.mark.slow
def test_200_random_triaxial_bodies_against_quad_truth():
    _check_random_bodies(200, seed=2024)


@pytest.mark.parametrize("distance", [1e-3, -1e-3, 1e-6, -1e-6])
@pytest.mark.parametrize("rotated", [False, True])
def test_near_the_separatrix(distance, rotated):
    """ω0 placed at separatrix distance δ exactly (to rounding): the invariants are formed in 40-digit decimals,
    without which a rotated body at δ = 7e-4 missed by 3e-11."""
    moments = np.array([2.7, 1.9, 1.1])
    frame = zxz_to_matrix(0.4, 1.1, -2.0) if rotated else np.eye(3)
    body = RigidBody(0.5 * (frame @ np.diag(moments) @ frame.T + (frame @ np.diag(moments) @ frame.T).T), 1.0,
                     np.zeros(3))
    w = np.array([0.9, -0.6, 0.0])
    # δ (I1 - I3) 2E = I1 w1² (I1 - I2) - I3 w3² (I2 - I3): solve for w3 by fixed-point iteration
    i1, i2, i3 = moments
    for _ in range(60):
        two_energy = float(np.sum(moments * w * w))
        w[2] = math.sqrt((i1 * w[0] ** 2 * (i1 - i2) - distance * two_energy * (i1 - i3)) / (i3 * (i2 - i3)))
    omega0 = frame @ w
    assert separatrix_distance(body, omega0) == pytest.approx(distance, rel=1e-6)
    quat0 = matrix_to_quat(zxz_to_matrix(0.3, 1.2, -0.4))
    motion, attitude, omega_err = _error_over_periods(body, quat0, omega0)
    assert motion.kind == ("major" if distance > 0 else "minor")
    assert attitude <= ATTITUDE_BOUND and omega_err <= ATTITUDE_BOUND


@pytest.mark.parametrize("moments", [(2.0, 2.0, 1.0), (1.0, 1.0, 2.0), (3.0, 1.5, 1.5), (1.0, 1.0, 1.0)])
@pytest.mark.parametrize("rotated", [False, True])
def test_symmetric_bodies_against_quad_truth(moments, rotated):
    """Exactly symmetric inertia: the trigonometric closed form. Rotated, the float64 tensor is symmetric only to
    ~1e-16, a genuinely triaxial body that the elliptic solution handles (m, ν ~ 1e-16)."""
    frame = zxz_to_matrix(-0.7, 0.5, 2.2) if rotated else np.eye(3)
    inertia = frame @ np.diag(moments) @ frame.T
    body = RigidBody(0.5 * (inertia + inertia.T), 1.0, np.zeros(3))
    quat0 = matrix_to_quat(zxz_to_matrix(0.3, 1.2, -0.4))
    motion, attitude, omega_err = _error_over_periods(body, quat0, np.array([0.3, -0.5, 1.1]))
    assert rotated or motion.kind == "symmetric"
    # measured on an AMD EPYC (AVX-512): <= 5.2e-14 (closed form), <= 3.2e-13 (rotated: (3, 1.5, 1.5) spins slowly
    # in its principal frame, period 194 s, so 10 periods are ~2300 rad of rotation at ~1e-16 rad each)
    assert attitude <= ATTITUDE_BOUND and omega_err <= ATTITUDE_BOUND


@pytest.mark.parametrize("moments", [(2.0, 2.0, 1.0), (1.0, 1.0, 2.0), (3.0, 1.5, 1.5)])
def test_rotated_symmetric_tensors_stay_accurate(moments):
    """A rotated symmetric tensor is triaxial by ~1 ulp, and its refined moments can come out of the Jacobi sweeps
    ascending (I2 < I3 by 4e-16 for (3, 1.5, 1.5)). Unsorted, that body took the symmetric form with the mean
    moment, which ignores the gap: 2.1e-12 rad over 10 periods, because a slow spin about the symmetry axis
    (ω_a = 0.03 rad/s here) feels the gap amplified by (ω_⊥ / ω_a)². Sorted, the elliptic solution (m, ν ~ 1e-16)
    is exact for the body as given."""
    frame = zxz_to_matrix(-0.7, 0.5, 2.2)
    inertia = frame @ np.diag(moments) @ frame.T
    body = RigidBody(0.5 * (inertia + inertia.T), 1.0, np.zeros(3))
    refined, axes, _ = principal_frame_precise(body.inertia, np.array([0.3, -0.5, 1.1]))
    assert refined[0] >= refined[1] >= refined[2]
    assert float(np.linalg.det(np.array([[float(x) for x in row] for row in axes]))) == pytest.approx(1.0, abs=1e-15)
    quat0 = matrix_to_quat(zxz_to_matrix(0.3, 1.2, -0.4))
    motion, attitude, omega_err = _error_over_periods(body, quat0, np.array([0.3, -0.5, 1.1]), periods=1)
    assert motion.kind in ("major", "minor")
    # measured on an AMD EPYC (AVX-512) over one period (5.9 .. 194 s): <= 3.2e-14 rad, omega <= 1.1e-15
    assert attitude <= 1e-13 and omega_err <= 1e-13


@pytest.mark.parametrize("omega0", [(1.0, 0.0, 0.0), (0.0, 0.0, -2.0), (0.0, 1.5, 0.0), (0.0, 0.0, 0.0)])
def test_rotations_about_principal_axes_are_uniform(omega0):
    body = RigidBody(np.diag([3.0, 2.0, 1.0]), 1.0, np.zeros(3))
    quat0 = matrix_to_quat(zxz_to_matrix(0.3, 1.2, -0.4))
    motion = free_motion(body, quat0, np.array(omega0))
    assert motion.kind == "uniform"
    times = np.linspace(0.0, 20.0, 101)
    quat, omega = motion.evaluate(times)
    reference = truth(body, quat0, np.array(omega0), times, precision="quad")
    assert np.max(attitude_angle(quat_to_matrix(quat), quat_to_matrix(reference.quat))) <= 1e-14
    assert np.array_equal(omega, reference.omega)


@pytest.mark.parametrize("phase, sign1, direction", [(0.0, 1.0, 1.0), (-3.0, 1.0, -1.0), (-2.0, -1.0, 1.0),
                                                     (-5.0, -1.0, -1.0)])
def test_separatrix_against_quad_truth(phase, sign1, direction):
    """The closed form through the flip. A double-precision state sits ~1e-17 off the separatrix and the truth leaves
    it like e^{λ t} (λ = 0.87 here), so the horizon is the flip itself: u = λ t + phase runs over [phase, phase + 7]."""
    body = RigidBody(np.diag([3.0, 2.0, 1.0]), 1.0, np.zeros(3))
    omega0 = separatrix_omega(body, 1.5, phase, sign1, direction)
    quat0 = matrix_to_quat(zxz_to_matrix(0.3, 1.2, -0.4))
    motion = free_motion(body, quat0, omega0)
    assert motion.kind == "separatrix"
    assert abs(separatrix_distance(body, omega0)) < 1e-15
    times = np.linspace(0.0, 8.0, 161)
    quat, omega = motion.evaluate(times)
    reference = truth(body, quat0, omega0, times, precision="quad")
    # measured <= 2.2e-14
    assert np.max(attitude_angle(quat_to_matrix(quat), quat_to_matrix(reference.quat))) <= 1e-12
    assert np.max(np.abs(omega - reference.omega)) <= 1e-12
    # and the motion does flip: ω2 changes sign or runs from near 0 to near ±W
    assert np.ptp(omega @ np.array([0.0, 1.0, 0.0])) > 1.0


def test_separatrix_closed_form_is_the_limit_of_the_families():
    """Just off the separatrix on either side the elliptic solution approaches the tanh/sech one (T8)."""
    body = RigidBody(np.diag([3.0, 2.0, 1.0]), 1.0, np.zeros(3))
    on = separatrix_omega(body, 1.5, -2.0)
    times = np.linspace(0.0, 4.0, 41)
    exact = free_motion(body, np.array([1.0, 0, 0, 0]), on).omega(times)
    for tilt in (1e-9, -1e-9):
        near = on * np.array([1.0 + tilt, 1.0, 1.0])
        assert free_motion(body, np.array([1.0, 0, 0, 0]), near).kind == ("major" if tilt > 0 else "minor")
        # the deviation grows like δ e^{λ t} ~ 1e-9 · 30
        assert np.max(np.abs(free_motion(body, np.array([1.0, 0, 0, 0]), near).omega(times) - exact)) < 1e-6


def _period_formula_t9(moments, omega):
    """FORMULARY T9, printed form, as an independent check of FreeMotion.period."""
    i1, i2, i3 = moments
    two_energy = float(np.sum(moments * omega * omega))
    momentum2 = float(np.sum((moments * omega) ** 2))
    if momentum2 > two_energy * i2:
        m = (i2 - i3) * (two_energy * i1 - momentum2) / ((i1 - i2) * (momentum2 - two_energy * i3))
        return 4.0 * ellipk(m) * math.sqrt(i1 * i2 * i3 / ((i1 - i2) * (momentum2 - two_energy * i3)))
    m = (i1 - i2) * (momentum2 - two_energy * i3) / ((i2 - i3) * (two_energy * i1 - momentum2))
    return 4.0 * ellipk(m) * math.sqrt(i1 * i2 * i3 / ((i2 - i3) * (two_energy * i1 - momentum2)))


@pytest.mark.parametrize("omega0", [(1.0, 0.2, 0.3), (0.1, 0.3, 1.2), (0.5, -0.9, 0.2), (-0.05, 0.4, -1.0)])
def test_period_matches_t9_and_the_truth(omega0):
    moments = np.array([2.7, 1.9, 1.1])
    body = RigidBody(np.diag(moments), 1.0, np.zeros(3))
    omega0 = np.array(omega0)
    value = period(body, omega0)
    assert value == pytest.approx(_period_formula_t9(moments, omega0), rel=1e-14)
    reference = truth(body, np.array([1.0, 0, 0, 0]), omega0, np.array([0.0, 0.5 * value, value]), precision="quad")
    # ω returns after T (measured 3e-15) and not after T/2
    assert np.max(np.abs(reference.omega[2] - omega0)) <= 1e-13
    assert np.max(np.abs(reference.omega[1] - omega0)) > 1e-3


# Four inertia sets and both families (FORMULARY T9's check covered the same ground).
MONTGOMERY_CASES = [((2.7, 1.9, 1.1), (1.0, 0.2, 0.3)), ((2.7, 1.9, 1.1), (0.1, 0.3, 1.2)),
                    ((3.0, 2.0, 1.5), (0.5, -0.4, 0.2)), ((3.0, 2.0, 1.5), (-0.05, 0.4, -1.0)),
                    ((2.0, 1.2, 1.0), (0.7, 0.2, -0.1)), ((2.2, 1.6, 0.9), (0.2, -0.1, 1.4)),
                    ((2.0, 2.0, 1.0), (0.3, -0.5, 1.1)), ((1.0, 1.0, 2.0), (0.3, -0.5, 1.1))]


def _measured_montgomery(body, quat0, omega0, span):
    """Δθ from the truth: the angle of R(T) R(0)ᵀ about the world angular momentum, in (-π, π]."""
    reference = truth(body, quat0, omega0, np.array([0.0, span]), precision="quad")
    start, end = quat_to_matrix(reference.quat)
    relative = matrix_to_quat(end @ start.T)
    axis = start @ (body.inertia @ omega0)
    axis = axis / np.linalg.norm(axis)
    # the relative rotation is about M itself (its axis is off M by ~1e-16)
    assert np.linalg.norm(np.cross(relative[1:], axis)) < 1e-13
    return 2.0 * math.atan2(relative[1:] @ axis, relative[0])


@pytest.mark.parametrize("moments, omega0", MONTGOMERY_CASES)
def test_montgomery_phase_from_the_truth(moments, omega0):
    body = RigidBody(np.diag(moments), 1.0, np.zeros(3))
    omega0 = np.array(omega0)
    quat0 = matrix_to_quat(zxz_to_matrix(0.3, 1.2, -0.4))
    motion = free_motion(body, quat0, omega0)
    measured = _measured_montgomery(body, quat0, omega0, motion.period)
    formula = montgomery_phase(body, omega0)
    # the bound; measured <= 1e-14
    assert abs(math.remainder(measured - formula, 2.0 * math.pi)) <= 1e-10
    # the opposite sign of Ω (the seed's unspecified orientation) misses
    wrong = 2.0 * motion.energy * motion.period / motion.momentum + motion.solid_angle
    assert abs(math.remainder(measured - wrong, 2.0 * math.pi)) > 1e-2


@pytest.mark.parametrize("moments, omega0", MONTGOMERY_CASES)
def test_solid_angle_sign_and_continuous_precession(moments, omega0):
    """Ω > 0 about the largest axis, < 0 about the smallest (T9), and Φ(T) = 2ET/L - Ω + 2π sgn Ω."""
    body = RigidBody(np.diag(moments), 1.0, np.zeros(3))
    omega0 = np.array(omega0)
    motion = free_motion(body, np.array([1.0, 0, 0, 0]), omega0)
    omega_solid = solid_angle(body, omega0)
    largest = int(np.argmax(moments)) if motion.kind != "symmetric" else None
    if motion.kind == "major":
        assert omega_solid > 0
    elif motion.kind == "minor":
        assert omega_solid < 0
    elif largest is None:
        # symmetric: positive iff the symmetry axis has the largest moment
        assert (omega_solid > 0) == (moments[2] > moments[0])
    continuous = 2.0 * motion.energy * motion.period / motion.momentum - omega_solid \
        + 2.0 * math.pi * math.copysign(1.0, omega_solid)
    # two independent elliptic expressions (precession angle and area); measured <= 7e-15
    assert precession_per_period(body, omega0) == pytest.approx(continuous, abs=1e-12)


def test_symmetric_montgomery_closed_form():
    """Φ(T) = 2ET/L ± 2π cos ϑ for the symmetric top (T9), + if I3 > I1."""
    for moments, sign in (((1.0, 1.0, 2.0), 1.0), ((2.0, 2.0, 1.0), -1.0)):
        body = RigidBody(np.diag(moments), 1.0, np.zeros(3))
        omega0 = np.array([0.3, -0.5, 1.1])
        motion = free_motion(body, np.array([1.0, 0, 0, 0]), omega0)
        momentum = body.inertia @ omega0
        cos_tilt = momentum[2] / np.linalg.norm(momentum)
        expected = 2.0 * motion.energy * motion.period / motion.momentum + sign * 2.0 * math.pi * abs(cos_tilt)
        assert motion.precession == pytest.approx(expected, rel=1e-14)


def test_lyapunov_exponent_from_two_nearby_truth_runs():
    """Divergence of two runs about the middle axis, ω = w e2 and ω + 1e-10 (a generic direction): the slope of
    log|Δω| once the decaying mode has died is |w| √(α1 α3) (T8), well within the issue's 2%."""
    body = RigidBody(np.diag([3.0, 2.0, 1.0]), 1.0, np.zeros(3))
    rate = 1.5
    stationary = np.array([0.0, rate, 0.0])
    times = np.linspace(0.0, 16.0, 161)
    base = truth(body, np.array([1.0, 0, 0, 0]), stationary, times)
    nearby = truth(body, np.array([1.0, 0, 0, 0]), stationary + 1e-10 * np.array([0.6, 0.0, -0.8]), times)
    distance = np.linalg.norm(nearby.omega - base.omega, axis=1)
    window = (times >= 4.0) & (distance < 1e-4)  # linear regime, after e^{-μ t} has decayed by e^{-3.5}
    slope = np.polyfit(times[window], np.log(distance[window]), 1)[0]
    exponent = lyapunov_exponent(body, rate)
    assert exponent == pytest.approx(rate * math.sqrt(1.0 / 3.0), rel=1e-15)
    # measured 1e-4 relative (the decaying mode's remnant)
    assert slope == pytest.approx(exponent, rel=0.02)
    assert slope == pytest.approx(exponent, rel=1e-3)


def test_unstable_direction_grows_as_a_pure_exponential():
    body = RigidBody(np.diag([3.0, 2.0, 1.0]), 1.0, np.zeros(3))
    rate = -1.5  # the exponent does not depend on the sign of w
    direction = unstable_direction(body, rate)
    times = np.linspace(0.0, 10.0, 11)
    run = truth(body, np.array([1.0, 0, 0, 0]), np.array([0.0, rate, 0.0]) + 1e-12 * direction, times,
                precision="quad")
    growth = np.linalg.norm(run.omega - [0.0, rate, 0.0], axis=1) / 1e-12
    assert np.max(np.abs(growth / np.exp(lyapunov_exponent(body, rate) * times) - 1.0)) < 1e-6


@pytest.mark.parametrize("axis", [0, 2])
def test_small_oscillation_frequencies(axis):
    """ω = w e_a + ε e2: the measured oscillation of ω2 in the truth and the elliptic period both give T8's
    frequency (to O(ε²))."""
    body = RigidBody(np.diag([3.0, 2.0, 1.0]), 1.0, np.zeros(3))
    rate = 1.3
    omega0 = np.zeros(3)
    omega0[axis] = rate
    omega0[1] = 1e-5
    expected = oscillation_frequencies(body, rate)[0 if axis == 0 else 1]
    assert 2.0 * math.pi / period(body, omega0) == pytest.approx(expected, rel=1e-9)
    times = np.linspace(0.0, 60.0, 6001)
    run = truth(body, np.array([1.0, 0, 0, 0]), omega0, times)
    signal = run.omega[:, 1]
    crossings = np.nonzero(np.diff(np.sign(signal)) != 0)[0]
    # linear interpolation of the zero crossings; their mean spacing is half a period
    roots = times[crossings] - signal[crossings] * (times[crossings + 1] - times[crossings]) \
        / (signal[crossings + 1] - signal[crossings])
    measured = math.pi / np.mean(np.diff(roots))
    assert measured == pytest.approx(expected, rel=1e-6)
