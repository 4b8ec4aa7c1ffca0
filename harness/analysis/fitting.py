"""Work–precision fitting: the one order fitter (order_slope), the round-off floor and the order of a ladder's points
(fit), the orders of a sweep's own dt lists, the tolerance proportionality of a tolerance ladder (tolerance_fit), and
the Pareto table (the cheapest run, fixed-step or adaptive, reaching each accuracy target).

- the round-off floor: walking from large to small dt among the points below ASYMPTOTIC_MAX, the first point after
  which the error falls with a local slope below FLOOR_SLOPE while it is below FLOOR_MAX (a stall higher up is not
  round-off); floor_dt is that point's dt, floor_err the smallest error from there on;
- each point's regime (regimes): failed (not ok), above (state_err > ASYMPTOTIC_MAX), round-off (below
  ROUNDOFF_MARGIN times the rounding level: eps steps, or the measured floor_err where one is found), irregular (at or
  after the floor but above that: an error that does not fall steadily with dt) or asymptotic;
- the order: least-squares slope of log state_err against log dt over the asymptotic points; at least two, and a fit
  of two only when its slope is not more than STEEP above the declared order (two points cannot tell superconvergence
  from a point at round-off); a fit of three or more that far above is kept with the note SUPERCONVERGENT;
- without an order the note says why: how many points are asymptotic and where the others lie (reason).
"""
from __future__ import annotations

import math
import re

import numpy as np
import pandas as pd

from .. import checks
from ..engines import EngineError, get_engine
from ..report.markdown import number as _num
from ..trajectory import Status

CONVERGENCE_COLUMNS = ("case", "engine", "formulation", "integrator", "order", "floor_dt", "floor_err",
                       "stable_dt_max", "declared_order", "points", "source", "note")
PARETO_COLUMNS = ("case", "target", "engine", "formulation", "integrator", "dt", "tolerance", "attitude_err",
                  "us_per_sim_s", "us_per_sim_s_spread", "rhs_per_sim_s", "steps", "source", "ties", "not_recommended")
# The columns a Pareto cell copies from its winning candidate.
_CELL_COLUMNS = PARETO_COLUMNS[2:13]
# pareto.csv's `source`: where the winning candidate came from.
SOURCE_SWEEP, SOURCE_LADDER, SOURCE_TOLERANCE = "sweep", "ladder", "tolerance_ladder"
ORDER_QUANTITY = "convergence_order"

# A state error above this (rad, or relative for ω) is pre-asymptotic: higher-order terms and the saturation of the
# attitude angle at π bend the curve (measured on the suite: RK4 at 5e-2 rad gives a slope of 3.6, Euler at 0.3 of 1.2).
ASYMPTOTIC_MAX = 3e-2
# Below ROUNDOFF_MARGIN × eps × steps the error is contaminated by rounding, which accumulates at most ~ eps per step
# (measured floors of the suite: 2e-14 to 5e-12 rad after 2e3 to 2e4 steps): a 30x margin keeps its share of a
# 2-point slope below 0.03.
ROUNDOFF_MARGIN = 30.0
EPS = float(np.finfo(float).eps)
FLOOR_SLOPE = 0.5            # a local slope below this: the error has stopped falling
FLOOR_MAX = 1e-6             # a stall above this is not round-off (pre-asymptotic wiggles, resonances)
ACCURACY_TARGETS = tuple(10.0 ** -k for k in range(2, 13))


def order_slope(dt, err) -> float:
    """The convergence order of errors err at steps dt: the least-squares slope of log err against log dt (the
    error is the dependent variable: err ~ C dt^p). The one order fitter of the harness (convergence.csv,
    harness.testing)."""
    return float(np.polyfit(np.log(np.asarray(dt, dtype=float)), np.log(np.asarray(err, dtype=float)), 1)[0])


def declared_order(engine: str, integrator: str) -> float:
    """The order the engine declares for an integrator (Engine.declared_order); NaN for an engine not registered."""
    try:
        return get_engine(engine).declared_order(integrator)
    except (KeyError, EngineError):
        return math.nan


FAILED, ABOVE, ROUNDOFF, ASYMPTOTIC = "failed", "above", "round-off", "asymptotic"
IRREGULAR = "irregular"  # at or after the floor, yet well above it: the error does not fall steadily with dt
# Where the coarsest asymptotic pair's local slope differs from the next pair's by more than PRE_ASYMPTOTIC_GAP, the
# coarsest point is not yet asymptotic (higher-order terms as large as the leading one) and leaves the fit, as long as
# two points remain. Measured: Drake's rpy_ball runge_kutta3 on kovalevskaya, dt 1e-2, 3e-3, 1e-3, has local slopes
# 1.06 then 2.90 (all three fit 1.92); from 4e-3 down to 2.5e-4 they settle at 2.75, 2.94, 2.99, 2.99. The suite's
# clean fits have neighbouring local slopes within 0.2 of each other.
PRE_ASYMPTOTIC, PRE_ASYMPTOTIC_GAP = "pre-asymptotic", 0.5
# A fit more than STEEP above the declared order is a special motion the method solves better than in general
# (SUPERCONVERGENT, with three points or more) or a point contaminated by rounding (two points): the suite's fits of
# general motions lie within 0.15 of their declared orders (harness.verdicts), the special ones measured so far at
# declared + 2 (rk4_naive, declared 2, fits 4 where the angular velocity keeps its direction: the stages commute).
STEEP = 1.0
SUPERCONVERGENT = "superconvergent on this motion"


def regimes(points: pd.DataFrame) -> tuple[pd.DataFrame, float, float]:
    """(points sorted by dt from large to small with a column `regime`, floor_dt, floor_err); points: columns dt,
    steps, status, state_err."""
    points = points.sort_values("dt", ascending=False, kind="stable").reset_index(drop=True)
    err = points["state_err"].to_numpy(float)
    ran = (points["status"] == Status.OK.value).to_numpy() & np.isfinite(err)
    index = np.flatnonzero(ran & (err > 0))  # an error of exactly 0 is at round-off and has no logarithm
    dt, err_ok, steps = points["dt"].to_numpy(float)[index], err[index], points["steps"].to_numpy(float)[index]
    floor_at = None
    for i in range(len(index) - 1):
        if not (err_ok[i] <= ASYMPTOTIC_MAX and err_ok[i] <= FLOOR_MAX):
            continue
        if math.log(err_ok[i] / err_ok[i + 1]) / math.log(dt[i] / dt[i + 1]) < FLOOR_SLOPE:
            floor_at = i
            break
    floor_dt = float(dt[floor_at]) if floor_at is not None else math.nan
    floor_err = float(err_ok[floor_at:].min()) if floor_at is not None else math.nan
    # the rounding level: eps per step, or the floor where the points show it (a formulation whose charts round
    # worse than eps per step, e.g. ZXZ angles growing without bound on a regular precession)
    rounding = EPS * steps if floor_at is None else np.maximum(EPS * steps, floor_err)
    regime = np.where(ran, ROUNDOFF, FAILED).astype(object)
    near_rounding = err_ok < ROUNDOFF_MARGIN * rounding
    past_floor = np.arange(len(index)) >= (len(index) if floor_at is None else floor_at)
    if floor_at is not None:  # past the floor rounding grows with the steps: from the floor's point, in proportion
        at_floor = floor_at + int(np.argmin(err_ok[floor_at:]))
        near_rounding |= past_floor & (err_ok < ROUNDOFF_MARGIN * floor_err * steps / steps[at_floor])
    regime[index] = np.where(err_ok > ASYMPTOTIC_MAX, ABOVE,
                             np.where(near_rounding, ROUNDOFF, np.where(past_floor, IRREGULAR, ASYMPTOTIC)))
    while True:  # the coarsest asymptotic point, while its local slope disagrees with the next pair's
        at = np.flatnonzero(regime == ASYMPTOTIC)
        if len(at) < 3:
            break
        log_dt, log_err = np.log(points["dt"].to_numpy(float)[at[:3]]), np.log(err[at[:3]])
        slopes = np.diff(log_err) / np.diff(log_dt)
        if not abs(slopes[0] - slopes[1]) > PRE_ASYMPTOTIC_GAP:
            break
        regime[at[0]] = PRE_ASYMPTOTIC
    return points.assign(regime=regime), floor_dt, floor_err


def reason(marked: pd.DataFrame) -> str:
    """Where the points lie when fewer than two are asymptotic (marked: regimes()' points)."""
    ok = marked[marked["regime"] != FAILED]
    if ok.empty:
        return "no run ok" if marked.empty else "no run ok: " + ", ".join(sorted(set(marked["status"].astype(str))))

    def span(points: pd.DataFrame) -> str:
        low, high = points["dt"].min(), points["dt"].max()
        return f"dt = {low:.3g}" if low == high else f"dt = {low:.3g} to {high:.3g}"

    if (ok["regime"] == ROUNDOFF).all():
        return f"error at round-off at every ok {span(ok)} (state_err <= {ok['state_err'].max():.2g})"
    if (ok["regime"] == ABOVE).all():
        return f"state_err > {ASYMPTOTIC_MAX:g} at every ok {span(ok)}"
    parts = []
    for regime, words in ((ABOVE, f"above {ASYMPTOTIC_MAX:g}"), (PRE_ASYMPTOTIC, "pre-asymptotic (local slope off "
                                                                                 "the next pair's)"),
                          (ASYMPTOTIC, "asymptotic"), (ROUNDOFF, "at round-off"),
                          (IRREGULAR, "irregular (past the round-off floor, yet above it)"), (FAILED, "not ok")):
        chosen = marked[marked["regime"] == regime]
        if len(chosen):
            parts.append(f"{len(chosen)} {words} ({span(chosen)})")
    return ", ".join(parts)


# The kinds of reason a convergence row's note gives, by the words that start them (the report counts families by
# these): fit() and harness.dt_ladders write them.
NOTE_GROUPS = (
    (SUPERCONVERGENT, SUPERCONVERGENT),
    ("too few to tell superconvergence", "2 points steeper than declared: too few to tell superconvergence"),
    ("exact for this motion", "exact for this motion (round-off up to t_end / 20)"),
    ("round-off for every stable dt", "error at round-off for every stable dt"),
    ("error at round-off for every dt up to", "error at round-off for every dt up to a limit, not beyond it"),
    ("its error grows exponentially", "chaotic or unstable case: error above the range at every dt tried"),
    ("not falling above", "error above the range and saturated (not falling as dt halves)"),
    ("error at round-off at every", "error at round-off at every dt tried"),
    (f"state_err > {ASYMPTOTIC_MAX:g} at every", "error above the range at every dt down to the steps cap"),
    ("smallest tried", "fewer than two asymptotic points down to the steps cap"),
    ("no run ok", "no run ok"),
    ("worker failed", "worker failed"),
)


def note_group(note: str) -> str:
    """The kind of reason a note gives (NOTE_GROUPS), or the note itself."""
    for words, group in NOTE_GROUPS:
        if words in str(note):
            return group
    # "N point(s) in the asymptotic range (...): 1 above 0.03 (dt = ...), 1 at round-off (dt = ...)": the regimes
    where = re.search(r"asymptotic range \(.*?\): ([^;]*)", str(note))
    return re.sub(r" \(dt = [^)]*\)", "", where.group(1)) if where else str(note)


def fit(points: pd.DataFrame, declared: float) -> dict:
    """order, floor_dt, floor_err, points and a note from ladder points (columns dt, steps, status, state_err)."""
    marked, floor_dt, floor_err = regimes(points)
    asymptotic = marked[marked["regime"] == ASYMPTOTIC]
    n = len(asymptotic)
    notes = []
    order = math.nan
    if n >= 2:
        slope = order_slope(asymptotic["dt"], asymptotic["state_err"])
        if not slope > declared + STEEP:  # NaN declared: no claim to be steeper than
            order = slope
        elif n >= 3:
            order = slope
            notes.append(f"{SUPERCONVERGENT} (fitted {slope:.2f}, declared {declared:g})")
        else:
            notes.append(f"2 points fit {slope:.2f}, more than {STEEP:g} above the declared {declared:g}: too few to "
                         "tell superconvergence from a point at round-off")
    else:
        notes.append(f"{n} point(s) in the asymptotic range ({ROUNDOFF_MARGIN:g} x rounding <= state_err <= "
                     f"{ASYMPTOTIC_MAX:g}): {reason(marked)}")
    early = marked[marked["regime"] == PRE_ASYMPTOTIC]
    if n >= 2 and len(early):
        notes.append(f"{PRE_ASYMPTOTIC}, left out of the fit: dt = " + ", ".join(f"{dt:.3g}" for dt in early["dt"]))
    ok = marked[marked["regime"] != FAILED]
    if math.isnan(floor_dt) and len(ok):
        notes.append(f"no round-off floor down to dt = {ok['dt'].min():.3g}")
    return {"order": order, "floor_dt": floor_dt, "floor_err": floor_err, "declared_order": declared, "points": n,
            "note": "; ".join(notes)}


def with_state_err(df: pd.DataFrame) -> pd.DataFrame:
    df = df.copy()
    parts = df[["attitude_err", "omega_err", "casimir_drift"]].astype(float)
    df["state_err"] = parts.max(axis=1).where(np.isfinite(df["attitude_err"].astype(float)))
    return df


def sweep_orders(results: pd.DataFrame, skip: set[tuple]) -> list[dict]:
    """Convergence rows from the sweep's own dt lists (no extra runs), for families not in skip."""
    df = with_state_err(results[results["dt"].notna()].fillna({"formulation": ""}))
    rows = []
    for (case, engine, formulation, integrator), group in df.groupby(
            ["case", "engine", "formulation", "integrator"], sort=False):
        if (case, engine, formulation, integrator) in skip or group["dt"].nunique() < 2:
            continue
        declared = declared_order(engine, integrator)
        row = {"case": case, "engine": engine, "formulation": formulation, "integrator": integrator,
               "stable_dt_max": math.nan, "source": "dt_list", **fit(group, declared)}
        rows.append(row)
    return rows


def convergence_table(rows: list[dict]) -> pd.DataFrame:
    df = pd.DataFrame(rows, columns=list(CONVERGENCE_COLUMNS))
    return df.fillna({"formulation": "", "note": ""})


def order_checks(convergence: pd.DataFrame) -> pd.DataFrame:
    """checks.csv rows: the fitted order against the declared one (dt empty: a fit over many)."""
    records = []
    for _, row in convergence.iterrows():
        if not math.isfinite(row["order"]) or not math.isfinite(row["declared_order"]):
            continue
        records.append({"case": row["case"], "engine": row["engine"], "formulation": row["formulation"],
                        "integrator": row["integrator"], "dt": math.nan, "quantity": ORDER_QUANTITY,
                        "theory": row["declared_order"], "measured": row["order"],
                        "error": checks.error(ORDER_QUANTITY, row["declared_order"], row["order"])})
    return pd.DataFrame(records, columns=list(checks.COLUMNS))


# Two candidates tie when their costs differ by no more than the timing noise: the sum of their spreads (slowest
# minus fastest of their timed runs), and at least TIE_RTOL of the cheaper cost. The floor stands for the noise that
# repeats inside one process do not show and two runs of the sweep do (clock boost, cache and memory placement); 5% is
# the usual run-to-run scatter of a micro-benchmark on an idle machine. Checked on the timings of two consecutive
# idle default runs (2-core AMD EPYC, 2026-11-25; tests/benchmarks/ranking_stability.py), ranked by pareto_table:
# 254 of 264 cells named the same winner, the other 10 were tie-marked, none differed unmarked.
TIE_RTOL = 0.05


def pareto(results: pd.DataFrame, ladder: pd.DataFrame, failed: set | None = None,
           tolerance: pd.DataFrame | None = None) -> pd.DataFrame:
    """Per case and accuracy target, the cheapest run whose attitude_err reaches it, with ties and the runs not
    recommended (pareto_table). Candidates: every timed run of the sweep, fixed-step and adaptive (at the engine's
    default tolerance; the truth has no error of its own and is none), the dt ladders' points and the tolerance
    ladders' points (tolerance.csv, pareto_candidates)."""
    # an adaptive row whose error is exactly 0 is the reference its errors are measured against (the sliding ladder's
    # equation); the rigid bodies' truth has no error at all. Neither is a contender.
    sweep = results[results["dt"].notna() | (results["attitude_err"] != 0.0)].copy()
    sweep["us_per_sim_s"] = sweep["wall_s"] / sweep["t_end"] * 1e6
    sweep["us_per_sim_s_spread"] = sweep["us_per_step_spread"] * sweep["steps"] / sweep["t_end"]
    sweep["source"] = SOURCE_SWEEP
    ladder = ladder.copy()
    ladder["source"] = SOURCE_LADDER
    frames = [sweep, ladder] + ([pareto_candidates(tolerance)] if tolerance is not None else [])
    both = pd.concat([_candidate_columns(f) for f in frames if len(f)] or [_candidate_columns(sweep)],
                     ignore_index=True)
    return pareto_table(both, list(dict.fromkeys(results["case"])), failed or set())


_CANDIDATE_COLUMNS = ("case", "engine", "formulation", "integrator", "dt", "tolerance", "attitude_err",
                      "us_per_sim_s", "us_per_sim_s_spread", "rhs_per_sim_s", "steps", "source", "status")


def _candidate_columns(frame_: pd.DataFrame) -> pd.DataFrame:
    """A candidate frame with exactly _CANDIDATE_COLUMNS (NaN where it has none)."""
    frame_ = frame_.copy()
    for column in _CANDIDATE_COLUMNS:
        if column not in frame_:
            frame_[column] = math.nan
    return frame_[list(_CANDIDATE_COLUMNS)]


def pareto_candidates(tolerance: pd.DataFrame) -> pd.DataFrame:
    """The tolerance ladders' points (tolerance.csv) as Pareto candidates: adaptive (dt NaN), with their tolerance,
    source SOURCE_TOLERANCE."""
    points = tolerance.copy()
    points["dt"] = math.nan
    points["source"] = SOURCE_TOLERANCE
    return _candidate_columns(points)


def setting(row) -> str:
    """How a run was set: its step (dt=...), its requested tolerance (tol=...) or the engine's default tolerance."""
    dt, tol = row.get("dt", math.nan), row.get("tolerance", math.nan)
    if isinstance(dt, (int, float)) and math.isfinite(dt):
        return f"dt={dt:.3g}"
    if isinstance(tol, (int, float)) and math.isfinite(tol):
        return f"tol={tol:.0e}"
    return "default tol"


def _candidate_name(row) -> str:
    return f"{_name(row)} {setting(row)}"


def _candidate(row) -> str:
    return f"{_candidate_name(row)} ({_num(row['us_per_sim_s'], '.3g')} µs/s)"


def is_failed(failed_set: set[tuple[str, str, str]], engine: str, formulation: str, integrator: str) -> bool:
    """Whether a run's integrator failed a verdict (harness.verdicts.failed_integrators; "*" matches any engine and
    formulation)."""
    return (engine, formulation, integrator) in failed_set or ("*", "*", integrator) in failed_set


def pareto_table(runs: pd.DataFrame, cases: list[str], failed: set = frozenset()) -> pd.DataFrame:
    """The Pareto table from candidate runs (columns case, engine, formulation, integrator, dt, attitude_err,
    us_per_sim_s, us_per_sim_s_spread, rhs_per_sim_s, steps, source, status; optionally tolerance), fixed-step (dt)
    and adaptive (dt NaN) alike: an adaptive run competes on its cost like any other.

    Per case and target: among the ok runs reaching the target whose integrator passed its verdicts (failed: a set of
    (engine, formulation, integrator), harness.verdicts.failed_integrators), the cheapest; every run within the timing
    noise of it (TIE_RTOL, the spreads) is a tie, listed in `ties`, and the winner among the tied is the one with the
    fewest right-hand-side evaluations per simulated second (a cost noise cannot touch), then the cheapest; where a
    tied run has no count (rhs_per_sim_s NaN: heyoka's taylor), the cheapest. Runs that noise alone tells apart (the
    same evaluations and the same attitude_err, e.g. two names of one computation) are taken in name order, so that
    two runs of the sweep name the same one.
    `not_recommended` names the cheaper runs left out because their integrator failed a verdict."""
    runs = runs.fillna({"formulation": ""})
    runs = runs[(runs["status"] == Status.OK.value) & np.isfinite(runs["attitude_err"].astype(float))
                & np.isfinite(runs["us_per_sim_s"].astype(float))]
    bad = np.array([is_failed(set(failed), r.engine, r.formulation, r.integrator) for r in runs.itertuples()],
                   dtype=bool)
    records = []
    for case in cases:
        in_case = (runs["case"] == case).to_numpy()
        for target in ACCURACY_TARGETS:
            reach = in_case & (runs["attitude_err"] <= target).to_numpy()
            good, excluded = runs[reach & ~bad], runs[reach & bad]
            if good.empty:
                records.append({"case": case, "target": target, "engine": "", "formulation": "", "integrator": "",
                                "source": "none reached it" if excluded.empty else "only runs that failed a verdict",
                                "ties": "", "not_recommended": "; ".join(_candidate(r) for _, r in
                                                                          excluded.nsmallest(3, "us_per_sim_s")
                                                                          .iterrows())})
                continue
            cheapest = good.loc[good["us_per_sim_s"].idxmin()]
            noise = np.maximum(good["us_per_sim_s_spread"].fillna(0.0).to_numpy(float)
                               + (0.0 if not math.isfinite(cheapest["us_per_sim_s_spread"])
                                  else cheapest["us_per_sim_s_spread"]),
                               TIE_RTOL * cheapest["us_per_sim_s"])
            tied = good[(good["us_per_sim_s"].to_numpy(float) - cheapest["us_per_sim_s"]) <= noise]
            rhs = tied["rhs_per_sim_s"].astype(float)
            # the evaluations decide a tie only where every tied run counts them (heyoka's taylor does not: a
            # Taylor step has no stages), else the best time does
            rhs = rhs if rhs.notna().all() else pd.Series(0.0, index=tied.index)
            best = tied.loc[tied.assign(_rhs=rhs).sort_values(["_rhs", "us_per_sim_s"], kind="stable").index[0]]
            # Two idle default runs named different winners in 11 of 264 cells only because MuJoCo's euler and
            # implicitfast (bit-identical on a ball joint) swapped places by a few per cent of time.
            twins = tied[(rhs == rhs[best.name]) & (tied["attitude_err"] == best["attitude_err"])]
            best = twins.loc[min(twins.index, key=lambda i: _candidate_name(twins.loc[i]))]
            cheaper_bad = excluded[excluded["us_per_sim_s"] < best["us_per_sim_s"]]
            records.append({"case": case, "target": target, **{c: best.get(c, math.nan) for c in _CELL_COLUMNS},
                            "ties": "; ".join(_candidate(r) for i, r in tied.iterrows() if i != best.name),
                            "not_recommended": "; ".join(_candidate(r) for _, r in
                                                         cheaper_bad.nsmallest(3, "us_per_sim_s").iterrows())})
    return pd.DataFrame(records, columns=list(PARETO_COLUMNS))


def _name(row) -> str:
    return " ".join(str(x) for x in (row["engine"], row["formulation"], row["integrator"]) if isinstance(x, str) and x)


# ------------------------------------------------------------------------------------------------ tolerance ladders

TOLERANCE_FIT_COLUMNS = ("case", "engine", "formulation", "integrator", "slope", "points", "tol_min", "tol_max",
                         "below_tol", "max_err_over_tol", "note")


def tolerance_fit(points: pd.DataFrame) -> dict:
    """The tolerance proportionality of one adaptive method's ladder (columns tolerance, steps, status, state_err):
    slope: least-squares slope of log state_err against log tolerance (order_slope) over the points above round-off
    (ROUNDOFF_MARGIN eps steps <= state_err <= ASYMPTOTIC_MAX, as the dt ladders' asymptotic range), at least two;
    1 is an error proportional to the tolerance. points, tol_min, tol_max: the points fitted and their range.
    below_tol: how many of them reached state_err <= tolerance; max_err_over_tol: the largest state_err / tolerance
    among them (above 1: the global error exceeded the per-step tolerance requested)."""
    ok = points[(points["status"] == Status.OK.value) & np.isfinite(points["state_err"].astype(float))
                & (points["state_err"].astype(float) > 0)]
    tol, err = ok["tolerance"].to_numpy(float), ok["state_err"].to_numpy(float)
    steps = ok["steps"].to_numpy(float)
    fitted = (err <= ASYMPTOTIC_MAX) & (err >= ROUNDOFF_MARGIN * EPS * steps)
    n = int(fitted.sum())
    notes = []
    if n < len(points):
        not_ok = int((points["status"] != Status.OK.value).sum())
        outside = len(ok) - n
        notes += [f"{not_ok} point(s) not ok"] if not_ok else []
        notes += [f"{outside} point(s) outside {ROUNDOFF_MARGIN:g} eps steps <= state_err <= {ASYMPTOTIC_MAX:g}"] \
            if outside else []
    slope = order_slope(tol[fitted], err[fitted]) if n >= 2 else math.nan
    if n < 2:
        notes.append(f"{n} point(s) to fit")
    ratio = err[fitted] / tol[fitted]
    return {"slope": slope, "points": n, "tol_min": float(tol[fitted].min()) if n else math.nan,
            "tol_max": float(tol[fitted].max()) if n else math.nan, "below_tol": int((ratio <= 1.0).sum()),
            "max_err_over_tol": float(ratio.max()) if n else math.nan, "note": "; ".join(notes)}


def tolerance_fits(points: pd.DataFrame) -> pd.DataFrame:
    """tolerance_fit of every family (case, engine, formulation, integrator) of tolerance.csv's points: the rows of
    tolerance_fit.csv."""
    rows = []
    if len(points):
        for key, group in points.fillna({"formulation": ""}).groupby(["case", "engine", "formulation", "integrator"],
                                                                     sort=False):
            rows.append({**dict(zip(("case", "engine", "formulation", "integrator"), key)), **tolerance_fit(group)})
    return pd.DataFrame(rows, columns=list(TOLERANCE_FIT_COLUMNS)).fillna({"formulation": "", "note": ""})
