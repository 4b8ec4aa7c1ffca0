"""Engine-affine scheduling (issue 29 item 2): a run goes preferably to a worker that has already paid its engine's
start-up; an engine whose start-up outweighs its queued runs is served by the workers that paid for it; both cores
stay busy where the queued runs outweigh a start-up. Fake tasks stand in for engines: each pays a sleep once per
worker process and counts that start-up."""
import time
from types import SimpleNamespace

import pytest
from child_processes import pay

from stereodyn.harness.run import pool as run_pool
from stereodyn.harness.run.workers import Affinity, WatchedPool

def _sweep(tasks: list[tuple[str, float, float]], declared_startup_s: float) -> list[tuple[int, str, bool]]:
    """The tasks on a 2-worker pool, both workers ready before the first is submitted (a worker still spawning
    would leave every task to the other, whatever the scheduling)."""
    pool = WatchedPool(2, run_pool._init_worker, ((),))
    try:
        deadline = time.monotonic() + 60
        while not all(w.ready for w in pool._workers) and time.monotonic() < deadline:
            time.sleep(0.05)
            pool._wake()
        futures = [pool.submit(pay, key, startup, run, affinity=Affinity(key, declared_startup_s, run))
                   for key, startup, run in tasks]
        return [f.result(timeout=60) for f in futures]
    finally:
        pool.shutdown()


def test_each_engine_starts_once_when_its_start_up_outweighs_its_runs():
    # an engine's 6 runs of 0.05 s (0.3 s queued) against a start-up of 0.5 s: one worker each. First in first out,
    # both workers took engine a's first two runs and then engine b's: 4 start-ups.
    tasks = [("a", 0.5, 0.05)] * 6 + [("b", 0.5, 0.05)] * 6
    done = _sweep(tasks, declared_startup_s=0.5)
    startups = [(pid, key) for pid, key, first in done if first]
    assert sorted(key for _, key in startups) == ["a", "b"], done
    assert len({pid for pid, _ in startups}) == 2  # and the two engines went to the two workers
    by_key = {key: {pid for pid, k, _ in done if k == key} for key in "ab"}
    assert all(len(pids) == 1 for pids in by_key.values()), by_key


def test_both_workers_serve_an_engine_whose_runs_outweigh_its_start_up():
    # 10 runs of 0.2 s (2 s queued) against a start-up of 0.1 s: the second core pays it too rather than idle
    done = _sweep([("a", 0.1, 0.2)] * 10, declared_startup_s=0.1)
    assert len({pid for pid, _, _ in done}) == 2 and sum(first for _, _, first in done) == 2


@pytest.mark.parametrize("engine, expected", [
    (SimpleNamespace(startup_s=12.0), 12.0),                               # the attribute
    (SimpleNamespace(timing=SimpleNamespace(startup_s=3.0)), 3.0),         # the Timing group
    (SimpleNamespace(), 0.0),                                              # a 0.2.0 engine declares none
    (SimpleNamespace(startup_s=float("nan")), 0.0)])
def test_an_engines_start_up_is_read_from_its_declaration(monkeypatch, engine, expected):
    monkeypatch.setattr(run_pool, "get_engine", lambda name: engine)
    assert run_pool.startup_s("x") == expected
    specs = [SimpleNamespace(engine="x")] * 3
    assert run_pool.startup_cost(specs, jobs=2) == 2 * expected  # once per worker that needs it: min(jobs, runs)
    assert run_pool.startup_cost(specs[:1], jobs=2) == expected


def test_a_worker_counts_the_engines_it_ran(monkeypatch):
    """The counter a worker exposes (pool.started_engines): its first run of an engine paid the start-up."""
    monkeypatch.setattr(run_pool, "measure", lambda spec, truth, **options: {"engine": spec.engine})
    monkeypatch.setattr(run_pool, "_STARTED", {})
    for engine in ("mujoco", "drake", "mujoco"):
        run_pool.sweep_run(SimpleNamespace(engine=engine, keep_states=False, compared=False), None)
    assert run_pool.started_engines() == {"mujoco": 2, "drake": 1}
