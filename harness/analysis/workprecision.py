"""Work–precision, the tables: which ladders a run gets (plan_ladders), how their rows and the sweep's make
convergence.csv (convergence_rows), and the writing of the tables (its report sections: harness.report.workprecision).

Measuring is harness.pipeline (dt_ladders: dt ladders, stability bisection; tolerance_ladders: adaptive methods against
the requested tolerance; work_precision: the phase that runs what plan_ladders chose, on the sweep's pool), fitting
analysis.fitting (orders, round-off floors, tolerance proportionality, the Pareto table). This module runs nothing.

Outputs in the run folder: ladder.csv (every point), convergence.csv (one row per ladder, per short ladder, and per
other run family of the sweep with two dt or more), tolerance.csv (every tolerance-ladder point), tolerance_fit.csv
(one row per tolerance ladder), pareto.csv (per case and accuracy target, the cheapest run, fixed-step or adaptive),
and the orders as rows of checks.csv (quantity convergence_order, theory = the declared order).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from ..scenes import checks
from ..scenes import scene_of
from ..scenes.cases import CHAOTIC_TAGS, Case
from . import ladders as ladder_rules
from .ladders import LADDER, LADDER_COLUMNS, MIN_STEPS, SHORT_LADDER, families
from ..engines import declared, get_engine
from .pareto import ACCURACY_TARGETS
from .fitting import (CONVERGENCE_FILE, FAMILY, ORDER_QUANTITY, TIE_RTOL, convergence_table, declared_order, order_checks, pareto,
                      pareto_table, sweep_orders, tolerance_fits, with_state_err)
from ..precision import FLOAT64
from ..run.plan import Selection
from ..run.results import read_csv_table, with_precision, write_atomic  # noqa: F401 (read_csv_table: this API)
from ..run.spec import Family
from ..tables import read_optional  # noqa: F401 (the report's and the answers' readers use it from here)

__all__ = ["LADDER_FILE", "CONVERGENCE_FILE", "PARETO_FILE", "TOLERANCE_FILE", "TOLERANCE_FIT_FILE", "MIN_STEPS",
           "analyse", "read_optional", "rewrite_pareto", "pareto_table", "TIE_RTOL", "Family"]

LADDER_FILE, PARETO_FILE = "ladder.csv", "pareto.csv"
ADVICE_FILE = "advice.csv"
# The default run's checked advice: the laddered families (DEFAULT_LADDER's 28 with an order or slope) at 1e-3 and
# 1e-6 rad; every laddered family at every Pareto target with --dt-ladder. Measured on the committed default run's
# tables (tests/benchmarks/bench_advice.py, 2 workers, load average 11 from the other helpers): 1e-3 and 1e-6: 26 s,
# 117 check runs; 1e-6 alone 20 s; with 1e-9 as well 91 s (Drake's and scipy's BDF/Radau tight runs: seconds each).
DEFAULT_ADVICE_TARGETS = (1e-3, 1e-6)
TOLERANCE_FILE, TOLERANCE_FIT_FILE = "tolerance.csv", "tolerance_fit.csv"
TEXT_COLUMNS = ("formulation", "engine", "integrator", "precision", "message", "timing")
FULL_MAX_STEPS = 200_000     # --dt-ladder: rk4 reaches its round-off floor on the suite's cases well before this
DEFAULT_MAX_STEPS = 40_000   # the default run's small ladder (see DEFAULT_LADDER)
# The default run ladders these cases only, on the quaternion formulation of the reference engine: one free body and
# the chaotic heavy top whose MuJoCo Euler stability limit the suite documents (cases/heavy-asymmetric.toml).
DEFAULT_LADDER = ("free-asymmetric", "heavy-asymmetric")
DEFAULT_LADDER_FORMULATIONS = ("", "quaternion")
# Left out of the default ladder (their orders still come from the dt lists): MuJoCo's implicitfast is bit-identical
# to its Euler on a ball joint (ENGINES.md), and rk4_naive is a documented contrast that costs as much as rk4.
DEFAULT_LADDER_SKIP = ("implicitfast", "rk4_naive")
# A short ladder's point takes at most SHORT_MAX_STEPS steps, or SHORT_MAX_EVALS right-hand-side evaluations where that
# allows more (the sweep's rhs_per_sim_s): 40000 steps of rk4, 80000 of Euler, whose first-order error needs smaller
# steps to come down into the asymptotic range. Measured on the default run's results (tests/benchmarks/
# bench_short_ladders.py, 1 worker, other processes on the machine): +53 s of one core, 286 of 400 families fitted;
# 160000 evaluations (Euler 160000 steps): +92 s, 296.
SHORT_MAX_STEPS, SHORT_MAX_EVALS = DEFAULT_MAX_STEPS, 2 * DEFAULT_MAX_STEPS
# ... and at most SHORT_MAX_POINT_S of stepping at the family's own cost of a step in the sweep (its median
# us_per_step), never below the sweep's own steps. Genesis steps at ~0.5 ms: 64000-80000 steps were 30-40 s a point,
# and its short ladders 1.26 M steps, ~640 s of CPU (the default run with every extra, 2026-11-27). The other engines'
# points stayed under 9.4 s at these caps in four default runs (Drake's discrete and runge_kutta3 the dearest), so
# 15 s leaves them as they were.
SHORT_MAX_POINT_S = 15.0


def _ladder_cost(family: Family) -> float:
    """Rank of a family's ladder cost, to start the costliest first so the pool ends together: the engine's cost of
    a step times the integrator's declared order (higher orders reach their floor at more, smaller steps)."""
    engine = get_engine(family.engine)
    order = declared.declared_order(engine, family.integrator)
    return engine.timing.pass_us * (order if math.isfinite(order) else 1.0)


def rewrite_pareto(out_dir: Path, results: pd.DataFrame, failed: set) -> None:
    """pareto.csv again, leaving out the runs of the integrators that failed a verdict (harness.analysis.verdicts)."""
    ladder = read_optional(Path(out_dir) / LADDER_FILE, TEXT_COLUMNS)
    if ladder is None:
        ladder = pd.DataFrame(columns=list(LADDER_COLUMNS))
    tolerance = read_optional(Path(out_dir) / TOLERANCE_FILE, TEXT_COLUMNS)
    _write(pareto(results, ladder, failed, tolerance), Path(out_dir) / PARETO_FILE)


def _write(df: pd.DataFrame, path: Path) -> None:
    write_atomic(path, df.to_csv(index=False, float_format="%.10g"))


def short_ladder_families(results: pd.DataFrame, cases: list[Case], engines: list[str], integrators: list[str] | None,
                          sweep_rows: list[dict], laddered: set[tuple],
                          remeasure: set[tuple] = frozenset()) -> list[tuple[Family, list[dict], int]]:
    """The families that get a short ladder (pipeline.dt_ladders.run_short_ladder), each with its sweep runs and its
    steps cap (SHORT_MAX_STEPS, or SHORT_MAX_EVALS over the evaluations a step of it costs in the sweep; at most
    SHORT_MAX_POINT_S of stepping at its cost of a step in the sweep): every
    fixed-step family of these cases with a declared order (Offer.order), not laddered, whose own dt list
    gives no order (or, for a claim (engine, formulation, integrator) in remeasure, whose order misses the rule on
    too few points: weak_claims; its non-chaotic cases), and with a run that was not failed or skipped (those keep
    their sweep row and its reason)."""
    chaotic = {c.name for c in cases if set(c.tags) & set(CHAOTIC_TAGS)}
    fitted = {tuple(r[c] for c in FAMILY) for r in sweep_rows if math.isfinite(r["order"])
              and not ((r["engine"], r["formulation"], r["integrator"]) in remeasure and r["case"] not in chaotic)}
    runs = with_state_err(with_precision(results[results["dt"].notna()]).fillna({"formulation": ""}))
    by_family = {key: group for key, group in runs.groupby(list(FAMILY), sort=False)}
    out = []
    for family in families(cases, engines, integrators):
        key = family.key
        declared = declared_order(family.engine, family.integrator, family.formulation)
        if key in laddered or key in fitted or not math.isfinite(declared):
            continue
        group = by_family.get(key)
        if group is None or group["status"].isin(("failed", "skipped")).all():
            continue
        per_step = (group["rhs_per_sim_s"] * group["t_end"] / group["steps"]).median() \
            if {"rhs_per_sim_s", "t_end"} <= set(group) else math.nan
        # evaluations a step: a whole number for a fixed-step method (its stages); rounded, since a results.csv read
        # back gives 0.99999999995 for Euler (its numbers are written to 10 digits)
        evals = round(per_step) if math.isfinite(per_step) else 0
        max_steps = max(SHORT_MAX_STEPS, int(SHORT_MAX_EVALS / evals) if evals >= 1 else 0)
        per_step_s = group["us_per_step"].median() * 1e-6 if "us_per_step" in group else math.nan
        if math.isfinite(per_step_s) and per_step_s > 0.0:
            most = group["steps"].max()
            floor = int(most) if math.isfinite(most) else 0
            max_steps = min(max_steps, max(int(SHORT_MAX_POINT_S / per_step_s), floor))
        out.append((family, group[["dt", "steps", "status", "state_err"]].to_dict("records"), max_steps))
    return out


def weak_claims(sweep_rows: list[dict], chaotic: set[str]) -> set[tuple]:
    """The claims (engine, formulation, integrator) whose dt lists give too little evidence to judge (fewer than
    MIN_POINTS asymptotic points on every non-chaotic case and fewer than MIN_CASES such cases: verdicts.weak_evidence),
    whether they meet the order rule or miss it (verdicts.NOT_ENOUGH): a --strict run measures them more before it
    judges. Without --strict they are judged as they are, the verdict stating its evidence."""
    from .verdicts import weak_evidence

    return weak_evidence(convergence_table(sweep_rows), chaotic) if sweep_rows else set()


def first_part_families(short: list[tuple[Family, list[dict], int]], points: list[dict], ladder_rows: list[dict],
                        sweep_rows: list[dict], cases: list[Case]) -> list[tuple[Family, list[dict], int, dict]]:
    """The short-laddered families that may get a first part, each with its points, steps cap and row: no order, a
    case not chaotic, and a claim (engine, formulation, integrator, precision) that no non-chaotic case's fit measured
    (only the order verdict needs it; it costs up to ~2 caps of steps). pipeline.dt_ladders.run_first_part runs one
    only where the finest ok point is above the range (or the only asymptotic one): never where the reason is
    exactness, round-off or no run ok."""
    chaotic = {c.name for c in cases if set(c.tags) & set(CHAOTIC_TAGS)}

    def claim(row) -> tuple:
        return row["engine"], row["formulation"], row["integrator"], row.get("precision", FLOAT64)

    measured = {claim(r) for r in [*ladder_rows, *sweep_rows] if math.isfinite(r["order"]) and r["case"] not in chaotic}
    rows = {tuple(r[c] for c in FAMILY): r for r in ladder_rows if r["source"] == SHORT_LADDER}
    out = []
    for family, known, steps in short:
        row = rows.get(family.key)
        if row is None or math.isfinite(row["order"]) or family.case.name in chaotic or claim(row) in measured:
            continue
        own = [p for p in points if p.get("source") == SHORT_LADDER
               and tuple(p.get(c, FLOAT64 if c == "precision" else "") for c in FAMILY) == family.key]
        out.append((family, known + own, steps, row))
    return out


def default_tolerance_families(cases: list[Case], engines: list[str],
                               integrators: list[str] | None) -> list[ladder_rules.AdaptiveFamily]:
    """The default run's tolerance ladders: on DEFAULT_LADDER_FORMULATIONS, the adaptive methods of the sweep's
    selection (run.plan.Selection: those named, or without --integrators each engine's default sweep). The others get
    ladders with --dt-ladder: Drake's six other error-controlled schemes were 70% of the tolerance ladders' timed
    seconds in a default run (2-core machine; radau3 and bogacki_shampine3 at 1e-11 take 0.2-0.6 M steps)."""
    selected = {name: Selection.of(get_engine(name), integrators).integrators for name in engines}
    return [f for f in ladder_rules.adaptive_families(cases, engines, integrators, DEFAULT_LADDER_FORMULATIONS)
            if f.integrator in selected[f.engine]]


@dataclass(frozen=True)
class LadderPlan:
    """The ladders a run gets (plan_ladders), for harness.pipeline.work_precision to run. mode: "full", "default",
    "short" or "off"; chosen: the dt ladders' families, costliest first; adaptive: the tolerance ladders' families;
    tolerances: their requested tolerances (1); max_steps: a ladder's steps cap; short: the short ladders (family, its
    sweep runs, its steps cap), costliest first; sweep_rows: the convergence rows of the sweep's own dt lists; rigid:
    the cases with work–precision (Scene.work_precision); other_kinds: the names of the other cases."""

    mode: str
    chosen: list[Family]
    adaptive: list[Family]
    tolerances: tuple[float, ...]
    max_steps: int
    short: list[tuple[Family, list[dict], int]]
    sweep_rows: list[dict]
    rigid: list[Case]
    other_kinds: frozenset[str]


def plan_ladders(results: pd.DataFrame, cases: list[Case], engines: list[str], integrators: list[str] | None,
                 ladder: str = "default", max_steps: int | None = None) -> LadderPlan:
    """Which ladders the work–precision phase runs after this sweep (results: its table). ladder: "full" (every family
    of the sweep, and a tolerance ladder for every adaptive method on every case and formulation), "default"
    (DEFAULT_LADDER cases, DEFAULT_LADDER_FORMULATIONS, both kinds of ladder, and a short ladder for every other
    family whose dt list gives no order), "short" (those short ladders only, for the integrators no case's dt list
    measured: a --strict run of named cases) or "off"."""
    # Orders, floors and stability limits are about the body with a fixed point; other scene kinds (the constrained
    # sliding ladder, whose MuJoCo model has soft constraints) keep their Pareto rows only.
    rigid = [c for c in cases if scene_of(c).work_precision]
    other_kinds = frozenset({c.name for c in cases} - {c.name for c in rigid})
    if ladder == "full":
        chosen = families(rigid, engines, integrators)
        adaptive = ladder_rules.adaptive_families(rigid, engines, integrators)
        tolerances = ladder_rules.TOLERANCES
        max_steps = max_steps or FULL_MAX_STEPS
    elif ladder == "default":
        laddered_cases = [c for c in rigid if c.name in DEFAULT_LADDER]
        chosen = [f for f in families(laddered_cases, engines, integrators, DEFAULT_LADDER_FORMULATIONS)
                  if f.integrator not in DEFAULT_LADDER_SKIP]
        adaptive = default_tolerance_families(laddered_cases, engines, integrators)
        tolerances = ladder_rules.DEFAULT_TOLERANCES
        max_steps = max_steps or DEFAULT_MAX_STEPS
    else:
        chosen, adaptive, tolerances = [], [], ()
    # the costliest first, so the pool ends together
    chosen.sort(key=_ladder_cost, reverse=True)
    laddered = {f.key for f in chosen}
    rigid_results = results[~results["case"].isin(other_kinds)]
    sweep_rows = sweep_orders(rigid_results, laddered)
    short = short_ladder_families(rigid_results, rigid, engines, integrators, sweep_rows, laddered) \
        if ladder in ("default", "short") else []
    if ladder == "short":  # only what the order verdicts need: integrators no non-chaotic case's dt list measured
        chaotic = {c.name for c in rigid if set(c.tags) & set(CHAOTIC_TAGS)}
        measured = {(r["engine"], r["formulation"], r["integrator"]) for r in sweep_rows
                    if math.isfinite(r["order"]) and r["case"] not in chaotic}
        # and those whose dt lists give too few points to judge, passed or missed (weak_claims): measured more
        weak = weak_claims(sweep_rows, chaotic)
        if weak:
            short = short_ladder_families(rigid_results, rigid, engines, integrators, sweep_rows, laddered, weak)
        short = [item for item in short if (item[0].engine, item[0].formulation, item[0].integrator) not in measured
                 or (item[0].engine, item[0].formulation, item[0].integrator) in weak]
    short.sort(key=lambda item: _ladder_cost(item[0]), reverse=True)
    return LadderPlan(ladder, chosen, adaptive, tolerances, max_steps or DEFAULT_MAX_STEPS, short, sweep_rows, rigid,
                      other_kinds)


def with_first_parts(ladder_rows: list[dict], parts: list[dict]) -> list[dict]:
    """The ladders' convergence rows, each short ladder's replaced by its first part's row where one ran."""
    by_family = {tuple(r[c] for c in FAMILY): r for r in parts}
    return [by_family.get(tuple(r[c] for c in FAMILY), r) if r["source"] == SHORT_LADDER else r for r in ladder_rows]


def convergence_rows(ladder_rows: list[dict], sweep_rows: list[dict]) -> pd.DataFrame:
    """convergence.csv: the ladders' rows, then the sweep's, a short ladder's row in place of its family's row from
    the dt list (a family with one dt had none: its short-ladder row comes last)."""
    by_key = {tuple(r[c] for c in FAMILY): r for r in ladder_rows if r["source"] == SHORT_LADDER}
    rows = [r for r in ladder_rows if r["source"] == LADDER]
    for row in sweep_rows:
        rows.append(by_key.pop(tuple(row[c] for c in FAMILY), row))
    return convergence_table(rows + list(by_key.values()))


def table_paths(out_dir: Path) -> dict[str, Path]:
    """The work–precision phase's tables in a run folder, by name."""
    out_dir = Path(out_dir)
    return {"ladder": out_dir / LADDER_FILE, "convergence": out_dir / CONVERGENCE_FILE,
            "tolerance": out_dir / TOLERANCE_FILE, "tolerance_fit": out_dir / TOLERANCE_FIT_FILE,
            "pareto": out_dir / PARETO_FILE}


def write_tables(out_dir: Path, results: pd.DataFrame, ladder_df: pd.DataFrame, convergence: pd.DataFrame,
                 tolerance_df: pd.DataFrame, write_pareto: bool = True) -> dict[str, Path]:
    """ladder.csv, convergence.csv, tolerance.csv, tolerance_fit.csv and (write_pareto) pareto.csv; the paths."""
    paths = table_paths(out_dir)
    _write(ladder_df, paths["ladder"])
    _write(convergence, paths["convergence"])
    _write(tolerance_df, paths["tolerance"])
    _write(tolerance_fits(tolerance_df), paths["tolerance_fit"])
    if write_pareto:
        _write(pareto(results, ladder_df, tolerance=tolerance_df), paths["pareto"])
    return paths


def write_advice(out_dir: Path, table: pd.DataFrame) -> Path:
    """advice.csv (analysis.step_advice.ADVICE_COLUMNS); its path."""
    path = Path(out_dir) / ADVICE_FILE
    _write(table, path)
    return path


def write_order_checks(out_dir: Path, convergence: pd.DataFrame) -> None:
    """The fitted orders as checks.csv's convergence_order rows, in place of any the folder had."""
    checks_path = Path(out_dir) / checks.CHECKS_FILE
    existing = checks.read_checks(checks_path) if checks_path.is_file() else pd.DataFrame(columns=list(checks.COLUMNS))
    existing = existing[existing["quantity"] != ORDER_QUANTITY]
    merged = pd.concat([existing, order_checks(convergence)], ignore_index=True) if len(existing) \
        else order_checks(convergence)
    write_atomic(checks_path, merged.to_csv(index=False, float_format="%.17g"))


def advice_targets(mode: str) -> tuple[float, ...]:
    """The accuracy targets advised (rad): every Pareto target with --dt-ladder ("full"), else
    DEFAULT_ADVICE_TARGETS."""
    return ACCURACY_TARGETS if mode == "full" else DEFAULT_ADVICE_TARGETS
