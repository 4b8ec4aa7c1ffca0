"""Tolerance ladders (analysis.tolerance_ladders, analysis.fitting.tolerance_fit) and adaptive runs in "What to use":
an engine's adaptive integrator joins through the contract's hooks alone (a stub engine here), tolerance.csv's
columns, the proportionality fit on synthetic data, and the Pareto rule with adaptive candidates."""
from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from scipy.integrate import solve_ivp

from stereodyn.harness import engines
from stereodyn.harness.run.pool import worker_pool
from stereodyn.harness.run.sweep import SweepOptions, run_sweep
from stereodyn.harness.pipeline import tolerance_ladders
from stereodyn.harness.analysis import fitting, ladders, workprecision
from stereodyn.harness.pipeline import work_precision
from stereodyn.harness.scenes.cases import find_case, with_overrides
from stereodyn.harness.engines.base import Engine, Offer, Timing
from stereodyn.harness.report import build
from stereodyn.harness.report.build import write_reports
from stereodyn.harness.trajectory import Status, Trajectory
from stereodyn.reference import euler_poisson


# ------------------------------------------------------------------------------------------------ a stub engine

class _StubSimulation:
    """Euler–Poisson (numpy) by scipy's DOP853 at tolerance tol, the dense output on the grid."""

    def __init__(self, case, tol):
        self.case, self.tol = case, tol

    def run(self, grid):
        body = self.case.body

        def fun(t, y):
            quat_dot, omega_dot = euler_poisson.rhs(body, y[:4], y[4:], t)
            return np.concatenate([quat_dot, omega_dot])

        y0 = np.concatenate([self.case.quat0, self.case.omega0])
        result = solve_ivp(fun, (0.0, grid.times[-1]), y0, method="DOP853", rtol=self.tol, atol=self.tol,
                           dense_output=True)
        states = result.sol(grid.times).T
        return Trajectory(grid.times, states[:, :4], states[:, 4:], Status.OK, "", math.nan, len(result.t) - 1,
                          result.nfev, {"tolerance": self.tol})


class StubEngine(Engine):
    """An engine with one adaptive integrator ("stub_dop853", following the contract: adaptive(), prepare's tolerance
    keyword, steps and rhs_evals filled) and one fixed-step name, which never gets a tolerance ladder."""

    name = "stub"
    timing = Timing(pass_us=50.0)

    def integrators(self):
        return ("stub_fixed", "stub_dop853")

    def offer(self, integrator):
        return Offer(adaptive=integrator == "stub_dop853")

    def unsupported(self, case):
        return "stub: no external torques" if case.body.has_external_torque else None

    def prepare(self, case, integrator, dt, tolerance=None):
        if integrator != "stub_dop853":
            raise KeyError(integrator)
        return _StubSimulation(case, 1e-6 if tolerance is None else tolerance)


class _Entry:
    """An entry point of the group stereodyn.engines as a plug-in package would install it, loading StubEngine."""

    name, value, group = "stub", "test_tolerance_ladders:StubEngine", engines.ENTRY_POINT_GROUP

    def load(self):
        return StubEngine


@pytest.fixture
def stub_engine(monkeypatch):
    """The stub registered as the engine plug-in "stub" (harness.engines' entry points)."""
    registered = engines._entry_points()
    monkeypatch.setattr(engines, "_entry_points", lambda: {**registered, "stub": _Entry()})
    engines.get_engine.cache_clear()
    yield engines.get_engine("stub")
    engines.get_engine.cache_clear()


def _short_case():
    return with_overrides(find_case("free-asymmetric"), t_end=4.0)


@pytest.mark.slow  # since 2026-12-02, ~12 s; by default the tolerance ladders on the sweep's pool (the default suite's 8 minutes)
def test_a_stub_engines_adaptive_integrator_gets_a_tolerance_ladder(stub_engine, tmp_path):
    case = _short_case()
    assert stub_engine.name == "stub" and stub_engine.offer("stub_dop853").adaptive
    found = ladders.adaptive_families([case], ["stub"], None)
    assert [(f.engine, f.formulation, f.integrator) for f in found] == [("stub", "", "stub_dop853")]
    # the whole phase, as `stereodyn run --dt-ladder` has it: the sweep's rows, then the ladders and the tables
    df = run_sweep([case], SweepOptions(["stub"], tmp_path, ["stub_dop853"], jobs=1))
    work_precision.analyse(tmp_path, df, [case], ["stub"], ["stub_dop853"], ladder="full")
    points = pd.read_csv(tmp_path / workprecision.TOLERANCE_FILE, keep_default_na=False, na_values=[""])
    assert tuple(points.columns) == tolerance_ladders.TOLERANCE_COLUMNS
    assert list(points["tolerance"]) == sorted(tolerance_ladders.TOLERANCES, reverse=True)
    assert (points["status"] == "ok").all() and (points["steps"] > 0).all() and (points["rhs_evals"] > 0).all()
    # every point timed once in its worker; those whose time can change a "What to use" cell (analysis.decisive: the
    # point at 1e-3 misses every target, 1.1e-2) again, best of N, with a spread; the others say they are single
    assert (points["us_per_sim_s"] > 0).all()
    repeated = points["timing"].str.startswith("best of")
    assert set(points["timing"]) <= {"single", "best of 2", "best of 3"} and repeated.sum() >= 5
    assert np.isfinite(points["us_per_sim_s_spread"][repeated]).all()
    assert points["us_per_sim_s_spread"][~repeated].isna().all() and not repeated.iloc[0]
    # the stub's error falls with the tolerance: measured 1.1e-2 at 1e-3 down to 1.3e-10 at 1e-11 (4 s)
    err = points["state_err"].to_numpy()
    assert err[0] > 1e3 * err[8] and err[8] < 1e-8
    fits = pd.read_csv(tmp_path / workprecision.TOLERANCE_FIT_FILE, keep_default_na=False, na_values=[""])
    assert tuple(fits.columns) == fitting.TOLERANCE_FIT_COLUMNS and len(fits) == 1
    # measured: slope 0.98 over all 11 points, the error 8 to 16 times the tolerance
    assert fits["points"].iloc[0] >= 3 and 0.8 <= fits["slope"].iloc[0] <= 1.2
    assert fits["below_tol"].iloc[0] == 0 and 1.0 < fits["max_err_over_tol"].iloc[0] < 100.0
    # its points are candidates of "What to use": here the only ones, so they fill every cell they reach
    pareto = pd.read_csv(tmp_path / workprecision.PARETO_FILE, keep_default_na=False, na_values=[""])
    reached = pareto[pareto["engine"].notna()]
    assert set(pareto["scope"]) == {"any", "stub"}  # the stub engine's scope holds the same runs
    assert len(reached) >= 5 and set(reached["integrator"]) == {"stub_dop853"}
    assert set(reached["source"]) <= {"sweep", "tolerance_ladder"} and "tolerance_ladder" in set(reached["source"])
    # the report: a "Tolerance ladders" section with the fit and the figure of error against tolerance
    write_reports(tmp_path, df)
    section = (tmp_path / "report.md").read_text().split("## Tolerance ladders")[1].split("\n## ")[0]
    row = [line for line in section.splitlines() if line.startswith("| free-asymmetric | stub stub_dop853 | ")]
    assert len(row) == 1 and row[0].split(" | ")[2:4] == [f"{fits['slope'].iloc[0]:.2f}", "11"], row
    figure = f"figures/{build.figure_stem(case.name)}-tolerance.png"
    assert f"]({figure})" in section and (tmp_path / figure).read_bytes().startswith(b"\x89PNG")


def test_the_tolerance_ladders_run_on_the_sweeps_pool(tmp_path):
    """One family per worker task, as the dt ladders (tests/test_workprecision_pool.py): heyoka's taylor on two
    formulations of a short case, the points back in the families' order and timed here. No point budget: a point
    (heyoka's JIT compilation included) took over POINT_BUDGET_S once at load ~10 and the ladder stopped after it;
    the early stop has its own test below."""
    case = with_overrides(find_case("free-asymmetric"), t_end=1.0)
    chosen = ladders.adaptive_families([case], ["reference"], ["taylor"], ("quaternion", "gibbs"))
    with worker_pool(2) as pool:
        points = tolerance_ladders.run_ladders(chosen, pool, tolerances=(1e-4, 1e-8), budget_s=math.inf)
    assert [(p["formulation"], p["tolerance"]) for p in points] == [("quaternion", 1e-4), ("quaternion", 1e-8),
                                                                     ("gibbs", 1e-4), ("gibbs", 1e-8)]
    assert all(p["status"] == "ok" and p["us_per_sim_s"] > 0 for p in points), points


def test_the_tolerance_ladder_stops_at_a_point_over_its_budget(stub_engine):
    family = tolerance_ladders.AdaptiveFamily(_short_case(), "stub", "", "stub_dop853")
    points = tolerance_ladders.run_ladder(family, (1e-3, 1e-4, 1e-5), budget_s=0.0)
    assert len(points) == 1 and "ladder stopped after this point" in points[0]["message"]


class _OmegaOffSimulation:
    """The truth's own attitude (no attitude error at all) with ω 1e-5 too large: an error in ω alone."""

    def __init__(self, case):
        self.case = case

    def run(self, grid):
        from stereodyn.reference import truth

        exact = truth.truth(self.case.body, self.case.quat0, self.case.omega0, grid.times)
        return Trajectory(grid.times, exact.quat, exact.omega * (1 + 1e-5), Status.OK, "", math.nan, 100, 400, {})


class OmegaOffEngine(StubEngine):
    name = "stub"

    def prepare(self, case, integrator, dt, tolerance=None):
        return _OmegaOffSimulation(case)


def test_err_over_tol_is_the_state_error_over_the_tolerance(monkeypatch):
    """err_over_tol divides the state error (the max of attitude_err, omega_err, casimir_drift), not the attitude
    error: a run whose attitude is exact but whose ω is off by 1e-5 is 10x over a tolerance of 1e-6."""
    registered = engines._entry_points()
    entry = type("_OmegaOffEntry", (_Entry,), {"load": lambda self: OmegaOffEngine})()
    monkeypatch.setattr(engines, "_entry_points", lambda: {**registered, "stub": entry})
    engines.get_engine.cache_clear()
    try:
        point = tolerance_ladders.measure(tolerance_ladders.AdaptiveFamily(_short_case(), "stub", "", "stub_dop853"),
                                          1e-6)
    finally:
        engines.get_engine.cache_clear()
    assert point["status"] == "ok" and point["attitude_err"] < 1e-15
    assert point["omega_err"] == pytest.approx(1e-5, rel=1e-6)
    assert point["state_err"] == point["omega_err"] and point["err_over_tol"] == pytest.approx(10.0, rel=1e-6)


# ------------------------------------------------------------------------------------------------ the fit

def _points(slope: float, c: float, floor: float, tolerances=tolerance_ladders.TOLERANCES, steps=1000):
    tol = np.asarray(tolerances, dtype=float)
    return pd.DataFrame({"tolerance": tol, "steps": steps, "status": "ok", "state_err": c * tol ** slope + floor})


FLOOR = 1e-13  # what rounding leaves over 1000 steps; the fit's lower edge is 30 eps steps = 6.7e-12


# (slope, c): err = c tol^slope + FLOOR at tol 1e-3 ... 1e-13; counted by hand: the points within 6.7e-12 <= err <=
# 3e-2, how many of them have err <= tol, and the tolerance of the worst err / tol.
@pytest.mark.parametrize("slope, c, points, below, worst", [(1.0, 20.0, 10, 0, 1e-12), (0.8, 3.0, 11, 0, 1e-13),
                                                            (0.9, 0.1, 9, 7, 1e-11)])
def test_tolerance_fit_recovers_the_proportionality_above_round_off(slope, c, points, below, worst):
    fit = fitting.tolerance_fit(_points(slope, c, FLOOR))
    assert fit["slope"] == pytest.approx(slope, abs=0.01)  # the floor's share of the fitted points is <= 1.5%
    assert (fit["points"], fit["below_tol"], fit["tol_max"]) == (points, below, 1e-3)
    assert fit["tol_min"] == pytest.approx(10.0 ** -(points + 2), rel=1e-12)
    assert fit["max_err_over_tol"] == pytest.approx(c * worst ** (slope - 1.0) + FLOOR / worst, rel=1e-9)
    assert ("outside" in fit["note"]) == (points < 11)  # the points in the floor are left out, and said so


def test_tolerance_fit_counts_the_points_below_the_tolerance():
    fit = fitting.tolerance_fit(_points(1.0, 0.5, 0.0, (1e-4, 1e-6, 1e-8)))
    assert fit["below_tol"] == 3 and fit["max_err_over_tol"] == pytest.approx(0.5)
    fit = fitting.tolerance_fit(_points(1.0, 2.0, 0.0, (1e-4, 1e-6, 1e-8)))
    assert fit["below_tol"] == 0 and fit["max_err_over_tol"] == pytest.approx(2.0)


def test_tolerance_fit_leaves_out_failed_points_and_needs_two():
    points = _points(1.0, 1.0, 0.0, (1e-4, 1e-6))
    points.loc[1, "status"] = "failed"
    fit = fitting.tolerance_fit(points)
    assert math.isnan(fit["slope"]) and fit["points"] == 1 and "1 point(s) not ok" in fit["note"]


# ------------------------------------------------------------------------------------------------ What to use

def _fixed(integrator, dt, err, cost, spread=0.0, rhs=400.0):
    return {"case": "c", "engine": "e", "formulation": "", "integrator": integrator, "dt": dt, "attitude_err": err,
            "wall_s": cost * 2e-6, "us_per_step_spread": spread * 2.0 / (2.0 / dt), "t_end": 2.0, "steps": 2.0 / dt,
            "rhs_per_sim_s": rhs, "status": "ok"}


def _any(table: pd.DataFrame) -> pd.DataFrame:
    return table[table["scope"] == "any"]


def test_an_adaptive_point_cheaper_than_every_fixed_step_run_wins_its_cell():
    results = pd.DataFrame([_fixed("rk4", 0.01, 9e-7, 100.0), _fixed("rk4", 0.001, 9e-10, 1000.0),
                            # the sweep's adaptive row (dt NaN, default tolerance): 80 µs/s for 5e-9
                            _fixed("dop", math.nan, 5e-9, 80.0) | {"steps": 40.0, "us_per_step_spread": 0.0}])
    tolerance = pd.DataFrame([{"case": "c", "engine": "e", "formulation": "", "integrator": "dop", "tolerance": tol,
                               "attitude_err": err, "us_per_sim_s": cost, "us_per_sim_s_spread": 0.0,
                               "rhs_per_sim_s": 100.0, "steps": 10, "status": "ok"}
                              for tol, err, cost in ((1e-6, 5e-7, 40.0), (1e-10, 4e-11, 300.0))])
    table = fitting.pareto(results, pd.DataFrame(), tolerance=tolerance)
    assert tuple(table.columns) == fitting.PARETO_COLUMNS and fitting.PARETO_COLUMNS[6:8] == ("dt", "tolerance")
    table = _any(table).set_index("target")
    # 1e-6: the tolerance point (40) beats rk4 dt=0.01 (100): source and tolerance say where it came from
    cell = table.loc[1e-6]
    assert (cell.integrator, cell.source, cell.tolerance) == ("dop", "tolerance_ladder", 1e-6)
    assert math.isnan(cell["dt"])
    # 1e-8: the sweep's adaptive row (80) beats rk4 dt=0.001 (1000) and the 1e-10 point (300)
    cell = table.loc[1e-8]
    assert (cell.integrator, cell.source) == ("dop", "sweep") and math.isnan(cell.tolerance)
    assert (table.loc[1e-10, "integrator"], table.loc[1e-10, "source"]) == ("dop", "tolerance_ladder")
    assert table.loc[1e-11, "source"] == "none reached it"
    cells = fitting.setting(table.loc[1e-6]), fitting.setting(table.loc[1e-8])
    assert cells == ("tol=1e-06", "default tol")


def test_an_adaptive_point_within_the_timing_noise_of_a_fixed_step_run_is_a_tie():
    rtol = fitting.TIE_RTOL
    results = pd.DataFrame([_fixed("rk4", 0.01, 9e-7, 100.0, rhs=400.0)])
    tolerance = pd.DataFrame([{"case": "c", "engine": "e", "formulation": "", "integrator": "dop", "tolerance": 1e-6,
                               "attitude_err": 5e-7, "us_per_sim_s": 100.0 * (1 - 0.5 * rtol),
                               "us_per_sim_s_spread": 0.0, "rhs_per_sim_s": 900.0, "steps": 10, "status": "ok"}])
    cell = _any(fitting.pareto(results, pd.DataFrame(), tolerance=tolerance)).set_index("target").loc[1e-6]
    # cheaper by half the tie floor: a tie, and the fixed-step run needs fewer evaluations, so it is shown
    assert (cell.integrator, cell.source) == ("rk4", "sweep") and "e dop tol=1e-06" in cell.ties


def test_a_tie_with_a_run_that_does_not_count_its_evaluations_goes_to_the_cheaper():
    """heyoka's taylor has no right-hand-side count: a tie it is in is decided by the best time, not by a count it
    lacks (which would make it lose every tie, however much cheaper)."""
    results = pd.DataFrame([_fixed("euler", 0.005, 9e-3, 300.0, spread=40.0, rhs=200.0),
                            _fixed("taylor", math.nan, 3e-15, 270.0, rhs=math.nan)
                            | {"steps": 55.0, "us_per_step_spread": 10.0 * 2.0 / 55.0}])
    cell = _any(fitting.pareto(results, pd.DataFrame())).set_index("target").loc[1e-2]
    assert cell.integrator == "taylor" and "e euler dt=0.005" in cell.ties  # still a tie, within euler's spread


def test_an_adaptive_row_with_no_error_at_all_is_the_reference_and_no_candidate():
    """The sliding ladder's equation (an adaptive row measured against itself: error exactly 0) never wins a cell."""
    results = pd.DataFrame([_fixed("rk4", 0.01, 9e-7, 100.0),
                            _fixed("theta", math.nan, 0.0, 1.0) | {"steps": 40.0, "us_per_step_spread": 0.0}])
    table = _any(fitting.pareto(results, pd.DataFrame())).set_index("target")
    assert table.loc[1e-6, "integrator"] == "rk4" and table.loc[1e-12, "source"] == "none reached it"


def test_the_default_run_ladders_the_adaptive_methods_of_each_engines_default_sweep():
    from stereodyn.harness.analysis import workprecision
    from stereodyn.harness.scenes.cases import find_case
    from stereodyn.harness.engines import UnavailableEngine, get_engine

    engines = ["reference"] + ([] if isinstance(get_engine("drake"), UnavailableEngine) else ["drake"])
    chosen = workprecision.default_tolerance_families([find_case("free-asymmetric")], engines, None)
    by_engine = {e: {f.integrator for f in chosen if f.engine == e} for e in engines}
    assert {"taylor", "scipy_dop853", "scipy_radau"} <= by_engine["reference"]
    assert {f.formulation for f in chosen if f.engine == "reference"} == {"quaternion"}
    if "drake" in engines:  # its one default adaptive scheme, on its first model
        assert by_engine["drake"] == {"runge_kutta3_adaptive"}
        assert {f.formulation for f in chosen if f.engine == "drake"} == {"rpy_ball"}
    named = workprecision.default_tolerance_families([find_case("free-asymmetric")], engines, ["radau3_adaptive"])
    assert {f.integrator for f in named} == ({"radau3_adaptive"} if "drake" in engines else set())
