"""`stereodyn compare A B`: two runs side by side, what someone upgrading MuJoCo or Pinocchio reads.

A and B are result directories (results.csv, and runs.json for the environment) or baseline files (`stereodyn
baseline`). This module compares (the tables, as data); harness.report.compare writes OUT/compare.md, compare.html and
compare.csv. Rows are matched by (case, engine, formulation, integrator, precision, dt) as in the gate; a table or
baseline without precision (0.2.0) holds float64 runs.
"""
from __future__ import annotations

import math
from pathlib import Path

import pandas as pd

from . import gate
from ..precision import FLOAT64
from ..environment import differences
from ..run.results import with_precision
from ..run.store import read_manifest

# Values below this are round-off (the gate's floor): two of them have no meaningful ratio, so a ratio is taken of
# max(value, FLOOR). The truth's drifts sit at 1e-16 .. 1e-14 and move by factors of ten between machines.
FLOOR = 1e-12
# Groups of rows by the largest accuracy change, |log10 ratio|: a tenfold change, twofold, a tenth; below the last,
# rows count as unchanged (round-off moves deterministic runs by far less than 10 %, harness.analysis.gate).
GROUPS = ((1.0, "changed 10x or more"), (math.log10(2.0), "changed 2x to 10x"),
          (math.log10(1.1), "changed 1.1x to 2x"))
TIMING = "us_per_step"
# The ratio of a metric that had a number in A and is NaN in B: infinitely worse (check fails it as it fails a
# metric over its bound); compare.csv writes it as inf, the pages as "NaN in B".
BECAME_NAN = math.inf
DIFFERS = "DIFFERS"
LISTED = 40      # rows listed per group (the output folder's compare.csv holds every row)
# --format pr: a metric changed when B / A leaves [1 / PR_RATIO, PR_RATIO] (the same-machine gate's factor), a fitted
# order when it moved by more than ORDER_CHANGE (fits are deterministic to < 0.01 on one machine: gate.ORDER_DROP).
PR_RATIO = 1.05
ORDER_CHANGE = 0.1
# Verdict statuses from best to worst (harness.analysis.verdicts): a change is better or worse by this rank.
VERDICT_RANK = {"pass": 0, "known": 0, "fixed upstream?": 0, "not measured": 1, "not measured, no reason": 2,
                "fail": 3}
FIGURE_ROWS = 20


class CompareError(ValueError):
    """A missing or malformed input of compare: one line, exit 2."""


def load(path: Path) -> tuple[pd.DataFrame, dict]:
    """(table, environment) of a result directory or a baseline file; CompareError when the table lacks the key
    columns or the status."""
    table, env = _load(Path(path))
    table = with_precision(table)  # a table or baseline of 0.2.0 has no precision: float64 runs
    missing = [c for c in (*gate.KEY, "status") if c not in table.columns]
    if missing:
        name = Path(path) / "results.csv" if Path(path).is_dir() else Path(path)
        raise CompareError(f"{name}: no column {', '.join(missing)} (a row is keyed by {', '.join(gate.KEY)})")
    return table.fillna({"formulation": ""}), env


def _load(path: Path) -> tuple[pd.DataFrame, dict]:
    try:
        if path.is_dir():  # a runs.json of the wrong shape counts as absent (harness.run.store.read_manifest)
            manifest = read_manifest(path)  # the environment with the code: a plug-in's changed source differs
            return gate.read_table(path), gate.recorded_environment(manifest)
        if path.is_file():
            baseline = gate.read_baseline_file(path)
            return pd.DataFrame(baseline.rows), baseline.environment
    except gate.GateError as exc:
        raise CompareError(str(exc)) from None
    except ValueError as exc:
        raise CompareError(f"{path}: not readable ({exc})") from None
    raise CompareError(f"{path}: no such result directory or baseline file")


def environment_rows(a: dict, b: dict) -> list[list[str]]:
    """[key, A, B, mark]: the keys that differ (environment.differences) first, then those that differ as expected
    (the measurement context: the date, the load at timing; a source hash only one side records), then the equal
    ones."""
    keys = list(dict.fromkeys([*a, *b]))
    rows = [[k, str(a.get(k, "-")), str(b.get(k, "-"))] for k in keys]
    differ = set(differences(a, b))
    rank = lambda r: (0 if r[0] in differ else 1 if r[1] != r[2] else 2)  # noqa: E731
    return [r + [DIFFERS if rank(r) == 0 else "differs (expected)" if rank(r) == 1 else ""]
            for r in sorted(rows, key=rank)]


def _metrics(a: pd.DataFrame, b: pd.DataFrame) -> list[str]:
    return [c for c in gate.metric_columns(a.columns) if c in b.columns]


def row_changes(a: pd.DataFrame, b: pd.DataFrame) -> pd.DataFrame:
    """One row per key in A or B: statuses, the ratio B/A of every metric and of the timing (BECAME_NAN for a metric
    that had a number in A and is NaN in B), the largest accuracy change (|log10 ratio|, inf for a metric become NaN)
    and its metric."""
    metrics = _metrics(a, b)
    index = lambda df: {gate._key(row): row for row in df.to_dict("records")}  # noqa: E731
    rows_a, rows_b = index(a), index(b)
    out = []
    for key in dict.fromkeys([*rows_a, *rows_b]):
        ra, rb = rows_a.get(key), rows_b.get(key)
        entry = dict(zip(gate.KEY, key))
        entry["status_a"] = "-" if ra is None else str(ra.get("status"))
        entry["status_b"] = "-" if rb is None else str(rb.get("status"))
        worst, worst_metric = 0.0, ""
        for metric in metrics + [TIMING]:
            x = gate._number(ra.get(metric)) if ra else math.nan
            y = gate._number(rb.get(metric)) if rb else math.nan
            ratio = max(y, FLOOR) / max(x, FLOOR) if math.isfinite(x) and math.isfinite(y) else math.nan
            if metric != TIMING and math.isfinite(x) and math.isnan(y) and rb is not None:
                ratio = BECAME_NAN  # a number in A, NaN in B: the gate fails it on a row ok in both, so worse
            entry[metric] = ratio
            if metric != TIMING and ratio > 0 and abs(math.log10(ratio)) > worst:  # NaN > 0 is False
                worst, worst_metric = abs(math.log10(ratio)), metric  # inf for a metric become NaN: the largest
        entry["change"], entry["metric"] = worst, worst_metric
        out.append(entry)
    return pd.DataFrame(out)


def group(row) -> str:
    """The group of a row of row_changes: status changed, changed 10x or more, ..., only in A, only in B, unchanged."""
    if row["status_a"] == "-":
        return "only in B"
    if row["status_b"] == "-":
        return "only in A"
    if row["status_a"] != row["status_b"]:
        return "status changed"
    for threshold, name in GROUPS:
        if row["change"] >= threshold:
            return name
    return "unchanged"


def label(row) -> str:
    dt = row["dt"] or "adaptive"
    precision = row.get("precision") if row.get("precision") != FLOAT64 else ""
    return " ".join(str(x) for x in (row["case"], row["engine"], row["formulation"], row["integrator"], precision)
                    if x) + f" dt={dt}"


def load_orders(path: Path) -> dict[tuple, dict]:
    """The fitted orders of a result directory (convergence.csv) or a baseline file, by run family (gate.ORDER_KEY):
    {"fitted", "declared"} (None where not fitted)."""
    path = Path(path)
    try:
        rows = (gate._order_rows(gate.read_orders(path)) if path.is_dir()
                else gate.read_baseline_file(path).orders)
    except gate.GateError as exc:
        raise CompareError(str(exc)) from None
    return {gate._order_key(row): row for row in rows}


def order_changes(a: dict[tuple, dict], b: dict[tuple, dict]) -> list[dict]:
    """The run families whose fitted order moved by more than ORDER_CHANGE, appeared, or went (NaN counts as none):
    {key, declared, a, b, sign}; sign: worse where the gate fails it (B fell more than gate.ORDER_DROP below A, or
    went), better when B is nearer the declared order, new when only B has one, changed otherwise. Worst first."""
    out = []
    for key in dict.fromkeys([*a, *b]):
        x, y = (gate._number((side.get(key) or {}).get("fitted")) for side in (a, b))
        declared = gate._number((b.get(key) or a.get(key) or {}).get("declared"))
        if math.isnan(x) and math.isnan(y) or abs(y - x) <= ORDER_CHANGE:
            continue
        if math.isnan(y) or math.isnan(x):  # gone is worse (the gate fails it); a new fit has no direction
            sign = "worse" if math.isnan(y) else "new"
        elif y < x - gate.ORDER_DROP:  # worse exactly where the gate fails it (fell): the PR summary agrees with check
            sign = "worse"
        elif not math.isnan(declared) and abs(y - declared) < abs(x - declared):
            sign = "better"
        else:  # farther from the declared order, within what the gate passes, or none declared
            sign = "changed"
        out.append({"key": key, "declared": declared, "a": x, "b": y, "sign": sign})
    moved = lambda c: math.inf if math.isnan(c["a"] - c["b"]) else abs(c["b"] - c["a"])  # noqa: E731
    return sorted(out, key=lambda c: (c["sign"] != "worse", -moved(c)))


def verdict_changes(a: Path, b: Path) -> list[dict]:
    """The verdicts (verdicts.csv of two result directories) whose status changed: {name, a, b, sign}; a verdict in
    one run only counts from or to "-". Worse first. None where either side is a baseline file: it keeps no
    verdicts, so it has none to lose or gain (its rows and orders are compared)."""
    from .verdicts import read

    if not (Path(a).is_dir() and Path(b).is_dir()):
        return []

    def index(path: Path) -> dict:
        found = read(path) if Path(path).is_dir() else None
        return {(v.verdict, v.engine, v.formulation, v.integrator, v.precision, v.case): v.status
                for v in found or []}

    old, new = index(a), index(b)
    out = []
    for key in dict.fromkeys([*old, *new]):
        x, y = old.get(key, "-"), new.get(key, "-")
        if x == y:
            continue
        rank_x, rank_y = VERDICT_RANK.get(x, 1), VERDICT_RANK.get(y, 1)
        sign = "worse" if rank_y > rank_x else "better" if rank_y < rank_x else "changed"
        name = " ".join(p for p in (key[0], key[1], key[2], key[3], "" if key[4] in ("", FLOAT64) else key[4],
                                    key[5]) if p)
        out.append({"name": name, "a": x, "b": y, "sign": sign})
    return sorted(out, key=lambda c: c["sign"] != "worse")


def metric_signs(changes: pd.DataFrame) -> list[dict]:
    """Per accuracy metric (lower is better), over the rows ok in both runs: how many got worse (B / A > PR_RATIO)
    and better (< 1 / PR_RATIO), and the largest ratio each way with its row. Metrics with a change, most worsened
    first."""
    both = changes[(changes["status_a"] == "ok") & (changes["status_b"] == "ok")] if len(changes) else changes
    out = []
    for metric in [c for c in changes.columns if c.endswith(gate.METRIC_SUFFIXES)]:
        ratios = both[metric].dropna() if len(both) else pd.Series([], dtype=float)
        worse, better = ratios[ratios > PR_RATIO], ratios[ratios < 1.0 / PR_RATIO]
        if worse.empty and better.empty:
            continue
        entry = {"metric": metric, "worse": len(worse), "better": len(better), "worst": None, "best": None}
        if len(worse):
            entry["worst"] = (label(both.loc[worse.idxmax()]), float(worse.max()))
        if len(better):
            entry["best"] = (label(both.loc[better.idxmin()]), float(better.min()))
        out.append(entry)
    return sorted(out, key=lambda e: (-(e["worst"][1] if e["worst"] else 0.0), -e["better"]))


def identical(a: pd.DataFrame, b: pd.DataFrame) -> bool:
    """The same rows (by key), statuses and accuracy metrics, value for value (NaN where the other is NaN)."""
    metrics = ["status", *_metrics(a, b)]
    if set(gate.metric_columns(a.columns)) != set(gate.metric_columns(b.columns)):
        return False
    index = lambda df: {gate._key(row): [row.get(m) for m in metrics] for row in df.to_dict("records")}  # noqa: E731
    rows_a, rows_b = index(a), index(b)

    def same(x, y) -> bool:
        return x == y or (isinstance(x, float) and isinstance(y, float) and math.isnan(x) and math.isnan(y))

    return rows_a.keys() == rows_b.keys() and all(all(same(x, y) for x, y in zip(rows_a[k], rows_b[k]))
                                                   for k in rows_a)
