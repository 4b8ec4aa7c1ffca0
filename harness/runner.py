"""Sweeps: every case x engine x integrator x dt, plus the truth; per-run failures become rows, never exceptions."""
from __future__ import annotations

import math
import multiprocessing
import os
import sys
import time
from concurrent.futures import Future, ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
import pandas as pd

from harness import metrics
from harness.cases import Case
from harness.engines import get_engine
from harness.engines.base import Status, Trajectory
from harness.grid import TimeGrid, time_grid
from harness.results import frame, write_results
from harness.timing import best_time
from reference import truth as reference_truth

TRUTH_ENGINE, TRUTH_FORMULATION, TRUTH_INTEGRATOR = "reference", "quaternion", "taylor"


@dataclass(frozen=True, eq=False)
class CaseTruth:
    """The truth of one case on the union of every run's sample times.

    times: (n,) s, sorted; quat: (n, 4) wxyz body -> world; omega: (n, 3) rad/s body frame.
    truth_err: rad, the double-versus-quadruple-precision bound (NaN unless certified).
    """

    times: np.ndarray
    quat: np.ndarray
    omega: np.ndarray
    truth_err: float
    applicable: tuple[str, ...]

    def on(self, grid: TimeGrid) -> tuple[np.ndarray, np.ndarray]:
        """The truth at exactly the grid's sample times."""
        index = np.searchsorted(self.times, grid.times)
        if not np.array_equal(self.times[index], grid.times):
            raise ValueError("truth was not evaluated on this grid's sample times")
        return self.quat[index], self.omega[index]


@dataclass(frozen=True)
class RunSpec:
    """One run: a case on an engine with an integrator and a step (dt is None for adaptive integrators)."""

    case: Case
    engine: str
    integrator: str
    dt: float | None
    engine_rank: int = 0
    integrator_rank: int = 0

    @property
    def label(self) -> str:
        dt = "" if self.dt is None else f" dt={self.dt:g}"
        return f"{self.case.name} {self.engine} {self.integrator}{dt}"


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
    return CaseTruth(times, result.quat, result.omega, truth_err, metrics.applicable_integrals(case))


def _base_row(spec: RunSpec, grid: TimeGrid | None) -> dict:
    return {"case": spec.case.name, "engine": spec.engine,
            "formulation": TRUTH_FORMULATION if spec.engine == TRUTH_ENGINE else "",
            "integrator": spec.integrator, "dt": math.nan if spec.dt is None else spec.dt,
            "t_end": grid.t_end if grid is not None else spec.case.t_end,
            "steps": grid.steps if grid is not None else math.nan,
            "_engine_rank": spec.engine_rank, "_integrator_rank": spec.integrator_rank,
            "_dt_rank": -(spec.dt if spec.dt is not None else math.inf)}


def skipped_row(spec: RunSpec, reason: str) -> dict:
    grid = None if spec.dt is None else time_grid(spec.case.t_end, spec.dt, spec.case.samples)
    return {**_base_row(spec, grid), "status": Status.SKIPPED.value, "message": reason}


def execute(spec: RunSpec, truth: CaseTruth) -> dict:
    """Run one spec: an untimed accuracy run (also the warm-up), metrics, then timed runs. Never raises."""
    grid = truth_grid(spec.case) if spec.dt is None else time_grid(spec.case.t_end, spec.dt, spec.case.samples)
    row = _base_row(spec, grid)
    try:
        sim = get_engine(spec.engine).prepare(spec.case, spec.integrator, spec.dt)
        traj: Trajectory = sim.run(grid)
        row.update(status=traj.status.value, message=traj.message, diverged_at=traj.diverged_at)
        if spec.dt is None:
            row["steps"] = traj.steps
        row.update(metrics.drifts(spec.case, traj, truth.applicable))
        if spec.engine == TRUTH_ENGINE:
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
    """The runs of a sweep, and the rows of runs skipped up front (engine cannot model the case)."""
    specs, skipped = [], []
    for engine_rank, name in enumerate(engines):
        engine = get_engine(name)
        chosen = [i for i in engine.integrators() if integrators is None or i in integrators]
        for case in cases:
            dts = (None,) if name == TRUTH_ENGINE else case.dt
            reason = engine.unsupported(case)
            for integrator_rank, integrator in enumerate(chosen or ([""] if reason else [])):
                for dt in dts:
                    spec = RunSpec(case, name, integrator, dt, engine_rank, integrator_rank)
                    (skipped.append(skipped_row(spec, reason)) if reason else specs.append(spec))
    return specs, skipped


def _cost(spec: RunSpec) -> float:
    """Rough relative cost, to start the longest runs first."""
    return 1.0 if spec.dt is None else spec.case.t_end / spec.dt


def run_sweep(cases: list[Case], engines: list[str], integrators: list[str] | None, out_dir: Path,
              jobs: int | None = None, certify: bool = False,
              progress: Callable[[str], None] | None = None) -> pd.DataFrame:
    """Run everything, writing out_dir/results.csv atomically after every finished run; return the table."""
    out_dir.mkdir(parents=True, exist_ok=True)
    progress = progress or (lambda line: None)
    specs, rows = plan(cases, engines, integrators)
    truths = {}
    for case in cases:
        start = time.perf_counter()
        truths[case.name] = compute_truth(case, case.dt, certify)
        progress(f"truth {case.name}: {time.perf_counter() - start:.2f} s")
    specs.sort(key=_cost, reverse=True)
    results_path = out_dir / "results.csv"
    total = len(specs)

    def finished(spec: RunSpec, row: dict) -> None:
        rows.append(row)
        write_results(frame(rows), results_path)
        progress(f"[{len(rows) - len(skipped_rows)}/{total}] {spec.label}: {row['status']}")

    skipped_rows = list(rows)
    write_results(frame(rows), results_path)
    jobs = jobs or os.cpu_count() or 1
    if jobs == 1 or len(specs) <= 1:
        for spec in specs:
            finished(spec, execute(spec, truths[spec.case.name]))
    else:
        # spawn, not fork: the parent holds heyoka's LLVM state and threads, which fork does not copy safely.
        context = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(max_workers=jobs, mp_context=context) as pool:
            futures: dict[Future, RunSpec] = {pool.submit(execute, s, truths[s.case.name]): s for s in specs}
            for future in as_completed(futures):
                spec = futures[future]
                try:
                    row = future.result()
                except Exception as exc:  # the worker process died (e.g. a crash inside an SDK)
                    row = {**_base_row(spec, None), "status": Status.FAILED.value,
                           "message": f"worker process failed: {type(exc).__name__}: {exc}".splitlines()[0]}
                finished(spec, row)
    return frame(rows)


def stderr_progress(line: str) -> None:
    print(line, file=sys.stderr, flush=True)
