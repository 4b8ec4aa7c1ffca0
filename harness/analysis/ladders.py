"""The ladders' tables and rules, without running anything: what a dt ladder and a tolerance ladder are (their
columns, sources and constants), which families a sweep's selection has, the stability search and the short ladders'
walk over a given `is_stable`, the first part's span, and the words of a short ladder that found no order.

The runs themselves (accuracy runs, timing, the pool) are harness.pipeline.dt_ladders and
harness.pipeline.tolerance_ladders; their module docstrings say what a ladder measures.
"""
from __future__ import annotations

import math
from typing import Callable

import numpy as np
import pandas as pd

from . import fitting
from ..engines import declared, get_engine
from ..precision import EPS, FLOAT64
from ..run.spec import Family
from ..scenes.cases import CHAOTIC_TAGS, Case
from ..trajectory import Status

# timing: how wall_s was measured, as results.csv's column: SINGLE (once, in the worker) or "best of N" (alone)
LADDER_COLUMNS = ("case", "engine", "formulation", "integrator", "precision", "dt", "t_end", "steps", "rhs_evals",
                  "status", "message", "attitude_err", "attitude_err_end", "omega_err", "casimir_drift", "energy_drift",
                  "state_err", "wall_s", "us_per_sim_s", "us_per_sim_s_spread", "rhs_per_sim_s", "source",
                  "timing")
LADDER, SHORT_LADDER = "ladder", "short-ladder"   # the `source` of a ladder's points and convergence row
LADDER_POINTS = 10
STABLE_ENERGY_DRIFT = 1.0    # energy off by its whole scale: the run has blown up even if |ω| is not yet 1e6 x
STABILITY_RTOL = 0.02        # bisection stops when the bracket [stable, unstable] is this tight (relative)
MIN_STEPS = 20               # the largest dt tried is t_end / MIN_STEPS: fewer steps say nothing about stability


# A short ladder measures finer: it halves dt from the finest point until the judged range (fitting.judged_start) is
# settled, SHORT_TARGET points, three, so that one point bent by rounding or by the pre-asymptotic range shows as a
# bent line, and so that a fit steeper than the declared order can be kept as superconvergence (fitting.STEEP); or
# until the round-off floor shows, the steps cap (each point at most max_steps steps) or SHORT_POINTS points in all
# stop it. More evidence for an order comes from smaller steps, toward the asymptotic range (issue 45: a coarser point
# added to settle an order failed a correct rk4 on a user's body). It walks coarser only where finer steps cannot give
# a fit at all: fewer than two points in the band and the finest at round-off (an exact method, which needs steps up to
# t_end / MIN_STEPS to be called exact, or a float32 family whose round-off closes the fine end): doubling from dt,
# all its points together cost fewer steps than one run at dt (t_end/2dt + t_end/4dt + ...). Measured:
# strang_free_flow on a 500 s case from dt = 0.25 stopped at 6.4 s with a 6-point cap, its claim unmeasured.
SHORT_POINTS, SHORT_TARGET = 6, 3


def stable(row: dict) -> bool:
    """Whether a stability-search run finished ok without its energy blowing up (STABLE_ENERGY_DRIFT)."""
    drift = row.get("energy_drift", math.nan)
    return row.get("status") == Status.OK.value and not (isinstance(drift, float) and drift > STABLE_ENERGY_DRIFT)


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


def ladder_dts(top: float, bottom: float, points: int = LADDER_POINTS) -> list[float]:
    """points log-spaced steps from top down to bottom (each rounded to 4 significant digits, so a dt prints back)."""
    if not bottom < top:
        return [top]
    return [float(f"{x:.4g}") for x in np.geomspace(top, bottom, points)]


def short_ladder(family: Family, known: list[dict], max_steps: int, declared: float,
                 measure_at: Callable[[float], dict]) -> tuple[list[dict], dict]:
    """A short ladder's walk (harness.pipeline.dt_ladders' docstring): from the family's known points (columns dt,
    steps, status, state_err), which dt to run next, coarser first, until SHORT_TARGET points are asymptotic or the walk
    stops; measure_at(dt) runs one point and returns its ladder row (the pipeline's). Returns the new points and the
    family's convergence row (fitted against declared, its note saying why where no order came)."""
    case = family.case
    cap, floor = case.t_end / MIN_STEPS, case.t_end / max_steps
    columns = ["dt", "steps", "status", "state_err"]
    new: list[dict] = []

    def frame() -> pd.DataFrame:  # the sweep's points and the new ones
        return pd.DataFrame([{c: p.get(c, math.nan) for c in columns} for p in known + new], columns=columns)

    def marked() -> pd.DataFrame:
        return fitting.regimes(frame(), EPS[family.precision])[0]

    def asymptotic() -> int:
        return int((marked()["regime"] == fitting.ASYMPTOTIC).sum())

    def band() -> int:  # the points above round-off and at most ASYMPTOTIC_MAX, judged or pre-asymptotic
        return int(marked()["regime"].isin((fitting.ASYMPTOTIC, fitting.PRE_ASYMPTOTIC)).sum())

    # a point that leaves the range in the walk's direction ends that direction
    leaves = {1: (fitting.ABOVE, fitting.FAILED), -1: (fitting.ROUNDOFF, fitting.IRREGULAR)}
    stops = []
    for direction in (-1, 1):  # finer first: toward the asymptotic range
        points = marked()
        edge = points.iloc[0] if direction == 1 else points.iloc[-1]
        if asymptotic() >= SHORT_TARGET or edge["regime"] in leaves[direction]:
            if direction == -1 and edge["regime"] in leaves[-1] and asymptotic() < SHORT_TARGET:
                stops.append(f"finer: the round-off floor shows at dt = {edge['dt']:.3g}")
            continue
        ran = points[points["regime"] != fitting.FAILED]
        if direction == 1 and (band() >= 2 or ran.empty or ran.iloc[-1]["regime"] not in leaves[-1]):
            continue  # coarser only where finer steps cannot give a fit at all (the walk's comment above)
        if direction == -1 and edge["regime"] == fitting.FAILED and (points["regime"] != fitting.FAILED).any():
            stops.append(f"finer: dt = {edge['dt']:.3g} did not run ok where a coarser dt did (a run budget)")
            continue  # failed finer than a run that finished (a run budget, not a stability limit): finer costs more
        last = None
        for dt in walk(float(edge["dt"]), direction, floor, cap):
            if direction == -1 and len(new) >= SHORT_POINTS:  # the coarse walk ends at the cap (its cost: see above)
                stops.append(f"short ladder stopped at {SHORT_POINTS} points")
                break
            previous = marked().iloc[-1]  # the finest point before this one (used when walking finer)
            new.append(measure_at(float(f"{dt:.4g}")) | {"source": SHORT_LADDER})
            points = marked()
            last = points.loc[points["dt"] == new[-1]["dt"], "regime"].iloc[-1]
            if asymptotic() >= SHORT_TARGET:
                stops.append(f"{'finer' if direction == -1 else 'coarser'} to dt = {new[-1]['dt']:.3g}: the slopes "
                             f"settled ({SHORT_TARGET} points judged)")
                break
            if last in leaves[direction]:
                stops.append(f"finer to dt = {new[-1]['dt']:.3g}: the round-off floor shows" if direction == -1 else
                             f"coarser to dt = {new[-1]['dt']:.3g}: " + ("not ok" if last == fitting.FAILED else
                                                                         f"state_err > {fitting.ASYMPTOTIC_MAX:g}"))
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
    row.update(fitting.fit(frame(), declared, family.precision))
    if not math.isfinite(row["order"]):
        row["note"] = "; ".join([row["note"], *dict.fromkeys(stops), *short_reason(family, marked())])
    elif new:  # how far it measured and why it stopped: the evidence's extent
        row["note"] = "; ".join([x for x in (row["note"], *dict.fromkeys(stops)) if x])
    return new, row


def short_reason(family: Family, points: pd.DataFrame) -> list[str]:
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


# ------------------------------------------------------------------------------------------------ tolerance ladders

TOLERANCE_COLUMNS = ("case", "engine", "formulation", "integrator", "precision", "tolerance", "t_end", "steps", "rhs_evals",
                     "status", "message", "attitude_err", "attitude_err_end", "omega_err", "casimir_drift",
                     "energy_drift", "state_err", "err_over_tol", "wall_s", "us_per_sim_s", "us_per_sim_s_spread",
                     "rhs_per_sim_s", "steps_per_sim_s", "timing")


TOLERANCES = tuple(10.0 ** -k for k in range(3, 14))  # --dt-ladder: every decade


# The default run's ladders: every other decade, which halves their cost (~0.5 min on two cores, most of it Radau's
# and BDF's tight points) and still spans the range.
DEFAULT_TOLERANCES = TOLERANCES[::2]


# A point whose accuracy run took longer than this (s) ends its ladder: each tighter tolerance costs more. Measured on
# the 2-core dev machine (default ladder cases, t_end 20): the scipy methods' points take 0.005-3 s, BDF's and
# Radau's at 1e-12 the longest.
POINT_BUDGET_S = 5.0


AdaptiveFamily = Family  # runs of one adaptive integrator that differ only in the requested tolerance


def adaptive_families(cases: list[Case], engines: list[str], integrators: list[str] | None,
             formulations: tuple[str, ...] | None = None) -> list[AdaptiveFamily]:
    """Every adaptive integrator (Offer.adaptive) of the engines, on each formulation and case the engine models;
    integrators: the names chosen (None: all of them, whatever the sweep's default). formulations: only these (an
    engine with formulations but none of these: its first), None: all."""
    out = []
    for name in engines:
        engine = get_engine(name)
        chosen = [i for i in engine.integrators()
                  if engine.offer(i).adaptive and (integrators is None or i in integrators)]
        own, model = declared.formulations(engine) or ("",), declared.rigid_body(engine)
        if formulations is not None:
            own = tuple(f for f in own if f in formulations) or own[:1]
        for case in cases:
            if engine.unsupported(case):
                continue
            for integrator in chosen:
                for formulation in own:
                    if model.unsupported_run(case, formulation, integrator):
                        continue
                    for precision in engine.offer(integrator).precisions:
                        out.append(AdaptiveFamily(case, name, formulation, integrator, precision))
    return out


def failed_point(family: AdaptiveFamily, tolerance: float, message: str) -> dict:
    return {**family.columns, "tolerance": float(tolerance), "status": Status.FAILED.value,
            "message": message.splitlines()[0]}


def adaptive_cost(family: AdaptiveFamily) -> float:
    """Rank of a family's cost, to start the costliest first: the engine's cost of a step (Timing.pass_us)."""
    return get_engine(family.engine).timing.pass_us


def tolerance_frame(points: list[dict]) -> pd.DataFrame:
    """The points as tolerance.csv's table (TOLERANCE_COLUMNS, NaN where a column does not apply)."""
    df = pd.DataFrame(points, columns=list(TOLERANCE_COLUMNS))
    return df.fillna({"formulation": "", "message": "", "precision": FLOAT64}).astype({"tolerance": float})
