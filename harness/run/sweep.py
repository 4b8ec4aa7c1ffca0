"""Sweeps: every case x engine x integrator x formulation x dt, plus the truth; per-run failures become rows, never
exceptions."""
from __future__ import annotations

import dataclasses
import functools
import math
import multiprocessing
import os
import signal
import time
from collections.abc import Iterator
from concurrent.futures import Future, ProcessPoolExecutor, as_completed
from contextlib import contextmanager, nullcontext
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
import pandas as pd

from ..scenes import checks
from ..scenes import metrics
from ..scenes import oracles
from ..scenes import series
from ..scenes import sliding_ladder
from . import timing
from .. import budget
from .. import integrators as integrator_registry
from ..scenes.cases import SLIDING_LADDER, Case
from ..engines import get_engine
from .plan import RunSpec, base_row, plan
from ..trajectory import Status, Trajectory
from ..grid import TimeGrid, time_grid
from .distributed import run_on_cluster
from ..environment import environment as current_environment
from .processes import exit_with_parent, raise_if_interrupted, starting_workers
from .progress import ProgressBar
from .results import frame, write_results
from .store import Store, mark_complete, run_key
from ...reference import truth as reference_truth

PUBLISH_EVERY_S = 2.0  # results.csv / checks.csv refresh interval during a sweep (s)


@dataclass(frozen=True, eq=False)
class CaseTruth:
    """The truth of one case on the union of every run's sample times.

    times: (n,) s, sorted; quat: (n, 4) wxyz body -> world; omega: (n, 3) rad/s body frame.
    truth_err: rad, a bound on the truth's attitude error up to the case's horizon; truth_omega_err: a bound on its
    relative omega error (reference.truth.truth_bound: a quadruple-precision rerun plus the rounding of a float64
    comparison); both NaN when not certified (--no-certify).
    exact_quat: (n, 4) the case's exact solution (harness.scenes.oracles) at the same times, or None without an oracle.
    """

    times: np.ndarray
    quat: np.ndarray
    omega: np.ndarray
    truth_err: float
    applicable: tuple[str, ...]
    exact_quat: np.ndarray | None = None
    truth_omega_err: float = math.nan

    def on(self, grid: TimeGrid) -> tuple[np.ndarray, np.ndarray]:
        """The truth at exactly the grid's sample times."""
        index = np.searchsorted(self.times, grid.times)
        if not np.array_equal(self.times[index], grid.times):
            raise ValueError("truth was not evaluated on this grid's sample times")
        return self.quat[index], self.omega[index]


def truth_grid(case: Case) -> TimeGrid:
    """The truth row's own grid: the case's samples evenly over [0, t_end]."""
    return time_grid(case.t_end, case.t_end / (case.samples - 1), case.samples)


def compute_truth(case: Case, dts: tuple[float, ...], certify: bool, budget_s: float | None = None) -> CaseTruth:
    """The case's truth on the union of its grids, certified by a real128 rerun when certify; both within the truth
    budget (budget_s, default harness.budget's configured one): BudgetExceeded past it."""
    grids = [time_grid(case.t_end, dt, case.samples) for dt in dts] + [truth_grid(case)]
    times = np.unique(np.concatenate([g.times for g in grids]))
    with budget.within("truth", budget.configured().truth_s if budget_s is None else budget_s):
        result = reference_truth.truth(case.body, case.quat0, case.omega0, times, deadline=budget.deadline())
        bound = reference_truth.TruthBound(math.nan, math.nan)
        if certify:
            horizon = case.horizon if case.horizon is not None else case.t_end
            certified = truth_grid(case).times
            bound = reference_truth.truth_bound(case.body, case.quat0, case.omega0,
                                                certified[certified <= horizon * (1 + 1e-12)],
                                                deadline=budget.deadline())
    return CaseTruth(times, result.quat, result.omega, bound.attitude, metrics.applicable_integrals(case),
                     oracles.exact_attitude(case, times), bound.omega)


def _grid(spec: RunSpec) -> TimeGrid:
    return truth_grid(spec.case) if spec.dt is None else time_grid(spec.case.t_end, spec.dt, spec.case.samples)


def rhs_per_sim_s(spec: RunSpec, rhs_evals: int, steps: float, t_end: float) -> float:
    """Right-hand-side evaluations per simulated second: the engine's count, or for a fixed-step run of an engine that
    does not count them, steps x the integrator's stages (_stages); NaN for an adaptive run that does not count."""
    if rhs_evals:
        return rhs_evals / t_end
    if spec.dt is None or not math.isfinite(steps):
        return math.nan
    return steps * _stages(spec.integrator) / t_end


def execute(spec: RunSpec, truth: CaseTruth | None, timed: bool = False,
            budgets: budget.Budgets | None = None) -> dict:
    """Run one spec: an untimed accuracy run (also the warm-up), metrics, then, when timed, timed runs. Never raises.
    The sweep runs it untimed and times every run afterwards, alone (time_spec). budgets (default: this process's,
    harness.budget.configured): prepare under its prepare budget, the accuracy run with its metrics and checks under
    its run budget; a run past one is a failed row naming it."""
    budgets = budgets or budget.configured()
    grid = _grid(spec)
    row = base_row(spec, grid)
    if spec.case.kind == SLIDING_LADDER:  # not a body with a fixed point: its own runs and metrics
        return sliding_ladder.execute(spec, row, timed, budgets)
    try:
        formulation = {"formulation": spec.formulation} if spec.formulation else {}
        engine = get_engine(spec.engine)
        sim = budget.prepared(lambda: engine.prepare(spec.case, spec.integrator, spec.dt, **formulation),
                              budgets.prepare_s)
        with budget.within("run", budgets.run_s):
            _accuracy_run(spec, truth, grid, sim, engine, formulation, row)
        if timed and row["status"] == Status.OK.value:
            row.update(_timing_columns(timing.measure(lambda: sim.run(grid)), row["steps"]))
    except budget.BudgetExceeded as exc:  # nothing it measured before the stop counts
        row = {**base_row(spec, grid), **budget.failed_row(exc)}
    except Exception as exc:  # a run that breaks is data: record why and let the sweep go on
        raise_if_interrupted(exc)  # ... unless Ctrl-C broke it (an SDK may rewrap the KeyboardInterrupt)
        row.update(status=Status.FAILED.value, message=f"{type(exc).__name__}: {exc}".splitlines()[0])
    return row


def _accuracy_run(spec: RunSpec, truth: CaseTruth, grid: TimeGrid, sim, engine, formulation: dict,
                  row: dict) -> None:
    """The untimed run of execute and everything measured from it, into row."""
    traj: Trajectory = sim.run(grid)
    row.update(status=traj.status.value, message=traj.message, diverged_at=traj.diverged_at,
               chart_changes=math.nan if traj.chart_changes is None else traj.chart_changes,
               torque_mode=traj.info.get("torque_mode") or engine.torque_mode(spec.case))
    if spec.dt is None:
        row["steps"] = traj.steps
    row["rhs_per_sim_s"] = rhs_per_sim_s(spec, traj.rhs_evals, row["steps"], grid.t_end)
    if spec.keep_states:  # with the truth on the run's own times, so that each file is audited on its own
        truth_quat, truth_omega = truth.on(grid)
        row["_states"] = {"times": traj.times, "quat": traj.quat, "omega": traj.omega, "truth_quat": truth_quat,
                          "truth_omega": truth_omega}
    row.update(metrics.drifts(spec.case, traj, truth.applicable))
    row.update(metrics.torque_metrics(spec.case, traj))
    row["_series"] = series.invariant_series(spec.case, traj, truth.applicable, truth.on(grid)[0])
    row["oracle_err"] = oracles.oracle_err(spec.case, traj, truth.times, truth.exact_quat)
    # theory checks; the perturbed reruns some of them need are untimed, like the accuracy run
    row[checks.ROW_KEY] = checks.measure(spec.case, traj, lambda case: get_engine(spec.engine).prepare(
        case, spec.integrator, spec.dt, **formulation).run(grid))
    if not spec.is_truth:
        truth_quat, truth_omega = truth.on(grid)
        row.update(metrics.errors(traj, truth_quat, truth_omega, spec.case.horizon))
    row.update(truth_err=truth.truth_err, truth_omega_err=truth.truth_omega_err)


def _timing_columns(measured: timing.Timing, steps: float) -> dict:
    per_step = 1e6 / max(1, steps)
    return {"wall_s": measured.best, "us_per_step": measured.best * per_step,
            "us_per_step_spread": measured.spread * per_step}


def time_spec(spec: RunSpec, steps: float) -> dict:
    """The timing columns of one finished ok run, timed alone (time_specs of one run). {} when it fails here."""
    return {k: v for k, v in time_specs([spec], [steps])[0].items() if not k.startswith("_")}


def _warm_run(spec: RunSpec):
    """A fresh preparation of the spec, run once untimed (caches, lazily compiled code): a function of no arguments
    for the timing phase, or None when it fails here (it ran ok untimed: the row is then left untimed)."""
    try:
        if spec.case.kind == SLIDING_LADDER:
            run = sliding_ladder.timed_run(spec, sliding_ladder._grid(spec))
        else:
            grid = _grid(spec)
            formulation = {"formulation": spec.formulation} if spec.formulation else {}
            sim = get_engine(spec.engine).prepare(spec.case, spec.integrator, spec.dt, **formulation)
            run = lambda: sim.run(grid)  # noqa: E731
        run()
        return run
    except Exception as exc:
        raise_if_interrupted(exc)
        return None


def time_specs(specs: list[RunSpec], steps: list[float]) -> list[dict]:
    """The timing columns of finished ok runs, in this process with no other run sharing the cores: each prepared
    and warmed up, then timed in rounds over all of them (timing.measure_interleaved). {} for a run that fails here;
    a timing still disturbed when re-timed carries it as `_disturbed`."""
    runs = [_warm_run(spec) for spec in specs]
    kept = [i for i, run in enumerate(runs) if run is not None]
    measured = timing.measure_interleaved([runs[i] for i in kept])
    rows: list[dict] = [{} for _ in specs]
    for i, m in zip(kept, measured):
        if m is not None:
            rows[i] = _timing_columns(m, steps[i]) | ({"_disturbed": m} if m.disturbed else {})
    return rows


# The cost model of a run (execute), to start the longest runs first and to weigh the progress bar's ETA. Measured on
# the suite's four general cases (t_end 5 and 20, every engine, 2-core AMD EPYC): one simulation pass costs about
# Engine.pass_us µs per stage per step (MuJoCo 1.2-1.9, Pinocchio 2.4-2.9, the reference formulations 5.6-7.5), and
# execute about 4.1-4.5 passes (the accuracy run, the timed runs, ~0.1-0.5 for metrics and check reruns) plus ~6-25 ms.
# Only the ranking matters, so rough constants are enough: each engine declares its own (Engine.pass_us).
RUN_OVERHEAD_S = 0.01   # prepare, metrics and the row, s
CHECK_PASSES = 0.3      # mean extra passes of metrics and the checks' perturbed reruns


def _stages(integrator: str) -> int:
    """Derivative evaluations per step of a registered integrator; 1 for an engine's own (e.g. MuJoCo implicit)."""
    for space in integrator_registry.state_spaces():
        if integrator in integrator_registry.names(space):
            return integrator_registry.get(integrator, space).stages
    return 1


def _cost(spec: RunSpec) -> float:
    """Estimated seconds of execute(spec): by steps x stages x the engine's cost of a step, not by steps alone, since
    the cost of a step differs ~4x between engines and ~4x between integrators. An adaptive run, whose steps are
    unknown before it runs, counts as a one-stage run at the case's finest step: an upper bound for the reference's
    Taylor runs (measured 0.02-1 times that), since underestimating a long run is what leaves it alone at the end."""
    dt = min(spec.case.dt) if spec.dt is None else spec.dt
    steps = math.ceil(spec.case.t_end / dt - 1e-9)
    one_pass = steps * _stages(spec.integrator) * get_engine(spec.engine).pass_us * 1e-6
    # the timing phase (time_spec, timing.measure) repeats the run at most REPEATS times within BUDGET_S
    timed = min(timing.REPEATS * one_pass, timing.BUDGET_S + one_pass)
    return RUN_OVERHEAD_S + (1 + CHECK_PASSES) * one_pass + timed


def _worker_failed_row(spec: RunSpec, exc: BaseException) -> dict:
    """The row of a run whose worker process died (e.g. a crash inside an SDK) or whose task was lost. It is shown in
    results.csv but not stored (_lost), so --resume tries the run again: the cause may have been passing (an
    interrupt, the memory killer, a cluster going away)."""
    return {**base_row(spec, None), "status": Status.FAILED.value, "_lost": True,
            "message": f"worker process failed: {type(exc).__name__}: {exc}".splitlines()[0]}


def _init_worker(engines: tuple[str, ...], budgets: budget.Budgets | None = None) -> None:
    """A pool worker's start-up: ignore Ctrl-C, take the parent's budgets (for the ladders' points, which run here
    too) and import the engines' SDKs now, while the parent computes the truths, rather than in the worker's first
    run."""
    if budgets is not None:
        budget.configure(budgets)
    # Ctrl-C reaches the whole process group: the parent handles it (stops the sweep, ends the workers), so a worker
    # must not die mid-run on it and send back a traceback instead of a row.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    exit_with_parent()
    for name in engines:
        try:
            get_engine(name)
        except Exception:  # the runs that need the engine record why
            pass


def worker_pool(jobs: int | None, engines: tuple[str, ...]):
    """The local process pool of `stereodyn run`, shared by the sweep (run_sweep(pool=...)) and the dt ladders
    (harness.workprecision.analyse(pool=...)); None when jobs is 1. A context manager: Ctrl-C inside it ends the
    workers at once."""
    return _local_pool(jobs or os.cpu_count() or 1, 2, engines)


@contextmanager
def _local_pool(jobs: int, runs: int, engines: tuple[str, ...]) -> Iterator[ProcessPoolExecutor | None]:
    """The process pool of a local sweep (None when it runs in this process), its workers started at once so that
    they spawn and import (~1 s) while the parent computes the truths. On an exception (Ctrl-C) the queued runs are
    dropped and the running ones ended now rather than waited for."""
    if jobs == 1 or runs <= 1:
        yield None
        return
    jobs = min(jobs, runs)  # no idle worker (each spawns and imports the SDKs: ~185 MB)
    # spawn, not fork: the parent holds heyoka's LLVM state and threads, which fork does not copy safely.
    pool = None
    try:
        with starting_workers():  # tied to this process, deaf to Ctrl-C, from their first moment (harness.processes)
            pool = ProcessPoolExecutor(max_workers=jobs, mp_context=multiprocessing.get_context("spawn"),
                                       initializer=_init_worker, initargs=(engines, budget.configured()))
            for _ in range(jobs):  # the pool starts a worker per task submitted while none is idle: start them all
                pool.submit(int)
        yield pool
    except BaseException:
        # Python < 3.14 has no public way to end a pool's workers, hence the private process table, read before
        # shutdown() empties it.
        if pool is None:
            raise
        processes = list((getattr(pool, "_processes", None) or {}).values())
        pool.shutdown(wait=False, cancel_futures=True)
        for process in processes:
            process.terminate()
        raise
    # Every run is done and stored: let the idle workers exit on their own rather than wait here for their interpreter
    # teardown (0.2-0.5 s with the SDKs loaded, ~3% of a short sweep). Python joins them at exit at the latest.
    pool.shutdown(wait=False)


def _run_local(specs: list[RunSpec], truths: dict[str, CaseTruth], pool: ProcessPoolExecutor | None,
               finished: Callable[[RunSpec, dict], None], budgets: budget.Budgets | None = None) -> None:
    """Run the specs in this process (pool None) or on the pool, in the order given; finished(spec, row) as each
    completes."""
    if pool is None:
        for spec in specs:
            finished(spec, execute(spec, truths[spec.case.name]))  # this process's budgets
        return
    futures: dict[Future, RunSpec] = {pool.submit(execute, s, truths[s.case.name], False, budgets): s for s in specs}
    for future in as_completed(futures):
        spec = futures[future]
        try:
            row = future.result()
        except Exception as exc:
            row = _worker_failed_row(spec, exc)
        finished(spec, row)


def run_sweep(cases: list[Case], engines: list[str], integrators: list[str] | None, out_dir: Path,
              jobs: int | None = None, certify: bool = True, progress: ProgressBar | None = None,
              resume: bool = False, scheduler: str | None = None, save_trajectories: bool = False,
              pool: ProcessPoolExecutor | None = None, final: bool = True) -> pd.DataFrame:
    """Run everything and return the table.

    Every finished run is stored at once (harness.run.store: out_dir/store/<key>.json) and out_dir/results.csv is
    re-assembled from the store, atomically, after each; resume=True reuses the stored runs of this sweep instead of
    redoing them. scheduler: a Dask scheduler address to run on (harness.run.distributed) instead of local processes.
    pool: a worker_pool to run on (its owner ends it); without one the sweep starts its own for `jobs` processes.
    certify: bound every truth's error by a quadruple-precision rerun (truth_err, truth_omega_err; ~0.2 s a case).
    save_trajectories: also write each run's recorded states, and the truth on its times, to
    out_dir/trajectories/<key>.npz (Store.put_states) and their index, out_dir/trajectories/index.csv; with resume, a stored
    run without its file is redone.
    final: the sweep is all that writes the folder: mark it complete at the end (runs.json; harness.run.store
    mark_complete). `stereodyn run` marks it itself, after the work–precision tables and the report.
    """
    out_dir.mkdir(parents=True, exist_ok=True)
    progress = progress or ProgressBar(enabled=False)
    budgets = budget.configured()  # the command's (harness.budget.configure), for every run, truth and --resume
    specs, skipped_rows = plan(cases, engines, integrators)
    if save_trajectories:  # the sliding ladder records another state (harness.scenes.sliding_ladder): none to save
        specs = [dataclasses.replace(s, keep_states=True) if s.case.kind != SLIDING_LADDER else s for s in specs]
    specs.sort(key=_cost, reverse=True)
    results_path = out_dir / "results.csv"
    with Store(out_dir) as store:
        identities = {id(s): store.identity(s.case, s.engine, s.formulation, s.integrator, s.dt, certify)
                      for s in specs}
        keys = {id(s): run_key(identities[id(s)]) for s in specs}
        stored: dict[str, dict] = {}  # key -> row of every run of this sweep done so far
        if resume:
            # reused unless its states are wanted and missing, or it was stopped by a budget raised since
            stored = {keys[id(s)]: record["row"] for s in specs if (record := store.get(keys[id(s)])) is not None
                      and not (s.keep_states and record["row"]["status"] != Status.FAILED.value
                               and not store.states_path(keys[id(s)]).is_file())
                      and budget.still_holds(record.get("budget"), budgets)}
        environment = current_environment()

        def table() -> pd.DataFrame:
            done = [s for s in specs if keys[id(s)] in stored]
            return frame(skipped_rows + [{**stored[keys[id(s)]], **_ranks(s)} for s in done])

        last_publish = [time.monotonic()]

        def publish() -> None:
            last_publish[0] = time.monotonic()
            write_results(table(), results_path)
            checks.write_checks([{**stored[keys[id(s)]], **_ranks(s)} for s in specs if keys[id(s)] in stored],
                                out_dir / checks.CHECKS_FILE)
            store.write_manifest([keys[id(s)] for s in specs if keys[id(s)] in stored], environment)
            if save_trajectories:
                store.write_trajectory_index([(stored[keys[id(s)]], keys[id(s)]) for s in specs
                                              if s.keep_states and keys[id(s)] in stored])

        def finished(spec: RunSpec, row: dict) -> None:
            key = keys[id(spec)]
            series = row.pop("_series", None)
            states = row.pop("_states", None)
            if not row.get("_lost"):
                if states is not None:  # before the record: a stored record means its states are there too
                    store.put_states(key, row, states)
                store.put(key, identities[id(spec)], row, series, row.get("_budget"))
            stored[key] = {k: v for k, v in row.items() if not k.startswith("_")}
            # The run is safe in the store already; re-assembling the tables after every run was quadratic in the
            # sweep (seconds per run at ~1000 rows), so refresh them at most every PUBLISH_EVERY_S and at the end.
            if time.monotonic() - last_publish[0] >= PUBLISH_EVERY_S:
                publish()
            progress.advance(spec.label, _cost(spec), str(row.get("status", "")))

        publish()
        pending = [s for s in specs if keys[id(s)] not in stored]
        local_jobs = 1 if scheduler else jobs or os.cpu_count() or 1
        own_pool = nullcontext(pool) if pool is not None and not scheduler else \
            _local_pool(local_jobs, len(pending), tuple(engines))
        with own_pool as pool:
            truths = {}
            progress.stage(f"truths of {len(cases)} cases, then {len(pending)} runs on {local_jobs} workers")
            for case in cases:
                if case.kind == SLIDING_LADDER:  # harness.scenes.sliding_ladder solves the equation in each run
                    truths[case.name] = None
                elif any(s.case is case for s in pending):
                    progress.phase(f"truth {case.name}")
                    try:
                        truths[case.name] = compute_truth(case, case.dt, certify, budgets.truth_s)
                    except Exception as exc:  # a truth that cannot be computed fails its case's runs, as data
                        raise_if_interrupted(exc)
                        failure = {"status": Status.FAILED.value,
                                   "message": f"truth failed: {type(exc).__name__}: {exc}".splitlines()[0]}
                        if isinstance(exc, budget.BudgetExceeded):  # stored as such: --resume redoes it if raised
                            failure = {**budget.failed_row(exc), "message": f"truth failed: {exc}"}
                        for spec in [s for s in pending if s.case is case]:
                            finished(spec, {**base_row(spec, None), **failure})
                        pending = [s for s in pending if s.case is not case]
            progress.start(len(pending), sum(_cost(s) for s in pending), resumed=len(specs) - len(pending))
            try:
                if scheduler:
                    run_on_cluster(scheduler, pending, truths, functools.partial(execute, budgets=budgets), finished,
                                   _worker_failed_row)
                else:
                    _run_local(pending, truths, pool, finished, budgets)
            finally:
                publish()
                progress.close()
        # The timing phase: every accuracy run is done and the pool idle (or gone): each timed run has the cores alone.
        untimed = [s for s in specs if keys[id(s)] in stored and _needs_timing(stored[keys[id(s)]])]
        if untimed:
            progress.stage(f"timing {len(untimed)} runs, one at a time, in rounds")
        timings = time_specs(untimed, [stored[keys[id(s)]].get("steps", math.nan) for s in untimed])
        for spec, timed_columns in zip(untimed, timings):
            key = keys[id(spec)]
            row = stored[key]
            mark = timed_columns.pop("_disturbed", None)
            row.update(timed_columns)
            if mark is not None:  # still disturbed when re-timed: the row says so, and the Pareto table skips it
                row["message"] = timing.with_disturbed(row.get("message"), mark)
            record = store.get(key)
            store.put(key, identities[id(spec)], row, record.get("series") if record else None)
        if untimed:
            publish()
        if final:
            mark_complete(out_dir)
        return table()


def _needs_timing(row: dict) -> bool:
    wall = row.get("wall_s", math.nan)
    return row.get("status") == Status.OK.value and not row.get("_lost") and not (
        isinstance(wall, float) and math.isfinite(wall))


def _ranks(spec: RunSpec) -> dict:
    """The private sort keys of a spec's row (row order is not part of a stored run)."""
    return {k: v for k, v in base_row(spec, None).items() if k.startswith("_")}
