"""Step-size advice (harness.pipeline.advice, analysis.step_advice) on a known error law: the rows a family gets, their order,
the step cap, the cost, the families advised. The runs are replaced by the law (dt_ladders.measure), so every answer is
known. Found by the mutation check (tools/mutants.py, docs/mutants.md)."""
from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from stereodyn.harness.analysis import step_advice
from stereodyn.harness.pipeline import advice, dt_ladders, tolerance_ladders
from stereodyn.harness.pipeline.dt_ladders import Family
from stereodyn.harness.analysis.step_advice import error_model, rounded, search
from stereodyn.harness.engines import get_engine
from stereodyn.harness.engines.declared import rigid_body
from stereodyn.harness.scenes.cases import find_case, with_overrides

CASE = with_overrides(find_case("free-asymmetric"), t_end=2.0, dt=[1e-2])
FAMILY = Family(CASE, "mujoco", "", "rk4")
MAX_STEPS = 1000  # the step cap: dt >= t_end / 1000 = 2e-3


@pytest.fixture
def law(monkeypatch):
    """Runs that follow error = 1e2 dt^4 (ok, state error 2x the attitude's); the runs made are listed."""
    made = []

    def measure(family, dt, timed=True, with_truth=True):
        made.append(dt)
        err = 1e2 * dt ** 4
        return {**family.columns, "dt": dt, "steps": round(CASE.t_end / dt), "status": "ok", "attitude_err": err,
                "state_err": 2 * err, "_private": 1}
    monkeypatch.setattr(dt_ladders, "measure", measure)
    return made


def test_rows_run_loose_to_tight_each_reaching_its_target(law):
    rows, untimed = advice.advise_family(FAMILY, False, [], 4.0, (1e-6, 1e-3), MAX_STEPS)
    assert [r["target"] for r in rows] == [1e-3, 1e-6]
    for row in rows:
        assert row["error_checked"] <= row["target"] < row["error_fails"] and row["note"] == ""
    # neither advised run was timed yet: both go to the timing phase, without the private columns
    assert sorted(p["dt"] for p in untimed) == sorted(r["dt"] for r in rows)
    assert all(not any(k.startswith("_") for k in p) for p in untimed)


def test_a_target_beyond_the_step_cap_is_checked_at_the_cap_and_named_so(law):
    # 1e-12 needs dt = 1e-3.5 ~ 3.2e-4, below the cap t_end / 1000 = 2e-3 (error 1.6e-9 there)
    row = advice.advise_family(FAMILY, False, [], 4.0, (1e-12,), MAX_STEPS)[0][0]
    assert math.isnan(row["dt"]) and row["fails_at"] == pytest.approx(2e-3)
    assert row["note"].startswith("beyond the step cap") and "(t_end / 1000)" in row["note"]
    assert min(law) == pytest.approx(2e-3)  # nothing finer than the cap was run


def test_a_point_that_did_not_finish_ok_never_reaches_a_target(law):
    # the sweep's run at dt 0.1 diverged after a small error: it is no advice, and the search runs below it
    known = [{"dt": 0.1, "steps": 20, "status": "diverged", "attitude_err": 1e-9, "state_err": 1e-9}]
    row = advice.advise_family(FAMILY, False, known, 4.0, (1e-3,), MAX_STEPS)[0][0]
    assert row["dt"] < 0.1 and row["error_checked"] <= 1e-3


def test_the_advised_runs_are_timed_and_their_cost_is_in_the_row(law, monkeypatch):
    def time_points(points, families, setting="dt", pool=None):
        for p in points:
            p["us_per_sim_s"] = 1e4 * p[setting]
    monkeypatch.setattr(dt_ladders, "time_points", time_points)
    table = advice.run_advice([(FAMILY, False, [], 4.0)], (1e-3, 1e-6), MAX_STEPS)
    assert np.allclose(table["us_per_sim_s"], 1e4 * table["dt"], rtol=1e-12)


def test_adaptive_advice_carries_the_cost_of_its_timed_run(monkeypatch):
    """An adaptive family's advised tolerance is timed by the tolerance ladders' timing phase; its row gets that cost
    (issue 28: advice.csv had no us_per_sim_s for adaptive methods)."""
    family = Family(CASE, "reference", "quaternion", "scipy_rk45")
    row = advice.advice_row(family, 1e-6, "tolerance", setting=1e-8, error=5e-7)
    point = {**family.columns, "tolerance": 1e-8, "status": "ok", "attitude_err": 5e-7}
    monkeypatch.setattr(advice, "advise_family", lambda *a: ([dict(row)], [dict(point)]))

    def time_points(points, families, setting="dt", pool=None):  # the one timing phase, at the points' tolerances here
        assert setting == "tolerance"
        for p in points:
            p["us_per_sim_s"] = 321.0
    monkeypatch.setattr(dt_ladders, "time_points", time_points)
    table = advice.run_advice([(family, True, [], 1.0)], (1e-6,), MAX_STEPS)
    assert table["us_per_sim_s"].tolist() == [321.0] and table["tolerance"].tolist() == [1e-8]


def test_a_family_without_a_fitted_order_gets_no_advice_and_says_why(monkeypatch):
    monkeypatch.setattr(dt_ladders, "measure", lambda family, dt, timed=True: {"dt": dt, "status": "ok"})
    monkeypatch.setattr(dt_ladders, "run_short_ladder",
                        lambda family, known, max_steps: ([], {"order": math.nan, "note": "no run ok"}))
    table, why = advice.advise(CASE, [(FAMILY, False)], (1e-6,), MAX_STEPS)
    assert table.empty and why == {FAMILY.key: "no run ok"}


def test_advice_tasks_take_the_families_with_a_fitted_order_only():
    columns = {"case": CASE.name, "engine": "mujoco", "formulation": "", "precision": "float64"}
    convergence = pd.DataFrame([{**columns, "integrator": "rk4", "order": 4.0},
                                {**columns, "integrator": "euler", "order": math.nan}])
    empty = pd.DataFrame(columns=["case", "engine", "formulation", "integrator", "precision", "dt", "steps", "status",
                                  "state_err", "attitude_err", "us_per_sim_s", "tolerance", "slope"])
    tasks = advice.advice_tasks([FAMILY, Family(CASE, "mujoco", "", "euler")], [], empty, empty, empty, convergence,
                                empty)
    assert [(t[0].integrator, t[3]) for t in tasks] == [("rk4", 4.0)]


def test_advise_leaves_out_integrators_without_an_order_or_error_control_and_runs_it_cannot_do(monkeypatch):
    declared = step_advice.declared_order
    monkeypatch.setattr(step_advice, "declared_order", lambda e, i: math.nan if i == "implicit" else declared(e, i))
    chosen = [f.integrator for f, _ in advice.families_to_advise(CASE, "mujoco", None)]
    assert "implicit" not in chosen and "rk4" in chosen
    model = type(rigid_body(get_engine("mujoco")))  # the rigid body's model class: its runs the advice checks
    monkeypatch.setattr(model, "unsupported_run", lambda self, case, formulation, integrator:
                        "not here" if integrator == "rk4" else None)
    assert "rk4" not in [f.integrator for f, _ in advice.families_to_advise(CASE, "mujoco", ["rk4", "euler"])]


# ------------------------------------------------------------------------------------------- the search itself

def test_points_below_the_step_cap_are_never_advised():
    """A known point finer than the cap (lo) that reaches the target is no advice: the target is beyond the cap
    (issue 28: advice's bracket took known steps below the step cap)."""
    known = {1e-4: 1e-12}
    result = search(lambda dt: dt, 1e-9, 1e-9, lo=1e-3, hi=1.0, known=known, cap="t_end / 1000")
    assert math.isnan(result.setting) and result.note.startswith("beyond the step cap")


def test_a_model_just_below_the_cap_checks_the_cap_and_says_what_the_model_needs():
    calls = []

    def error_at(dt):
        calls.append(dt)
        return dt

    result = search(error_at, 1e-4, 5e-4, lo=1e-3, hi=1.0)
    assert calls == [1e-3] and "the model needs dt = 0.0005, below 0.001" in result.note


def test_below_the_floor_names_the_smallest_error_reached():
    errors = {}

    def error_at(dt):
        errors[dt] = 1e2 * dt ** 4 + 3e-6
        return errors[dt]

    result = search(error_at, 1e-6, 1e-2, lo=1e-6, hi=1.0)
    assert result.note.startswith("below the method's floor") and len(errors) >= 2
    assert result.error_fails == min(errors.values()) and f"at {min(errors.values()):.3g}" in result.note


def test_an_adaptive_target_beyond_the_tightest_tolerance_says_so():
    result = search(lambda tol: 10 * tol, 1e-14, 1e-15, lo=1e-13, hi=1e-3, what="tolerance")
    assert result.note.startswith("beyond the tightest tolerance")


def test_an_advised_setting_has_four_significant_digits():
    assert rounded(1 / 3) == 0.3333 and rounded(0.0123456) == 0.01235


def test_an_exact_point_does_not_zero_the_error_model():
    dts = np.array([0.02, 0.01, 0.005, 0.0025])
    points = pd.DataFrame({"dt": dts, "steps": 2.0 / dts, "status": "ok", "state_err": 3.0 * dts ** 2,
                           "attitude_err": [1.2e-3, 3e-4, 7.5e-5, 0.0]})
    model = error_model(points, 2.0)
    assert model.points == 3 and model.coefficient == pytest.approx(3.0)
