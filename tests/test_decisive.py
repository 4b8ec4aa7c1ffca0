"""Time only what decides (issue 29 item 3): analysis.decisive picks the runs whose time can change a "What to use"
cell; the sweep's timing phase times those with repeats and every other run once."""
from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from stereodyn.harness.analysis import decisive, gate
from stereodyn.harness.analysis.pareto import pareto_table
from stereodyn.harness.run import timing
from stereodyn.harness.run.results import SINGLE

NAN = math.nan


def _runs(rows):
    """A sweep table: (case, engine, integrator, dt, status, attitude_err, us_per_sim_s) per run."""
    return pd.DataFrame(rows, columns=["case", "engine", "integrator", "dt", "status", "attitude_err", "us_per_sim_s"])


def test_a_run_decides_within_the_margin_of_the_fastest_of_its_cell():
    runs = _runs([
        ("c", "mujoco", "euler", 1e-2, "ok", 5e-3, 100.0),    # 0: the fastest reaching 1e-2
        ("c", "mujoco", "rk4", 1e-2, "ok", 3e-3, 290.0),      # 1: 2.9x slower in the 1e-2 cell: within MARGIN (3)
        ("c", "mujoco", "rk4b", 1e-2, "ok", 4e-3, 310.0),     # 2: 3.1x slower in the same cell: never a tie-mate
        ("c", "mujoco", "rk4", 1e-3, "ok", 2e-10, 1000.0),    # 3: the only run reaching 1e-10: decides that cell
        ("c", "mujoco", "euler", 1e-3, "ok", 5e-2, 50.0),     # 4: reaches no target: never a candidate
        ("c", "pinocchio", "rk4", 1e-2, "ok", 3e-3, 900.0),   # 5: 9x mujoco's, but its own engine's scope's fastest
        ("c", "mujoco", "implicit", 1e-2, "diverged", 1e-3, 1.0),  # 6: not ok
        ("d", "mujoco", "rk4", 1e-2, "ok", 3e-3, 800.0),      # 7: another case: its own fastest
        ("c", "mujoco", "euler", 3e-3, "ok", 1.5e-3, NAN),    # 8: untimed
        ("c", "reference", "taylor", NAN, "ok", 0.0, 1.0),    # 9: the exact reference row: pareto's non-candidate
        ("c", "reference", "scipy_rk45", NAN, "ok", 1e-8, 5000.0),  # 10: adaptive, its scope's only one
    ], )
    assert decisive.decisive(runs) == {0, 1, 3, 5, 7, 10}
    assert decisive.decisive(runs, margin=3.2) == {0, 1, 2, 3, 5, 7, 10}


def test_the_winners_and_ties_of_pareto_are_decisive_runs():
    """Every winner and tie-mate pareto names from the single times is in the set, in every scope; a run more than
    MARGIN times slower than its engine's fastest at its accuracy is not."""
    rows = []
    for engine, integrator, err, cost in [
            ("mujoco", "euler", 4e-3, 10.0), ("mujoco", "rk4", 3e-9, 40.0), ("mujoco", "rk4b", 2e-12, 120.0),
            ("pinocchio", "euler", 4e-3, 14.0), ("pinocchio", "rk4", 3e-9, 45.0), ("pinocchio", "rk4b", 2e-12, 160.0),
            ("reference", "rk4", 3e-9, 400.0), ("reference", "rk4b", 2e-12, 1300.0), ("drake", "rk3", 1e-6, 60.0),
            ("drake", "rk3b", 1e-8, 130.0), ("mujoco", "implicit", 5e-3, 10.3), ("reference", "euler", 3e-3, 200.0),
            ("reference", "rk2", 2e-3, 900.0), ("mujoco", "rk2", 1e-4, 130.0)]:
        rows.append({"case": "c", "engine": engine, "formulation": "", "integrator": integrator, "dt": 1e-2,
                     "tolerance": NAN, "attitude_err": err, "us_per_sim_s": cost, "us_per_sim_s_spread": NAN,
                     "rhs_per_sim_s": NAN, "steps": 100, "source": "sweep", "status": "ok"})
    runs = pd.DataFrame(rows)
    table = pareto_table(runs, ["c"])
    name = {f"{r.engine} {r.integrator}": i for i, r in runs.iterrows()}
    won = {name[f"{r.engine} {r.integrator}"] for r in table[table["engine"].astype(bool)].itertuples()}
    tied = {name[" ".join(t.split()[:2])] for ties in table["ties"] if ties for t in ties.split("; ")}
    chosen = decisive.decisive(runs)
    assert won and tied and won | tied <= chosen
    # reference rk2: 4.5x reference euler, mujoco rk2 3.25x mujoco rk4, each more accurate than it
    assert set(runs.index) - chosen == {name["reference rk2"], name["mujoco rk2"]}


def _fake_group(durations):
    """Runs of one engine whose run() advances a fake clock by its duration; calls counts the runs made."""
    clock, calls = [0.0], {}

    class Sim:
        def __init__(self, name):
            self.name = name

        def run(self, grid):
            calls[self.name] = calls.get(self.name, 0) + 1
            clock[0] += durations[self.name]

    specs = [SimpleNamespace(engine="nope", precision="float64", name=name) for name in durations]
    return specs, (lambda spec: (Sim(spec.name), "grid")), clock, calls


def test_time_runs_repeats_only_the_selected_runs(monkeypatch):
    specs, prepare, clock, calls = _fake_group({"fast": 0.01, "slow": 1.5, "mid": 0.02})
    monkeypatch.setattr(timing.time, "perf_counter", lambda: clock[0])
    monkeypatch.setattr(timing, "warm_up", lambda sim, grid, engine: sim.run(grid))
    seen = []

    def select(indices, seconds):
        seen.append(dict(zip(indices, seconds)))
        return {i for i, s in zip(indices, seconds) if s < 0.1}

    rows = timing.time_runs(specs, [100, 100, 100], prepare, select)
    assert seen == [{0: pytest.approx(0.01), 1: pytest.approx(1.5), 2: pytest.approx(0.02)}]
    # warm-up + one timed run for each (no single time: timed once first, a chunk of its own); then for the chosen
    # a warm-up + 2 repeats where they are timed again (the single one counts among the 3)
    assert calls == {"fast": 5, "slow": 2, "mid": 5}
    assert rows[1]["timing"] == SINGLE and math.isnan(rows[1]["us_per_step_spread"])
    assert rows[1]["us_per_step"] == pytest.approx(1.5 / 100 * 1e6)
    assert rows[0]["timing"] == "best of 3" and rows[0]["us_per_step_spread"] == pytest.approx(0.0)
    # without select every run is timed with repeats; the slow one, over BUDGET_S, still gets MIN_REPEATS more
    # after its single time (which counts among REPEATS: timing.measure_interleaved's first)
    calls.clear()
    rows = timing.time_runs(specs, [100, 100, 100], prepare)
    assert calls == {"fast": 5, "slow": 5, "mid": 5} and rows[1]["timing"] == "best of 3"


def test_the_gate_checks_the_time_of_repeated_rows_only():
    base = {"case": "c", "engine": "e", "formulation": "", "integrator": "i", "precision": "float64", "dt": 0.01,
            "status": "ok", "us_per_step": 1.0}
    slow = dict(base, us_per_step=10.0)
    tolerances = gate.Tolerances(time_factor=3.0)
    table = pd.DataFrame([dict(slow, timing="best of 3")])
    assert [f.what for f in gate.compare(table, [base], tolerances)] == ["us_per_step"]
    assert gate.compare(pd.DataFrame([dict(slow, timing=SINGLE)]), [base], tolerances) == []


def test_a_ladder_point_decides_against_the_sweeps_runs_as_rivals():
    """deciding_points: the ladders' points, each with its single time, decide with the sweep's runs (their wall_s
    over t_end) as the rivals in their cells; the indices are the points' own."""
    sweep = pd.DataFrame([  # one mujoco run reaching 1e-3 at 100 µs per simulated second (1e-4 s over 1 s)
        {"case": "c", "engine": "mujoco", "dt": 1e-2, "status": "ok", "attitude_err": 5e-4, "wall_s": 1e-4,
         "t_end": 1.0}])
    point = {"case": "c", "engine": "mujoco", "dt": 5e-3, "status": "ok"}
    points = [dict(point, attitude_err=4e-4, us_per_sim_s=250.0),   # 0: 2.5x the sweep's run: within MARGIN
              dict(point, attitude_err=4e-4, us_per_sim_s=400.0),   # 1: 4x: can neither win nor tie
              dict(point, attitude_err=1e-7, us_per_sim_s=900.0),   # 2: the only one reaching 1e-7
              dict(point, attitude_err=1e-7, us_per_sim_s=NAN),     # 3: untimed
              dict(point, engine="pinocchio", attitude_err=4e-4, us_per_sim_s=5000.0)]  # 4: its own engine's fastest
    assert decisive.deciding_points(sweep, points) == {0, 2, 4}
    assert decisive.deciding_points(sweep.iloc[:0], points) == {0, 1, 2, 4}  # without the sweep's rival
    assert decisive.deciding_points(sweep, []) == set()


@pytest.mark.parametrize("repeat", [False, True])
def test_the_sweep_times_once_what_decides_nothing(tmp_path, monkeypatch, repeat):
    """Every ok run is timed once in its worker, after its accuracy run, and decides() sees every one. It names
    nothing: no run is prepared again, each keeps its single time; names everything: each is prepared once in the
    timing phase and timed with repeats."""
    from helpers import case_file, tiny_case
    from stereodyn.harness.run import pool, sweep
    from stereodyn.harness.scenes.cases import load_case

    case = load_case(case_file(tmp_path, tiny_case(dt="1e-2, 5e-3")))
    prepared, seen = [], []
    real = pool.prepare  # the timing phase's (pool.prepare_kept: neither engine declares a start-up, none is kept)
    monkeypatch.setattr(pool, "prepare", lambda run: prepared.append(run.engine) or real(run))

    def decides(rows):
        seen.append(sorted(rows["engine"]))
        return set(rows.index) if repeat else set()

    df = sweep.run_sweep([case], sweep.SweepOptions(["mujoco", "reference"], tmp_path / "out", ["euler", "rk4"],
                                                    jobs=1, certify=False), decides=decides)
    ok = df[df["status"] == "ok"]
    assert set(ok["engine"]) == {"mujoco", "reference"} and np.isfinite(ok["wall_s"]).all()
    assert sorted(prepared) == (sorted(ok["engine"]) if repeat else []) and \
        sorted(sum(seen, [])) == sorted(ok["engine"])
    if repeat:
        assert set(ok["timing"]) <= {"best of 2", "best of 3"} and ok["us_per_step_spread"].notna().all()
    else:
        assert set(ok["timing"]) == {SINGLE} and ok["us_per_step_spread"].isna().all()


def test_the_advice_does_not_report_a_single_time():
    """An advised setting that is a sweep run timed once is timed with repeats by the advice itself (its known point
    carries no time); a sweep run timed with repeats lends its time."""
    from stereodyn.harness.analysis import step_advice as advice  # advice_tasks: its pure home
    from stereodyn.harness.run.spec import Family

    case = SimpleNamespace(name="c")
    family = Family(case, "mujoco", "", "rk4")
    base = {"case": "c", "engine": "mujoco", "formulation": "", "integrator": "rk4", "precision": "float64",
            "t_end": 10.0, "steps": 1000, "status": "ok", "attitude_err": 1e-6, "omega_err": 1e-6,
            "casimir_drift": 0.0}
    results = pd.DataFrame([dict(base, dt=1e-2, wall_s=0.01, timing="best of 3"),
                            dict(base, dt=5e-3, wall_s=0.03, timing=SINGLE)])
    convergence = pd.DataFrame([{"case": "c", "engine": "mujoco", "formulation": "", "integrator": "rk4",
                                 "precision": "float64", "order": 4.0}])
    empty = pd.DataFrame()
    (task,) = advice.advice_tasks([family], [], results, empty, empty, convergence, empty)
    times = {p["dt"]: p["us_per_sim_s"] for p in task[2]}
    assert times[1e-2] == pytest.approx(1000.0) and math.isnan(times[5e-3])


def test_a_single_time_from_a_runs_first_steps_follows_its_line(monkeypatch):
    """Issue 49 (the experiment): a Python-stepped run's single time is taken on its first WARM_UP_STEPS and first
    ~PARTIAL_S of steps and extrapolated along their line. On a run costing a + b steps exactly (a synthetic clock:
    timing.once answers the cost of the grid it ran), the extrapolation is the whole run's cost; an engine without a
    short warm-up, or an adaptive run, is timed whole. Break-checked: scaling the second partial alone (no
    intercept) misses a 5 ms fixed cost by its share."""
    from types import SimpleNamespace

    from stereodyn.harness.grid import time_grid

    fixed, per_step = 5e-3, 2e-6
    ran = []

    class Sim:
        def run(self, grid):
            ran.append(grid.steps)

    monkeypatch.setattr(timing, "once", lambda call: (call(), fixed + per_step * ran[-1])[1])
    grid = time_grid(10.0, 1e-4, 201)  # 100000 steps: 0.205 s whole
    got = timing.single_time(Sim(), grid, SimpleNamespace(engine="reference", dt=1e-4))
    assert abs(got - (fixed + per_step * grid.steps)) <= 1e-9 and max(ran) < grid.steps / 2, (got, ran)
    ran.clear()
    assert timing.single_time(Sim(), grid, SimpleNamespace(engine="mujoco", dt=1e-4)) == fixed + per_step * 100000
    assert ran == [grid.steps]
    ran.clear()
    assert timing.single_time(Sim(), grid, SimpleNamespace(engine="reference", dt=None)) == fixed + per_step * 100000
