"""Engine-affine scheduling (issue 29 item 2): a run goes preferably to a worker that has already paid its engine's
start-up; an engine whose start-up outweighs its queued runs is served by the workers that paid for it; both cores
stay busy where the queued runs outweigh a start-up. Fake tasks stand in for engines: each pays a sleep once per
worker process and counts that start-up."""
import dataclasses
import json
import os
import sys
import time
from types import SimpleNamespace

import pytest
from child_processes import pay

from stereodyn.harness import engines
from stereodyn.harness.run import pool as run_pool, timing
from stereodyn.harness.run.progress import ProgressBar
from stereodyn.harness.run.sweep import SweepOptions, run_sweep
from stereodyn.harness.run.workers import Affinity, WatchedPool
from stereodyn.harness.scenes.cases import find_case, with_overrides

def _sweep(tasks: list[tuple[str, float, float]], declared_startup_s: float) -> list[tuple[int, str, bool]]:
    """The tasks on a 2-worker pool, both workers ready before the first is submitted (a worker still spawning
    would leave every task to the other, whatever the scheduling)."""
    pool = WatchedPool(2, run_pool._init_worker, ())
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
    (SimpleNamespace(timing=SimpleNamespace(startup_s=3.0)), 3.0),         # the Timing group
    (SimpleNamespace(), 0.0),                                              # a 0.2.0 engine declares none
    (SimpleNamespace(startup_s=float("nan")), 0.0)])
def test_an_engines_start_up_is_read_from_its_declaration(monkeypatch, engine, expected):
    monkeypatch.setattr(timing, "get_engine", lambda name: engine)  # startup_s's home: timing (the chunks read it)
    assert run_pool.startup_s("x") == expected
    specs = [SimpleNamespace(engine="x")] * 3
    assert run_pool.startup_cost(specs, jobs=2) == 2 * expected  # once per worker that needs it: min(jobs, runs)
    assert run_pool.startup_cost(specs[:1], jobs=2) == expected


def test_a_worker_counts_the_engines_it_ran(monkeypatch):
    """The counter a worker exposes (pool.started_engines): its first run of an engine paid the start-up."""
    monkeypatch.setattr(run_pool, "measure", lambda spec, truth, **options: {"engine": spec.engine})
    monkeypatch.setattr(run_pool, "_STARTED", {})
    for engine in ("mujoco", "drake", "mujoco"):
        run_pool.sweep_run(SimpleNamespace(engine=engine, precision="float64", keep_states=False, compared=False),
                           None)
    assert run_pool.started_engines() == {"mujoco": 2, "drake": 1}


# --- the sweep's timing phase: an engine with a start-up is timed on a worker that paid it, one task at a time

TIMED_PLUGIN = '''
"""Two engines that wrap MuJoCo's euler: `warm` declares a start-up, `cold` none. Each simulation appends
(engine, pid, start, end) of every run() to a file of the folder STEREODYN_TEST_CALLS names (one file per process),
and each prepare (engine, pid, dt, time) to another."""
import json
import os
import time

from stereodyn.harness.engines import get_engine
from stereodyn.harness.engines.base import About, Engine, Timing


class _Recorded:
    def __init__(self, engine, inner):
        self.engine, self.inner = engine, inner

    def run(self, grid):
        start = time.monotonic()  # one system-wide clock: the processes' intervals compare
        try:
            time.sleep(0.02)  # long enough that two calls at once would overlap
            return self.inner.run(grid)
        finally:
            end = time.monotonic()
            with open(os.path.join(os.environ["STEREODYN_TEST_CALLS"], f"{os.getpid()}.jsonl"), "a") as out:
                cores = sorted(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else []
                out.write(json.dumps([self.engine, os.getpid(), start, end, cores]) + "\\n")


class _Wrapped(Engine):
    def integrators(self):
        return ("euler",)

    def unsupported(self, case):
        return None

    def prepare(self, case, integrator, dt):
        with open(os.path.join(os.environ["STEREODYN_TEST_CALLS"], f"{os.getpid()}.prepared"), "a") as out:
            out.write(json.dumps([self.name, os.getpid(), dt, time.monotonic()]) + "\\n")
        return _Recorded(self.name, get_engine("mujoco").prepare(case, "euler", dt))


class Warm(_Wrapped):
    name = "warm"
    about = About(state_space="lie")
    timing = Timing(pass_us=3.0, startup_s=5.0)


class Cold(_Wrapped):
    name = "cold"
    about = About(state_space="lie")
    timing = Timing(pass_us=3.0)
'''


class _Stages(ProgressBar):
    """A silent bar that notes when the timing phase begins (time.monotonic())."""

    def __init__(self):
        super().__init__(enabled=False)
        self.timing_from = None

    def stage(self, text: str) -> None:
        if text.startswith("timing"):
            self.timing_from = time.monotonic()
        super().stage(text)


@pytest.fixture
def timed_plugin(tmp_path, monkeypatch):
    """The two engines, registered by a distribution on sys.path (the spawned workers get the parent's), and the
    folder their calls are written to."""
    site = tmp_path / "site"
    site.mkdir()
    (site / "stereodyn_timed.py").write_text(TIMED_PLUGIN)
    info = site / "stereodyn_timed-0.1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: stereodyn-timed\nVersion: 0.1.0\n")
    (info / "entry_points.txt").write_text("[stereodyn.engines]\nwarm = stereodyn_timed:Warm\n"
                                           "cold = stereodyn_timed:Cold\n")
    calls = tmp_path / "calls"
    calls.mkdir()
    monkeypatch.syspath_prepend(str(site))
    monkeypatch.setenv("STEREODYN_TEST_CALLS", str(calls))
    engines._entry_points.cache_clear()
    engines.get_engine.cache_clear()
    yield calls
    engines._entry_points.cache_clear()
    engines.get_engine.cache_clear()
    sys.modules.pop("stereodyn_timed", None)


@pytest.mark.parametrize("given_pool", [False, True])
def test_the_deciding_runs_are_timed_on_the_workers_each_on_a_core_of_its_own(timed_plugin, tmp_path, given_pool):
    """A sweep on a pool of 2 workers (its own, or one it is given as `stereodyn run`'s pipeline gives it), every ok
    run timed with repeats (no decides): every run is timed on a worker, none in the parent (issue 49: the parent's
    serial timing phase); the runs of `warm` (declared start-up 5 s) on a worker that ran `warm`'s accuracy runs
    (which would otherwise pay the SDK and every compilation again). On a machine with 2 cores each timing is pinned
    to one core, and two timings at once are never on the same core. Break-checked: timing_cores giving both workers
    core 0 fails the last assertion; elsewhere None (the parent times) the second."""
    case = dataclasses.replace(with_overrides(find_case("free-asymmetric"), t_end=0.2, dt=[1e-2, 5e-3]), samples=11)
    progress = _Stages()
    options = SweepOptions(["warm", "cold"], tmp_path / "out", jobs=2, certify=False)
    if given_pool:
        with run_pool.local_pool(2, 4) as pool:
            table = run_sweep([case], options, progress=progress, pool=pool)
    else:
        table = run_sweep([case], options, progress=progress)
    assert set(table.status) == {"ok"} and len(table) == 4, table[["engine", "status", "message"]]
    assert table.timing.str.startswith("best of").all(), table[["engine", "timing"]]
    calls = [json.loads(line) for path in timed_plugin.glob("*.jsonl") for line in path.read_text().splitlines()]
    assert progress.timing_from is not None
    accuracy = {(engine, pid) for engine, pid, start, _, _ in calls if start < progress.timing_from}
    timed = sorted((start, end, engine, pid, cores) for engine, pid, start, end, cores in calls
                   if start >= progress.timing_from)
    parent = os.getpid()
    assert parent not in {pid for _, pid in accuracy}  # the accuracy runs ran on the pool
    assert timed and parent not in {pid for *_, pid, _ in timed}, timed  # ... and so did the timings
    warm_timed = {pid for _, _, engine, pid, _ in timed if engine == "warm"}
    assert warm_timed and warm_timed <= {pid for engine, pid in accuracy if engine == "warm"}, (warm_timed, accuracy)
    if len(os.sched_getaffinity(0)) >= 2:
        assert all(len(cores) == 1 for *_, cores in timed), timed
        for k, (start, end, *_, cores) in enumerate(timed):
            for other_start, _, *_, other_cores in timed[k + 1:]:
                if other_start < end:  # at the same time: on another core
                    assert other_cores != cores, timed


def test_a_run_timed_on_the_worker_that_ran_it_is_not_prepared_again(timed_plugin, tmp_path):
    """The timing phase times `warm`'s runs (declared start-up) on a worker that ran them, with the models that worker
    kept from their accuracy runs (pool.prepare_kept): it prepares again only a run whose accuracy run was on another
    worker. Before, it built every one again (Genesis: ~22 of the quick suite's 48 s of timing)."""
    case = dataclasses.replace(with_overrides(find_case("free-asymmetric"), t_end=0.2, dt=[1e-2, 5e-3, 2.5e-3]),
                               samples=11)
    progress = _Stages()
    table = run_sweep([case], SweepOptions(["warm"], tmp_path / "out", jobs=2, certify=False), progress=progress)
    assert set(table.status) == {"ok"} and table.timing.str.startswith("best of").all(), table
    prepared = [json.loads(line) for path in timed_plugin.glob("*.prepared") for line in path.read_text().splitlines()]
    ran = {dt: pid for _, pid, dt, at in prepared if at < progress.timing_from}  # the accuracy runs' workers
    again = [(pid, dt) for _, pid, dt, at in prepared if at >= progress.timing_from]
    assert len(ran) == 3 and len(again) < 3, (ran, again)
    assert all(ran[dt] != pid for pid, dt in again), (ran, again)


class _Sim:
    def run(self, grid):
        time.sleep(0.001)


def test_runs_whose_worker_dies_while_timing_them_keep_their_single_time():
    """timing.time_runs with an `elsewhere` whose chunk of engine x is lost (its worker died: None each), so x's run
    keeps its single time ({}), and y's, timed, is timed all the same; Ctrl-C while waiting stops the phase."""
    runs = [SimpleNamespace(engine="x", precision="float64"), SimpleNamespace(engine="y", precision="float64")]

    def spread(chunks):
        return [[None] * len(c.runs) if c.runs[0].engine == "x" else timing.in_turn(lambda run: (_Sim(), None))([c])[0]
                for c in chunks]

    rows = timing.time_runs(runs, [10, 10], lambda run: (_Sim(), None), singles=[0.01, 0.01], elsewhere=spread,
                            ways=2)
    assert rows[0] == {} and rows[1]["timing"].startswith("best of"), rows

    def interrupted(chunks):
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        timing.time_runs(runs, [10, 10], lambda run: (_Sim(), None), singles=[0.01, 0.01], elsewhere=interrupted)


def test_a_run_with_no_single_time_is_timed_once_first_elsewhere_too():
    """A run with no single time (--resume of a run stored before single times) is timed once first, in a chunk of
    single times given to `elsewhere` as well, then with the others, best of: nothing is timed in this process."""
    runs = [SimpleNamespace(engine="x", precision="float64")] * 2
    sent = []

    def spread(chunks):
        sent.append([(len(c.runs), c.repeats) for c in chunks])
        return timing.in_turn(lambda run: (_Sim(), None))(chunks)

    rows = timing.time_runs(runs, [10, 10], lambda run: None, singles=[None, 0.01], elsewhere=spread, ways=2)
    assert sent == [[(1, 1)], [(1, timing.REPEATS), (1, timing.REPEATS)]], sent
    assert all(row["timing"].startswith("best of") for row in rows), rows
