"""Checks against theory (harness.checks): the measurements on known signals, the sleeping top's linearisation, an
engine against theory, and check rows through the result store and --resume."""
import dataclasses
import json
import math

import numpy as np
import pandas as pd
import pytest

from stereodyn.harness import cli
from stereodyn.harness.scenes import checks
from stereodyn.harness.scenes.cases import find_case
from stereodyn.harness.trajectory import Status, Trajectory
from stereodyn.harness.grid import time_grid
from stereodyn.reference.exact import lyapunov_exponent, sleeping_top_threshold
from stereodyn.reference.rotations import quat_exp
from stereodyn.reference.truth import truth

# The suite's sample spacing: t_end 20 over 999 intervals.
TIMES = np.linspace(0.0, 20.0, 1000)


def test_zero_crossings_are_refined_to_round_off():
    """On the degree-7 local interpolant the roots are exact to round-off (measured 3.6e-15 s)."""
    rate, phase = 1.3, 0.4
    roots = checks.zero_crossings(TIMES, np.sin(rate * TIMES + phase))
    exact = (np.arange(1, len(roots) + 1) * math.pi - phase) / rate
    assert len(roots) == 8 and np.max(np.abs(roots - exact)) <= 1e-12


def test_attitude_between_samples():
    """A uniform rotation, with the samples' signs scrambled (q and -q are one attitude): measured 8e-16."""
    rotvec = np.array([0.3, -1.1, 0.7])
    quat = quat_exp(TIMES[:, None] * rotvec)
    quat[::3] *= -1.0
    for t in (0.0, 3.21, 11.111, 19.999):
        expected = quat_exp(t * rotvec)
        got = checks.attitude_at(TIMES, quat, t)
        assert min(np.max(np.abs(got - expected)), np.max(np.abs(got + expected))) <= 1e-13


def test_growth_rate_is_the_slope_of_the_log():
    separation = 1e-9 * np.exp(0.37 * TIMES)
    assert checks.growth_rate(TIMES, separation, TIMES <= 10.0) == pytest.approx(0.37, rel=1e-12)
    assert math.isnan(checks.growth_rate(TIMES, separation, TIMES <= 0.05))  # too few samples to fit


def test_unstable_direction_is_the_linearisations_eigenvector():
    case = find_case("dzhanibekov")
    direction = checks.unstable_direction(case)
    sigma, omega = case.inertia, case.omega0
    image = np.linalg.solve(sigma, np.cross(sigma @ direction, omega) + np.cross(sigma @ omega, direction))
    exponent = lyapunov_exponent(case.body, float(np.linalg.norm(sigma @ omega)) / 2.0)
    # ω0 is 1e-3 rad off the middle axis: the eigenvalue there differs from T8's by O(1e-6)
    assert image == pytest.approx(exponent * direction, rel=1e-5, abs=1e-5)


@pytest.mark.parametrize("factor", [0.9, 0.99, 1.01, 1.1])
def test_sleeping_top_linearisation_against_the_truth(factor):
    """A3² r² < 4 A1 α: the tilt of the mode of largest real part grows like e^{Re s t}, Re s = √(4 A1 α - A3² r²) /
    (2 A1) (checks.tilt_exponents); above the threshold it neither grows nor decays. Measured: <= 6e-9 relative below
    (at 0.9 r_c the tilt reaches LINEAR_TILT, where nonlinear terms are O(1e-6)), <= 1.5e-13 /s above."""
    base = find_case("sleeping-top-stable")
    case = dataclasses.replace(base, omega0=factor * sleeping_top_threshold(base.body) * np.array([0.0, 0.0, 1.0]))
    exponents = checks.tilt_exponents(case)
    theory = checks._sleeping_theory(case)["tilt_growth_rate"]
    assert max(exponents.real) == pytest.approx(theory, abs=1e-12)
    assert (theory > 0.0) == (factor < 1.0)
    run = truth(case.body, case.quat0, case.omega0, TIMES)
    quat0, omega0 = checks.tilted_state(case, checks.TILT_KICK)
    tilted = truth(case.body, quat0, omega0, TIMES)
    trajectory = Trajectory(TIMES, run.quat, run.omega)
    measured = checks._sleeping_measured(case, trajectory, lambda _: Trajectory(TIMES, tilted.quat, tilted.omega))
    assert measured["tilt_growth_rate"] == pytest.approx(theory, rel=1e-6, abs=1e-10)


def test_a_run_that_did_not_finish_has_nan_measurements():
    case = find_case("euler-poinsot-major")
    grid = time_grid(case.t_end, 0.01, case.samples)
    n = len(grid.times)
    diverged = Trajectory(grid.times, np.full((n, 4), np.nan), np.full((n, 3), np.nan), Status.DIVERGED, "boom", 1.0)
    rows = checks.measure(case, diverged, lambda _: pytest.fail("no rerun for a run that did not finish"))
    assert [row["quantity"] for row in rows] == ["period", "montgomery_phase"]
    assert all(math.isnan(row["measured"]) and math.isnan(row["error"]) for row in rows)
    assert all(math.isfinite(row["theory"]) for row in rows)


def test_no_checks_for_a_case_without_theory():
    assert checks.applicable(find_case("heavy-asymmetric")) == []
    assert checks.applicable(find_case("kovalevskaya")) == []
    assert checks.applicable(find_case("staude-rotation")) == []


ENGINE_CASES = ["euler-poinsot-major", "euler-poinsot-minor", "dzhanibekov", "lagrange-precession",
                "sleeping-top-stable", "sleeping-top-unstable", "grioli-precession"]
# MuJoCo's rk4 at dt = 3e-3: its global error ~ dt^4 puts every quantity near 1e-13..1e-8 (measured); each bound is
# 10 to 100 times the largest measured, named beside it.
ENGINE_TOLERANCE = {
    "period": 1e-9,                  # 7.5e-11 (dzhanibekov: its flips amplify the step error)
    "montgomery_phase": 1e-7,        # 3.9e-9 rad (dzhanibekov)
    "lyapunov_exponent": 1e-3,       # 4.6e-5, as the truth: the linearisation's own O(angle²)
    "precession_rate": 1e-6,         # 6.2e-8
    "tilt_growth_rate": 1e-6,        # 4.3e-8 relative below the threshold, 6.8e-10 /s above it
    "omega_squared": 1e-9,           # 2.2e-11
    "precession_axis_drift": 1e-9,   # 4.7e-11
}


@pytest.fixture(scope="module")
def mujoco_rk4(tmp_path_factory):
    out = tmp_path_factory.mktemp("mujoco")
    assert cli.main(["run", *ENGINE_CASES, "--engines", "mujoco", "--integrators", "rk4", "--dt", "3e-3",
                     "--jobs", "1", "--quiet", "--out", str(out)]) == 0
    return out


def test_an_engine_agrees_with_theory(mujoco_rk4):
    table = checks.read_checks(mujoco_rk4 / "checks.csv")
    assert set(table.engine) == {"mujoco"} and set(table.dt) == {3e-3}
    assert set(table.quantity) == set(ENGINE_TOLERANCE)
    for _, row in table.iterrows():
        assert row.error <= ENGINE_TOLERANCE[row.quantity], (row.case, row.quantity, row.error)


def test_check_rows_follow_the_results_table_order(mujoco_rk4):
    """The sweep runs the costliest first; checks.csv is written in results.csv's row order all the same."""
    cases = list(dict.fromkeys(checks.read_checks(mujoco_rk4 / "checks.csv").case))
    in_results = [c for c in dict.fromkeys(pd.read_csv(mujoco_rk4 / "results.csv").case) if c in cases]
    assert len(cases) >= 5 and cases == in_results


def test_check_rows_are_stored_and_survive_resume(mujoco_rk4):
    before = (mujoco_rk4 / "checks.csv").read_text()
    records = [json.loads(path.read_text()) for path in (mujoco_rk4 / "store").glob("*.json")]
    assert sum(len(record["row"][checks.ROW_KEY]) for record in records) == len(before.splitlines()) - 1
    (mujoco_rk4 / "checks.csv").unlink()
    assert cli.main(["run", *ENGINE_CASES, "--engines", "mujoco", "--integrators", "rk4", "--dt", "3e-3",
                     "--jobs", "1", "--quiet", "--resume", "--out", str(mujoco_rk4)]) == 0
    assert (mujoco_rk4 / "checks.csv").read_text() == before


@pytest.mark.slow  # since 2026-12-02, ~6 s; by default the checks' sweep of this file (the default suite's 8 minutes)
def test_a_sweep_without_checks_writes_an_empty_table(tmp_path):
    assert cli.main(["run", "kovalevskaya", "--engines", "mujoco", "--integrators", "rk4", "--t-end", "0.5",
                     "--quiet", "--out", str(tmp_path)]) == 0
    table = pd.read_csv(tmp_path / "checks.csv")
    assert tuple(table.columns) == checks.COLUMNS and table.empty
    assert "checks.csv has no rows" in (tmp_path / "report.md").read_text()
