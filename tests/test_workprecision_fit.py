"""The work–precision infrastructure on synthetic data, where the answers are known: the order fitter and the round-off
floor on errors C dt^p + floor, the stability bisection on a fake run that diverges above a known dt, and the Pareto
table (the cheapest run reaching each accuracy target)."""
import math

import numpy as np
import pandas as pd
import pytest

from stereodyn.harness.pipeline import dt_ladders
from stereodyn.harness.analysis import fitting
from stereodyn.harness.scenes.cases import find_case, with_overrides
from stereodyn.harness.pipeline.dt_ladders import Family, stability_limit
from stereodyn.harness.analysis.fitting import fit, order_slope, pareto

T_END = 10.0


def points(p: float, c: float, floor: float, dts=None) -> pd.DataFrame:
    """Ladder points with state_err = c dt^p + floor over T_END."""
    dts = np.geomspace(0.1, 1e-4, 16) if dts is None else np.asarray(dts)
    return pd.DataFrame({"dt": dts, "steps": np.ceil(T_END / dts), "status": "ok", "state_err": c * dts ** p + floor})


def test_order_slope_is_the_slope_of_log_error_against_log_dt():
    dts = np.array([0.1, 0.05, 0.025, 0.0125])
    assert order_slope(dts, 3.0 * dts ** 4) == pytest.approx(4.0, abs=1e-12)
    assert order_slope(dts, 0.2 * dts) == pytest.approx(1.0, abs=1e-12)
    # regressing log dt on log error instead would give 1/4 here: the error is the dependent variable
    assert order_slope(dts, dts ** 4) != pytest.approx(0.25, abs=0.1)


# Floors of the size rounding gives (the suite's measured floors: 2e-14 to 5e-12 rad); a second-order method needs
# steps down to 1e-7 to reach one.
@pytest.mark.parametrize("p, c, floor, bottom", [(4, 1.0, 1e-12, 1e-4), (2, 0.3, 1e-13, 1e-7), (1, 0.5, 1e-14, 1e-4)])
def test_fit_recovers_the_order_and_the_round_off_floor(p, c, floor, bottom):
    result = fit(points(p, c, floor, np.geomspace(0.1, bottom, 16)), declared=float(p))
    # the points fitted lie >= 30 eps steps above the floor's share, so the floor bends the slope by < 0.03
    # (ROUNDOFF_MARGIN's comment); measured here: |order - p| <= 4.1e-3 (rk4)
    assert result["order"] == pytest.approx(p, abs=0.03)
    assert result["points"] >= 2 and result["declared_order"] == p
    if p >= 2:  # rk4 and a 2nd-order method reach the floor within the ladder: it is found, and its level
        assert result["floor_err"] == pytest.approx(floor, rel=0.5)
        assert c * result["floor_dt"] ** p < 10 * floor  # the floor starts where the truncation error meets it
    else:  # Euler never gets there above dt = 1e-4: no floor, and the note says so
        assert math.isnan(result["floor_dt"]) and "no round-off floor" in result["note"]


def test_fit_leaves_out_pre_asymptotic_and_failed_points():
    df = points(4, 1.0, 1e-12)
    big = pd.DataFrame({"dt": [1.0, 0.5], "steps": [10, 20], "status": "ok", "state_err": [2.0, 0.9]})
    failed = pd.DataFrame({"dt": [0.2], "steps": [50], "status": "diverged", "state_err": [1e-30]})
    result = fit(pd.concat([big, failed, df], ignore_index=True), declared=4.0)
    assert result["order"] == pytest.approx(4.0, abs=0.03)


def test_fit_with_fewer_than_two_asymptotic_points_has_no_order():
    result = fit(points(4, 1.0, 1e-12, dts=[0.3, 1e-4]), declared=4.0)
    assert math.isnan(result["order"]) and "point(s) in the asymptotic range" in result["note"]


# ------------------------------------------------------------------------------------------------ stability

DT_CRIT = 0.0123


@pytest.mark.parametrize("start", [1e-3, 0.0123, 0.05, 0.4])
def test_stability_bisection_finds_the_known_limit(start):
    calls = []

    def is_stable(dt):
        calls.append(dt)
        return dt <= DT_CRIT

    stable, note = stability_limit(is_stable, start, dt_cap=0.5, dt_floor=1e-5)
    assert note == ""
    assert DT_CRIT / (1 + dt_ladders.STABILITY_RTOL) <= stable <= DT_CRIT
    assert len(calls) < 20  # doubling/halving, then bisection: logarithmic, not a scan


def test_stability_bisection_says_when_no_limit_is_in_range():
    stable, note = stability_limit(lambda dt: True, 0.01, dt_cap=0.1, dt_floor=1e-5)
    assert math.isnan(stable) and note.startswith("stable up to dt = 0.08")
    stable, note = stability_limit(lambda dt: False, 0.01, dt_cap=0.1, dt_floor=1e-5)
    assert math.isnan(stable) and note.startswith("unstable down to")


def test_a_ladder_of_a_fake_run_that_diverges_above_a_known_dt(monkeypatch):
    """run_ladder end to end on a fake run: ok with error dt^4 below DT_CRIT, diverged above, blown energy just below
    it (a run can finish and still be unstable)."""
    case = with_overrides(find_case("free-asymmetric"), t_end=T_END, dt=[0.01])

    def fake_measure(family, dt, timed=True, with_truth=True):
        steps = math.ceil(T_END / dt - 1e-9)
        row = {"case": case.name, "engine": family.engine, "formulation": family.formulation,
               "integrator": family.integrator, "dt": dt, "t_end": T_END, "steps": steps}
        if dt > DT_CRIT:
            return {**row, "status": "diverged", "energy_drift": math.nan, "state_err": math.nan}
        drift = 5.0 if dt > 0.98 * DT_CRIT else 1e-6
        return {**row, "status": "ok", "energy_drift": drift, "state_err": dt ** 4 + 1e-13,
                "us_per_sim_s": 1e6 / dt}

    monkeypatch.setattr(dt_ladders, "measure", fake_measure)
    family = Family(case, "reference", "quaternion", "rk4")
    points_, row = dt_ladders.run_ladder(family, max_steps=100_000)
    limit = 0.98 * DT_CRIT  # the largest dt that is ok and keeps its energy
    assert limit / (1 + dt_ladders.STABILITY_RTOL) <= row["stable_dt_max"] <= limit
    assert len(points_) == dt_ladders.LADDER_POINTS and max(p["dt"] for p in points_) <= limit
    assert row["declared_order"] == 4.0 and row["order"] == pytest.approx(4.0, abs=0.03)


# ------------------------------------------------------------------------------------------------ Pareto

def test_pareto_picks_the_cheapest_run_reaching_each_target():
    def sweep_row(integrator, dt, err, wall_s, status="ok"):
        return {"case": "c", "engine": "e", "formulation": "", "integrator": integrator, "dt": dt,
                "attitude_err": err, "wall_s": wall_s, "us_per_step_spread": 0.0, "t_end": 2.0, "steps": 2.0 / dt,
                "status": status}

    results = pd.DataFrame([
        sweep_row("a", 0.1, 9e-4, 2e-5),      # 10 µs per simulated s
        sweep_row("b", 0.01, 9e-7, 1e-4),     # 50
        sweep_row("d", 0.001, 9e-10, 2e-4),   # 100
        sweep_row("x", 0.05, 1e-14, 2e-6),    # failed: cheapest and most accurate, never chosen
        sweep_row("x", 0.05, 1e-14, 2e-6, status="failed"),
        # the truth (adaptive, dt NaN) has no error of its own: no contender (adaptive runs that have one are:
        # tests/test_tolerance_ladders.py)
        sweep_row("t", math.nan, math.nan, 1e-6),
    ]).drop(index=3)
    ladder = pd.DataFrame([{"case": "c", "engine": "e", "formulation": "", "integrator": "c", "dt": 0.02,
                            "attitude_err": 8e-7, "us_per_sim_s": 30.0, "us_per_sim_s_spread": 0.0, "steps": 100,
                            "status": "ok"}])
    table = pareto(results, ladder)
    assert list(dict.fromkeys(table["scope"])) == ["any", "e"]
    table = table[table["scope"] == "any"].set_index("target")
    expected = {1e-2: "a", 1e-3: "a", 1e-4: "c", 1e-5: "c", 1e-6: "c", 1e-7: "d", 1e-8: "d", 1e-9: "d"}
    for target, integrator in expected.items():
        assert table.loc[target, "integrator"] == integrator, target
    assert table.loc[1e-4, "source"] == "ladder" and table.loc[1e-2, "source"] == "sweep"
    assert table.loc[1e-2, "us_per_sim_s"] == pytest.approx(10.0)
    for target in (1e-10, 1e-11, 1e-12):
        assert table.loc[target, "source"] == "none reached it" and table.loc[target, "engine"] == ""
    assert list(table.index) == list(fitting.ACCURACY_TARGETS)
    assert (table["ties"].fillna("") == "").all()  # costs 10, 30, 50, 100 differ by more than the timing noise


def test_a_coarsest_point_whose_local_slope_disagrees_is_left_out_of_the_fit():
    # Drake's rpy_ball runge_kutta3 on kovalevskaya, the case's dt list: state_err measured 5.08e-4, 1.41e-4, 5.85e-6
    # (local slopes 1.06, 2.90; the three fit 1.92, a third-order method verdict-failed by its coarsest point)
    measured = pd.DataFrame({"dt": [1e-2, 3e-3, 1e-3], "steps": [2000, 6667, 20000], "status": "ok",
                             "state_err": [5.078755252e-4, 1.408940359e-4, 5.84945678e-6]})
    result = fit(measured, declared=3.0)
    assert result["order"] == pytest.approx(2.90, abs=0.01) and result["points"] == 2
    assert "pre-asymptotic, left out of the fit: dt = 0.01" in result["note"]
    # a clean third-order curve keeps every point (neighbouring local slopes agree to 1e-12 here)
    clean = fit(points(3, 0.5, 0.0, [1e-2, 3e-3, 1e-3]), declared=3.0)
    assert clean["points"] == 3 and "pre-asymptotic" not in clean["note"]
    # two points cannot show a disagreement: nothing is left out
    assert fit(measured.iloc[:2], declared=3.0)["points"] == 2
