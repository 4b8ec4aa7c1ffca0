"""How a local sweep schedules its runs: the cost model that orders them, and the worker pool's life."""
import multiprocessing

import pytest
from child_processes import ended, started_since, watch_exit

from stereodyn.harness.run.pool import cost, local_pool
from stereodyn.harness.run.sweep import SweepOptions, run_sweep
from stereodyn.harness.scenes.cases import find_case, with_overrides
from stereodyn.harness.run.plan import RunSpec


def spec(engine, integrator, dt, case="lagrange-top", formulation=""):
    return RunSpec(with_overrides(find_case(case), t_end=5.0), engine, integrator, dt, formulation=formulation)


def test_the_cost_grows_with_steps_stages_and_the_engines_cost_of_a_step():
    assert cost(spec("mujoco", "euler", 1e-3)) > cost(spec("mujoco", "euler", 1e-2))
    assert cost(spec("mujoco", "rk4", 1e-3)) > cost(spec("mujoco", "euler", 1e-3))
    assert cost(spec("pinocchio", "rk4", 1e-3)) > cost(spec("mujoco", "rk4", 1e-3))
    assert cost(spec("reference", "rk4", 1e-3, formulation="gibbs")) > cost(spec("pinocchio", "rk4", 1e-3))
    # a run on a slow engine goes before a run of more steps on a fast one: steps alone would say otherwise
    assert cost(spec("reference", "rk4", 3e-3, formulation="gibbs")) > cost(spec("mujoco", "euler", 1e-3))


def test_an_adaptive_run_is_not_ranked_below_the_engines_runs_at_the_finest_step():
    case = find_case("lagrange-top")
    adaptive = cost(spec("reference", "taylor", None, formulation="gibbs"))
    assert adaptive >= cost(spec("reference", "euler", min(case.dt), formulation="gibbs"))


def test_a_runs_cost_is_its_accuracy_run_checks_and_single_timed_run():
    """A worker runs the accuracy run, its metrics and checks (CHECK_PASSES), then times it once (timing.timed_once):
    2 + CHECK_PASSES passes of steps x stages x the engine's pass_us, plus the fixed overhead; the repeats of the runs
    that decide are the parent's, after the sweep, and cost the worker nothing."""
    from stereodyn.harness.engines import get_engine
    from stereodyn.harness.run import pool

    run = spec("reference", "rk4", 1e-3, formulation="gibbs")
    one_pass = 5000 * 4 * get_engine("reference").timing.pass_us * 1e-6  # t_end 5 s at 1e-3: 5000 steps of 4 stages
    assert cost(run) == pytest.approx(pool.RUN_OVERHEAD_S + (2 + pool.CHECK_PASSES) * one_pass, rel=1e-12)


def test_the_pool_starts_its_workers_before_any_run_is_submitted():
    before = set(multiprocessing.active_children())
    with local_pool(2, 5) as pool:
        workers = started_since(before)
        assert pool is not None and len(workers) == 2
    assert ended(workers)  # idle workers exit on their own after the sweep


def test_a_worker_told_to_stop_runs_its_exit_handlers_and_skips_the_interpreters_teardown(tmp_path):
    """An SDK may write its caches in an exit handler; freeing every module and model after the last task cost a worker
    of the quick suite 15-17 s of CPU while the report was drawing (harness.run.workers._exit)."""
    before = set(multiprocessing.active_children())
    with local_pool(2, 5) as pool:
        assert pool is not None
        pool.submit(watch_exit, str(tmp_path)).result(timeout=300)
        workers = started_since(before)
    assert ended(workers)
    assert (tmp_path / "exit-handler").read_text() == "ran"
    assert not (tmp_path / "teardown").exists()


@pytest.mark.parametrize("jobs, runs", [(1, 5), (2, 0)])
def test_a_sweep_in_process_or_without_runs_starts_no_pool(jobs, runs):
    """--jobs 1 in this process (STEREODYN_IN_PROCESS=1, tests/conftest.py), or nothing to run; a single run or
    --jobs 1 otherwise is a watched worker (tests/test_hung_engines.py)."""
    before = set(multiprocessing.active_children())
    with local_pool(jobs, runs) as pool:
        assert pool is None and not started_since(before)


def test_an_interrupt_while_computing_the_truth_ends_the_started_workers(tmp_path, monkeypatch):
    """Ctrl-C while the parent waits for the truths, which are pool tasks (issue 49): the workers end at once."""
    from stereodyn.harness.run import pool as run_pool

    before, workers = set(multiprocessing.active_children()), set()

    def interrupted(*args, **kwargs):
        workers.update(started_since(before))  # the workers compute the truth: the parent waits for it here
        raise KeyboardInterrupt

    monkeypatch.setattr(run_pool, "wait", interrupted)
    case = with_overrides(find_case("free-asymmetric"), t_end=0.2, dt=[1e-2, 5e-3])
    with pytest.raises(KeyboardInterrupt):
        run_sweep([case], SweepOptions(["mujoco"], tmp_path, ["euler"], jobs=2))
    assert len(workers) == 2 and ended(workers)
    assert 0 not in {p.exitcode for p in workers}  # ended at once (SIGKILL), not left to finish their start-up


def test_an_engine_whose_precision_is_process_global_gets_its_runs_one_precision_at_a_time(monkeypatch):
    """The runs of such an engine (Genesis: each change of precision re-initialised it, 8-11 s a run in the quick
    suite) trade places among those they hold, so that each precision's come together in the order first met; every
    other run keeps its place, and within a precision the order (the cost's) is kept."""
    from types import SimpleNamespace

    from stereodyn.harness.run import timing
    from stereodyn.harness.run.pool import one_precision_at_a_time

    monkeypatch.setattr(timing, "get_engine",
                        lambda name: SimpleNamespace(timing=SimpleNamespace(process_global_precision=name == "g")))
    runs = [SimpleNamespace(engine=e, precision=p, n=i) for i, (e, p) in enumerate(
        [("g", "float64"), ("m", "float64"), ("g", "float32"), ("g", "float64"), ("m", "float32"), ("g", "float32"),
         ("g", "float64")])]
    ordered = one_precision_at_a_time(runs)
    assert [r.n for r in ordered] == [0, 1, 3, 6, 4, 2, 5]
    assert [r.precision for r in ordered if r.engine == "g"] == ["float64"] * 3 + ["float32"] * 2
    assert [r.n for r in ordered if r.engine == "m"] == [1, 4]  # the others stay where they were
    assert one_precision_at_a_time([]) == []


def test_the_runs_of_an_engine_with_a_start_up_are_queued_first(monkeypatch):
    """pool.queue_key: a run's cost plus its engine's start-up, so the cheap runs of an engine that pays a start-up
    (Newton's: 45 s cold) come before costlier runs of engines that pay none, and the heavier start-up first; by cost
    alone Newton's start-up began at 67 s of the cold quick suite on one worker while the other idled."""
    from types import SimpleNamespace

    from stereodyn.harness.run import pool as pool_module

    monkeypatch.setattr(pool_module, "startup_s", lambda engine: {"n": 20.0, "m": 10.0}.get(engine, 0.0))
    monkeypatch.setattr(pool_module, "cost", lambda spec: spec.cost)
    runs = [SimpleNamespace(engine=e, cost=c) for e, c in [("r", 5.0), ("n", 0.1), ("r", 0.5), ("m", 0.2), ("n", 0.3)]]
    ordered = sorted(runs, key=pool_module.queue_key, reverse=True)
    assert [(r.engine, r.cost) for r in ordered] == [("n", 0.3), ("n", 0.1), ("m", 0.2), ("r", 5.0), ("r", 0.5)]


def test_the_sweep_queues_its_runs_by_cost_one_precision_at_a_time(tmp_path, monkeypatch):
    """The sweep hands its runs to the pool in the order one_precision_at_a_time gives the runs sorted by
    pool.queue_key (cost plus the engine's start-up; here a key that reverses the cost, to see it is the one used)."""
    from stereodyn.harness.run import sweep

    seen, queued = [], []
    real = sweep.one_precision_at_a_time
    monkeypatch.setattr(sweep, "one_precision_at_a_time", lambda specs: seen.append(list(specs)) or real(specs)[::-1])
    monkeypatch.setattr(sweep, "run_local", lambda specs, *args, **kwargs: queued.append(list(specs)))
    monkeypatch.setattr(sweep, "queue_key", lambda spec: -cost(spec))
    case = with_overrides(find_case("lagrange-top"), t_end=0.2, dt=[0.01, 0.02])
    run_sweep([case], SweepOptions(["mujoco"], tmp_path, ["euler", "rk4"], jobs=1, certify=False))
    assert len(seen) == 1 and [cost(s) for s in seen[0]] == sorted(cost(s) for s in seen[0])
    assert len({cost(s) for s in seen[0]}) > 1  # an order to see
    assert [s.label for s in queued[0]] == [s.label for s in seen[0][::-1]]  # its order, whatever it is


def test_the_ladders_go_to_the_pool_with_their_engines_affinity_one_precision_at_a_time(monkeypatch):
    """A family's ladder (dt ladder, short ladder, first part) is submitted to the sweep's pool with its engine's
    affinity (the engine's start-up; a cost of twice its finest point), so it goes preferably to a worker that paid
    for that engine, and an engine whose precision is process-global gets its families one precision at a time: the
    default run with every extra spent 19 min in its ladders, Genesis's short ladders spread over both workers with
    their precision alternating."""
    from concurrent.futures import Future
    from types import SimpleNamespace

    from stereodyn.harness.pipeline import dt_ladders
    from stereodyn.harness.run import pool as pool_module, timing

    monkeypatch.setattr(timing, "process_global_precision", lambda engine: engine == "g")
    monkeypatch.setattr(pool_module, "startup_s", lambda engine: {"g": 45.0}.get(engine, 0.0))
    monkeypatch.setattr(pool_module, "get_engine",
                        lambda engine: SimpleNamespace(timing=SimpleNamespace(pass_us={"g": 400.0}.get(engine, 1.0))))
    submitted = []

    class Pool:
        def submit(self, fn, *args, affinity=None):
            submitted.append((args[0], affinity))
            future = Future()
            future.set_result(([], {}))
            return future

    case = find_case("lagrange-top")
    families = [dt_ladders.Family(case, engine, "", "euler", precision) for engine, precision in
                [("g", "float64"), ("m", "float64"), ("g", "float32"), ("g", "float64"), ("m", "float32")]]
    dt_ladders.run_ladders([], 1000, Pool(), short=[(family, [], 1000) for family in families], timed=False)
    assert [(f.engine, f.precision) for f, _ in submitted] == \
        [("g", "float64"), ("m", "float64"), ("g", "float64"), ("g", "float32"), ("m", "float32")]
    assert all(a.key == f.engine for f, a in submitted)
    assert [a.startup_s for f, a in submitted if f.engine == "g"] == [45.0] * 3
    assert all(a.cost_s == pytest.approx(2 * 1000 * 400e-6) for f, a in submitted if f.engine == "g")
