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
from ..engines.base import FLOAT64
from ..run.results import with_precision
from ..run.store import read_manifest

# Values below this are round-off (the gate's floor): two of them have no meaningful ratio, so a ratio is taken of
# max(value, FLOOR). The truth's drifts sit at 1e-16 .. 1e-14 and move by factors of ten between machines.
FLOOR = 1e-12
# Groups of rows by the largest accuracy change, |log10 ratio|: a tenfold change, twofold, a tenth; below the last,
# rows count as unchanged (round-off moves deterministic runs by far less than 10 %, harness.analysis.gate).
GROUPS = ((1.0, "changed 10x or more"), (math.log10(2.0), "changed 2x to 10x"),
          (math.log10(1.1), "changed 1.1x to 2x"))
# Environment keys that differ between any two runs (not a difference in what ran).
EXPECTED = ("date", "report rendered")
TIMING = "us_per_step"
DIFFERS = "DIFFERS"
LISTED = 40      # rows listed per group (the output folder's compare.csv holds every row)
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
            return gate.read_table(path), (read_manifest(path) or {}).get("environment") or {}
        if path.is_file():
            baseline = gate.read_baseline_file(path)
            return pd.DataFrame(baseline.rows), baseline.environment
    except gate.GateError as exc:
        raise CompareError(str(exc)) from None
    except ValueError as exc:
        raise CompareError(f"{path}: not readable ({exc})") from None
    raise CompareError(f"{path}: no such result directory or baseline file")


def environment_rows(a: dict, b: dict) -> list[list[str]]:
    """[key, A, B, mark]: the keys that differ first (expected ones, the date, after them), then the equal ones."""
    keys = list(dict.fromkeys([*a, *b]))
    rows = [[k, str(a.get(k, "-")), str(b.get(k, "-"))] for k in keys]
    differs = lambda r: r[1] != r[2]  # noqa: E731
    rank = lambda r: (0 if differs(r) and r[0] not in EXPECTED else 1 if differs(r) else 2)  # noqa: E731
    return [r + [DIFFERS if rank(r) == 0 else "differs (expected)" if rank(r) == 1 else ""]
            for r in sorted(rows, key=rank)]


def _metrics(a: pd.DataFrame, b: pd.DataFrame) -> list[str]:
    return [c for c in gate.metric_columns(a.columns) if c in b.columns]


def row_changes(a: pd.DataFrame, b: pd.DataFrame) -> pd.DataFrame:
    """One row per key in A or B: statuses, the ratio B/A of every metric and of the timing, the largest accuracy
    change (|log10 ratio|) and its metric."""
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
            entry[metric] = ratio
            if metric != TIMING and math.isfinite(ratio) and abs(math.log10(ratio)) > worst:
                worst, worst_metric = abs(math.log10(ratio)), metric
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
