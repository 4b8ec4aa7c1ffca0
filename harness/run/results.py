"""The results table (DESIGN §4): its columns and row order, written atomically (harness/atomic.py) so an
interrupted run loses nothing written."""
from __future__ import annotations

import math
from pathlib import Path

import pandas as pd

from ..atomic import write_atomic  # noqa: F401 (imported from here too)
from ..tables import TableError, read_csv_table  # noqa: F401 (imported from here too)
# (home: harness/tables.py, so that analysis reads them without the columns here, which need the integrals)
from ..tables import SINGLE, disturbed, with_precision  # noqa: F401 (imported from here too)
from ..tables import (ANGLES, MAX_ANGLE, MAX_VALUE, METRIC_SUFFIXES, NON_NEGATIVE, POSITIVE,  # noqa: F401 (here too)
                      value_rule)
from ..scenes import kinds, scene
from ..scenes.metrics import DRIFT_COLUMNS, ERROR_COLUMNS, TORQUE_COLUMNS
from ..words import clipped, one_line
from ...reference.plugins import markup_problem

COLUMNS = ("case", "engine", "formulation", "integrator", "precision", "dt", "t_end", "steps", "status", "message",
           "diverged_at", "wall_s", "us_per_step", "us_per_step_spread", "timing", "rhs_per_sim_s", *DRIFT_COLUMNS, *ERROR_COLUMNS, "oracle_err",
           "truth_err", "truth_omega_err", "chart_changes", "torque_mode", *TORQUE_COLUMNS)

# Row order in the table and the report: the truth first, then engines as listed, integrators as each engine lists
# them, formulations as the engine lists them, dt descending, precisions as the engine lists them.
SORT_KEYS = ("case", "_engine_rank", "_integrator_rank", "_formulation_rank", "_dt_rank", "_precision_rank")


def row_order(row: dict) -> tuple:
    """A row's place in that order (its SORT_KEYS; 0 for a key it lacks)."""
    return tuple(row.get(key, 0) for key in SORT_KEYS)


def columns() -> tuple[str, ...]:
    """The table's columns: COLUMNS, then each registered scene's own (Scene.columns not in COLUMNS), in the scenes'
    registry order, so that a new scene's metric reaches results.csv (DESIGN §7)."""
    own = (column for kind in kinds() for column in scene(kind).columns if column not in COLUMNS)
    return (*COLUMNS, *dict.fromkeys(own))


def frame(rows: list[dict]) -> pd.DataFrame:
    """A DataFrame with exactly columns() (missing values NaN), in the canonical row order. A scene's own column
    that no row fills is left out: the table of a sweep without that scene's cases is COLUMNS, as before."""
    df = pd.DataFrame(rows)
    if "message" in df:  # every reason, whoever wrote it (a truth's, a worker's), within the rule (words.TEXT_MAX)
        df["message"] = df["message"].map(lambda text: clipped(text) if isinstance(text, str) else text)
    names = [c for c in columns() if c in COLUMNS or c in df]
    for column in names:
        if column not in df:
            df[column] = float("nan")
    if df.empty:
        return df[names]
    df = df.sort_values([k for k in SORT_KEYS if k in df], kind="stable")
    return df[names].reset_index(drop=True)


def write_results(df: pd.DataFrame, path: Path) -> None:
    write_atomic(path, df.to_csv(index=False, float_format="%.10g"))


REQUIRED_COLUMNS = ("case", "engine", "integrator", "status")
TEXT_COLUMNS = ("case", "engine", "formulation", "integrator", "precision", "status", "message", "timing",
                "torque_mode")
NAMED = ("case", "engine")  # never empty (the integrator is, on a skipped row of an engine that cannot run a case)
FINITE = ("dt", "us_per_step")
STATUSES = ("ok", "diverged", "failed", "skipped")  # trajectory.Status
# A row's identity (the gate's and compare's): one row per key in a table or a baseline.
KEY = ("case", "engine", "formulation", "integrator", "precision", "dt")


def metric_names() -> list[str]:
    """The drift and error columns of the results table: the names a baseline or a tolerance file may use."""
    return [c for c in COLUMNS if c.endswith(METRIC_SUFFIXES)]


def dt_key(value) -> str:
    """A step as a key compares it: 10 significant digits; "" for an adaptive row (no dt)."""
    try:
        value = float(value)
    except (TypeError, ValueError):
        return ""
    return "" if math.isnan(value) else f"{value:.10g}"


def duplicate(keys: list[tuple]) -> tuple[int, int] | None:
    """(first, again): the indices of the first key seen twice, or None."""
    seen: dict[tuple, int] = {}
    for index, key in enumerate(keys):
        if key in seen:
            return seen[key], index
        seen[key] = index
    return None


def describe_key(key: tuple) -> str:
    return " ".join(f"{name}={value}" for name, value in zip(KEY, key))


def read_results(path: Path) -> pd.DataFrame:
    """A results.csv, validated: the one reading of the table that `check`, `baseline`, `compare` and `report` share,
    so what one of them refuses the others refuse too. TableError (one line naming the file, and the row and column
    where there is one: row N counts data rows from 1, the header not counted) when the file is not a regular file,
    too large, empty, not CSV, has a row of another length than the header (ragged or truncated), lacks case, engine,
    integrator or status, has no rows, an empty case or engine, a status that is not one of STATUSES, text in a
    number column, a non-finite metric, timing or dt, a negative metric, count or timing (a dt <= 0), or two rows of
    one KEY. Text columns read as text ("" where empty), unprintable characters escaped (words.one_line: JUnit XML
    with an ESC or NUL from a hand-edited message was no XML), the others as numbers (NaN where empty)."""
    path = Path(path)
    df = read_csv_table(path, REQUIRED_COLUMNS, dtype=str, keep_default_na=False, skip_blank_lines=True)
    if df.empty:
        raise TableError(f"{path}: no rows (a header only)")
    for column in ("formulation", "message"):  # optional text columns a results.csv of an older version may lack
        if column not in df:
            df[column] = ""
    for column in [c for c in TEXT_COLUMNS if c in df]:  # a foreign file's ESC or NUL escaped as our writer does, so
        df[column] = df[column].map(lambda text: text if text.isprintable() else one_line(text))  # no output holds it
    for column in NAMED:
        empty = df.index[df[column].str.strip() == ""]
        if len(empty):
            raise TableError(f"{path}: row {empty[0] + 1}, column {column}: empty")
    for column in ("case", "engine", "formulation", "integrator"):  # names, shown as themselves in every report
        marked = df.index[df[column].map(lambda name: markup_problem(name) is not None)] if column in df else []
        if len(marked):
            raise TableError(f"{path}: row {marked[0] + 1}, column {column}: {df[column][marked[0]][:40]!r}: "
                             f"{markup_problem(df[column][marked[0]])}")
    bad = df.index[~df["status"].isin(STATUSES)]
    if len(bad):
        raise TableError(f"{path}: row {bad[0] + 1}, column status: {df['status'][bad[0]][:40]!r} is not a status "
                         f"({', '.join(STATUSES)})")
    for column in [c for c in df.columns if c not in TEXT_COLUMNS]:
        text = df[column].str.strip()
        values = pd.to_numeric(text.replace("", "nan"), errors="coerce")
        bad = df.index[values.isna() & (text != "") & (text.str.lower() != "nan")]
        if len(bad):
            raise TableError(f"{path}: row {bad[0] + 1}, column {column}: {text[bad[0]][:40]!r} is not a number")
        if column == "dt":  # a key: empty is an adaptive run's; "nan" spelled out (elsewhere a missing number, as
            bad = df.index[values.isna() & (text != "")]  # empty) re-keyed a fixed-step row as one: issue 46's 8th
            if len(bad):  # attack, where -0.01 was refused
                raise TableError(f"{path}: row {bad[0] + 1}, column dt: {text[bad[0]][:40]!r}: must be a number > 0, "
                                 "or empty (an adaptive run)")
        if column in FINITE or column.endswith(METRIC_SUFFIXES):
            bad = df.index[values.isin((math.inf, -math.inf))]
            if len(bad):
                raise TableError(f"{path}: row {bad[0] + 1}, column {column}: {text[bad[0]]!r}: must be finite "
                                 "or empty")
        if column in POSITIVE or column in NON_NEGATIVE or column.endswith(METRIC_SUFFIXES):
            bad = df.index[values.map(lambda value: value_rule(column, value) is not None)]
            if len(bad):
                raise TableError(f"{path}: row {bad[0] + 1}, column {column}: {text[bad[0]][:40]!r}: "
                                 f"{value_rule(column, values[bad[0]])}")
        df[column] = values
    df = with_precision(df)  # a results.csv of 0.2.0 has none: float64
    dts = df["dt"] if "dt" in df else pd.Series(math.nan, index=df.index)
    keys = list(zip(df["case"], df["engine"], df["formulation"], df["integrator"], df["precision"], dts.map(dt_key)))
    twice = duplicate(keys)
    if twice:
        raise TableError(f"{path}: row {twice[1] + 1}: duplicate key {describe_key(keys[twice[1]])} (also row "
                         f"{twice[0] + 1}): one row per key")
    return df
