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
"""
from __future__ import annotations

import math
from pathlib import Path

import pandas as pd

from .pareto import ANY, ACCURACY_TARGETS, is_failed, scope_rows, scopes

SEARCHED, LISTED = "searched", "listed, not searched"
ANSWER_COLUMNS = ("case", "scope", "target", "engine", "formulation", "integrator", "dt", "tolerance", "error",
                  "us_per_sim_s", "us_per_sim_s_spread", "source", "fails_at", "why_none")
_TEXT = ("engine", "formulation", "integrator", "source", "why_none")


def _text(value) -> str:
    return value if isinstance(value, str) else ""


def _finite(value) -> bool:
    return isinstance(value, (int, float)) and math.isfinite(value)


def _same(a: float, b: float) -> bool:
    """Two targets read back from CSV (1e-06 written as 1e-06): equal to 1e-9 relative."""
    return abs(a - b) <= 1e-9 * max(abs(a), abs(b))


def _searched(advice: pd.DataFrame, case: str, engine: str, target: float, failed) -> list[dict]:
    """advice.csv's advised rows (a finite dt or tolerance) of one case, engine and target, as answers."""
    if advice is None or advice.empty:
        return []
    rows = advice[(advice["case"] == case) & (advice["engine"] == engine)]
    out = []
    for _, row in rows.iterrows():
        if not _same(float(row["target"]), target) or not (_finite(row["dt"]) or _finite(row["tolerance"])):
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
            "integrator": _text(row["integrator"]), "dt": row["dt"], "tolerance": row["tolerance"],
            "error": row["attitude_err"], "us_per_sim_s": row["us_per_sim_s"],
            "us_per_sim_s_spread": row["us_per_sim_s_spread"], "source": LISTED, "fails_at": math.nan}


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
    if advice is not None and len(advice):
        advice = advice.assign(formulation=advice["formulation"].map(_text))
    targets = sorted(set(pareto["target"]) if len(pareto) else ACCURACY_TARGETS, reverse=True)
    engines = scopes(pareto)
    records = []
    for case in dict.fromkeys(pareto["case"]):
        in_case = pareto[pareto["case"] == case]
        by_scope: dict[str, list[dict]] = {scope: [] for scope in [*engines, ANY]}
        for target in targets:
            at = in_case[[_same(float(t), target) for t in in_case["target"]]]
            found = []
            for engine in engines:
                cell = scope_rows(at, engine)
                searched = _searched(advice, case, engine, target, failed)
                covered = {(c["formulation"], c["integrator"]) for c in searched}
                listed = [_listed(r) for _, r in cell.iterrows() if _text(r["engine"])
                          and (_text(r["formulation"]), _text(r["integrator"])) not in covered]
                answer = _cheapest(searched + listed)
                why = "" if answer else (_text(cell["source"].iloc[0]) if len(cell) else "")
                by_scope[engine].append(_record(case, engine, target, answer, why))
                if answer:
                    found.append(answer)
            why_any = scope_rows(at, ANY)["source"]
            by_scope[ANY].append(_record(case, ANY, target, _cheapest(found),
                                         "" if found else (_text(why_any.iloc[0]) if len(why_any) else "")))
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
    """The answers of an output folder (pareto.csv, advice.csv and verdicts.csv); None without pareto.csv."""
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
