"""The formulations behind one protocol and as reference-engine runs: conversions and charts, the four formulations
checking each other under heyoka, fixed-step convergence orders, rows and report of a sweep."""
from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from stereodyn.harness.analysis.fitting import order_slope
from stereodyn.harness import cli
from stereodyn.harness.run import plan
from stereodyn.harness.scenes.cases import Case, find_case, load_suite
from stereodyn.harness.engines import declared, get_engine
from stereodyn.harness.trajectory import Status
from stereodyn.harness.engines.reference import FormulationSystem, ReferenceEngine
from stereodyn.harness.grid import time_grid
from stereodyn.harness.integrators import get as get_integrator
from stereodyn.harness.report.markdown import formulation_lines
from stereodyn.harness.run.results import COLUMNS
from stereodyn.reference import formulations, truth
from stereodyn.reference.body import RigidBody
from stereodyn.reference.euler_angles import to_quat
from stereodyn.reference.expressions import THRESHOLD
from stereodyn.reference.rotations import attitude_angle, quat_to_matrix

NAMES = ("quaternion", "gibbs", "gibbs_hamiltonian", "euler_zxz")
CHARTED = NAMES[1:]
FREE = RigidBody(np.diag([2.0, 1.5, 1.0]), 1.0, np.zeros(3))
LAGRANGE = RigidBody(np.diag([1.0, 1.0, 0.4]), 1.0, np.array([0.0, 0.0, 0.2]), 9.81, np.array([0.0, 0.0, -1.0]))
# Non-principal axes, centre of mass off every axis, gravity not along a world axis.
HEAVY = RigidBody(np.array([[2.0, 0.1, -0.05], [0.1, 1.6, 0.08], [-0.05, 0.08, 1.1]]), 1.0,
                  np.array([0.1, -0.05, 0.25]), 9.81,
                  np.array([0.3, -0.2, -0.933]) / np.linalg.norm([0.3, -0.2, -0.933]))


def angle(quat_a: np.ndarray, quat_b: np.ndarray) -> np.ndarray:
    return attitude_angle(quat_to_matrix(quat_a), quat_to_matrix(quat_b))


def through_identity(body: RigidBody, omega: np.ndarray, before: float) -> tuple[np.ndarray, np.ndarray]:
    """The state `before` seconds ahead of the identity attitude (θ = 0) with body angular velocity omega: integrated
    backwards as the time-reversed motion (R(-t), -ω(-t)), which is a motion of the same body."""
    run = truth.truth(body, np.array([1.0, 0.0, 0.0, 0.0]), -np.asarray(omega), np.array([0.0, before]))
    return run.quat[-1], -run.omega[-1]


def make_case(body: RigidBody, quat0: np.ndarray, omega0: np.ndarray, t_end: float, samples: int = 201) -> Case:
    return Case(name="test", description="", tags=(), mass=body.mass, com=body.com, inertia=body.inertia,
                gravity=body.gravity, gravity_direction=body.gravity_direction, quat0=quat0, omega0=omega0,
                t_end=t_end, dt=(1e-3,), samples=samples)


# ------------------------------------------------------------------------------------------ protocol and charts

def test_registry_and_engine_lists():
    assert tuple(formulations.FORMULATIONS) == NAMES
    with pytest.raises(KeyError, match="valid: quaternion, gibbs"):
        formulations.get("rodrigues", FREE)
    engine = get_engine("reference")
    assert declared.formulations(engine) == NAMES
    assert engine.integrators()[0] == "taylor" and {"euler", "rk4", "scipy_dop853"} <= set(engine.integrators())
    assert engine.offer("taylor").adaptive and engine.offer("scipy_dop853").adaptive
    assert not engine.offer("rk4").adaptive
    case = make_case(FREE, np.array([1.0, 0.0, 0.0, 0.0]), np.array([0.4, 0.1, 2.0]), 1.0)
    with pytest.raises(KeyError, match="valid: quaternion"):
        engine.prepare(case, "taylor", None, formulation="rodrigues")
    with pytest.raises(KeyError, match="valid: taylor, scipy_rk45, .*euler, rk4"):
        engine.prepare(case, "rk4_naive", 1e-2, formulation="gibbs")  # a Lie-group method: not for coordinates
    with pytest.raises(ValueError, match="dt"):
        engine.prepare(case, "rk4", None, formulation="gibbs")


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("angles", [(0.3, 0.8, -0.5), (2.0, 2.9, 1.0), (0.0, 0.02, 0.0)])
def test_start_and_observe_give_back_the_initial_state(name, angles):
    """Rotation angles inside and outside each chart's domain (0.02 rad from gimbal lock, 2.9 rad from identity):
    outside, the chart is re-centred at once and that counts as a change."""
    formulation = formulations.get(name, HEAVY)
    quat0, omega0 = to_quat(np.array(angles)), np.array([0.4, -1.1, 2.0])
    chart, state = formulation.start(quat0, omega0)
    quat, omega = formulation.observe(chart, state)
    assert angle(quat, quat0) <= 2e-15
    np.testing.assert_allclose(omega, omega0, rtol=0, atol=1e-14)
    quat_one, omega_one = formulation.observe_one(chart, state)
    np.testing.assert_allclose(quat_one, quat, rtol=0, atol=1e-15)
    np.testing.assert_allclose(omega_one, omega, rtol=0, atol=1e-15)
    if formulation.charted:
        assert not formulation.outside(state, formulation.recentre_threshold)
        assert chart.changes == int(formulation.outside(formulation.local_state(quat0, omega0),
                                                         formulation.recentre_threshold))


@pytest.mark.parametrize("name", CHARTED)
def test_rechart_keeps_the_attitude_and_the_angular_velocity(name):
    rng = np.random.default_rng(11)
    formulation = formulations.get(name, HEAVY)
    chart = formulation.chart(np.array([0.6, -0.2, 0.7, 0.3]) / np.linalg.norm([0.6, -0.2, 0.7, 0.3]), changes=4)
    for _ in range(20):
        state = formulation.local_state(to_quat(rng.uniform(0.3, 2.8, 3)), rng.normal(size=3))
        new_chart, new_state = formulation.rechart(chart, state)
        assert new_chart.changes == 5
        (quat, omega), (new_quat, new_omega) = formulation.observe(chart, state), formulation.observe(new_chart,
                                                                                                    new_state)
        assert angle(quat, new_quat) <= 2e-15
        np.testing.assert_allclose(new_omega, omega, rtol=0, atol=1e-14)


def test_quaternion_formulation_equations_match_euler_poisson():
    """The compiled quaternion right-hand side (the truth's heyoka system) against reference.euler_poisson."""
    rng = np.random.default_rng(5)
    formulation = formulations.get("quaternion", HEAVY)
    chart = formulation.chart(np.array([1.0, 0.0, 0.0, 0.0]))
    states = np.concatenate([to_quat(rng.uniform(0, 3, (50, 3))), rng.normal(size=(50, 3))], axis=1)
    pars = np.repeat(formulation.rhs_parameters(chart)[:, None], len(states), axis=1)
    compiled = formulations.compiled_rhs("quaternion")(states.T.copy(), pars=pars, time=np.zeros(len(states))).T
    np.testing.assert_allclose(compiled, formulation.rhs(0.0, chart, states), rtol=0, atol=1e-13)


# ------------------------------------------------------------------------------- the formulations check each other

AGREEMENT_MOTIONS = {
    # The suite's free body and angular velocity, through the identity (θ = 0) at t = 5; it spins through angle π
    # every few seconds.
    "free-asymmetric": (FREE, np.array([0.4, 0.1, 2.0])),
    # The suite's Lagrange top on a looping motion: its axis passes through the upward vertical (θ = 0) at t = 5 s,
    # and every nutation period, nutating down to θ = 2.45 rad in between.
    "lagrange-top": (LAGRANGE, np.array([2.0, 0.0, 3.0])),
}


@pytest.mark.parametrize("motion", AGREEMENT_MOTIONS)
def test_heyoka_formulations_agree_over_50s_through_both_singularities(motion):
    """All four formulations integrated by heyoka give the same R(t) to 1e-12 over t = 50, on motions through
    rotation angle π (the Gibbs charts change) and through θ = 0 (the angles' chart changes)."""
    body, omega = AGREEMENT_MOTIONS[motion]
    quat0, omega0 = through_identity(body, omega, 5.0)
    times = np.linspace(0.0, 50.0, 2001)
    runs = {name: formulations.integrate_taylor(name, body, quat0, omega0, times) for name in NAMES}
    assert runs["quaternion"].chart_changes is None
    assert all(runs[name].chart_changes > 0 for name in CHARTED), {n: runs[n].chart_changes for n in CHARTED}
    errors = {name: float(np.max(angle(runs[name].quat, runs["quaternion"].quat))) for name in CHARTED}
    assert max(errors.values()) <= 1e-12, errors
    for name in CHARTED:
        np.testing.assert_allclose(runs[name].omega, runs["quaternion"].omega, rtol=0, atol=1e-11)


def test_heyoka_formulations_on_a_heavy_body_with_tilted_gravity():
    """Non-principal axes, centre of mass off every axis, gravity along no world axis: every formulation agrees with
    the truth to 1e-12 over t = 10, through several chart changes."""
    quat0, omega0 = to_quat(np.array([0.1, 0.7, 0.3])), np.array([1.0, -0.5, 2.0])
    times = np.linspace(0.0, 10.0, 501)
    reference = truth.truth(HEAVY, quat0, omega0, times)
    for name in CHARTED:
        run = formulations.integrate_taylor(name, HEAVY, quat0, omega0, times)
        assert run.chart_changes > 0 and np.max(angle(run.quat, reference.quat)) <= 1e-12, name


# ------------------------------------------------------------------------------------------- fixed-step integrators

ORDER_MOTION = (to_quat(np.array([0.0, 1.3, 0.0])), np.array([-1.0, 0.5, 1.0]), 1.0)  # quat0, omega0, t_end


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("integrator, dts, bounds", [("rk4", (0.1, 0.05, 0.025), (3.7, 4.3)),
                                                     ("euler", (4e-3, 2e-3, 1e-3), (0.9, 1.1))])
def test_fixed_step_convergence_order_without_chart_changes(name, integrator, dts, bounds):
    """Fitted order of the final attitude error against the truth, on the heavy body with tilted gravity: a rotation
    of 75° about x, so the motion stays where |q| < 1 and |sin θ| > 0.5 (no chart change). Errors 1e-5..1e-8
    (rk4), 1e-3 (euler): far above the truth's and the round-off."""
    quat0, omega0, t_end = ORDER_MOTION
    reference = truth.truth(HEAVY, quat0, omega0, np.array([0.0, t_end]))
    engine, errors = ReferenceEngine(), []
    for dt in dts:
        run = engine.prepare(make_case(HEAVY, quat0, omega0, t_end), integrator, dt, formulation=name).run(
            time_grid(t_end, dt, 2))
        assert run.status is Status.OK and run.chart_changes in (None, 0)
        assert run.rhs_evals == get_integrator(integrator, "vector").stages * run.steps
        errors.append(float(angle(run.quat[-1], reference.quat[-1])))
    order = order_slope(dts, errors)
    assert bounds[0] <= order <= bounds[1], (order, errors)


@pytest.mark.parametrize("name", CHARTED)
def test_fixed_step_runs_change_charts_and_stay_accurate(name):
    """rk4 at dt = 1e-3 over 10 s on the heavy body with tilted gravity, through chart changes, against the truth."""
    quat0, omega0 = to_quat(np.array([0.1, 0.7, 0.3])), np.array([1.0, -0.5, 2.0])
    case = make_case(HEAVY, quat0, omega0, 10.0)
    grid = time_grid(case.t_end, 1e-3, case.samples)
    run = ReferenceEngine().prepare(case, "rk4", 1e-3, formulation=name).run(grid)
    reference = truth.truth(HEAVY, quat0, omega0, grid.times)
    assert run.status is Status.OK and run.chart_changes > 0
    assert np.max(angle(run.quat, reference.quat)) <= 1e-8  # rk4's error at this dt: ~1e-10 (quaternion: 5e-12)


def test_numpy_and_compiled_right_hand_sides_step_alike():
    """The numpy right-hand side through the same integrator gives the same run: to round-off for the charts; for
    the quaternion to the size of its norm's drift, |q|² - 1, because the two extend Euler–Poisson off the unit
    sphere differently (the compiled one takes R(q) as the homogeneous quadratic, |q|² times a rotation; the numpy
    one normalises q first)."""
    quat0, omega0 = to_quat(np.array([0.1, 0.7, 0.3])), np.array([1.0, -0.5, 2.0])
    grid = time_grid(0.5, 1e-2, 6)
    for name in NAMES:
        formulation = formulations.get(name, HEAVY)
        chart, state = formulation.start(quat0, omega0)
        runs = [get_integrator("rk4", "vector")().integrate(FormulationSystem(formulation, compiled=compiled),
                                                            chart, state, grid) for compiled in (True, False)]
        norm_drift = np.max(np.abs(np.sum(runs[0].quat ** 2, axis=1) - 1.0)) if name == "quaternion" else 0.0
        assert np.max(angle(runs[0].quat, runs[1].quat)) <= 1e-13 + 10 * norm_drift, name
        np.testing.assert_allclose(runs[0].omega, runs[1].omega, rtol=0, atol=1e-12 + 10 * norm_drift)


# --------------------------------------------------------------------------------------------- sweep and report

@pytest.fixture(scope="module")
def reference_sweep(tmp_path_factory):
    out = tmp_path_factory.mktemp("formulations")
    assert cli.main(["run", "lagrange-top", "--engines", "reference", "--t-end", "1", "--dt", "1e-2,5e-3,2e-3",
                     "--jobs", "1", "--quiet", "--out", str(out)]) == 0
    return out, pd.read_csv(out / "results.csv", dtype={"formulation": str}, keep_default_na=True)


def test_rows_carry_the_formulation_and_the_chart_changes(reference_sweep):
    _, df = reference_sweep
    assert COLUMNS[COLUMNS.index("truth_omega_err") + 1] == "chart_changes" and tuple(df.columns) == COLUMNS
    # the truth and taylor on the 3 other formulations, scipy's default methods (default_run) on the quaternion,
    # euler and rk4 on every formulation at 3 dt
    assert len(df) == 4 + 3 + 2 * 4 * 3 and set(df.status) == {"ok"}
    truth_row = df[(df.formulation == "quaternion") & (df.integrator == "taylor")]
    assert len(truth_row) == 1 and truth_row.dt.isna().all() and truth_row.attitude_err.isna().all()
    assert df[df.formulation == "quaternion"].chart_changes.isna().all()
    charted = df[df.formulation.isin(CHARTED)]
    assert (charted.chart_changes >= 0).all() and (charted[charted.formulation != "euler_zxz"].chart_changes > 0).all()
    taylor = df[(df.integrator == "taylor") & (df.formulation != "quaternion")]
    assert len(taylor) == 3 and taylor.dt.isna().all() and (taylor.attitude_err <= 1e-12).all()


def test_plan_gives_every_formulation_its_rows():
    case = find_case("free-asymmetric")
    specs, skipped = plan.plan([case], ["reference"], None)
    assert not skipped
    taylor = [s for s in specs if s.integrator == "taylor"]
    assert [s.formulation for s in taylor] == list(NAMES) and all(s.dt is None for s in taylor)
    assert [s.is_truth for s in taylor] == [True, False, False, False]
    fixed = [s for s in specs if s.dt is not None]
    assert len(fixed) == 2 * len(NAMES) * len(case.dt) and all(s.dt in case.dt for s in fixed)
    scipy_runs = [s for s in specs if s.integrator.startswith("scipy_")]   # the default ones, on the quaternion
    assert scipy_runs and all(s.dt is None and s.formulation == "quaternion" for s in scipy_runs)


def test_report_shows_the_formulations_side_by_side(reference_sweep):
    out, df = reference_sweep
    report = (out / "report.md").read_text()
    section = report.split("## Formulations side by side")[1].split("\n## ")[0]
    assert "dt = 0.005" in section  # the middle of the three steps, which every formulation ran
    header = next(line for line in section.splitlines() if line.startswith("| formulation"))
    for column in ("energy", "att_err", "us/step", "charts"):
        assert f" {column} " in header
    rows = [line for line in section.splitlines() if line.startswith("| ") and line != header]
    for name in NAMES:
        for integrator, dt in (("taylor", "adaptive"), ("euler", "0.005"), ("rk4", "0.005")):
            assert any(row.startswith(f"| {name} | {integrator} | {dt} | ok |") for row in rows), (name, integrator)
    assert formulation_lines(df[df.formulation == "quaternion"]) == []  # one formulation: nothing to compare


def test_formulation_section_needs_no_formulations():
    df = pd.DataFrame({"case": ["c"], "engine": ["mujoco"], "formulation": [""], "integrator": ["rk4"],
                       "dt": [1e-3], "status": ["ok"], "chart_changes": [math.nan]})
    assert formulation_lines(df) == []


# slow (issue 28: the default suite within 8 min on 2 idle cores): 20-80 s at load ~6; `pytest -m slow` runs it
@pytest.mark.slow
def test_report_shows_the_formulations_side_by_side_on_a_torqued_case_too(tmp_path):
    """Issue 13 item 4: one table on the Lagrange top, one on a torqued case, every formulation ok on both."""
    out = tmp_path / "out"
    assert cli.main(["run", "lagrange-top", "self-excited-conic", "--engines", "reference", "--t-end", "1",
                     "--dt", "1e-2,5e-3", "--integrators", "taylor,rk4", "--jobs", "1", "--quiet", "--no-ladder",
                     "--out", str(out)]) == 0
    section = (out / "report.md").read_text().split("## Formulations side by side")[1].split("\n## ")[0]
    for case in ("lagrange-top", "self-excited-conic"):
        table = section.split(f"### {case}")[1].split("\n### ")[0]
        rows = [line for line in table.splitlines() if line.startswith("| ") and not line.startswith("| formulation")]
        for name in NAMES:
            for integrator, dt in (("taylor", "adaptive"), ("rk4", "0.005")):  # the middle of the two
                assert any(row.startswith(f"| {name} | {integrator} | {dt} | ok |") for row in rows), (case, name)
    assert "external torques" in section.split("### self-excited-conic")[1]
    assert "external torques" not in section.split("### lagrange-top")[1].split("### ")[0]
