"""Stepping time, measured apart from accuracy (DESIGN §6.4). Every ok run is timed once in its worker, right after its
accuracy run, which is its warm-up (once: the sweep's runs, the ladders' points); only the runs whose time decides
something are then timed again, best of N in rounds, each timing on a core that no other timing shares (time_runs,
time_points, their `select`: harness.analysis.decisive), with the spread of the N recorded so that a ranking can tell
a difference from noise. The others keep their single time, and say so (results.csv's and the ladders' `timing`
column). The repeats are timed on the workers, in chunks (chunks_of), as many at once as workers, each worker pinned
to a core of its own for its chunk (pool.time_on_pool, timing_cores, on_core; on Dask on_a_free_core), never in the
command's process: there they were a serial phase after the sweep that no worker could take (issue 49: 2 workers
were 1.2-1.6x one). A start-up engine's runs (Engine startup_s: MJX, Warp, Genesis, Newton) go in chunks of their
own to a worker that has paid it (in the parent they paid the SDK's import and every compilation again: 19 MJX
rollouts, 44 s of a 70 s timing phase of the quick suite). Why a time once, in the worker: issue 29 (the timing
phase, every run timed alone, was a third of the default run); why the accuracy run itself is no timing: with its
counting and its first-call costs it measured Pinocchio's and the reference's runs 2-3x slower than their best of 3,
up to 20x."""
from __future__ import annotations

import gc
import math
import os
import sys
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Callable, NamedTuple

import numpy as np

from ..engines import get_engine
from ..grid import TimeGrid
from ..integrators.base import uncounted
from ..precision import FLOAT64
from ..trajectory import Status
from ..words import plural
from .processes import plugin_fault, raise_unless_data


def _raise_unless_data(exc: BaseException) -> None:
    """raise_unless_data for what a timed run raised, in this process too: a plug-in's SystemExit, GeneratorExit or
    own KeyboardInterrupt leaves the run untimed, as an Exception does; anything else (Ctrl-C, our bug) goes on."""
    if not isinstance(exc, Exception) and not plugin_fault(exc):
        raise exc
    raise_unless_data(exc)
# (their home: harness/tables.py, not run.results, whose columns need the integrals and the scenes' metrics)
from ..tables import SINGLE, disturbed

REPEATS = 3          # timed runs at most
MIN_REPEATS = 2      # timed runs at least, even past the budget: one run has no spread
BUDGET_S = 2.0       # stop repeating once the timed runs have taken this long (after MIN_REPEATS)
# The short warm-up's length (Timing.short_warm_up), steps: a few ms of a Python-stepped run. The full warm-up was a
# quarter of the default run's timing phase (54 of 205 s of its main process, sampled), most of it Python-stepped runs.
WARM_UP_STEPS = 256
# A timing whose spread is larger than its best time measured the machine, not the run: re-timed once, and if still so,
# its row's message says DISTURBED and the Pareto table names it nowhere (issue 21: a spread of 2030 µs/s on a best of
# 1690 made scipy_rk45 "tie" with runs six times faster).
DISTURBED = "timing disturbed"
ONCE = "_once_s"   # a row's single timed run in its worker (s), before the row is stored (timed_once)


class Timing(NamedTuple):
    """best: the fastest timed run (s); spread: the second fastest minus the fastest (s), how far the best is from
    being reproduced (the slowest would mostly measure the one repeat another process preempted); repeats: how many
    ran; disturbed: still disturbed (spread > best) after measure_interleaved re-timed it once; t_end: the timed
    grid's span (s), where time_here knows it."""

    best: float
    spread: float
    repeats: int
    disturbed: bool = False
    t_end: float = math.nan


def measure(run: Callable[[], object], repeats: int = REPEATS, budget_s: float = BUDGET_S,
            min_repeats: int = MIN_REPEATS) -> Timing:
    """Time up to `repeats` calls of run() (at least min(min_repeats, repeats)), stopping once `budget_s` is spent;
    the caller has already warmed it up.

    The garbage collector is off while timing (as timeit does) so a collection does not land in one repeat.
    """
    times: list[float] = []
    run = _uncounted(run)
    enabled = gc.isenabled()
    gc.disable()
    try:
        for i in range(max(1, repeats)):
            start = time.perf_counter()
            run()
            times.append(time.perf_counter() - start)
            if i + 1 >= min_repeats and sum(times) >= budget_s:
                break
    finally:
        if enabled:
            gc.enable()
    return _timing(times)


def once(run: Callable[[], object]) -> float:
    """One timed call of run() (s), uncounted, with the collector off: a single time. The caller has warmed it up."""
    return measure(run, repeats=1, budget_s=0.0, min_repeats=1).best


def timed_once(sim, grid, run) -> dict:
    """measure()'s `timed` hook of a worker's run: its single time right after the accuracy run (its warm-up), s,
    under ONCE (single_time); the sweep and the ladders turn it into their timing columns (step_columns, columns)
    with timing SINGLE."""
    return {ONCE: single_time(sim, grid, run)}


# A single time's least length (s) once it is cut to a run's first steps (single_time): the run's own time per step
# from there on. 20 ms is ~1e4 steps of a Python-stepped run, above the ~1 ms timer and scheduler effects; the timed
# run of the whole grid was 40 % of a sweep's work (profiled, 2026-12-06: 228 of 529 s of the sweep's runs).
PARTIAL_S = 0.02


def single_time(sim, grid, run) -> float:
    """One timed run of sim over grid (s), or for a fixed-step run of an engine whose every step costs the same from
    the first (Timing.short_warm_up: nothing is built per grid length) and whose run lasts more than 2 PARTIAL_S,
    the time of its first WARM_UP_STEPS and of its first steps of about PARTIAL_S, extrapolated along their line to
    the grid's steps. A deciding run is timed again, whole, best of N (time_runs, time_points)."""
    whole = lambda: once(lambda: sim.run(grid))  # noqa: E731
    if getattr(run, "dt", None) is None or not _short_warm_up(run.engine):
        return whole()
    probe = first_steps(grid, WARM_UP_STEPS)
    if 2 * probe.steps >= grid.steps:
        return whole()
    probe_s = once(lambda: sim.run(probe))
    steps = math.ceil(PARTIAL_S * probe.steps / probe_s) if probe_s > 0.0 else grid.steps
    if 2 * steps >= grid.steps:
        return whole()
    part = first_steps(grid, steps)
    part_s = once(lambda: sim.run(part))
    # a line through the two partial runs: a run's own cost outside its steps (its arrays, its trajectory) is the
    # intercept, not scaled with the steps (scaled from the second alone, single times were 0.77-0.9x the whole run's)
    per_step = max(0.0, (part_s - probe_s) / (part.steps - probe.steps))
    return part_s + per_step * (grid.steps - part.steps)


def best_time(run: Callable[[], object], repeats: int = REPEATS, budget_s: float = BUDGET_S) -> float:
    """Best wall time (s) of measure(run, repeats, budget_s)."""
    return measure(run, repeats, budget_s).best


def measure_interleaved(runs: list[Callable[[], object]], repeats: int = REPEATS, budget_s: float = BUDGET_S,
                        min_repeats: int = MIN_REPEATS, first: list[float | None] | None = None) -> list[Timing | None]:
    """measure() for many runs at once (each already warmed up), in rounds: round r times every run still short of
    its repeats once, so the repeats of one run lie a whole round apart. A run drops out of later rounds once it has
    `min_repeats` repeats and has spent `budget_s`. A run that raises is dropped: its entry is None.

    Why rounds: on this project's 2-core machine, two idle default runs timed the same run up to 2x apart while each
    run's back-to-back repeats agreed to a few per cent (a slow period of the host lasts longer than one run's repeats).
    Spread over the phase, the repeats sample different periods: the best is then reproducible across runs, and the
    spread shows a slow period instead of hiding it.

    A run whose timing is disturbed (spread > best) is timed again once, in rounds over those runs; the second timing
    replaces the first, with `disturbed` set when it is disturbed too.

    first: a time each run already has (s; None: none): its worker's single time, or time_runs' single round. It
    counts among the run's `repeats`, not among its `min_repeats`, which are always timed here, alone.
    """
    measured = _rounds(runs, repeats, budget_s, min_repeats, first)
    again = [i for i, m in enumerate(measured) if m is not None and disturbed(m.best, m.spread)]
    for i, m in zip(again, _rounds([runs[i] for i in again], repeats, budget_s, min_repeats) if again else []):
        measured[i] = None if m is None else m._replace(disturbed=bool(disturbed(m.best, m.spread)))
    return measured


def _rounds(runs: list[Callable[[], object]], repeats: int, budget_s: float, min_repeats: int,
            first: list[float | None] | None = None) -> list[Timing | None]:
    """One timing of each run, in rounds (measure_interleaved without the re-time). first: a time each already has
    (None: none), counted among its `repeats` but not among its `min_repeats`, which are all timed here: a run stops
    once it has min_repeats timed here and either `repeats` in all or `budget_s` spent here."""
    given = list(first) if first is not None else [None] * len(runs)
    times: list[list[float] | None] = [[] for _ in runs]
    runs = [_uncounted(run) for run in runs]
    enabled = gc.isenabled()
    gc.disable()
    try:
        for _ in range(max(1, repeats, min_repeats)):
            for i, run in enumerate(runs):
                ts = times[i]
                if ts is None or (len(ts) >= min_repeats and (
                        len(ts) + (given[i] is not None) >= repeats or sum(ts) >= budget_s)):
                    continue
                start = time.perf_counter()
                try:
                    run()
                except BaseException as exc:  # it ran ok before: left untimed rather than breaking the phase
                    _raise_unless_data(exc)
                    times[i] = None
                    continue
                ts.append(time.perf_counter() - start)
    finally:
        if enabled:
            gc.enable()
    return [None if ts is None else _timing(ts + ([given[i]] if given[i] is not None else []))
            for i, ts in enumerate(times)]


def _uncounted(run: Callable[[], object]) -> Callable[[], object]:
    """run() without counting right-hand-side calls (harness.integrators.base.uncounted: the count is bookkeeping, as
    the metrics are, not stepping; ~1 µs a run to enter)."""
    def timed():
        with uncounted():
            return run()
    return timed


def _timing(times: list[float]) -> Timing:
    ordered = sorted(times)
    return Timing(ordered[0], (ordered[1] if len(ordered) > 1 else ordered[0]) - ordered[0], len(ordered))


def time_points(points: list[dict], prepare: Callable[[dict], tuple], repeats: int, budget_s: float,
                select: Callable[[list[int]], set[int]] | None = None,
                elsewhere: Callable[[list[Chunk]], list[list[Timing | None]]] | None = None, ways: int = 1) -> None:
    """A ladder's timing phase (dt ladders, tolerance ladders, the advised runs): the ok points timed after all the
    accuracy runs, best of `repeats` in rounds over the points of each chunk (chunks_of, per timing group: groups),
    timed by elsewhere(chunks) as time_runs' are (pool.time_on_pool: on the workers, each on a core of its own; None:
    here, in turn). prepare(point) -> (simulation, grid), picklable where elsewhere sends it to a worker.
    select(indices of the ok points) -> those to time (None: all); the others keep the single time their worker took
    (timing SINGLE). Sets wall_s (s), us_per_sim_s, us_per_sim_s_spread (µs of stepping per simulated second) and
    timing on each timed point, in place; a point that fails there keeps what it had."""
    ok = [p for p in points if p.get("status") == Status.OK.value]
    chosen = sorted(select(list(range(len(ok))))) if select is not None else range(len(ok))
    ok = [ok[i] for i in chosen]
    first = [single(p) for p in ok]  # its worker's single time is its first repeat, as in time_runs
    pieces = [chunks_of(group, ok, first, repeats, ways, prepare, budget_s)
              for group in groups([(p["engine"], p.get("precision") or FLOAT64) for p in ok])]
    for i, measured in _timed_at_once(elsewhere or in_turn(prepare), pieces).items():
        if measured is not None:
            ok[i].update(columns(measured, measured.t_end))
            if measured.disturbed:
                ok[i]["message"] = with_disturbed(ok[i].get("message"), measured)


def single(row: dict) -> float | None:
    """A row's or point's single time (s), when that is all it has (timing SINGLE), else None."""
    wall = row.get("wall_s")
    return float(wall) if row.get("timing") == SINGLE and isinstance(wall, (int, float)) and math.isfinite(wall) \
        else None


def _warmed(items: dict, prepare: Callable, engine_of: Callable) -> dict:
    """{key: (run, grid)} for each item prepared (prepare(item) -> (simulation, grid)) and warmed up (warm_up), in the
    order given; an item that fails here is left out (it ran ok untimed: left untimed rather than breaking the phase)."""
    warm = {}
    for key, item in items.items():
        try:
            sim, grid = prepare(item)
            warm_up(sim, grid, engine_of(item))
        except BaseException as exc:
            _raise_unless_data(exc)
            continue
        warm[key] = (lambda sim=sim, grid=grid: sim.run(grid)), grid
    return warm


def warm_up(sim, grid: TimeGrid, engine: str) -> None:
    """Run sim once, untimed, before it is timed: its caches, lazily compiled code, first-call costs. The whole grid,
    or for an engine that declares Timing.short_warm_up only the grid's first WARM_UP_STEPS steps (to the first sample
    at or past them): the timed repeats of a run lie a whole round apart (measure_interleaved), so a warm-up leaves
    no cache warm for them anyway; only its first-call costs matter, and a few hundred steps pay them."""
    sim.run(first_steps(grid, WARM_UP_STEPS) if _short_warm_up(engine) else grid)


def _short_warm_up(engine: str) -> bool:
    """Whether the engine declares Timing.short_warm_up; False for a name this registry does not know."""
    try:
        return bool(get_engine(engine).timing.short_warm_up)
    except (KeyError, ValueError):
        return False


def first_steps(grid: TimeGrid, steps: int) -> TimeGrid:
    """grid up to its first sample at or past `steps` steps (the whole grid when it is shorter), same dt."""
    last = min(int(np.searchsorted(grid.sample_steps, max(1, steps))), grid.sample_steps.size - 1)
    return TimeGrid(grid.dt, int(grid.sample_steps[last]), grid.sample_steps[:last + 1], grid.times[:last + 1])


def groups(keys: list[tuple[str, str]]) -> list[list[int]]:
    """The timing groups of runs given by (engine, precision): the indices of the runs prepared side by side and
    timed in rounds together. One group for every engine's runs, except an engine whose precision is process-global
    (Timing.process_global_precision: building a model of one precision releases the models of the other), whose runs
    form a group per precision, after the shared one: the precision met last first, since the sweep ran its runs last
    (pool.one_precision_at_a_time), so its workers still hold that precision and the models they kept
    (pool.prepare_kept): one switch of precision, not two. Empty groups are left out."""
    found: dict[tuple | None, list[int]] = {None: []}
    for index, (engine, precision) in enumerate(keys):
        found.setdefault((engine, precision) if process_global_precision(engine) else None, []).append(index)
    shared = found.pop(None)
    engines = list(dict.fromkeys(engine for engine, _ in found))
    ordered = [indices for engine in engines for key, indices in reversed(found.items()) if key[0] == engine]
    return [indices for indices in [shared, *ordered] if indices]


def process_global_precision(engine: str) -> bool:
    """Whether building a model of one precision releases the other's in a process (Timing.process_global_precision:
    Genesis re-initialises itself); False for a name this registry does not know."""
    try:
        return bool(get_engine(engine).timing.process_global_precision)
    except (KeyError, ValueError):
        return False


def with_disturbed(message, measured: Timing) -> str:
    """A row's message with the DISTURBED mark of its timing appended."""
    mark = f"{DISTURBED}: spread {measured.spread:.3g} s > best {measured.best:.3g} s, also when re-timed"
    return "; ".join(m for m in (message if isinstance(message, str) else "", mark) if m)


def columns(measured: Timing, t_end: float) -> dict:
    """A ladder point's timing columns: wall_s (s), us_per_sim_s and its spread (µs per simulated second; NaN for a
    single timed run: one run has no spread) and timing ("best of N", or SINGLE)."""
    return {"wall_s": measured.best, "us_per_sim_s": measured.best / t_end * 1e6,
            "us_per_sim_s_spread": measured.spread / t_end * 1e6 if measured.repeats > 1 else math.nan,
            "timing": label(measured)}


def label(measured: Timing) -> str:
    """How a time was measured: "best of N", or SINGLE for one timed run."""
    return f"best of {measured.repeats}" if measured.repeats > 1 else SINGLE


def step_columns(measured: Timing, steps: float) -> dict:
    """A sweep row's timing columns (results.csv): wall_s (s), us_per_step and us_per_step_spread (µs per step; NaN
    for a single timed run: one run has no spread) and timing ("best of N", or SINGLE)."""
    per_step = 1e6 / max(1, steps)
    return {"wall_s": measured.best, "us_per_step": measured.best * per_step,
            "us_per_step_spread": measured.spread * per_step if measured.repeats > 1 else math.nan,
            "timing": label(measured)}


class Chunk(NamedTuple):
    """Runs timed together, in rounds, on one core (time_here): runs (RunSpecs of one timing group), first (each
    run's time so far, s, or None: timing.measure_interleaved's first), repeats (REPEATS, or 1: a single time), engine
    (the start-up engine, Timing.startup_s, whose runs these all are, for a worker that paid it; None: any worker),
    prepare (item -> (simulation, grid); None: the worker's own, pool.prepare_kept), budget_s (time_here's)."""

    runs: list
    first: list
    repeats: int = REPEATS
    engine: str | None = None
    prepare: Callable | None = None
    budget_s: float = BUDGET_S


def time_here(runs: list, prepare: Callable, first: list[float | None], repeats: int = REPEATS,
              budget_s: float = BUDGET_S) -> list[Timing | None]:
    """The timings of runs (RunSpecs, or ladder points: dicts with their engine) in this process, on its core alone:
    each prepared and warmed up, then best of `repeats` in rounds (measure_interleaved), first[i] counted among run
    i's repeats, each with its grid's t_end; None for a run that fails here. What a pool worker runs for time_runs and
    time_points (pool.time_on_pool), and they themselves without workers (in_turn)."""
    warm = _warmed(dict(enumerate(runs)), prepare, _engine_of)
    if repeats <= 1:  # a single time: no spread to judge, no re-time
        measured = dict(zip(warm, _rounds([run for run, _ in warm.values()], 1, budget_s, 1)))
    else:
        measured = dict(zip(warm, measure_interleaved([run for run, _ in warm.values()], repeats, budget_s,
                                                      first=[first[i] for i in warm])))
    return [None if measured.get(i) is None else measured[i]._replace(t_end=getattr(warm[i][1], "t_end", math.nan))
            for i in range(len(runs))]


def _engine_of(item) -> str:
    """A timed item's engine: a ladder point's (a dict) or a run's."""
    return item["engine"] if isinstance(item, dict) else item.engine


def in_turn(prepare: Callable) -> Callable[[list[Chunk]], list[list[Timing | None]]]:
    """time_runs' `elsewhere` without workers (--jobs 1 in this process: a debugger's mode): each chunk timed here,
    one after the other."""
    return lambda chunks: [time_here(c.runs, c.prepare or prepare, c.first, c.repeats, c.budget_s)
                           for c in chunks]


def chunks_of(indices: list[int], runs: list, first: list[float | None], repeats: int, ways: int,
              prepare: Callable | None = None, budget_s: float = BUDGET_S) -> list[tuple]:
    """(indices, Chunk) pieces of one timing group's runs, to time at once on `ways` cores: the runs of an engine
    with a declared start-up (Timing.startup_s) apart, for a worker that has paid it, the others together; each split
    round-robin into at most `ways` chunks, so that each chunk's rounds still spread its runs' repeats (in the order
    given: the plan's, mixing cheap and costly runs)."""
    by_engine: dict[str | None, list[int]] = {}
    for i in indices:
        engine = _engine_of(runs[i])
        by_engine.setdefault(engine if startup_s(engine) > 0.0 else None, []).append(i)
    pieces = []
    for engine, members in by_engine.items():
        for k in range(min(max(1, ways), len(members))):
            part = members[k::max(1, ways)]
            pieces.append((part, Chunk([runs[i] for i in part], [first[i] for i in part], repeats, engine, prepare,
                                       budget_s)))
    return pieces


def startup_s(engine: str) -> float:
    """The start-up a worker pays once for an engine before its first run (SDK import, compilations), s: the engine's
    declaration (Timing.startup_s), 0.0 where it declares none or cannot be loaded."""
    try:
        adapter = get_engine(engine)
    except Exception:  # its runs say why; nothing to schedule around
        return 0.0
    declared = getattr(getattr(adapter, "timing", None), "startup_s", 0.0)
    try:
        declared = float(declared)
    except (TypeError, ValueError):
        return 0.0
    return declared if math.isfinite(declared) and declared > 0.0 else 0.0


def time_runs(runs: list, steps: list[float], prepare: Callable,
              select: Callable[[list[int], list[float]], set[int]] | None = None,
              singles: list[float | None] | None = None,
              elsewhere: Callable[[list[Chunk]], list[list[Timing | None]]] | None = None,
              ways: int = 1) -> list[dict]:
    """The sweep's timing phase: the step_columns of finished ok runs, each timing on a core that no other run
    shares. The runs are cut into chunks (chunks_of: per timing group, groups(), into `ways` pieces) and
    elsewhere(chunks) times them (pool.time_on_pool: on the workers, as many at once as workers, each pinned to a
    core of its own; distributed's on the cluster's workers; None: in_turn(prepare), here) -> each chunk's timings,
    None for a run that failed there or whose worker died: its row keeps what it had ({}). A timing still disturbed
    when re-timed carries it as `_disturbed`.

    singles: each run's single time from its worker (s; None: none, then it is timed once first, in a chunk of
    single times); a run timed with repeats counts its single time among its REPEATS (after MIN_REPEATS timed
    alone). select(indices, seconds) -> the indices to time with repeats, from the single times (None: every run);
    the others keep their single time (timing SINGLE, no spread, never re-timed as disturbed): {} for a run whose
    single time came from its worker, which its row has already."""
    singles = list(singles) if singles is not None else [None] * len(runs)
    spread = elsewhere or in_turn(prepare)
    timing_groups = groups([(run.engine, run.precision) for run in runs])
    rows: list[dict] = [{} for _ in runs]
    once = _timed_at_once(spread, [chunks_of([i for i in group if singles[i] is None], runs, singles, 1, ways)
                                   for group in timing_groups])
    seconds = {i: singles[i] for i in range(len(runs)) if singles[i] is not None}
    seconds |= {i: m.best for i, m in once.items() if m is not None}
    repeated = []
    for group in timing_groups:
        known = [i for i in group if i in seconds]
        repeat = set(known) if select is None else set(select(known, [seconds[i] for i in known])) & set(known)
        # its single time counts among its repeats, whether taken once here or in its worker right after its
        # accuracy run (beside another run it is no faster: it lowers neither the best nor, the slowest, the
        # spread); at least MIN_REPEATS are timed alone, whatever it was (one timed-alone repeat of a ladder
        # point, a single slow period of the machine, once changed a "What to use" winner)
        repeated.append(chunks_of([i for i in known if i in repeat], runs,
                                  [seconds.get(i) for i in range(len(runs))], REPEATS, ways))
    measured = _timed_at_once(spread, repeated)
    for i in seconds:
        m = measured.get(i) or once.get(i)  # repeated, else the single time taken here (if any)
        if m is not None:
            rows[i] = step_columns(m, steps[i]) | ({"_disturbed": m} if m.disturbed else {})
    return rows


def _timed_at_once(spread: Callable, pieces_by_group: list[list[tuple]]) -> dict[int, Timing | None]:
    """run index -> its timing, every group's chunks given to spread() at once (they are independent: each chunk
    prepares its own models where it is timed)."""
    pieces = [piece for group in pieces_by_group for piece in group]
    if not pieces:
        return {}
    results = spread([chunk for _, chunk in pieces])
    return {i: m for (indices, _), timed in zip(pieces, results) for i, m in zip(indices, timed)}


# ------------------------------------------------------------------------------------------ a core for each timing
_SAID: set[str] = set()  # what timing_cores has said on this process's terminal (once each)


def timing_cores(workers: int) -> list[int | None]:
    """The core each of `workers` simultaneous timings is pinned to (os.sched_setaffinity): this process's first
    `workers` cores; [None] * workers (unpinned) where the platform cannot pin or has fewer cores than workers, said
    once on the terminal: two timings then share a core, and the times say so (their spread, DISTURBED)."""
    workers = max(1, workers)
    try:
        cores = sorted(os.sched_getaffinity(0)) if hasattr(os, "sched_setaffinity") else []
    except OSError:
        cores = []
    if len(cores) >= workers:
        return cores[:workers]
    why = (f"only {plural(len(cores), 'core')} for {plural(workers, 'worker')}" if cores else
           "this platform cannot pin a process to a core")
    if why not in _SAID:
        _SAID.add(why)
        print(f"stereodyn: warning: timing on {plural(workers, 'worker')} unpinned ({why}): a timed run may share "
              "its core with another", file=sys.stderr)
    return [None] * workers


def _threads() -> list[int]:
    """This process's threads (Linux: /proc/self/task), else [0]: this thread."""
    try:
        return [int(tid) for tid in os.listdir("/proc/self/task")]
    except OSError:
        return [0]


@contextmanager
def on_core(core: int | None, whole_process: bool = True):
    """Pin this process (whole_process: every thread; else the calling thread only, a Dask worker's) to `core` for
    the block, then give back the mask it had; nothing for None. A thread started inside inherits the pin and gets
    the mask back too."""
    if core is None:
        yield
        return
    tids = _threads() if whole_process else [0]
    before = os.sched_getaffinity(0)
    for tid in tids:
        try:
            os.sched_setaffinity(tid, {core})
        except OSError:  # a thread that ended meanwhile
            pass
    try:
        yield
    finally:
        for tid in (_threads() if whole_process else [0]):
            try:
                os.sched_setaffinity(tid, before)
            except OSError:
                pass


LOCK_PREFIX = "stereodyn-timing-core-"  # in the temporary folder: one lock file per core, for on_a_free_core
FREE_CORE_POLL_S = 0.05


@contextmanager
def on_a_free_core():
    """The calling thread pinned, for the block, to a core of this machine on which no other timing runs (one lock
    file per core, flock: machine-wide, across processes, released when its holder dies), waiting for one: a Dask
    worker's timing task (its threads, and other workers' processes on the machine, share its cores). Unpinned where
    the platform cannot pin or lock."""
    try:
        import fcntl
        cores = sorted(os.sched_getaffinity(0))
    except (ImportError, AttributeError, OSError):
        yield
        return
    held = None
    while held is None:
        for core in cores:
            try:
                handle = open(Path(tempfile.gettempdir()) / f"{LOCK_PREFIX}{core}.lock", "a")
            except OSError:  # another user's file: not ours to lock
                continue
            try:
                fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                handle.close()
                continue
            held = core, handle
            break
        else:
            if not any(os.access(Path(tempfile.gettempdir()) / f"{LOCK_PREFIX}{c}.lock", os.W_OK)
                       or not (Path(tempfile.gettempdir()) / f"{LOCK_PREFIX}{c}.lock").exists() for c in cores):
                yield  # no core's lock can be taken by this user: unpinned
                return
            time.sleep(FREE_CORE_POLL_S)
    core, handle = held
    try:
        with on_core(core, whole_process=False):
            yield
    finally:
        handle.close()
