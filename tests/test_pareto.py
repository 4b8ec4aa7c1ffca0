"""The Pareto table's scopes and tie rules (harness.analysis.pareto, issue 21 item 1) and the timing phase's re-time of a
disturbed measurement (harness.timing)."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from stereodyn.harness.run import timing
from stereodyn.harness.analysis import pareto as pareto_module
from stereodyn.harness.analysis import summary
from stereodyn.harness.analysis.pareto import ANY, pareto_table

RATIO = 1.5  # issue 21: no winner or tie-mate above 1.5x the fastest of its cell (not the module constant: a test of it)


def _candidates(rows, case="c") -> pd.DataFrame:
    return pd.DataFrame([{"case": case, "engine": e, "formulation": "", "integrator": i, "dt": 0.01,
                          "attitude_err": err, "us_per_sim_s": cost, "us_per_sim_s_spread": spread,
                          "rhs_per_sim_s": rhs, "steps": 100, "source": "sweep", "status": "ok"}
                         for e, i, err, cost, spread, rhs in rows])


def _cell(table, scope, target=1e-6):
    return table[(table["scope"] == scope) & np.isclose(table["target"], target, rtol=1e-9, atol=0)].iloc[0]


def _tie_names(cell) -> list[str]:
    return [t for t in str(cell["ties"]).split("; ") if t]


def test_every_engine_that_ran_has_a_scope_whose_winner_is_its_own_run():
    runs = _candidates([("reference", "taylor", 1e-9, 50.0, 1.0, np.nan),
                        ("mujoco", "rk4", 1e-7, 400.0, 5.0, 400.0),
                        ("pinocchio", "rk4", 1e-7, 900.0, 5.0, 400.0)])
    table = pareto_table(runs, ["c"], engines=["reference", "mujoco", "pinocchio", "drake"])
    assert list(dict.fromkeys(table["scope"])) == [ANY, "reference", "mujoco", "pinocchio", "drake"]
    assert _cell(table, ANY).engine == "reference"
    for engine in ("reference", "mujoco", "pinocchio"):
        assert _cell(table, engine).engine == engine
    # an engine that ran but reached nothing says so in its own scope
    assert _cell(table, "drake").engine == "" and _cell(table, "drake").source == "none reached it"
    assert _cell(table, "mujoco", 1e-8).source == "none reached it"


def test_a_tie_never_crowns_or_lists_a_run_more_than_1_5x_slower_whatever_its_spread():
    # issue 21: scipy_rk45 at 1690 µs/s with a spread of 2030 "tied" with Pinocchio euler (263) and MuJoCo rk4 (418)
    # and won on evaluations. Here its spread (1600) is below its time, so it is not disturbed: the ratio rule alone
    # must keep it out.
    runs = _candidates([("reference", "scipy_rk45", 1e-7, 1690.0, 1600.0, 50.0),
                        ("pinocchio", "euler", 1e-7, 263.0, 20.0, 100.0),
                        ("mujoco", "rk4", 1e-7, 418.0, 30.0, 400.0),
                        ("pinocchio", "rk4", 1e-7, 1.4 * 263.0, 200.0, 400.0)])  # inside 1.5x and its noise: a tie
    table = pareto_table(runs, ["c"])
    cell = _cell(table, ANY)
    assert (cell.engine, cell.integrator) == ("pinocchio", "euler")
    assert _tie_names(cell) == ["pinocchio rk4 dt=0.01 (368 µs/s)"]
    # the reference scope has scipy alone: it wins there, and nowhere else
    assert _cell(table, "reference").integrator == "scipy_rk45"
    reached = table[table["engine"] != ""]
    for _, row in reached.iterrows():  # the acceptance rule on every cell, tie-mates included
        in_scope = runs if row.scope == ANY else runs[runs.engine == row.scope]
        fastest = in_scope[in_scope.attitude_err <= row.target].us_per_sim_s.min()
        assert row.us_per_sim_s <= RATIO * fastest
        for tie in _tie_names(row):
            assert float(tie.rsplit("(", 1)[1].split(" ")[0]) <= RATIO * fastest


def test_no_winner_or_tie_mate_above_1_5x_the_fastest_on_random_tables():
    rng = np.random.default_rng(21)
    engines = ["a", "b", "c"]
    for _ in range(40):
        n = int(rng.integers(2, 12))
        runs = _candidates([(engines[int(rng.integers(3))], f"m{i}", float(10.0 ** -rng.uniform(2, 11)),
                             float(rng.uniform(10, 1000)), float(rng.uniform(0, 900)), float(rng.uniform(10, 1000)))
                            for i in range(n)])
        runs = runs[~timing.disturbed(runs.us_per_sim_s, runs.us_per_sim_s_spread)]  # those are out anyway
        table = pareto_table(runs, ["c"])
        for _, row in table[table["engine"] != ""].iterrows():
            in_scope = runs if row.scope == ANY else runs[runs.engine == row.scope]
            fastest = in_scope[in_scope.attitude_err <= row.target].us_per_sim_s.min()
            named = runs[runs.integrator == row.integrator].us_per_sim_s.iloc[0]
            assert named <= RATIO * fastest
            for tie in _tie_names(row):
                mate = runs[runs.integrator == tie.split(" ")[1]].us_per_sim_s.iloc[0]
                assert mate <= RATIO * fastest, (row.scope, row.target, tie, fastest)


def test_a_disturbed_timing_is_never_named_and_a_cell_of_only_those_says_so():
    runs = _candidates([("mujoco", "rk4", 1e-7, 100.0, 150.0, 400.0),      # spread > time: disturbed, though fastest
                        ("mujoco", "euler", 1e-3, 90.0, 200.0, 100.0),     # disturbed, the only one reaching 1e-3 ...
                        ("pinocchio", "rk4", 1e-7, 300.0, 10.0, 400.0)])
    table = pareto_table(runs, ["c"])
    assert _cell(table, ANY).engine == "pinocchio" and "mujoco" not in _cell(table, ANY).ties
    assert _cell(table, "mujoco").source == "only runs whose timing was disturbed"
    assert _cell(table, "mujoco", 1e-2).engine == ""
    # a spread equal to the time is not yet disturbed
    equal = _candidates([("mujoco", "rk4", 1e-7, 100.0, 100.0, 400.0)])
    assert _cell(pareto_table(equal, ["c"]), "mujoco").integrator == "rk4"


def test_the_evaluations_decide_ties_only_between_runs_of_one_engine():
    runs = _candidates([("mujoco", "rk4", 1e-7, 100.0, 3.0, 400.0),
                        ("pinocchio", "euler", 1e-7, 103.0, 3.0, 100.0),   # tied, fewer evaluations: another engine
                        ("mujoco", "rk2", 1e-7, 104.0, 2.0, 200.0)])      # tied, fewer evaluations: the same engine
    table = pareto_table(runs, ["c"])
    cell = _cell(table, ANY)
    # the fastest is MuJoCo's: among MuJoCo's tie-mates rk2 needs half the evaluations; Pinocchio's euler count does
    # not enter (its evaluations are other work), though it stays a listed tie
    assert (cell.engine, cell.integrator) == ("mujoco", "rk2")
    assert sorted(t.split(" dt")[0] for t in _tie_names(cell)) == ["mujoco rk4", "pinocchio euler"]
    assert _cell(table, "pinocchio").integrator == "euler"


def test_the_verdict_exclusion_holds_in_every_scope():
    runs = _candidates([("pinocchio", "bad", 1e-9, 50.0, 0.0, 200.0), ("pinocchio", "rk4", 1e-9, 100.0, 0.0, 400.0),
                        ("mujoco", "rk4", 1e-9, 80.0, 0.0, 400.0)])
    table = pareto_table(runs, ["c"], {("*", "*", "bad")})
    assert "bad" not in set(table["integrator"])
    assert _cell(table, "pinocchio").integrator == "rk4" and "pinocchio bad" in _cell(table, "pinocchio").not_recommended
    assert _cell(table, ANY).engine == "mujoco" and "pinocchio bad" in _cell(table, ANY).not_recommended
    assert _cell(table, "mujoco").not_recommended == ""  # another engine's failure is not this scope's business
    only_bad = pareto_table(runs[runs.integrator == "bad"], ["c"], {("*", "*", "bad")})
    assert _cell(only_bad, "pinocchio").source == "only runs that failed a verdict"


def test_terminal_names_the_cheapest_run_per_engine(tmp_path):
    runs = pd.concat([_candidates([("reference", "taylor", 1e-12, 50.0, 1.0, np.nan),
                                   ("mujoco", "rk4", 1e-7, 400.0 + k, 5.0, 400.0),
                                   ("mujoco", "euler", 1e-3, 100.0 + k, 5.0, 100.0),
                                   ("pinocchio", "rk4", 1e-10, 900.0 + k, 5.0, 400.0)], case=case)
                      for k, case in enumerate(("a", "b"))], ignore_index=True)
    pareto_table(runs, ["a", "b"]).to_csv(tmp_path / "pareto.csv", index=False)
    lines = summary.cheapest_lines(tmp_path)
    # per engine first (its runs named without the engine), then any; a scope that reaches no case says why
    assert lines[4:7] == ["  mujoco     <= 1e-03: 2/2 cases, most often euler dt=0.01 (2); most expensive b: euler dt=0.01 (101 µs/s)",
                          "             <= 1e-06: 2/2 cases, most often rk4 dt=0.01 (2); most expensive b: rk4 dt=0.01 (401 µs/s)",
                          "             <= 1e-09: no case (none reached it: 2)"]
    assert [line[:13].strip() for line in lines[1::3]] == ["reference", "mujoco", "pinocchio", "any"]
    assert lines[-1].endswith("most often reference taylor dt=0.01 (2); most expensive a: reference taylor dt=0.01 (50 µs/s)")


# ------------------------------------------------------------------------------------------------ timing phase

def test_a_disturbed_timing_is_re_timed_once_and_marked_when_still_disturbed(monkeypatch):
    clock, calls = [0.0], []

    def make(name, durations):
        durations = iter(durations)

        def run():
            calls.append(name)
            clock[0] += next(durations)
        return run

    monkeypatch.setattr(timing.time, "perf_counter", lambda: clock[0])
    runs = [make("calm", [0.1, 0.1, 0.1]),
            make("once", [0.1, 0.3, 0.3, 0.1, 0.11, 0.12]),     # disturbed (spread 0.2 > 0.1), calm when re-timed
            make("always", [0.1, 0.3, 0.3, 0.1, 0.3, 0.3])]     # disturbed twice
    measured = timing.measure_interleaved(runs, repeats=3, budget_s=10.0)
    assert calls.count("calm") == 3 and calls.count("once") == 6 and calls.count("always") == 6
    assert not measured[0].disturbed and not measured[1].disturbed and measured[2].disturbed
    assert measured[1].spread == pytest.approx(0.01) and measured[2].spread == pytest.approx(0.2)
    point = {"status": "ok", "message": "warning x"}
    assert timing.with_disturbed(point["message"], measured[2]).startswith("warning x; timing disturbed")


def test_the_report_shows_each_engines_table_before_any(tmp_path):
    from stereodyn.harness.analysis import workprecision
    from stereodyn.harness.report.workprecision import report_lines

    runs = _candidates([("reference", "taylor", 1e-12, 50.0, 1.0, np.nan), ("mujoco", "rk4", 1e-7, 400.0, 5.0, 400.0),
                        ("pinocchio", "rk4", 1e-10, 900.0, 5.0, 400.0)])
    pareto_table(runs, ["c"]).to_csv(tmp_path / workprecision.PARETO_FILE, index=False)
    text = "\n".join(report_lines(tmp_path))
    section = text.split("## What to use")[1]
    heads = [line for line in section.splitlines() if line.startswith("### ")]
    assert heads == ["### reference", "### mujoco", "### pinocchio", "### any engine"]
    mujoco = section.split("### mujoco")[1].split("###")[0]
    row = [line for line in mujoco.splitlines() if line.startswith("| c |")][0].split(" | ")
    # targets shown 1e-2, 1e-3, 1e-4, 1e-6, 1e-8 ...: MuJoCo's rk4 (named without its engine) down to 1e-7 (the
    # cells after the first say '=': the same answer), then nothing
    assert row[1] == "rk4 dt=0.01: 1e-07 rad, 400 µs/s (listed, not searched)"
    assert row[2:5] == ["=", "=", "="] and row[5] == "-"
    every = section.split("### any engine")[1]
    assert "| c | reference taylor dt=0.01: 1e-12 rad, 50 µs/s (listed, not searched) | = |" in every


def test_an_engine_whose_rows_are_all_skipped_gets_no_scope_and_no_terminal_line(tmp_path):
    """pareto() builds its scopes from the engines that ran: an uninstalled optional engine (every row `skipped`) gets
    no "What to use" table of "none reached it", and the terminal does not say it reached nothing, as if it had run
    and failed. Break-check: scopes from every engine of results.csv (`engines=list(results["engine"])`) fail this."""
    def row(engine, status, err, wall):
        return {"case": "c", "engine": engine, "formulation": "", "integrator": "rk4", "dt": 0.01, "t_end": 1.0,
                "steps": 100, "status": status, "attitude_err": err, "wall_s": wall, "us_per_step_spread": 0.01}

    results = pd.DataFrame([row("mujoco", "ok", 1e-7, 4e-4), row("bullet", "skipped", np.nan, np.nan),
                            row("pinocchio", "ok", 1e-7, 9e-4), row("bullet", "skipped", np.nan, np.nan)])
    table = pareto_module.pareto(results, pd.DataFrame())
    assert list(dict.fromkeys(table["scope"])) == [ANY, "mujoco", "pinocchio"]
    assert _cell(table, ANY).engine == "mujoco" and _cell(table, "pinocchio").engine == "pinocchio"
    table.to_csv(tmp_path / "pareto.csv", index=False)
    lines = summary.cheapest_lines(tmp_path)
    assert lines and not any("bullet" in line for line in lines), lines
