"""One answer per case, engine and accuracy target (issue 32 item 3): the table that "What to use", "Step-size
advice" and the Summary all read, so that they never contradict each other.

Per case, scope (an engine, or `any`) and target the answer is the cheapest of:
- the engine's families that advice.csv searched at that target (`searched`: the largest dt or tolerance checked to
  reach it, analysis.step_advice), and
- pareto.csv's winner of the cell (`listed, not searched`: the cheapest of the runs the sweep and the ladders listed,
  with the error it reached), unless advice searched that winner's own family at that target: then the searched
  setting stands for it.
Integrators that failed a verdict are no answer (as in pareto.csv). `any` is the cheapest engine's answer, so an
engine's row and `any`'s never disagree. Costs tie to the searched answer, then name order.

`stereodyn run` writes the table as DIR/answers.csv (write), beside pareto.csv, once the verdicts are in; the report,
the Summary and the terminal read that file (read), as a CI job or a notebook would.
"""
from __future__ import annotations

import math
from pathlib import Path

import pandas as pd

from .pareto import ANY, ACCURACY_TARGETS, is_failed, scopes, tied

ANSWERS_FILE = "answers.csv"
SEARCHED, LISTED = "searched", "listed, not searched"
ANSWER_COLUMNS = ("case", "scope", "target", "engine", "formulation", "integrator", "dt", "tolerance", "error",
                  "us_per_sim_s", "us_per_sim_s_spread", "source", "fails_at", "why_none")
_TEXT = ("engine", "formulation", "integrator", "source", "why_none")


def _text(value) -> str:
    return value if isinstance(value, str) else ""


def _finite(value) -> bool:
    return isinstance(value, (int, float)) and math.isfinite(value)


def _target_key(target: float) -> str:
    """A target as a key: equal for 1e-06 read back from CSV and 1e-6."""
    return f"{float(target):.6e}"


def _searched(advice: list[dict], engine: str, failed) -> list[dict]:
    """advice.csv's advised rows (a finite dt or tolerance) of one case, engine and target, as answers."""
    out = []
    for row in advice:
        if not (_finite(row["dt"]) or _finite(row["tolerance"])):
            continue
        formulation, integrator = _text(row["formulation"]), _text(row["integrator"])
        if is_failed(failed, engine, formulation, integrator):
            continue
        out.append({"engine": engine, "formulation": formulation, "integrator": integrator, "dt": row["dt"],
                    "tolerance": row["tolerance"], "error": row["error_checked"],
                    "us_per_sim_s": row["us_per_sim_s"], "us_per_sim_s_spread": math.nan, "source": SEARCHED,
                    "fails_at": row["fails_at"]})
    return out


def _listed(row) -> dict:
    return {"engine": _text(row["engine"]), "formulation": _text(row["formulation"]),
            "integrator": _text(row["integrator"]), "dt": row["dt"], "tolerance": row.get("tolerance", math.nan),
            "error": row.get("attitude_err", math.nan), "us_per_sim_s": row["us_per_sim_s"],
            "us_per_sim_s_spread": row.get("us_per_sim_s_spread", math.nan), "source": LISTED, "fails_at": math.nan}


def _cheapest(candidates: list[dict]) -> dict | None:
    if not candidates:
        return None
    return min(candidates, key=lambda c: (not _finite(c["us_per_sim_s"]),
                                          c["us_per_sim_s"] if _finite(c["us_per_sim_s"]) else 0.0,
                                          c["source"] != SEARCHED, c["formulation"], c["integrator"]))


def answers(pareto: pd.DataFrame, advice: pd.DataFrame | None = None, failed: set = frozenset()) -> pd.DataFrame:
    """The answers table (ANSWER_COLUMNS) from pareto.csv and advice.csv (either may be empty; text columns read as
    strings). failed: the integrators that failed a verdict (analysis.verdicts.failed_integrators). Rows per case,
    then each engine scope of pareto.csv and `any`, then target (pareto.csv's targets); a cell without an answer has
    an empty engine and `why_none` says why (pareto.csv's `source`)."""
    failed = set(failed)
    scope_of = pareto["scope"].fillna(ANY).astype(str) if "scope" in pareto else pd.Series(ANY, index=pareto.index)
    cells: dict[tuple, list[dict]] = {}
    for scope, row in zip(scope_of, pareto.to_dict("records")):
        cells.setdefault((row["case"], scope, _target_key(row["target"])), []).append(row)
    advised: dict[tuple, list[dict]] = {}
    for row in ([] if advice is None else advice.to_dict("records")):
        advised.setdefault((row["case"], row["engine"], _target_key(row["target"])), []).append(row)
    targets = sorted({float(t) for t in pareto["target"]} or set(ACCURACY_TARGETS), reverse=True)
    engines = scopes(pareto)
    records = []
    for case in dict.fromkeys(pareto["case"]):
        by_scope: dict[str, list[dict]] = {scope: [] for scope in [*engines, ANY]}
        for target in targets:
            key = _target_key(target)
            found = []
            for engine in engines:
                cell = cells.get((case, engine, key), [])
                searched = _searched(advised.get((case, engine, key), []), engine, failed)
                covered = {(c["formulation"], c["integrator"]) for c in searched}
                listed = [_listed(r) for r in cell if _text(r["engine"])
                          and (_text(r["formulation"]), _text(r["integrator"])) not in covered]
                answer = _cheapest(searched + listed)
                why = "" if answer or not cell else _text(cell[0].get("source"))
                by_scope[engine].append(_record(case, engine, target, answer, why))
                if answer:
                    found.append(answer)
            cell = cells.get((case, ANY, key), [])
            if not engines:  # a pareto.csv written before scopes (0.3) is all `any`: its rows are the answers
                found = [_listed(r) for r in cell if _text(r["engine"])]
            by_scope[ANY].append(_record(case, ANY, target, _cheapest(found),
                                         "" if found or not cell else _text(cell[0].get("source"))))
        records += [record for rows in by_scope.values() for record in rows]
    return pd.DataFrame(records, columns=list(ANSWER_COLUMNS))


def _record(case: str, scope: str, target: float, answer: dict | None, why: str) -> dict:
    empty = {"engine": "", "formulation": "", "integrator": "", "dt": math.nan, "tolerance": math.nan,
             "error": math.nan, "us_per_sim_s": math.nan, "us_per_sim_s_spread": math.nan, "source": "",
             "fails_at": math.nan}
    return {"case": case, "scope": scope, "target": target, **(answer or empty), "why_none": why}


def answer_setting(row) -> str:
    """An answer's dt or tolerance as the report prints it (4 significant digits: advice's rounding)."""
    if _finite(row["dt"]):
        return f"dt={row['dt']:.4g}"
    if _finite(row["tolerance"]):
        return f"tol={row['tolerance']:.3g}"
    return "default tol"


def key(row) -> tuple:
    """What must agree between the sections: the method and its setting."""
    return (_text(row["engine"]), _text(row["formulation"]), _text(row["integrator"]), answer_setting(row))


def read(out_dir: Path, failed: set | None = None) -> pd.DataFrame | None:
    """The answers of an output folder: its answers.csv; for a folder written before it (stereodyn wrote none), the
    table made from pareto.csv, advice.csv and verdicts.csv (compute). None without either."""
    from ..tables import read_optional

    table = read_optional(Path(out_dir) / ANSWERS_FILE, _TEXT)
    return compute(out_dir, failed) if table is None else table


def write(out_dir: Path, failed: set | None = None) -> Path | None:
    """Write DIR/answers.csv (compute's table, every digit kept: what the report shows is what the file holds);
    None, and no file (an earlier run's removed), without pareto.csv."""
    from ..atomic import write_atomic

    path = Path(out_dir) / ANSWERS_FILE
    table = compute(out_dir, failed)
    if table is None:
        path.unlink(missing_ok=True)
        return None
    write_atomic(path, table.to_csv(index=False, float_format="%.17g"))
    return path


def compute(out_dir: Path, failed: set | None = None) -> pd.DataFrame | None:
    """The answers from an output folder's pareto.csv, advice.csv and verdicts.csv (failed: the integrators that
    failed a verdict, default verdicts.csv's); None without pareto.csv."""
    from . import verdicts, workprecision

    pareto = workprecision.read_optional(Path(out_dir) / workprecision.PARETO_FILE,
                                         ("formulation", "engine", "integrator", "scope", "source", "ties",
                                          "not_recommended"))
    if pareto is None or pareto.empty:
        return None
    advice = workprecision.read_optional(Path(out_dir) / workprecision.ADVICE_FILE,
                                         ("formulation", "engine", "integrator", "note"))
    if failed is None:
        failed = verdicts.failed_integrators(verdicts.read(out_dir) or [])
    table = answers(pareto, advice, failed)
    for column in _TEXT:
        table[column] = table[column].fillna("").astype(str)
    return table


def changed(a: pd.DataFrame | None, b: pd.DataFrame | None) -> list[dict]:
    """The answers that differ between two answers tables (A the reference): per (case, scope, target) of either,
    {"case", "scope", "target", "a", "b", "noise"} with each side's method and setting (key), "-" for no answer
    (no engine) or a cell absent; in B's order, then A's cells that B lacks.

    noise: the answer moved only within the timing noise, which is no change (`compare --format pr` says so and
    counts it nowhere else): both sides answer, and A's answer's cost and B's answer's cost tie by the Pareto cells'
    rule (pareto.tied: within the sum of their spreads, at least TIE_RTOL of the cheaper, never TIE_MAX_RATIO apart).
    A rerun on one machine names another of the runs that tie (their timings vary run to run) at about the same
    cost; an answer that went or came, or whose run became costlier beyond the noise (or stopped reaching the target,
    so that a costlier one answers), is a change."""
    def cells(table) -> dict:
        if table is None:
            return {}
        return {(r["case"], r["scope"], _target_key(r["target"])):  # a cell without an answer (no engine) says "-"
                (r, " ".join(x for x in key(r) if x) if _text(r["engine"]) else "-") for _, r in table.iterrows()}

    in_a, in_b = cells(a), cells(b)
    out = []
    for cell in [*in_b, *(c for c in in_a if c not in in_b)]:
        row_b, said_b = in_b.get(cell, (None, "-"))
        row_a, said_a = in_a.get(cell, (None, "-"))
        if said_a != said_b:
            out.append({"case": cell[0], "scope": cell[1], "target": float(cell[2]), "a": said_a, "b": said_b,
                        "noise": said_a != "-" and said_b != "-" and _costs_tie(row_a, row_b)})
    return out


def folder_changes(a: Path, b: Path) -> list[dict]:
    """changed() between two result directories' answers (read); none where either side is a baseline file, which
    holds no answers."""
    if not (Path(a).is_dir() and Path(b).is_dir()):
        return []
    return changed(read(a), read(b))


def _costs_tie(row_a, row_b) -> bool:
    """Whether two answers' costs (us_per_sim_s, with their spreads) tie: pareto.tied, the cheaper as the fastest."""
    number = lambda value: float(value) if _finite(value) else math.nan  # noqa: E731
    costs = sorted((number(row["us_per_sim_s"]), number(row.get("us_per_sim_s_spread"))) for row in (row_a, row_b))
    if not all(math.isfinite(cost) and cost > 0 for cost, _ in costs):
        return False
    (fastest, fastest_spread), (cost, spread) = costs
    return bool(tied(cost, spread, fastest, fastest_spread))
