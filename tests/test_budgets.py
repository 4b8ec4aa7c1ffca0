"""Every run ends in bounded time (harness.budget): each engine's loop stops at its run's wall-time budget, a run, a
preparation or a truth past its budget is a failed row naming it, stored as such, and redone by --resume only once
that budget is raised.

No timing is asserted: each stopped run here would take minutes (1e7 steps, a propagation over 1e5 s) without its
budget, so a test that passes has seen it stop."""
import dataclasses
import time

import pandas as pd
import pytest
from helpers import installed_engine, store_mtimes, store_records, tiny_case

from stereodyn.harness import budget, cli
from stereodyn.harness.engines import get_engine
from stereodyn.harness.grid import time_grid
from stereodyn.harness.scenes.cases import find_case, with_overrides
from stereodyn.reference import truth as reference_truth

LONG = 1e3  # s of simulated time: 1e7 steps at dt = 1e-4, far beyond any budget here


def test_a_deadline_holds_inside_its_block_only_and_the_earlier_one_wins():
    assert budget.deadline() is None
    budget.check()  # no deadline: nothing to exceed
    with budget.within("truth", 1e3):
        outer = budget.deadline()
        with budget.within("run", 1e6):  # a later deadline inside does not extend the outer one
            assert budget.deadline() == outer
        with budget.within("run", 0.0):
            with pytest.raises(budget.BudgetExceeded, match=r"^run budget exceeded: stopped after 0 s of wall "
                                                           r"time \(--run-budget raises it\)$"):
                list(budget.pieces(0, 10_000))
        assert budget.deadline() == outer
    assert budget.deadline() is None


def test_a_reference_propagation_out_of_time_leaves_within_as_the_budget():
    case = find_case("free-asymmetric")
    with pytest.raises(budget.BudgetExceeded) as stopped:
        with budget.within("truth", 0.0):
            reference_truth.truth(case.body, case.quat0, case.omega0, [0.0, 1e5], deadline=budget.deadline())
    assert stopped.value.what == "truth" and "--truth-budget" in str(stopped.value)


# Every built-in loop: the harness's integrators (Pinocchio, the reference formulations), MuJoCo's rollout chunks and
# its Python step loop (a torque), scipy's methods, heyoka's Taylor runs, Drake's fixed-step and error-controlled
# integrators (its simulator's monitor), Bullet's and MuJoCo Warp's step loops, and the sliding ladder's models and
# equation. Not MJX: its rollout is one compiled XLA call (docs/limits.md, "Time").
RIGID = [("free-asymmetric", "pinocchio", "", "rk4", 1e-4), ("free-asymmetric", "mujoco", "", "rk4", 1e-4),
         ("self-excited-conic", "mujoco", "", "rk4", 1e-4),
         ("free-asymmetric", "reference", "quaternion", "rk4", 1e-4),
         ("free-asymmetric", "reference", "quaternion", "scipy_rk45", None),
         ("free-asymmetric", "reference", "gibbs", "taylor", None),
         ("free-asymmetric", "drake", "rpy_ball", "runge_kutta2", 1e-4),
         ("free-asymmetric", "drake", "rpy_ball", "runge_kutta3_adaptive", None),
         ("free-asymmetric", "bullet", "", "semi_implicit_euler", 1e-4),
         ("self-excited-conic", "bullet", "", "semi_implicit_euler", 1e-4),
         ("free-asymmetric", "warp", "", "euler", 1e-4)]


@pytest.mark.parametrize("name, engine, formulation, integrator, dt", RIGID)
def test_every_engine_loop_stops_at_the_run_budget(name, engine, formulation, integrator, dt):
    case = with_overrides(find_case(name), t_end=LONG, dt=1e-4)
    extra = {"formulation": formulation} if formulation else {}
    sim = installed_engine(engine).prepare(case, integrator, dt, **extra)
    grid = time_grid(LONG, dt or LONG / 99, 100)
    with pytest.raises(budget.BudgetExceeded, match="run budget exceeded"):
        with budget.within("run", 0.05):
            sim.run(grid)


@pytest.mark.parametrize("spacing", [1, budget.CHECK_EVERY, budget.CHECK_EVERY + 1])
def test_drake_stops_at_the_run_budget_with_dense_and_sparse_samples(spacing):
    # Drake's fixed-step runs are checked between samples up to CHECK_EVERY steps apart, and by the simulator's
    # monitor beyond (harness/engines/drake.py, _watch): both sides of the switch stop
    case = with_overrides(find_case("free-asymmetric"), t_end=LONG, dt=1e-4)
    sim = installed_engine("drake").prepare(case, "runge_kutta2", 1e-4, formulation="rpy_ball")
    spans = 400_000 // spacing
    grid = time_grid(spans * spacing * 1e-4, 1e-4, spans + 1)  # ~4e5 steps, seconds: far beyond the budget
    assert int(max(grid.sample_steps[1:] - grid.sample_steps[:-1])) == spacing
    with pytest.raises(budget.BudgetExceeded, match="run budget exceeded"):
        with budget.within("run", 0.05):
            sim.run(grid)


# Samples every step, or every few steps: each span between two samples is <= CHECK_EVERY steps, so the loops take
# budget.pieces()'s fast path (one range, no generator), which must look at the clock too. The grids above have
# thousands of steps between samples and take the other path.
DENSE = [("free-asymmetric", "pinocchio", "", "rk4"), ("free-asymmetric", "reference", "quaternion", "rk4"),
         ("self-excited-conic", "mujoco", "", "rk4"), ("free-asymmetric", "bullet", "", "semi_implicit_euler")]


@pytest.mark.parametrize("spacing", [1, 7, budget.CHECK_EVERY])
@pytest.mark.parametrize("name, engine, formulation, integrator", DENSE)
def test_a_python_step_loop_with_a_sample_every_few_steps_stops_at_the_run_budget(name, engine, formulation,
                                                                                   integrator, spacing):
    case = with_overrides(find_case(name), t_end=LONG, dt=1e-4)
    extra = {"formulation": formulation} if formulation else {}
    sim = installed_engine(engine).prepare(case, integrator, 1e-4, **extra)
    spans = 100_000 // spacing
    grid = time_grid(spans * spacing * 1e-4, 1e-4, spans + 1)  # ~1e5 steps: about a second or more, 20x the budget
    assert int(max(grid.sample_steps[1:] - grid.sample_steps[:-1])) == spacing <= budget.CHECK_EVERY
    with pytest.raises(budget.BudgetExceeded, match="run budget exceeded"):
        with budget.within("run", 0.05):
            sim.run(grid)


@pytest.mark.parametrize("engine, model, integrator, dt", [("reference", "theta", "taylor", None),
                                                           ("mujoco", "bilateral", "rk4", 1e-5),
                                                           ("pinocchio", "bilateral", "rk4", 1e-5)])
def test_the_sliding_ladder_stops_at_the_run_budget(engine, model, integrator, dt):
    case = find_case("sliding-ladder")
    # the extreme rod of issue 22: l = 1e-9 m, g = 1e6 m/s^2 (sqrt(g/l) ~ 3e7 rad/s) for the equation
    ladder = dataclasses.replace(case.ladder, mass=1e6, half_length=1e-9, g=1e6) if dt is None else case.ladder
    case = dataclasses.replace(case, ladder=ladder, t_end=LONG if dt else 1.5, dt=(dt or 1e-3,))
    sim = installed_engine(engine).models()["sliding_ladder"].prepare(case, model, integrator, dt)
    grid = time_grid(case.t_end, dt or case.t_end / 99, 100)
    with pytest.raises(budget.BudgetExceeded):
        with budget.within("run", 0.05):
            sim.run(grid)


CASE = tiny_case("budgeted", t_end=2.0, dt="1e-3")  # 2000 steps: long enough to pass a tiny budget


@pytest.fixture
def budgeted(tmp_path):
    path = tmp_path / "budgeted.toml"
    path.write_text(CASE)
    out = tmp_path / "out"

    def run(*options: str) -> pd.DataFrame:
        argv = ["run", "--case-file", str(path), "--engines", "pinocchio", "--integrators", "rk4", "--jobs", "1",
                "--quiet", "--no-ladder", "--out", str(out), *options]
        assert cli.main(argv) == 0
        return pd.read_csv(out / "results.csv", keep_default_na=False).set_index(["engine", "integrator"])

    return out, run


@pytest.mark.parametrize("what, flag, tiny", [("run", "--run-budget", "0.001"), ("prepare", "--prepare-budget",
                                                                                    "0.001")])
def test_a_row_past_its_budget_is_failed_stored_so_and_redone_only_when_the_budget_is_raised(budgeted, what, flag,
                                                                                             tiny, monkeypatch):
    """2000 steps of Pinocchio's RK4 (~20 ms) against a 1 ms run budget; a preparation made to take 20 ms (the model
    is cached per process, so building it may take less than the 1 ms) against a 1 ms prepare budget."""
    out, run = budgeted
    engine = get_engine("pinocchio")
    slow = type(engine).prepare

    def slow_prepare(*args, **kwargs):
        time.sleep(0.02)
        return slow(engine, *args, **kwargs)

    monkeypatch.setattr(engine, "prepare", slow_prepare)
    rows = run(flag, tiny)
    stopped = rows.loc[("pinocchio", "rk4")]
    assert stopped.status == "failed"
    assert stopped.message == f"{what} budget exceeded: stopped after 0.001 s of wall time ({flag} raises it)"
    assert stopped.attitude_err == "" and stopped.wall_s == ""  # no numbers from a run that did not finish
    records = store_records(out)
    [record] = [r for r in records.values() if r["row"]["engine"] == "pinocchio"]
    assert record["budget"] == {"what": what, "seconds": 0.001}
    before = store_mtimes(out)
    assert run(flag, tiny, "--resume").loc[("pinocchio", "rk4")].status == "failed"
    assert store_mtimes(out) == before  # the same budget: the stored rows serve, the failure included
    other = "--truth-budget" if what == "run" else "--run-budget"
    run(flag, tiny, other, "500", "--resume")  # another budget raised: this row would stop again, so it is reused
    assert store_mtimes(out) == before
    again = run(flag, "60", "--resume")  # its budget raised: redone, now ok
    assert again.loc[("pinocchio", "rk4")].status == "ok" and float(again.loc[("pinocchio", "rk4")].attitude_err) > 0
    after = store_mtimes(out)
    redone = {name for name in before if after.get(name) != before[name]}
    assert redone == {f"{record['key']}.json"}
    assert "budget" not in store_records(out)[f"{record['key']}.json"]


def test_a_truth_past_its_budget_fails_its_case_and_is_redone_when_raised(budgeted):
    out, run = budgeted
    rows = run("--truth-budget", "0.001")
    assert set(rows.status) == {"failed"} and len(rows) == 1
    assert set(rows.message) == {"truth failed: truth budget exceeded: stopped after 0.001 s of wall time "
                                 "(--truth-budget raises it)"}
    assert {r["budget"]["what"] for r in store_records(out).values()} == {"truth"}
    assert set(run("--truth-budget", "0.001", "--resume").status) == {"failed"}
    assert set(run("--truth-budget", "120", "--resume").status) == {"ok"}


@pytest.mark.parametrize("value", ["0", "-1", "nan", "inf", "1e7", "abc"])
def test_a_budget_outside_its_range_is_one_line_exit_2(value, capsys):
    assert cli.main(["run", "--run-budget", value, "--out", "unused"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--run-budget" in err, err


def test_a_stored_budget_that_is_not_what_this_version_writes_redoes_the_run():
    budgets = budget.Budgets()
    assert budget.still_holds(None, budgets)
    assert budget.still_holds({"what": "run", "seconds": budgets.run_s}, budgets)
    assert not budget.still_holds({"what": "run", "seconds": budgets.run_s / 2}, budgets)
    assert not budget.still_holds({"what": "nothing", "seconds": 1.0}, budgets)
    assert not budget.still_holds(["run", 60], budgets)
