"""The one process pool of `stereodyn run` (the sweep's runs and the ladders' families), its workers, and the cost
model that starts the longest runs first."""
from __future__ import annotations

import math
import os
import signal
from collections.abc import Iterator
from concurrent.futures import FIRST_COMPLETED, Future, wait
from contextlib import contextmanager
from typing import Callable, NamedTuple

from .. import budget, integrators as integrator_registry
from ..engines import get_engine
from ..scenes import scene_of
from ..trajectory import Status
from ..words import clipped
from . import timing
from .timing import startup_s
from .measure import measure, prepare
from .processes import exit_with_parent, raise_unless_data
from .spec import RunSpec, base_row
from .truth import case_truth, truth_failure
from .workers import Affinity, WatchedPool

# The cost model of a run (measure + its timing), to start the longest runs first and to weigh the progress bar's ETA.
# Measured on the suite's four general cases (t_end 5 and 20, every engine, 2-core AMD EPYC): one simulation pass
# costs about Timing.pass_us µs per stage per step (MuJoCo 1.2-1.9, Pinocchio 2.4-2.9, the reference formulations
# 5.6-7.5), and a run about 4.1-4.5 passes (the accuracy run, the timed runs, ~0.1-0.5 for metrics and check reruns)
# plus ~6-25 ms. Only the ranking matters, so rough constants are enough: each engine declares its own (pass_us).
RUN_OVERHEAD_S = 0.01   # prepare, metrics and the row, s
CHECK_PASSES = 0.3      # mean extra passes of metrics and the checks' perturbed reruns


def _startups(specs: list, jobs: int) -> dict[str, tuple[float, int]]:
    """engine -> (its startup_s, how many workers pay it: min(jobs, its runs)) for the engines of specs."""
    runs: dict[str, int] = {}
    for spec in specs:
        runs[spec.engine] = runs.get(spec.engine, 0) + 1
    return {engine: (startup_s(engine), min(max(1, jobs), count)) for engine, count in runs.items()}


def startup_cost(specs: list[RunSpec], jobs: int = 1) -> float:
    """The start-ups a sweep of specs pays, s: each engine's startup_s once per worker that needs it (the engine-
    affine pool gives an engine's runs to as few workers as keep the cores busy: at most min(jobs, its runs))."""
    return sum(seconds * workers for seconds, workers in _startups(specs, jobs).values())


def startup_charges(specs: list[RunSpec], jobs: int = 1) -> Callable[[str], float]:
    """charge(engine) -> the start-up seconds a finished run of that engine counts in the progress bar: its startup_s
    for each of the engine's first min(jobs, runs) finished runs (the runs that paid it), then 0. Over every run of
    specs the charges add up to startup_cost(specs, jobs), so a bar whose total counts the start-ups ends at 100 %
    (it stalled at the runs' share of the total: 'ETA 1:00:01' a minute before the quick suite's sweep ended)."""
    left = {engine: [seconds, workers] for engine, (seconds, workers) in _startups(specs, jobs).items()}

    def charge(engine: str) -> float:
        entry = left.get(engine)
        if entry is None or entry[1] <= 0:
            return 0.0
        entry[1] -= 1
        return entry[0]
    return charge


def cost(spec: RunSpec) -> float:
    """Estimated seconds of a run: by steps x stages x the engine's cost of a step, not by steps alone, since the cost
    of a step differs ~4x between engines and ~4x between integrators. An adaptive run, whose steps are unknown before
    it runs, counts as a one-stage run at the case's finest step: an upper bound for the reference's Taylor runs
    (measured 0.02-1 times that), since underestimating a long run is what leaves it alone at the end."""
    dt = min(spec.case.dt) if spec.dt is None else spec.dt
    one_pass = pass_s(spec.engine, spec.integrator, math.ceil(spec.case.t_end / dt - 1e-9))
    # the accuracy run with its metrics and checks, then the worker's single timed run (timing.timed_once)
    return RUN_OVERHEAD_S + (2 + CHECK_PASSES) * one_pass


def queue_key(spec: RunSpec) -> float:
    """The sweep's queue order, largest first: a run's cost plus its engine's start-up, so the runs of the engines
    that pay one come first and their start-ups spread over the workers from the start (the pool's affinity then
    keeps each engine on the workers that paid it). By cost alone Newton's cheap runs came last: in the quick suite
    with every extra and cold caches, its 45 s start-up began at 67 s on one worker while the other idled for 44 s
    (2 cores, 2026-11-27: 135-155 s by cost alone, 123-150 s with the start-ups, alternating runs; warm 50-52 s both)."""
    return cost(spec) + startup_s(spec.engine)


def pass_s(engine: str, integrator: str, steps: int) -> float:
    """Estimated seconds of one pass of `steps` steps: steps x the integrator's stages x the engine's cost of a stage
    (Engine pass_us). At least one stage a step: moser_veselov declares 0 (it calls no accel) yet costs a solve a
    step."""
    return steps * max(1, integrator_registry.stages(integrator)) * get_engine(engine).timing.pass_us * 1e-6


def one_precision_at_a_time(specs: list, of: Callable = lambda item: item) -> list:
    """specs in their order, except that the runs of an engine whose precision is process-global (timing.
    process_global_precision) trade places among those they hold so that each precision's runs come together, in
    the order first met, each in its order: its workers take them in queue order, and Genesis re-initialised itself
    at each change of precision (measured: 8-11 s a run in the quick suite, where its float64 and float32 runs of
    equal cost alternated; 0.3-3 s a run without the change). of(item) -> what has the engine and precision (a
    RunSpec, a ladder's Family): the item itself by default."""
    places: dict[str, list[int]] = {}
    for index, item in enumerate(specs):
        if timing.process_global_precision(of(item).engine):
            places.setdefault(of(item).engine, []).append(index)
    ordered = list(specs)
    for indices in places.values():
        items = [specs[i] for i in indices]
        first = list(dict.fromkeys(of(item).precision for item in items))
        for index, item in zip(indices, sorted(items, key=lambda item: first.index(of(item).precision))):  # stable
            ordered[index] = item
    return ordered


def worker_failed_row(spec: RunSpec, exc: BaseException) -> dict:
    """The row of a run whose worker process died (e.g. a crash inside an SDK) or whose task was lost. It is shown in
    results.csv but not stored (_lost), so --resume tries the run again: the cause may have been passing (an
    interrupt, the memory killer, a cluster going away)."""
    return {**base_row(spec, None), "status": Status.FAILED.value, "_lost": True,
            "message": clipped(f"worker process failed: {type(exc).__name__}: {exc}".splitlines()[0])}


def _init_worker(budgets: budget.Budgets | None = None) -> None:
    """A pool worker's start-up: ignore Ctrl-C and take the parent's budgets (for the ladders' points, which run here
    too). The engines' adapters load on their first run here (get_engine, cached per process): a worker the
    engine-affine pool never gives an engine's run never pays for its SDK (issue 29: every worker paid for every
    engine)."""
    if budgets is not None:
        budget.configure(budgets)
    # Ctrl-C reaches the whole process group: the parent handles it (stops the sweep, ends the workers), so a worker
    # must not die mid-run on it and send back a traceback instead of a row.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    exit_with_parent()


_STARTED: dict[str, int] = {}  # engine -> runs of it in this process: the first one paid its start-up


def started_engines() -> dict[str, int]:
    """The engines this process has run (sweep_run), with how many runs each: a worker's first run of an engine pays
    its start-up (the counter the tests read per worker)."""
    return dict(_STARTED)


# The simulations this process prepared for the ok runs of start-up engines in the sweep (sweep_run), by run, for the
# sweep's timing phase: it times those runs on a worker that ran them (time_on_pool, Affinity), which would otherwise
# build each model again (Genesis: ~2.7 s a scene; its 8 scenes were ~22 of the quick suite's 48 s of timing). A pool
# serves one sweep; the parent forgets its own after the timing phase (forget_kept: --jobs 1 in process). At most
# KEPT_MAX, the oldest dropped first (a Genesis scene holds ~10 MB).
KEPT_MAX = 32


class _Kept(NamedTuple):
    """What makes a kept simulation the one a run needs."""
    case: str
    t_end: float
    samples: int
    engine: str
    formulation: str
    integrator: str
    dt: float | None
    tolerance: float | None
    precision: str


_KEPT: dict[_Kept, object] = {}


def _kept_key(run: RunSpec) -> _Kept:
    case = run.case
    return _Kept(case.name, case.t_end, case.samples, run.engine, run.formulation, run.integrator, run.dt,
                 run.tolerance, run.precision)


def _released(engine: str, precision: str) -> None:
    """Forget the kept simulations that a model of engine at precision releases: those of its other precision, where
    its precision is process-global (timing.process_global_precision: Genesis re-initialises itself)."""
    if timing.process_global_precision(engine):
        for key in [key for key in _KEPT if key.engine == engine and key.precision != precision]:
            del _KEPT[key]


def _keep(run: RunSpec, sim) -> None:
    _KEPT[_kept_key(run)] = sim
    while len(_KEPT) > KEPT_MAX:
        del _KEPT[next(iter(_KEPT))]


def prepare_kept(run: RunSpec) -> tuple:
    """(simulation, grid) of a run, as measure.prepare: the simulation this process kept from the run's accuracy run
    (sweep_run) where it has one, else built anew."""
    sim = _KEPT.pop(_kept_key(run), None)
    if sim is not None:
        return sim, run.grid
    _released(run.engine, run.precision)
    return prepare(run)


def forget_kept() -> None:
    _KEPT.clear()


def affinity(spec: RunSpec) -> Affinity:
    """A run's affinity (harness.run.workers): its engine, the engine's start-up and the run's estimated cost."""
    return Affinity(spec.engine, startup_s(spec.engine), cost(spec))


def family_affinity(family, max_steps: int) -> Affinity:
    """A ladder task's affinity (one family's ladder, short ladder or first part, run on the sweep's pool): its
    engine, the engine's start-up, and a rough cost: its finest point (max_steps) twice over, as a walk of halvings
    sums to about that (pass_s)."""
    return Affinity(family.engine, startup_s(family.engine), 2.0 * pass_s(family.engine, family.integrator, max_steps))


def time_pinned(core: int | None, chunk: timing.Chunk) -> list:
    """A worker's timing task (time_on_pool): the chunk's runs timed here (timing.time_here, the models it kept from
    their accuracy runs where it has them: prepare_kept), the whole process pinned to `core` meanwhile (None:
    unpinned)."""
    with timing.on_core(core):
        return _time_chunk(chunk)


def time_on_pool(pool: WatchedPool) -> Callable[[list[timing.Chunk]], list]:
    """timing.time_runs' `elsewhere` on the pool: each chunk a task (time_pinned), as many at once as the pool has
    workers, each holding a core of its own (timing.timing_cores) until it is done, so no two timings share a core;
    a chunk of a start-up engine's runs with its Affinity (a worker that paid it). In the order given; a chunk whose
    worker died keeps its runs' single times (None each); our bug raises."""
    def spread(chunks: list[timing.Chunk]) -> list:
        free = timing.timing_cores(pool.jobs)
        results: list = [[None] * len(chunk.runs) for chunk in chunks]
        queue, flying = list(range(len(chunks))), {}
        while queue or flying:
            while queue and free:
                k, core = queue.pop(0), free.pop(0)
                chunk = chunks[k]
                needs = None if chunk.engine is None else Affinity(chunk.engine, startup_s(chunk.engine))
                flying[pool.submit(time_pinned, core, chunk, affinity=needs)] = k, core
            done, _ = wait(flying, return_when=FIRST_COMPLETED)
            for future in done:
                k, core = flying.pop(future)
                free.append(core)
                try:
                    results[k] = future.result()
                except Exception as exc:  # its worker died: the runs keep their single times
                    raise_unless_data(exc)
        return results
    return spread


def pool_timer(pool: WatchedPool | None) -> tuple[Callable | None, int]:
    """(elsewhere, ways) of timing.time_runs and time_points: on the pool's workers (time_on_pool), as many at once as
    it has; (None, 1) without a pool: here, in turn."""
    return (None, 1) if pool is None else (time_on_pool(pool), pool.jobs)


def time_on_a_free_core(chunk: timing.Chunk) -> list:
    """A Dask worker's timing task (distributed.time_on_cluster): the chunk's runs timed on a core of the machine
    that no other timing holds (timing.on_a_free_core), this thread pinned to it."""
    with timing.on_a_free_core():
        return _time_chunk(chunk)


def _time_chunk(chunk: timing.Chunk) -> list:
    """timing.time_here of a chunk in a worker, with the models it kept from the runs' accuracy runs
    (prepare_kept) unless the chunk brings its own prepare (ladder points)."""
    return timing.time_here(chunk.runs, chunk.prepare or prepare_kept, chunk.first, chunk.repeats, chunk.budget_s)


IN_PROCESS_ENV = "STEREODYN_IN_PROCESS"  # "1": --jobs 1 runs in the command's own process (in_process)


def in_process(jobs: int) -> bool:
    """Whether runs go in this process rather than to watched workers: only --jobs 1 with STEREODYN_IN_PROCESS=1, for
    a debugger or a profiler (and the tests, which patch this process); the budgets are then only cooperative."""
    return jobs == 1 and os.environ.get(IN_PROCESS_ENV) == "1"


def worker_pool(jobs: int | None):
    """The local process pool of `stereodyn run`, shared by the sweep (run_sweep(pool=...)) and the dt ladders
    (harness.workprecision.analyse(pool=...)); None when the runs go in this process (in_process). A context
    manager: Ctrl-C inside it ends the workers at once."""
    return local_pool(jobs or os.cpu_count() or 1, 2)


@contextmanager
def local_pool(jobs: int, runs: int) -> Iterator[WatchedPool | None]:
    """The process pool of a local sweep (None when there is no run, or they go in this process: in_process), its
    workers started at once so that they spawn and import (~1 s) while the parent computes the truths. Even one job
    is a worker: the parent ends one that runs past its budget (harness.run.workers). On an exception (Ctrl-C) the
    queued runs are dropped and the running ones ended now rather than waited for."""
    if runs == 0 or in_process(jobs):
        yield None
        return
    jobs = min(jobs, runs)  # no idle worker (each spawns and imports the SDKs: ~185 MB)
    pool = WatchedPool(jobs, _init_worker, (budget.configured(),))
    try:
        yield pool
    except BaseException:
        pool.kill()
        raise
    # Every task is done: let the idle workers exit on their own (their exit handlers, not the interpreter's teardown:
    # workers._exit) rather than wait here for them. Python joins them at exit at the latest.
    pool.shutdown()


def sweep_run(spec: RunSpec, truth, budgets: budget.Budgets | None = None) -> dict:
    """A sweep's run on a worker: measure() with the sweep's extras (checks, series, --save-trajectories' states),
    within the budgets (default this process's), then timed once (timing.timed_once: results.csv's timing SINGLE)."""
    _STARTED[spec.engine] = _STARTED.get(spec.engine, 0) + 1
    _released(spec.engine, spec.precision)  # measure prepares a model of this precision, whatever its outcome
    keep = startup_s(spec.engine) > 0.0

    def timed_once(sim, grid, run) -> dict:  # called only for an ok run, after its accuracy run
        if keep:
            _keep(spec, sim)
        return timing.timed_once(sim, grid, run)

    row = measure(spec, truth, full=True, keep_states=spec.keep_states or spec.compared, timed=timed_once,
                  budgets=budgets)
    once = row.pop(timing.ONCE, None)
    if once is not None:  # timed once here, after its accuracy run; the timing phase repeats it if it decides
        row.update(timing.step_columns(timing.Timing(once, 0.0, 1), row.get("steps", math.nan)))
    return row


def run_local(specs: list[RunSpec], pool: WatchedPool | None, finished: Callable[[RunSpec, dict], None],
              certify: bool, budgets: budget.Budgets | None = None,
              phase: Callable[[str], None] = lambda text: None) -> None:
    """Each case's truth, then its runs, in this process (pool None: every truth first, phase(text) saying which) or
    on the pool, in the order given; finished(spec, row) as each run completes. On the pool each case's truth is a
    task of its own, the truths first, those of the costliest cases first; a case's runs are queued the moment its
    own truth is back, whatever the other truths are doing (the parent computed them all first: a serial part no
    worker could take, issue 49). A truth that fails fails its case's runs (truth.truth_failure)."""
    budgets = budgets or budget.configured()
    by_case: dict[int, list[RunSpec]] = {}
    for spec in specs:
        by_case.setdefault(id(spec.case), []).append(spec)

    def fail_case(runs: list[RunSpec], exc: Exception) -> None:
        failure = truth_failure(exc)
        for spec in runs:
            finished(spec, {**base_row(spec, None), **failure})

    if pool is None:
        truths = {}
        for runs in by_case.values():
            case = runs[0].case
            if scene_of(case).needs_truth:
                phase(f"truth {case.name}")
            try:
                truths[id(case)] = case_truth(case, certify, budgets.truth_s)
            except Exception as exc:
                fail_case(runs, exc)
        for spec in specs:
            if id(spec.case) in truths:
                finished(spec, sweep_run(spec, truths[id(spec.case)]))  # this process's budgets
        return
    ordered = sorted(by_case.values(), key=lambda runs: sum(cost(s) for s in runs), reverse=True)  # stable
    truths: dict[Future, list[RunSpec]] = {pool.submit(case_truth, runs[0].case, certify, budgets.truth_s): runs
                                           for runs in ordered}
    running: dict[Future, RunSpec] = {}
    while truths or running:
        done, _ = wait([*truths, *running], return_when=FIRST_COMPLETED)
        for future in done:
            if future in truths:
                runs = truths.pop(future)
                try:
                    truth = future.result()
                except Exception as exc:  # past its budget, the worker died, an error; our bug raises (exit 3)
                    fail_case(runs, exc)
                    continue
                running |= {pool.submit(sweep_run, s, truth, budgets, affinity=affinity(s)): s for s in runs}
                continue
            spec = running.pop(future)
            try:
                row = future.result()
            except budget.BudgetExceeded as exc:  # its worker ended past its budget (harness.run.workers)
                row = {**base_row(spec, spec.grid), **budget.failed_row(exc)}
            except Exception as exc:  # the worker died or the task was lost; a bug of ours raised there is no row
                raise_unless_data(exc)
                row = worker_failed_row(spec, exc)
            finished(spec, row)
