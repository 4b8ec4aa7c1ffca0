"""The pipeline of `stereodyn run` (harness.pipeline.phases): its phases in the issue's order, each need given by an
earlier phase, run() handing each step only what it declared, a worker pool for each stretch of pool phases, and a
phase that breaks its declaration is our bug (AssertionError: exit 3), never a row. No simulation runs here."""
from contextlib import contextmanager

import pytest

from stereodyn.harness import budget
from stereodyn.harness.pipeline import phases
from stereodyn.harness.pipeline.phases import PHASES, Phase, Request, run
from stereodyn.harness.run import sweep
from stereodyn.harness.run.sweep import SweepOptions


def test_the_phases_of_run_in_order_each_need_given_before():
    assert [p.name for p in PHASES] == ["truths and sweep", "ladders", "advice", "verdicts", "What to use", "report"]
    given: set[str] = set()
    for phase in PHASES:
        assert set(phase.needs) <= given, f"{phase.name} needs {set(phase.needs) - given}"
        assert not set(phase.gives) & given, f"{phase.name} gives again {set(phase.gives) & given}"
        given |= set(phase.gives)
    # one pool for the whole command: the runs go to it, and the report draws its figures on its workers (verdicts'
    # check runs stay in this process, as before)
    assert all(p.in_pool for p in PHASES)


@pytest.fixture
def request_(tmp_path, monkeypatch):
    pools = []

    @contextmanager
    def fake_pool(jobs):
        pools.append(object())
        yield pools[-1]

    monkeypatch.setattr(sweep, "worker_pool", fake_pool)
    monkeypatch.setattr(budget, "_CONFIGURED", [budget.configured()])  # run() configures this process's budgets
    monkeypatch.setattr(phases, "_quiet_engines", lambda out: None)  # leaves the environment as it was
    options = SweepOptions(["reference"], tmp_path, jobs=1)
    return Request([], options, "off", None, budget.Budgets(7.0, 8.0, 9.0), quiet=True), pools


def test_run_passes_each_step_its_needs_only_and_pools_each_stretch(request_):
    request, pools = request_
    seen = []

    def step(name, gives):
        def run_step(req, values, pool, progress):
            seen.append((name, sorted(values), pool))
            return {g: f"{name}:{g}" for g in gives}
        return run_step

    chosen = (Phase("a", (), ("x",), step("a", ("x",)), in_pool=True),
              Phase("b", ("x",), ("y",), step("b", ("y",)), in_pool=True),
              Phase("c", ("y",), ("z",), step("c", ("z",))),
              Phase("d", ("x", "z"), ("w",), step("d", ("w",)), in_pool=True))
    values = run(request, chosen)
    assert values == {"x": "a:x", "y": "b:y", "z": "c:z", "w": "d:w"}
    assert len(pools) == 2  # a and b share one pool, d gets its own, c none
    assert seen == [("a", [], pools[0]), ("b", ["x"], pools[0]), ("c", ["y"], None), ("d", ["x", "z"], pools[1])]
    assert budget.configured() == budget.Budgets(7.0, 8.0, 9.0)


def test_a_phase_that_breaks_its_declaration_is_our_bug(request_):
    request, _ = request_
    wrong = (Phase("a", (), ("x",), lambda *args: {"x": 1, "extra": 2}),)
    with pytest.raises(AssertionError, match=r"phase 'a' gave \['extra', 'x'\], not its declared \['x'\]"):
        run(request, wrong)
    early = (Phase("b", ("x",), ("y",), lambda *args: {"y": 1}),)
    with pytest.raises(AssertionError, match="phase 'b' needs x, which no earlier phase gives"):
        run(request, early)


def test_the_report_draws_its_figures_on_the_runs_worker_pool(request_, monkeypatch):
    """The pool's workers have imported most of what drawing needs: the report spawns no processes of its own."""
    from stereodyn.harness.report import build
    from stereodyn.harness.run import store
    from stereodyn.harness.run.progress import ProgressBar

    request, _ = request_

    class Pool:
        def map(self, fn, items):
            return [fn(item) for item in items]

    pool, given = Pool(), {}
    monkeypatch.setattr(build, "write_reports", lambda out, results, **options: given.update(options) or ("md", "h"))
    monkeypatch.setattr(store, "mark_complete", lambda out: None)
    phases._report(request, {"results": None, "verdicts": None}, pool, ProgressBar(enabled=False))
    assert given["render_map"] == pool.map
    phases._report(request, {"results": None, "verdicts": None}, None, ProgressBar(enabled=False))
    assert given["render_map"] is None  # --jobs 1: no pool, the report's own processes
