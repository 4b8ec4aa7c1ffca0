"""Work–precision fitting: the one order fitter (order_slope), the round-off floor and the order of a ladder's points
(fit), the orders of a sweep's own dt lists and the tolerance proportionality of a tolerance ladder (tolerance_fit).
The Pareto table is harness.analysis.pareto.

- the round-off floor: walking from large to small dt among the points below ASYMPTOTIC_MAX, the first point after
  which the error falls with a local slope below FLOOR_SLOPE while it is below FLOOR_MAX (a stall higher up is not
  round-off); floor_dt is that point's dt, floor_err the smallest error from there on;
- each point's regime (regimes): failed (not ok), above (state_err > ASYMPTOTIC_MAX), round-off (below
  ROUNDOFF_MARGIN times the rounding level: eps steps, or the measured floor_err where one is found), irregular (at or
  after the floor but above that: an error that does not fall steadily with dt) or asymptotic;
- the judged range (judged_start): the points in the band (above round-off, at most ASYMPTOTIC_MAX) have local slopes
  between neighbouring dt; from the fine end, the longest run of points whose local slopes agree (spread <= AGREE) is
  asymptotic, the band's coarser points pre-asymptotic. Settled: three points or more. A range of two whose finest
  slope moves toward the declared order is NOT_YET (its note says so: the verdict never fails it for that);
- the order: least-squares slope of log state_err against log dt over the judged range; at least two points, and a fit
  of two only when its slope is not more than STEEP above the declared order (two points cannot tell superconvergence
  from a point at round-off); a fit of three or more that far above is kept with the note SUPERCONVERGENT; the note
  shows the evidence (evidence: the band's local slopes and the dt range judged);
- without an order the note says why: how many points are asymptotic and where the others lie (reason).
"""
from __future__ import annotations

import math
import re

import numpy as np
import pandas as pd

from ..scenes import checks
from ..scenes.metrics import state_err
from ..engines import EngineError, get_engine
from ..engines.declared import formulation_order
from ..precision import EPS as PRECISION_EPS, FLOAT64
from ..tables import with_precision
from ..trajectory import Status
# The Pareto table has its own module; its names stay importable from here.
from .pareto import (ACCURACY_TARGETS, PARETO_COLUMNS, SOURCE_LADDER, SOURCE_SWEEP,  # noqa: F401
                     SOURCE_TOLERANCE, TIE_RTOL, is_failed, pareto, pareto_candidates, pareto_table,
                     run_name as _name, setting)

CONVERGENCE_FILE = "convergence.csv"  # the fitted orders of a run folder (DESIGN §4)

CONVERGENCE_COLUMNS = ("case", "engine", "formulation", "integrator", "precision", "order", "floor_dt", "floor_err",
                       "stable_dt_max", "declared_order", "points", "source", "note")
ORDER_QUANTITY = "convergence_order"

# A state error above this (rad, or relative for ω) is pre-asymptotic: higher-order terms and the saturation of the
# attitude angle at π bend the curve (measured on the suite: RK4 at 5e-2 rad gives a slope of 3.6, Euler at 0.3 of 1.2).
ASYMPTOTIC_MAX = 3e-2
# Below ROUNDOFF_MARGIN × eps × steps the error is contaminated by rounding, which accumulates at most ~ eps per step
# (measured floors of the suite: 2e-14 to 5e-12 rad after 2e3 to 2e4 steps): a 30x margin keeps its share of a
# 2-point slope below 0.03.
ROUNDOFF_MARGIN = 30.0
EPS = float(np.finfo(float).eps)
# A run family: the runs that differ only in dt (a dt ladder) or in the requested tolerance. Precision is part of
# it: float32 and float64 runs of one integrator are two families, fitted apart, each with its own eps.
FAMILY = ("case", "engine", "formulation", "integrator", "precision")
FLOOR_SLOPE = 0.5            # a local slope below this: the error has stopped falling
FLOOR_MAX = 1e-6             # a stall above this is not round-off (pre-asymptotic wiggles, resonances)


def order_slope(dt, err) -> float:
    """The convergence order of errors err at steps dt: the least-squares slope of log err against log dt (the
    error is the dependent variable: err ~ C dt^p). The one order fitter of the harness (convergence.csv,
    harness.testing)."""
    return float(np.polyfit(np.log(np.asarray(dt, dtype=float)), np.log(np.asarray(err, dtype=float)), 1)[0])


def declared_order(engine: str, integrator: str, formulation: str = "") -> float:
    """The order the engine declares for an integrator on a model (engines.declared.formulation_order, by default
    engines.declared.declared_order); NaN for an engine not registered."""
    try:
        return formulation_order(get_engine(engine), formulation, integrator)
    except (KeyError, EngineError):
        return math.nan


FAILED, ABOVE, ROUNDOFF, ASYMPTOTIC = "failed", "above", "round-off", "asymptotic"
IRREGULAR = "irregular"  # at or after the floor, yet well above it: the error does not fall steadily with dt
# The judged range (judged_start): from the fine end, the longest run of points whose local slopes between
# neighbouring dt agree, their spread (max - min) at most AGREE; the band's coarser points are PRE_ASYMPTOTIC, left out
# of the fit. Measured: the suite's settled ranges (reports/default, dt lists and ladders, 88 families of 3 points or
# more) have neighbouring slopes within 0.07 (median 0.004); the drift the rule must cut off is 0.17 and more a pair
# (heavy-asymmetric rk4 4.33 4.16 4.10 ...; issue 45's user top, MuJoCo rk4 halving from 0.0372: 4.48 4.33 4.19 4.11,
# judged 4.19 4.11 -> 4.15, where one line through all fitted 4.27); random bodies (tests/test_verdict_properties.py):
# halving ladders of correct methods settle within 0.15 with the spread of a range's fit off its limit < 0.1.
PRE_ASYMPTOTIC, AGREE = "pre-asymptotic", 0.15
# A range of only two points (its finest slope disagrees with the next) whose finest slope is closer to the declared
# order than the one before: the slopes still drift toward it (issue 45: 3.67 3.31 3.75 3.89 3.94 on a 32x ladder
# stopped short of the range). The note names it; analysis.verdicts never fails a case for it (within
# ORDER_CASE_TOLERANCE), and --strict measures finer first.
NOT_YET = "not yet asymptotic"
# A fit more than STEEP above the declared order is a special motion the method solves better than in general
# (SUPERCONVERGENT, with three points or more) or a point contaminated by rounding (two points): the suite's fits of
# general motions lie within 0.15 of their declared orders (analysis.verdicts), the special ones measured so far at
# declared + 2 (rk4_naive, declared 2, fits 4 where the angular velocity keeps its direction: the stages commute).
STEEP = 1.0
SUPERCONVERGENT = "superconvergent on this motion"
# The evidence an order verdict needs (analysis.verdicts): MIN_POINTS asymptotic points on one non-chaotic case, or
# MIN_CASES cases with a fitted order. Less may be a pre-asymptotic pair: a user's body run at `advise`'s dt for 1e-6
# and 2.5 times it fitted MuJoCo's rk4 3.40 on one case, which the suite measures at 3.99-4.08 on 14 cases. A fit
# more than a whole order off still fails on any evidence (Heun declared 4 fits 2.0 on two points).
MIN_POINTS, MIN_CASES = 3, 3
# The note of a float32 family whose round-off leaves no asymptotic range: a named reason, not a failure.
NOT_MEASURABLE = "not measurable in"
# A short ladder's point that did not run ok (a run budget) where the others are at round-off: its words in the note.
NO_EVIDENCE = "no error, no evidence either way"
# The note of an order measured over the case's first part only (pipeline.dt_ladders.run_first_part): the verdict
# quotes it, so a reader sees over what span the order was measured.
FIRST_PART = "order measured over the first"


def local_slopes(dt, err) -> np.ndarray:
    """The slopes of log err against log dt between neighbouring points (dt from large to small, distinct)."""
    return np.diff(np.log(np.asarray(err, dtype=float))) / np.diff(np.log(np.asarray(dt, dtype=float)))


def judged_start(slopes) -> int:
    """The index of the judged range's coarsest point among the points whose local slopes these are (coarse to fine):
    from the finest slope back, while every slope of the run is within AGREE of every other."""
    start = len(slopes) - 1
    low = high = slopes[-1]
    while start > 0 and max(high, slopes[start - 1]) - min(low, slopes[start - 1]) <= AGREE:
        start -= 1
        low, high = min(low, slopes[start]), max(high, slopes[start])
    return start


def _one_a_dt(dts: np.ndarray, index: np.ndarray) -> np.ndarray:
    """index (into dts, sorted from large to small) with one point a dt: two points of one dt (a ladder's and the
    sweep's) have no slope between them."""
    return index[np.sort(np.unique(dts[index], return_index=True)[1])]


def regimes(points: pd.DataFrame, eps: float = EPS) -> tuple[pd.DataFrame, float, float]:
    """(points sorted by dt from large to small with a column `regime`, floor_dt, floor_err); points: columns dt,
    steps, status, state_err; eps: the unit round-off of the runs' precision (float64's by default)."""
    points = points.sort_values("dt", ascending=False, kind="stable").reset_index(drop=True)
    err = points["state_err"].to_numpy(float)
    ran = (points["status"] == Status.OK.value).to_numpy() & np.isfinite(err)
    index = np.flatnonzero(ran & (err > 0))  # an error of exactly 0 is at round-off and has no logarithm
    dt, err_ok, steps = points["dt"].to_numpy(float)[index], err[index], points["steps"].to_numpy(float)[index]
    floor_at = None
    for i in range(len(index) - 1):
        if not (err_ok[i] <= ASYMPTOTIC_MAX and err_ok[i] <= FLOOR_MAX) or dt[i] == dt[i + 1]:
            continue  # two points of one dt (a ladder's and the sweep's) have no slope between them
        if math.log(err_ok[i] / err_ok[i + 1]) / math.log(dt[i] / dt[i + 1]) < FLOOR_SLOPE:
            floor_at = i
            break
    floor_dt = float(dt[floor_at]) if floor_at is not None else math.nan
    floor_err = float(err_ok[floor_at:].min()) if floor_at is not None else math.nan
    # the rounding level: eps per step, or the floor where the points show it (a formulation whose charts round
    # worse than eps per step, e.g. ZXZ angles growing without bound on a regular precession)
    rounding = eps * steps if floor_at is None else np.maximum(eps * steps, floor_err)
    regime = np.where(ran, ROUNDOFF, FAILED).astype(object)
    near_rounding = err_ok < ROUNDOFF_MARGIN * rounding
    past_floor = np.arange(len(index)) >= (len(index) if floor_at is None else floor_at)
    if floor_at is not None:  # past the floor rounding grows with the steps: from the floor's point, in proportion
        at_floor = floor_at + int(np.argmin(err_ok[floor_at:]))
        near_rounding |= past_floor & (err_ok < ROUNDOFF_MARGIN * floor_err * steps / steps[at_floor])
    regime[index] = np.where(err_ok > ASYMPTOTIC_MAX, ABOVE,
                             np.where(near_rounding, ROUNDOFF, np.where(past_floor, IRREGULAR, ASYMPTOTIC)))
    at = _one_a_dt(points["dt"].to_numpy(float), np.flatnonzero(regime == ASYMPTOTIC))
    if len(at) >= 3:  # the band's points coarser than the judged range are pre-asymptotic
        dts = points["dt"].to_numpy(float)
        start = judged_start(local_slopes(dts[at], err[at]))
        regime[(regime == ASYMPTOTIC) & (dts > dts[at[start]])] = PRE_ASYMPTOTIC
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
# these): fit() and harness.pipeline.dt_ladders write them.
NOTE_GROUPS = (
    (FIRST_PART, "order measured over the case's first part (the whole span's error above the range at the cap)"),
    (SUPERCONVERGENT, SUPERCONVERGENT),
    (NOT_MEASURABLE, "not measurable in float32: its round-off closes the asymptotic range"),
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


def fit(points: pd.DataFrame, declared: float, precision: str = FLOAT64) -> dict:
    """order, floor_dt, floor_err, points and a note from ladder points (columns dt, steps, status, state_err) of one
    precision: the round-off margin is that precision's eps per step."""
    marked, floor_dt, floor_err = regimes(points, PRECISION_EPS[precision])
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
    elif precision != FLOAT64 and (marked["regime"] == ROUNDOFF).any():
        # eps of float32 is 5e8 times float64's: 30 eps per step reaches the range's top after ~8000 steps
        ok = marked[marked["regime"] != FAILED]
        notes.append(f"{NOT_MEASURABLE} {precision}: its round-off ({ROUNDOFF_MARGIN:g} x {precision} eps x steps = "
                     f"{ROUNDOFF_MARGIN * PRECISION_EPS[precision] * ok['steps'].min():.2g} at the coarsest ok dt) "
                     f"closes the asymptotic range (<= {ASYMPTOTIC_MAX:g}): {reason(marked)}")
    else:
        notes.append(f"{n} point(s) in the asymptotic range ({ROUNDOFF_MARGIN:g} x rounding <= state_err <= "
                     f"{ASYMPTOTIC_MAX:g}): {reason(marked)}")
    early = marked[marked["regime"] == PRE_ASYMPTOTIC]
    if n >= 2 and len(early):
        notes.append(f"{PRE_ASYMPTOTIC}, left out of the fit: dt = " + ", ".join(f"{dt:.3g}" for dt in early["dt"]))
    notes += evidence(marked, declared, order)
    ok = marked[marked["regime"] != FAILED]
    if math.isnan(floor_dt) and len(ok):
        notes.append(f"no round-off floor down to dt = {ok['dt'].min():.3g}")
    return {"order": order, "floor_dt": floor_dt, "floor_err": floor_err, "declared_order": declared, "points": n,
            "note": "; ".join(notes)}


def evidence(marked: pd.DataFrame, declared: float, order: float) -> list[str]:
    """The note's evidence of a fit (marked: regimes()' points): NOT_YET where it applies, then the band's local slopes
    coarse to fine and the dt range judged, e.g. "slopes 4.48 4.33 4.19 4.11; judged on dt 0.0093 to 0.00233: 4.15"."""
    band = marked[marked["regime"].isin((ASYMPTOTIC, PRE_ASYMPTOTIC))]
    band = band.iloc[_one_a_dt(band["dt"].to_numpy(float), np.arange(len(band)))]
    judged = band[band["regime"] == ASYMPTOTIC]
    if len(judged) < 2:
        return []
    slopes = local_slopes(band["dt"], band["state_err"])
    out = []
    if len(judged) == 2 and len(band) >= 3 and abs(slopes[-1] - declared) < abs(slopes[-2] - declared):
        out.append(f"{NOT_YET}: the local slopes still move toward the declared {declared:g} at the finest dt")
    fitted = f": {order:.2f}" if math.isfinite(order) else ""
    out.append("slopes " + " ".join(f"{x:.2f}" for x in slopes)
               + f"; judged on dt {judged['dt'].max():.3g} to {judged['dt'].min():.3g}{fitted}")
    return out


def with_state_err(df: pd.DataFrame) -> pd.DataFrame:
    """A copy of the table with its state_err column (harness.scenes.metrics.state_err, the rule's one home)."""
    df = df.copy()
    df["state_err"] = state_err(df)
    return df


def sweep_orders(results: pd.DataFrame, skip: set[tuple]) -> list[dict]:
    """Convergence rows from the sweep's own dt lists (no extra runs), for families (FAMILY tuples) not in skip."""
    df = with_state_err(with_precision(results[results["dt"].notna()]).fillna({"formulation": ""}))
    rows = []
    for key, group in df.groupby(list(FAMILY), sort=False):
        if key in skip or group["dt"].nunique() < 2:
            continue
        family = dict(zip(FAMILY, key))
        declared = declared_order(family["engine"], family["integrator"], family["formulation"])
        rows.append({**family, "stable_dt_max": math.nan, "source": "dt_list",
                     **fit(group, declared, family["precision"])})
    return rows


def convergence_table(rows: list[dict]) -> pd.DataFrame:
    df = pd.DataFrame(rows, columns=list(CONVERGENCE_COLUMNS))
    return df.fillna({"formulation": "", "note": "", "precision": FLOAT64})


def order_checks(convergence: pd.DataFrame) -> pd.DataFrame:
    """checks.csv rows: the fitted order against the declared one (dt empty: a fit over many)."""
    records = []
    for _, row in convergence.iterrows():
        if not math.isfinite(row["order"]) or not math.isfinite(row["declared_order"]):
            continue
        records.append({"case": row["case"], "engine": row["engine"], "formulation": row["formulation"],
                        "integrator": row["integrator"], "precision": row.get("precision", FLOAT64), "dt": math.nan, "quantity": ORDER_QUANTITY,
                        "theory": row["declared_order"], "measured": row["order"],
                        "error": checks.error(ORDER_QUANTITY, row["declared_order"], row["order"])})
    return pd.DataFrame(records, columns=list(checks.COLUMNS))


# ------------------------------------------------------------------------------------------------ tolerance ladders

TOLERANCE_FIT_COLUMNS = ("case", "engine", "formulation", "integrator", "precision", "slope", "points", "tol_min", "tol_max",
                         "below_tol", "max_err_over_tol", "note")


def tolerance_fit(points: pd.DataFrame, precision: str = FLOAT64) -> dict:
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
    fitted = (err <= ASYMPTOTIC_MAX) & (err >= ROUNDOFF_MARGIN * PRECISION_EPS[precision] * steps)
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
    """tolerance_fit of every family (FAMILY) of tolerance.csv's points: the rows of tolerance_fit.csv."""
    rows = []
    if len(points):
        for key, group in with_precision(points).fillna({"formulation": ""}).groupby(list(FAMILY), sort=False):
            family = dict(zip(FAMILY, key))
            rows.append({**family, **tolerance_fit(group, family["precision"])})
    return pd.DataFrame(rows, columns=list(TOLERANCE_FIT_COLUMNS)).fillna({"formulation": "", "note": "",
                                                                             "precision": FLOAT64})
