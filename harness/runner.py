"""Sweeps: every case x engine x integrator x formulation x dt, plus the truth; per-run failures become rows, never
exceptions."""
from __future__ import annotations

import math
import multiprocessing
import os
import signal
import time
from concurrent.futures import Future, ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
import pandas as pd

from harness import checks, ladder, metrics, oracles, series
from harness import integrators as integrator_registry
from harness.cases import SLIDING_LADDER, Case
from harness.engines import get_engine
from harness.engines.base import Status, Trajectory
from harness.grid import TimeGrid, time_grid
from harness.distributed import run_on_cluster
from harness.environment import environment as current_environment
from harness.progress import ProgressBar
from harness.results import frame, write_results
from harness.store import Store, run_key
from harness.timing import best_time
from reference import truth as reference_truth

TRUTH_ENGINE, TRUTH_FORMULATION, TRUTH_INTEGRATOR = "reference", "quaternion", "taylor"
PUBLISH_EVERY_S = 2.0  # results.csv / checks.csv refresh interval during a sweep (s)


@dataclass(frozen=True, eq=False)
class CaseTruth:
    """The truth of one case on the union of every run's sample times.

    times: (n,) s, sorted; quat: (n, 4) wxyz body -> world; omega: (n, 3) rad/s body frame.
    truth_err: rad, the double-versus-quadruple-precision bound (NaN unless certified).
    exact_quat: (n, 4) the case's exact solution (harness.oracles) at the same times, or None without an oracle.
    """

    times: np.ndarray
    quat: np.ndarray
    omega: np.ndarray
    truth_err: float
    applicable: tuple[str, ...]
    exact_quat: np.ndarray | None = None

    def on(self, grid: TimeGrid) -> tuple[np.ndarray, np.ndarray]:
        """The truth at exactly the grid's sample times."""
        index = np.searchsorted(self.times, grid.times)
        if not np.array_equal(self.times[index], grid.times):
            raise ValueError("truth was not evaluated on this grid's sample times")
        return self.quat[index], self.omega[index]


@dataclass(frozen=True)
class RunSpec:
    """One run: a case on an engine with an integrator and a step (dt is None for adaptive integrators), and the
    engine's formulation ("" for an engine without formulations)."""

    case: Case
    engine: str
    integrator: str
    dt: float | None
    engine_rank: int = 0
    integrator_rank: int = 0
    formulation: str = ""
    formulation_rank: int = 0

    @property
    def label(self) -> str:
        dt = "" if self.dt is None else f" dt={self.dt:g}"
        formulation = f" {self.formulation}" if self.formulation else ""
        return f"{self.case.name} {self.engine}{formulation} {self.integrator}{dt}"

    @property
    def is_truth(self) -> bool:
        return (self.engine, self.formulation, self.integrator) == (TRUTH_ENGINE, TRUTH_FORMULATION, TRUTH_INTEGRATOR)


def truth_grid(case: Case) -> TimeGrid:
    """The truth row's own grid: the case's samples evenly over [0, t_end]."""
    return time_grid(case.t_end, case.t_end / (case.samples - 1), case.samples)


def compute_truth(case: Case, dts: tuple[float, ...], certify: bool) -> CaseTruth:
    grids = [time_grid(case.t_end, dt, case.samples) for dt in dts] + [truth_grid(case)]
    times = np.unique(np.concatenate([g.times for g in grids]))
    result = reference_truth.truth(case.body, case.quat0, case.omega0, times)
    truth_err = math.nan
    if certify:
        horizon = case.horizon if case.horizon is not None else case.t_end
        certified = truth_grid(case).times
        truth_err = reference_truth.truth_error(case.body, case.quat0, case.omega0,
                                                certified[certified <= horizon * (1 + 1e-12)])
    return CaseTruth(times, result.quat, result.omega, truth_err, metrics.applicable_integrals(case),
                     oracles.exact_attitude(case, times))


def _base_row(spec: RunSpec, grid: TimeGrid | None) -> dict:
    return {"case": spec.case.name, "engine": spec.engine, "formulation": spec.formulation,
            "integrator": spec.integrator, "dt": math.nan if spec.dt is None else spec.dt,
            "t_end": grid.t_end if grid is not None else spec.case.t_end,
            "steps": grid.steps if grid is not None else math.nan,
            "_engine_rank": spec.engine_rank, "_integrator_rank": spec.integrator_rank,
            "_formulation_rank": spec.formulation_rank, "_dt_rank": -(spec.dt if spec.dt is not None else math.inf)}


def skipped_row(spec: RunSpec, reason: str) -> dict:
    grid = None if spec.dt is None else time_grid(spec.case.t_end, spec.dt, spec.case.samples)
    return {**_base_row(spec, grid), "status": Status.SKIPPED.value, "message": reason}


def execute(spec: RunSpec, truth: CaseTruth | None) -> dict:
    """Run one spec: an untimed accuracy run (also the warm-up), metrics, then timed runs. Never raises."""
    grid = truth_grid(spec.case) if spec.dt is None else time_grid(spec.case.t_end, spec.dt, spec.case.samples)
    row = _base_row(spec, grid)
    if spec.case.kind == SLIDING_LADDER:  # not a body with a fixed point: its own runs and metrics
        return ladder.execute(spec, row)
    try:
        formulation = {"formulation": spec.formulation} if spec.formulation else {}
        engine = get_engine(spec.engine)
        sim = engine.prepare(spec.case, spec.integrator, spec.dt, **formulation)
        traj: Trajectory = sim.run(grid)
        row.update(status=traj.status.value, message=traj.message, diverged_at=traj.diverged_at,
                   chart_changes=math.nan if traj.chart_changes is None else traj.chart_changes,
                   torque_mode=traj.info.get("torque_mode") or getattr(engine, "torque_mode", lambda case: "none")(
                       spec.case))
        if spec.dt is None:
            row["steps"] = traj.steps
        row.update(metrics.drifts(spec.case, traj, truth.applicable))
        row.update(metrics.torque_metrics(spec.case, traj))
        row["_series"] = series.invariant_series(spec.case, traj, truth.applicable, truth.on(grid)[0])
        row["oracle_err"] = oracles.oracle_err(spec.case, traj, truth.times, truth.exact_quat)
        # theory checks; the perturbed reruns some of them need are untimed, like the accuracy run
        row[checks.ROW_KEY] = checks.measure(spec.case, traj, lambda case: get_engine(spec.engine).prepare(
            case, spec.integrator, spec.dt, **formulation).run(grid))
        if spec.is_truth:
            row["truth_err"] = truth.truth_err
        else:
            truth_quat, truth_omega = truth.on(grid)
            row.update(metrics.errors(traj, truth_quat, truth_omega, spec.case.horizon))
            row["truth_err"] = truth.truth_err
        if traj.status is Status.OK:
            wall = best_time(lambda: sim.run(grid))
            row.update(wall_s=wall, us_per_step=wall / max(1, row["steps"]) * 1e6)
    except Exception as exc:  # a run that breaks is data: record why and let the sweep go on
        row.update(status=Status.FAILED.value, message=f"{type(exc).__name__}: {exc}".splitlines()[0])
    return row


def plan(cases: list[Case], engines: list[str], integrators: list[str] | None) -> tuple[list[RunSpec], list[dict]]:
    """The runs of a sweep, and the rows of runs skipped up front (engine cannot model the case).

    An engine's adaptive integrators (Engine.adaptive) run once per case with dt None, the others once per dt of the
    case; each runs every formulation of the engine (Engine.formulations; "" for an engine without).
    """
    specs, skipped = [], []
    for engine_rank, name in enumerate(engines):
        engine = get_engine(name)
        chosen = [i for i in engine.integrators()
                  if (integrators is None and integrator_registry.in_default_sweep(i))
                  or (integrators is not None and i in integrators)]
        formulations = tuple(getattr(engine, "formulations", tuple)()) or ("",)
        adaptive = getattr(engine, "adaptive", lambda integrator: False)
        for case in cases:
            if case.kind == SLIDING_LADDER:
                ladder_specs, ladder_skipped = ladder.specs(case, name, engine_rank, chosen, RunSpec)
                specs += ladder_specs
                skipped += ladder_skipped
                continue
            reason = engine.unsupported(case)
            for integrator_rank, integrator in enumerate(chosen or ([""] if reason else [])):
                dts = (None,) if integrator and adaptive(integrator) else case.dt
                for formulation_rank, formulation in enumerate(formulations):
                    for dt in dts:
                        spec = RunSpec(case, name, integrator, dt, engine_rank, integrator_rank, formulation,
                                       formulation_rank)
                        # a formulation/integrator pair that cannot model the case (engine.unsupported_run)
                        why = reason or (integrator and getattr(engine, "unsupported_run", lambda *a: None)(
                            case, formulation, integrator))
                        (skipped.append(skipped_row(spec, why)) if why else specs.append(spec))
    return specs, skipped


def _cost(spec: RunSpec) -> float:
    """Rough relative cost, to start the longest runs first."""
    return 1.0 if spec.dt is None else spec.case.t_end / spec.dt


def _worker_failed_row(spec: RunSpec, exc: BaseException) -> dict:
    """The row of a run whose worker process died (e.g. a crash inside an SDK) or whose task was lost. It is shown in
    results.csv but not stored (_lost), so --resume tries the run again: the cause may have been passing (an
    interrupt, the memory killer, a cluster going away)."""
    return {**_base_row(spec, None), "status": Status.FAILED.value, "_lost": True,
            "message": f"worker process failed: {type(exc).__name__}: {exc}".splitlines()[0]}


def _ignore_sigint() -> None:
    # Ctrl-C reaches the whole process group: the parent handles it (stops the sweep, ends the workers), so a worker
    # must not die mid-run on it and send back a traceback instead of a row.
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _run_local(specs: list[RunSpec], truths: dict[str, CaseTruth], jobs: int,
               finished: Callable[[RunSpec, dict], None]) -> None:
    if jobs == 1 or len(specs) <= 1:
        for spec in specs:
            finished(spec, execute(spec, truths[spec.case.name]))
        return
    # spawn, not fork: the parent holds heyoka's LLVM state and threads, which fork does not copy safely.
    context = multiprocessing.get_context("spawn")
    pool = ProcessPoolExecutor(max_workers=jobs, mp_context=context, initializer=_ignore_sigint)
    try:
        futures: dict[Future, RunSpec] = {pool.submit(execute, s, truths[s.case.name]): s for s in specs}
        for future in as_completed(futures):
            spec = futures[future]
            try:
                row = future.result()
            except Exception as exc:
                row = _worker_failed_row(spec, exc)
            finished(spec, row)
    except BaseException:
        # Interrupted: drop the queued runs and end the running ones now rather than waiting for them. Python < 3.14
        # has no public way to end a pool's workers, hence the private process table.
        pool.shutdown(wait=False, cancel_futures=True)
        for process in list((getattr(pool, "_processes", None) or {}).values()):
            process.terminate()
        raise
    pool.shutdown(wait=True)


def run_sweep(cases: list[Case], engines: list[str], integrators: list[str] | None, out_dir: Path,
              jobs: int | None = None, certify: bool = False, progress: ProgressBar | None = None,
              resume: bool = False, scheduler: str | None = None) -> pd.DataFrame:
    """Run everything and return the table.

    Every finished run is stored at once (harness.store: out_dir/store/<key>.json) and out_dir/results.csv is
    re-assembled from the store, atomically, after each; resume=True reuses the stored runs of this sweep instead of
    redoing them. scheduler: a Dask scheduler address to run on (harness.distributed) instead of local processes.
    """
    out_dir.mkdir(parents=True, exist_ok=True)
    progress = progress or ProgressBar(enabled=False)
    specs, skipped_rows = plan(cases, engines, integrators)
    specs.sort(key=_cost, reverse=True)
    results_path = out_dir / "results.csv"
    with Store(out_dir) as store:
        identities = {id(s): store.identity(s.case, s.engine, s.formulation, s.integrator, s.dt, certify)
                      for s in specs}
        keys = {id(s): run_key(identities[id(s)]) for s in specs}
        stored: dict[str, dict] = {}  # key -> row of every run of this sweep done so far
        if resume:
            stored = {key: record["row"] for key in keys.values() if (record := store.get(key)) is not None}
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

        def finished(spec: RunSpec, row: dict) -> None:
            key = keys[id(spec)]
            series = row.pop("_series", None)
            if not row.get("_lost"):
                store.put(key, identities[id(spec)], row, series)
            stored[key] = {k: v for k, v in row.items() if not k.startswith("_")}
            # The run is safe in the store already; re-assembling the tables after every run was quadratic in the
            # sweep (seconds per run at ~1000 rows), so refresh them at most every PUBLISH_EVERY_S and at the end.
            if time.monotonic() - last_publish[0] >= PUBLISH_EVERY_S:
                publish()
            progress.advance(spec.label, _cost(spec), str(row.get("status", "")))

        publish()
        pending = [s for s in specs if keys[id(s)] not in stored]
        truths = {}
        for case in cases:
            if case.kind == SLIDING_LADDER:  # harness.ladder solves the equation in each run
                truths[case.name] = None
            elif any(s.case is case for s in pending):
                progress.phase(f"truth {case.name}")
                truths[case.name] = compute_truth(case, case.dt, certify)
        progress.start(len(pending), sum(_cost(s) for s in pending), resumed=len(specs) - len(pending))
        try:
            if scheduler:
                run_on_cluster(scheduler, pending, truths, execute, finished, _worker_failed_row)
            else:
                _run_local(pending, truths, jobs or os.cpu_count() or 1, finished)
        finally:
            publish()
            progress.close()
        return table()


def _ranks(spec: RunSpec) -> dict:
    """The private sort keys of a spec's row (row order is not part of a stored run)."""
    return {k: v for k, v in _base_row(spec, None).items() if k.startswith("_")}
