"""Sweeps: every case x engine x integrator x formulation x dt, plus the truth; per-run failures become rows, never
exceptions. The jobs around it have their own modules: the plan (plan.py), one run -> row (measure.py), the truths
(truth.py), the process pool and cost model (pool.py), timing (timing.py), the store (store.py)."""
from __future__ import annotations

import dataclasses
import functools
import math
import os
import time
from contextlib import ExitStack, nullcontext
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
import pandas as pd

from .. import budget
from ..engines import EngineError, get_engine
from ..engines.declared import method
from ..environment import TIMING_END, TIMING_START, load_snapshot
from ..environment import environment as current_environment
from ..scenes import checks, scene_of
from ..trajectory import Status
from . import timing
from .distributed import cluster_timer, run_on_cluster
from .measure import prepare
from .plan import RunSpec, agreement_candidates, base_row, plan
from .pool import (cost, forget_kept, local_pool, one_precision_at_a_time, pool_timer,  # noqa: F401 (worker_pool)
                   prepare_kept, queue_key, run_local, startup_charges, startup_cost, sweep_run, worker_failed_row,
                   worker_pool)
from .workers import WatchedPool
from ..words import plural
from .progress import ProgressBar
from .results import frame, row_order, write_results
from .store import Store, mark_complete, run_key, sweep_ended
from .truth import case_truth

PUBLISH_EVERY_S = 2.0  # results.csv / checks.csv refresh interval during a sweep (s)


@dataclass(frozen=True)
class SweepOptions:
    """What a sweep runs and how, as `stereodyn run` was asked: engines (registry names, in report order), out_dir
    (the result folder), integrators (names; None: each engine's default sweep, resolved where the plan is made:
    run.plan.Selection), jobs (local worker processes; None: all cores), certify (bound every truth's error by a
    quadruple-precision rerun), resume (reuse the stored runs), scheduler (a Dask scheduler address instead of local
    processes), save_trajectories (write each run's states)."""

    engines: tuple[str, ...]
    out_dir: Path
    integrators: tuple[str, ...] | None = None
    jobs: int | None = None
    certify: bool = True
    resume: bool = False
    scheduler: str | None = None
    save_trajectories: bool = False

    def __post_init__(self):  # lists welcome: the fields are stored as tuples, the folder as a Path
        object.__setattr__(self, "engines", tuple(self.engines))
        object.__setattr__(self, "out_dir", Path(self.out_dir))
        if self.integrators is not None:
            object.__setattr__(self, "integrators", tuple(self.integrators))


def execute(spec: RunSpec, truth, timed: bool = False, budgets: budget.Budgets | None = None) -> dict:
    """One sweep run's row (measure.measure with the sweep's extras), timed when asked (the sweep times afterwards, on
    its workers: timing.time_runs)."""
    row = sweep_run(spec, truth, budgets)
    if timed and row.get("status") == Status.OK.value:
        row.update(time_spec(spec, row["steps"]))
    return row


def time_specs(specs: list[RunSpec], steps: list[float]) -> list[dict]:
    """The timing columns of finished ok runs (timing.time_runs)."""
    return timing.time_runs(specs, steps, prepare)


def time_spec(spec: RunSpec, steps: float) -> dict:
    """The timing columns of one finished ok run, timed alone (the disturbed mark is the timing phase's). {} when it
    fails here."""
    return {k: v for k, v in time_specs([spec], [steps])[0].items() if not k.startswith("_")}


def run_sweep(cases: list, options: SweepOptions, *, progress: ProgressBar | None = None,
              pool: WatchedPool | None = None, agreement: list | None = None, final: bool = True,
              decides: Callable[[pd.DataFrame], set] | None = None) -> pd.DataFrame:
    """Run every case as `options` says and return the table.

    Every finished run is stored at once (harness.run.store: out_dir/store/<key>.json) and out_dir/results.csv is
    re-assembled from the store, atomically, after each; options.resume reuses the stored runs of this sweep instead
    of redoing them; options.scheduler runs on a Dask scheduler (harness.run.distributed) instead of local processes;
    options.save_trajectories also writes each run's recorded states, and the truth on its times, to
    out_dir/trajectories/<key>.npz (Store.put_states) and their index, out_dir/trajectories/index.csv (with resume, a
    stored run without its file is redone).
    pool: a worker_pool to run on (its owner ends it); without one the sweep starts its own for options.jobs processes.
    progress: the bar to advance (none drawn without one).
    agreement: a list the sweep appends the states of the runs the cross-engine agreement compares to (plan.
    agreement_candidates; harness.analysis.agreement's entries), kept in memory; a resumed run's come from
    out_dir/trajectories where it saved them, else it is left out.
    final: the sweep is all that writes the folder: mark it complete at the end (runs.json; harness.run.store
    mark_complete). `stereodyn run` marks it itself, after the work–precision tables and the report.
    decides: which runs to time with repeats (harness.analysis.decisive.decisive: the ok rows of one timing group,
    their us_per_sim_s a single timed run, in -> the index labels to repeat); the others keep their single time
    (results.csv `timing`). None: every run is timed with repeats.
    """
    if not isinstance(options, SweepOptions):  # 0.3.0 dropped run_sweep(cases, engines, integrators, out_dir, ...)
        raise TypeError(f"run_sweep(cases, options): options must be a SweepOptions, not {type(options).__name__}")
    return _sweep(cases, options, progress or ProgressBar(enabled=False), pool, final, agreement, decides)


def _sweep(cases: list, options: SweepOptions, progress: ProgressBar, pool: WatchedPool | None, final: bool,
           agreement: list | None = None, decides: Callable[[pd.DataFrame], set] | None = None) -> pd.DataFrame:
    out_dir, engines = options.out_dir, options.engines
    specs, skipped_rows = plan(cases, engines, options.integrators)
    if cases and not specs and not skipped_rows:  # a folder of no rows, which every reader refuses, is no green run
        raise EngineError(f"nothing to run: the plans of {', '.join(engines)} for {plural(len(cases), 'case')} hold "
                          "no run and no skipped row (every integrator of their default sweep left out: default_dts() "
                          "gave no step, or default_run() said no)")
    out_dir.mkdir(parents=True, exist_ok=True)
    if options.save_trajectories:  # a scene whose state is not a body's (quat, omega) has none to save
        specs = [dataclasses.replace(s, keep_states=True) if scene_of(s.case).keeps_states else s for s in specs]
    if agreement is not None:
        candidates = agreement_candidates(specs)
        specs = [dataclasses.replace(s, compared=True) if i in candidates else s for i, s in enumerate(specs)]
    specs = one_precision_at_a_time(sorted(specs, key=queue_key, reverse=True))
    results_path = out_dir / "results.csv"
    budgets = budget.configured()  # the command's (harness.budget.configure), for every run, truth and --resume
    # --resume of a folder whose sweep ended: its timing phase has chosen and re-timed what decides, so its runs keep
    # their records (a choice made again with the new best times would pick another run, and rewrite it); of a killed
    # sweep, its finished runs never met a timing phase: they are candidates as the new ones are
    timed_before = options.resume and sweep_ended(out_dir)
    with Store(out_dir) as store, ExitStack() as open_pool:  # the pool, open until the timing phase is done
        identities = {id(s): s.identity(store, options.certify) for s in specs}
        keys = {id(s): run_key(identities[id(s)]) for s in specs}
        stored: dict[str, dict] = {}  # key -> row of every run of this sweep done so far
        if options.resume:
            stored = {keys[id(s)]: record["row"] for s in specs if (record := store.get(keys[id(s)])) is not None
                      # reused unless its states are wanted and missing, or it was stopped by a budget raised since
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
            checks.write_checks(sorted(({**stored[keys[id(s)]], **_ranks(s)} for s in specs if keys[id(s)] in stored),
                                       key=row_order), out_dir / checks.CHECKS_FILE)
            store.write_manifest([keys[id(s)] for s in specs if keys[id(s)] in stored], environment)
            if options.save_trajectories:
                store.write_trajectory_index([(stored[keys[id(s)]], keys[id(s)]) for s in specs
                                              if s.keep_states and keys[id(s)] in stored])

        def finished(spec: RunSpec, row: dict) -> None:
            key = keys[id(spec)]
            series = row.pop("_series", None)
            states = row.pop("_states", None)
            if states is not None and spec.compared and row.get("status") == Status.OK.value:
                _compare(spec, states)
            if not row.get("_lost"):
                if states is not None and spec.keep_states:  # before the record: its states are there too
                    store.put_states(key, row, states)
                store.put(key, identities[id(spec)], row, series, row.get("_budget"))
            stored[key] = {k: v for k, v in row.items() if not k.startswith("_")}
            # The run is safe in the store already; re-assembling the tables after every run was quadratic in the
            # sweep (seconds per run at ~1000 rows), so refresh them at most every PUBLISH_EVERY_S and at the end.
            if time.monotonic() - last_publish[0] >= PUBLISH_EVERY_S:
                publish()
            progress.advance(spec.label, cost(spec) + charge(spec.engine), str(row.get("status", "")))

        def _compare(spec: RunSpec, states: dict) -> None:
            agreement.append({"case": spec.case.name, "engine": spec.engine, "formulation": spec.formulation,
                              "integrator": spec.integrator, "precision": spec.precision, "dt": spec.dt,
                              "method": method(get_engine(spec.engine), spec.integrator), "horizon": spec.case.horizon,
                              "rank": tuple(_ranks(spec).values()), **states})

        for spec in specs:  # resumed runs: their states where the earlier run saved them
            key = keys[id(spec)]
            if spec.compared and key in stored and stored[key].get("status") == Status.OK.value \
                    and store.states_path(key).is_file():
                with np.load(store.states_path(key)) as saved:
                    _compare(spec, {name: saved[name] for name in ("times", "quat", "omega")})
        publish()
        pending = [s for s in specs if keys[id(s)] not in stored]
        local_jobs = 1 if options.scheduler else options.jobs or os.cpu_count() or 1
        # a cluster runs the runs itself (no local worker); else the given pool, or one of the sweep's own
        own_pool = nullcontext(None) if options.scheduler else nullcontext(pool) if pool is not None else \
            local_pool(local_jobs, len(pending))
        pool = open_pool.enter_context(own_pool)
        progress.stage(f"truths of {plural(len({id(s.case) for s in pending}), 'case')} and "
                       f"{plural(len(pending), 'run')} on {plural(local_jobs, 'worker')}")
        progress.start(len(pending), sum(cost(s) for s in pending) + startup_cost(pending, local_jobs),
                       resumed=len(specs) - len(pending))
        charge = startup_charges(pending, local_jobs)
        try:
            if options.scheduler:
                run_on_cluster(options.scheduler, pending, functools.partial(sweep_run, budgets=budgets),
                               functools.partial(case_truth, certify=options.certify, budget_s=budgets.truth_s),
                               finished, worker_failed_row)
            else:
                run_local(pending, pool, finished, options.certify, budgets, progress.phase)
        finally:
            publish()
            progress.close()
        # The timing phase: every accuracy run is done and the workers idle: each run whose time decides is timed on
        # a worker (or a cluster's), as many at once as workers, each on a core of its own; none in this process
        # (only without workers: --jobs 1 in process, a debugger's mode)
        new = {keys[id(s)] for s in pending}
        untimed = [s for s in specs if keys[id(s)] in stored and _needs_timing(stored[keys[id(s)]])
                   and not (timed_before and keys[id(s)] not in new)]
        if options.scheduler:
            elsewhere, ways = cluster_timer(options.scheduler) if untimed else (None, 1)
        else:
            elsewhere, ways = pool_timer(pool)
        if untimed:
            where = f"on {plural(ways, 'worker')} at once" if elsewhere is not None else "here, one at a time"
            progress.stage(f"timing {plural(len(untimed), 'run')} timed once: again, best of {timing.REPEATS}, "
                           f"{where}, those whose time decides an answer" if decides is not None else
                           f"timing {plural(len(untimed), 'run')}, {where}, in rounds")
            environment[TIMING_START] = load_snapshot()  # how busy the machine was: the report's Environment

        def select(indices: list[int], seconds: list[float]) -> set[int]:  # decides() for one timing group's runs
            # every run of the sweep is a rival, with its time (best of N, or single), the group's with `seconds`:
            # a run timed with repeats before (--resume) is the fastest of its cell as much as a new one
            given = {keys[id(untimed[i])]: second for i, second in zip(indices, seconds)}
            names = [keys[id(s)] for s in specs if keys[id(s)] in stored]
            rows = pd.DataFrame([stored[name] for name in names], index=names)
            rows = rows.reindex(columns=list(dict.fromkeys([*rows.columns, "dt", "attitude_err", "wall_s", "t_end"])))
            wall = pd.Series(given, dtype=float).reindex(names).fillna(rows["wall_s"].astype(float))
            rows["us_per_sim_s"] = wall.to_numpy(float) / rows["t_end"].to_numpy(float) * 1e6
            chosen = set(decides(rows))
            return {i for i in indices if keys[id(untimed[i])] in chosen}

        # prepare_kept: a run timed where its accuracy run was (a worker that paid its engine) reuses its model
        timings = timing.time_runs(untimed, [stored[keys[id(s)]].get("steps", math.nan) for s in untimed],
                                   prepare_kept, select if decides is not None else None,
                                   [timing.single(stored[keys[id(s)]]) for s in untimed], elsewhere, ways)
        forget_kept()
        if untimed:
            environment[TIMING_END] = load_snapshot()
        for spec, timed_columns in zip(untimed, timings):
            if not timed_columns:  # it keeps what it has: its single time (and its record, untouched for --resume)
                continue
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
    """An ok row with no time, or only the single time of its worker (timing.timed_once: it may decide an answer)."""
    return row.get("status") == Status.OK.value and not row.get("_lost") and (
        timing.single(row) is not None or not _finite(row.get("wall_s")))


def _finite(value) -> bool:
    return isinstance(value, (int, float)) and math.isfinite(value)



def _ranks(spec: RunSpec) -> dict:
    """The private sort keys of a spec's row (row order is not part of a stored run)."""
    return {k: v for k, v in base_row(spec, None).items() if k.startswith("_")}
