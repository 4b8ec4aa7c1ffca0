"""Order verdicts that weigh their evidence (issue 30, item 5): how many asymptotic points and cases a verdict rests
on; a miss found on too little evidence is "not enough evidence", not a failure, unless a fit is a whole order off;
`run --strict` measures such a claim first (a short ladder, with --no-ladder too), then judges. And the "not
measured" reasons tell skipped runs from failed ones (item 4)."""
import math

import pandas as pd
import pytest

from stereodyn.harness import cli
from stereodyn.harness.analysis import verdicts, workprecision
from stereodyn.harness.pipeline import dt_ladders


def _convergence(rows) -> pd.DataFrame:
    """convergence.csv rows of one claim (mujoco rk4, declared 4): (case, order, points, note)."""
    return pd.DataFrame([dict(case=case, engine="mujoco", formulation="", integrator="rk4", precision="float64",
                              order=order, declared_order=4.0, points=points, source="dt_list", note=note)
                         for case, order, points, note in rows])


def _verdict(rows) -> verdicts.Verdict:
    (verdict,) = verdicts.order_verdicts(_convergence(rows))
    return verdict


def test_a_miss_on_one_pre_asymptotic_pair_is_not_enough_evidence():
    """Issue 30's user body: MuJoCo's rk4 at advise's dt and 2.5 times it fitted 3.40 on one case."""
    verdict = _verdict([("mybody", 3.40, 2, "")])
    assert verdict.status == verdicts.NOT_ENOUGH
    assert "fitted 3.40 on 1 case from 2 asymptotic points" in verdict.detail
    assert f"fewer than {verdicts.MIN_POINTS} asymptotic points" in verdict.detail and "--strict" in verdict.rule
    assert verdicts.failed_integrators([verdict]) == set()  # "What to use" still recommends its runs
    assert verdicts.strict_failures([verdict]) == [verdict]  # --strict fails it if measuring more did not help
    assert verdicts.summary_lines([verdict])[1].startswith("verdict not enough evidence: integrator mujoco rk4")


@pytest.mark.parametrize("rows, why", [
    ([("mybody", 2.0, 2, "")], "a whole order off fails on any evidence: Heun declared 4"),
    ([("mybody", 3.40, 3, "")], "three asymptotic points on one case are enough"),
    ([("a", 3.5, 2, ""), ("b", 3.6, 2, ""), ("c", 3.4, 2, "")], "three cases are enough"),
])
def test_enough_evidence_or_a_gross_miss_still_fails(rows, why):
    verdict = _verdict(rows)
    assert verdict.status == verdicts.FAIL, why
    assert f"from {sum(r[2] for r in rows)} asymptotic points (at most {max(r[2] for r in rows)} on a case)" \
        in verdict.detail


def test_a_pass_states_its_evidence_and_old_tables_without_points_judge_as_before():
    assert _verdict([("mybody", 3.95, 2, "")]).status == verdicts.PASS
    old = _convergence([("mybody", 3.40, 2, "")]).drop(columns="points")  # a convergence.csv of 0.2.0
    (verdict,) = verdicts.order_verdicts(old)
    assert verdict.status == verdicts.FAIL and "asymptotic points" not in verdict.detail


def test_weak_claims_are_those_a_strict_run_measures_more_passed_or_missed():
    def row(case, integrator, order, points):
        return dict(case=case, engine="pinocchio", formulation="", integrator=integrator, precision="float64",
                    order=order, declared_order=4.0, points=points, stable_dt_max=math.nan, source="dt_list", note="")

    rows = [row("a", "weak_miss", 3.5, 2), row("b", "weak_miss", 3.6, 2), row("chaos", "weak_miss", 4.0, 5),
            row("a", "weak_pass", 3.95, 2),  # a pre-asymptotic pair can fit the declared order by chance too
            row("a", "gross", 2.0, 2),  # failed on any evidence; --strict measures it too, and it still fails
            row("a", "strong_miss", 3.5, 3), row("a", "unfitted", math.nan, 1)]  # judged as they are
    assert workprecision.weak_claims(rows, {"chaos"}) == {("pinocchio", "", name)
                                                          for name in ("weak_miss", "weak_pass", "gross")}


@pytest.mark.parametrize("note, reason", [
    ("0 point(s) in the asymptotic range (...): no run ok: skipped", "every run skipped"),
    ("0 point(s) in the asymptotic range (...): no run ok: failed, skipped", "no run finished ok (failed, skipped)"),
    ("0 point(s) in the asymptotic range (...): no run ok: diverged", "no run finished ok (diverged)"),
])
def test_not_measured_reasons_tell_skipped_from_failed(note, reason):
    (verdict,) = verdicts.order_verdicts(_convergence([("mybody", math.nan, 0, note)]))
    assert verdict.status == verdicts.UNMEASURED
    assert f"mybody {reason}" in verdict.detail


BODY = """
description = "a heavy top of a user's own, outside the suite"
[body]
mass = 0.8
com = [0.02, 0.0, 0.15]
principal_moments = [1.2, 1.0, 0.5]
[gravity]
g = 9.81
[initial]
attitude = { euler_zxz = [0.0, 0.4, 0.0] }
omega = [0.2, 0.1, 8.0]
[run]
t_end = 5.0
dt = [1e-2]
samples = 500
"""
# `stereodyn advise F --engine mujoco --integrator rk4 --target 1e-6` on BODY: dt = 0.01186 s (error 6.4e-7)
ADVISED = 0.01186


def test_the_acceptance_pair_on_a_users_body_passes_under_strict_no_ladder(tmp_path):
    """Issue 30's acceptance command on a body outside the suite: --dt D,2.5D --no-ladder --strict measures first
    (two points on one case are too few to judge, even where they fit: measured 4.00 on the pair) with a short
    ladder, then judges: MuJoCo's rk4 passes, exit 0 (measured 3.97 on 3 points, 2026-11-26). Without --strict the
    pair is judged as it is (the plain run of the slow test below)."""
    case = tmp_path / "mybody.toml"
    case.write_text(BODY)
    out = tmp_path / "out"
    assert cli.main(["run", "--case-file", str(case), "--engines", "mujoco", "--integrators", "rk4", "--dt",
                     f"{ADVISED},{2.5 * ADVISED:.5g}", "--no-ladder", "--strict", "--no-certify", "--jobs", "1",
                     "--quiet", "--out", str(out)]) == 0
    table = pd.read_csv(out / "verdicts.csv", keep_default_na=False)
    order = table[table.verdict == "order"]
    assert list(order.status) == [verdicts.PASS]
    assert "on 1 case from 3 asymptotic points" in order.detail.iloc[0], order.detail.iloc[0]
    convergence = pd.read_csv(out / "convergence.csv", keep_default_na=False)
    assert list(convergence.source) == [dt_ladders.SHORT_LADDER]


# slow: two sweeps of the reference's four formulations, ~25 s of CPU (2-core machine, load ~3)
@pytest.mark.slow
def test_strict_measures_a_miss_on_two_points_first_then_judges(tmp_path, capsys):
    """The reference's gibbs rk4 on lagrange-top over 2 s at dt 1e-2, 3e-3 fits 3.41 on its two points (19 chart
    changes). Without --strict: not enough evidence, exit 0, its runs still recommended. With --strict --no-ladder:
    every formulation's pair is too little evidence, so each gets a short ladder, and the three points judge gibbs:
    measured 3.48, a failure now resting on evidence."""
    def run(out, *extra):
        return cli.main(["run", "lagrange-top", "--engines", "reference", "--integrators", "rk4", "--t-end", "2",
                         "--dt", "1e-2,3e-3", "--no-ladder", "--no-certify", "--jobs", "1", "--quiet", "--out",
                         str(out), *extra])

    assert run(tmp_path / "plain") == 0
    table = pd.read_csv(tmp_path / "plain" / "verdicts.csv", keep_default_na=False)
    gibbs = table[(table.verdict == "order") & (table.formulation == "gibbs")]
    assert list(gibbs.status) == [verdicts.NOT_ENOUGH], gibbs.detail.tolist()
    pareto = pd.read_csv(tmp_path / "plain" / "pareto.csv", keep_default_na=False)
    assert "only runs that failed a verdict" not in set(pareto.source)
    assert run(tmp_path / "strict", "--strict") == 1
    convergence = pd.read_csv(tmp_path / "strict" / "convergence.csv", keep_default_na=False)
    measured = convergence[convergence.source == dt_ladders.SHORT_LADDER].set_index("formulation")
    assert "gibbs" in measured.index and measured.loc["gibbs", "points"] == 3, measured
    line = next(x for x in capsys.readouterr().err.splitlines() if x.startswith("verdict failed:"))
    assert "reference gibbs rk4 declares order 4" in line and "from 3 asymptotic points" in line, line


# ------------------------------------------------------------------------------------------------ issue 45

def _ladder(slopes, dt0=0.0372, err0=1e-4, t_end=10.0) -> pd.DataFrame:
    """Points halving from dt0 whose local slopes, coarse to fine, are `slopes`."""
    import numpy as np

    dts = dt0 / 2.0 ** np.arange(len(slopes) + 1)
    err = err0 * np.exp(np.cumsum([0.0] + [s * math.log(0.5) for s in slopes]))
    return pd.DataFrame({"dt": dts, "steps": np.round(t_end / dts), "status": "ok", "state_err": err})


def _row(points, declared, integrator="rk4") -> dict:
    from stereodyn.harness.analysis import fitting

    return {"case": "usertop", "engine": "mujoco", "formulation": "", "integrator": integrator,
            "precision": "float64", "stable_dt_max": math.nan, "source": "dt_list", **fitting.fit(points, declared)}


def test_the_order_is_judged_on_the_finest_run_of_agreeing_slopes():
    """Issue 45's user top: MuJoCo's rk4 from 0.0372 to 0.00116, local slopes 3.67 3.31 3.75 3.89 3.94. One line
    through all six fitted 3.70 and failed; the finest three agree (spread 0.05 <= AGREE) and judge 3.92: pass,
    the evidence in the note and the verdict."""
    row = _row(_ladder([3.67, 3.31, 3.75, 3.89, 3.94]), 4.0)
    assert row["points"] == 3 and abs(row["order"] - 3.915) < 1e-6, row  # the mean of the finest slopes, 3.89 and 3.94
    # 3.915 to 3 digits reads 3.91 or 3.92 by its last bit (3.92 here, 3.91 on another machine: CI of stop 52)
    assert (f"slopes 3.67 3.31 3.75 3.89 3.94; judged on dt 0.00465 to 0.00116: {row['order']:.3g}"
            in row["note"]), row["note"]
    (verdict,) = verdicts.order_verdicts(pd.DataFrame([row]))
    assert verdict.status == verdicts.PASS and "usertop: slopes 3.67 3.31 3.75 3.89 3.94" in verdict.detail
    # falling toward 4 from above (issue 45's random body: 4.62 4.46 4.28 4.15 4.08): judged 4.15 4.08
    row = _row(_ladder([4.62, 4.46, 4.28, 4.15, 4.08], err0=1e-3), 4.0)
    assert row["points"] == 3 and abs(row["order"] - 4.11) < 0.01 and "judged on dt 0.00465 to 0.00116" in row["note"]


def test_slopes_still_moving_toward_the_declared_order_are_not_yet_asymptotic_never_failed():
    row = _row(_ladder([2.6, 3.0, 3.4]), 4.0)
    assert row["points"] == 2 and "not yet asymptotic" in row["note"], row
    (verdict,) = verdicts.order_verdicts(pd.DataFrame([row]))
    assert verdict.status == verdicts.NOT_ASYMPTOTIC and "slopes 2.60 3.00 3.40" in verdict.detail, verdict
    assert verdicts.failed_integrators([verdict]) == set() and verdicts.strict_failures([verdict]) == [verdict]
    assert verdicts.weak_evidence(pd.DataFrame([row])) == {("mujoco", "", "rk4")}  # --strict measures finer
    # moving away from it is no excuse: a settled miss fails
    assert "not yet asymptotic" not in _row(_ladder([3.4, 3.0, 2.6]), 4.0)["note"]


@pytest.mark.parametrize("slopes, declared", [([2.0, 2.0, 2.01, 2.0], 4.0),   # Heun or rk4_naive declared 4
                                              ([4.0, 4.01, 4.0, 4.0], 5.0),   # rk4 declared 5
                                              ([1.5, 1.8, 2.0, 2.0], 4.0)])   # settled at 2 after a drift
def test_a_false_claim_fails_once_its_slopes_settle(slopes, declared):
    (verdict,) = verdicts.order_verdicts(pd.DataFrame([_row(_ladder(slopes, err0=1e-3), declared)]))
    assert verdict.status == verdicts.FAIL, verdict


def test_a_short_ladder_measures_finer_never_coarser():
    """Issue 45: at advise's dt and 2.5x it (0.0117, 0.0293 on the user top, one slope 4.41) --strict's short ladder
    added 0.0372, coarser than both. Now it halves from the finest until the judged range settles (3 points)."""
    from stereodyn.harness.analysis.ladders import short_ladder
    from stereodyn.harness.run.spec import Family
    from stereodyn.harness.scenes.cases import find_case, with_overrides

    case = with_overrides(find_case("heavy-asymmetric"), t_end=10.0, dt=[0.0293, 0.0117])

    def point(dt):  # rk4 with a pre-asymptotic term: slopes fall toward 4 as dt halves
        return {"dt": dt, "steps": round(10.0 / dt), "status": "ok", "state_err": 50.0 * dt ** 4 * (1 + 40 * dt)}

    tried = []
    new, row = short_ladder(Family(case, "mujoco", "", "rk4"), [point(0.0293), point(0.0117)], 40_000, 4.0,
                            lambda dt: tried.append(dt) or point(dt))
    assert tried and max(tried) < 0.0117, tried
    assert row["points"] >= 3 and "the slopes settled" in row["note"], row["note"]
