"""Step-size advice (issue 21 item 2): the error model and the checked search (harness.analysis.step_advice) on known error
functions, then `stereodyn advise` on a case file outside the suite (MuJoCo rk4, 1e-6 rad)."""
from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from stereodyn.harness.analysis import step_advice
from stereodyn.harness.analysis.step_advice import CHECK_RATIO, error_model, search


def _law(c: float, p: float, floor: float = 0.0, unstable_above: float = math.inf):
    calls = []

    def error_at(dt: float) -> float:
        calls.append(dt)
        return math.nan if dt > unstable_above else c * dt ** p + floor
    return error_at, calls


@pytest.mark.parametrize("misjudged", [1.0, 0.1, 10.0, 0.7])
def test_the_search_brackets_the_target_within_the_ratio_however_good_the_estimate(misjudged):
    error_at, calls = _law(2e3, 4.0)
    exact = (1e-6 / 2e3) ** 0.25
    advice = search(error_at, 1e-6, exact * misjudged, lo=1e-5, hi=1.0)
    assert advice.note == "" and advice.error <= 1e-6 and advice.error == error_at(advice.setting)
    assert advice.fails_at <= advice.setting * CHECK_RATIO * (1 + 1e-9) and error_at(advice.fails_at) > 1e-6
    assert advice.setting <= exact < advice.fails_at
    assert advice.runs == len(set(calls[:-2])) and advice.runs <= step_advice.MAX_CHECK_RUNS
    if misjudged == 1.0:
        assert advice.runs == 2  # just inside the estimate, then one ratio step across it


def test_known_points_are_reused_and_an_unstable_step_counts_as_not_reaching():
    error_at, calls = _law(1.0, 1.0, unstable_above=0.05)
    known = {0.1: math.nan, 0.01: 0.01, 0.001: 0.001}
    advice = search(error_at, 3e-3, math.nan, lo=1e-4, hi=0.5, known=known)
    assert 2.4e-3 <= advice.setting <= 3e-3 and advice.error <= 3e-3 and advice.fails_at / advice.setting <= 1.25
    assert all(1e-3 < dt < 1e-2 for dt in calls)  # only inside the known bracket
    assert set(known) >= set(calls)  # the runs join the shared points


@pytest.mark.parametrize("floor, target", [(2e-12, 1e-13),   # float64 round-off
                                           (3e-6, 1e-6)])     # a float32 engine's precision
def test_a_target_below_the_methods_floor_says_so(floor, target):
    error_at, _ = _law(1e2, 4.0, floor=floor)
    advice = search(error_at, target, (target / 1e2) ** 0.25, lo=1e-6, hi=1.0)
    assert math.isnan(advice.setting) and advice.note.startswith("below the method's floor"), advice
    assert advice.runs <= step_advice.MAX_CHECK_RUNS


def test_a_saturated_error_is_no_floor():
    """A chaotic case's error saturates near pi above the asymptotic range: not falling there is no floor."""
    advice = search(lambda dt: 3.0, 1e-6, 1e-2, lo=1e-3, hi=1.0)
    assert math.isnan(advice.setting) and advice.note.startswith("beyond the step cap: not reached"), advice


def test_a_target_beyond_the_step_cap_says_so_after_checking_the_cap():
    error_at, calls = _law(1.0, 1.0)
    advice = search(error_at, 1e-9, 1e-9, lo=1e-5, hi=1.0, cap="t_end / 40000")
    assert math.isnan(advice.setting) and advice.note.startswith("beyond the step cap") and "t_end / 40000" in advice.note
    assert calls == [1e-5] and advice.error_fails == pytest.approx(1e-5)
    # a wrong model (the law is steeper than it says: dt = 3.2e-5 reaches 1e-9) is found out at the cap, and the
    # search goes on
    error_at, _ = _law(1.0, 2.0)
    advice = search(error_at, 1e-9, 1e-9, lo=1e-5, hi=1.0)
    assert advice.note == "" and advice.error <= 1e-9 and advice.fails_at / advice.setting <= 1.25


def test_a_target_reached_at_the_largest_step_says_so():
    error_at, _ = _law(1e-9, 1.0)
    advice = search(error_at, 1e-3, 1e6, lo=1e-5, hi=0.5)
    assert advice.setting == 0.5 and advice.note == "reached at the largest dt tried (0.5)"


def test_the_error_model_is_c_dt_p_on_the_asymptotic_points():
    dts = np.array([0.1, 0.05, 0.025, 0.0125, 1e-4])
    state = 3.0 * dts ** 2
    points = pd.DataFrame({"dt": dts, "steps": 10.0 / dts, "status": "ok", "state_err": state,
                           "attitude_err": 0.5 * state})
    model = error_model(points, 2.0)
    # 0.1 gives 3e-2 (rounded just above the range's top edge: left out); 1e-4 gives 3e-8, above 30 eps steps
    # (6.7e-10): asymptotic
    assert model.coefficient == pytest.approx(1.5) and model.points == 4
    assert model.setting_for(1.5e-6) == pytest.approx(1e-3)
    assert error_model(points, math.nan) is None


# ------------------------------------------------------------------------------------------------ stereodyn advise

CASE_OUTSIDE_THE_SUITE = """\
name = "advice-top"
description = "a heavy asymmetric body with its centre of mass off every axis: in no suite"
[body]
mass = 2.0
com = [0.05, 0.02, 0.1]
principal_moments = [0.9, 0.7, 0.4]
[gravity]
g = 9.81
[initial]
attitude = { euler_zxz = [0.2, 0.6, -0.3] }
omega = [1.5, -0.8, 3.0]
[run]
t_end = 4.0
dt = [1e-2, 5e-3]
samples = 400
"""


def test_advise_on_a_case_outside_the_suite_gives_a_dt_that_reaches_the_target_and_2_5x_that_does_not(
        tmp_path, capsys):
    """Issue 21's acceptance: MuJoCo rk4, 1e-6 rad. The advised dt, run again by itself through `stereodyn run` (the
    sweep's path, not the ladder's), reaches the target, and 2.5 x that dt does not: the advice is neither wrong nor
    needlessly small. Measured by hand (2026-11-25): dt = 0.02 s, 9.46e-7 rad; 0.05 s: 3.99e-5 rad."""
    import re

    from stereodyn.harness.cli import main

    case = tmp_path / "advice-top.toml"
    case.write_text(CASE_OUTSIDE_THE_SUITE)
    assert main(["advise", str(case), "--engine", "mujoco", "--integrator", "rk4", "--target", "1e-6"]) == 0
    out = capsys.readouterr().out
    found = re.findall(r"dt = ([0-9.e+-]+) s \(error", out)
    assert len(found) == 1, out
    dt = float(found[0])
    assert main(["run", "--case-file", str(case), "--engines", "mujoco", "--integrators", "rk4", "--dt",
                 f"{dt!r},{2.5 * dt!r}", "--out", str(tmp_path / "out"), "--quiet", "--no-certify"]) == 0
    rows = pd.read_csv(tmp_path / "out" / "results.csv").set_index("dt")
    assert rows.loc[dt, "status"] == "ok" and rows.loc[dt, "attitude_err"] <= 1e-6, out
    assert not rows.loc[2.5 * dt, "attitude_err"] <= 1e-6, out


@pytest.mark.parametrize("argv, words", [
    (["--engine", "nope"], "--engine: unknown engine nope"),
    (["--engine", "mujoco", "--integrator", "rk5"], "--integrator: unknown for mujoco: rk5"),
    (["--engine", "mujoco", "--target", "2"], "must be in (0, 1) rad"),
])
def test_advise_refuses_bad_input_in_one_line(argv, words, capsys):
    from stereodyn.harness.cli import main

    assert main(["advise", "free-asymmetric", *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and words in err, err


def test_the_default_run_writes_checked_advice_and_the_report_shows_it_per_engine(tmp_path):
    """The default ladders' families get advice.csv rows at 1e-3 and 1e-6 rad, each checked: the dt reaches the
    target, the checked dt above it (at most 1.25x) does not, and the advised run is timed."""
    from stereodyn.harness.analysis import workprecision
    from stereodyn.harness.pipeline import work_precision
    from stereodyn.harness.report.workprecision import report_lines
    from stereodyn.harness.run.sweep import SweepOptions, run_sweep
    from stereodyn.harness.scenes.cases import find_case, with_overrides

    case = with_overrides(find_case("free-asymmetric"), t_end=2.0, dt=[2e-2, 1e-2])
    df = run_sweep([case], SweepOptions(["mujoco"], tmp_path, ["rk4"], jobs=1, certify=False))
    work_precision.analyse(tmp_path, df, [case], ["mujoco"], ["rk4"], ladder="default", max_steps=2000)
    advice = pd.read_csv(tmp_path / workprecision.ADVICE_FILE, keep_default_na=False, na_values=[""])
    assert tuple(advice.columns) == step_advice.ADVICE_COLUMNS
    assert list(advice["target"]) == list(workprecision.DEFAULT_ADVICE_TARGETS)
    assert (advice["integrator"] == "rk4").all() and advice["dt"].notna().all(), advice.to_string()
    assert (advice["error_checked"] <= advice["target"]).all()
    # 1e-3 over 2 s: rk4 reaches it at dt = t_end / 20, the largest step tried (measured 2.7e-6 rad), and says so
    assert advice["note"].iloc[0] == "reached at the largest dt tried (0.1)" and advice["dt"].iloc[0] == 0.1
    bracketed = advice.iloc[1:]
    assert (bracketed["error_fails"] > bracketed["target"]).all() and bracketed["note"].isna().all()
    assert (bracketed["fails_at"] <= bracketed["dt"] * CHECK_RATIO * (1 + 1e-9)).all()
    assert (advice["us_per_sim_s"] > 0).all() and (advice["order"] - 4.0).abs().max() < 0.3
    text = "\n".join(report_lines(tmp_path))
    section = text.split("## Step-size advice")[1].split("\n## ")[0]
    assert "### mujoco: step sizes" in section and f"| dt = {advice['dt'].iloc[1]:.4g} |" in section


def test_a_missed_target_prints_with_the_digits_that_show_it_missed():
    from stereodyn.harness.cli.advise import _above

    assert _above(1.00386e-06, 1e-6) == "1.00386e-06" and _above(2.34e-06, 1e-6) == "2.34e-06"


@pytest.mark.parametrize("estimate", [1e-9, math.nan])  # the model says below the cap; no model
def test_a_known_point_below_the_step_cap_is_never_advised(estimate):
    """Advice never names a dt below the step cap, even one a ladder already ran and found reaching the target: a
    target the cap does not reach reads "beyond the step cap". Break-check: bracketing on every known point (no
    `lo <= s <= hi` filter) advises dt = 1e-6, below the cap 1e-4, with no note."""
    error_at, calls = _law(1.0, 1.0)  # error = dt: 1e-9 needs dt = 1e-9
    known = {1e-6: 1e-6 * 1e-4, 1e-2: 1e-2}  # a point below the cap, made to reach the target (a ladder's luck)
    advice = search(error_at, 1e-8, estimate, lo=1e-4, hi=1.0, known=known, cap="t_end / 40000")
    assert math.isnan(advice.setting) and advice.note.startswith("beyond the step cap"), advice
    assert "t_end / 40000" in advice.note and all(dt >= 1e-4 for dt in calls), (advice, calls)


def test_advise_takes_the_budgets_its_failed_runs_name(monkeypatch, capsys):
    """Issue 46's fifth attack, finding 4: a hung plug-in's advice said "run budget exceeded ... (--run-budget raises
    it)", and `advise --run-budget 5` was refused (unrecognized arguments). advise takes each budget option a
    failed run names (harness.budget.FLAGS), and its runs are held to it (here and, passed on, in the workers).
    Break-checked: without budget_options in advise's parser the command exits 2."""
    from stereodyn.harness import budget
    from stereodyn.harness.cli import main
    from stereodyn.harness.pipeline import advice

    seen = []

    def answer(case, families, targets, max_steps, say, pool):
        seen.append(budget.configured())
        return pd.DataFrame(columns=list(advice.ADVICE_COLUMNS)), {}

    monkeypatch.setattr(advice, "advise", answer)
    argv = ["advise", "free-asymmetric", "--engine", "mujoco", "--integrator", "rk4", "--t-end", "1"]
    flags = [budget.FLAGS[what] for what in ("run", "prepare", "truth")]
    try:
        assert main([*argv, flags[0], "5", flags[1], "7", flags[2], "9"]) == 0, capsys.readouterr().err
        assert (seen[0].run_s, seen[0].prepare_s, seen[0].truth_s) == (5.0, 7.0, 9.0)
    finally:
        budget.configure(budget.Budgets())
