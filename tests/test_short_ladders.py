"""An order, or a reason, for every run family with a declared order (issue 13, item 3): the fitter's guards on
synthetic errors C dt^p + floor (a point at round-off, two points steeper than declared, superconvergence), the short
ladder's walk on fake runs (an exact method, a method exact only below its stability limit, a chaotic case), a real
short ladder on the families whose dt list gave no order (rk4 on kovalevskaya), and the default run's choice of the
families that get one."""
import dataclasses
import math

import numpy as np
import pandas as pd
import pytest

from stereodyn.harness.pipeline import dt_ladders
from stereodyn.harness.analysis import fitting, workprecision
from stereodyn.harness.scenes.cases import find_case, with_overrides
from stereodyn.harness.pipeline.dt_ladders import Family, run_short_ladder
from stereodyn.harness.analysis.fitting import fit

T_END = 10.0


def points(dts, err, steps=None) -> pd.DataFrame:
    dts = np.asarray(dts, dtype=float)
    return pd.DataFrame({"dt": dts, "steps": np.round(T_END / dts) if steps is None else steps, "status": "ok",
                         "state_err": err})


# ------------------------------------------------------------------------------------------------ the fitter's guards

def test_a_point_within_the_margin_of_a_measured_floor_is_at_round_off():
    """err = C dt^4 + 1e-10: a floor 1e-10 (a formulation that rounds worse than eps per step: above 30 eps steps
    here) bends the point at dt = 0.02 (7.3e-10, 14% floor). Fitted with eps steps as the rounding level it gave 3.8
    from two points; with the measured floor the two-point fit is refused and the note says why."""
    dts = np.array([0.04, 0.02, 0.01, 0.005])
    result = fit(points(dts, 1e-8 * (dts / 0.04) ** 4 + 1e-10), declared=4.0)
    assert result["floor_dt"] == pytest.approx(0.01) and result["floor_err"] == pytest.approx(1e-10, rel=0.05)
    assert math.isnan(result["order"]) and result["points"] == 1, result
    assert "1 point(s) in the asymptotic range" in result["note"]
    assert "round-off" in result["note"]


def test_an_error_that_rises_again_past_the_floor_is_irregular_not_round_off():
    """Measured (reference euler_zxz Euler on lagrange-precession, t_end 20, its dt list and a short ladder): at
    round-off up to dt = 0.04, then 8.4e-10, 3.7e-5, 5.3e-8 and 0.37. The floor test stops at dt = 0.32 (the error
    rises as dt halves); the points past it that lie far above the floor are not called round-off."""
    dts = [0.64, 0.32, 0.16, 0.08, 0.04, 0.02, 0.01, 0.003]
    err = [0.37, 5.3e-8, 3.7e-5, 8.4e-10, 1.7e-12, 2.8e-12, 3.7e-12, 1.5e-11]
    marked, floor_dt, floor_err = fitting.regimes(points(dts, err, steps=[round(20 / dt) for dt in dts]))
    assert list(marked["regime"]) == ["above"] + ["irregular"] * 3 + ["round-off"] * 4
    result = fit(points(dts, err, steps=[round(20 / dt) for dt in dts]), declared=1.0)
    assert math.isnan(result["order"]) and "3 irregular" in result["note"], result["note"]


def test_two_points_steeper_than_declared_are_refused_three_are_superconvergence():
    """A first-order method whose error falls like dt^3 on this motion: two points cannot tell that from a point at
    round-off (fitting.STEEP), three consistent ones can."""
    dts = np.array([0.04, 0.02, 0.01])
    err = 1e-3 * (dts / 0.04) ** 3
    two = fit(points(dts[:2], err[:2]), declared=1.0)
    assert math.isnan(two["order"]) and two["points"] == 2
    assert "too few to tell superconvergence" in two["note"], two
    three = fit(points(dts, err), declared=1.0)
    assert three["order"] == pytest.approx(3.0, abs=1e-9) and three["points"] == 3
    assert three["note"].startswith(fitting.SUPERCONVERGENT), three
    # within STEEP of the declared order a two-point fit stands and says nothing special
    ordinary = fit(points(dts[:2], 1e-3 * (dts[:2] / 0.04) ** 1.02), declared=1.0)
    assert ordinary["order"] == pytest.approx(1.02, abs=1e-9) and fitting.SUPERCONVERGENT not in ordinary["note"]


def test_the_order_verdict_does_not_fail_a_superconvergent_case_alone():
    from stereodyn.harness.analysis import verdicts

    def row(case, order, note=""):
        return {"case": case, "engine": "e", "formulation": "", "integrator": "m", "order": order,
                "declared_order": 2.0, "note": note}

    special = f"{fitting.SUPERCONVERGENT} (fitted 4.00, declared 2)"
    table = pd.DataFrame([row("a", 2.0), row("b", 2.01), row("c", 1.98), row("d", 4.0, special)])
    [verdict] = verdicts.order_verdicts(table)
    assert verdict.status == verdicts.PASS and "superconvergent" in verdict.detail, verdict
    # the same fit without the note (a two-point fit the fitter would have refused) fails the case bound
    [verdict] = verdicts.order_verdicts(table.assign(note=""))
    assert verdict.status == verdicts.FAIL and "off by more than 1 on d" in verdict.detail, verdict


# ------------------------------------------------------------------------------------------------ the walk, on fakes

def _fake(monkeypatch, error, unstable_above=math.inf):
    """dt_ladders.measure replaced: state_err = error(dt, steps); diverged above unstable_above. Records the dts."""
    tried = []

    def fake_measure(family, dt, timed=True, with_truth=True):
        tried.append(dt)
        steps = round(family.case.t_end / dt)
        row = {"case": family.case.name, "engine": family.engine, "formulation": family.formulation,
               "integrator": family.integrator, "dt": dt, "t_end": steps * dt, "steps": steps, "source": "ladder"}
        if dt > unstable_above:
            return {**row, "status": "diverged", "state_err": math.nan, "energy_drift": math.nan}
        return {**row, "status": "ok", "state_err": error(dt, steps), "energy_drift": 1e-12}

    monkeypatch.setattr(dt_ladders, "measure", fake_measure)
    return tried


def _known(case, error):
    return [{"dt": dt, "steps": round(case.t_end / dt), "status": "ok", "state_err": error(dt, round(case.t_end / dt))}
            for dt in case.dt]


def _round_off(dt, steps):
    return 2.0 * fitting.EPS * steps  # the error of an exact method: rounding only, ~eps per step


def test_an_exact_method_walks_to_the_largest_dt_and_is_called_exact(monkeypatch):
    case = with_overrides(find_case("sleeping-top-stable"), t_end=T_END, dt=[0.01, 0.005])
    tried = _fake(monkeypatch, _round_off)
    new, row = run_short_ladder(Family(case, "mujoco", "", "euler"), _known(case, _round_off), max_steps=40_000)
    # doubling from 0.01 up to t_end / MIN_STEPS = 0.5: 0.02 ... 0.32
    assert tried == pytest.approx([0.02, 0.04, 0.08, 0.16, 0.32])
    assert all(p["source"] == dt_ladders.SHORT_LADDER for p in new)
    assert math.isnan(row["order"]) and row["source"] == dt_ladders.SHORT_LADDER
    assert "exact for this motion" in row["note"], row["note"]


def test_round_off_up_to_the_stability_limit_is_not_called_exact(monkeypatch):
    case = with_overrides(find_case("sleeping-top-stable"), t_end=T_END, dt=[0.01, 0.005])
    _fake(monkeypatch, _round_off, unstable_above=0.05)
    _, row = run_short_ladder(Family(case, "mujoco", "", "euler"), _known(case, _round_off), max_steps=40_000)
    assert math.isnan(row["order"])
    assert "round-off for every stable dt: every dt up to 0.04 (dt = 0.08: did not run ok)" in row["note"], row["note"]
    assert "exact" not in row["note"]


def test_a_family_at_round_off_in_its_dt_list_gets_its_order_from_coarser_steps(monkeypatch):
    """rk4 whose dt list is at round-off after one point (kovalevskaya's pattern): the walk doubles dt."""
    case = with_overrides(find_case("kovalevskaya"), t_end=T_END, dt=[1e-2, 3e-3, 1e-3])

    def rk4(dt, steps):
        return 4e-2 * dt ** 4 + _round_off(dt, steps)

    tried = _fake(monkeypatch, rk4)
    known = _known(case, rk4)
    assert math.isnan(fit(pd.DataFrame(known), 4.0)["order"])  # the problem: one asymptotic point
    new, row = run_short_ladder(Family(case, "mujoco", "", "rk4"), known, max_steps=40_000)
    assert tried == pytest.approx([0.02, 0.04])  # two coarser points give three asymptotic ones
    assert row["order"] == pytest.approx(4.0, abs=0.05) and row["points"] == 3, row


def test_a_chaotic_case_above_the_range_says_so_and_a_saturated_error_stops_the_walk(monkeypatch):
    case = dataclasses.replace(with_overrides(find_case("kovalevskaya"), t_end=T_END, dt=[1e-2, 5e-3]),
                               tags=("chaotic",))

    def slow(dt, steps):  # falls, but too slowly to reach 3e-2 before the steps cap: 0.29 at t_end / 8000
        return (dt / 0.01) ** 0.6

    tried = _fake(monkeypatch, slow)
    _, row = run_short_ladder(Family(case, "mujoco", "", "rk4"), _known(case, slow), 8_000)
    assert tried == pytest.approx([2.5e-3, 1.25e-3])  # halving down to t_end / 8000
    assert math.isnan(row["order"])
    assert "smallest tried (t_end / 8000)" in row["note"] and "the case is chaotic" in row["note"], row["note"]
    # an error that does not fall as dt halves (saturated, of order pi) ends the walk at the first such point
    tried = _fake(monkeypatch, lambda dt, steps: 3.0)
    _, row = run_short_ladder(Family(case, "mujoco", "", "rk4"), _known(case, lambda dt, steps: 3.0), 8_000)
    assert tried == pytest.approx([2.5e-3]) and "state_err not falling above 0.03" in row["note"], row["note"]


def test_a_walk_that_would_go_on_stops_at_six_points(monkeypatch):
    """DESIGN §4: a short ladder adds at most 6 points. An error far above the range that falls fourfold per halving
    (1e5 at dt = 5e-3: still 6 above 3e-2 after 6 halvings) would walk on; the seventh point is never run."""
    case = with_overrides(find_case("kovalevskaya"), t_end=T_END, dt=[1e-2, 5e-3])

    def far_above(dt, steps):
        return 1e5 * (dt / 5e-3) ** 2

    tried = _fake(monkeypatch, far_above)
    new, row = run_short_ladder(Family(case, "mujoco", "", "rk4"), _known(case, far_above), 10_000_000)
    assert tried == pytest.approx([5e-3 / 2 ** k for k in range(1, 7)], rel=1e-3)  # six halvings (4 digits each)
    assert len(new) == 6 and "short ladder stopped at 6 points" in row["note"], row["note"]


def test_finer_points_that_did_not_run_do_not_block_exactness(monkeypatch):
    """Issue 21: strang_free_flow on a 500 s case is at round-off at dt = 0.5 while its dt 0.02 and 0.01 runs hit the
    run budget (1.3 ms a step). A run that did not finish has no error: the walk to t_end / 20 decides, and the note
    says what rests on what."""
    case = with_overrides(find_case("sleeping-top-stable"), t_end=T_END, dt=[0.01, 0.005, 0.0025])
    tried = _fake(monkeypatch, _round_off)
    known = _known(case, _round_off)
    for point in known[1:]:  # the finer two: out of budget
        point.update(status="failed", state_err=math.nan)
    new, row = run_short_ladder(Family(case, "mujoco", "", "euler"), known, max_steps=40_000)
    assert tried == pytest.approx([0.02, 0.04, 0.08, 0.16, 0.32])
    assert math.isnan(row["order"])
    assert "exact for this motion" in row["note"], row["note"]
    assert ("dt = 0.005, 0.0025 did not run ok: no error, no evidence either way, so this rests on the 6 points that "
            "ran, dt = 0.01 to 0.32") in row["note"], row["note"]
    from stereodyn.harness.analysis import verdicts
    why = verdicts.excuse({**row, "case": case.name}, set())
    assert why.startswith("exact for this motion (dt = 0.005, 0.0025 did not run ok"), why
    # a point that did not run COARSER than the round-off ones is still a stability limit, not exactness
    _fake(monkeypatch, _round_off, unstable_above=0.05)
    _, row = run_short_ladder(Family(case, "mujoco", "", "euler"), known, max_steps=40_000)
    assert "exact" not in row["note"] and "round-off for every stable dt: every dt up to 0.04" in row["note"], row


def test_the_coarse_walk_goes_on_to_t_end_over_20(monkeypatch):
    """An exact method from dt = 1e-3 over 10 s: 8 doublings to reach 0.256 (t_end / 20 = 0.5); all of them cost
    fewer steps than the one run at 1e-3. With six points at most the walk stopped at 0.064 and no reason was given."""
    case = with_overrides(find_case("sleeping-top-stable"), t_end=T_END, dt=[1e-3])
    tried = _fake(monkeypatch, _round_off)
    new, row = run_short_ladder(Family(case, "mujoco", "", "euler"), _known(case, _round_off), max_steps=40_000)
    assert tried == pytest.approx([1e-3 * 2 ** k for k in range(1, 9)])
    assert sum(p["steps"] for p in new) < T_END / 1e-3
    assert "exact for this motion" in row["note"] and "stopped at" not in row["note"], row["note"]


def _phase(dt, steps):
    """A second-order method's global error on an integrable motion: a phase error growing linearly in time."""
    return 40.0 * (steps * dt) * dt ** 2


def test_a_long_horizon_has_its_order_measured_over_its_first_part(monkeypatch):
    """Over 10 s with at most 1000 steps the error is 0.04 at the cap (dt = 0.01): above the range, no order (as
    moser_veselov over 500 s: 0.036 at dt = 0.01, the cap 0.00625). The first part: t_end halved until the model error
    at 4 x the part's cap is <= 0.015 (2.5 s: 0.01 at dt 0.01), then a short ladder there: order 2 over 2.5 s."""
    case = with_overrides(find_case("sleeping-top-stable"), t_end=T_END, dt=[0.02, 0.01])
    family = Family(case, "mujoco", "", "rk4")
    monkeypatch.setattr(fitting, "declared_order", lambda engine, integrator, formulation="": 2.0)
    monkeypatch.setattr(dt_ladders, "declared_order", lambda engine, integrator, formulation="": 2.0)
    tried = _fake(monkeypatch, _phase)
    known = _known(case, _phase)
    new, row = run_short_ladder(family, known, max_steps=1000)
    assert tried == [] and math.isnan(row["order"]) and "smallest tried (t_end / 1000)" in row["note"], row["note"]
    assert dt_ladders.first_part_span(T_END, 0.01, _phase(0.01, 1000), 2.0, 1000) == 2.5
    more, part = dt_ladders.run_first_part(family, known + new, 1000, row)
    assert tried == pytest.approx([0.01, 0.005, 0.0025])  # from 4 x the cap: finer only (issue 45), to the cap
    assert [p["t_end"] for p in more] == pytest.approx([2.5] * 3)
    assert part["order"] == pytest.approx(2.0, abs=1e-6) and part["points"] == 3, part
    assert part["note"].startswith(f"{fitting.FIRST_PART} 2.5 s of 10 s (over all 10 s, 0 point(s) in the asymptotic "
                                   "range down to dt = 0.01 (state_err 0.04), steps cap t_end / 1000)"), part["note"]
    # the verdict says over what span, and a false claim still fails on it
    from stereodyn.harness.analysis import verdicts
    table = pd.DataFrame([{**part, "case": case.name, "engine": "e", "formulation": "", "integrator": "m"}])
    [verdict] = verdicts.order_verdicts(table)
    assert verdict.status == verdicts.PASS and f"{case.name}: {fitting.FIRST_PART} 2.5 s of 10 s" in verdict.detail
    [verdict] = verdicts.order_verdicts(table.assign(declared_order=4.0))
    assert verdict.status == verdicts.FAIL, verdict
    # nothing above the range at the cap (an order found, or round-off): no first part, nothing run
    tried.clear()
    assert dt_ladders.run_first_part(family, known, 1000, {**row, "order": 2.0}) == ([], {**row, "order": 2.0})
    assert dt_ladders.run_first_part(family, _known(case, _round_off), 1000, row) == ([], row) and tried == []


# ------------------------------------------------------------------------------------------------ real runs

# measured (2-core AMD EPYC, MuJoCo 3.x, Pinocchio 3.x): the dt list 1e-2, 3e-3, 1e-3 gives state_err 4.4e-9 (1e-2),
# then 3.5e-11 and 5e-13, at or below 30 eps steps: one asymptotic point, no order.
@pytest.mark.parametrize("engine, formulation", [("mujoco", ""), ("pinocchio", ""), ("reference", "quaternion")])
def test_a_real_short_ladder_gives_rk4_its_order_on_kovalevskaya(engine, formulation):
    case = find_case("kovalevskaya")
    family = Family(case, engine, formulation, "rk4")
    known = [dt_ladders.measure(family, dt, timed=False) for dt in case.dt]
    assert math.isnan(fit(pd.DataFrame(known), 4.0)["order"])  # the dt list alone still shows the problem
    new, row = run_short_ladder(family, known, max_steps=40_000)
    # measured: 4.01 (mujoco, pinocchio), 4.06 (reference quaternion) on dt 1e-2, 2e-2, 4e-2
    assert 3.7 <= row["order"] <= 4.3 and row["points"] >= 3, row
    assert row["declared_order"] == 4.0 and all(math.isnan(p.get("wall_s", math.nan)) for p in new)


def test_the_default_run_gives_a_short_ladder_to_the_families_without_an_order():
    case = with_overrides(find_case("kovalevskaya"), t_end=T_END, dt=[1e-2, 3e-3])

    def run(engine, formulation, integrator, dt, err, status="ok"):
        stages = {"rk4": 4}.get(integrator, 1)
        return {"case": case.name, "engine": engine, "formulation": formulation, "integrator": integrator,
                "dt": dt, "steps": round(T_END / dt) if dt == dt else 1000, "status": status, "attitude_err": err,
                "t_end": T_END, "rhs_per_sim_s": stages / dt, "omega_err": err, "casimir_drift": 0.0}

    results = pd.DataFrame([
        run("mujoco", "", "rk4", 1e-2, 1e-9), run("mujoco", "", "rk4", 3e-3, 1e-15),         # one asymptotic point
        run("mujoco", "", "euler", 1e-2, 1e-3), run("mujoco", "", "euler", 3e-3, 3e-4),    # an order: none needed
        run("mujoco", "", "implicit", 1e-2, math.nan, "failed"),                            # failed: its reason
        run("mujoco", "", "implicit", 3e-3, math.nan, "failed"),
        run("reference", "quaternion", "taylor", math.nan, 1e-15),                          # adaptive: no order
    ])
    sweep_rows = fitting.sweep_orders(results, set())
    chosen = workprecision.short_ladder_families(results, [case], ["mujoco", "reference"], None, sweep_rows, set())
    assert [(f.engine, f.integrator) for f, _, _ in chosen] == [("mujoco", "rk4")]
    assert [p["dt"] for p in chosen[0][1]] == [1e-2, 3e-3]
    # its steps cap: SHORT_MAX_STEPS for rk4 (4 evaluations a step in the sweep, rhs_per_sim_s)
    assert chosen[0][2] == workprecision.SHORT_MAX_STEPS
    # Euler, were its list to give no order (no sweep rows): one evaluation a step, SHORT_MAX_EVALS steps (80000)
    [(family, _, steps)] = workprecision.short_ladder_families(results, [case], ["mujoco"], ["euler"], [], set())
    assert family.integrator == "euler" and steps == workprecision.SHORT_MAX_EVALS > workprecision.SHORT_MAX_STEPS
    # the same read back from results.csv, whose 10 digits make it 0.99999999995 evaluations a step
    read_back = results.assign(rhs_per_sim_s=results["rhs_per_sim_s"] * (1 - 5e-11))
    [(_, _, steps)] = workprecision.short_ladder_families(read_back, [case], ["mujoco"], ["euler"], [], set())
    assert steps == workprecision.SHORT_MAX_EVALS


def test_a_short_ladder_point_is_capped_at_its_seconds_of_stepping_in_the_sweep():
    """A family whose steps cost SHORT_MAX_POINT_S / SHORT_MAX_EVALS or more in the sweep (its median us_per_step)
    gets a steps cap of SHORT_MAX_POINT_S of stepping, never below its own sweep's steps: Genesis's Euler at ~0.5
    ms a step ran 64000-80000-step points of 30-40 s. A cheap family keeps SHORT_MAX_EVALS."""
    case = with_overrides(find_case("kovalevskaya"), t_end=T_END, dt=[1e-2, 3e-3])

    def runs(us_per_step):
        return pd.DataFrame([{"case": case.name, "engine": "mujoco", "formulation": "", "integrator": "euler",
                              "dt": dt, "steps": round(T_END / dt), "status": "ok", "attitude_err": 1e-3,
                              "omega_err": 1e-3, "casimir_drift": 0.0, "t_end": T_END, "rhs_per_sim_s": 1 / dt,
                              "us_per_step": us_per_step} for dt in case.dt])

    def cap(us_per_step):
        [(_, _, steps)] = workprecision.short_ladder_families(runs(us_per_step), [case], ["mujoco"], ["euler"], [],
                                                             set())
        return steps

    assert cap(2.0) == workprecision.SHORT_MAX_EVALS  # 80000 steps x 2 µs = 0.16 s
    assert cap(500.0) == int(workprecision.SHORT_MAX_POINT_S / 500e-6)  # 30000 steps: 15 s
    assert cap(1e7) == round(T_END / 3e-3)  # 10 s a step: the sweep's own steps, no fewer
