"""The dt ladders run on the sweep's process pool (harness.run.pool.worker_pool): one pool for both, and Ctrl-C during
the ladders ends its workers at once, as during the sweep (tests/test_scheduling.py)."""
import math
import multiprocessing
from concurrent.futures import Future
from pathlib import Path

import pandas as pd
import pytest
from child_processes import ended, started_since

from stereodyn.harness.pipeline import dt_ladders
from stereodyn.harness.run.pool import worker_pool
from stereodyn.harness.run.workers import WorkerDied
from stereodyn.harness.run.sweep import SweepOptions, run_sweep
from stereodyn.harness.pipeline import work_precision as workprecision
from stereodyn.harness.scenes.cases import find_case, with_overrides

ROOT = Path(__file__).resolve().parents[1]


def _case():
    return with_overrides(find_case("free-asymmetric"), t_end=0.5, dt=[1e-2, 5e-3])


def test_the_sweep_and_the_ladders_share_one_pool(tmp_path):
    before = set(multiprocessing.active_children())
    with worker_pool(2) as pool:
        workers = started_since(before)
        df = run_sweep([_case()], SweepOptions(["reference"], tmp_path, ["rk4"]), pool=pool)
        workprecision.analyse(tmp_path, df, [_case()], ["reference"], ["rk4"], ladder="full", max_steps=200,
                              pool=pool)
        assert started_since(before) == workers and len(workers) == 2  # no other process was started
    convergence = pd.read_csv(tmp_path / "convergence.csv", dtype={"formulation": str})
    ladders = convergence[convergence["source"] == "ladder"]
    # one ladder per formulation of the reference engine, each with a fitted rk4 order (measured 3.9-4.1 over
    # t_end 0.5 down to 200 steps; 0.3 is harness.testing's tolerance)
    assert len(ladders) == 4 and ((ladders["order"] - 4.0).abs() < 0.3).all(), ladders
    assert (ladders["declared_order"] == 4.0).all()


@pytest.mark.slow  # since 2026-12-02, ~20 s; by default test_store.py's Ctrl-C of a parallel sweep (the default suite's 8 minutes)
def test_an_interrupt_during_the_ladders_ends_the_workers_at_once(tmp_path):
    before = set(multiprocessing.active_children())
    workers, done = set(), []

    def interrupt(label: str) -> None:  # the first ladder done: Ctrl-C while the others run
        done.append(label)
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        with worker_pool(2) as pool:
            workers.update(started_since(before))
            df = run_sweep([_case()], SweepOptions(["reference"], tmp_path, ["rk4"]), pool=pool)
            workprecision.analyse(tmp_path, df, [_case()], ["reference"], ["rk4"], ladder="full",
                                  max_steps=20_000, pool=pool, progress=interrupt)
    assert len(done) == 1 and len(workers) == 2 and ended(workers)
    assert 0 not in {p.exitcode for p in workers}  # ended at once (SIGKILL), not left to finish their ladders


def test_only_the_runner_starts_a_process_pool_for_runs():
    """The sweep's and the ladders' pool is the runner's; the report's figures (harness.report.build, also run alone by
    `stereodyn report`) draw on a pool of their own (the runs' is watched: harness.run.workers)."""
    starts = sorted(path.relative_to(ROOT) for path in (ROOT / "harness").rglob("*.py")
                    if "ProcessPoolExecutor(" in path.read_text() or "WatchedPool(" in path.read_text())
    assert starts == [Path("harness/report/build.py"), Path("harness/run/pool.py")]


def test_without_a_pool_the_ladders_run_here(tmp_path):
    df = run_sweep([_case()], SweepOptions(["reference"], tmp_path, ["rk4"], jobs=1))
    paths = workprecision.analyse(tmp_path, df, [_case()], ["reference"], ["rk4"], ladder="full", max_steps=200)
    ladder = pd.read_csv(paths["ladder"])
    assert len(ladder) == 4 * 10 and math.isfinite(ladder["state_err"].min())


class _OneWorkerDies:
    """A pool that runs each task here, except the first dt ladder's, whose worker dies under it (as
    WatchedPool reports a process killed by an SDK's crash or the memory killer)."""

    jobs = 1  # one task at a time, here (the timing phases hand it one chunk at a time)

    def __init__(self):
        self.died = []

    def submit(self, fn, *args, affinity=None) -> Future:
        future = Future()
        if fn is dt_ladders.run_ladder and not self.died:
            self.died.append(args[0].key)
            future.set_exception(WorkerDied("worker process died (exit code -9)"))
        else:
            future.set_result(fn(*args))
        return future


def test_a_ladder_whose_worker_died_is_a_row_saying_so_and_the_phase_goes_on(tmp_path):
    """A failing run is a row with its reason: a family whose worker died has a convergence row saying so, and the
    other ladders, the orders, the Pareto table and the advice are still written (its row lacked the fit's columns,
    and the first-part selection after the ladders raised KeyError: 'order', ending `stereodyn run`)."""
    df = run_sweep([_case()], SweepOptions(["reference"], tmp_path, ["rk4"], jobs=1))
    pool = _OneWorkerDies()
    paths = workprecision.analyse(tmp_path, df, [_case()], ["reference"], ["rk4"], ladder="full", max_steps=200,
                                  pool=pool)
    assert len(pool.died) == 1 and {"pareto", "advice"} <= set(paths)
    convergence = pd.read_csv(paths["convergence"], dtype={"formulation": str}, keep_default_na=False,
                              na_values=[""])
    ladders = convergence[convergence["source"] == "ladder"]
    dead = ladders[ladders["note"].str.startswith("worker failed: WorkerDied")]
    assert len(dead) == 1 and dead["order"].isna().all() and (dead["declared_order"] == 4.0).all()
    others = ladders.drop(dead.index)
    # the other three formulations' rk4 orders, as in test_the_sweep_and_the_ladders_share_one_pool
    assert len(others) == 3 and ((others["order"] - 4.0).abs() < 0.3).all(), others
