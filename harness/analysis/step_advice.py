"""Step-size advice, the arithmetic (advice.csv; issue 21 item 2): the error model C·s^p of a run family on its
asymptotic range (s the step dt, or the requested tolerance of an adaptive method), and the checked search for the
largest setting whose max attitude error reaches a target.

The search is given a function that runs the family at a setting and returns the error (harness.pipeline.advice runs
it, and the advised runs' timing; which families are advised, and on which known points, is advice_tasks and
families_to_advise below):
it starts just inside the model's estimate, steps once by CHECK_RATIO to the other side, then doubles or halves until
a setting that reaches the target and one that does not are known, and bisects (geometrically) until they are within
CHECK_RATIO. The setting advised is the one that reaches it, with its measured error. A target the family cannot
reach in [lo, hi] is said so instead: beyond the step cap (the model needs a setting below lo, and lo does not reach
it), or below the method's floor (the error stops falling before it reaches the target: round-off, or the engine's
precision).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np
import pandas as pd

from . import fitting
from .fitting import FAMILY, with_state_err
from .ladders import TOLERANCES
from ..engines import get_engine
from ..engines.declared import declared_order, formulations, in_default_sweep, rigid_body
from ..precision import FLOAT64
from ..run.results import SINGLE, with_precision
from ..run.spec import Family
from ..trajectory import Status

CHECK_RATIO = 1.25        # the advised setting reaches the target, CHECK_RATIO times it (checked) does not
MAX_CHECK_RUNS = 10       # runs per target at most (a good model needs 2; a bracket from scratch ~6)
FLOOR_SLOPE = fitting.FLOOR_SLOPE   # walking finer, an error falling slower than this has hit its floor

# advice.csv: the setting is dt (fixed-step) or tolerance (adaptive), the other empty. fails_at / error_fails: the
# checked setting CHECK_RATIO above (or less) that does not reach the target; estimate: the model's setting.
ADVICE_COLUMNS = ("case", "engine", "formulation", "integrator", "precision", "target", "dt", "tolerance", "error_checked",
                  "us_per_sim_s", "fails_at", "error_fails", "estimate", "order", "runs", "note")


@dataclass(frozen=True)
class ErrorModel:
    """error ≈ coefficient · setting^order (error: max attitude error, rad; setting: dt in s, or a tolerance), fitted
    on `points` points of the asymptotic range."""

    coefficient: float
    order: float
    points: int

    def setting_for(self, target: float) -> float:
        """The setting whose modelled error is the target."""
        return (target / self.coefficient) ** (1.0 / self.order)


def error_model(points: pd.DataFrame, order: float, setting: str = "dt") -> ErrorModel | None:
    """The model of a family's max attitude error with the fitted order (convergence.csv's, or a tolerance ladder's
    slope): C from the points in the asymptotic range (harness.analysis.fitting.regimes on state_err; points: columns
    `setting`, steps, status, state_err, attitude_err), the geometric mean of attitude_err / setting^order. None
    without an order or such a point."""
    if not (math.isfinite(order) and order > 0) or points.empty:
        return None
    frame = points.rename(columns={setting: "dt"}) if setting != "dt" else points
    marked = fitting.regimes(frame)[0]
    chosen = marked[(marked["regime"] == fitting.ASYMPTOTIC)]
    err = chosen["attitude_err"].to_numpy(float)
    at = chosen["dt"].to_numpy(float)
    keep = np.isfinite(err) & (err > 0)
    if not keep.any():
        return None
    log_c = float(np.mean(np.log(err[keep]) - order * np.log(at[keep])))
    return ErrorModel(math.exp(log_c), float(order), int(keep.sum()))


@dataclass(frozen=True)
class Advice:
    """The outcome of one search. setting: the largest setting checked to reach the target (NaN when none did);
    error: its max attitude error; fails_at, error_fails: the smallest larger setting checked not to reach it (NaN
    when none: the target is reached up to hi); runs: runs made for this target; note: what the reader must know
    (empty for a bracket within CHECK_RATIO)."""

    setting: float
    error: float
    fails_at: float
    error_fails: float
    runs: int
    note: str


def rounded(setting: float) -> float:
    """A setting as printed and run: 4 significant digits, so that `dt = VALUE` reproduces it exactly."""
    return float(f"{setting:.4g}")


def search(error_at: Callable[[float], float], target: float, estimate: float, lo: float, hi: float,
           known: dict[float, float] | None = None, what: str = "dt", cap: str = "",
           ratio: float = CHECK_RATIO, max_runs: int = MAX_CHECK_RUNS) -> Advice:
    """The largest setting in [lo, hi] whose error (error_at(setting): max attitude error, NaN for a run that is not
    ok) reaches target, checked within ratio (module docstring). estimate: the model's setting (NaN: none). known:
    settings already run -> their errors (shared by the targets of one family: filled in place). cap: words naming
    lo (e.g. "t_end / 40000")."""
    known = {} if known is None else known
    runs = 0
    clip = lambda s: min(max(s, lo), hi)  # noqa: E731

    def reaches(error: float) -> bool:
        return math.isfinite(error) and error <= target

    def bracket() -> tuple[float | None, float | None]:
        inside = {s: e for s, e in known.items() if lo * (1 - 1e-9) <= s <= hi * (1 + 1e-9)}
        good = [s for s, e in inside.items() if reaches(e)]
        best = max(good) if good else None
        bad = [s for s, e in inside.items() if not reaches(e) and (best is None or s > best)]
        return best, (min(bad) if bad else None)

    def run(setting: float) -> bool:
        """Run a setting not yet known (rounded, clipped); False when it is known already."""
        nonlocal runs
        setting = rounded(clip(setting))
        if setting in known:
            return False
        known[setting] = error_at(setting)
        runs += 1
        return True

    modelled = math.isfinite(estimate) and estimate > 0
    if modelled and estimate < lo:  # the model needs a step below the cap: the cap is checked, nothing finer
        run(lo)
        if bracket()[0] is None:
            error = known[rounded(lo)]
            return Advice(math.nan, math.nan, rounded(lo), error, runs,
                          f"{_beyond(what)}: the model needs {what} = {estimate:.3g}, below {lo:.4g}"
                          + (f" ({cap})" if cap else "") + f", where the error is {error:.3g}")
    # first just inside the estimate, then one CHECK_RATIO step across it: a good model is checked in two runs
    first = rounded(clip(estimate / math.sqrt(ratio))) if modelled else math.nan
    step = ratio
    while runs < max_runs:
        best, fail = bracket()
        if best is not None and fail is not None and fail <= best * ratio * (1 + 1e-9):
            return Advice(best, known[best], fail, known[fail], runs, "")
        low, high = best or 0.0, fail or math.inf
        if modelled and first not in known and low < first < high:
            probe = first
        elif best is None and fail is None:  # nothing known and no model: start at the top
            probe = hi
        elif best is None:  # nothing reaches yet: finer
            if _stalled(known, fail):
                return _floor(known, what, runs)
            if fail <= lo * (1 + 1e-9):
                return _not_reached(known, lo, what, cap, runs, estimate)
            probe = fail / step
        elif fail is None:  # everything checked reaches: coarser
            if best >= hi * (1 - 1e-9):
                return Advice(best, known[best], math.nan, math.nan, runs,
                              f"reached at the largest {what} tried ({hi:.4g})")
            probe = best * step
        elif step == ratio and best == first and best * ratio < fail:
            probe = best * ratio
        elif step == ratio and fail == first and fail / ratio > best:
            probe = fail / ratio
        else:
            probe = math.sqrt(best * fail)
        if not run(probe):
            break
        if probe != first:
            step = 2.0
    best, fail = bracket()
    if best is None:
        return _not_reached(known, lo, what, cap, runs, estimate)
    return Advice(best, known[best], math.nan if fail is None else fail,
                  math.nan if fail is None else known[fail], runs,
                  f"search stopped after {runs} runs" + (f": the next {what} not reaching it is {fail / best:.3g}x"
                                                         if fail is not None else ""))


def _beyond(what: str) -> str:
    """The words of a target the smallest setting allowed does not reach."""
    return "beyond the step cap" if what == "dt" else f"beyond the tightest {what}"


def _stalled(known: dict[float, float], fail: float) -> bool:
    """Whether the error at `fail` and the next coarser setting tried shows a floor: both ok, in the asymptotic range
    or below (<= analysis.fitting.ASYMPTOTIC_MAX) and falling with a local slope below FLOOR_SLOPE. Not fitting's
    FLOOR_MAX (1e-6): a float32 engine's floor lies near 1e-5 rad; a saturated error (a chaotic separation, ~pi) lies
    above the range and is no floor."""
    coarser = sorted(s for s in known if s > fail and math.isfinite(known[s]))
    if not coarser or not math.isfinite(known[fail]):
        return False
    above = coarser[0]
    e0, e1 = known[above], known[fail]
    if not (e0 <= fitting.ASYMPTOTIC_MAX and e0 > 0 and e1 > 0):
        return False
    return math.log(e0 / e1) / math.log(above / fail) < FLOOR_SLOPE


def _floor(known: dict[float, float], what: str, runs: int) -> Advice:
    finite = {s: e for s, e in known.items() if math.isfinite(e)}
    at = min(finite, key=finite.get)
    return Advice(math.nan, math.nan, at, finite[at], runs,
                  f"below the method's floor: the error stops falling at {finite[at]:.3g} ({what} = {at:.4g}; "
                  "round-off or the engine's precision)")


def _not_reached(known: dict[float, float], lo: float, what: str, cap: str, runs: int, estimate: float) -> Advice:
    at = rounded(lo) if rounded(lo) in known else min(known)
    error = known[at]
    why = "not ok" if not math.isfinite(error) else f"error {error:.3g}"
    return Advice(math.nan, math.nan, at, error, runs,
                  f"{_beyond(what)}: not reached down to {what} = {at:.4g}" + (f" ({cap})" if cap else "")
                  + f", {why}" + (f"; the model needs {what} = {estimate:.3g}" if math.isfinite(estimate) else ""))


# ------------------------------------------------------------------------------------------------ what is advised

# The tolerances an advice may name: the tolerance ladders' range (harness.analysis.ladders.TOLERANCES).
TOLERANCE_LO, TOLERANCE_HI = min(TOLERANCES), max(TOLERANCES)


def advised_error(row: dict) -> float:
    """The error an advice is checked on: a run's attitude_err, NaN unless it ran ok."""
    err = row.get("attitude_err", math.nan)
    return float(err) if row.get("status") == Status.OK.value and err is not None and math.isfinite(err) \
        else math.nan


def advice_row(family: Family, target: float, what: str, setting: float = math.nan, **columns) -> dict:
    """One advice.csv row (ADVICE_COLUMNS) of a family at a target; what: its setting's column, "dt" or "tolerance"."""
    row = {c: math.nan for c in ADVICE_COLUMNS} | {
        "case": family.case.name, "engine": family.engine, "formulation": family.formulation,
        "integrator": family.integrator, "precision": family.precision, "target": target, "note": ""}
    row[what] = setting
    row["error_checked"] = columns.pop("error", math.nan)
    row.update(columns)
    return row


def family_key(point: dict) -> tuple:
    """The family key (Family.key: case, engine, formulation, integrator, precision) of a point or row."""
    return (point["case"], point["engine"], point["formulation"], point["integrator"],
            point.get("precision") or FLOAT64)


def advice_tasks(fixed: list[Family], adaptive: list[Family], results: pd.DataFrame, ladder: pd.DataFrame,
                 tolerance: pd.DataFrame, convergence: pd.DataFrame,
                 tolerance_fit: pd.DataFrame) -> list[tuple[Family, bool, list[dict], float]]:
    """run_advice's tasks after a sweep: each fixed-step family with a fitted order (convergence.csv), its points
    the sweep's runs and its ladder points (ladder.csv); each adaptive family with a fitted slope (tolerance_fit.csv),
    its points the tolerance ladder's (tolerance.csv)."""
    keys = list(FAMILY)
    results, ladder, tolerance, convergence, tolerance_fit = (
        with_precision(t) if len(t) else t for t in (results, ladder, tolerance, convergence, tolerance_fit))
    sweep = results[results["dt"].notna()].fillna({"formulation": ""})
    if len(sweep):
        sweep = with_state_err(sweep)
        sweep["us_per_sim_s"] = sweep["wall_s"] / sweep["t_end"] * 1e6
        if "timing" in sweep:  # a run timed once (analysis.decisive): an advised one is timed with repeats here
            sweep.loc[sweep["timing"] == SINGLE, "us_per_sim_s"] = math.nan
    ladder, tolerance = (_repeated_times(t) for t in (ladder, tolerance))
    columns = ["dt", "steps", "status", "state_err", "attitude_err", "us_per_sim_s"]
    by_family: dict[tuple, list[dict]] = {}
    for frame_ in (sweep, ladder):
        if len(frame_):
            for key, group in frame_.fillna({"formulation": ""}).groupby(keys, sort=False):
                by_family.setdefault(key, []).extend(group[columns].to_dict("records"))
    orders = {tuple(r[k] for k in keys): r["order"] for _, r in convergence.fillna({"formulation": ""}).iterrows()}
    tasks = [(f, False, by_family.get(f.key, []), orders[f.key]) for f in fixed
             if math.isfinite(orders.get(f.key, math.nan))]
    slopes = {tuple(r[k] for k in keys): r["slope"] for _, r in tolerance_fit.fillna({"formulation": ""}).iterrows()}
    points = {key: group[["tolerance", "steps", "status", "state_err", "attitude_err", "us_per_sim_s"]]
              .to_dict("records") for key, group in tolerance.fillna({"formulation": ""}).groupby(keys, sort=False)} \
        if len(tolerance) else {}
    tasks += [(f, True, points.get(f.key, []), slopes[f.key]) for f in adaptive
              if math.isfinite(slopes.get(f.key, math.nan))]
    return tasks


def _repeated_times(points: pd.DataFrame) -> pd.DataFrame:
    """Ladder points with us_per_sim_s only where timed with repeats: a point timed once (SINGLE) that is advised is
    timed with repeats by run_advice, as a sweep's run is."""
    if len(points) and "timing" in points:
        points = points.copy()
        points.loc[points["timing"] == SINGLE, "us_per_sim_s"] = math.nan
    return points


def families_to_advise(case, engine_name: str, integrators: list[str] | None,
                       formulation: str | None = None) -> list[tuple[Family, bool]]:
    """The families `stereodyn advise` checks: the integrators named, or the engine's default-sweep integrators
    with a declared order or error control, on one formulation (the one named, else quaternion or the engine's
    first). Bad names raise ValueError with the valid ones."""
    from ..run.plan import Hooks, flag

    engine = get_engine(engine_name)
    ask = Hooks(engine, engine_name)  # a plug-in's hooks behind the guard, as a sweep's plan asks them
    own, model = ask("formulations", formulations, engine), ask("models()", rigid_body, engine)
    ask.model = model
    if formulation is None:
        formulation = "quaternion" if "quaternion" in own else (own[0] if own else "")
    elif formulation not in own:
        raise ValueError(f"--formulation: {engine_name} has {', '.join(own) or 'no formulations'}, not {formulation!r}")
    known = ask("integrators()", engine.integrators)
    if integrators:
        unknown = [i for i in integrators if i not in known]
        if unknown:
            raise ValueError(f"--integrator: unknown for {engine_name}: {', '.join(unknown)}; valid: {', '.join(known)}")
        chosen = list(integrators)
    else:
        chosen = [i for i in known if ask(f"offer({i!r})", in_default_sweep, engine, i)
                  and ask("default_run(...)", model.default_run, case, formulation, i, rule=flag)
                  and (ask(f"offer({i!r})", engine.offer, i).adaptive or math.isfinite(declared_order(engine, i)))]
    out = []
    if ask.reason("unsupported(case)", model.unsupported, case):
        return out
    for integrator in chosen:
        if ask.reason("unsupported_run(...)", model.unsupported_run, case, formulation, integrator):
            continue
        out.append((Family(case, engine_name, formulation, integrator), ask(f"offer({integrator!r})", engine.offer,
                                                                           integrator).adaptive))
    return out
