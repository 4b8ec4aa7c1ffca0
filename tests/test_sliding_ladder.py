"""The sliding ladder (FORMULARY T5, kind "sliding_ladder"): the case format, the reference equation and its
detachment event, the MuJoCo models' rows and check rows."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from stereodyn.harness.scenes.cases import CaseError, LadderCase, find_case, load_case
from stereodyn.harness.run.plan import plan
from stereodyn.harness.run.measure import measure
from stereodyn.reference import sliding_ladder as ref_ladder

LADDER = """kind = "sliding_ladder"
[ladder]
mass = 1.0
half_length = 1.0
theta0 = 0.3
g = 9.81
[run]
t_end = 0.8
dt = [1e-3]
samples = 161
"""


def write(tmp_path, text):
    path = tmp_path / "sliding_ladder.toml"
    path.write_text(text)
    return path


def test_ladder_case_loads(tmp_path):
    case = load_case(write(tmp_path, LADDER))
    assert isinstance(case, LadderCase) and case.ladder.theta_dot0 == 0.0 and case.kind == "sliding_ladder"


@pytest.mark.parametrize("old, new, key, rule", [
    ("theta0 = 0.3", "theta0 = 1.7", "ladder.theta0", "must be in (0, pi/2)"),
    ("mass = 1.0", "mass = 0.0", "ladder.mass", "must be > 0"),
    ("g = 9.81", "g = 9.81\nmu = 0.2", "ladder.mu", "unknown key"),
    ('kind = "sliding_ladder"', 'kind = "ladder"', "kind", "unknown scene kind"),
    ("g = 9.81", "g = 9.81\ntheta_dot0 = 10.0", "ladder.theta_dot0", "the wall would pull"),
])
def test_bad_ladder_files_are_errors(tmp_path, old, new, key, rule):
    with pytest.raises(CaseError) as error:
        load_case(write(tmp_path, LADDER.replace(old, new)))
    assert error.value.key == key and rule in error.value.rule


def test_reference_detaches_at_the_formulary_angle():
    """Within 1e-8 rad of arccos((2/3) cos θ0), found by a heyoka event; energy conserved."""
    case = find_case("sliding-ladder")
    times = np.linspace(0.0, case.t_end, case.samples)
    motion = ref_ladder.solve(case.ladder, times)
    assert abs(motion.detach_angle - math.acos(2.0 / 3.0 * math.cos(case.ladder.theta0))) <= 1e-8
    assert abs(ref_ladder.wall_force(case.ladder, motion.detach_angle,
                                     np.interp(motion.detach_time, times, motion.theta_dot))) < 1e-3
    # Φ1 changes sign there: positive before, negative after (the bilateral wall would pull)
    before, after = times < motion.detach_time, times > motion.detach_time
    assert np.all(ref_ladder.wall_force(case.ladder, motion.theta[before][1:], motion.theta_dot[before][1:]) > 0)
    assert np.all(ref_ladder.wall_force(case.ladder, motion.theta[after], motion.theta_dot[after]) < 0)
    state = ref_ladder.planar_state(case.ladder, motion.theta, motion.theta_dot)
    energy = ref_ladder.energy(case.ladder, state)
    assert np.ptp(energy) / ref_ladder.energy_scale(case.ladder, state[0]) <= 1e-14


def test_detachment_with_an_initial_rate():
    lad = ref_ladder.Ladder(mass=2.0, half_length=0.5, theta0=0.4, theta_dot0=0.5, g=9.81)
    motion = ref_ladder.solve(lad, np.linspace(0.0, 1.0, 101))
    assert abs(motion.detach_angle - ref_ladder.detachment_angle(lad)) <= 1e-8


def test_ladder_rows_and_checks(monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)
    case = dataclasses.replace(find_case("sliding-ladder"), dt=(1e-3,))
    specs, skipped = plan([case], ["mujoco", "pinocchio", "reference"], ["rk4", "taylor"])
    assert not skipped
    rows = {}
    for spec in specs:
        # the one run -> row path of every scene (the sweep's, with its checks)
        rows[(spec.engine, spec.formulation)] = measure(spec, None, full=True)
    assert set(rows) == {("reference", "theta"), ("mujoco", "bilateral"), ("mujoco", "unilateral"),
                         ("pinocchio", "bilateral")}
    for key, row in rows.items():
        assert row["status"] == "ok", row.get("message")
        quantities = {check["quantity"]: check for check in row["checks"]}
        assert {"energy_drift", "constraint_violation"} <= set(quantities)
        assert math.isfinite(quantities["energy_drift"]["measured"])
        assert math.isfinite(quantities["constraint_violation"]["measured"])
    reference = {c["quantity"]: c for c in rows[("reference", "theta")]["checks"]}
    assert reference["detachment_angle"]["error"] <= 1e-8
    unilateral = {c["quantity"]: c for c in rows[("mujoco", "unilateral")]["checks"]}
    # soft contacts and one-step resolution: the top leaves the wall within 1e-2 rad of theory at dt = 1e-3
    assert unilateral["detachment_angle"]["error"] <= 1e-2
    # the bilateral model follows the equation over the whole motion (soft equality: violation ~5e-5 m)
    bilateral = rows[("mujoco", "bilateral")]
    assert bilateral["attitude_err"] <= 1e-4 and {c["quantity"]: c for c in bilateral["checks"]}[
        "constraint_violation"]["measured"] <= 1e-4
    # Pinocchio's constrained dynamics hold the ends exactly (up to the integrator's drift): rk4 at dt = 1e-3
    # follows the equation to 7.9e-13 rad, the ends 2.9e-13 m off their axes, energy 1.4e-12 (measured here)
    pinocchio = rows[("pinocchio", "bilateral")]
    checks = {c["quantity"]: c for c in pinocchio["checks"]}
    assert pinocchio["attitude_err"] <= 1e-10 and pinocchio["omega_err"] <= 1e-10
    assert checks["constraint_violation"]["measured"] <= 1e-10 and checks["energy_drift"]["measured"] <= 1e-10


def test_pinocchio_ladder_forces_are_the_equations():
    """The Lagrange multipliers of Pinocchio's constrained dynamics are the wall's and the floor's push (5.21),
    (corrected 5.22), and its angular acceleration is (5.23), at states on both sides of the detachment."""
    from stereodyn.harness.engines.pinocchio import LadderSystem
    ladder = ref_ladder.Ladder(mass=2.0, half_length=0.7, theta0=0.3, theta_dot0=0.0, g=9.81)
    system = LadderSystem(ladder)
    for theta, rate in ((0.4, 0.5), (0.7, 1.3), (1.1, 2.6)):
        y = ref_ladder.planar_state(ladder, theta, rate)
        accel = system.rhs(0.0, None, y)
        assert abs(accel[5] - ref_ladder.angular_acceleration(ladder, theta)) <= 1e-12
        wall, floor = system.data.lambda_c
        assert abs(wall - ref_ladder.wall_force(ladder, theta, rate)) <= 1e-12
        assert abs(floor - ref_ladder.floor_force(ladder, theta, rate)) <= 1e-12
    assert wall < 0.0  # the last state is past the detachment: the bilateral wall pulls


def test_pinocchio_ladder_plans_only_the_integrators_of_a_vector_state():
    case = find_case("sliding-ladder")
    specs, skipped = plan([case], ["pinocchio"], None)
    assert not skipped and {s.integrator for s in specs} == {"euler", "rk4"}  # symplectic_euler & co. are SO(3)'s
    assert {s.formulation for s in specs} == {"bilateral"} and len(specs) == 2 * len(case.dt)


def test_the_ladders_attitude_error_is_the_angle_on_the_circle():
    """attitude_err is an angle in [0, pi] in every scene (results.ANGLES, which every reader checks): a rod a full turn
    and a bit ahead of the equation (theta - theta_equation = 2 pi + 0.1) is 0.1 rad from it, one 3 rad behind is 3."""
    from types import SimpleNamespace

    from stereodyn.harness.scenes.sliding_ladder import ladder_metrics

    ladder = ref_ladder.Ladder(mass=1.0, half_length=1.0, theta0=0.3, theta_dot0=0.0, g=9.81)
    times = np.array([0.0, 0.1, 0.2])
    theta = np.array([0.3, 0.35, 0.4])
    equation = ref_ladder.LadderMotion(times, theta, np.zeros(3), math.nan, math.nan)
    state = ref_ladder.planar_state(ladder, theta + np.array([0.0, 2 * np.pi + 0.1, -3.0]), np.zeros(3))
    traj = SimpleNamespace(state=state, times=times, violation=np.zeros(3))
    out = ladder_metrics(SimpleNamespace(case=SimpleNamespace(ladder=ladder), formulation="bilateral"), traj, equation)
    assert out["attitude_err"] == pytest.approx(3.0, abs=1e-12)
    assert out["attitude_err_end"] == pytest.approx(3.0, abs=1e-12)
    traj.state = ref_ladder.planar_state(ladder, theta + np.array([0.0, 0.05, 2 * np.pi + 0.1]), np.zeros(3))
    out = ladder_metrics(SimpleNamespace(case=SimpleNamespace(ladder=ladder), formulation="bilateral"), traj, equation)
    assert out["attitude_err"] == pytest.approx(0.1, abs=1e-12)
    # an error within pi keeps every digit (wrapping it through + pi rounded 4.64e-14 to 4.62e-14: Pinocchio's rk4
    # at dt 5e-4 in the default run)
    tiny = 4.640732243e-14
    traj.state = ref_ladder.planar_state(ladder, theta + np.array([0.0, tiny, -tiny / 2]), np.zeros(3))
    out = ladder_metrics(SimpleNamespace(case=SimpleNamespace(ladder=ladder), formulation="bilateral"), traj, equation)
    assert out["attitude_err"] == abs((theta[1] + tiny) - theta[1])
