"""Work–precision measuring: dt ladders and stability limits.

For a case × engine × formulation × integrator, a ladder is LADDER_POINTS log-spaced steps from the largest stable dt
(found by bisection) down to t_end / max_steps, where the 4th-order methods reach their round-off floor. Each point is
one untimed accuracy run (errors against the truth, energy drift) and separate timed runs (harness.run.timing: best of N
after the accuracy run as warm-up, within a budget), costed as µs of stepping per simulated second.

The error whose order is fitted (analysis.fitting) is the global error of the state, state_err = max(attitude_err,
omega_err, casimir_drift): a method's order is that of its whole state. (The attitude alone can converge faster than
the method: MuJoCo's semi-implicit Euler on a plane pendulum has the positions of Störmer–Verlet, second order, while
its velocities are first order; explicit Euler on a steady rotation has a second-order phase but a first-order |q|
growth.)

stable_dt_max: the largest dt whose run over t_end finishes ok with energy_drift <= STABLE_ENERGY_DRIFT, by
doubling/halving from a start until the outcome changes, then geometric bisection to STABILITY_RTOL.

A short ladder (run_short_ladder) is for a family whose sweep dt list has fewer than two points in the asymptotic
range: it walks from the list, doubling dt while the coarsest point is asymptotic or at round-off and halving it while
the finest is above the range or failed (unless a coarser run finished: then it failed for its cost), until
SHORT_TARGET points are asymptotic, a point leaves the range in the walk's direction, dt leaves
[t_end / max_steps, t_end / MIN_STEPS] or (halving) SHORT_POINTS points are spent. Its points are untimed: they are
for the order only. Without an order, its note says where the points lie and why the walk stopped.

A first part (run_first_part) is for a family whose error over the whole span stays above the asymptotic range down to
the steps cap (a long horizon): its order is measured by a short ladder over the case's first part, t_end halved until
the cap leaves room for three asymptotic points (first_part_span); its note says over what span.

The ladders run on the sweep's process pool (harness.run.sweep.worker_pool), one task per family.
"""
from __future__ import annotations

import math
from concurrent.futures import as_completed
from typing import Callable

import numpy as np
import pandas as pd

from .. import budget
from . import fitting
from .fitting import declared_order, fit
from ..scenes import scene_of
from ..scenes.cases import CHAOTIC_TAGS, Case, with_overrides
from ..scenes.rigid_body import state_err
from ..trajectory import Status
from ..run import timing
from ..run.processes import raise_unless_data
from ..run.measure import measure as run_measure, prepare as prepare_run, rate
from ..run.spec import Family, base_row  # noqa: F401 (Family: part of this API)
from ..engines.base import EPS
from ..run.workers import WatchedPool

LADDER_COLUMNS = ("case", "engine", "formulation", "integrator", "precision", "dt", "t_end", "steps", "rhs_evals",
                  "status", "message", "attitude_err", "attitude_err_end", "omega_err", "casimir_drift", "energy_drift",
                  "state_err", "wall_s", "us_per_sim_s", "us_per_sim_s_spread", "rhs_per_sim_s", "source")
LADDER, SHORT_LADDER = "ladder", "short-ladder"   # the `source` of a ladder's points and convergence row
LADDER_POINTS = 10
TIMING_REPEATS, TIMING_BUDGET_S = 3, 0.3
STABLE_ENERGY_DRIFT = 1.0    # energy off by its whole scale: the run has blown up even if |ω| is not yet 1e6 x
STABILITY_RTOL = 0.02        # bisection stops when the bracket [stable, unstable] is this tight (relative)
MIN_STEPS = 20               # the largest dt tried is t_end / MIN_STEPS: fewer steps say nothing about stability
# A short ladder stops at SHORT_TARGET asymptotic points: three, so that one point bent by rounding or by the
# pre-asymptotic range shows as a bent line, and so that a fit steeper than the declared order can be kept as
# superconvergence (fitting.STEEP). Its walk to finer steps ends after SHORT_POINTS points in all (each at most
# max_steps steps); its walk to coarser steps goes on up to t_end / MIN_STEPS, which an exact method needs to be called
# exact: doubling from dt, all its points together cost fewer steps than one run at dt (t_end/2dt + t_end/4dt + ...).
# Measured: strang_free_flow on a 500 s case from dt = 0.25 stopped at 6.4 s with a 6-point cap, its claim unmeasured.
SHORT_POINTS, SHORT_TARGET = 6, 3


# ------------------------------------------------------------------------------------------------ one point

def measure(family: Family, dt: float, timed: bool = True, with_truth: bool = True) -> dict:
    """One ladder point (measure.measure): accuracy run, errors against the truth when with_truth (computed on the
    point's grid), then timed runs when timed. Never raises."""
    run = family.run(dt=float(dt))
    try:
        with budget.within("run", budget.configured().run_s):  # the point's truth under a run's budget, as before
            truth = case_truth_on(run) if with_truth else None
    except budget.BudgetExceeded as exc:
        return {**base_row(run, run.grid), "source": LADDER, "status": Status.FAILED.value, "message": str(exc)}
    except Exception as exc:  # a point that breaks is data, as in the sweep
        raise_unless_data(exc)
        return {**base_row(run, run.grid), "source": LADDER, "status": Status.FAILED.value,
                "message": f"truth failed: {type(exc).__name__}: {exc}".splitlines()[0]}
    row = run_measure(run, truth, full=False, timed=_timed if timed else None)
    row.update(source=LADDER, rhs_evals=row.get("_rhs_evals", math.nan), rhs_per_sim_s=math.nan)
    if "_rhs_evals" in row:  # as the engine counts them: a fixed-step run without counts has none here
        row["rhs_per_sim_s"] = rate(row["_rhs_evals"], row["t_end"])
    if with_truth and "attitude_err" in row:
        row["state_err"] = state_err(row)
    return {k: v for k, v in row.items() if k in LADDER_COLUMNS}


def case_truth_on(run) -> object:
    """The truth of a run's case on the run's own grid (its scene's Scene.truth), uncertified."""
    return scene_of(run.case).truth(run.case, [run.grid], False)


def _timed(sim, grid) -> dict:
    return timing.columns(timing.measure(lambda: sim.run(grid), TIMING_REPEATS, TIMING_BUDGET_S), grid.t_end)


def time_points(points: list[dict], families_by_label: dict[tuple, "Family"]) -> None:
    """The ladders' timing phase (harness.run.timing.time_points: a timed run shares the cores with no other run)."""
    def prepare(row: dict):
        family = families_by_label[(row["case"], row["engine"], row["formulation"], row["integrator"],
                                    row["precision"])]
        return prepare_run(family.run(dt=row["dt"]))

    timing.time_points(points, prepare, TIMING_REPEATS, TIMING_BUDGET_S)


def _stable(row: dict) -> bool:
    drift = row.get("energy_drift", math.nan)
    return row.get("status") == Status.OK.value and not (isinstance(drift, float) and drift > STABLE_ENERGY_DRIFT)


# ------------------------------------------------------------------------------------------------ stability

def walk(dt: float, direction: int, dt_floor: float, dt_cap: float):
    """dt doubled (direction +1) or halved (-1) again and again while it stays in [dt_floor, dt_cap]: the one walk of
    the stability search and the short ladders."""
    while True:
        dt = dt * 2.0 ** direction
        if not dt_floor * (1 - 1e-12) <= dt <= dt_cap * (1 + 1e-12):
            return
        yield dt


def stability_limit(is_stable: Callable[[float], bool], dt_start: float, dt_cap: float,
                    dt_floor: float) -> tuple[float, str]:
    """(largest stable dt, note): doubling or halving from dt_start until the outcome changes, then geometric
    bisection to STABILITY_RTOL. NaN with a note when no change is found in [dt_floor, dt_cap]."""
    dt = min(dt_start, dt_cap)
    first = is_stable(dt)
    last = {first: dt}  # the last dt tried with each outcome
    for dt in walk(dt, 1 if first else -1, dt_floor, dt_cap):
        outcome = is_stable(dt)
        last[outcome] = dt
        if outcome != first:
            break
    else:
        return math.nan, (f"stable up to dt = {dt:.4g} s (t_end / {MIN_STEPS} is the largest tried)" if first
                          else f"unstable down to dt = {dt:.4g} s")
    stable_dt, unstable_dt = last[True], last[False]
    while unstable_dt / stable_dt > 1.0 + STABILITY_RTOL:
        middle = math.sqrt(stable_dt * unstable_dt)
        if is_stable(middle):
            stable_dt = middle
        else:
            unstable_dt = middle
    return stable_dt, ""


# ------------------------------------------------------------------------------------------------ ladders

def ladder_dts(top: float, bottom: float, points: int = LADDER_POINTS) -> list[float]:
    """points log-spaced steps from top down to bottom (each rounded to 4 significant digits, so a dt prints back)."""
    if not bottom < top:
        return [top]
    return [float(f"{x:.4g}") for x in np.geomspace(top, bottom, points)]


def run_ladder(family: Family, max_steps: int) -> tuple[list[dict], dict]:
    """The ladder of one family: its points and its convergence row. Never raises."""
    case = family.case
    declared = declared_order(family.engine, family.integrator, family.formulation)
    cap, floor = case.t_end / MIN_STEPS, case.t_end / max_steps
    cache: dict[float, dict] = {}

    def is_stable(dt: float) -> bool:
        cache[dt] = measure(family, dt, timed=False, with_truth=False)
        return _stable(cache[dt])

    start = max(case.dt)
    stable_dt, stability_note = stability_limit(is_stable, start, cap, floor)
    top = stable_dt if math.isfinite(stable_dt) else (cap if "stable up to" in stability_note else start)
    points = [measure(family, dt, timed=False) for dt in ladder_dts(top, floor)]  # timed later (time_points)
    frame = pd.DataFrame(points, columns=list(LADDER_COLUMNS))
    row = {**family.columns, "stable_dt_max": stable_dt, "source": LADDER,
           **fit(frame, declared, family.precision)}
    if stability_note:
        row["note"] = "; ".join(x for x in (row["note"], stability_note) if x)
    return points, row


def run_short_ladder(family: Family, known: list[dict], max_steps: int) -> tuple[list[dict], dict]:
    """The short ladder of a family whose own dt list (known: the sweep's runs of it, with columns dt, steps, status,
    state_err) has fewer than two asymptotic points: its points (untimed) and its convergence row. A point that
    breaks is data (measure), as in the sweep."""
    case = family.case
    declared = declared_order(family.engine, family.integrator, family.formulation)
    cap, floor = case.t_end / MIN_STEPS, case.t_end / max_steps
    columns = ["dt", "steps", "status", "state_err"]
    new: list[dict] = []

    def frame() -> pd.DataFrame:  # the sweep's points and the new ones
        return pd.DataFrame([{c: p.get(c, math.nan) for c in columns} for p in known + new], columns=columns)

    def marked() -> pd.DataFrame:
        return fitting.regimes(frame(), EPS[family.precision])[0]

    def asymptotic() -> int:
        return int((marked()["regime"] == fitting.ASYMPTOTIC).sum())

    # a point that leaves the range in the walk's direction ends that direction
    leaves = {1: (fitting.ABOVE, fitting.FAILED), -1: (fitting.ROUNDOFF, fitting.IRREGULAR)}
    stops = []
    for direction in (1, -1):  # coarser first: its steps are the cheap ones
        points = marked()
        edge = points.iloc[0] if direction == 1 else points.iloc[-1]
        if asymptotic() >= SHORT_TARGET or edge["regime"] in leaves[direction]:
            continue
        if direction == -1 and edge["regime"] == fitting.FAILED and (points["regime"] != fitting.FAILED).any():
            continue  # failed finer than a run that finished (a run budget, not a stability limit): finer costs more
        last = None
        for dt in walk(float(edge["dt"]), direction, floor, cap):
            if direction == -1 and len(new) >= SHORT_POINTS:  # the coarse walk ends at the cap (its cost: see above)
                stops.append(f"short ladder stopped at {SHORT_POINTS} points")
                break
            previous = marked().iloc[-1]  # the finest point before this one (used when walking finer)
            new.append(measure(family, float(f"{dt:.4g}"), timed=False) | {"source": SHORT_LADDER})
            points = marked()
            last = points.loc[points["dt"] == new[-1]["dt"], "regime"].iloc[-1]
            if asymptotic() >= SHORT_TARGET or last in leaves[direction]:
                break
            if direction == -1 and last == previous["regime"] == fitting.ABOVE \
                    and new[-1]["state_err"] > previous["state_err"] * 2.0 ** -fitting.FLOOR_SLOPE:
                # saturated (an attitude error of order pi, a chaotic separation): finer steps here are the costly ones
                stops.append(f"state_err not falling above {fitting.ASYMPTOTIC_MAX:g} from dt = {previous['dt']:.3g} "
                             f"to {new[-1]['dt']:.3g}")
                break
        else:
            stops.append(f"dt = {dt if last else edge['dt']:.3g} is the " + (
                f"largest tried (t_end / {MIN_STEPS})" if direction == 1 else f"smallest tried (t_end / {max_steps})"))
    row = {**family.columns, "stable_dt_max": math.nan, "source": SHORT_LADDER}
    row.update(fit(frame(), declared, family.precision))
    if not math.isfinite(row["order"]):
        row["note"] = "; ".join([row["note"], *dict.fromkeys(stops), *_short_reason(family, marked())])
    return new, row


def _short_reason(family: Family, points: pd.DataFrame) -> list[str]:
    """Why a short ladder found no order, in words a reader acts on (points: fitting.regimes' marked points)."""
    at_round_off = points[points["regime"] == fitting.ROUNDOFF]
    others = points[points["regime"] != fitting.ROUNDOFF]
    # A point finer than every point at round-off that did not run ok (a run budget: an elliptic-function step costs
    # 1.3 ms) has no error: no evidence either way. Whether the method is exact rests on the points that ran.
    unrun = others[(others["regime"] == fitting.FAILED) & (others["dt"] < at_round_off["dt"].min())] \
        if len(at_round_off) else others.iloc[:0]
    others = others.drop(unrun.index)
    if len(at_round_off) and (others.empty or others["dt"].min() > at_round_off["dt"].max()):
        largest = at_round_off["dt"].max()
        ran = "" if unrun.empty else (
            f" (dt = {', '.join(f'{dt:.3g}' for dt in unrun['dt'])} did not run ok: {fitting.NO_EVIDENCE}, so this "
            f"rests on the {len(at_round_off)} points that ran, dt = {at_round_off['dt'].min():.3g} to {largest:.3g})")
        if others.empty:  # exact at every dt the walk reached: up to t_end / MIN_STEPS, or the walk stopped early
            return ["exact for this motion: the error is at round-off up to the largest dt tried" + ran] \
                if largest * 2.0 > family.case.t_end / MIN_STEPS * (1 + 1e-9) else []
        first = others.loc[others["dt"].idxmin()]
        what = {fitting.FAILED: "did not run ok", fitting.ABOVE: f"state_err > {fitting.ASYMPTOTIC_MAX:g}",
                fitting.ASYMPTOTIC: "the error leaves round-off",
                fitting.IRREGULAR: "the error leaves round-off"}[first["regime"]]
        if first["regime"] == fitting.FAILED:
            return [f"error at round-off for every stable dt: every dt up to {largest:.3g} (dt = {first['dt']:.3g}: "
                    f"{what}){ran}"]
        return [f"error at round-off for every dt up to {largest:.3g} (dt = {first['dt']:.3g}: {what}){ran}"]
    chaotic = sorted(set(family.case.tags) & set(CHAOTIC_TAGS))
    ok = points[points["regime"] != fitting.FAILED]
    if len(ok) and (ok["regime"] == fitting.ABOVE).all() and chaotic:
        return [f"the case is {'/'.join(chaotic)}: its error grows exponentially and stays above the asymptotic "
                "range at every dt tried"]
    return []


# A first part keeps FIRST_PART_MARGIN between the range's top and its model error at the coarsest of three points
# above the steps cap, and is at least t_end / 2 ** FIRST_PART_HALVINGS long.
FIRST_PART_MARGIN, FIRST_PART_HALVINGS = 2.0, 10


def first_part_span(t_end: float, dt: float, err: float, order: float, max_steps: int) -> float:
    """The longest span t_end / 2^k (k >= 1) over which three dt down to its steps cap, 4, 2 and 1 x span / max_steps,
    are in the asymptotic range by the error model err x (t / t_end) x (dt' / dt)^order (a phase error, growing
    linearly in time; order the declared one) from one point (dt, err) over t_end; NaN where none is."""
    for k in range(1, FIRST_PART_HALVINGS + 1):
        span = t_end / 2 ** k
        coarsest = 4.0 * span / max_steps
        if err * (span / t_end) * (coarsest / dt) ** order <= fitting.ASYMPTOTIC_MAX / FIRST_PART_MARGIN:
            return span
    return math.nan


def run_first_part(family: Family, points: list[dict], max_steps: int, row: dict) -> tuple[list[dict], dict]:
    """The order of a family whose short ladder found none, its finest ok point above the asymptotic range (or its
    only asymptotic one) at the steps cap: a short ladder over the case's first part (first_part_span) from 4 x the
    part's cap. points: the family's sweep runs and short-ladder points; row: its convergence row. Returns the new
    points (their t_end the part's) and the row: the part's fit where it gives an order, its note saying over what
    span; else the row as it was, its note saying what the part gave. ([], row) where this does not apply."""
    case = family.case
    declared = declared_order(family.engine, family.integrator, family.formulation)
    columns = ["dt", "steps", "status", "state_err"]
    marked = fitting.regimes(pd.DataFrame([{c: p.get(c, math.nan) for c in columns} for p in points],
                                          columns=columns), EPS[family.precision])[0]
    ok = marked[marked["regime"] != fitting.FAILED]
    if math.isfinite(row.get("order", math.nan)) or not math.isfinite(declared) or ok.empty \
            or ok.iloc[-1]["regime"] not in (fitting.ABOVE, fitting.ASYMPTOTIC):
        return [], row
    finest = ok.iloc[-1]
    span = first_part_span(case.t_end, float(finest["dt"]), float(finest["state_err"]), declared, max_steps)
    if not math.isfinite(span):
        return [], row
    start = float(f"{4.0 * span / max_steps:.4g}")
    part = Family(with_overrides(case, t_end=span, dt=[start]), family.engine, family.formulation, family.integrator,
                  family.precision)
    new = [measure(part, start, timed=False) | {"source": SHORT_LADDER}]
    more, fitted = run_short_ladder(part, new, max_steps)
    new += more
    why = (f"over all {case.t_end:g} s, {int((marked['regime'] == fitting.ASYMPTOTIC).sum())} point(s) in the "
           f"asymptotic range down to dt = {finest['dt']:.3g} (state_err {finest['state_err']:.2g}), steps cap t_end / "
           f"{max_steps}")
    if math.isfinite(fitted["order"]):
        note = f"{fitting.FIRST_PART} {span:g} s of {case.t_end:g} s ({why})"
        return new, {**fitted, "note": "; ".join(x for x in (note, fitted["note"]) if x)}
    return new, {**row, "note": "; ".join(x for x in (row["note"], f"over the first {span:g} s no order either "
                                                                     f"({fitted['points']} asymptotic point(s))") if x)}


def families(cases: list[Case], engines: list[str], integrators: list[str] | None,
             formulations: tuple[str, ...] | None = None) -> list[Family]:
    """The fixed-step run families a sweep of these cases would have (harness.run.plan.plan's selection)."""
    from ..run.plan import plan

    specs, _ = plan(cases, engines, integrators)
    out = {}
    for spec in specs:
        if spec.dt is None or (formulations is not None and spec.formulation not in formulations):
            continue
        out.setdefault((spec.case.name, spec.engine, spec.formulation, spec.integrator, spec.precision),
                       Family(spec.case, spec.engine, spec.formulation, spec.integrator, spec.precision))
    return list(out.values())


def _failed_family(family: Family, exc: BaseException, source: str = LADDER) -> tuple[list[dict], dict]:
    """A family whose worker died: no points, and its convergence row says why."""
    return [], {**family.columns, "source": source,
                "note": f"worker failed: {type(exc).__name__}: {exc}".splitlines()[0]}


def run_ladders(chosen: list[Family], max_steps: int, pool: WatchedPool | None = None,
                progress: Callable[[str], None] | None = None,
                short: list[tuple[Family, list[dict], int]] = (),
                first_parts: list[tuple[Family, list[dict], int, dict]] = ()) -> tuple[list[dict], list[dict]]:
    """Every family's ladder, every short ladder (short: (family, its sweep runs, its steps cap), run_short_ladder)
    and every first part (first_parts: (family, its points, its steps cap, its row), run_first_part), their accuracy
    runs in this process (pool None) or on the sweep's pool, then the ladders' points timed here (time_points; the
    short ladders' points stay untimed). Returns (points, convergence rows): the ladders' in the order of `chosen`,
    then the short ladders' in the order of `short`, then the first parts', whatever order the families finish in."""
    tasks = [(run_ladder, family, (family, max_steps), LADDER) for family in chosen]
    tasks += [(run_short_ladder, family, (family, known, steps), SHORT_LADDER) for family, known, steps in short]
    tasks += [(run_first_part, family, (family, known, steps, row), SHORT_LADDER)
              for family, known, steps, row in first_parts]
    results: dict[int, tuple[list[dict], dict]] = {}
    if pool is None:
        for index, (function, family, args, _) in enumerate(tasks):
            results[index] = function(*args)
            if progress:
                progress(family.label)
    else:
        futures = {pool.submit(function, *args): index for index, (function, _, args, _) in enumerate(tasks)}
        for future in as_completed(futures):
            index = futures[future]
            try:
                results[index] = future.result()
            except Exception as exc:  # a worker that died: the family's row says so
                raise_unless_data(exc)
                results[index] = _failed_family(tasks[index][1], exc, tasks[index][3])
            if progress:
                progress(tasks[index][1].label)
    points, rows = [], []
    for index in range(len(tasks)):
        points += results[index][0]
        rows.append(results[index][1])
    # the timing phase, once every accuracy run is done and the pool idle: each point timed alone, here
    time_points([p for p in points if p.get("source") == LADDER],
                {f.key: f for f in chosen})
    return points, rows
