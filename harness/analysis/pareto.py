"""The Pareto table (pareto.csv): per case, scope and accuracy target, the cheapest run whose max attitude error
reaches the target, fixed-step or adaptive.

Scopes: `any` (every run: the reference formulations and heyoka's Taylor method included) and one per engine that
ran (only that engine's runs: what a user of that engine can switch to). In each cell of a scope:
- candidates: the scope's ok runs with a finite error and a timing that reach the target; runs whose integrator failed
  a verdict are left out (named in `not_recommended` where cheaper), and so are runs whose timing was disturbed
  (harness.run.results.disturbed: a spread larger than the time itself, still so after the timing phase re-timed it);
- tie-mates: every candidate within the timing noise of the fastest (TIE_RTOL, the spreads), but never one more than
  TIE_MAX_RATIO times slower than the fastest, whatever its spread;
- the winner: among the tie-mates of the fastest's engine, the fewest right-hand-side evaluations per simulated second
  (evaluations mean different work in different engines, so only one engine's runs are compared by them), then the
  fastest; runs that only noise tells apart (same evaluations, same error) in name order.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from ..tables import disturbed
from ..trajectory import Status
from .text import number as _num

PARETO_COLUMNS = ("case", "scope", "target", "engine", "formulation", "integrator", "dt", "tolerance",
                  "attitude_err", "us_per_sim_s", "us_per_sim_s_spread", "rhs_per_sim_s", "steps", "source", "ties",
                  "not_recommended")
# The columns a Pareto cell copies from its winning candidate.
_CELL_COLUMNS = PARETO_COLUMNS[3:14]
ANY = "any"   # the scope of every run; the others are named by their engine
# pareto.csv's `source`: where the winning candidate came from, or why no run is named.
SOURCE_SWEEP, SOURCE_LADDER, SOURCE_TOLERANCE = "sweep", "ladder", "tolerance_ladder"
NONE_REACHED, ONLY_FAILED, ONLY_DISTURBED = ("none reached it", "only runs that failed a verdict",
                                             "only runs whose timing was disturbed")
ACCURACY_TARGETS = tuple(10.0 ** -k for k in range(2, 13))

# Two candidates tie when their costs differ by no more than the timing noise: the sum of their spreads (slowest
# minus fastest of their timed runs), and at least TIE_RTOL of the cheaper cost. The floor stands for the noise that
# repeats inside one process do not show and two runs of the sweep do (clock boost, cache and memory placement); 5% is
# the usual run-to-run scatter of a micro-benchmark on an idle machine. Checked on the timings of two consecutive
# idle default runs (2-core AMD EPYC, 2026-11-25; tests/benchmarks/ranking_stability.py), ranked by pareto_table:
# 254 of 264 cells named the same winner, the other 10 were tie-marked, none differed unmarked.
TIE_RTOL = 0.05
# A large spread is a disturbed measurement, not a licence: a run 1.5x slower than the fastest is never its tie
# (issue 21: scipy_rk45 at 1690 µs/s, spread 2030, "tied" with Pinocchio euler at 263 and then won on evaluations).
TIE_MAX_RATIO = 1.5


def tied(cost, spread, fastest: float, fastest_spread: float):
    """Whether a cost (a number or an array, with its spread) ties with the fastest's: within the timing noise (the
    sum of the two spreads, a NaN spread counting as 0, and at least TIE_RTOL of the fastest's cost) and never more
    than TIE_MAX_RATIO times the fastest. The one tie rule: the Pareto cells' (_cell) and compare's (answers.changed:
    an answer that moved between two runs whose costs tie is timing noise, no change)."""
    cost, spread = np.asarray(cost, dtype=float), np.asarray(spread, dtype=float)
    fastest_spread = fastest_spread if math.isfinite(fastest_spread) else 0.0
    noise = np.maximum(np.where(np.isnan(spread), 0.0, spread) + fastest_spread, TIE_RTOL * fastest)
    return (cost - fastest <= noise) & (cost <= TIE_MAX_RATIO * fastest)

_CANDIDATE_COLUMNS = ("case", "engine", "formulation", "integrator", "dt", "tolerance", "attitude_err",
                      "us_per_sim_s", "us_per_sim_s_spread", "rhs_per_sim_s", "steps", "source", "status")


def pareto(results: pd.DataFrame, ladder: pd.DataFrame, failed: set | None = None,
           tolerance: pd.DataFrame | None = None) -> pd.DataFrame:
    """pareto.csv from the sweep's results, the dt ladders' points and the tolerance ladders' points (tolerance.csv,
    pareto_candidates). Candidates: every timed run of the sweep, fixed-step and adaptive (at the engine's default
    tolerance; the truth has no error of its own and is none), and the ladders' points. failed: the integrators that
    failed a verdict (harness.analysis.verdicts.failed_integrators)."""
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
    ran = results[results["status"] != Status.SKIPPED.value] if "status" in results else results
    return pareto_table(both, list(dict.fromkeys(results["case"])), failed or set(),
                        engines=list(dict.fromkeys(ran["engine"])))


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


def run_name(row) -> str:
    return " ".join(str(x) for x in (row["engine"], row["formulation"], row["integrator"]) if isinstance(x, str) and x)


def _candidate_name(row) -> str:
    return f"{run_name(row)} {setting(row)}"


def _candidate(row) -> str:
    return f"{_candidate_name(row)} ({_num(row['us_per_sim_s'], '.3g')} µs/s)"


def is_failed(failed_set: set[tuple[str, str, str]], engine: str, formulation: str, integrator: str) -> bool:
    """Whether a run's integrator failed a verdict (analysis.verdicts.failed_integrators; "*" matches any engine and
    formulation)."""
    return (engine, formulation, integrator) in failed_set or ("*", "*", integrator) in failed_set


def pareto_table(runs: pd.DataFrame, cases: list[str], failed: set = frozenset(),
                 engines: list[str] | None = None) -> pd.DataFrame:
    """The Pareto table from candidate runs (columns case, engine, formulation, integrator, dt, attitude_err,
    us_per_sim_s, us_per_sim_s_spread, rhs_per_sim_s, steps, source, status; optionally tolerance): rows per case,
    scope (ANY, then each of `engines`, default the candidates' engines in order) and target, with the rules of the
    module docstring. failed: (engine, formulation, integrator) of the integrators that failed a verdict."""
    runs = runs.fillna({"formulation": ""})
    if engines is None:
        engines = list(dict.fromkeys(runs["engine"]))
    runs = runs[(runs["status"] == Status.OK.value) & np.isfinite(runs["attitude_err"].astype(float))
                & np.isfinite(runs["us_per_sim_s"].astype(float))]
    bad = np.array([is_failed(set(failed), r.engine, r.formulation, r.integrator) for r in runs.itertuples()],
                   dtype=bool)
    shaky = disturbed(runs["us_per_sim_s"].to_numpy(float), runs["us_per_sim_s_spread"].to_numpy(float))
    table = _Candidates.of(runs)
    case_of, engine_of = runs["case"].to_numpy(object), runs["engine"].to_numpy(object)
    records = []
    for case in cases:
        in_case = case_of == case
        for scope in [ANY, *engines]:
            in_scope = in_case if scope == ANY else in_case & (engine_of == scope)
            for target in ACCURACY_TARGETS:
                reach = in_scope & (table.err <= target)
                cell = _cell(table, *(np.flatnonzero(m) for m in (reach & ~bad & ~shaky, reach & bad,
                                                                  reach & shaky & ~bad)))
                records.append({"case": case, "scope": scope, "target": target, **cell})
    return pd.DataFrame(records, columns=list(PARETO_COLUMNS))


@dataclass(frozen=True)
class _Candidates:
    """The candidate runs as arrays, a run a position (1430 cells of pandas subsets were 4 s of the default run):
    cost, spread (us_per_sim_s and its spread), err (attitude_err), rhs (rhs_per_sim_s), engine, and per run its
    row as a dict, its name (_candidate_name) and its label (_candidate)."""

    cost: np.ndarray
    spread: np.ndarray
    err: np.ndarray
    rhs: np.ndarray
    engine: np.ndarray
    rows: list[dict]
    names: list[str]
    labels: list[str]

    @classmethod
    def of(cls, runs: pd.DataFrame) -> "_Candidates":
        rows = runs.to_dict("records")
        return cls(runs["us_per_sim_s"].to_numpy(float), runs["us_per_sim_s_spread"].to_numpy(float),
                   runs["attitude_err"].to_numpy(float), runs["rhs_per_sim_s"].to_numpy(float),
                   runs["engine"].to_numpy(object), rows, [_candidate_name(r) for r in rows],
                   [_candidate(r) for r in rows])

    def cheapest(self, positions: np.ndarray, n: int = 3) -> str:
        """The labels of the n cheapest of positions, cheapest first (equal costs in table order)."""
        return "; ".join(self.labels[i] for i in positions[np.argsort(self.cost[positions], kind="stable")[:n]])


def _cell(table: _Candidates, good: np.ndarray, excluded: np.ndarray, shaky: np.ndarray) -> dict:
    """One cell from the positions of its candidates (good), of the runs left out for a failed verdict (excluded) and
    for a disturbed timing (shaky): the winner's columns, its tie-mates and the cheaper runs not recommended."""
    if not len(good):
        source = ONLY_FAILED if len(excluded) else ONLY_DISTURBED if len(shaky) else NONE_REACHED
        return {"engine": "", "formulation": "", "integrator": "", "source": source, "ties": "",
                "not_recommended": table.cheapest(excluded)}
    fastest = good[np.argmin(table.cost[good])]  # the first of equal costs
    mates = good[tied(table.cost[good], table.spread[good], table.cost[fastest], table.spread[fastest])]
    # right-hand-side evaluations are comparable within one engine only: they decide among the fastest's engine's
    # tie-mates, and only where every one of them counts them (heyoka's taylor does not: a Taylor step has no stages)
    same = mates[table.engine[mates] == table.engine[fastest]]
    rhs = table.rhs[same]
    rhs = rhs if not np.isnan(rhs).any() else np.zeros(len(same))
    first = np.lexsort((table.cost[same], rhs))[0]  # fewest evaluations, then fastest (stable: table order)
    # Two idle default runs named different winners in 11 of 264 cells only because MuJoCo's euler and
    # implicitfast (bit-identical on a ball joint) swapped places by a few per cent of time.
    twins = same[(rhs == rhs[first]) & (table.err[same] == table.err[same[first]])]
    best = min(twins, key=lambda i: table.names[i])
    return {**{c: table.rows[best].get(c, math.nan) for c in _CELL_COLUMNS},
            "ties": "; ".join(table.labels[i] for i in mates if i != best),
            "not_recommended": table.cheapest(excluded[table.cost[excluded] < table.cost[best]])}


def scope_rows(table: pd.DataFrame, scope: str = ANY) -> pd.DataFrame:
    """The rows of one scope of a pareto.csv table (a table written before scopes existed is all ANY)."""
    if "scope" not in table:
        return table
    return table[table["scope"].fillna(ANY).astype(str) == scope]


def scopes(table: pd.DataFrame) -> list[str]:
    """The engine scopes of a pareto.csv table, in its order (ANY left out)."""
    if "scope" not in table:
        return []
    return [s for s in dict.fromkeys(table["scope"].fillna(ANY).astype(str)) if s != ANY]
