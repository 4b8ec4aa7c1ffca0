"""pareto.csv from a sweep's results table (harness.analysis.pareto.pareto): which runs are candidates, what a cell
costs and which scopes exist. Found by the mutation check (tools/mutants.py, docs/mutants.md)."""
from __future__ import annotations

import math

import numpy as np
import pandas as pd

from stereodyn.harness.analysis.pareto import ANY, NONE_REACHED, ONLY_DISTURBED, pareto, scopes


def _results(rows) -> pd.DataFrame:
    """results.csv rows: (engine, integrator, dt, status, attitude_err, wall_s, spread per step, rhs per sim s);
    t_end 2, 100 steps."""
    return pd.DataFrame([{"case": "c", "engine": e, "formulation": "", "integrator": i, "dt": dt, "t_end": 2.0,
                          "steps": 100, "status": status, "attitude_err": err, "wall_s": wall,
                          "us_per_step_spread": spread, "rhs_per_sim_s": rhs}
                         for e, i, dt, status, err, wall, spread, rhs in rows])


EMPTY_LADDER = pd.DataFrame(columns=["case", "engine", "formulation", "integrator", "dt", "attitude_err", "status"])


def _cell(table, scope, target):
    return table[(table["scope"] == scope) & np.isclose(table["target"], target, rtol=1e-9, atol=0)].iloc[0]


def test_the_scopes_are_the_engines_that_ran_not_the_skipped_ones():
    results = _results([("reference", "rk4", 0.01, "ok", 1e-8, 0.002, 0.0, 400.0),
                        ("drake", "", math.nan, "skipped", math.nan, math.nan, math.nan, math.nan)])
    table = pareto(results, EMPTY_LADDER)
    assert scopes(table) == ["reference"]
    assert set(table["scope"]) == {ANY, "reference"}


def test_an_adaptive_run_of_the_sweep_is_a_candidate_and_an_error_of_exactly_0_is_not():
    # the adaptive run (dt empty) at its default tolerance reaches 1e-7; the reference's own row (error 0) never wins
    results = _results([("reference", "scipy_rk45", math.nan, "ok", 5e-8, 0.004, 0.0, 300.0),
                        ("reference", "taylor", math.nan, "ok", 0.0, 0.0001, 0.0, math.nan)])
    table = pareto(results, EMPTY_LADDER)
    cell = _cell(table, ANY, 1e-7)
    assert (cell.integrator, cell.source) == ("scipy_rk45", "sweep")
    assert "taylor" not in set(table["integrator"])
    assert _cell(table, ANY, 1e-8).source == NONE_REACHED


def test_the_cost_is_microseconds_per_simulated_second():
    # 0.002 s of wall time for 2 s simulated: 1000 µs/s
    table = pareto(_results([("reference", "rk4", 0.01, "ok", 1e-8, 0.002, 0.0, 400.0)]), EMPTY_LADDER)
    assert math.isclose(_cell(table, ANY, 1e-6).us_per_sim_s, 1000.0, rel_tol=1e-12)


def test_a_run_whose_error_equals_the_target_reaches_it():
    target = 10.0 ** -6  # as pareto.ACCURACY_TARGETS writes it
    table = pareto(_results([("reference", "rk4", 0.01, "ok", target, 0.002, 0.0, 400.0)]), EMPTY_LADDER)
    assert _cell(table, ANY, target).integrator == "rk4"
    assert _cell(table, ANY, target / 10).source == NONE_REACHED


def test_a_run_that_did_not_finish_ok_is_never_recommended():
    # the diverged run kept a finite error before it diverged and is cheaper: still no candidate
    results = _results([("reference", "euler", 0.01, "diverged", 1e-9, 0.001, 0.0, 100.0),
                        ("reference", "rk4", 0.01, "ok", 1e-8, 0.002, 0.0, 400.0)])
    table = pareto(results, EMPTY_LADDER)
    assert _cell(table, ANY, 1e-8).integrator == "rk4"
    assert _cell(table, ANY, 1e-9).source == NONE_REACHED


def test_a_disturbed_timing_is_never_recommended_and_says_so_when_alone():
    # spread 30 µs a step x 100 steps / 2 s = 1500 µs/s, above its 500 µs/s: disturbed
    results = _results([("reference", "euler", 0.01, "ok", 1e-9, 0.001, 30.0, 100.0),
                        ("reference", "rk4", 0.01, "ok", 1e-8, 0.002, 0.0, 400.0)])
    table = pareto(results, EMPTY_LADDER)
    assert _cell(table, ANY, 1e-8).integrator == "rk4"
    assert (_cell(table, ANY, 1e-9).engine, _cell(table, ANY, 1e-9).source) == ("", ONLY_DISTURBED)


def test_evaluations_decide_only_among_the_fastest_engines_tie_mates():
    # b's run ties with a's within the noise and needs 4x fewer evaluations, but evaluations of two engines are not
    # the same work: the fastest's engine keeps the cell, b's run is a tie-mate
    results = _results([("a", "rk4", 0.01, "ok", 1e-8, 0.002, 0.0, 400.0),
                        ("b", "rk4", 0.01, "ok", 1e-8, 0.00205, 0.0, 100.0)])
    cell = _cell(pareto(results, EMPTY_LADDER), ANY, 1e-8)
    assert cell.engine == "a" and cell.ties.startswith("b rk4")
